#include "alpha_expansion.h"

#include <maxflow/graph.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <thread>

#include "dhfcast/error.h"
#include "line_walks.h"

namespace dhfcast {
namespace detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Problems up to this size are solved directly; larger ones start from a coarsened problem.
// Why: on tet meshes, where smoothness outweighs the data cost, one max-flow over ~50k active
// nodes takes ~0.5 s, and 512 labels x a few cycles x 15 restarts of those is hours. Full
// cycles on a few hundred clusters, then banded refinement with the labels in use, take < 1 s.
constexpr std::int32_t kDirectNodes = 500;
// Nodes per cluster of the coarse level (at most).
constexpr std::size_t kClusterSize = 8;
// Width, in edges, of the band around part boundaries that a refined level may move.
constexpr std::int8_t kBandHops = 2;

using FlowGraph = maxflow::Graph<double, double, double>;

// The max-flow library calls this on allocation failure instead of exit().
void on_maxflow_error(const char* message) {
  throw Error(ErrorCode::Internal, std::string("max-flow: ") + message);
}

// Uniform integer in [0, n) by rejection: exact, and independent of the standard library's
// distribution implementations, so a seed gives the same run everywhere.
std::uint64_t uniform_below(std::mt19937_64& rng, std::uint64_t n) {
  constexpr std::uint64_t kMax = std::numeric_limits<std::uint64_t>::max();
  const std::uint64_t limit = kMax - kMax % n;
  std::uint64_t x = rng();
  while (x >= limit) x = rng();
  return x % n;
}

std::uint64_t splitmix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

void check_problem(const LabelProblem& p) {
  const auto bad_input = [](const std::string& what) {
    throw Error(ErrorCode::InvalidInput, "label problem: " + what);
  };
  if (p.num_nodes < 0 || p.num_labels < 0) bad_input("negative size");
  const std::size_t n = static_cast<std::size_t>(p.num_nodes);
  const std::size_t k = static_cast<std::size_t>(p.num_labels);
  if (p.data.size() != n * k)
    bad_input("data has " + std::to_string(p.data.size()) +
              " costs, expected num_nodes * num_labels");
  if (p.label_cost.size() != k) bad_input("label_cost needs one value per label");
  for (double c : p.label_cost) {
    if (!(c >= 0.0) || !std::isfinite(c)) {
      throw Error(ErrorCode::InvalidOptions, "label problem: label costs must be finite and >= 0");
    }
  }
  for (const PottsEdge& e : p.edges) {
    if (e.a < 0 || e.b < 0 || e.a >= p.num_nodes || e.b >= p.num_nodes) {
      bad_input("edge (" + std::to_string(e.a) + ", " + std::to_string(e.b) + ") out of range");
    }
    if (!(e.weight >= 0.0) || !std::isfinite(e.weight)) {
      throw Error(ErrorCode::InvalidOptions, "label problem: edge weights must be finite and >= 0");
    }
  }
  for (double c : p.data) {
    if (std::isnan(c) || c == -kInf) bad_input("data costs must be numbers or +infinity");
  }
}

}  // namespace

// Per-run mutable state; the scratch arrays are left cleared after every expansion.
struct ExpansionSolver::State {
  State(std::int32_t n, std::int32_t k)
      : label(n, -1),
        cost(n, 0.0),
        count(k, 0),
        active_count(k, 0),
        moved_count(k, 0),
        aux(k, -1),
        gid(n, -1),
        moving(n, 0),
        ahead(k),
        behind(k),
        fresh(k, 0),
        lines(k, nullptr),
        graph(n + k + 1, 4 * n + 1, &on_maxflow_error) {}
  std::mt19937_64 rng;
  std::vector<std::int32_t> label;
  std::vector<double> cost;                // data cost of each node's current label
  std::vector<std::int32_t> count;         // nodes per label
  std::vector<std::int32_t> active_count;  // scratch: active nodes per label
  std::vector<std::int32_t> moved_count;   // scratch: nodes per label that switch to alpha
  std::vector<std::int32_t> aux;         // scratch: label-cost node of a label in the graph, or -1
  std::vector<std::int32_t> gid;         // scratch: graph node of an active node, or -1
  std::vector<char> moving;              // scratch: the node switches to alpha
  std::vector<std::int32_t> candidates;  // the nodes an expansion may move, ascending
  std::vector<std::int32_t> active, present, moved, queue;
  std::vector<std::int8_t> hops;
  // The line constraints' marks per label l: ahead[l][i] / behind[l][i] = 1 when node i's line
  // along l's direction meets a node labeled l ahead of / behind i. They change only with l's
  // nodes, so they are kept until a move adds or takes nodes of l (fresh[l] = 0).
  std::vector<std::vector<std::int8_t>> ahead, behind;
  std::vector<char> fresh;
  std::vector<const LineSteps*> lines;  // scratch: each label's lines
  std::vector<std::int32_t> stack;
  double energy = 0.0;
  FlowGraph graph;
};

