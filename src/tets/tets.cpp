#include "dhfcast/tets.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "dhfcast/error.h"
#include "volume_mesher.h"

namespace dhfcast {

namespace {

// A run whose tet count is within this fraction of the target is kept.
constexpr double kCountTolerance = 0.2;
// Meshing runs at most: the first from the size estimate, then rescaled ones.
constexpr int kMaxRuns = 3;
// Mesh_3 makes more tets than the regular-tet estimate (boundary refinement, radius-edge bound
// rather than regular tets): the first run's sizes are scaled up by this measured factor.
constexpr double kInitialSizeFactor = 1.45;
// Lower bound on the measured count-vs-edge exponent: a boundary-bound count still falls.
constexpr double kMinExponent = 1.0;
// A run stops at this many vertices per target tet (a mesh has about one vertex per 5 to 6
// tets, so its tets stay within about 100 times the target): a mesh that would grow further
// (feature edges too close together to protect, a model metres across at a boundary distance in
// mm) ends the stage instead of the memory. Where the boundary distance sets the size, a mesh
// has several times the target (the shared elephant at 8000 tets: over 2 vertices per target
// tet).
constexpr double kMaxVerticesPerTargetTet = 20.0;
// A run stops after this long (plus this much per target tet): Mesh_3 takes seconds for 50 000
// tets, so this is a runaway's guard, not a limit an ordinary model meets on a slow machine.
constexpr double kMesherSeconds = 60.0;
constexpr double kMesherSecondsPerTargetTet = 0.002;

// Sizes for tets of edge `edge_mm`: a regular tet's circumradius is edge * sqrt(6) / 4, a
// boundary triangle's edge / sqrt(3).
detail::MeshSizes sizes_for_edge(double edge_mm, double facet_distance_mm) {
  return {.facet_size_mm = edge_mm / std::sqrt(3.0),
          .facet_distance_mm = facet_distance_mm,
          .cell_size_mm = edge_mm * std::sqrt(6.0) / 4.0};
}

// Number of face-connected components of the tets. Pre: neighbors filled.
std::int32_t num_components(const TetMesh& mesh) {
  const std::int32_t n = static_cast<std::int32_t>(mesh.tets.size());
  std::vector<char> seen(n, 0);
  std::vector<std::int32_t> stack;
  std::int32_t components = 0;
  for (std::int32_t s = 0; s < n; ++s) {
    if (seen[s]) continue;
    ++components;
    seen[s] = 1;
    stack.push_back(s);
    while (!stack.empty()) {
      const std::int32_t t = stack.back();
      stack.pop_back();
      for (const std::int32_t u : mesh.neighbors[t])
        if (u >= 0 && !seen[u]) seen[u] = 1, stack.push_back(u);
    }
  }
  return components;
}

// The boundary faces form a closed surface when every directed edge is matched by its reverse.
// Pre: neighbors filled.
bool boundary_is_closed(const TetMesh& mesh) {
  std::unordered_map<std::uint64_t, std::int32_t> balance;
  for (std::size_t t = 0; t < mesh.tets.size(); ++t)
    for (int i = 0; i < 4; ++i) {
      if (mesh.neighbors[t][i] >= 0) continue;
      for (int e = 0; e < 3; ++e) {
        const std::int32_t a = mesh.tets[t][kTetFaces[i][e]];
        const std::int32_t b = mesh.tets[t][kTetFaces[i][(e + 1) % 3]];
        const std::uint64_t key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) |
                                  static_cast<std::uint32_t>(std::max(a, b));
        balance[key] += a < b ? 1 : -1;
      }
    }
  for (const auto& [key, count] : balance)
    if (count != 0) return false;
  return true;
}

// Boundary-face vertices and centroids: where the boundary is farthest from the input surface.
std::vector<Vec3> boundary_samples(const TetMesh& mesh) {
  std::vector<Vec3> points;
  std::vector<char> used(mesh.vertices.size(), 0);
  for (std::size_t t = 0; t < mesh.tets.size(); ++t)
    for (int i = 0; i < 4; ++i) {
      if (mesh.neighbors[t][i] >= 0) continue;
      Vec3 centroid = Vec3::Zero();
      for (const int k : kTetFaces[i]) {
        const std::int32_t v = mesh.tets[t][k];
        centroid += mesh.vertices[v] / 3.0;
        if (!used[v]) used[v] = 1, points.push_back(mesh.vertices[v]);
      }
      points.push_back(centroid);
    }
  return points;
}

}  // namespace

void TetOptions::validate() const {
  require_option(std::isfinite(max_mesher_seconds) && max_mesher_seconds >= 0,
                 "tets max_mesher_seconds must be >= 0");
  require_option(target_tets >= 100 && target_tets <= 5'000'000,
                 "--tets must be between 100 and 5000000");
  require_option(std::isfinite(facet_distance_mm) && facet_distance_mm > 0,
                 "--facet-distance must be > 0");
}

