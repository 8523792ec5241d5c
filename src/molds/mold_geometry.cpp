// Small closed meshes and mesh helpers for the mold stage.
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>

#include "molds_internal.h"

namespace dhfcast::detail {

TriMesh make_frustum(const Vec3& base_centre, const Vec3& axis, double base_radius,
                     double top_radius, double height, int segments) {
  const Vec3 a = axis.unitOrthogonal(), b = axis.cross(a).normalized();
  TriMesh m;
  const double radius[2] = {base_radius, top_radius};
  for (int ring = 0; ring < 2; ++ring)
    for (int q = 0; q < segments; ++q) {
      // Half a step off the axes, so no vertex lies in the planes a grid is built on.
      const double angle = (q + 0.5) * 2 * std::numbers::pi / segments;
      m.vertices.push_back(base_centre + ring * height * axis +
                           radius[ring] * (std::cos(angle) * a + std::sin(angle) * b));
    }
  const auto bottom = static_cast<std::int32_t>(m.vertices.size());
  m.vertices.push_back(base_centre);
  m.vertices.push_back(base_centre + height * axis);
  const std::int32_t n = segments;
  for (std::int32_t q = 0; q < n; ++q) {
    const std::int32_t r = (q + 1) % n;
    m.triangles.push_back({q, r, n + r});
    m.triangles.push_back({q, n + r, n + q});
    m.triangles.push_back({bottom, r, q});
    m.triangles.push_back({bottom + 1, n + q, n + r});
  }
  orient_outward(m);
  return m;
}

void append_mesh(TriMesh& a, const TriMesh& b) {
  const auto offset = static_cast<std::int32_t>(a.vertices.size());
  a.vertices.insert(a.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (const Tri& t : b.triangles) a.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
}

void orient_outward(TriMesh& mesh) {
  if (signed_volume(mesh) < 0) flip_orientation(mesh);
}

TriMesh weld_exact(const TriMesh& mesh) {
  TriMesh out;
  std::map<std::array<double, 3>, std::int32_t> index;
  std::vector<std::int32_t> remap(mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    const Vec3& p = mesh.vertices[v];
    auto [it, added] = index.emplace(std::array<double, 3>{p.x(), p.y(), p.z()},
                                     static_cast<std::int32_t>(out.vertices.size()));
    if (added) out.vertices.push_back(p);
    remap[v] = it->second;
  }
  for (const Tri& t : mesh.triangles) out.triangles.push_back({remap[t[0]], remap[t[1]], remap[t[2]]});
  return out;
}

void canonicalize(TriMesh& mesh) {
  std::vector<std::int32_t> order(mesh.vertices.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::int32_t>(i);
  auto key = [&](std::int32_t v) {
    const Vec3& p = mesh.vertices[v];
    return std::array<double, 3>{p.x(), p.y(), p.z()};
  };
  std::stable_sort(order.begin(), order.end(),
                   [&](std::int32_t a, std::int32_t b) { return key(a) < key(b); });
  std::vector<std::int32_t> rank(order.size());
  std::vector<Vec3> vertices(order.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    rank[order[i]] = static_cast<std::int32_t>(i);
    vertices[i] = mesh.vertices[order[i]];
  }
  for (Tri& t : mesh.triangles) {
    for (std::int32_t& v : t) v = rank[v];
    // Rotate (keeping orientation) so the smallest index comes first.
    while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
  }
  std::sort(mesh.triangles.begin(), mesh.triangles.end());
  mesh.vertices = std::move(vertices);
}

void keep_shells_on_bed(TriMesh& mesh) {
  const std::size_t n = mesh.vertices.size();
  std::vector<std::int32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](std::int32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (const Tri& t : mesh.triangles)
    for (int k = 1; k < 3; ++k) parent[root(t[k])] = root(t[0]);
  std::vector<char> on_bed(n, 0), used(n, 0);
  for (const Tri& t : mesh.triangles)
    for (std::int32_t v : t) {
      used[v] = 1;
      if (mesh.vertices[v].z() == 0.0) on_bed[root(v)] = 1;
    }
  TriMesh kept;
  std::vector<std::int32_t> remap(n, -1);
  for (std::size_t v = 0; v < n; ++v)
    if (used[v] && on_bed[root(static_cast<std::int32_t>(v))]) {
      remap[v] = static_cast<std::int32_t>(kept.vertices.size());
      kept.vertices.push_back(mesh.vertices[v]);
    }
  for (const Tri& t : mesh.triangles)
    if (remap[t[0]] >= 0) kept.triangles.push_back({remap[t[0]], remap[t[1]], remap[t[2]]});
  mesh = std::move(kept);
}

}  // namespace dhfcast::detail
