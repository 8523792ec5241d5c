// Private to parts: where a line along one direction enters and leaves the solid, and which
// part owns the outer triangle it crosses there. Lets smoothing keep interfaces out of each
// part's infeasible volume (paper §4.3.1).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "dhfcast/projected_grid.h"
#include "dhfcast/types.h"

namespace dhfcast::detail {

class OuterColumns {
 public:
  OuterColumns() = default;  // meets nothing
  // triangles[i] (corners in `position`) is an outer triangle of part owner[i]; d is unit.
  OuterColumns(const std::vector<Vec3>& position, const std::vector<Tri>& triangles,
               const std::vector<std::int32_t>& owner, const Vec3& d);

  // The owners of the nearest outer triangles the line x + s * d meets at s > 0 and at s < 0
  // (-1 where it meets none). For x inside the solid these are the parts at the two ends of
  // the stretch of solid through x.
  std::pair<std::int32_t, std::int32_t> ends(const Vec3& x) const;

 private:
  Vec3 d_, u_, w_;
  ProjectedGrid grid_;  // of flat_
  struct Flat {
    Vec3 a, n;                      // a corner and the (unnormalized) normal
    double au, aw, bu, bw, cu, cw;  // projected corners
    std::int32_t owner;
  };
  std::vector<Flat> flat_;
};

}  // namespace dhfcast::detail
