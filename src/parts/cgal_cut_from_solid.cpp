// Cuts the parts from the exact input solid, so their outer surfaces are the input surface and
// not the tet mesh's approximation of it.
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/convex_hull_3.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "cgal_exact.h"
#include "dhfcast/mesh.h"
#include "dhfcast/parts.h"

namespace dhfcast {

namespace {
using namespace exact;
// Where a face of a cut part comes from: kFromSolid for the input surface, else the part
// across the region's face it is a piece of (below kFromSolid for a moved-out outer face).
constexpr std::int32_t kFromSolid = -2;

using PointMap = std::map<Vec3, Vec3, VecLess>;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Triangles = std::vector<K::Triangle_3>;
using Tree = CGAL::AABB_tree<
    CGAL::AABB_traits<K, CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>>>;
K::Point_3 point(const Vec3& v) { return K::Point_3(v.x(), v.y(), v.z()); }
using LengthMap = std::map<Vec3, double, VecLess>;

// The parts' outer triangles (triangle_neighbor < 0), each once, with their corner positions.
std::vector<std::array<Vec3, 3>> outer_triangles(const std::vector<Part>& parts) {
  std::vector<std::array<Vec3, 3>> out;
  for (const Part& part : parts)
    for (std::size_t t = 0; t < part.mesh.triangles.size(); ++t)
      if (part.triangle_neighbor[t] < 0) {
        const Tri& tri = part.mesh.triangles[t];
        out.push_back(
            {part.mesh.vertices[tri[0]], part.mesh.vertices[tri[1]], part.mesh.vertices[tri[2]]});
      }
  return out;
}

// How far the input surface sticks out of the parts' outer surface near each of its vertices:
// every sample of the input (vertices and edge midpoints) charges its distance to the corners
// of the outer triangle nearest to it, and then to their neighbours.
LengthMap local_reach(const TriMesh& solid, const std::vector<std::array<Vec3, 3>>& outer) {
  Triangles triangles;
  for (const auto& t : outer) triangles.emplace_back(point(t[0]), point(t[1]), point(t[2]));
  LengthMap reach;
  if (triangles.empty()) return reach;
  Tree tree(triangles.begin(), triangles.end());
  tree.accelerate_distance_queries();
  // Samples a quarter of an outer edge apart (at most 64 a side, at least its corners and
  // edge midpoints), so that large input triangles over small tets are not missed.
  double edges = 0.0;
  for (const auto& t : outer)
    edges += (t[1] - t[0]).norm() + (t[2] - t[1]).norm() + (t[0] - t[2]).norm();
  const double spacing = 0.25 * edges / (3.0 * static_cast<double>(outer.size()));
  std::vector<Vec3> samples;
  for (const Tri& t : solid.triangles) {
    const Vec3 &a = solid.vertices[t[0]], &b = solid.vertices[t[1]], &c = solid.vertices[t[2]];
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    const int k = std::clamp(static_cast<int>(std::ceil(longest / spacing)), 2, 64);
    for (int i = 0; i <= k; ++i)
      for (int j = 0; i + j <= k; ++j) samples.push_back((i * a + j * b + (k - i - j) * c) / k);
  }
  std::vector<std::pair<double, std::size_t>> nearest(samples.size());
  tbb::parallel_for(std::size_t{0}, samples.size(), [&](std::size_t i) {
    const auto [p, id] = tree.closest_point_and_primitive(point(samples[i]));
    nearest[i] = {std::sqrt(CGAL::squared_distance(p, point(samples[i]))),
                  static_cast<std::size_t>(id - triangles.cbegin())};
  });
  std::vector<double> triangle_reach(outer.size(), 0.0);
  for (const auto& [d, t] : nearest) triangle_reach[t] = std::max(triangle_reach[t], d);
  for (std::size_t t = 0; t < outer.size(); ++t)
    for (const Vec3& p : outer[t]) reach[p] = std::max(reach[p], triangle_reach[t]);
  // Once more over the neighbours: a triangle moves out no further than its lowest corner.
  LengthMap spread = reach;
  for (const auto& t : outer) {
    double m = 0.0;
    for (const Vec3& p : t) m = std::max(m, reach.at(p));
    for (const Vec3& p : t) spread[p] = std::max(spread[p], m);
  }
  return spread;
}

// The input surface's normal at the point nearest to each outer vertex, interpolated from its
// vertex normals: a smooth direction field even where the tet mesh's boundary is creased.
PointMap input_normals(const TriMesh& solid, const Triangles& triangles, const Tree& tree,
                       const std::vector<std::array<Vec3, 3>>& outer) {
  std::vector<Vec3> vertex_normal(solid.vertices.size(), Vec3::Zero());
  for (const Tri& t : solid.triangles) {
    const Vec3 &a = solid.vertices[t[0]], &b = solid.vertices[t[1]], &c = solid.vertices[t[2]];
    const Vec3 n = (b - a).cross(c - a);  // area-weighted
    for (std::int32_t v : t) vertex_normal[v] += n;
  }
  for (Vec3& n : vertex_normal) n.normalize();
  std::vector<Vec3> corners;
  for (const auto& t : outer) corners.insert(corners.end(), t.begin(), t.end());
  std::sort(corners.begin(), corners.end(), VecLess());
  corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
  std::vector<Vec3> normal(corners.size());
  tbb::parallel_for(std::size_t{0}, corners.size(), [&](std::size_t i) {
    const auto [q, id] = tree.closest_point_and_primitive(point(corners[i]));
    const Tri& t = solid.triangles[id - triangles.cbegin()];
    const Vec3 &a = solid.vertices[t[0]], &b = solid.vertices[t[1]], &c = solid.vertices[t[2]];
    const Vec3 p(q.x(), q.y(), q.z());
    const Vec3 n = (b - a).cross(c - a);
    const double area = n.squaredNorm();
    Vec3 sum = Vec3::Zero();
    if (area > 0.0) {  // barycentric weights of p
      sum += (c - b).cross(p - b).dot(n) / area * vertex_normal[t[0]];
      sum += (a - c).cross(p - c).dot(n) / area * vertex_normal[t[1]];
      sum += (b - a).cross(p - a).dot(n) / area * vertex_normal[t[2]];
    }
    normal[i] = sum.norm() > 1e-9 ? sum.normalized() : n.normalized();
  });
  PointMap out;
  for (std::size_t i = 0; i < corners.size(); ++i) out.emplace(corners[i], normal[i]);
  return out;
}

// Where a part touches itself at a vertex (one position, several vertices), each copy moves a
// hair into its own fan, as CGAL takes touching for crossing. The neighbours keep the vertex
// where it was: the parts leave a hair-wide gap there.
void separate_pinches(TriMesh& m, double hair) {
  std::map<Vec3, std::vector<std::int32_t>, VecLess> at;
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    at[m.vertices[v]].push_back(static_cast<std::int32_t>(v));
  std::vector<Vec3> toward(m.vertices.size(), Vec3::Zero());  // to its fan's other corners
  for (const Tri& t : m.triangles)
    for (int k = 0; k < 3; ++k)
      toward[t[k]] +=
          m.vertices[t[(k + 1) % 3]] + m.vertices[t[(k + 2) % 3]] - 2 * m.vertices[t[k]];
  for (const auto& [p, copies] : at)
    if (copies.size() > 1)
      for (std::int32_t v : copies)
        if (toward[v].norm() > 0.0) m.vertices[v] = p + hair * toward[v].normalized();
}

// Directed outer edges (by their ends' positions) and the part whose outer triangle has them.
using EdgeKey = std::array<double, 6>;
EdgeKey edge_key(const Vec3& a, const Vec3& b) {
  return {a.x(), a.y(), a.z(), b.x(), b.y(), b.z()};
}
using EdgeOwners = std::map<EdgeKey, std::int32_t>;
EdgeOwners outer_edge_owners(const std::vector<Part>& parts) {
  EdgeOwners owner;
  for (std::size_t i = 0; i < parts.size(); ++i)
    for (std::size_t t = 0; t < parts[i].mesh.triangles.size(); ++t)
      if (parts[i].triangle_neighbor[t] < 0)
        for (int k = 0; k < 3; ++k)
          owner[edge_key(parts[i].mesh.vertices[parts[i].mesh.triangles[t][k]],
                         parts[i].mesh.vertices[parts[i].mesh.triangles[t][(k + 1) % 3]])] =
              static_cast<std::int32_t>(i);
  return owner;
}

// Seam vertices (outer vertices that interfaces reach too) and how far each moves into the
// solid: a thousandth of its outer edges' mean length, so that the input surface, which passes
// through the vertex, crosses the walls there cleanly instead of grazing a corner. Left out
// where a part's triangles around the vertex change between outer and interface more than
// twice: one wall edge could not join them. Left out too at the ends of an outer edge that no
// outer edge runs back along (a part touching itself along it, one sheet split at the edge's
// midpoint): no part would take a wall there.
LengthMap seam_insets(const std::vector<Part>& parts, const std::vector<std::array<Vec3, 3>>& outer,
                      const EdgeOwners& owner) {
  std::map<Vec3, std::pair<double, int>, VecLess> edges;  // outer edge lengths at each vertex
  for (const auto& t : outer)
    for (int k = 0; k < 3; ++k) {
      const double l = (t[(k + 1) % 3] - t[k]).norm();
      for (const Vec3& p : {t[k], t[(k + 1) % 3]}) {
        edges[p].first += l;
        ++edges[p].second;
      }
    }
  LengthMap inset;
  std::set<Vec3, VecLess> excluded;
  for (const Part& part : parts) {
    const TriMesh& m = part.mesh;
    std::map<std::pair<std::int32_t, std::int32_t>, bool>
        is_outer;  // directed edge -> its triangle
    for (std::size_t t = 0; t < m.triangles.size(); ++t)
      for (int k = 0; k < 3; ++k)
        is_outer[{m.triangles[t][k], m.triangles[t][(k + 1) % 3]}] = part.triangle_neighbor[t] < 0;
    std::vector<int> seam_edges(m.vertices.size(), 0);
    for (const auto& [e, outer_side] : is_outer)
      if (outer_side && !is_outer.at({e.second, e.first})) {
        ++seam_edges[e.first];
        ++seam_edges[e.second];
      }
    for (std::size_t t = 0; t < m.triangles.size(); ++t)
      if (part.triangle_neighbor[t] >= 0)
        for (std::int32_t v : m.triangles[t])
          if (const auto it = edges.find(m.vertices[v]); it != edges.end())
            inset[m.vertices[v]] = 1e-3 * it->second.first / it->second.second;
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
      if (seam_edges[v] > 2) excluded.insert(m.vertices[v]);
  }
  for (const auto& [key, part] : owner)
    if (const Vec3 a(key[0], key[1], key[2]), b(key[3], key[4], key[5]);
        !owner.contains(edge_key(b, a))) {
      excluded.insert(a);
      excluded.insert(b);
    }
  for (const Vec3& p : excluded) inset.erase(p);
  return inset;
}

// A part's region, moved out, with the part on the other side of each face (-1: outer) and
// the position each vertex came from.
struct Region {
  TriMesh mesh;
  std::vector<std::int32_t> neighbor;
  std::vector<Vec3> source;
};

// The part's region with its outer vertices moved out along `dirs` by `push`. A seam vertex
// (in `inset`) splits: its outer triangles take the moved copy, its interface triangles a copy
// moved `inset` into the solid, and a wall between the two copies along each seam edge extends
// the interface outward. So interfaces barely move and a thin fin's outer side cannot fold
// through them.
Region moved_region(const Part& part, const PointMap& dirs, const LengthMap& push,
                    const LengthMap& inset, const EdgeOwners& owner) {
  const TriMesh& m = part.mesh;
  Region r;
  std::vector<std::int32_t> out(m.vertices.size());  // the copy outer triangles use
  for (std::size_t v = 0; v < m.vertices.size(); ++v) {
    const Vec3& p = m.vertices[v];
    out[v] = static_cast<std::int32_t>(v);
    r.source.push_back(p);
    const auto d = dirs.find(p);
    if (d == dirs.end()) {
      r.mesh.vertices.push_back(p);
      continue;
    }
    const Vec3 moved = p + push.at(p) * d->second;
    const auto in = inset.find(p);
    r.mesh.vertices.push_back(in == inset.end() ? moved : p - in->second * d->second);
    if (in != inset.end()) out[v] = -1;
  }
  // The moved copies of split vertices follow the others, in vertex order.
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    if (out[v] < 0) {
      out[v] = static_cast<std::int32_t>(r.mesh.vertices.size());
      r.mesh.vertices.push_back(m.vertices[v] + push.at(m.vertices[v]) * dirs.at(m.vertices[v]));
      r.source.push_back(m.vertices[v]);
    }
  std::set<std::pair<std::int32_t, std::int32_t>> across;  // directed edges of interfaces
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    if (part.triangle_neighbor[t] >= 0)
      for (int k = 0; k < 3; ++k) across.insert({m.triangles[t][k], m.triangles[t][(k + 1) % 3]});
  auto add = [&](std::int32_t a, std::int32_t b, std::int32_t c, std::int32_t neighbor) {
    if (a == b || b == c || c == a) return;  // a wall beside a vertex that did not split
    r.mesh.triangles.push_back({a, b, c});
    r.neighbor.push_back(neighbor);
  };
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Tri& tri = m.triangles[t];
    if (part.triangle_neighbor[t] >= 0) {
      add(tri[0], tri[1], tri[2], part.triangle_neighbor[t]);
      continue;
    }
    add(out[tri[0]], out[tri[1]], out[tri[2]], -1);
    for (int k = 0; k < 3; ++k) {
      const std::int32_t a = tri[k], b = tri[(k + 1) % 3];
      if (!across.contains({b, a}) || (out[a] == a && out[b] == b)) continue;  // no wall
      // The part across the seam on the surface: not always the one across the interface.
      const std::int32_t x = owner.at(edge_key(m.vertices[b], m.vertices[a]));
      // The wall a, b, b', a': split along the same diagonal in both parts it bounds.
      if (VecLess()(m.vertices[a], m.vertices[b])) {
        add(a, b, out[b], x);
        add(a, out[b], out[a], x);
      } else {
        add(a, b, out[a], x);
        add(b, out[b], out[a], x);
      }
    }
  }
  // A split vertex that only outer triangles use here keeps no copy inside.
  std::vector<std::int32_t> index(r.mesh.vertices.size(), -1);
  for (const Tri& t : r.mesh.triangles)
    for (std::int32_t v : t) index[v] = 0;
  Region kept;
  for (std::size_t v = 0; v < index.size(); ++v)
    if (index[v] == 0) {
      index[v] = static_cast<std::int32_t>(kept.mesh.vertices.size());
      kept.mesh.vertices.push_back(r.mesh.vertices[v]);
      kept.source.push_back(r.source[v]);
    }
  for (const Tri& t : r.mesh.triangles)
    kept.mesh.triangles.push_back({index[t[0]], index[t[1]], index[t[2]]});
  kept.neighbor = std::move(r.neighbor);
  return kept;
}

// The origin of the region's outer face t, below kFromSolid, and back.
std::int32_t outer_face_origin(std::int32_t t) { return kFromSolid - 1 - t; }
std::int32_t outer_face_of(std::int32_t origin) { return kFromSolid - 1 - origin; }

// The origin of each region face for the cut: the part across it, or outer_face_origin(t) for an
// outer face t.
std::vector<std::int32_t> origins(const Region& r) {
  std::vector<std::int32_t> origin = r.neighbor;
  for (std::size_t t = 0; t < origin.size(); ++t)
    if (origin[t] < 0) origin[t] = outer_face_origin(static_cast<std::int32_t>(t));
  return origin;
}

// The region as an exact mesh whose faces carry their origin ("f:origin"); nullopt when it is
// not a 2-manifold surface.
std::optional<ExactMesh> exact_region(const TriMesh& region,
                                      const std::vector<std::int32_t>& origin) {
  std::optional<ExactMesh> m = to_exact(region);
  if (!m) return std::nullopt;
  const OriginMap o = origin_map(*m, kFromSolid);
  for (Face f : m->faces()) o[f] = origin[f.idx()];
  return m;
}

// solid ∩ region, with the origins of the result's faces; nullopt when CGAL cannot build it.
std::optional<std::pair<TriMesh, std::vector<std::int32_t>>> intersect(const TriMesh& solid,
                                                                       ExactMesh region,
                                                                       std::string& problem) {
  std::optional<ExactMesh> a = to_exact(solid);
  if (!a) {
    problem = "the input solid is not a 2-manifold surface";
    return std::nullopt;
  }
  ExactMesh out;
  // The input solid is valid; regions are cut only when intersecting_triangles() finds none.
  if (!boolean(Boolean::Intersection, *a, region, out, kFromSolid, Operands::Known)) {
    problem = "CGAL cannot cut its region, moved out past the input surface, from the input solid";
    return std::nullopt;
  }
  return canonical(out, kFromSolid);
}

using CutResult = std::pair<TriMesh, std::vector<std::int32_t>>;

// Which cut part holds a point: a part's point-in-solid test is built the first time it is asked.
class PartCover {
 public:
  explicit PartCover(const std::vector<std::optional<CutResult>>& results)
      : results_(results), side_(results.size()) {}
  // The part other than `self` that holds p inside, or -1.
  std::int32_t covering(std::size_t self, const Vec3& p) {
    for (std::size_t j = 0; j < results_.size(); ++j) {
      if (j == self || !results_[j] || results_[j]->first.triangles.empty()) continue;
      if (!side_[j]) {
        const TriMesh& m = results_[j]->first;
        side_[j] = std::make_unique<Side>();
        for (const Vec3& v : m.vertices) side_[j]->mesh.add_vertex(point(v));
        for (const Tri& t : m.triangles)
          side_[j]->mesh.add_face(InexactMesh::Vertex_index(t[0]), InexactMesh::Vertex_index(t[1]),
                                  InexactMesh::Vertex_index(t[2]));
        side_[j]->inside = std::make_unique<Inside>(side_[j]->mesh);
      }
      if ((*side_[j]->inside)(point(p)) == CGAL::ON_BOUNDED_SIDE)
        return static_cast<std::int32_t>(j);
    }
    return -1;
  }
  // Part j was cut again.
  void changed(std::size_t j) { side_[j].reset(); }

