// Private to the parts stage: exact CGAL meshes, and booleans whose result faces remember which
// operand face they come from ("f:origin"). Included by the stage's CGAL files only.
#pragma once

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::exact {

namespace PMP = CGAL::Polygon_mesh_processing;
using EK = CGAL::Exact_predicates_exact_constructions_kernel;
using ExactMesh = CGAL::Surface_mesh<EK::Point_3>;
using Face = ExactMesh::Face_index;
using OriginMap = ExactMesh::Property_map<Face, std::int32_t>;
using SplitMap = ExactMesh::Property_map<Face, std::int32_t>;

// Vertex positions as map keys: shared vertices of neighbouring parts have equal coordinates.
struct VecLess {
  bool operator()(const Vec3& a, const Vec3& b) const {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  }
};

inline std::optional<ExactMesh> to_exact(const TriMesh& m) {
  ExactMesh out;
  for (const Vec3& p : m.vertices) out.add_vertex(EK::Point_3(p.x(), p.y(), p.z()));
  for (const Tri& t : m.triangles)
    if (out.add_face(ExactMesh::Vertex_index(t[0]), ExactMesh::Vertex_index(t[1]),
                     ExactMesh::Vertex_index(t[2])) == ExactMesh::null_face())
      return std::nullopt;
  return out;
}

// The mesh's "f:origin" map (made, with `fallback` for every face, when it has none).
inline OriginMap origin_map(ExactMesh& m, std::int32_t fallback) {
  return m.add_property_map<Face, std::int32_t>("f:origin", fallback).first;
}

// The mesh's "f:split" map, every face at -1: which faces of one boolean's result come from
// one operand face that the boolean split (equal values >= 0).
inline SplitMap fresh_split_map(ExactMesh& m) {
  const auto [split, made] = m.add_property_map<Face, std::int32_t>("f:split", -1);
  if (!made)
    for (Face f : m.faces()) split[f] = -1;
  return split;
}

// Keeps, for every face of the result, the origin of the face it was split or copied from, and
// which split face it is a piece of.
struct OriginVisitor : PMP::Corefinement::Default_visitor<ExactMesh> {
  std::map<const ExactMesh*, OriginMap> origin;
  std::map<const ExactMesh*, SplitMap> split;
  std::int32_t current = 0, current_split = -1, splits = 0;
  void before_subface_creations(Face f, ExactMesh& tm) {
    current = origin.at(&tm)[f];
    current_split = splits++;
    split.at(&tm)[f] = current_split;
  }
  void after_subface_created(Face f, ExactMesh& tm) {
    origin.at(&tm)[f] = current;
    split.at(&tm)[f] = current_split;
  }
  void after_face_copy(Face from, const ExactMesh& src, Face to, ExactMesh& dst) {
    origin.at(&dst)[to] = origin.at(&src)[from];
    split.at(&dst)[to] = split.at(&src)[from];
  }
};

enum class Boolean { Intersection, Union, Difference };

// Whether boolean() has CGAL check its operands for self-intersections. Known: both were checked
// already (intersecting_triangles(), exact predicates on the same float points) or made by a
// boolean or as a convex hull. CGAL's check, in exact arithmetic, is a large share of a boolean.
enum class Operands { Unchecked, Known };

// a op b into `out`, whose faces keep the origins of the faces they come from (faces of an
// operand without an origin map get `fallback`); false when CGAL rejects an unchecked operand
// (self-intersecting) or cannot build the result.
inline bool boolean(Boolean op, ExactMesh& a, ExactMesh& b, ExactMesh& out, std::int32_t fallback,
                    Operands operands) {
  OriginVisitor visitor;
  for (ExactMesh* m : {&a, &b, &out}) {
    visitor.origin[m] = origin_map(*m, fallback);
    visitor.split[m] = fresh_split_map(*m);
  }
  const bool check = operands == Operands::Unchecked;
  const auto for_a = CGAL::parameters::visitor(visitor).throw_on_self_intersection(check);
  const auto for_b = CGAL::parameters::throw_on_self_intersection(check);
  bool built = false;
  try {
    switch (op) {
      case Boolean::Intersection:
        built = PMP::corefine_and_compute_intersection(a, b, out, for_a, for_b);
        break;
      case Boolean::Union:
        built = PMP::corefine_and_compute_union(a, b, out, for_a, for_b);
        break;
      case Boolean::Difference:
        built = PMP::corefine_and_compute_difference(a, b, out, for_a, for_b);
        break;
    }
  } catch (const PMP::Corefinement::Self_intersection_exception&) {
  }
  // Where the operands touch at a point the result can pinch there, which a Surface_mesh holds
  // only as a broken structure (and CGAL then crashes on it).
  return built && CGAL::is_valid_polygon_mesh(out);
}

// The point as the float STL will hold it. From the exact value, which does not depend on what
// was evaluated before or on the thread, so neighbours round shared points alike.
inline Vec3 rounded(const EK::Point_3& p) {
  // Rounding is monotone, so when both ends of the interval that holds x round alike, x rounds
  // to that too: its exact value (slow to compute) is needed only near a float's midpoint.
  auto f = [](const EK::FT& x) {
    const auto [lo, hi] = CGAL::to_interval(x);
    if (float(lo) == float(hi)) return double(float(lo));
    return double(float(CGAL::to_double(CGAL::exact(x))));
  };
  return Vec3(f(p.x()), f(p.y()), f(p.z()));
}

// The mesh as a TriMesh, with each triangle's origin. Points within a float step of each other
// become one, and the needle triangles between them go (in a neighbour too, which rounds the
// same points). The order CGAL lists faces and their corners in can follow memory addresses,
// which differ from run to run, so the result is in a canonical order: vertices by position,
// triangles by corners, each from its lowest corner. (How it triangulates co-circular corners
// can follow them too; carving rebuilds its results for that, see cgal_carve.cpp.)
inline std::pair<TriMesh, std::vector<std::int32_t>> canonical(ExactMesh& m,
                                                               std::int32_t fallback) {
  const OriginMap origin_of = origin_map(m, fallback);
  std::map<Vec3, std::int32_t, VecLess> at;
  std::map<ExactMesh::Vertex_index, Vec3> position;
  for (ExactMesh::Vertex_index v : m.vertices()) {
    position[v] = rounded(m.point(v));
    at.emplace(position[v], 0);
  }
  TriMesh mesh;
  for (auto& [p, i] : at) {
    i = static_cast<std::int32_t>(mesh.vertices.size());
    mesh.vertices.push_back(p);
  }
  std::vector<std::pair<Tri, std::int32_t>> faces;  // with their origin
  for (Face f : m.faces()) {
    Tri t{};
    int k = 0;
    for (ExactMesh::Vertex_index v : CGAL::vertices_around_face(m.halfedge(f), m))
      if (k < 3) t[k++] = at.at(position.at(v));
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    faces.emplace_back(t, origin_of[f]);
  }
  std::sort(faces.begin(), faces.end());
  std::vector<std::int32_t> origin;
  for (const auto& [t, o] : faces) {
    mesh.triangles.push_back(t);
    origin.push_back(o);
  }
  return {std::move(mesh), std::move(origin)};
}

}  // namespace dhfcast::exact
