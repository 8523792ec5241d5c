// Triangles binned by their projection across a direction d: lines along +-d through a point
// can meet only the triangles listed in that point's cell. Shared by the smoothing's outer
// columns (parts) and the molds' line queries.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast {

class ProjectedGrid {
 public:
  ProjectedGrid() = default;  // lists nothing
  // boxes[i]: item i's box in the plane across d, {x min, x max, y min, y max} with
  // (x, y) = (p.u, p.v) (see across()), each grown by `slack` on every side. About two items
  // per cell, and at most 2048 cells along a side.
  ProjectedGrid(const std::vector<std::array<double, 4>>& boxes, double slack);

  // A point's coordinates in the plane across the unit vector d: (p.u, p.v) with u =
  // d.unitOrthogonal(), v = d x u.
  static std::array<Vec3, 2> across(const Vec3& d) {
    const Vec3 u = d.unitOrthogonal();
    return {u, d.cross(u)};
  }

  // The items whose grown box meets the cell of (x, y), ascending; none outside the grid.
  std::span<const std::int32_t> at(double x, double y) const;

 private:
  double x0_ = 0, y0_ = 0, inv_cell_ = 1;
  std::int32_t nx_ = 0, ny_ = 0;
  std::vector<std::int32_t> cell_begin_, items_;  // items of cell c: [cell_begin_[c], [c + 1])
};

}  // namespace dhfcast