 private:
  using InexactMesh = CGAL::Surface_mesh<K::Point_3>;
  using Inside = CGAL::Side_of_triangle_mesh<InexactMesh, K>;
  struct Side {
    InexactMesh mesh;
    std::unique_ptr<Inside> inside;
  };
  const std::vector<std::optional<CutResult>>& results_;
  std::vector<std::unique_ptr<Side>> side_;
};

// The region's outer triangles whose pieces in the cut part lie deeper than `depth` inside the
// solid with no other part in front of them, in patches that share corners, each with how deep
// it goes. A piece that another part covers (it filled a dent there) becomes an interface with
// it. `hair`: how far in front of a piece the cover is looked for.
std::vector<std::pair<std::vector<std::int32_t>, double>> dents(std::size_t i, CutResult& cut,
                                                                const Region& region,
                                                                const Tree& surface, double depth,
                                                                double hair, PartCover& cover) {
  auto& [mesh, origin] = cut;
  std::map<std::int32_t, double> deep;  // region triangle -> depth
  for (std::size_t f = 0; f < origin.size(); ++f) {
    if (origin[f] >= kFromSolid) continue;
    const Tri& t = mesh.triangles[f];
    const Vec3 centre = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3.0;
    double d = 0.0;
    for (const Vec3& p : {mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]], centre})
      d = std::max(d, std::sqrt(surface.squared_distance(point(p))));
    if (d <= depth) continue;
    const Vec3 normal = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                            .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]])
                            .normalized();
    if (const std::int32_t j = cover.covering(i, centre + std::min(hair, 0.5 * d) * normal);
        j >= 0) {
      origin[f] = j;
    } else {
      double& slot = deep[outer_face_of(origin[f])];
      slot = std::max(slot, d);
    }
  }
  // Patches: triangles joined through shared corners (union-find on the corners).
  std::vector<std::int32_t> parent(region.mesh.vertices.size());
  for (std::size_t v = 0; v < parent.size(); ++v) parent[v] = static_cast<std::int32_t>(v);
  auto find = [&](std::int32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (const auto& [t, d] : deep)
    for (std::int32_t v : region.mesh.triangles[t])
      parent[find(v)] = find(region.mesh.triangles[t][0]);
  std::map<std::int32_t, std::pair<std::vector<std::int32_t>, double>> patch;
  for (const auto& [t, d] : deep) {
    auto& [triangles, patch_depth] = patch[find(region.mesh.triangles[t][0])];
    triangles.push_back(t);
    patch_depth = std::max(patch_depth, d);
  }
  std::vector<std::pair<std::vector<std::int32_t>, double>> out;
  for (auto& [root, p] : patch) out.push_back(std::move(p));
  return out;
}

