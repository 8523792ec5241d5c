// Core geometric types shared by every stage. Units are millimetres throughout.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // Vec3::cross
#include <array>
#include <cstdint>
#include <functional>
#include <vector>

namespace dhfcast {

using Vec3 = Eigen::Vector3d;
using Tri = std::array<std::int32_t, 3>;
using Tet = std::array<std::int32_t, 4>;

// Reports progress of a long stage as a fraction in [0, 1]. May be empty. Called from the
// calling thread only.
using Progress = std::function<void(double fraction)>;

// An indexed triangle mesh. Triangles are counter-clockwise seen from outside (outward normals).
struct TriMesh {
  std::vector<Vec3> vertices;
  std::vector<Tri> triangles;
};

// Axis-aligned bounding box.
struct Box3 {
  Vec3 min = Vec3::Constant(0.0);
  Vec3 max = Vec3::Constant(0.0);
  double diagonal() const { return (max - min).norm(); }
};

// A tetrahedral mesh of a solid. Every tet is positively oriented:
// dot(v1 - v0, cross(v2 - v0, v3 - v0)) > 0.
// Local face i of a tet is the face opposite its vertex i; kTetFaces lists its vertices so that
// its normal (right-hand rule) points out of the tet.
struct TetMesh {
  std::vector<Vec3> vertices;
  std::vector<Tet> tets;
  // neighbors[t][i]: the tet sharing local face i of t, or -1 when that face is on the boundary.
  // Filled by build_tet_adjacency().
  std::vector<std::array<std::int32_t, 4>> neighbors;
  // Largest distance (mm) from the tet mesh's boundary to the input surface, as measured by
  // the mesher. Reported, never used to decide anything.
  double boundary_tolerance_mm = 0.0;
};

// Vertices of local face i (opposite vertex i), ordered so the normal points out of the tet.
inline constexpr std::array<std::array<int, 3>, 4> kTetFaces = {{
    {1, 2, 3},
    {0, 3, 2},
    {0, 1, 3},
    {0, 2, 1},
}};

// Signed volume enclosed by a closed mesh (positive when outward oriented), mm^3.
double signed_volume(const TriMesh& mesh);
// Bounding box of the vertices; an empty mesh gives a zero box.
Box3 bounding_box(const std::vector<Vec3>& points);
// Volume of tet t (positive for a positively oriented tet), mm^3.
double tet_volume(const TetMesh& mesh, std::int32_t t);
// Sum of all tet volumes, mm^3.
double total_volume(const TetMesh& mesh);
// Normal of local face i of tet t, pointing out of a positively oriented tet; its length is
// twice the face's area (mm^2).
Vec3 tet_face_normal(const TetMesh& mesh, std::int32_t t, int i);
// Area of local face i of tet t, mm^2.
double tet_face_area(const TetMesh& mesh, std::int32_t t, int i);
// Fills mesh.neighbors from mesh.tets. Throws Error{Internal} when a face is shared by more
// than two tets.
void build_tet_adjacency(TetMesh& mesh);
// The point of triangle abc closest to p.
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);
// Reverses every triangle's winding.
void flip_orientation(TriMesh& mesh);

}  // namespace dhfcast
