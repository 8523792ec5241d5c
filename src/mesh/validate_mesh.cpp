// validate_mesh(): is a welded triangle mesh the boundary of a solid?
#include <Eigen/Geometry>
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include "cgal_checks.h"
#include "dhfcast/mesh.h"

namespace dhfcast {

namespace {

// Reporting the first few pairs is enough to explain the problem; counting them all could take
// as long as the pairs are many.
constexpr unsigned kMaxIntersectingPairs = 100;

std::string count_of(std::int64_t n, const std::string& noun) {
  return std::to_string(n) + " " + noun + (n == 1 ? "" : "s");
}

std::string edge_name(std::int32_t a, std::int32_t b) {
  return "edge (v" + std::to_string(a) + ", v" + std::to_string(b) + ")";
}

std::string point_mm(const Vec3& p) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.5g, %.5g, %.5g)", p.x(), p.y(), p.z());
  return text;
}

// A triangle side a -> b, with a = tri[k], b = tri[(k + 1) % 3]; key identifies {a, b}.
struct HalfEdge {
  std::uint64_t key;
  std::uint32_t corner;  // 3 * triangle + k
  bool operator<(const HalfEdge& o) const { return key != o.key ? key < o.key : corner < o.corner; }
};

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }
  std::uint32_t find(std::uint32_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    // The smaller index wins, so roots do not depend on the order of unions.
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<std::uint32_t> parent_;
};

}  // namespace

