// Mesh booleans (CGAL corefinement, exact predicates) and the clean-up that makes a result
// exactly what its float STL will hold. One of the two files of the mold stage that include
// CGAL.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/manifoldness.h>
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
std::optional<Mesh> to_cgal(const TriMesh& m) {
  Mesh out;
  out.reserve(static_cast<Mesh::size_type>(m.vertices.size()),
              static_cast<Mesh::size_type>(3 * m.triangles.size() / 2),
              static_cast<Mesh::size_type>(m.triangles.size()));
  for (const Vec3& p : m.vertices) out.add_vertex(K::Point_3(p.x(), p.y(), p.z()));
  for (const Tri& t : m.triangles)
    if (out.add_face(Mesh::Vertex_index(t[0]), Mesh::Vertex_index(t[1]),
                     Mesh::Vertex_index(t[2])) == Mesh::null_face())
      return std::nullopt;
  return out;
}

TriMesh from_cgal(const Mesh& m) {
  TriMesh out;
  std::map<Mesh::Vertex_index, std::int32_t> index;
  for (Mesh::Vertex_index v : m.vertices()) {
    index[v] = static_cast<std::int32_t>(out.vertices.size());
    const K::Point_3& p = m.point(v);
    out.vertices.emplace_back(p.x(), p.y(), p.z());
  }
  for (Mesh::Face_index f : m.faces()) {
    Tri t{};
    int k = 0;
    for (Mesh::Vertex_index v : CGAL::vertices_around_face(m.halfedge(f), m)) {
      if (k < 3) t[k] = index[v];
      ++k;
    }
    if (k == 3) out.triangles.push_back(t);
  }
  return out;
}

}  // namespace

TriMesh mesh_boolean(const TriMesh& a, const TriMesh& b, BooleanOp op, const std::string& what) {
  std::optional<Mesh> ma = to_cgal(a), mb = to_cgal(b);
  if (!ma || !mb)
    throw Error(ErrorCode::BooleanFailed, what + ": an operand is not a manifold surface");
  Mesh out;
  const bool ok = op == BooleanOp::Union ? PMP::corefine_and_compute_union(*ma, *mb, out)
                                         : PMP::corefine_and_compute_difference(*ma, *mb, out);
  if (!ok) throw Error(ErrorCode::BooleanFailed, what + ": the boolean operation failed");
  return from_cgal(out);
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
    const Mesh::Vertex_index a = m.target(m.next(hl)),
                             b = m.target(m.next(m.opposite(hl)));
    if (a == b || m.halfedge(a, b) != Mesh::null_halfedge()) continue;
    CGAL::Euler::flip_edge(hl, m);
    changed = true;
  }
  m.collect_garbage();
  return changed;
}

std::set<Mesh::Face_index> degenerate_faces(const Mesh& m) {
  std::set<Mesh::Face_index> out;
  for (Mesh::Face_index f : m.faces()) {
    const Mesh::Halfedge_index h = m.halfedge(f);
    if (CGAL::collinear(m.point(m.source(h)), m.point(m.target(h)),
                        m.point(m.target(m.next(h)))))
      out.insert(f);
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

std::string finish_solid(TriMesh& mesh) {
  std::optional<Mesh> m = to_cgal(mesh);
  if (!m) return "not a manifold surface";
  // Booleans leave needles and caps where the intersection curve passes near a vertex; micron
  // edges go before rounding, so rounding has fewer slivers to fold.
  PMP::experimental::remove_almost_degenerate_faces(*m, std::cos(179.0 / 180.0 * M_PI), 100.0,
                                                    1e-3);
  m->collect_garbage();
  // Rounding flattens or folds the thinnest slivers: collapse them (keeping points on the float
  // grid) until none is left.
  round_points(*m);
  for (int pass = 0;; ++pass) {
    if (pass == 40) return "intersects itself after rounding to float";
    std::set<Mesh::Face_index> bad = degenerate_faces(*m);
    if (bad.empty()) bad = crossing_faces(*m);
    if (bad.empty()) break;
    if (!repair_slivers(*m, bad, 1e-3)) return "has slivers that cannot be repaired";
  }
  PMP::duplicate_non_manifold_vertices(*m);
  if (!CGAL::is_closed(*m)) return "not closed";
  if (!PMP::is_outward_oriented(*m)) PMP::reverse_face_orientations(*m);
  mesh = from_cgal(*m);
  return {};
}

}  // namespace dhfcast::detail
