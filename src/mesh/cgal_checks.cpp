// Exact predicates for validate_mesh() and intersecting_triangles(): the only file of the mesh
// stage that includes CGAL.
#include "cgal_checks.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <iterator>
#include <utility>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"

namespace dhfcast::detail {

namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using FaceIndex = SurfaceMesh::Face_index;

Point to_point(const Vec3& p) { return Point(p.x(), p.y(), p.z()); }
}  // namespace

bool collinear_exact(const Vec3& a, const Vec3& b, const Vec3& c) {
  return CGAL::collinear(to_point(a), to_point(b), to_point(c));
}

std::vector<std::array<std::int32_t, 2>> intersecting_pairs(const TriMesh& mesh,
                                                            unsigned max_pairs) {
  SurfaceMesh sm;
  sm.reserve(static_cast<SurfaceMesh::size_type>(mesh.vertices.size()),
             static_cast<SurfaceMesh::size_type>(3 * mesh.triangles.size() / 2),
             static_cast<SurfaceMesh::size_type>(mesh.triangles.size()));
  for (const Vec3& p : mesh.vertices) sm.add_vertex(to_point(p));
  // Faces are added in order, so face index i is triangle i.
  bool surface = true;
  for (const Tri& t : mesh.triangles) {
    surface = sm.add_face(SurfaceMesh::Vertex_index(t[0]), SurfaceMesh::Vertex_index(t[1]),
                          SurfaceMesh::Vertex_index(t[2])) != SurfaceMesh::null_face();
    if (!surface) break;
  }
  if (!surface) {
    // Not a surface mesh (a pinched vertex, an edge in three triangles): CGAL's soup repair
    // gives each fan its own copy of such a vertex or edge, keeping the triangles' order, so the
    // contact there counts as an intersection.
    namespace PMP = CGAL::Polygon_mesh_processing;
    std::vector<Point> points;
    for (const Vec3& p : mesh.vertices) points.push_back(to_point(p));
    std::vector<std::vector<std::size_t>> polygons;
    for (const Tri& t : mesh.triangles)
      polygons.push_back({static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]),
                          static_cast<std::size_t>(t[2])});
    PMP::orient_polygon_soup(points, polygons);
    sm.clear();
    PMP::polygon_soup_to_polygon_mesh(points, polygons, sm);
    if (sm.number_of_faces() != mesh.triangles.size())
      throw Error(ErrorCode::Internal, "internal error: a triangle soup could not be meshed");
  }

  std::vector<std::pair<FaceIndex, FaceIndex>> found;
  CGAL::Polygon_mesh_processing::self_intersections<CGAL::Sequential_tag>(
      sm, std::back_inserter(found), CGAL::parameters::maximum_number(max_pairs));
  std::vector<std::array<std::int32_t, 2>> pairs;
  for (const auto& [f, g] : found) {
    std::array<std::int32_t, 2> pair = {static_cast<std::int32_t>(f), static_cast<std::int32_t>(g)};
    if (pair[0] > pair[1]) std::swap(pair[0], pair[1]);
    pairs.push_back(pair);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

SelfIntersections find_self_intersections(const TriMesh& mesh, unsigned max_pairs) {
  const std::vector<std::array<std::int32_t, 2>> pairs = intersecting_pairs(mesh, max_pairs);
  SelfIntersections result;
  result.pairs = static_cast<std::int64_t>(pairs.size());
  result.limit_reached = pairs.size() >= max_pairs;
  if (!pairs.empty()) result.first = pairs.front();
  return result;
}

}  // namespace dhfcast::detail

namespace dhfcast {

std::vector<std::array<std::int32_t, 2>> intersecting_triangles(const TriMesh& mesh,
                                                                unsigned max_pairs) {
  return detail::intersecting_pairs(mesh, max_pairs);
}

}  // namespace dhfcast
