#include "dhfcast/access.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>
#include <queue>
#include <thread>

#include "dhfcast/error.h"
#include "dhfcast/tolerance.h"
#include "parallel_rays.h"
#include "ray_scene.h"
#include "tet_samples.h"

namespace dhfcast {

namespace {

using detail::Crossing;
using detail::ParallelRays;
using detail::RayScene;

// Is a sample p DHF-accessible along the unit direction d (see compute_accessibility)?
class SampleTester {
 public:
  SampleTester(const RayScene& scene, const ParallelRays& rays, const Vec3& d, double epsilon_mm)
      : scene_(scene),
        rays_(rays),
        d_(d),
        eps_(epsilon_mm),
        // Crossings closer than this along one ray are the same point (float round-off).
        merge_mm_(1e-6 * scene.diagonal_mm()) {}

  bool accessible(const Vec3& p) {
    rays_.crossings(p, merge_mm_, crossings_);
    if (crossings_.empty()) return true;
    // Breakpoints of the ray from its first exit to its last crossing.
    breaks_.clear();
    bool start_on_surface = true;
    std::size_t first = 0;
    if (crossings_[0].sign < 0) {
      if (crossings_[0].t <= eps_) {
        first = 1;  // p lies just outside the surface but belongs to the solid
      } else {
        breaks_.push_back(0.0);  // p is outside: it is its own first exit
        start_on_surface = false;
      }
    }
    for (std::size_t i = first; i < crossings_.size(); ++i) breaks_.push_back(crossings_[i].t);
    if (breaks_.size() < 2) return true;
    if (eps_ <= 0.0) return false;

    // Cheap rejection first: the middle of every stretch too long to pass trivially.
    for (std::size_t i = 0; i + 1 < breaks_.size(); ++i) {
      const double len = breaks_[i + 1] - breaks_[i];
      if (len > 2 * eps_ && far(p + d_ * (0.5 * (breaks_[i] + breaks_[i + 1])))) return false;
    }
    for (std::size_t i = 0; i + 1 < breaks_.size(); ++i) {
      // Points within eps of a crossing are within eps of the surface.
      const bool on_surface = i > 0 || start_on_surface;
      double t = on_surface ? breaks_[i] + eps_ : breaks_[i];
      const double end = breaks_[i + 1] - eps_;
      while (t < end) {
        const double r = scene_.distance_below(p + d_ * t, eps_);
        if (r >= eps_) return false;
        // Every point within eps - r of this one is within eps of the surface.
        t += std::max(eps_ - r, 0.5 * eps_);
      }
    }
    return true;
  }

 private:
  bool far(const Vec3& q) const { return !scene_.near(q, eps_); }

  const RayScene& scene_;
  const ParallelRays& rays_;
  const Vec3 d_;
  const double eps_, merge_mm_;
  std::vector<Crossing> crossings_;
  std::vector<double> breaks_;
};

// Fraction of cosine-weighted hemisphere rays around n that escape from `origin`.
double openness(const RayScene& scene, const Vec3& origin, const Vec3& n,
                const std::vector<Vec3>& local_dirs) {
  const Vec3 helper = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 u = n.cross(helper).normalized();
  const Vec3 v = n.cross(u);
  int open = 0;
  for (const Vec3& l : local_dirs)
    open += scene.escapes(origin, (u * l.x() + v * l.y() + n * l.z()).normalized());
  return static_cast<double>(open) / static_cast<double>(local_dirs.size());
}

// Fixed cosine-weighted directions on the hemisphere z > 0 (a Fibonacci spiral on the disk,
// lifted): deterministic, so seam visibility is reproducible.
std::vector<Vec3> hemisphere_directions(int n) {
  std::vector<Vec3> dirs;
  for (int i = 0; i < n; ++i) {
    const double u = (i + 0.5) / n;
    const double g = i * std::numbers::phi;
    const double phi = 2.0 * std::numbers::pi * (g - std::floor(g));
    const double r = std::sqrt(u);
    dirs.emplace_back(r * std::cos(phi), r * std::sin(phi), std::sqrt(1.0 - u));
  }
  return dirs;
}

std::vector<SeamEdge> seam_edges(const TetMesh& tets, const RayScene& scene) {
  // Every boundary face contributes its three edges; an edge met twice is a surface edge.
  struct Entry {
    std::array<std::int32_t, 2> edge;
    std::int32_t tet;
    std::int32_t face;  // local face index
  };
  std::vector<Entry> entries;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(tets.tets.size()); ++t)
    for (int i = 0; i < 4; ++i) {
      if (tets.neighbors[t][i] != -1) continue;
      for (int k = 0; k < 3; ++k) {
        const std::int32_t a = tets.tets[t][kTetFaces[i][k]];
        const std::int32_t b = tets.tets[t][kTetFaces[i][(k + 1) % 3]];
        entries.push_back({{std::min(a, b), std::max(a, b)}, t, i});
      }
    }
  std::sort(entries.begin(), entries.end(), [](const Entry& x, const Entry& y) {
    return x.edge != y.edge ? x.edge < y.edge : x.tet < y.tet;
  });
  auto face_normal = [&](const Entry& e) {
    return tet_face_normal(tets, e.tet, e.face).normalized();
  };

