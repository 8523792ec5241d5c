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
using GridPoint = std::array<int, 3>;

// Welds grid points into mesh vertices, numbered in order of first use.
template <class Mesh>
auto grid_vertex(Mesh& mesh, const std::vector<double>& xs, const std::vector<double>& ys,
                 const std::vector<double>& zs) {
  return [&mesh, &xs, &ys, &zs, index = std::map<GridPoint, std::int32_t>()](
             const GridPoint& g) mutable {
    auto [it, added] = index.emplace(g, 0);
    if (added) {
      it->second = static_cast<std::int32_t>(mesh.vertices.size());
      mesh.vertices.emplace_back(xs[g[0]], ys[g[1]], zs[g[2]]);
    }
    return it->second;
  };
}
}  // namespace

TriMesh grid_surface(const std::vector<double>& xs, const std::vector<double>& ys,
                     const std::vector<double>& zs, const GridFilled& filled) {
  const GridPoint n{static_cast<int>(xs.size()) - 1, static_cast<int>(ys.size()) - 1,
                    static_cast<int>(zs.size()) - 1};
  auto in = [&](const GridPoint& c) {
    for (int a = 0; a < 3; ++a)
      if (c[a] < 0 || c[a] >= n[a]) return false;
    return filled(c[0], c[1], c[2]);
  };
  TriMesh mesh;
  auto vertex = grid_vertex(mesh, xs, ys, zs);
  for (int i = 0; i < n[0]; ++i)
    for (int j = 0; j < n[1]; ++j)
      for (int k = 0; k < n[2]; ++k) {
        const GridPoint c{i, j, k};
        if (!in(c)) continue;
        for (int axis = 0; axis < 3; ++axis)
          for (int side = 0; side < 2; ++side) {
            GridPoint nb = c;
            nb[axis] += side ? 1 : -1;
            if (in(nb)) continue;
            // Quad on the face of cell c at c[axis] + side, corners in the other two axes.
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            std::array<std::int32_t, 4> q;
            for (int corner = 0; corner < 4; ++corner) {
              GridPoint g = c;
              g[axis] += side;
              g[u] += (corner == 1 || corner == 2);
              g[v] += (corner >= 2);
              q[corner] = vertex(g);
            }
            // (u, v) order gives the normal +axis; the low side is flipped.
            if (side) {
              mesh.triangles.push_back({q[0], q[1], q[2]});
              mesh.triangles.push_back({q[0], q[2], q[3]});
            } else {
              mesh.triangles.push_back({q[0], q[2], q[1]});
              mesh.triangles.push_back({q[0], q[3], q[2]});
            }
          }
      }
  return mesh;
}

TetMesh grid_tets(const std::vector<double>& xs, const std::vector<double>& ys,
                  const std::vector<double>& zs, const GridFilled& filled) {
  TetMesh mesh;
  auto vertex = grid_vertex(mesh, xs, ys, zs);
  const std::array<GridPoint, 6> perms = {
      {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  for (int i = 0; i + 1 < static_cast<int>(xs.size()); ++i)
    for (int j = 0; j + 1 < static_cast<int>(ys.size()); ++j)
      for (int k = 0; k + 1 < static_cast<int>(zs.size()); ++k) {
        if (!filled(i, j, k)) continue;
        // Walk from corner (i, j, k) to the opposite one, one axis at a time.
        for (const auto& p : perms) {
          GridPoint c{i, j, k};
          Tet t;
          t[0] = vertex(c);
          for (int s = 0; s < 3; ++s) {
            ++c[p[s]];
            t[s + 1] = vertex(c);
          }
          mesh.tets.push_back(t);
          if (tet_volume(mesh, static_cast<std::int32_t>(mesh.tets.size()) - 1) < 0)
            std::swap(mesh.tets.back()[2], mesh.tets.back()[3]);
        }
      }
  build_tet_adjacency(mesh);
  return mesh;
}

TriMesh make_box(const Vec3& min, const Vec3& max) {
  return grid_surface({min.x(), max.x()}, {min.y(), max.y()}, {min.z(), max.z()},
                      [](int, int, int) { return true; });
}

TriMesh make_cup(double size_mm, double wall_mm) {
  // 5x5x5 cells: outer ring and floor filled, the 3x3 core above the floor empty; walls and floor
  // wall_mm thick.
  const int n = 5;
  std::vector<double> c;
  for (int i = 0; i <= n; ++i)
    c.push_back(i <= 1       ? i * wall_mm
                : i >= n - 1 ? size_mm - (n - i) * wall_mm
                             : wall_mm + (i - 1.0) / (n - 2) * (size_mm - 2 * wall_mm));
  return grid_surface(c, c, c, [&](int i, int j, int k) {
    const bool core = i > 0 && i < n - 1 && j > 0 && j < n - 1;
    return !(core && k > 0);
  });
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
