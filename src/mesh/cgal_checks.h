// Private to the mesh stage: the exact geometric tests of validate_mesh(), done with CGAL.
#pragma once

#include <array>
#include <cstdint>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// Exact predicate: are a, b and c on one line (coincident points included)? Finite inputs only.
bool collinear_exact(const Vec3& a, const Vec3& b, const Vec3& c);

// Result of find_self_intersections().
struct SelfIntersections {
  std::int64_t pairs = 0;      // intersecting triangle pairs found (at most the limit)
  bool limit_reached = false;  // the search stopped at the limit: there may be more
  std::array<std::int32_t, 2> first = {-1, -1};  // smallest pair found, by triangle index
};

// Pairs of triangles that intersect other than along a shared edge or vertex (exact predicates).
// Stops after max_pairs pairs. Pre: mesh is a closed, 2-manifold, consistently oriented mesh with
// finite coordinates and no degenerate triangle.
SelfIntersections find_self_intersections(const TriMesh& mesh, unsigned max_pairs);

}  // namespace dhfcast::detail
