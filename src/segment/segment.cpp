#include "dhfcast/segment.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <string>
#include <tuple>

#include "alpha_expansion.h"
#include "dhfcast/error.h"
#include "reduce_parts.h"

namespace dhfcast {
namespace {

// Candidates solved on a small covering label set, besides the randomized restarts.
constexpr std::int32_t kCoveringCandidates = 12;

// Directions kept as labels, ascending. Two directions with the same feasible set give the same
// data costs everywhere: only the lowest index is kept. A direction whose feasible set is a
// strict subset of another's costs at least as much on every tet (it is closer to its
// infeasible region), and moving its tets to the other never raises smoothness or label costs:
// it is dropped. So is a direction feasible nowhere.
std::vector<std::int32_t> candidate_directions(const DirectionBits& feasible) {
  const std::int32_t num_tets = feasible.num_tets();
  const std::int32_t num_dirs = feasible.num_directions();
  const std::size_t words = (static_cast<std::size_t>(num_tets) + 63) / 64;
  // Transpose the per-tet rows into one bitset of tets per direction.
  std::vector<std::uint64_t> cols(words * num_dirs, 0);
  for (std::int32_t t = 0; t < num_tets; ++t) {
    const std::uint64_t* row = feasible.row(t);
    for (std::int32_t w = 0; w < feasible.words_per_tet(); ++w) {
      for (std::uint64_t bits = row[w]; bits != 0; bits &= bits - 1) {
        const std::int32_t d = w * 64 + std::countr_zero(bits);
        if (d < num_dirs) cols[d * words + t / 64] |= 1ull << (t % 64);
      }
    }
  }
  std::vector<std::int64_t> size(num_dirs, 0);
  for (std::int32_t d = 0; d < num_dirs; ++d) {
    for (std::size_t w = 0; w < words; ++w) size[d] += std::popcount(cols[d * words + w]);
  }
  std::vector<char> keep(num_dirs, 0);
  tbb::parallel_for(std::int32_t{0}, num_dirs, [&](std::int32_t d) {
    if (size[d] == 0) return;
    const std::uint64_t* fd = cols.data() + d * words;
    for (std::int32_t e = 0; e < num_dirs; ++e) {
      if (e == d || size[e] < size[d] || (size[e] == size[d] && e > d)) continue;
      const std::uint64_t* fe = cols.data() + e * words;
      std::size_t w = 0;
      while (w < words && (fd[w] & ~fe[w]) == 0) ++w;
      if (w == words) return;  // F_d is inside F_e: identical (e < d) or strictly smaller
    }
    keep[d] = 1;
  });
  std::vector<std::int32_t> out;
  for (std::int32_t d = 0; d < num_dirs; ++d) {
    if (keep[d]) out.push_back(d);
  }
  return out;
}

// Parts of a labeling (connected components of equal label through shared faces; unlabeled
// tets belong to none) and the variance of their volumes.
struct PartStats {
  std::int32_t parts = 0;
  double volume_variance_mm6 = 0.0;
};

PartStats part_stats(const TetMesh& tets, const std::vector<double>& volume_mm3,
                     const std::vector<std::int32_t>& label) {
  const auto num_tets = static_cast<std::int32_t>(tets.tets.size());
  std::vector<char> seen(num_tets, 0);
  std::vector<std::int32_t> stack;
  std::vector<double> part_volume_mm3;
  for (std::int32_t s = 0; s < num_tets; ++s) {
    if (seen[s] || label[s] < 0) continue;
    double v = 0.0;
    seen[s] = 1;
    stack.assign(1, s);
    while (!stack.empty()) {
      const std::int32_t t = stack.back();
      stack.pop_back();
      v += volume_mm3[t];
      for (std::int32_t u : tets.neighbors[t]) {
        if (u >= 0 && !seen[u] && label[u] == label[t]) {
          seen[u] = 1;
          stack.push_back(u);
        }
      }
    }
    part_volume_mm3.push_back(v);
  }
  PartStats out;
  out.parts = static_cast<std::int32_t>(part_volume_mm3.size());
  if (out.parts == 0) return out;
  double mean = 0.0;
  for (double v : part_volume_mm3) mean += v;
  mean /= out.parts;
  for (double v : part_volume_mm3) out.volume_variance_mm6 += (v - mean) * (v - mean);
  out.volume_variance_mm6 /= out.parts;
  return out;
}

// Label sets that together allow every node, built greedily: each next label allows the most
// volume not yet allowed. Set c starts from the label with the c-th largest feasible volume, so
// the sets differ. Identical sets are returned once.
std::vector<std::vector<std::int32_t>> covering_label_sets(const LabelProblem& problem,
                                                           const std::vector<double>& volume_mm3,
                                                           std::int32_t count) {
  const std::int32_t n = problem.num_nodes, k = problem.num_labels;
  const std::size_t words = (static_cast<std::size_t>(n) + 63) / 64;
  std::vector<std::uint64_t> cols(words * k, 0);
  std::vector<double> feasible_mm3(k, 0.0);
  tbb::parallel_for(std::int32_t{0}, k, [&](std::int32_t l) {
    const double* d = problem.data.data() + static_cast<std::size_t>(l) * n;
    for (std::int32_t i = 0; i < n; ++i) {
      if (std::isfinite(d[i])) {
        cols[l * words + i / 64] |= 1ull << (i % 64);
        feasible_mm3[l] += volume_mm3[i];
      }
    }
  });
  std::vector<std::int32_t> by_volume(k);
  std::iota(by_volume.begin(), by_volume.end(), 0);
  std::stable_sort(by_volume.begin(), by_volume.end(), [&](std::int32_t a, std::int32_t b) {
    return feasible_mm3[a] > feasible_mm3[b];
  });
  std::vector<std::vector<std::int32_t>> sets;
  for (std::int32_t c = 0; c < std::min(count, k); ++c) {
    std::vector<std::int32_t> set{by_volume[c]};
    std::vector<std::uint64_t> open(words, ~0ull);  // nodes no label of the set allows
    if (n % 64 != 0) open.back() = (1ull << (n % 64)) - 1;
    for (;;) {
      for (std::size_t w = 0; w < words; ++w) open[w] &= ~cols[set.back() * words + w];
      if (std::all_of(open.begin(), open.end(), [](std::uint64_t w) { return w == 0; })) break;
      std::vector<double> gain_mm3(k, 0.0);
      tbb::parallel_for(std::int32_t{0}, k, [&](std::int32_t l) {
        for (std::size_t w = 0; w < words; ++w)
          for (std::uint64_t bits = cols[l * words + w] & open[w]; bits != 0; bits &= bits - 1)
            gain_mm3[l] += volume_mm3[w * 64 + std::countr_zero(bits)];
      });
      set.push_back(static_cast<std::int32_t>(std::max_element(gain_mm3.begin(), gain_mm3.end()) -
                                              gain_mm3.begin()));
    }
    std::sort(set.begin(), set.end());
    if (std::find(sets.begin(), sets.end(), set) == sets.end()) sets.push_back(std::move(set));
  }
  return sets;
}

// The lines of each label through the nodes (LineSteps), made when an expansion first needs them:
// one step from a tet's barycentre along a direction leaves through the face whose outward
// area vector has the largest component along it.
class LineStepsCache {
 public:
  LineStepsCache(const TetMesh& tets, const std::vector<std::int32_t>& tet_of,
                 const std::vector<std::int32_t>& node_of, std::vector<Vec3> label_direction)
      : tets_(tets),
        tet_of_(tet_of),
        node_of_(node_of),
        direction_(std::move(label_direction)),
        once_(std::make_unique<std::once_flag[]>(direction_.size())),
        steps_(direction_.size()) {
    face_area_.resize(tet_of.size());
    for (std::size_t i = 0; i < tet_of.size(); ++i) {
      const Tet& tet = tets.tets[tet_of[i]];
      for (int f = 0; f < 4; ++f) {
        const Vec3& a = tets.vertices[tet[kTetFaces[f][0]]];
        const Vec3& b = tets.vertices[tet[kTetFaces[f][1]]];
        const Vec3& c = tets.vertices[tet[kTetFaces[f][2]]];
        face_area_[i][f] = 0.5 * (b - a).cross(c - a);
      }
    }
  }

