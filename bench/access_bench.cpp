// Accessibility on a shared model with a tet mesh of about the paper's size (Table 1).
// Usage: access_bench [--benchmark_repetitions=3]; models are read from DHFCAST_MODELS_DIR.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <string>

#include "dhfcast/access.h"
#include "dhfcast/directions.h"
#include "dhfcast/mesh.h"
#include "dhfcast/tets.h"
#include "support/test_support.h"

namespace {

using namespace dhfcast;

// Tets (six per cell) of the grid cells of size h_mm whose centre is inside `surface`, decided
// by the parity of crossings of the vertical line through the cell column.
TetMesh voxel_tets(const TriMesh& surface, double h_mm) {
  const Box3 box = bounding_box(surface.vertices);
  const Vec3 origin = box.min - Vec3(0.37, 0.29, 0.41) * h_mm;  // off the surface's vertices
  std::array<int, 3> n;
  for (int a = 0; a < 3; ++a) n[a] = static_cast<int>(std::ceil((box.max - box.min)[a] / h_mm)) + 1;
  std::vector<std::vector<double>> columns(static_cast<std::size_t>(n[0]) * n[1]);
  for (const Tri& t : surface.triangles) {
    const Vec3& a = surface.vertices[t[0]];
    const Vec3& b = surface.vertices[t[1]];
    const Vec3& c = surface.vertices[t[2]];
    const double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (det == 0) continue;
    const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    for (int i = std::max(0, static_cast<int>((lo.x() - origin.x()) / h_mm - 1));
         i <= std::min(n[0] - 1, static_cast<int>((hi.x() - origin.x()) / h_mm)); ++i)
      for (int j = std::max(0, static_cast<int>((lo.y() - origin.y()) / h_mm - 1));
           j <= std::min(n[1] - 1, static_cast<int>((hi.y() - origin.y()) / h_mm)); ++j) {
        const double x = origin.x() + (i + 0.5) * h_mm, y = origin.y() + (j + 0.5) * h_mm;
        const double u = ((b.x() - x) * (c.y() - y) - (c.x() - x) * (b.y() - y)) / det;
        const double v = ((c.x() - x) * (a.y() - y) - (a.x() - x) * (c.y() - y)) / det;
        if (u < 0 || v < 0 || u + v > 1) continue;
        columns[static_cast<std::size_t>(i) * n[1] + j].push_back(u * a.z() + v * b.z() +
                                                                  (1 - u - v) * c.z());
      }
  }
  std::array<std::vector<double>, 3> coords;
  for (int a = 0; a < 3; ++a)
    for (int g = 0; g <= n[a]; ++g) coords[a].push_back(origin[a] + g * h_mm);
  return test::grid_tets(coords[0], coords[1], coords[2], [&](int i, int j, int k) {
    const double z = origin.z() + (k + 0.5) * h_mm;
    int above = 0;
    for (double c : columns[static_cast<std::size_t>(i) * n[1] + j]) above += c > z;
    return above % 2 == 1;
  });
}

std::string model_path(const std::string& name) {
  const char* dir = std::getenv("DHFCAST_MODELS_DIR");
  return std::string(dir ? dir : "../shared/models") + "/" + name;
}

// Arguments: number of directions, target number of tets. `mesher`: tets from tetrahedralize(),
// else a grid of cubes (six tets each) whose centres are inside.
void BM_Accessibility(benchmark::State& state, const std::string& model, bool mesher) {
  const TriMesh surface = load_solid(model_path(model)).mesh;
  const auto target_tets = static_cast<std::int32_t>(state.range(1));
  TetMesh tets;
  if (mesher) {
    TetOptions opts;
    opts.target_tets = target_tets;
    tets = tetrahedralize(surface, opts);
  } else {
    tets = voxel_tets(surface, std::cbrt(6.0 * signed_volume(surface) / target_tets));
  }
  const std::vector<Vec3> dirs = fibonacci_directions(static_cast<std::int32_t>(state.range(0)));
  std::int64_t rays = 0;
  for (auto _ : state) {
    const AccessibilityField f = compute_accessibility(surface, tets, dirs);
    rays = f.rays_cast;
    benchmark::DoNotOptimize(f.feasible.row(0));
  }
  state.counters["tets"] = static_cast<double>(tets.tets.size());
  state.counters["rays"] = static_cast<double>(rays);
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(rays) * state.iterations(),
                                                    benchmark::Counter::kIsRate);
}

BENCHMARK_CAPTURE(BM_Accessibility, bunny_grid, std::string("bunny.stl"), false)
    ->Args({512, 82000})
    ->Args({64, 82000})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->MeasureProcessCPUTime()
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Accessibility, bunny_mesher, std::string("bunny.stl"), true)
    ->Args({512, 82000})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->MeasureProcessCPUTime()
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