// The region grown over its dents: the convex hull of each patch's corners and of the same
// corners moved `reach` further out along `dirs`, less the other parts' regions, joined to the
// region. Faces of a hull keep the origin of an outer face of the patch, so a hull that
// still does not reach the input surface counts as uncovered. nullopt when a boolean fails.
std::optional<ExactMesh> fill_dents(
    std::size_t i, const std::vector<Region>& regions, const std::vector<char>& usable,
    const std::vector<std::pair<std::vector<std::int32_t>, double>>& patches, const PointMap& dirs,
    double reach_factor, double margin) {
  const Region& r = regions[i];
  std::optional<ExactMesh> grown = exact_region(r.mesh, origins(r));
  if (!grown) return std::nullopt;
  for (const auto& [triangles, depth] : patches) {
    const double reach = reach_factor * depth + margin;
    // The hull starts a margin inside the region, so that the two cross instead of touching.
    std::vector<Vec3> points;
    for (std::int32_t t : triangles) {
      const Tri& tri = r.mesh.triangles[t];
      const Vec3 normal = (r.mesh.vertices[tri[1]] - r.mesh.vertices[tri[0]])
                              .cross(r.mesh.vertices[tri[2]] - r.mesh.vertices[tri[0]])
                              .normalized();
      for (std::int32_t v : tri) {
        const auto d = dirs.find(r.source[v]);
        const Vec3 out = d == dirs.end() ? normal : d->second;
        points.push_back(r.mesh.vertices[v] - margin * out);
        points.push_back(r.mesh.vertices[v] + reach * out);
      }
    }
    std::vector<EK::Point_3> corners;
    for (const Vec3& p : points) corners.emplace_back(p.x(), p.y(), p.z());
    const Box3 box = bounding_box(points);
    ExactMesh hull;
    CGAL::convex_hull_3(corners.begin(), corners.end(), hull);
    if (!CGAL::is_closed(hull) || hull.number_of_faces() < 4) continue;  // flat: no volume
    auto hull_origin = hull.add_property_map<Face, std::int32_t>("f:origin").first;
    for (Face f : hull.faces()) hull_origin[f] = outer_face_origin(triangles.front());
    for (std::size_t j = 0; j < regions.size(); ++j) {
      const Box3 other_box = bounding_box(regions[j].mesh.vertices);
      if (j == i || !usable[j] || (box.max.array() < other_box.min.array()).any() ||
          (other_box.max.array() < box.min.array()).any())
        continue;
      std::optional<ExactMesh> other =
          exact_region(regions[j].mesh, std::vector<std::int32_t>(regions[j].mesh.triangles.size(),
                                                                  static_cast<std::int32_t>(j)));
      ExactMesh rest;
      // Checked: a neighbour's region here is not known free of self-intersections, and an
      // unchecked one crashed the corefinement (CGAL's hand.off at 150 mm).
      if (!other ||
          !boolean(Boolean::Difference, hull, *other, rest, kFromSolid, Operands::Unchecked))
        return std::nullopt;
      hull = std::move(rest);
    }
    ExactMesh joined;
    if (!boolean(Boolean::Union, *grown, hull, joined, kFromSolid, Operands::Unchecked))
      return std::nullopt;
    grown = std::move(joined);
  }
  return grown;
}