ExpansionSolver::ExpansionSolver(const LabelProblem& problem)
    : problem_(problem), n_(problem.num_nodes), k_(problem.num_labels) {
  check_problem(problem);
  // --- merged adjacency: both directions of every edge, sorted, duplicate pairs summed ---
  std::vector<std::int32_t> degree(n_ + 1, 0);
  for (const PottsEdge& e : problem.edges) {
    if (e.a == e.b) continue;  // a node never differs from itself
    ++degree[e.a];
    ++degree[e.b];
  }
  std::vector<std::int32_t> begin(n_ + 1, 0);
  for (std::int32_t i = 0; i < n_; ++i) begin[i + 1] = begin[i] + degree[i];
  std::vector<std::pair<std::int32_t, double>> raw(begin[n_]);
  std::vector<std::int32_t> fill(begin.begin(), begin.end() - 1);
  for (const PottsEdge& e : problem.edges) {
    if (e.a == e.b) continue;
    raw[fill[e.a]++] = {e.b, e.weight};
    raw[fill[e.b]++] = {e.a, e.weight};
  }
  adj_begin_.assign(n_ + 1, 0);
  adj_node_.reserve(raw.size());
  adj_weight_.reserve(raw.size());
  for (std::int32_t i = 0; i < n_; ++i) {
    std::sort(raw.begin() + begin[i], raw.begin() + begin[i + 1]);
    for (std::int32_t p = begin[i]; p < begin[i + 1]; ++p) {
      if (p > begin[i] && raw[p].first == raw[p - 1].first) {
        adj_weight_.back() += raw[p].second;
      } else {
        adj_node_.push_back(raw[p].first);
        adj_weight_.push_back(raw[p].second);
      }
    }
    adj_begin_[i + 1] = static_cast<std::int32_t>(adj_node_.size());
  }
  // --- allowed labels, node-major, for drawing random initial labels ---
  words_ = (k_ + 63) / 64;
  allowed_.assign(static_cast<std::size_t>(n_) * words_, 0);
  // Parallel over blocks of nodes: each task writes only its own rows.
  tbb::parallel_for(tbb::blocked_range<std::int32_t>(0, n_, 4096),
                    [&](const tbb::blocked_range<std::int32_t>& nodes) {
                      for (std::int32_t l = 0; l < k_; ++l) {
                        const double* d = problem.data.data() + static_cast<std::size_t>(l) * n_;
                        for (std::int32_t i = nodes.begin(); i < nodes.end(); ++i) {
                          if (d[i] < kInf) {
                            allowed_[static_cast<std::size_t>(i) * words_ + l / 64] |= 1ull
                                                                                       << (l % 64);
                          }
                        }
                      }
                    });
  for (std::int32_t i = 0; i < n_; ++i) {
    const std::uint64_t* row = allowed_.data() + static_cast<std::size_t>(i) * words_;
    if (std::all_of(row, row + words_, [](std::uint64_t w) { return w == 0; })) {
      throw Error(ErrorCode::InvalidInput,
                  "label problem: node " + std::to_string(i) + " has no allowed label");
    }
  }
  if (n_ > kDirectNodes) build_coarse_level();
}

ExpansionSolver::~ExpansionSolver() = default;