  std::vector<SeamEdge> seams;
  std::vector<std::pair<Vec3, Vec3>> rays;  // origin, normal
  const double offset_mm = 1e-4 * scene.diagonal_mm() + tets.boundary_tolerance_mm;
  for (std::size_t i = 0; i < entries.size();) {
    std::size_t j = i + 1;
    while (j < entries.size() && entries[j].edge == entries[i].edge) ++j;
    // Non-manifold boundary edges (more than two faces) are no place for a seam.
    if (j - i == 2 && entries[i].tet != entries[i + 1].tet) {
      const Vec3& a = tets.vertices[entries[i].edge[0]];
      const Vec3& b = tets.vertices[entries[i].edge[1]];
      Vec3 n = face_normal(entries[i]) + face_normal(entries[i + 1]);
      n = n.norm() > 1e-12 ? n.normalized() : face_normal(entries[i]);
      seams.push_back({entries[i].tet, entries[i + 1].tet, (b - a).norm(), 0.0});
      rays.emplace_back(0.5 * (a + b) + offset_mm * n, n);
    }
    i = j;
  }

  const std::vector<Vec3> local = hemisphere_directions(64);
  std::vector<double> open(seams.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, seams.size(), 64),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i)
                        open[i] = openness(scene, rays[i].first, rays[i].second, local);
                    });
  if (!open.empty()) {
    const auto [lo, hi] = std::minmax_element(open.begin(), open.end());
    const double min = *lo, max = *hi;
    for (std::size_t i = 0; i < seams.size(); ++i)
      seams[i].visibility = max > min ? (open[i] - min) / (max - min) : 1.0;
  }
  return seams;
}

}  // namespace

void AccessibilityOptions::validate() const { validate_epsilon(epsilon_mm); }