// Seam vertices that the cut left a little apart in two neighbouring parts, where
// separate_pinches() moved a region's corner by a hair: the later part's vertex moves onto the
// earlier part's nearest one within `radius` (and the other way round nearest), when only the
// two parts and the outer surface meet at both and the part stays free of self-intersections
// and of flat triangles. Both lie on the input surface, so the outer surface stays on it; the
// parts' interface then matches vertex for vertex and the seam closes. Returns how many moved.
std::int32_t close_seam_hairs(std::vector<Part>& parts, double radius) {
  // The parts each vertex's triangles face, by position (a part has one vertex per position).
  auto facing = [](const Part& p) {
    std::map<Vec3, std::set<std::int32_t>, VecLess> out;
    for (std::size_t t = 0; t < p.mesh.triangles.size(); ++t)
      for (std::int32_t v : p.mesh.triangles[t])
        out[p.mesh.vertices[v]].insert(p.triangle_neighbor[t]);
    return out;
  };
  std::vector<std::map<Vec3, std::set<std::int32_t>, VecLess>> faces;
  for (const Part& p : parts) faces.push_back(facing(p));
  std::int32_t closed = 0;
  for (std::size_t j = 1; j < parts.size(); ++j) {
    Part& part = parts[j];
    const auto& faces_of_j = faces[j];
    std::map<Vec3, Vec3, VecLess> moves;
    for (std::size_t i = 0; i < j; ++i) {
      const auto& faces_of_i = faces[i];
      // Vertices on the i|j interface that the other part lacks, whose triangles face only the
      // other part and the outside.
      auto unmatched = [](const auto& mine, const auto& theirs, std::int32_t other) {
        std::vector<Vec3> out;
        for (const auto& [p, across] : mine)
          if (across.contains(other) && !theirs.contains(p) &&
              std::all_of(across.begin(), across.end(),
                          [&](std::int32_t n) { return n == other || n < 0; }))
            out.push_back(p);
        return out;
      };
      const std::vector<Vec3> ours =
          unmatched(faces_of_j, faces_of_i, static_cast<std::int32_t>(i));
      if (ours.empty()) continue;
      const std::vector<Vec3> theirs =
          unmatched(faces_of_i, faces_of_j, static_cast<std::int32_t>(j));
      auto nearest = [&](const Vec3& p, const std::vector<Vec3>& among) {
        const Vec3* best = nullptr;
        for (const Vec3& q : among)
          if ((q - p).norm() < radius && (!best || (q - p).norm() < (*best - p).norm())) best = &q;
        return best;
      };
      for (const Vec3& p : ours)
        if (const Vec3* q = nearest(p, theirs); q && nearest(*q, ours) == &p) moves.emplace(p, *q);
    }
    std::set<Vec3, VecLess> targets;
    for (const auto& [from, to] : moves) targets.insert(to);
    if (moves.empty() || targets.size() != moves.size() ||
        !intersecting_triangles(part.mesh, 1).empty())
      continue;
    TriMesh moved = part.mesh;
    for (Vec3& v : moved.vertices)
      if (const auto it = moves.find(v); it != moves.end()) v = it->second;
    const bool flat =
        std::any_of(moved.triangles.begin(), moved.triangles.end(), [&](const Tri& t) {
          const Vec3 &a = moved.vertices[t[0]], &b = moved.vertices[t[1]],
                     &c = moved.vertices[t[2]];
          return (b - a).cross(c - a).norm() == 0.0;
        });
    if (flat || !intersecting_triangles(moved, 1).empty()) continue;
    part.mesh = std::move(moved);
    part.volume_mm3 = signed_volume(part.mesh);
    faces[j] = facing(part);  // later parts meet its corners where they are now
    closed += static_cast<std::int32_t>(moves.size());
  }
  return closed;
}

}  // namespace

