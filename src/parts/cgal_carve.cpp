// Exact booleans that mend a part's gaps: carving a convex hull out of it, or exchanging the
// material in a hull with a neighbour (see carve.h).
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Projection_traits_3.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/convex_hull_3.h>

#include <algorithm>
#include <array>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "carve.h"
#include "cgal_exact.h"
#include "dhfcast/mesh.h"

namespace dhfcast::detail {

namespace {
using namespace exact;

// A constrained Delaunay triangulation in the plane of a face, corners numbered.
using PlaneTraits = CGAL::Projection_traits_3<EK>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<
    PlaneTraits,
    CGAL::Triangulation_data_structure_2<
        CGAL::Triangulation_vertex_base_with_info_2<std::int32_t, PlaneTraits>,
        CGAL::Triangulation_face_base_with_info_2<
            int, PlaneTraits, CGAL::Constrained_triangulation_face_base_2<PlaneTraits>>>,
    CGAL::No_constraint_intersection_requiring_constructions_tag>;

// The pieces of one split face (`faces`, corners numbered by `index`) triangulated again from
// their corners and their outline alone, inserted in a fixed order: the same pieces whatever
// order the boolean made them in. False when that does not give as many triangles.
bool retriangulate(const ExactMesh& m, const std::vector<Face>& faces, const SplitMap& split,
                   const std::vector<std::int32_t>& index,
                   std::vector<std::array<std::int32_t, 3>>& out) {
  std::map<std::int32_t, ExactMesh::Vertex_index> corners;
  std::set<std::pair<std::int32_t, std::int32_t>> outline;
  const std::int32_t group = split[faces.front()];
  for (Face f : faces)
    for (auto h : CGAL::halfedges_around_face(m.halfedge(f), m)) {
      const std::int32_t a = index[m.source(h).idx()], b = index[m.target(h).idx()];
      corners.emplace(a, m.source(h));
      const Face across = m.face(m.opposite(h));
      if (across == ExactMesh::null_face() || split[across] != group)
        outline.insert(std::minmax(a, b));
    }
  const auto first = m.halfedge(faces.front());
  const EK::Vector_3 normal = CGAL::normal(m.point(m.source(first)), m.point(m.target(first)),
                                           m.point(m.target(m.next(first))));
  Cdt cdt{PlaneTraits(normal)};
  std::map<std::int32_t, Cdt::Vertex_handle> at;
  try {
    for (const auto& [i, v] : corners) {
      at[i] = cdt.insert(m.point(v));
      at[i]->info() = i;
    }
    for (const auto& [a, b] : outline) cdt.insert_constraint(at.at(a), at.at(b));
  } catch (const std::exception&) {
    return false;
  }
  if (cdt.number_of_vertices() != corners.size()) return false;
  // Inside: behind an odd number of outline edges from the infinite face.
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info() = -1;
  std::vector<std::pair<Cdt::Face_handle, int>> todo{{cdt.infinite_face(), 0}};
  while (!todo.empty()) {
    auto [f, level] = todo.back();
    todo.pop_back();
    if (f->info() != -1) continue;
    f->info() = level;
    for (int k = 0; k < 3; ++k) {
      const Cdt::Face_handle next = f->neighbor(k);
      if (next->info() == -1) todo.emplace_back(next, level + (cdt.is_constrained({f, k}) ? 1 : 0));
    }
  }
  const std::size_t before = out.size();
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (f->info() % 2 == 0) continue;
    std::array<std::int32_t, 3> t{f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()};
    const EK::Vector_3 n =
        CGAL::normal(f->vertex(0)->point(), f->vertex(1)->point(), f->vertex(2)->point());
    if (CGAL::is_negative(n * normal)) std::swap(t[1], t[2]);
    out.push_back(t);
  }
  return out.size() - before == faces.size();
}

// The mesh rebuilt in a canonical form that does not depend on the order in which the boolean
// that made it worked (CGAL orders some of its work by memory address, which differs from run
// to run): corners ordered by position, the pieces of each split face triangulated again from
// their corners and outline alone, faces ordered by corners, with their origins if they have
// them. False when that fails.
bool make_canonical(ExactMesh& m) {
  const auto [split, made_by_boolean] = m.property_map<Face, std::int32_t>("f:split");
  if (!made_by_boolean) return false;
  const auto [origin, has_origins] = m.property_map<Face, std::int32_t>("f:origin");
  std::vector<ExactMesh::Vertex_index> vertices(m.vertices().begin(), m.vertices().end());
  std::sort(vertices.begin(), vertices.end(), [&](auto a, auto b) {
    return CGAL::compare_xyz(m.point(a), m.point(b)) == CGAL::SMALLER;
  });
  std::vector<std::int32_t> index(m.num_vertices(), -1);
  for (std::size_t i = 0; i < vertices.size(); ++i)
    index[vertices[i].idx()] = static_cast<std::int32_t>(i);
  std::vector<std::pair<std::array<std::int32_t, 3>, std::int32_t>> faces;  // with their origin
  std::map<std::int32_t, std::vector<Face>> pieces;
  for (Face f : m.faces()) {
    if (split[f] >= 0) {
      pieces[split[f]].push_back(f);
      continue;
    }
    std::array<std::int32_t, 3> t{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(m.halfedge(f), m))
      if (k < 3) t[k++] = index[v.idx()];
    faces.emplace_back(t, has_origins ? origin[f] : 0);
  }
  for (const auto& [group, piece_faces] : pieces) {
    std::vector<std::array<std::int32_t, 3>> triangles;
    if (!retriangulate(m, piece_faces, split, index, triangles)) return false;
    for (const auto& t : triangles)
      faces.emplace_back(t, has_origins ? origin[piece_faces.front()] : 0);
  }
  for (auto& [t, o] : faces) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  std::sort(faces.begin(), faces.end());
  ExactMesh out;
  for (auto v : vertices) out.add_vertex(m.point(v));
  for (const auto& [t, o] : faces)
    if (out.add_face(ExactMesh::Vertex_index(t[0]), ExactMesh::Vertex_index(t[1]),
                     ExactMesh::Vertex_index(t[2])) == ExactMesh::null_face())
      return false;
  if (has_origins) {  // faces are numbered in the order added
    const OriginMap out_origin = origin_map(out, kCarvedVoid);
    for (std::size_t f = 0; f < faces.size(); ++f)
      out_origin[Face(static_cast<ExactMesh::size_type>(f))] = faces[f].second;
  }
  m = std::move(out);
  return true;
}

// boolean() with its result made canonical (make_canonical()).
bool canonical_boolean(Boolean op, ExactMesh& a, ExactMesh& b, ExactMesh& out,
                       std::int32_t fallback, Operands operands) {
  return boolean(op, a, b, out, fallback, operands) && make_canonical(out);
}

// The hull as tetrahedra fanned from one of its corners, with its bounding box.
struct Hull {
  ExactMesh mesh;
  std::vector<EK::Tetrahedron_3> tets;
  CGAL::Bbox_3 box;