AccessibilityField compute_accessibility(const TriMesh& surface, const TetMesh& tets,
                                         const std::vector<Vec3>& directions,
                                         const AccessibilityOptions& opts,
                                         const Progress& progress) {
  opts.validate();
  if (directions.empty())
    throw Error(ErrorCode::InvalidOptions, "access: at least one direction is needed");
  const std::int32_t num_tets = static_cast<std::int32_t>(tets.tets.size());
  const std::int32_t num_dirs = static_cast<std::int32_t>(directions.size());
  DHF_ASSERT(tets.neighbors.size() == tets.tets.size(), "tet adjacency not built");
  std::vector<Vec3> dirs(directions);
  for (Vec3& d : dirs) d.normalize();

  // Triangles close in space are close in memory, for both kinds of ray queries.
  const TriMesh sorted_surface = detail::morton_sorted(surface);
  const RayScene scene(sorted_surface);
  const detail::TetSamples samples = detail::tet_samples(tets);
  AccessibilityField field;
  field.feasible = DirectionBits(num_tets, num_dirs);
  DirectionBits& feasible = field.feasible;
  const std::int32_t words = feasible.words_per_tet();

  // --- 1. cast rays, one direction per task ---
  // First a cheap pass over all samples settles most rays from per-cell depth bounds.
  // Then tets are visited in Morton order: a tet with a sample already known to be blocked is
  // infeasible at once; otherwise its unsettled samples are tested vertices first (a vertex is
  // shared by ~20 tets) and the tet is infeasible at its first blocked sample, so its
  // remaining samples are never tested. Sample results are memoized per direction. Each
  // direction writes its own column and the set of rays cast depends on the direction only:
  // results do not depend on the scheduling.
  std::vector<std::int32_t> tet_order(num_tets);
  for (std::int32_t t = 0; t < num_tets; ++t)
    tet_order[samples.of_tet[t][14] - samples.kind_begin[detail::kTetSample]] = t;
  std::vector<std::array<std::int32_t, 15>> ordered_samples(num_tets);  // of_tet in that order
  for (std::int32_t i = 0; i < num_tets; ++i) ordered_samples[i] = samples.of_tet[tet_order[i]];
  const std::int32_t column_words = (num_tets + 63) / 64;
  std::vector<std::vector<std::uint64_t>> columns(num_dirs);
  struct Scratch {  // buffers reused across directions
    ParallelRays rays;
    std::vector<std::uint8_t> state;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  std::atomic<std::int64_t> rays{0};
  std::atomic<std::int32_t> done{0};
  const std::size_t num_samples = samples.points.size();
  // One loop over all directions, so no thread waits for another before the end; progress is
  // reported by the calling thread whenever it finishes a direction.
  const std::thread::id caller = std::this_thread::get_id();
  tbb::parallel_for(
      tbb::blocked_range<std::int32_t>(0, num_dirs, 1),
      [&](const tbb::blocked_range<std::int32_t>& r) {
        Scratch& local = scratch.local();
        ParallelRays& parallel = local.rays;
        std::vector<std::uint8_t>& state = local.state;
        for (std::int32_t d = r.begin(); d != r.end(); ++d) {
          parallel.project(sorted_surface, dirs[d]);
          SampleTester tester(scene, parallel, dirs[d], opts.epsilon_mm);
          state.resize(num_samples);
          parallel.settle(samples.points, opts.epsilon_mm, state.data());
          std::vector<std::uint64_t>& column = columns[d];
          column.assign(column_words, 0);
          std::int64_t cast = static_cast<std::int64_t>(num_samples);
          for (std::int32_t i = 0; i < num_tets; ++i) {
            const std::array<std::int32_t, 15>& slots = ordered_samples[i];
            bool ok = std::none_of(slots.begin(), slots.end(), [&](std::int32_t s) {
              return state[s] == ParallelRays::kBlocked;
            });
            for (std::size_t k = 0; ok && k < slots.size(); ++k) {
              std::uint8_t& st = state[slots[k]];
              if (st != ParallelRays::kUnknown) continue;
              st = tester.accessible(samples.points[slots[k]]) ? ParallelRays::kOpen
                                                               : ParallelRays::kBlocked;
              ok = st == ParallelRays::kOpen;
              ++cast;
            }
            const std::int32_t t = tet_order[i];
            if (ok) column[t >> 6] |= std::uint64_t{1} << (t & 63);
          }
          rays += cast;
          const std::int32_t finished = ++done;
          if (progress && std::this_thread::get_id() == caller)
            progress(0.95 * finished / num_dirs);
        }
      });
  // Columns (per direction) to rows (per tet).
  tbb::parallel_for(tbb::blocked_range<std::int32_t>(0, num_tets, 1024),
                    [&](const tbb::blocked_range<std::int32_t>& r) {
                      for (std::int32_t t = r.begin(); t != r.end(); ++t) {
                        std::uint64_t* row = feasible.row(t);
                        for (std::int32_t d = 0; d < num_dirs; ++d)
                          if ((columns[d][t >> 6] >> (t & 63)) & 1)
                            row[d >> 6] |= std::uint64_t{1} << (d & 63);
                      }
                    });
  columns.clear();

  // --- 2. erosion (paper §4.3.1): AND over the tets around each vertex, then per tet ---
  field.eroded = DirectionBits(num_tets, num_dirs);
  std::vector<std::uint64_t> vertex_rows(tets.vertices.size() * words, ~std::uint64_t{0});
  for (std::int32_t t = 0; t < num_tets; ++t)
    for (std::int32_t v : tets.tets[t])
      for (std::int32_t w = 0; w < words; ++w)
        vertex_rows[static_cast<std::size_t>(v) * words + w] &= feasible.row(t)[w];
  for (std::int32_t t = 0; t < num_tets; ++t)
    for (std::int32_t w = 0; w < words; ++w) {
      std::uint64_t x = ~std::uint64_t{0};
      for (std::int32_t v : tets.tets[t]) x &= vertex_rows[static_cast<std::size_t>(v) * words + w];
      field.eroded.row(t)[w] = x;
    }

  // --- 3. seam edges and their visibility (paper §4.2.2) ---
  field.seam_edges = seam_edges(tets, scene);
  field.rays_cast = rays + static_cast<std::int64_t>(field.seam_edges.size()) * 64;
  if (progress) progress(1.0);
  return field;
}

InfeasibleDistance::InfeasibleDistance(const TetMesh& tets) : tets_(tets) {
  DHF_ASSERT(tets.neighbors.size() == tets.tets.size(), "tet adjacency not built");
  const std::size_t n = tets.tets.size();
  std::vector<Vec3> centre(n);
  for (std::size_t t = 0; t < n; ++t) {
    const Tet& k = tets.tets[t];
    centre[t] = 0.25 * (tets.vertices[k[0]] + tets.vertices[k[1]] + tets.vertices[k[2]] +
                        tets.vertices[k[3]]);
  }
  step_mm_.resize(n);
  for (std::size_t t = 0; t < n; ++t)
    for (int f = 0; f < 4; ++f) {
      const std::int32_t u = tets.neighbors[t][f];
      step_mm_[t][f] = u >= 0 ? (centre[u] - centre[t]).norm() : 0.0;
    }
}

std::vector<float> InfeasibleDistance::operator()(const DirectionBits& feasible,
                                                  std::int32_t direction, double max_mm) const {
  const auto n = static_cast<std::int32_t>(tets_.tets.size());
  DHF_ASSERT(direction >= 0 && direction < feasible.num_directions(), "direction out of range");
  std::vector<float> dist(n, static_cast<float>(max_mm));
  if (n == 0) return dist;
  // Multi-source Dijkstra in double (float only for the result), lazy deletion.
  std::vector<double> best(n, max_mm);
  using Item = std::pair<double, std::int32_t>;
  std::vector<Item> heap_storage;
  heap_storage.reserve(n);
  std::priority_queue<Item, std::vector<Item>, std::greater<>> heap(std::greater<>{},
                                                                    std::move(heap_storage));
  for (std::int32_t t = 0; t < n; ++t)
    if (!feasible.get(t, direction)) {
      best[t] = 0.0;
      heap.emplace(0.0, t);
    }
  while (!heap.empty()) {
    const auto [d, t] = heap.top();
    heap.pop();
    if (d > best[t]) continue;
    for (int f = 0; f < 4; ++f) {
      const std::int32_t u = tets_.neighbors[t][f];
      if (u < 0) continue;
      const double du = d + step_mm_[t][f];
      if (du < best[u]) {
        best[u] = du;
        heap.emplace(du, u);
      }
    }
  }
  for (std::int32_t t = 0; t < n; ++t) dist[t] = static_cast<float>(best[t]);
  return dist;
}

}  // namespace dhfcast
