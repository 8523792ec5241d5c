// Mesh booleans (CGAL corefinement, exact predicates) and the clean-up that makes a result
// exactly what its float STL will hold. One of the two files of the mold stage that include
// CGAL.
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/manifoldness.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/Euler_operations.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "dhfcast/error.h"
#include "molds_internal.h"

namespace dhfcast::detail {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Mesh = CGAL::Surface_mesh<K::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

// nullopt when the triangles do not form an oriented 2-manifold surface.
template <typename M>
std::optional<M> to_surface_mesh(const TriMesh& m) {
  using Point = typename M::Point;
  M out;
  out.reserve(static_cast<typename M::size_type>(m.vertices.size()),
              static_cast<typename M::size_type>(3 * m.triangles.size() / 2),
              static_cast<typename M::size_type>(m.triangles.size()));
  for (const Vec3& p : m.vertices) out.add_vertex(Point(p.x(), p.y(), p.z()));
  for (const Tri& t : m.triangles)
    if (out.add_face(typename M::Vertex_index(t[0]), typename M::Vertex_index(t[1]),
                     typename M::Vertex_index(t[2])) == M::null_face())
      return std::nullopt;
  return out;
}

std::optional<Mesh> to_cgal(const TriMesh& m) { return to_surface_mesh<Mesh>(m); }

// The triangles of a CGAL surface mesh; `to_vec` turns its points into doubles.
template <typename M, typename ToVec>
TriMesh from_surface_mesh(const M& m, ToVec to_vec) {
  TriMesh out;
  std::map<typename M::Vertex_index, std::int32_t> index;
  for (typename M::Vertex_index v : m.vertices()) {
    index[v] = static_cast<std::int32_t>(out.vertices.size());
    out.vertices.push_back(to_vec(m.point(v)));
  }
  for (typename M::Face_index f : m.faces()) {
    Tri t{};
    int k = 0;
    for (typename M::Vertex_index v : CGAL::vertices_around_face(m.halfedge(f), m)) {
      if (k < 3) t[k] = index[v];
      ++k;
    }
    if (k == 3) out.triangles.push_back(t);
  }
  return out;
}

TriMesh from_cgal(const Mesh& m) {
  return from_surface_mesh(m, [](const K::Point_3& p) { return Vec3(p.x(), p.y(), p.z()); });
}

}  // namespace

TriMesh unweld_nonmanifold(const TriMesh& mesh) {
  if (to_cgal(mesh)) return mesh;
  std::vector<K::Point_3> points;
  for (const Vec3& p : mesh.vertices) points.emplace_back(p.x(), p.y(), p.z());
  std::vector<std::array<std::size_t, 3>> polygons;
  for (const Tri& t : mesh.triangles)
    polygons.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
  // Splits the vertices (and edges) where the surface touches itself; keeps orientation.
  PMP::orient_polygon_soup(points, polygons);
  TriMesh out;
  for (const K::Point_3& p : points) out.vertices.emplace_back(p.x(), p.y(), p.z());
  for (const auto& t : polygons)
    out.triangles.push_back({std::int32_t(t[0]), std::int32_t(t[1]), std::int32_t(t[2])});
  return out;
}