  template <class Object>
  bool meets(const Object& object) const {
    if (!CGAL::do_overlap(object.bbox(), box)) return false;
    return std::any_of(tets.begin(), tets.end(),
                       [&](const EK::Tetrahedron_3& t) { return CGAL::do_intersect(object, t); });
  }
};

EK::Point_3 exact_point(const Vec3& p) { return EK::Point_3(p.x(), p.y(), p.z()); }

EK::Triangle_3 exact_triangle(const TriMesh& m, const Tri& t) {
  return EK::Triangle_3(exact_point(m.vertices[t[0]]), exact_point(m.vertices[t[1]]),
                        exact_point(m.vertices[t[2]]));
}

// Numbers the faces of a convex mesh by the facet (plane) they lie in, as "f:split".
void number_facets(ExactMesh& m) {
  const SplitMap facet = fresh_split_map(m);
  std::int32_t facets = 0;
  for (Face f : m.faces()) {
    if (facet[f] >= 0) continue;
    facet[f] = facets;
    for (std::vector<Face> todo{f}; !todo.empty();) {
      const Face g = todo.back();
      todo.pop_back();
      for (auto h : CGAL::halfedges_around_face(m.halfedge(g), m)) {
        const Face across = m.face(m.opposite(h));
        if (facet[across] < 0 &&
            CGAL::coplanar(m.point(m.source(h)), m.point(m.target(h)), m.point(m.target(m.next(h))),
                           m.point(m.target(m.next(m.opposite(h)))))) {
          facet[across] = facets;
          todo.push_back(across);
        }
      }
    }
    ++facets;
  }
}

bool make_hull(const std::vector<Vec3>& points, Hull& hull) {
  std::vector<EK::Point_3> exact;
  for (const Vec3& p : points) exact.push_back(exact_point(p));
  CGAL::convex_hull_3(exact.begin(), exact.end(), hull.mesh);
  if (hull.mesh.number_of_faces() < 4 || !CGAL::is_closed(hull.mesh)) return false;
  // How CGAL triangulates a facet with more than three corners can follow memory addresses:
  // each facet is triangulated again, as the pieces of one split face.
  number_facets(hull.mesh);
  if (!make_canonical(hull.mesh)) return false;
  const ExactMesh::Vertex_index apex = *hull.mesh.vertices().begin();
  for (ExactMesh::Vertex_index v : hull.mesh.vertices()) hull.box += hull.mesh.point(v).bbox();
  for (Face f : hull.mesh.faces()) {
    std::array<ExactMesh::Vertex_index, 3> c{};
    int k = 0;
    for (ExactMesh::Vertex_index v : CGAL::vertices_around_face(hull.mesh.halfedge(f), hull.mesh))
      if (k < 3) c[k++] = v;
    if (std::find(c.begin(), c.end(), apex) != c.end()) continue;
    hull.tets.emplace_back(hull.mesh.point(apex), hull.mesh.point(c[0]), hull.mesh.point(c[1]),
                           hull.mesh.point(c[2]));
  }
  return !hull.tets.empty();
}

// Whether every directed edge of the mesh has exactly one opposite, and how many pieces
// (triangles connected through edges) it has; with each triangle's piece (numbered in the order
// of their first triangles) when asked.
bool closed(const TriMesh& m, std::int32_t& pieces, std::vector<std::int32_t>* piece = nullptr) {
  std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> edges;  // directed -> triangle
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    for (int k = 0; k < 3; ++k)
      if (!edges
               .emplace(std::make_pair(m.triangles[t][k], m.triangles[t][(k + 1) % 3]),
                        static_cast<std::int32_t>(t))
               .second)
        return false;
  std::vector<std::int32_t> root(m.triangles.size());
  std::iota(root.begin(), root.end(), 0);
  auto find = [&](std::int32_t x) {
    while (root[x] != x) x = root[x] = root[root[x]];
    return x;
  };
  for (const auto& [e, t] : edges) {
    const auto opposite = edges.find({e.second, e.first});
    if (opposite == edges.end()) return false;
    root[find(t)] = find(opposite->second);
  }
  pieces = 0;
  std::vector<std::int32_t> number(root.size(), -1);
  for (std::size_t t = 0; t < root.size(); ++t) {
    std::int32_t& n = number[find(static_cast<std::int32_t>(t))];
    if (n < 0) n = pieces++;
    if (piece) piece->push_back(n);
  }
  return true;
}

// Orders triangles given by their corners.
struct CornersLess {
  bool operator()(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b) const {
    return std::lexicographical_compare(a.begin(), a.end(), b.begin(), b.end(), VecLess());
  }
};

// Appends triangles to a mesh, finding their corners by position.
struct MeshBuilder {
  TriMesh mesh;
  std::vector<std::int32_t> neighbor;
  std::map<Vec3, std::int32_t, VecLess> at;

