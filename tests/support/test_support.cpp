#include "support/test_support.h"

#include <array>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <unistd.h>

#include "dhfcast/mesh.h"

namespace fs = std::filesystem;

namespace dhfcast::test {

namespace {
std::string existing(const fs::path& p) { return fs::exists(p) ? p.string() : std::string(); }

struct TempDirs {
  std::vector<fs::path> dirs;
  ~TempDirs() {
    std::error_code ec;
    for (const auto& d : dirs) fs::remove_all(d, ec);
  }
};
TempDirs& temp_dirs() {
  static TempDirs t;
  return t;
}
}  // namespace

std::string cgal_mesh(const std::string& name) {
  return existing(fs::path(DHFCAST_CGAL_MESHES_DIR) / name);
}

std::string extra_model(const std::string& name) {
  if (const char* env = std::getenv("DHFCAST_MODELS_DIR")) return existing(fs::path(env) / name);
  return existing(fs::path(DHFCAST_MODELS_DIR) / name);
}

std::string cli_path() { return DHFCAST_CLI_PATH; }

std::string temp_dir(const std::string& tag) {
  static std::atomic<int> counter{0};
  const fs::path dir = fs::temp_directory_path() /
                       ("dhfcast-test-" + tag + "-" + std::to_string(::getpid()) + "-" +
                        std::to_string(counter++));
  fs::remove_all(dir);
  fs::create_directories(dir);
  temp_dirs().dirs.push_back(dir);
  return dir.string();
}

TriMesh load_scaled(const std::string& path, double diag_mm) {
  LoadOptions opts;
  if (diag_mm > 0) {
    const TriMesh raw = read_mesh(path);
    opts.scale = diag_mm / bounding_box(raw.vertices).diagonal();
  }
  return load_solid(path, opts).mesh;
}

namespace {
// Boundary of a union of unit voxels (scaled by `cell`), outward, welded. Voxels must not touch
// only along an edge or at a vertex (that would be non-manifold).
template <class Inside>
TriMesh voxel_solid(const std::array<int, 3>& n, double cell, Inside inside) {
  TriMesh mesh;
  std::map<std::array<int, 3>, std::int32_t> index;
  auto vertex = [&](int x, int y, int z) {
    auto [it, added] = index.emplace(std::array<int, 3>{x, y, z}, 0);
    if (added) {
      it->second = static_cast<std::int32_t>(mesh.vertices.size());
      mesh.vertices.emplace_back(x * cell, y * cell, z * cell);
    }
    return it->second;
  };
  auto filled = [&](int x, int y, int z) {
    return x >= 0 && y >= 0 && z >= 0 && x < n[0] && y < n[1] && z < n[2] && inside(x, y, z);
  };
  for (int x = 0; x < n[0]; ++x)
    for (int y = 0; y < n[1]; ++y)
      for (int z = 0; z < n[2]; ++z) {
        if (!filled(x, y, z)) continue;
        for (int axis = 0; axis < 3; ++axis)
          for (int side = 0; side < 2; ++side) {
            std::array<int, 3> c{x, y, z};
            std::array<int, 3> nb = c;
            nb[axis] += side ? 1 : -1;
            if (filled(nb[0], nb[1], nb[2])) continue;
            // Quad on the face of voxel c at c[axis] + side, corners in the other two axes.
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            std::array<std::array<int, 3>, 4> q;
            for (int k = 0; k < 4; ++k) {
              q[k] = c;
              q[k][axis] += side;
              q[k][u] += (k == 1 || k == 2);
              q[k][v] += (k >= 2);
            }
            std::array<std::int32_t, 4> id;
            for (int k = 0; k < 4; ++k) id[k] = vertex(q[k][0], q[k][1], q[k][2]);
            // (u, v) order gives normal +axis; flip for the low side.
            if (side)
              mesh.triangles.push_back({id[0], id[1], id[2]}), mesh.triangles.push_back({id[0], id[2], id[3]});
            else
              mesh.triangles.push_back({id[0], id[2], id[1]}), mesh.triangles.push_back({id[0], id[3], id[2]});
          }
      }
  return mesh;
}
}  // namespace

TriMesh make_box(const Vec3& min, const Vec3& max) {
  TriMesh m = voxel_solid({1, 1, 1}, 1.0, [](int, int, int) { return true; });
  for (Vec3& p : m.vertices) p = min + p.cwiseProduct(max - min);
  return m;
}

TriMesh make_cup(double size_mm, double wall_mm) {
  // 5x5x5 voxels: outer ring and floor filled, the 3x3 core above the floor empty.
  const int n = 5;
  TriMesh m = voxel_solid({n, n, n}, 1.0, [&](int x, int y, int z) {
    const bool core = x > 0 && x < n - 1 && y > 0 && y < n - 1;
    return !(core && z > 0);
  });
  // Map voxel coordinates so that walls and floor have thickness wall_mm.
  auto map = [&](double c) {
    if (c <= 1) return c * wall_mm;
    if (c >= n - 1) return size_mm - (n - c) * wall_mm;
    return wall_mm + (c - 1) / (n - 2) * (size_mm - 2 * wall_mm);
  };
  for (Vec3& p : m.vertices) p = Vec3(map(p.x()), map(p.y()), map(p.z()));
  return m;
}

}  // namespace dhfcast::test