SolidCut cut_parts_from_solid(const TriMesh& solid, std::vector<Part>& parts) {
  SolidCut cut;
  cut.part_cut.assign(parts.size(), false);
  cut.problem.assign(parts.size(), "");
  const std::vector<std::array<Vec3, 3>> outer = outer_triangles(parts);
  // The input surface, for nearest points (normals) and depths (dents).
  Triangles solid_triangles;
  for (const Tri& t : solid.triangles)
    solid_triangles.emplace_back(point(solid.vertices[t[0]]), point(solid.vertices[t[1]]),
                                 point(solid.vertices[t[2]]));
  Tree surface(solid_triangles.begin(), solid_triangles.end());
  surface.accelerate_distance_queries();
  const PointMap dirs = input_normals(solid, solid_triangles, surface, outer);
  // Each outer vertex moves out twice as far as the input sticks out near it, plus a margin so
  // that no face of a region lies on the input surface.
  const double diagonal = bounding_box(solid.vertices).diagonal();
  const double margin = 1e-4 * diagonal;
  LengthMap push = local_reach(solid, outer);
  for (auto& [p, d] : push) d = 2.0 * d + margin;

  const std::size_t n = parts.size();
  using Pairs = std::vector<std::array<std::int32_t, 2>>;
  std::vector<Pairs> own(n);  // pairs that crossed before moving: the part's own
  const double hair = 1e-5 * diagonal;
  // Seam vertices this many hairs apart in neighbouring parts come from a moved pinch.
  constexpr double kSeamHairs = 10.0;
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    TriMesh separated = parts[i].mesh;
    separate_pinches(separated, hair);
    own[i] = intersecting_triangles(separated, 1);
  });
  // Where moving folds a region through itself, in every part (shared vertices move alike): a
  // seam vertex of the crossing triangles splits, once; one split already joins again; any other
  // moves half as far. Splitting only there keeps the cut away from seams elsewhere: it would
  // pass within a float step of them.
  const EdgeOwners owner = outer_edge_owners(parts);
  const LengthMap seams = seam_insets(parts, outer, owner);
  LengthMap inset;                // the seam vertices split now
  std::set<Vec3, VecLess> tried;  // and those split before
  std::vector<Region> regions(n);
  constexpr int kHalvings = 12;
  std::vector<char> folds(n, 0);
  std::set<Vec3, VecLess> halved;  // vertices that ever moved less for a fold
  std::vector<std::optional<std::pair<TriMesh, std::vector<std::int32_t>>>> results(n);
  // Where a moved outer side still lies inside the solid, its corners that never folded move
  // twice as far, and all is done again.
  constexpr int kGrowths = 3;
  // Dents shallower than this share of the diagonal are float noise of the moved faces.
  constexpr double kDentDepth = 1e-7;
  constexpr int kDentFills = 3;
  for (int pass = 0;; ++pass) {
    for (int round = 0;; ++round) {
      std::vector<std::set<Vec3, VecLess>> folded(n);
      tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        regions[i] = moved_region(parts[i], dirs, push, inset, owner);
        separate_pinches(regions[i].mesh, hair);
        if (!own[i].empty()) return;  // CGAL rejects it anyway
        for (const auto& pair : intersecting_triangles(regions[i].mesh, ~0u))
          for (std::int32_t t : pair)
            for (std::int32_t v : regions[i].mesh.triangles[t])
              folded[i].insert(regions[i].source[v]);
      });
      for (std::size_t i = 0; i < n; ++i) folds[i] = !folded[i].empty();
      if (std::find(folds.begin(), folds.end(), 1) == folds.end() || round == kHalvings) break;
      std::set<Vec3, VecLess> all;
      for (const auto& vs : folded) all.insert(vs.begin(), vs.end());
      for (const Vec3& v : all)
        if (const auto seam = seams.find(v); seam != seams.end() && !tried.contains(v)) {
          inset.insert(*seam);
          tried.insert(v);
        } else if (inset.erase(v) == 0) {
          if (const auto it = push.find(v); it != push.end()) {
            it->second *= 0.5;
            halved.insert(v);
          }
        }
    }
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      results[i].reset();
      cut.problem[i].clear();
      if (!own[i].empty())
        cut.problem[i] = "the part intersects itself (triangles " + std::to_string(own[i][0][0]) +
                         " and " + std::to_string(own[i][0][1]) + ")";
      else if (folds[i])
        cut.problem[i] = "its outer surface folds where it is moved out past the input surface";
      else if (std::optional<ExactMesh> region = exact_region(regions[i].mesh, origins(regions[i])))
        results[i] = intersect(solid, std::move(*region), cut.problem[i]);
      else
        cut.problem[i] = "its region is not a 2-manifold surface";
    });
    std::set<Vec3, VecLess> grow;
    for (std::size_t i = 0; i < n; ++i)
      if (results[i])
        for (std::int32_t o : results[i]->second)
          if (o < kFromSolid)
            for (std::int32_t v : regions[i].mesh.triangles[outer_face_of(o)])
              if (const Vec3& p = regions[i].source[v]; push.contains(p) && !halved.contains(p))
                grow.insert(p);
    if (grow.empty() || pass == kGrowths) break;
    for (const Vec3& p : grow) push.at(p) *= 2.0;
  }
  double largest = 0.0;
  for (const auto& [p, d] : push) largest = std::max(largest, d);
  cut.push_mm = largest;

  // Dents left where a fold kept the corners from moving far enough: each region grows over its
  // own, by convex hulls reaching further out each time, until its part covers the solid there.
  {
    const double depth = kDentDepth * diagonal;
    std::vector<char> usable(n);
    for (std::size_t i = 0; i < n; ++i) usable[i] = own[i].empty() && !folds[i];
    PartCover cover(results);
    const double hair_in_front = 1e-6 * diagonal;
    auto dents_of = [&](std::size_t i) {
      return dents(i, *results[i], regions[i], surface, depth, hair_in_front, cover);
    };
    for (std::size_t i = 0; i < n; ++i) {
      if (!results[i]) continue;
      const auto patches = dents_of(i);
      for (int attempt = 0; attempt < kDentFills && !patches.empty(); ++attempt) {
        std::optional<ExactMesh> grown =
            fill_dents(i, regions, usable, patches, dirs, 4.0 * (1 << attempt), margin);
        if (!grown) break;
        std::string problem;
        auto filled = intersect(solid, std::move(*grown), problem);
        if (!filled) break;
        results[i] = std::move(filled);
        cover.changed(i);
        if (dents_of(i).empty()) {
          cut.filled_dents += static_cast<std::int32_t>(patches.size());
          break;
        }
      }
    }
    // Counted once all are filled: a later part's fill can cover an earlier part's dent.
    for (std::size_t i = 0; i < n; ++i)
      if (results[i])
        for (const auto& [triangles, d] : dents_of(i))
          cut.uncovered_triangles += static_cast<std::int32_t>(triangles.size());
  }

  // A sliver part can lie wholly between the tet mesh's boundary and the input surface: cut, it
  // is empty. Its tets go to the neighbour it shares the most interface with.
  std::vector<std::int32_t> heir(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (!results[i] || !results[i]->first.triangles.empty()) continue;
    std::map<std::int32_t, double> shared;
    const TriMesh& m = parts[i].mesh;
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      const std::int32_t j = parts[i].triangle_neighbor[t];
      if (j < 0 || !results[j] || results[j]->first.triangles.empty()) continue;
      const Tri& tri = m.triangles[t];
      shared[j] += (m.vertices[tri[1]] - m.vertices[tri[0]])
                       .cross(m.vertices[tri[2]] - m.vertices[tri[0]])
                       .norm();
    }
    for (const auto& [j, area] : shared)
      if (heir[i] < 0 || area > shared[heir[i]]) heir[i] = j;
    if (heir[i] < 0) {
      results[i].reset();
      cut.problem[i] = "cut from the input solid, nothing of it is left and no neighbour takes it";
    }
  }
  std::vector<std::int32_t> new_id(n, -1);
  std::vector<Part> kept;
  SolidCut kept_cut = cut;
  kept_cut.part_cut.clear();
  kept_cut.problem.clear();
  for (std::size_t i = 0; i < n; ++i)
    if (heir[i] < 0) {
      new_id[i] = static_cast<std::int32_t>(kept.size());
      kept.push_back(std::move(parts[i]));
      kept_cut.part_cut.push_back(results[i].has_value());
      kept_cut.problem.push_back(cut.problem[i]);
    }
  for (std::size_t i = 0; i < n; ++i)
    if (heir[i] >= 0) {
      std::vector<std::int32_t>& tets = kept[new_id[heir[i]]].tets;
      tets.insert(tets.end(), parts[i].tets.begin(), parts[i].tets.end());
      std::sort(tets.begin(), tets.end());
      ++kept_cut.dropped_parts;
      kept_cut.dropped_tets.insert(kept_cut.dropped_tets.end(), parts[i].tets.begin(),
                                   parts[i].tets.end());
    }
  for (std::size_t i = 0; i < n; ++i) {
    if (heir[i] >= 0) continue;
    Part& part = kept[new_id[i]];
    part.id = new_id[i];
    if (results[i]) {
      auto& [mesh, origin] = *results[i];
      part.mesh = std::move(mesh);
      part.triangle_neighbor.assign(origin.size(), -1);
      for (std::size_t t = 0; t < origin.size(); ++t)
        if (origin[t] >= 0) part.triangle_neighbor[t] = origin[t];
      part.volume_mm3 = signed_volume(part.mesh);
    }
    // Faces towards a dropped part lay outside the solid with it, so none are left.
    for (std::int32_t& j : part.triangle_neighbor)
      if (j >= 0) j = heir[j] >= 0 ? new_id[heir[j]] : new_id[j];
  }
  std::sort(kept_cut.dropped_tets.begin(), kept_cut.dropped_tets.end());
  parts = std::move(kept);
  kept_cut.closed_seam_hairs = close_seam_hairs(parts, kSeamHairs * hair);
  return kept_cut;
}

}  // namespace dhfcast