namespace {

void round_points(Mesh& m) {
  for (Mesh::Vertex_index v : m.vertices()) {
    const K::Point_3& p = m.point(v);
    m.point(v) = K::Point_3(to_float(p.x()), to_float(p.y()), to_float(p.z()));
  }
}

// Repairs each sliver of `faces` without moving any point off the float grid: a needle (a
// micron-short edge) is collapsed onto one of its end points; a cap (a vertex on or near the
// opposite edge) has that long edge flipped. Returns whether anything changed.
bool repair_slivers(Mesh& m, const std::set<Mesh::Face_index>& faces, double collapse_mm) {
  bool changed = false;
  for (Mesh::Face_index f : faces) {
    if (m.is_removed(f)) continue;
    std::vector<std::pair<double, Mesh::Halfedge_index>> edges;
    for (Mesh::Halfedge_index h : CGAL::halfedges_around_face(m.halfedge(f), m))
      edges.emplace_back(CGAL::squared_distance(m.point(m.source(h)), m.point(m.target(h))), h);
    std::sort(edges.begin(), edges.end());
    const auto [shortest2, hs] = edges.front();
    if (shortest2 <= collapse_mm * collapse_mm) {
      const Mesh::Edge_index e = m.edge(hs);
      if (CGAL::Euler::does_satisfy_link_condition(e, m)) {
        const K::Point_3 keep = m.point(m.target(hs));
        m.point(CGAL::Euler::collapse_edge(e, m)) = keep;
        changed = true;
        continue;
      }
    }
    // A cap (its apex within collapse_mm of the longest edge): flip that edge, unless the two
    // opposite vertices are already joined. The surface moves by at most the cap's height.
    const Mesh::Halfedge_index hl = edges.back().second;
    if (m.is_border(m.opposite(hl))) continue;
    const K::Point_3 &p = m.point(m.source(hl)), &q = m.point(m.target(hl)),
                     &apex = m.point(m.target(m.next(hl)));
    if (CGAL::squared_distance(apex, K::Line_3(p, q)) > collapse_mm * collapse_mm) continue;
    // The flipped edge must not fold over: the far vertex must see the new diagonal from the
    // cap's side (a convex quad).
    const K::Point_3& far = m.point(m.target(m.next(m.opposite(hl))));
    if (CGAL::collinear(apex, far, p) || CGAL::collinear(apex, far, q)) continue;
    // Only within a flat stretch: both new triangles must face like the neighbour they replace
    // (within about 8 degrees), else the flip would cut a corner of the surface.
    const K::Vector_3 n_old = CGAL::cross_product(p - far, q - far);
    const K::Vector_3 n1 = CGAL::cross_product(q - apex, far - apex),
                      n2 = CGAL::cross_product(far - apex, p - apex);
    auto aligned = [&](const K::Vector_3& n) {
      const double denom = std::sqrt(n.squared_length() * n_old.squared_length());
      return denom > 0 && n * n_old >= 0.99 * denom;
    };
    if (!aligned(n1) || !aligned(n2)) continue;
    const Mesh::Vertex_index a = m.target(m.next(hl)),
                             b = m.target(m.next(m.opposite(hl)));
    if (a == b || m.halfedge(a, b) != Mesh::null_halfedge()) continue;
    CGAL::Euler::flip_edge(hl, m);
    changed = true;
  }
  m.collect_garbage();
  return changed;
}

// Faces with an altitude below min_height_mm (exact test for zero: collinear corners).
std::set<Mesh::Face_index> thin_faces(const Mesh& m, double min_height_mm) {
  std::set<Mesh::Face_index> out;
  for (Mesh::Face_index f : m.faces()) {
    const Mesh::Halfedge_index h = m.halfedge(f);
    const K::Point_3 &a = m.point(m.source(h)), &b = m.point(m.target(h)),
                     &c = m.point(m.target(m.next(h)));
    if (CGAL::collinear(a, b, c)) {
      out.insert(f);
      continue;
    }
    const double longest2 = std::max({CGAL::squared_distance(a, b), CGAL::squared_distance(b, c),
                                      CGAL::squared_distance(c, a)});
    const double area2 = CGAL::squared_area(a, b, c);  // (area)^2
    // smallest altitude = 2 * area / longest edge
    if (4 * area2 < min_height_mm * min_height_mm * longest2) out.insert(f);
  }
  return out;
}

std::set<Mesh::Face_index> crossing_faces(const Mesh& m) {
  std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
  PMP::self_intersections(m, std::back_inserter(pairs));
  std::set<Mesh::Face_index> out;
  for (const auto& [f, g] : pairs) {
    out.insert(f);
    out.insert(g);
  }
  return out;
}

}  // namespace