  std::int32_t vertex(const Vec3& x) {
    const auto [it, added] = at.emplace(x, static_cast<std::int32_t>(mesh.vertices.size()));
    if (added) mesh.vertices.push_back(x);
    return it->second;
  }
  void add(const TriMesh& from, const Tri& t, bool reversed, std::int32_t n) {
    Tri tri{vertex(from.vertices[t[0]]), vertex(from.vertices[t[1]]), vertex(from.vertices[t[2]])};
    if (reversed) std::swap(tri[1], tri[2]);
    mesh.triangles.push_back(tri);
    neighbor.push_back(n);
  }
  // from's triangles that do not face part `skip`, as they are.
  void keep_except(const TriMesh& from, const std::vector<std::int32_t>& from_neighbor,
                   std::int32_t skip) {
    for (std::size_t t = 0; t < from.triangles.size(); ++t)
      if (from_neighbor[t] != skip) add(from, from.triangles[t], false, from_neighbor[t]);
  }
  // from's triangles that face part `q`, reversed, facing `n` instead.
  void take_facing(const TriMesh& from, const std::vector<std::int32_t>& from_neighbor,
                   std::int32_t q, std::int32_t n) {
    for (std::size_t t = 0; t < from.triangles.size(); ++t)
      if (from_neighbor[t] == q) add(from, from.triangles[t], true, n);
  }
};

// A triangle's corners from its smallest, reversed when asked.
std::array<Vec3, 3> corners_of(const TriMesh& m, const Tri& t, bool reversed) {
  std::array<Vec3, 3> c{m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]};
  if (reversed) std::swap(c[1], c[2]);
  std::rotate(c.begin(), std::min_element(c.begin(), c.end(), VecLess()), c.end());
  return c;
}