  const LineSteps& operator()(std::int32_t l) const {
    std::call_once(once_[l], [&] { make(l); });
    return steps_[l];
  }

 private:
  void make(std::int32_t l) const {
    const Vec3& d = direction_[l];
    const std::size_t n = tet_of_.size();
    LineSteps& s = steps_[l];
    s.up.assign(n, -1);
    s.down.assign(n, -1);
    for (std::size_t i = 0; i < n; ++i) {
      int up = -1, down = -1;
      double most = 0.0, least = 0.0;
      for (int f = 0; f < 4; ++f) {
        const double x = face_area_[i][f].dot(d);
        if (x > most) most = x, up = f;
        if (x < least) least = x, down = f;
      }
      const auto& neighbors = tets_.neighbors[tet_of_[i]];
      if (up >= 0 && neighbors[up] >= 0) s.up[i] = node_of_[neighbors[up]];
      if (down >= 0 && neighbors[down] >= 0) s.down[i] = node_of_[neighbors[down]];
    }
  }

  const TetMesh& tets_;
  const std::vector<std::int32_t>& tet_of_;
  const std::vector<std::int32_t>& node_of_;
  std::vector<Vec3> direction_;
  std::vector<std::array<Vec3, 4>> face_area_;
  std::unique_ptr<std::once_flag[]> once_;
  mutable std::vector<LineSteps> steps_;
};

// Minimizes eq. 1 with only the labels in `subset` (which together allow every node); returns
// the labeling in the full problem's labels.
std::vector<std::int32_t> solve_with_labels(const LabelProblem& problem,
                                            const std::vector<std::int32_t>& subset,
                                            std::uint64_t seed) {
  const std::size_t n = static_cast<std::size_t>(problem.num_nodes);
  LabelProblem sub;
  sub.num_nodes = problem.num_nodes;
  sub.num_labels = static_cast<std::int32_t>(subset.size());
  sub.edges = problem.edges;
  if (problem.line_steps)
    sub.line_steps = [&](std::int32_t l) -> const LineSteps& {
      return problem.line_steps(subset[l]);
    };
  for (std::int32_t l : subset) {
    sub.data.insert(sub.data.end(), problem.data.begin() + l * n,
                    problem.data.begin() + (l + 1) * n);
    sub.label_cost.push_back(problem.label_cost[l]);
  }
  std::vector<std::int32_t> labels = minimize_labeling(sub, seed, 1);
  for (std::int32_t& l : labels) l = subset[l];
  return labels;
}

}  // namespace

void SegmentOptions::validate() const {
  require_option(std::isfinite(alpha) && alpha >= 0, "--alpha must be >= 0");
  require_option(std::isfinite(c_mm) && c_mm > 0, "--c must be > 0");
  require_option(std::isfinite(beta_mm) && beta_mm >= 0, "--beta must be >= 0");
  require_option(std::isfinite(lambda) && lambda >= 0, "--lambda must be >= 0");
  require_option(restarts >= 1 && restarts <= 1000, "--restarts must be between 1 and 1000");
}

Labeling segment(const TetMesh& tets, const AccessibilityField& field,
                 const std::vector<Vec3>& directions, const SegmentOptions& opts,
                 const Progress& progress) {
  opts.validate();
  const auto num_tets = static_cast<std::int32_t>(tets.tets.size());
  if (field.feasible.num_tets() != num_tets || tets.neighbors.size() != tets.tets.size()) {
    throw Error(ErrorCode::InvalidInput,
                "segmentation: the accessibility field or the adjacency does not match the tets");
  }
  Labeling out;
  out.label.assign(num_tets, -1);

  // --- 1. labels: directions left after removing duplicate and dominated feasible sets ---
  const std::vector<std::int32_t> dirs = candidate_directions(field.feasible);
  const auto num_labels = static_cast<std::int32_t>(dirs.size());
  out.candidate_labels = num_labels;

  // --- 2. nodes: tets feasible for some direction (hence for some candidate) ---
  std::vector<std::int32_t> node_of(num_tets, -1), tet_of;
  for (std::int32_t t = 0; t < num_tets; ++t) {
    if (field.feasible.count(t) > 0) {
      node_of[t] = static_cast<std::int32_t>(tet_of.size());
      tet_of.push_back(t);
    }
  }
  const auto num_nodes = static_cast<std::int32_t>(tet_of.size());
  if (num_nodes == 0) {
    if (progress) progress(1.0);
    return out;
  }
  std::vector<double> volume_mm3(num_tets);
  for (std::int32_t t = 0; t < num_tets; ++t) volume_mm3[t] = tet_volume(tets, t);

  // --- 3. data cost (eq. 3): Volume * alpha * exp(-dist^2 / 2c^2) where feasible ---
  LabelProblem problem;
  problem.num_nodes = num_nodes;
  problem.num_labels = num_labels;
  problem.data.assign(static_cast<std::size_t>(num_nodes) * num_labels,
                      std::numeric_limits<double>::infinity());
  const double two_c2 = 2.0 * opts.c_mm * opts.c_mm;
  const InfeasibleDistance distance_to_infeasible(tets);
  tbb::parallel_for(std::int32_t{0}, num_labels, [&](std::int32_t l) {
    const std::int32_t d = dirs[l];
    // Beyond 4c the Gaussian is ~0 (paper §4.2.1): the distance is capped there.
    const std::vector<float> dist_mm = distance_to_infeasible(field.feasible, d, 4.0 * opts.c_mm);
    double* data = problem.data.data() + static_cast<std::size_t>(l) * num_nodes;
    for (std::int32_t n = 0; n < num_nodes; ++n) {
      const std::int32_t t = tet_of[n];
      if (!field.feasible.get(t, d)) continue;
      const double dist = dist_mm[t];
      data[n] = volume_mm3[t] * opts.alpha * std::exp(-dist * dist / two_c2);
    }
  });

  // --- 4. smoothness (§4.2.2): shared faces, and surface edges between two tets' faces ---
  for (std::int32_t n = 0; n < num_nodes; ++n) {
    const std::int32_t t = tet_of[n];
    for (int f = 0; f < 4; ++f) {
      const std::int32_t u = tets.neighbors[t][f];
      if (u > t && node_of[u] >= 0) {
        problem.edges.push_back({n, node_of[u], opts.beta_mm * tet_face_area(tets, t, f)});
      }
    }
  }
  const double beta2 = opts.beta_mm * opts.beta_mm;
  for (const SeamEdge& e : field.seam_edges) {
    if (node_of[e.tet_a] < 0 || node_of[e.tet_b] < 0) continue;
    problem.edges.push_back(
        {node_of[e.tet_a], node_of[e.tet_b], beta2 * (1.0 + e.visibility * e.length_mm)});
  }

  // --- 5. label cost (§4.2.3), the randomized restarts and the covering candidates ---
  problem.label_cost.assign(num_labels, opts.lambda * total_volume(tets));
  std::vector<Vec3> label_direction;
  for (std::int32_t d : dirs)
    label_direction.push_back(d < std::ssize(directions) ? directions[d] : Vec3::Zero());
  const LineStepsCache line_steps(tets, tet_of, node_of, std::move(label_direction));
  if (!directions.empty())
    problem.line_steps = [&](std::int32_t l) -> const LineSteps& { return line_steps(l); };
  const detail::ExpansionSolver solver(problem);
  const Progress restarts_progress = [&](double f) {
    if (progress) progress(0.8 * f);
  };
  const std::vector<detail::ExpansionRun> runs =
      solver.run_all(opts.seed, opts.restarts, restarts_progress);
  std::vector<std::vector<std::int32_t>> candidates;
  for (const detail::ExpansionRun& run : runs) candidates.push_back(run.labels);
  std::vector<double> node_volume_mm3(num_nodes);
  for (std::int32_t n = 0; n < num_nodes; ++n) node_volume_mm3[n] = volume_mm3[tet_of[n]];
  const std::vector<std::vector<std::int32_t>> covers =
      covering_label_sets(problem, node_volume_mm3, kCoveringCandidates);
  candidates.resize(runs.size() + covers.size());
  tbb::parallel_for(std::size_t{0}, covers.size(), [&](std::size_t c) {
    const std::uint64_t seed = detail::restart_seed(~opts.seed, static_cast<std::int32_t>(c));
    candidates[runs.size() + c] = solve_with_labels(problem, covers[c], seed);
  });

  // --- 6. best candidate: fewest parts, then most even part volumes, then lowest energy ---
  // Each candidate's parts are first reduced (reduce_parts.h): fewer parts is what the caster
  // wants most, and alpha-expansion cannot find these moves when the energy they save is
  // smaller than the data cost they add.
  std::vector<std::array<std::int32_t, 4>> face_nodes(num_nodes);
  std::vector<Vec3> node_centre_mm(num_nodes);
  for (std::int32_t n = 0; n < num_nodes; ++n) {
    for (int f = 0; f < 4; ++f) {
      const std::int32_t u = tets.neighbors[tet_of[n]][f];
      face_nodes[n][f] = u >= 0 ? node_of[u] : -1;
    }
    node_centre_mm[n] = Vec3::Zero();
    for (std::int32_t v : tets.tets[tet_of[n]]) node_centre_mm[n] += 0.25 * tets.vertices[v];
  }
  const detail::PartReducer reducer(problem, std::move(face_nodes), std::move(node_volume_mm3),
                                    std::move(node_centre_mm));
  std::vector<std::vector<std::int32_t>> labels(candidates.size());
  std::vector<PartStats> stats(candidates.size());
  std::vector<double> energy(candidates.size());
  tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t r) {
    reducer.reduce(candidates[r], detail::restart_seed(opts.seed, static_cast<std::int32_t>(r)));
    energy[r] = labeling_energy(problem, candidates[r]);
    labels[r].assign(num_tets, -1);
    for (std::int32_t n = 0; n < num_nodes; ++n) labels[r][tet_of[n]] = dirs[candidates[r][n]];
    stats[r] = part_stats(tets, volume_mm3, labels[r]);
  });
  std::vector<std::size_t> rank(candidates.size());
  for (std::size_t r = 0; r < rank.size(); ++r) rank[r] = r;
  const auto key = [&](std::size_t r) {
    return std::make_tuple(stats[r].parts, stats[r].volume_variance_mm6, energy[r], r);
  };
  std::sort(rank.begin(), rank.end(),
            [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  const std::size_t best = rank.front();
  out.label = labels[best];
  for (std::size_t r : rank)
    out.candidates.push_back({std::move(labels[r]), static_cast<std::int32_t>(r), stats[r].parts,
                              stats[r].volume_variance_mm6, energy[r]});
  std::vector<std::int32_t> label_of_direction(field.feasible.num_directions(), -1);
  for (std::int32_t l = 0; l < num_labels; ++l) label_of_direction[dirs[l]] = l;
  std::vector<std::int32_t> node_labels(num_nodes);
  std::vector<char> used(num_labels, 0);
  for (std::int32_t n = 0; n < num_nodes; ++n) {
    node_labels[n] = label_of_direction[out.label[tet_of[n]]];
    used[node_labels[n]] = 1;
  }
  for (char u : used) out.num_labels += u;
  out.num_components = stats[best].parts;
  out.energy = energy[best];
  out.best_restart = static_cast<std::int32_t>(best);
  if (progress) progress(1.0);
  return out;
}

}  // namespace dhfcast