namespace {
using EK = CGAL::Exact_predicates_exact_constructions_kernel;
using ExactMesh = CGAL::Surface_mesh<EK::Point_3>;

ExactMesh to_exact(const TriMesh& m, const std::string& what) {
  std::optional<ExactMesh> out = to_surface_mesh<ExactMesh>(m);
  if (!out) throw Error(ErrorCode::BooleanFailed, what + ": an operand is not a manifold surface");
  return std::move(*out);
}

TriMesh from_exact(const ExactMesh& m) {
  // From the exact value: the lazy approximation depends on what was evaluated before (and
  // on which thread), the exact value does not.
  return from_surface_mesh(m, [](const EK::Point_3& p) {
    return Vec3(CGAL::to_double(CGAL::exact(p.x())), CGAL::to_double(CGAL::exact(p.y())),
                CGAL::to_double(CGAL::exact(p.z())));
  });
}

// a := a op b, exactly; both are checked for self-intersections where they meet.
void exact_boolean(ExactMesh& a, ExactMesh b, BooleanOp op, const std::string& what) {
  ExactMesh out;
  bool ok = false;
  try {
    // Both operands: with exact constructions a result of an earlier step is as valid as its
    // operands were, so a report here is the part's own (or a touching contact it makes).
    const auto checked = CGAL::parameters::throw_on_self_intersection(true);
    ok = op == BooleanOp::Union ? PMP::corefine_and_compute_union(a, b, out, checked, checked)
                                : PMP::corefine_and_compute_difference(a, b, out, checked, checked);
  } catch (const PMP::Corefinement::Self_intersection_exception&) {
    throw Error(ErrorCode::BooleanFailed,
                what + ": an operand intersects or touches itself (the part, or where it meets "
                       "the parting surface)");
  }
  if (!ok) throw Error(ErrorCode::BooleanFailed, what + ": the boolean operation failed");
  a = std::move(out);
}

}  // namespace

TriMesh carve(const TriMesh& block, const std::vector<CarveStep>& steps) {
  ExactMesh m = to_exact(block, steps.empty() ? std::string("block") : steps.front().what);
  for (const CarveStep& s : steps) {
    if (s.mesh->triangles.empty()) continue;
    exact_boolean(m, to_exact(*s.mesh, s.what), s.op, s.what);
  }
  return from_exact(m);
}

std::string finish_solid(TriMesh& mesh) {
  std::optional<Mesh> m = to_cgal(mesh);
  if (!m) return "not a manifold surface";
  // Booleans leave needles and caps where the intersection curve passes near a vertex or edge.
  // Rounding to float moves a point by up to half a float step (< 1e-5 mm at 100 mm): a
  // triangle thinner than that could fold. So first every triangle is made at least
  // kMinHeight thick (collapsing micron edges, flipping caps), then rounded, then whatever
  // rounding still flattened or made cross is repaired the same way.
  constexpr double kMinHeight = 2e-4, kCollapse = 1e-3;
  for (int pass = 0; pass < 20; ++pass) {
    const std::set<Mesh::Face_index> thin = thin_faces(*m, kMinHeight);
    if (thin.empty() || !repair_slivers(*m, thin, kCollapse)) break;
  }
  round_points(*m);
  for (int pass = 0;; ++pass) {
    if (pass == 40) return "intersects itself after rounding to float";
    std::set<Mesh::Face_index> bad = thin_faces(*m, 0.0);
    if (bad.empty()) bad = crossing_faces(*m);
    if (bad.empty()) break;
    if (!repair_slivers(*m, bad, kCollapse))
      return "intersects itself beyond sliver repair (e.g. where the part touches itself and "
             "leaves the mold no thickness)";
  }
  PMP::duplicate_non_manifold_vertices(*m);
  if (!CGAL::is_closed(*m)) return "not closed";
  if (!PMP::is_outward_oriented(*m)) PMP::reverse_face_orientations(*m);
  mesh = from_cgal(*m);
  return {};
}

}  // namespace dhfcast::detail