// The triangles of a mesh that face part n, as corner positions from the smallest corner,
// reversed when asked.
std::multiset<std::array<Vec3, 3>, CornersLess> facing(const TriMesh& m,
                                                       const std::vector<std::int32_t>& neighbor,
                                                       std::int32_t n, bool reversed) {
  std::multiset<std::array<Vec3, 3>, CornersLess> out;
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    if (neighbor[t] == n) out.insert(corners_of(m, m.triangles[t], reversed));
  return out;
}

// A part's mesh with the part across each triangle.
struct Sided {
  TriMesh mesh;
  std::vector<std::int32_t> neighbor;
};

// Where an exchange cut part a into pieces, a's pieces but its largest go to part b when they
// share an interface with it: b loses its triangles there and takes the piece's others, and a
// third part across the piece then faces b (in `third`, a copy of it). False when a piece
// meets no b or bounds a cavity, or a part is not closed.
bool hand_over_pieces(const std::vector<Part>& parts, std::int32_t a_id, Sided& a,
                      std::int32_t b_id, Sided& b, std::map<std::int32_t, Part>& third) {
  std::int32_t count = 0;
  std::vector<std::int32_t> piece;
  if (!closed(a.mesh, count, &piece)) return false;
  if (count == 1) return true;
  std::vector<double> volume(count, 0.0);
  for (std::size_t t = 0; t < a.mesh.triangles.size(); ++t) {
    const Tri& tri = a.mesh.triangles[t];
    volume[piece[t]] +=
        a.mesh.vertices[tri[0]].dot(a.mesh.vertices[tri[1]].cross(a.mesh.vertices[tri[2]]));
  }
  const std::int32_t largest =
      static_cast<std::int32_t>(std::max_element(volume.begin(), volume.end()) - volume.begin());
  std::vector<char> meets_b(count, 0);
  for (std::size_t t = 0; t < a.mesh.triangles.size(); ++t)
    if (a.neighbor[t] == b_id) meets_b[piece[t]] = 1;
  for (std::int32_t k = 0; k < count; ++k)
    if (k != largest && (!meets_b[k] || volume[k] <= 0.0)) return false;
  // The handed pieces' triangles facing b (as b has them), and those facing a third part (as
  // it has them).
  std::set<std::array<Vec3, 3>, CornersLess> shared;
  std::map<std::int32_t, std::set<std::array<Vec3, 3>, CornersLess>> across;
  MeshBuilder kept, grown;
  for (std::size_t t = 0; t < a.mesh.triangles.size(); ++t) {
    const Tri& tri = a.mesh.triangles[t];
    const std::int32_t n = a.neighbor[t];
    if (piece[t] == largest) {
      kept.add(a.mesh, tri, false, n);
      continue;
    }
    if (n == b_id) {
      shared.insert(corners_of(a.mesh, tri, true));
      continue;
    }
    grown.add(a.mesh, tri, false, n);
    if (n >= 0) across[n].insert(corners_of(a.mesh, tri, true));
  }
  for (std::size_t t = 0; t < b.mesh.triangles.size(); ++t)
    if (b.neighbor[t] != a_id || !shared.contains(corners_of(b.mesh, b.mesh.triangles[t], false)))
      grown.add(b.mesh, b.mesh.triangles[t], false, b.neighbor[t]);
  for (const auto& [k, faces] : across) {
    Part& other = third.try_emplace(k, parts[k]).first->second;
    std::size_t found = 0;
    for (std::size_t t = 0; t < other.mesh.triangles.size(); ++t)
      if (other.triangle_neighbor[t] == a_id &&
          faces.contains(corners_of(other.mesh, other.mesh.triangles[t], false))) {
        other.triangle_neighbor[t] = b_id;
        ++found;
      }
    if (found != faces.size()) return false;  // the part across triangulates it otherwise
  }
  a = {std::move(kept.mesh), std::move(kept.neighbor)};
  b = {std::move(grown.mesh), std::move(grown.neighbor)};
  return true;
}

