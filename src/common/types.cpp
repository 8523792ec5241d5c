#include "dhfcast/types.h"

#include <algorithm>
#include <string>
#include <unordered_map>

#include "dhfcast/error.h"

namespace dhfcast {

namespace detail {
void assert_fail(const char* cond, const std::string& msg, const char* file, int line) {
  throw Error(ErrorCode::Internal, std::string("internal error: ") + cond + " failed at " + file +
                                       ":" + std::to_string(line) + ": " + msg);
}
}  // namespace detail

double signed_volume(const TriMesh& mesh) {
  double six_v = 0.0;
  for (const Tri& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3& b = mesh.vertices[t[1]];
    const Vec3& c = mesh.vertices[t[2]];
    six_v += a.dot(b.cross(c));
  }
  return six_v / 6.0;
}

Box3 bounding_box(const std::vector<Vec3>& points) {
  Box3 box;
  if (points.empty()) return box;
  box.min = box.max = points[0];
  for (const Vec3& p : points) {
    box.min = box.min.cwiseMin(p);
    box.max = box.max.cwiseMax(p);
  }
  return box;
}

double tet_volume(const TetMesh& mesh, std::int32_t t) {
  const Tet& k = mesh.tets[t];
  const Vec3& a = mesh.vertices[k[0]];
  return (mesh.vertices[k[1]] - a).dot((mesh.vertices[k[2]] - a).cross(mesh.vertices[k[3]] - a)) /
         6.0;
}

double total_volume(const TetMesh& mesh) {
  double v = 0.0;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(mesh.tets.size()); ++t)
    v += tet_volume(mesh, t);
  return v;
}

Vec3 tet_face_normal(const TetMesh& mesh, std::int32_t t, int i) {
  const Tet& k = mesh.tets[t];
  const Vec3& a = mesh.vertices[k[kTetFaces[i][0]]];
  const Vec3& b = mesh.vertices[k[kTetFaces[i][1]]];
  const Vec3& c = mesh.vertices[k[kTetFaces[i][2]]];
  return (b - a).cross(c - a);
}

double tet_face_area(const TetMesh& mesh, std::int32_t t, int i) {
  return 0.5 * tet_face_normal(mesh, t, i).norm();
}

void build_tet_adjacency(TetMesh& mesh) {
  const std::int32_t n = static_cast<std::int32_t>(mesh.tets.size());
  mesh.neighbors.assign(n, {-1, -1, -1, -1});
  // Key: sorted face vertices; value: first (tet, local face) seen with it.
  struct Key {
    std::array<std::int32_t, 3> v;
    bool operator==(const Key& o) const { return v == o.v; }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = static_cast<std::uint32_t>(k.v[0]);
      h = h * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint32_t>(k.v[1]);
      h = h * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint32_t>(k.v[2]);
      return static_cast<std::size_t>(h * 0xBF58476D1CE4E5B9ull);
    }
  };
  std::unordered_map<Key, std::int64_t, Hash> open;
  open.reserve(static_cast<std::size_t>(n) * 2);
  for (std::int32_t t = 0; t < n; ++t) {
    for (int i = 0; i < 4; ++i) {
      Key key{{mesh.tets[t][kTetFaces[i][0]], mesh.tets[t][kTetFaces[i][1]],
               mesh.tets[t][kTetFaces[i][2]]}};
      std::sort(key.v.begin(), key.v.end());
      auto [it, inserted] = open.emplace(key, std::int64_t{t} * 4 + i);
      if (inserted) continue;
      if (it->second < 0)
        throw Error(ErrorCode::Internal, "tet mesh face shared by more than two tets");
      const std::int32_t u = static_cast<std::int32_t>(it->second / 4);
      const int j = static_cast<int>(it->second % 4);
      mesh.neighbors[t][i] = u;
      mesh.neighbors[u][j] = t;
      it->second = -1;
    }
  }
}

// Ericson, Real-Time Collision Detection, 5.1.5.
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

void flip_orientation(TriMesh& mesh) {
  for (Tri& t : mesh.triangles) std::swap(t[1], t[2]);
}

}  // namespace dhfcast
