// Private to check: ray crossings, inside tests and distances on one triangle mesh (a CGAL AABB
// tree over the triangles, Epick: exact do-intersect predicates). Only cgal_surface_index.cpp
// sees CGAL.
#pragma once

#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// A parameter interval [begin, end] along a line origin + t * dir.
struct Interval {
  double begin = 0.0;
  double end = 0.0;
};

class SurfaceIndex {
 public:
  // Builds the tree (degenerate triangles are left out). The mesh may touch itself at edges and
  // vertices; it should be closed and outward oriented for the inside queries to mean anything.
  explicit SurfaceIndex(const TriMesh& mesh);
  ~SurfaceIndex();
  SurfaceIndex(SurfaceIndex&&) noexcept;
  SurfaceIndex& operator=(SurfaceIndex&&) noexcept;

  const TriMesh& mesh() const;
  const Box3& bbox() const;

  // Where the whole line origin + t * dir (dir unit, t in R) is inside the solid, as sorted,
  // disjoint intervals. nullopt when the crossings are inconsistent (they do not alternate
  // enter/exit: the line grazes an edge, or the mesh is open or inverted there).
  // Crossings at the same point (an edge or vertex hit) count once; a tangent touch counts zero.
  std::optional<std::vector<Interval>> line_intervals(const Vec3& origin, const Vec3& dir) const;
  // The same on the ray t >= 0; an interval may begin at 0 when the origin is inside.
  std::optional<std::vector<Interval>> ray_intervals(const Vec3& origin, const Vec3& dir) const;
  // Is p inside the solid? Tries a few fixed oblique lines until one is consistent; false when
  // none is.
  bool contains(const Vec3& p) const;
  // Distance from p to the surface, mm.
  double distance(const Vec3& p) const;
  // Largest distance to the surface over samples of the segment origin + t * dir, t in
  // [t0, t1], spaced at most step_mm apart (at most 256 samples), endpoints included. Returns as
  // soon as a sample is farther than stop_above_mm (the midpoint is tried first).
  double max_distance_along(const Vec3& origin, const Vec3& dir, double t0, double t1,
                            double step_mm,
                            double stop_above_mm = std::numeric_limits<double>::infinity()) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dhfcast::detail