// Parts p and q once they exchanged material, from the booleans' results (face origins: the
// part across). The two results can triangulate their new interface differently (CGAL's
// choices); q then takes p's triangles there (reversed) in place of its own. Pieces cut off
// either part go to the other (hand_over_pieces()). Refused (the reason in `why`) when a part
// is empty, not closed once rounded, or falls apart all the same.
std::optional<CarvedHull> exchanged(const std::vector<Part>& parts, std::int32_t p, std::int32_t q,
                                    ExactMesh& p_result, ExactMesh& q_result, std::string& why) {
  auto [p_mesh, p_neighbor] = canonical(p_result, q);
  auto [q_own, q_own_neighbor] = canonical(q_result, p);
  MeshBuilder b;
  if (facing(p_mesh, p_neighbor, q, false) == facing(q_own, q_own_neighbor, p, true)) {
    b.mesh = std::move(q_own);
    b.neighbor = std::move(q_own_neighbor);
  } else {
    b.keep_except(q_own, q_own_neighbor, p);
    b.take_facing(p_mesh, p_neighbor, q, p);
  }
  std::int32_t p_pieces = 0, q_pieces = 0;
  if (p_mesh.triangles.empty() || b.mesh.triangles.empty() || !closed(p_mesh, p_pieces) ||
      !closed(b.mesh, q_pieces)) {
    why = "a part is empty or not closed once rounded";
    return std::nullopt;
  }
  Sided p_side{std::move(p_mesh), std::move(p_neighbor)},
      q_side{std::move(b.mesh), std::move(b.neighbor)};
  std::map<std::int32_t, Part> third;
  if (!hand_over_pieces(parts, p, p_side, q, q_side, third) ||
      !hand_over_pieces(parts, q, q_side, p, p_side, third) || !closed(p_side.mesh, p_pieces) ||
      !closed(q_side.mesh, q_pieces) || p_pieces != 1 || q_pieces != 1) {
    why = "a part would fall apart";
    return std::nullopt;
  }
  CarvedHull out;
  for (auto [k, side] : {std::pair{p, &p_side}, std::pair{q, &q_side}}) {
    Part changed = parts[k];
    changed.mesh = std::move(side->mesh);
    changed.triangle_neighbor = std::move(side->neighbor);
    changed.volume_mm3 = signed_volume(changed.mesh);
    out.changed.emplace_back(k, std::move(changed));
  }
  for (auto& [k, part] : third) out.changed.emplace_back(k, std::move(part));
  return out;
}

// Part k as an exact mesh whose faces carry the part across them ("f:origin").
std::optional<ExactMesh> exact_part(const Part& part) {
  std::optional<ExactMesh> m = to_exact(part.mesh);
  if (!m) return std::nullopt;
  const OriginMap origin = origin_map(*m, kCarvedVoid);
  for (Face f : m->faces()) origin[f] = part.triangle_neighbor[f.idx()];
  return m;
}

