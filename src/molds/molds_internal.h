// Private to molds: what the mold stage's files share.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dhfcast/molds.h"
#include "dhfcast/types.h"

namespace dhfcast::detail {

// x rounded to the nearest float (what an STL stores). The volatile store keeps GCC (12, -O3,
// with CGAL's headers) from dropping the float conversion, which it was seen to do.
inline double to_float(double x) {
  volatile float f = static_cast<float>(x);
  return f;
}

// --- cgal_rays.cpp: lines against one closed mesh (CGAL AABB tree or a grid along one axis,
// exact predicates) ---

// A parameter interval [begin, end] along a line origin + t * dir.
struct LineInterval {
  double begin = 0.0, end = 0.0;
};

class LineIndex {
 public:
  // Lines along +-axis (a unit vector; zero: none), most of the queries, find their triangles
  // in a grid of the mesh projected across it instead of the tree: the same triangles, as
  // both end with the same exact test.
  explicit LineIndex(const TriMesh& mesh, const Vec3& axis = Vec3::Zero());
  ~LineIndex();
  LineIndex(LineIndex&&) noexcept;
  LineIndex& operator=(LineIndex&&) noexcept;

  // Where the line origin + t * dir (t in R) is inside the solid, sorted. Crossings are told
  // apart by the sign of the face normal along dir; nullopt when they do not alternate
  // (the line grazes an edge or lies in a face's plane).
  std::optional<std::vector<LineInterval>> line_intervals(const Vec3& origin,
                                                          const Vec3& dir) const;
  // Distance from p to the mesh's surface, mm.
  double distance(const Vec3& p) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// line_intervals(), retried from a few points a hair away from `origin` (across dir) when the
// crossings are inconsistent; empty when none works.
std::vector<LineInterval> robust_line_intervals(const LineIndex& index, const Vec3& origin,
                                                const Vec3& dir, double hair_mm);

// --- cgal_booleans.cpp: corefinement booleans and the final clean-up ---

enum class BooleanOp { Union, Difference };

// `mesh` with its vertices (and edges) duplicated where the surface touches itself, so that it
// is a 2-manifold surface (a part read back from an STL is welded there).
TriMesh unweld_nonmanifold(const TriMesh& mesh);

// a op b for closed, outward, non-self-intersecting meshes (a soup of disjoint closed
// components is fine); b is checked for self-intersections where it meets a. Throws
// Error{BooleanFailed} naming `what` when b intersects itself or CGAL gives no solid.
TriMesh mesh_boolean(const TriMesh& a, const TriMesh& b, BooleanOp op, const std::string& what);

// One step of carve(): `op` with `mesh`, named `what` in errors.
struct CarveStep {
  BooleanOp op;
  const TriMesh* mesh;
  std::string what;
};

// block op1 mesh1 op2 mesh2 ..., with exact constructions throughout (results of inexact
// booleans, fed to the next one, can intersect themselves), converted to double at the end.
// Each step's operands are checked for self-intersections where they meet (CGAL would crash
// or give garbage); throws Error{BooleanFailed} naming the step.
TriMesh carve(const TriMesh& block, const std::vector<CarveStep>& steps);

// Rounds every vertex to float (as an STL stores it), then removes the degenerate faces that
// rounding made and unwelds vertices where the solid touches itself. Returns "" when the result
// is a closed, outward, self-intersection-free solid, else what is wrong.
std::string finish_solid(TriMesh& mesh);

// --- face_split.cpp ---

// Which half moulds each triangle of a part (paper §4.3.2).
struct FaceSplit {
  std::vector<std::uint8_t> up;  // per triangle: 1 = up half (+d), 0 = down half (-d)
  FaceSplitStats stats;
  // The parting line: edges between an up and a down triangle, as vertex pairs.
  std::vector<std::array<std::int32_t, 2>> parting_edges;
};

// Accessibility of each triangle along +d and -d (a ray from its centroid goes deeper than
// epsilon into the part or not), then a graph cut: triangles accessible both ways (or neither)
// go to the side their normal is better aligned with, and a boundary-length term keeps the
// parting line short and smooth.
FaceSplit split_faces(const TriMesh& part, const LineIndex& index, const Vec3& d,
                      double epsilon_mm);

// Points on the parting line where air is trapped when the mold stands with `up` pointing up:
// local maxima of height along `up` whose prominence is at least min_prominence_mm and where the
// cavity lies below (the part's outward normal has a positive component along `up`). Highest
// first (ties: lowest vertex index).
std::vector<std::int32_t> trapped_maxima(const TriMesh& part, const FaceSplit& split,
                                         const Vec3& up, double min_prominence_mm);

// --- geometry helpers (mold_geometry.cpp) ---

// A truncated cone with its axis along `axis` (unit): base circle (centre, radius) and top circle
// at `height` along the axis. Closed, outward.
TriMesh make_frustum(const Vec3& base_centre, const Vec3& axis, double base_radius,
                     double top_radius, double height, int segments);

// Appends b's triangles to a (disjoint closed components stay a valid operand of carve()).
void append_mesh(TriMesh& a, const TriMesh& b);

// Reverses every triangle when the signed volume is negative.
void orient_outward(TriMesh& mesh);

// Orders vertices by coordinates and triangles by vertices (orientation kept): the same surface
// gives the same arrays whatever order a boolean produced it in. Vertices with equal
// coordinates keep their relative order.
void canonicalize(TriMesh& mesh);

// Welds vertices with identical coordinates (what reading an STL does).
TriMesh weld_exact(const TriMesh& mesh);

// Keeps the shells (connected components) that have a vertex on the plane z = 0, and the
// vertices they use, in their order.
void keep_shells_on_bed(TriMesh& mesh);

}  // namespace dhfcast::detail
