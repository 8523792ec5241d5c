// Crossings of many parallel rays with a triangle surface: the surface is projected along the
// ray direction and binned in a 2D grid, so a ray only tests the triangles of its cell.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// One crossing of a ray with the surface.
struct Crossing {
  double t = 0.0;  // ray parameter (mm, the direction is unit length)
  int sign = 0;    // +1: the ray leaves the solid (exit), -1: it enters it (entry)
};

// The triangles of `surface` sorted along a Morton curve of their centroids: in any projection,
// the triangles of one grid cell then lie close together in memory.
TriMesh morton_sorted(const TriMesh& surface);

class ParallelRays {
 public:
  // Projects `surface` (outward triangles) along the unit vector `dir`. Buffers are kept when
  // project() is called again for another direction.
  void project(const TriMesh& surface, const Vec3& dir);

  // What is known of a sample's accessibility along the projected direction.
  enum SampleState : std::uint8_t { kUnknown = 0, kOpen, kBlocked };

  // A quick, conservative test of every point from per-cell depth bounds: kOpen when, ahead of
  // the point, the ray meets entry-facing triangles only within epsilon_mm and exit-facing
  // ones only beyond. Crossings alternate, so the ray then enters at most once, right at the
  // start, and leaves at most once: the sample is DHF-accessible without asking crossings().
  // Most rays are. kUnknown otherwise. Writes state[i] for points[i].
  void settle(const std::vector<Vec3>& points, double epsilon_mm, std::uint8_t* state) const;

  // All crossings of the ray origin + t * dir, t >= 0, sorted by t. Exact projected
  // point-in-triangle tests with a symbolic perturbation of the ray make shared edges and
  // vertices count once, so crossings alternate between entries and exits as they should.
  // Crossings closer than merge_tolerance_mm are merged: same side, one crossing; opposite
  // sides (the ray touches the surface), none. Not thread-safe (scratch buffers): use one
  // ParallelRays per thread.
  void crossings(const Vec3& origin, double merge_tolerance_mm, std::vector<Crossing>& out) const;

 private:
  struct Hit {
    float t;
    std::int32_t sign, id;
  };
  // A triangle as crossings() tests it, in one cache line (its corners' depths, needed only
  // for hits, are in tri_z_): edge j (corner j to j + 1) is a[j] (x - x[j]) + b[j] (y - y[j])
  // with (x[j], y[j]) its lower-index end, negated when bit j of `flip` is set; bit j of
  // `tie_up` is its sign for a point exactly on the line.
  struct alignas(64) ProjectedTri {
    float a[3], b[3], x[3], y[3];
    std::uint32_t flip, tie_up;
  };
  // Depth bounds of one depth_grid_ cell, side by side: a query reads one cache line.
  struct DepthBounds {
    float entry_top, exit_bottom;
  };
  // A uniform grid over the projection plane.
  struct Grid {
    float x0 = 0, y0 = 0, inv_cell = 1;
    std::int32_t nx = 0, ny = 0;
    // Covers [xmin, xmax] x [ymin, ymax] with about `cells` square cells.
    void fit(float xmin, float xmax, float ymin, float ymax, double cells);
    std::size_t size() const { return static_cast<std::size_t>(nx) * ny; }
    // The cell of a point, or -1 outside the grid.
    std::int64_t cell_of(float x, float y) const;
    // Calls f(first, n) for every row of cells meeting the box {x min, x max, y min, y max}:
    // the cells first, ..., first + n - 1.
    template <class F>
    void for_rows(const std::array<float, 4>& box, F&& f) const {
      auto clamp_cell = [](float v, std::int32_t n) {
        return std::clamp(static_cast<std::int32_t>(v), std::int32_t{0}, n - 1);
      };
      const std::int32_t i0 = clamp_cell((box[0] - x0) * inv_cell, nx);
      const std::int32_t i1 = clamp_cell((box[1] - x0) * inv_cell, nx);
      const std::int32_t j0 = clamp_cell((box[2] - y0) * inv_cell, ny);
      const std::int32_t j1 = clamp_cell((box[3] - y0) * inv_cell, ny);
      for (std::int32_t i = i0; i <= i1; ++i)
        f(static_cast<std::size_t>(i) * ny + j0, static_cast<std::size_t>(j1 - j0 + 1));
    }
  };

  Vec3 u_, v_, d_;
  std::vector<float> px_, py_, pz_;  // projected vertices: (u, v, dir) coordinates
  Grid depth_grid_;                  // fine
  // Per depth_grid_ cell: highest depth of its entry-facing triangles, lowest of its
  // exit-facing ones.
  std::vector<DepthBounds> depth_;
  Grid tri_grid_;  // coarse
  // Cell c of tri_grid_ holds the triangles cell_tris_[cell_start_[c] .. cell_start_[c + 1]).
  // cell_top_[k]: depth of the deepest corner of triangle cell_tris_[k].
  std::vector<std::int32_t> cell_start_, cell_tris_;
  std::vector<float> cell_top_;
  double depth_slack_mm_ = 0.0;  // round-off margin for comparisons with cell_top_
  std::vector<ProjectedTri> tris_;           // per triangle of the surface
  std::vector<std::array<float, 3>> tri_z_;  // per triangle: depth of its corners
  std::vector<std::array<float, 4>> boxes_;  // scratch: projected bounding boxes
  mutable std::vector<Hit> hits_;  // scratch
};

}  // namespace dhfcast::detail