// The hull of `points` for parts p and q to exchange material in; false (the reason in `why`)
// when it is flat, or meets a third part or a carved void, or (with outer) the outer surface.
bool exchange_hull(const std::vector<Part>& parts, std::int32_t p, std::int32_t q,
                   const std::vector<Vec3>& points, bool outer, Hull& hull, std::string& why) {
  if (!make_hull(points, hull)) {
    why = "its hull is flat";
    return false;
  }
  for (std::int32_t k = 0; k < static_cast<std::int32_t>(parts.size()); ++k) {
    const Part& part = parts[k];
    for (std::size_t t = 0; t < part.mesh.triangles.size(); ++t) {
      const std::int32_t n = part.triangle_neighbor[t];
      const bool ours = k == p || k == q;
      if (ours && (n >= 0 || (n == -1 && !outer))) continue;
      if (hull.meets(exact_triangle(part.mesh, part.mesh.triangles[t]))) {
        why = !ours     ? "its hull would reach part " + std::to_string(k)
              : n == -1 ? kHullReachesOuterSurface
                        : "its hull would reach a carved void";
        return false;
      }
    }
  }
  return true;
}

}  // namespace

std::optional<CarvedHull> carve_hull(const std::vector<Part>& parts, std::int32_t p,
                                     const std::vector<Vec3>& points, bool checked,
                                     std::string& why) {
  const Part& part = parts[p];
  const TriMesh& m = part.mesh;
  Hull hull;
  if (!make_hull(points, hull)) {
    why = "its hull is flat";
    return std::nullopt;
  }
  // The outer surface stays as it is, and so do the curves where p meets two other parts (the
  // neighbours' triangles there would need new corners on the curve).
  std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> edge_neighbor;
  std::set<std::pair<std::int32_t, std::int32_t>> junctions;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const std::int32_t n = part.triangle_neighbor[t];
    if (n < 0 && hull.meets(exact_triangle(m, m.triangles[t]))) {
      why = "its hull would cut the part's outer surface";
      return std::nullopt;
    }
    for (int k = 0; k < 3; ++k) {
      const std::pair e = std::minmax(m.triangles[t][k], m.triangles[t][(k + 1) % 3]);
      const auto [it, added] = edge_neighbor.emplace(e, n);
      if (!added && it->second != n) junctions.insert(e);
    }
  }
  for (const auto& [a, b] : junctions)
    if (hull.meets(EK::Segment_3(exact_point(m.vertices[a]), exact_point(m.vertices[b])))) {
      why = "its hull would cut a curve where the part meets two others";
      return std::nullopt;
    }

  std::optional<ExactMesh> whole = exact_part(part);
  if (!whole) {
    why = "the part is not a 2-manifold surface";
    return std::nullopt;
  }
  ExactMesh whole_copy = *whole, hull_copy = hull.mesh, rest, removed;
  const Operands operands = checked ? Operands::Known : Operands::Unchecked;
  if (!canonical_boolean(Boolean::Difference, *whole, hull.mesh, rest, kCarvedVoid, operands) ||
      !canonical_boolean(Boolean::Intersection, whole_copy, hull_copy, removed, kCarvedVoid,
                         operands)) {
    why = "CGAL rejects the cut";
    return std::nullopt;
  }
  auto [rest_mesh, rest_neighbor] = canonical(rest, kCarvedVoid);
  auto [hole_mesh, hole_neighbor] = canonical(removed, kCarvedVoid);
  std::int32_t pieces = 0, hole_pieces = 0;
  if (hole_mesh.triangles.empty() || rest_mesh.triangles.empty()) {
    why = "its hull holds none of the part, or all of it";
    return std::nullopt;
  }
  if (!closed(rest_mesh, pieces) || !closed(hole_mesh, hole_pieces)) {
    why = "the cut is not closed once rounded";
    return std::nullopt;
  }
  if (pieces != 1) {
    why = "the part would fall apart";
    return std::nullopt;
  }

  CarvedHull out;
  Part carved = part;
  carved.mesh = std::move(rest_mesh);
  carved.triangle_neighbor = std::move(rest_neighbor);
  carved.volume_mm3 = signed_volume(carved.mesh);
  // Each neighbour across the material removed swaps its triangles facing p for p's new ones
  // (facing it) and the removed material's (facing the void).
  std::set<std::int32_t> neighbours;
  for (std::int32_t n : hole_neighbor)
    if (n >= 0) neighbours.insert(n);
  for (std::int32_t q : neighbours) {
    const Part& other = parts[q];
    MeshBuilder b;
    b.keep_except(other.mesh, other.triangle_neighbor, p);
    b.take_facing(carved.mesh, carved.triangle_neighbor, q, p);
    b.take_facing(hole_mesh, hole_neighbor, q, kCarvedVoid);
    std::int32_t q_pieces = 0;
    if (!closed(b.mesh, q_pieces)) {
      why = "part " + std::to_string(q) + " across it would not be closed";
      return std::nullopt;
    }
    Part changed = other;
    changed.mesh = std::move(b.mesh);
    changed.triangle_neighbor = std::move(b.neighbor);
    changed.volume_mm3 = signed_volume(changed.mesh);
    out.changed.emplace_back(q, std::move(changed));
  }
  out.changed.insert(out.changed.begin(), {p, std::move(carved)});
  out.hole.part = p;
  out.hole.volume_mm3 = signed_volume(hole_mesh);
  out.hole.mesh = std::move(hole_mesh);
  return out;
}