void ExpansionSolver::build_coarse_level() {
  // --- clusters: BFS from each unassigned node in index order, up to kClusterSize nodes; a
  // neighbor joins while the labels allowed by the whole cluster stay >= 3/4 of the seed's ---
  cluster_.assign(n_, -1);
  std::int32_t num_clusters = 0;
  std::vector<std::uint64_t> common(words_);
  std::vector<std::int32_t> members;
  for (std::int32_t seed = 0; seed < n_; ++seed) {
    if (cluster_[seed] >= 0) continue;
    const std::int32_t c = num_clusters++;
    const std::uint64_t* seed_row = allowed_.data() + static_cast<std::size_t>(seed) * words_;
    std::copy(seed_row, seed_row + words_, common.begin());
    std::int32_t seed_count = 0;
    for (std::int32_t w = 0; w < words_; ++w) seed_count += std::popcount(seed_row[w]);
    const std::int32_t min_count = (3 * seed_count + 3) / 4;
    cluster_[seed] = c;
    members.assign(1, seed);
    for (std::size_t q = 0; q < members.size() && members.size() < kClusterSize; ++q) {
      const std::int32_t i = members[q];
      for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
        const std::int32_t j = adj_node_[p];
        if (cluster_[j] >= 0) continue;
        const std::uint64_t* row = allowed_.data() + static_cast<std::size_t>(j) * words_;
        std::int32_t kept = 0;
        for (std::int32_t w = 0; w < words_; ++w) kept += std::popcount(common[w] & row[w]);
        if (kept < min_count) continue;
        for (std::int32_t w = 0; w < words_; ++w) common[w] &= row[w];
        cluster_[j] = c;
        members.push_back(j);
        if (members.size() == kClusterSize) break;
      }
    }
  }
  // --- the coarse problem: summed data (+inf where a member forbids the label), the weights
  // of the edges between clusters; its energy equals the fine energy of the projection ---
  auto coarse = std::make_unique<LabelProblem>();
  coarse->num_nodes = num_clusters;
  coarse->num_labels = k_;
  coarse->data.assign(static_cast<std::size_t>(num_clusters) * k_, 0.0);
  tbb::parallel_for(std::int32_t{0}, k_, [&](std::int32_t l) {  // one coarse column per task
    const double* d = problem_.data.data() + static_cast<std::size_t>(l) * n_;
    double* cd = coarse->data.data() + static_cast<std::size_t>(l) * num_clusters;
    for (std::int32_t i = 0; i < n_; ++i) cd[cluster_[i]] += d[i];
  });
  for (std::int32_t i = 0; i < n_; ++i) {
    for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
      const std::int32_t j = adj_node_[p];
      if (j > i && cluster_[i] != cluster_[j]) {
        coarse->edges.push_back({cluster_[i], cluster_[j], adj_weight_[p]});
      }
    }
  }
  coarse->label_cost = problem_.label_cost;
  coarse_problem_ = std::move(coarse);
  coarse_ = std::make_unique<ExpansionSolver>(*coarse_problem_);
}

void ExpansionSolver::set_labels(State& s, std::vector<std::int32_t> labels) const {
  s.label = std::move(labels);
  std::fill(s.count.begin(), s.count.end(), 0);
  std::fill(s.fresh.begin(), s.fresh.end(), 0);
  double e = 0.0;
  for (std::int32_t i = 0; i < n_; ++i) {
    s.cost[i] = problem_.data[static_cast<std::size_t>(s.label[i]) * n_ + i];
    ++s.count[s.label[i]];
    e += s.cost[i];
    for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
      const std::int32_t j = adj_node_[p];
      if (j > i && s.label[i] != s.label[j]) e += adj_weight_[p];
    }
  }
  for (std::int32_t l = 0; l < k_; ++l) {
    if (s.count[l] > 0) e += problem_.label_cost[l];
  }
  s.energy = e;
}

std::vector<std::int32_t> ExpansionSolver::random_labels(std::mt19937_64& rng) const {
  std::vector<std::int32_t> labels(n_);
  // Each node draws one of its allowed labels uniformly.
  for (std::int32_t i = 0; i < n_; ++i) {
    const std::uint64_t* row = allowed_.data() + static_cast<std::size_t>(i) * words_;
    std::int32_t allowed = 0;
    for (std::int32_t w = 0; w < words_; ++w) allowed += std::popcount(row[w]);
    auto pick = static_cast<std::int32_t>(uniform_below(rng, allowed));
    std::int32_t w = 0;
    while (std::popcount(row[w]) <= pick) pick -= std::popcount(row[w++]);
    std::uint64_t bits = row[w];
    for (; pick > 0; --pick) bits &= bits - 1;
    labels[i] = w * 64 + std::countr_zero(bits);
  }
  return labels;
}