MeshDiagnostics validate_mesh(const TriMesh& mesh) {
  MeshDiagnostics d;
  const auto num_vertices = static_cast<std::int64_t>(mesh.vertices.size());
  const auto num_triangles = static_cast<std::int64_t>(mesh.triangles.size());

  // --- 0. preconditions of everything below ---
  if (num_triangles == 0) {
    d.first_problem = "has no triangles";
    return d;
  }
  if (3 * num_triangles > std::numeric_limits<std::uint32_t>::max()) {
    d.first_problem = "too many triangles (" + std::to_string(num_triangles) + ")";
    return d;
  }
  for (std::int64_t t = 0; t < num_triangles; ++t)
    for (std::int32_t v : mesh.triangles[t])
      if (v < 0 || v >= num_vertices) {
        d.first_problem = "triangle " + std::to_string(t) + " refers to vertex " +
                          std::to_string(v) + " but there are only " +
                          std::to_string(num_vertices) + " vertices";
        return d;
      }
  auto corner_vertex = [&](std::uint32_t c) { return mesh.triangles[c / 3][c % 3]; };

  // --- 1. finite coordinates ---
  std::int64_t first_nonfinite = -1;
  for (std::int64_t v = 0; v < num_vertices; ++v)
    if (!mesh.vertices[v].allFinite()) {
      ++d.nonfinite_vertices;
      if (first_nonfinite < 0) first_nonfinite = v;
    }

  // --- 2. edges: each undirected edge should be used by two triangles, once in each direction ---
  std::vector<HalfEdge> half_edges;
  half_edges.reserve(3 * static_cast<std::size_t>(num_triangles));
  for (std::uint32_t c = 0; c < 3 * num_triangles; ++c) {
    const std::uint32_t a = corner_vertex(c);
    const std::uint32_t b = corner_vertex(c - c % 3 + (c + 1) % 3);
    if (a == b) continue;  // a repeated vertex: reported as a degenerate triangle
    half_edges.push_back({std::uint64_t{std::min(a, b)} << 32 | std::max(a, b), c});
  }
  std::sort(half_edges.begin(), half_edges.end());

  // Corners (triangle, vertex) around one vertex are joined across the vertex's manifold edges;
  // a vertex whose corners end up in several groups has several fans.
  UnionFind fans(3 * static_cast<std::size_t>(num_triangles));
  auto corner_at = [&](std::uint32_t edge_corner, std::uint32_t vertex) {
    return static_cast<std::uint32_t>(corner_vertex(edge_corner)) == vertex
               ? edge_corner
               : edge_corner - edge_corner % 3 + (edge_corner + 1) % 3;
  };
  std::string boundary_example, nonmanifold_example, misoriented_example;
  for (std::size_t i = 0; i < half_edges.size();) {
    std::size_t j = i;
    while (j < half_edges.size() && half_edges[j].key == half_edges[i].key) ++j;
    const std::uint32_t c0 = half_edges[i].corner;
    const std::int32_t a = corner_vertex(c0);
    const std::int32_t b = corner_vertex(c0 - c0 % 3 + (c0 + 1) % 3);
    if (j - i == 1) {
      if (d.boundary_edges++ == 0)
        boundary_example = edge_name(a, b) + " is used by only one triangle (triangle " +
                           std::to_string(c0 / 3) + ")";
    } else if (j - i > 2) {
      if (d.nonmanifold_edges++ == 0) nonmanifold_example = edge_name(a, b);
    } else {
      const std::uint32_t c1 = half_edges[i + 1].corner;
      if (corner_vertex(c1) == a && d.misoriented_edges++ == 0)
        misoriented_example = edge_name(a, b);
      fans.unite(corner_at(c0, a), corner_at(c1, a));
      fans.unite(corner_at(c0, b), corner_at(c1, b));
    }
    i = j;
  }
  // A triangle with a repeated vertex has two corners there: they belong to the same fan.
  for (std::uint32_t t = 0; t < num_triangles; ++t)
    for (std::uint32_t k = 0; k < 3; ++k)
      if (corner_vertex(3 * t + k) == corner_vertex(3 * t + (k + 1) % 3))
        fans.unite(3 * t + k, 3 * t + (k + 1) % 3);

  std::vector<std::int32_t> fan_count(num_vertices, 0);
  for (std::uint32_t c = 0; c < 3 * num_triangles; ++c)
    if (fans.find(c) == c) ++fan_count[corner_vertex(c)];
  std::int64_t first_split_vertex = -1;
  for (std::int64_t v = 0; v < num_vertices; ++v)
    if (fan_count[v] > 1) {
      ++d.nonmanifold_vertices;
      if (first_split_vertex < 0) first_split_vertex = v;
    }

  // --- 3. degenerate triangles (exact collinearity) ---
  std::int64_t first_degenerate = -1;
  for (std::int64_t t = 0; t < num_triangles; ++t) {
    const Tri& tri = mesh.triangles[t];
    const Vec3& p = mesh.vertices[tri[0]];
    const Vec3& q = mesh.vertices[tri[1]];
    const Vec3& r = mesh.vertices[tri[2]];
    const bool repeated = tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0];
    const bool finite = p.allFinite() && q.allFinite() && r.allFinite();
    if (repeated || (finite && detail::collinear_exact(p, q, r))) {
      ++d.degenerate_triangles;
      if (first_degenerate < 0) first_degenerate = t;
    }
  }

  // --- 4. first problem, in order of the checks ---
  if (d.nonfinite_vertices > 0) {
    d.first_problem =
        "contains a NaN or infinite coordinate at vertex " + std::to_string(first_nonfinite);
  } else if (d.boundary_edges > 0) {
    d.first_problem =
        "not closed: " + count_of(d.boundary_edges, "boundary edge") + ", e.g. " + boundary_example;
  } else if (d.nonmanifold_edges > 0) {
    d.first_problem = "not 2-manifold: " + count_of(d.nonmanifold_edges, "edge") +
                      (d.nonmanifold_edges == 1 ? " is" : " are") +
                      " shared by more than two triangles, e.g. " + nonmanifold_example;
  } else if (d.nonmanifold_vertices > 0) {
    d.first_problem = "not 2-manifold at vertex " + std::to_string(first_split_vertex) + " " +
                      point_mm(mesh.vertices[first_split_vertex]) + ": its triangles form " +
                      std::to_string(fan_count[first_split_vertex]) + " separate fans";
  } else if (d.misoriented_edges > 0) {
    d.first_problem =
        "inconsistently oriented: " + misoriented_example + " is used twice in the same direction";
  } else if (d.degenerate_triangles > 0) {
    d.first_problem = "degenerate triangle " + std::to_string(first_degenerate) +
                      " (zero area or repeated vertex)";
  }

  // --- 5. self-intersections: only meaningful (and CGAL's preconditions only hold) on a
  // closed, oriented manifold with finite, non-degenerate triangles ---
  if (d.first_problem.empty()) {
    const detail::SelfIntersections si =
        detail::find_self_intersections(mesh, kMaxIntersectingPairs);
    d.intersecting_pairs = si.pairs;
    if (si.pairs > 0)
      d.first_problem = "self-intersecting: triangles " + std::to_string(si.first[0]) + " and " +
                        std::to_string(si.first[1]) + " intersect (" +
                        (si.limit_reached ? "at least " : "") +
                        count_of(si.pairs, "intersecting pair") + ")";
  }

  // --- 6. volume: zero up to the rounding error of the sum ---
  d.volume_mm3 = signed_volume(mesh);
  if (d.first_problem.empty()) {
    double sum_abs = 0.0;
    for (const Tri& t : mesh.triangles)
      sum_abs += std::abs(mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]])));
    if (std::abs(6.0 * d.volume_mm3) <= 64.0 * DBL_EPSILON * sum_abs)
      d.first_problem = "zero volume";
  }
  return d;
}

namespace {

// Directed uses of each edge must cancel: closed and consistently oriented, even where the part
// touches itself along an edge (four triangles, two each way).
std::int64_t unbalanced_edges(const TriMesh& mesh) {
  std::map<std::pair<std::int32_t, std::int32_t>, int> balance;
  for (const Tri& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const std::int32_t a = t[k], b = t[(k + 1) % 3];
      if (a != b) balance[{std::min(a, b), std::max(a, b)}] += a < b ? 1 : -1;
    }
  return std::ranges::count_if(balance, [](const auto& e) { return e.second != 0; });
}

}  // namespace

std::string part_solid_problem(const TriMesh& mesh) {
  const MeshDiagnostics d = validate_mesh(mesh);
  if (d.nonfinite_vertices > 0 || unbalanced_edges(mesh) > 0) return d.first_problem;
  if (d.degenerate_triangles > 0)
    return count_of(d.degenerate_triangles, "degenerate triangle") +
           " (zero area or repeated vertex)";
  if (d.intersecting_pairs > 0) return d.first_problem;
  if (d.volume_mm3 <= 0) {
    char text[64];
    std::snprintf(text, sizeof text, "inward oriented or empty (volume %.6g mm3)", d.volume_mm3);
    return text;
  }
  return {};
}

}  // namespace dhfcast