namespace dhfcast::test {

double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  // Closest point on a triangle by Voronoi regions (Ericson, Real-Time Collision Detection 5.1.5).
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

double max_distance_to_surface(const std::vector<Vec3>& points, const TriMesh& mesh) {
  double worst = 0.0;
  for (const Vec3& p : points) {
    double best = std::numeric_limits<double>::infinity();
    for (const Tri& t : mesh.triangles)
      best = std::min(best, point_triangle_distance(p, mesh.vertices[t[0]], mesh.vertices[t[1]],
                                                    mesh.vertices[t[2]]));
    worst = std::max(worst, best);
  }
  return worst;
}

std::string solid_topology_problem(const TriMesh& mesh) {
  std::map<std::pair<std::int32_t, std::int32_t>, int> directed;
  for (const Tri& t : mesh.triangles)
    for (int i = 0; i < 3; ++i) ++directed[{t[i], t[(i + 1) % 3]}];
  for (const auto& [e, n] : directed) {
    if (n != 1) return "edge used " + std::to_string(n) + " times in one direction";
    const auto it = directed.find({e.second, e.first});
    if (it == directed.end()) return "open edge";
  }
  // Each vertex: its triangles must form one fan (connected through shared edges).
  std::vector<std::vector<std::int32_t>> around(mesh.vertices.size());
  for (std::int32_t f = 0; f < static_cast<std::int32_t>(mesh.triangles.size()); ++f)
    for (std::int32_t v : mesh.triangles[f]) around[v].push_back(f);
  for (std::size_t v = 0; v < around.size(); ++v) {
    if (around[v].empty()) continue;
    // Follow "next triangle around v" through the outgoing edge (v -> w) of each triangle.
    std::map<std::int32_t, std::int32_t> by_incoming;  // w -> triangle with edge (w -> v)
    for (std::int32_t f : around[v]) {
      const Tri& t = mesh.triangles[f];
      for (int i = 0; i < 3; ++i)
        if (t[(i + 1) % 3] == static_cast<std::int32_t>(v)) by_incoming[t[i]] = f;
    }
    std::size_t steps = 0;
    std::int32_t f = around[v][0];
    do {
      const Tri& t = mesh.triangles[f];
      std::int32_t w = -1;
      for (int i = 0; i < 3; ++i)
        if (t[i] == static_cast<std::int32_t>(v)) w = t[(i + 1) % 3];
      f = by_incoming.at(w);
      ++steps;
    } while (f != around[v][0] && steps <= around[v].size());
    if (steps != around[v].size())
      return "vertex " + std::to_string(v) + " has several fans";
  }
  if (signed_volume(mesh) <= 0) return "non-positive volume";
  return "";
}

}  // namespace dhfcast::test