// One expansion move on alpha: the optimal "keep your label or switch to alpha" move by a
// minimum cut, accepted only when it lowers the energy. Returns whether it was accepted.
bool ExpansionSolver::expand(State& s, std::int32_t alpha) const {
  const double* d_alpha = problem_.data.data() + static_cast<std::size_t>(alpha) * n_;
  // --- 1. active nodes: candidates that may switch to alpha; all others keep their label ---
  s.active.clear();
  s.present.clear();
  for (std::int32_t i : s.candidates) {
    if (s.label[i] == alpha || !(d_alpha[i] < kInf)) continue;
    s.gid[i] = static_cast<std::int32_t>(s.active.size());
    s.active.push_back(i);
    if (s.active_count[s.label[i]]++ == 0) s.present.push_back(s.label[i]);
  }
  if (s.active.empty()) return false;

  // --- 2. graph: source side keeps its label, sink side takes alpha (Kolmogorov & Zabih) ---
  FlowGraph& g = s.graph;
  g.reset();
  const auto num_active = static_cast<std::int32_t>(s.active.size());
  g.add_node(num_active);
  for (std::int32_t k = 0; k < num_active; ++k) {
    const std::int32_t i = s.active[k];
    const std::int32_t li = s.label[i];
    double keep = s.cost[i], take = d_alpha[i];
    for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
      const std::int32_t j = adj_node_[p];
      const double w = adj_weight_[p];
      const std::int32_t lj = s.label[j];
      if (s.gid[j] < 0) {  // fixed neighbor: the Potts term is unary
        if (li != lj) keep += w;
        if (lj != alpha) take += w;
      } else if (j > i) {
        if (li == lj) {
          g.add_edge(k, s.gid[j], w, w);
        } else {
          // w * (1 - x_i x_j) = w - w x_i + w x_i (1 - x_j)
          keep += w;
          g.add_edge(s.gid[j], k, w, 0.0);
        }
      }
    }
    g.add_tweights(k, take, keep);
  }
  // Label costs (Delong et al. §3): a used label whose nodes are all active is paid only if one
  // of them keeps it; an unused alpha is paid only if some node takes it.
  for (std::int32_t l : s.present) {
    const double h = problem_.label_cost[l];
    if (h > 0.0 && s.active_count[l] == s.count[l]) {
      s.aux[l] = g.add_node();
      g.add_tweights(s.aux[l], 0.0, h);
    }
  }
  std::int32_t alpha_aux = -1;
  if (s.count[alpha] == 0 && problem_.label_cost[alpha] > 0.0) {
    alpha_aux = g.add_node();
    g.add_tweights(alpha_aux, problem_.label_cost[alpha], 0.0);
  }
  for (std::int32_t k = 0; k < num_active; ++k) {
    const std::int32_t a = s.aux[s.label[s.active[k]]];
    if (a >= 0) g.add_edge(k, a, kInf, 0.0);
    if (alpha_aux >= 0) g.add_edge(alpha_aux, k, kInf, 0.0);
  }
  if (problem_.line_steps) add_line_constraints(s, alpha);
  g.maxflow();

  // --- 3. exact energy change of the move ---
  s.moved.clear();
  for (std::int32_t k = 0; k < num_active; ++k) {
    if (g.what_segment(k) == FlowGraph::SINK) {
      s.moved.push_back(s.active[k]);
      s.moving[s.active[k]] = 1;
    }
  }
  double delta = 0.0;
  for (std::int32_t i : s.moved) {
    const std::int32_t li = s.label[i];
    delta += d_alpha[i] - s.cost[i];
    for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
      const std::int32_t j = adj_node_[p];
      const std::int32_t lj = s.label[j];
      const double w = adj_weight_[p];
      if (s.moving[j]) {
        if (j > i && li != lj) delta -= w;
      } else {
        delta += (lj != alpha ? w : 0.0) - (li != lj ? w : 0.0);
      }
    }
    ++s.moved_count[li];
  }
  for (std::int32_t l : s.present) {
    if (s.moved_count[l] == s.count[l]) delta -= problem_.label_cost[l];
  }
  if (!s.moved.empty() && s.count[alpha] == 0) delta += problem_.label_cost[alpha];

  // --- 4. accept only a strict decrease (the tolerance absorbs rounding in delta) ---
  const bool accept = delta < -1e-9 * std::abs(s.energy);
  if (accept) {
    s.fresh[alpha] = 0;
    for (std::int32_t l : s.present) {
      if (s.moved_count[l] > 0) s.fresh[l] = 0;
    }
    for (std::int32_t i : s.moved) {
      --s.count[s.label[i]];
      s.label[i] = alpha;
      s.cost[i] = d_alpha[i];
    }
    s.count[alpha] += static_cast<std::int32_t>(s.moved.size());
    s.energy += delta;
  }
  for (std::int32_t l : s.present) {
    s.active_count[l] = 0;
    s.moved_count[l] = 0;
    s.aux[l] = -1;
  }
  for (std::int32_t i : s.active) s.gid[i] = -1;
  for (std::int32_t i : s.moved) s.moving[i] = 0;
  return accept;
}