TetMesh tetrahedralize(const TriMesh& surface, const TetOptions& opts) {
  opts.validate();
  const double volume_mm3 = signed_volume(surface);
  if (!(volume_mm3 > 0.0))
    throw Error(ErrorCode::TetrahedralizationFailed,
                "tets: the surface encloses no volume (signed volume " +
                    std::to_string(volume_mm3) + " mm3)");

  // --- 1. mesh, rescaling the sizes until the count is near the target ---
  // Tets of mean volume V / N are regular tets of edge cbrt(6 sqrt(2) V / N).
  const double target = static_cast<double>(opts.target_tets);
  double edge_mm = kInitialSizeFactor * std::cbrt(6.0 * std::sqrt(2.0) * volume_mm3 / target);
  const Box3 box = bounding_box(surface.vertices);
  const double size_mm = (box.max - box.min).maxCoeff();  // for the messages below
  detail::VolumeMesher mesher(surface, opts.seed);
  // The count falls like edge^-3 inside but slower where the boundary (facet distance) sets the
  // size: after two runs, the exponent is measured instead (secant on log count vs log edge).
  double exponent = 3.0;
  double last_log_edge = 0.0, last_log_count = 0.0;
  const auto max_vertices = static_cast<std::size_t>(kMaxVerticesPerTargetTet * target);
  const double max_seconds = opts.max_mesher_seconds > 0.0
                                 ? opts.max_mesher_seconds
                                 : kMesherSeconds + kMesherSecondsPerTargetTet * target;
  for (int run = 0; run < kMaxRuns; ++run) {
    const auto [count, capped, timed_out] =
        mesher.refine(sizes_for_edge(edge_mm, opts.facet_distance_mm), max_vertices, max_seconds);
    if (timed_out) {
      char seconds[32];
      std::snprintf(seconds, sizeof seconds, "%.0f", max_seconds);
      throw Error(ErrorCode::TetrahedralizationFailed,
                  std::string("tets: the volume mesher ran for over ") + seconds +
                      " s for --tets " + std::to_string(opts.target_tets) +
                      " and was stopped (features of the model too small or too close together "
                      "to mesh, such as sharp edges almost touching; try a larger "
                      "--facet-distance)");
    }
    if (capped && run + 1 == kMaxRuns) {
      // The boundary's distance bound is in mm: on a model metres across it asks for millions
      // of boundary facets.
      throw Error(
          ErrorCode::TetrahedralizationFailed,
          "tets: the volume mesher went past " + std::to_string(max_vertices) +
              " vertices for --tets " + std::to_string(opts.target_tets) + " and was stopped (" +
              (size_mm > 2000.0 ? "the model is " + std::to_string(std::lround(size_mm / 1000.0)) +
                                      " m long: is it in mm? try --size MM or --units, or a larger "
                                      "--facet-distance)"
                                : "features of the model too small or too close together for that "
                                  "size; try a larger --facet-distance or more --tets)"));
    }
    if (count == 0 && !capped)
      throw Error(ErrorCode::TetrahedralizationFailed,
                  "tets: the mesher produced no tets (is the surface closed and outward?)");
    // An unfinished run counts as at least its budget's tets (about 5 per vertex): the next run
    // is coarser.
    const double made =
        capped ? std::max(static_cast<double>(count), 5.0 * static_cast<double>(max_vertices))
               : static_cast<double>(count);
    const double ratio = made / target;
    if (!capped && (std::abs(ratio - 1.0) <= kCountTolerance || run + 1 == kMaxRuns)) break;
    const double log_edge = std::log(edge_mm), log_count = std::log(made);
    if (run > 0 && log_edge != last_log_edge)
      exponent =
          std::clamp((last_log_count - log_count) / (log_edge - last_log_edge), kMinExponent, 3.0);
    last_log_edge = log_edge;
    last_log_count = log_count;
    edge_mm *= std::pow(ratio, 1.0 / exponent);
  }

  // --- 2. remove slivers, extract, orient ---
  mesher.exude();
  TetMesh mesh = mesher.extract();
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(mesh.tets.size()); ++t) {
    if (tet_volume(mesh, t) < 0.0) std::swap(mesh.tets[t][2], mesh.tets[t][3]);
    if (!(tet_volume(mesh, t) > 0.0))
      throw Error(ErrorCode::TetrahedralizationFailed,
                  "tets: the mesher produced a flat tet (" + std::to_string(t) + ")");
  }

  // --- 3. check it is one closed volume, measure the boundary's deviation ---
  build_tet_adjacency(mesh);
  const std::int32_t components = num_components(mesh);
  if (components != 1) {
    // The input is one solid (load_solid() checks its shells), so thin parts were lost: most
    // often because the model is tiny in mm, its units wrong.
    char size[32];
    std::snprintf(size, sizeof size, "%.3g", size_mm);
    throw Error(ErrorCode::TetrahedralizationFailed,
                "tets: the volume mesh has " + std::to_string(components) +
                    " disconnected pieces: thin parts of this model, " + size +
                    " mm long, were lost" +
                    (size_mm < 20.0 ? "; is it in mm? try --size MM or --units"
                                    : "; try a smaller --facet-distance or more --tets"));
  }
  if (!boundary_is_closed(mesh))
    throw Error(ErrorCode::TetrahedralizationFailed,
                "tets: the volume mesh's boundary is not a closed surface");
  mesh.boundary_tolerance_mm = mesher.max_distance_to_surface(boundary_samples(mesh));
  return mesh;
}

}  // namespace dhfcast
