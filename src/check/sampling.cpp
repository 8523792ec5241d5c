#include "sampling.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace dhfcast::detail {

std::uint64_t stream_seed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ull * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

namespace {
Vec3 unit_normal(const TriMesh& mesh, const Tri& t) {
  const Vec3& a = mesh.vertices[t[0]];
  return (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).normalized();
}
}  // namespace

std::vector<SurfaceSample> sample_surface(const TriMesh& mesh, std::int64_t count, Random& random) {
  std::vector<double> cumulative_area;
  cumulative_area.reserve(mesh.triangles.size());
  double total = 0.0;
  for (const Tri& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    total += 0.5 * (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).norm();
    cumulative_area.push_back(total);
  }
  std::vector<SurfaceSample> out;
  if (total <= 0.0 || count <= 0) return out;
  out.reserve(static_cast<std::size_t>(count));
  for (std::int64_t i = 0; i < count; ++i) {
    const double pick = random.uniform() * total;
    const std::size_t k = std::min<std::size_t>(
        std::upper_bound(cumulative_area.begin(), cumulative_area.end(), pick) -
            cumulative_area.begin(),
        cumulative_area.size() - 1);
    const Tri& t = mesh.triangles[k];
    // Uniform barycentric coordinates (square-root mapping).
    const double r1 = std::sqrt(random.uniform());
    const double r2 = random.uniform();
    const Vec3 p = (1.0 - r1) * mesh.vertices[t[0]] + r1 * (1.0 - r2) * mesh.vertices[t[1]] +
                   r1 * r2 * mesh.vertices[t[2]];
    out.push_back({p, unit_normal(mesh, t), static_cast<std::int32_t>(k)});
  }
  return out;
}

std::vector<SurfaceSample> vertex_samples(const TriMesh& mesh) {
  std::vector<std::int32_t> first_triangle(mesh.vertices.size(), -1);
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Tri& t = mesh.triangles[i];
    const Vec3& a = mesh.vertices[t[0]];
    if ((mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).squaredNorm() == 0.0) continue;
    for (std::int32_t v : t)
      if (first_triangle[v] < 0) first_triangle[v] = static_cast<std::int32_t>(i);
  }
  std::vector<SurfaceSample> out;
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    if (first_triangle[v] < 0) continue;
    const Tri& t = mesh.triangles[first_triangle[v]];
    const Vec3 centroid = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3.0;
    out.push_back({mesh.vertices[v] + 1e-3 * (centroid - mesh.vertices[v]), unit_normal(mesh, t),
                   first_triangle[v]});
  }
  return out;
}

void push_inside(std::vector<SurfaceSample>& samples, double depth_mm) {
  for (SurfaceSample& s : samples) s.point -= depth_mm * s.normal;
}

void perpendicular_basis(const Vec3& d, Vec3& u, Vec3& v) {
  // Cross with the axis least aligned with d: well conditioned for any d.
  Vec3 axis = Vec3::Zero();
  Eigen::Index smallest = 0;
  d.cwiseAbs().minCoeff(&smallest);
  axis[smallest] = 1.0;
  u = d.cross(axis).normalized();
  v = d.cross(u);
}

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(
      std::min(std::ceil(q * static_cast<double>(values.size())), double(values.size())));
  const std::size_t index = k == 0 ? 0 : k - 1;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(index),
                   values.end());
  return values[index];
}

}  // namespace dhfcast::detail