// Hard terms that keep each label's nodes one stretch per line where they were (see
// LabelProblem::line_steps): "node i takes alpha only if node j does" is an infinite edge j -> i,
// and one whose j cannot move forbids i the move.
void ExpansionSolver::add_line_constraints(State& s, std::int32_t alpha) const {
  FlowGraph& g = s.graph;
  const auto needs = [&](std::int32_t k, std::int32_t j) {
    if (s.gid[j] >= 0)
      g.add_edge(s.gid[j], k, kInf, 0.0);
    else
      g.add_tweights(k, kInf, 0.0);
  };
  const auto marks = [&](std::int32_t l) -> const LineSteps& {
    const LineSteps& lines = problem_.line_steps(l);
    if (!s.fresh[l]) {
      mark_label_ahead(lines.up, s.label, l, s.ahead[l], s.stack);
      mark_label_ahead(lines.down, s.label, l, s.behind[l], s.stack);
      s.fresh[l] = 1;
    }
    return lines;
  };
  // A node taking alpha brings the nodes between it and alpha's nodes along alpha's lines.
  const LineSteps& a = marks(alpha);
  const std::vector<std::int8_t>& alpha_ahead = s.ahead[alpha];
  const std::vector<std::int8_t>& alpha_behind = s.behind[alpha];
  for (std::size_t k = 0; k < s.active.size(); ++k) {
    const std::int32_t i = s.active[k];
    const auto gk = static_cast<std::int32_t>(k);
    if (alpha_ahead[i] == 1 && s.label[a.up[i]] != alpha) needs(gk, a.up[i]);
    if (alpha_behind[i] == 1 && s.label[a.down[i]] != alpha) needs(gk, a.down[i]);
  }
  // A node leaving label b from inside b's stretch of a line takes the stretch ahead of it along.
  for (std::int32_t b : s.present) s.lines[b] = &marks(b);
  for (std::size_t k = 0; k < s.active.size(); ++k) {
    const std::int32_t i = s.active[k], b = s.label[i];
    if (s.ahead[b][i] != 1 || s.behind[b][i] != 1) continue;
    const std::int32_t up = s.lines[b]->up[i];
    if (s.label[up] == b) needs(static_cast<std::int32_t>(k), up);
  }
}

void ExpansionSolver::mark_band(State& s) const {
  // Multi-source BFS from the nodes on a label boundary, kBandHops deep.
  s.hops.assign(n_, kBandHops + 1);
  s.queue.clear();
  for (std::int32_t i = 0; i < n_; ++i) {
    for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
      if (s.label[adj_node_[p]] != s.label[i]) {
        s.hops[i] = 0;
        s.queue.push_back(i);
        break;
      }
    }
  }
  for (std::size_t q = 0; q < s.queue.size(); ++q) {
    const std::int32_t i = s.queue[q];
    if (s.hops[i] == kBandHops) continue;
    for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
      const std::int32_t j = adj_node_[p];
      if (s.hops[j] > s.hops[i] + 1) {
        s.hops[j] = static_cast<std::int8_t>(s.hops[i] + 1);
        s.queue.push_back(j);
      }
    }
  }
  s.candidates.clear();
  for (std::int32_t i = 0; i < n_; ++i) {
    if (s.hops[i] <= kBandHops) s.candidates.push_back(i);
  }
}