std::optional<CarvedHull> fill_hull(const std::vector<Part>& parts, std::int32_t p, std::int32_t q,
                                    const std::vector<Vec3>& points, bool checked,
                                    std::string& why) {
  Hull hull;
  // The hull must lie inside p and q, away from the outer surface.
  if (!exchange_hull(parts, p, q, points, true, hull, why)) return std::nullopt;
  std::optional<ExactMesh> a = exact_part(parts[p]), b = exact_part(parts[q]);
  if (!a || !b) {
    why = "a part is not a 2-manifold surface";
    return std::nullopt;
  }
  ExactMesh hull_for_p = hull.mesh, hull_for_q = hull.mesh, grown, shrunk;
  const Operands operands = checked ? Operands::Known : Operands::Unchecked;
  origin_map(hull_for_p, q);  // the hull's faces that p gains face q, and the other way
  origin_map(hull_for_q, p);
  if (!canonical_boolean(Boolean::Union, *a, hull_for_p, grown, q, operands) ||
      !canonical_boolean(Boolean::Difference, *b, hull_for_q, shrunk, p, operands)) {
    why = "CGAL rejects the fill";
    return std::nullopt;
  }
  return exchanged(parts, p, q, grown, shrunk, why);
}

std::optional<CarvedHull> yield_hull(const std::vector<Part>& parts, std::int32_t p, std::int32_t q,
                                     const std::vector<Vec3>& points, bool checked,
                                     std::string& why) {
  Hull hull;
  // q takes p's faces inside the hull: their neighbours must be q or the outside.
  if (!exchange_hull(parts, p, q, points, false, hull, why)) return std::nullopt;
  std::optional<ExactMesh> a = exact_part(parts[p]), a_copy = exact_part(parts[p]),
                           b = exact_part(parts[q]);
  if (!a || !b) {
    why = "a part is not a 2-manifold surface";
    return std::nullopt;
  }
  ExactMesh hull_for_p = hull.mesh, hull_for_piece = hull.mesh, kept, piece, grown;
  const Operands operands = checked ? Operands::Known : Operands::Unchecked;
  origin_map(hull_for_p, q);  // p's new faces face q, the piece's face p
  origin_map(hull_for_piece, p);
  if (!canonical_boolean(Boolean::Difference, *a, hull_for_p, kept, q, operands) ||
      !canonical_boolean(Boolean::Intersection, *a_copy, hull_for_piece, piece, p, operands) ||
      !canonical_boolean(Boolean::Union, *b, piece, grown, p, operands)) {
    why = "CGAL rejects the exchange";
    return std::nullopt;
  }
  return exchanged(parts, p, q, kept, grown, why);
}

}  // namespace dhfcast::detail