ExpansionRun ExpansionSolver::run(std::uint64_t seed) const {
  State s(n_, k_);
  std::mt19937_64 rng(seed);
  std::vector<std::int32_t> order;
  if (coarse_) {
    // The coarse level's labeling, projected, is the start; this level only moves the band
    // around its boundaries, with the labels in use.
    const ExpansionRun coarse = coarse_->run(splitmix64(seed));
    std::vector<std::int32_t> labels(n_);
    for (std::int32_t i = 0; i < n_; ++i) labels[i] = coarse.labels[cluster_[i]];
    set_labels(s, std::move(labels));
  } else {
    set_labels(s, random_labels(rng));
    s.candidates.resize(n_);
    std::iota(s.candidates.begin(), s.candidates.end(), 0);
    order.resize(k_);
    std::iota(order.begin(), order.end(), 0);
  }
  for (bool improved = n_ > 0; improved;) {
    improved = false;
    if (coarse_) {
      mark_band(s);
      order.clear();
      for (std::int32_t l = 0; l < k_; ++l) {
        if (s.count[l] > 0) order.push_back(l);
      }
    }
    // Fisher-Yates with our own uniform draws: the same order on every platform.
    for (std::size_t i = order.size(); i > 1; --i) {
      std::swap(order[i - 1], order[uniform_below(rng, i)]);
    }
    for (std::int32_t alpha : order) improved |= expand(s, alpha);
  }
  ExpansionRun out;
  out.labels = std::move(s.label);
  out.energy = labeling_energy(problem_, out.labels);
  return out;
}

std::vector<ExpansionRun> ExpansionSolver::run_all(std::uint64_t seed, std::int32_t restarts,
                                                   const Progress& progress) const {
  std::vector<ExpansionRun> runs(restarts);
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<std::int32_t> finished{0};
  // One task per run: each has its own RNG and graph, so the runs do not depend on scheduling.
  tbb::parallel_for(
      tbb::blocked_range<std::int32_t>(0, restarts, 1),
      [&](const tbb::blocked_range<std::int32_t>& range) {
        for (std::int32_t r = range.begin(); r < range.end(); ++r) {
          runs[r] = run(restart_seed(seed, r));
          const std::int32_t done = ++finished;
          if (progress && std::this_thread::get_id() == caller) {
            progress(static_cast<double>(done) / restarts);
          }
        }
      },
      tbb::simple_partitioner());
  if (progress) progress(1.0);
  return runs;
}

std::uint64_t restart_seed(std::uint64_t seed, std::int32_t restart) {
  return splitmix64(splitmix64(seed) + static_cast<std::uint64_t>(restart) * 0x9E3779B97F4A7C15ull);
}

}  // namespace detail

double labeling_energy(const LabelProblem& problem, const std::vector<std::int32_t>& labels) {
  const std::int32_t n = problem.num_nodes, k = problem.num_labels;
  if (static_cast<std::int64_t>(labels.size()) != n ||
      problem.data.size() != static_cast<std::size_t>(n) * k ||
      problem.label_cost.size() != static_cast<std::size_t>(k)) {
    return detail::kInf;
  }
  std::vector<char> used(k, 0);
  double e = 0.0;
  for (std::int32_t i = 0; i < n; ++i) {
    const std::int32_t l = labels[i];
    if (l < 0 || l >= k) return detail::kInf;
    e += problem.data[static_cast<std::size_t>(l) * n + i];
    used[l] = 1;
  }
  for (const PottsEdge& p : problem.edges) {
    if (labels[p.a] != labels[p.b]) e += p.weight;
  }
  for (std::int32_t l = 0; l < k; ++l) {
    if (used[l]) e += problem.label_cost[l];
  }
  return e;
}

std::vector<std::int32_t> minimize_labeling(const LabelProblem& problem, std::uint64_t seed,
                                            std::int32_t restarts) {
  if (restarts < 1) throw Error(ErrorCode::InvalidOptions, "restarts must be >= 1");
  const detail::ExpansionSolver solver(problem);
  std::vector<detail::ExpansionRun> runs = solver.run_all(seed, restarts, {});
  std::size_t best = 0;
  for (std::size_t r = 1; r < runs.size(); ++r) {
    if (runs[r].energy < runs[best].energy) best = r;
  }
  return std::move(runs[best].labels);
}

}  // namespace dhfcast
