#include "reduce_parts.h"

#include <algorithm>
#include <bit>
#include <limits>
#include <numeric>
#include <queue>
#include <tuple>
#include <utility>

#include "line_walks.h"

namespace dhfcast::detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// A move may add lines that meet a label, leave it and meet it again, up to this share of the
// nodes it relabels (opens_gaps()). Merging a whole part between two pieces of a label adds
// about one per node, and is refused; a few short gaps along the new borders are left to the
// refine stage's sandwich repair. Measured on CGAL's elephant at 150 mm and 20 000 tets: 0 keeps
// 11 parts where 0.1 keeps 9, both passing every check (without the rule: 9 parts, two of them
// under 0.2 % of the volume, and no assembly order).
constexpr double kMergeGapShare = 0.1;

}  // namespace

// Face-connected components of equal label, with what the moves read about them.
struct PartReducer::Parts {
  std::vector<std::int32_t> of;  // part of each node
  std::vector<std::vector<std::int32_t>> members;
  std::vector<std::int32_t> label;
  std::vector<double> volume_mm3;
  std::vector<std::uint64_t> common;  // words_ per part: labels allowed on every member
  std::vector<std::vector<std::int32_t>> neighbours;  // face-adjacent parts, ascending
  std::vector<std::int32_t> label_nodes;              // nodes per label
  std::int32_t count() const { return static_cast<std::int32_t>(members.size()); }
};

PartReducer::PartReducer(const LabelProblem& problem,
                         std::vector<std::array<std::int32_t, 4>> face_neighbors,
                         std::vector<double> volume_mm3, std::vector<Vec3> centre_mm)
    : problem_(problem),
      n_(problem.num_nodes),
      k_(problem.num_labels),
      words_((problem.num_labels + 63) / 64),
      face_neighbors_(std::move(face_neighbors)),
      volume_mm3_(std::move(volume_mm3)),
      centre_mm_(std::move(centre_mm)) {
  std::vector<std::vector<std::pair<std::int32_t, double>>> adj(n_);
  for (const PottsEdge& e : problem.edges) {
    if (e.a == e.b) continue;
    adj[e.a].emplace_back(e.b, e.weight);
    adj[e.b].emplace_back(e.a, e.weight);
  }
  adj_begin_.assign(n_ + 1, 0);
  for (std::int32_t i = 0; i < n_; ++i) {
    std::sort(adj[i].begin(), adj[i].end());
    for (std::size_t p = 0; p < adj[i].size(); ++p) {
      if (p > 0 && adj[i][p].first == adj[i][p - 1].first) {
        adj_weight_.back() += adj[i][p].second;
      } else {
        adj_node_.push_back(adj[i][p].first);
        adj_weight_.push_back(adj[i][p].second);
      }
    }
    adj_begin_[i + 1] = static_cast<std::int32_t>(adj_node_.size());
  }
  allowed_.assign(static_cast<std::size_t>(n_) * words_, 0);
  for (std::int32_t l = 0; l < k_; ++l) {
    const double* d = problem.data.data() + static_cast<std::size_t>(l) * n_;
    for (std::int32_t i = 0; i < n_; ++i) {
      if (d[i] < kInf)
        allowed_[static_cast<std::size_t>(i) * words_ + (l >> 6)] |= 1ull << (l & 63);
    }
  }
}

PartReducer::Parts PartReducer::find_parts(const std::vector<std::int32_t>& labels) const {
  Parts parts;
  parts.of.assign(n_, -1);
  parts.label_nodes.assign(k_, 0);
  for (std::int32_t s = 0; s < n_; ++s) {
    ++parts.label_nodes[labels[s]];
    if (parts.of[s] >= 0) continue;
    const std::int32_t p = parts.count();
    parts.of[s] = p;
    parts.members.push_back({s});
    parts.label.push_back(labels[s]);
    std::vector<std::int32_t>& m = parts.members.back();
    for (std::size_t q = 0; q < m.size(); ++q) {
      for (std::int32_t j : face_neighbors_[m[q]]) {
        if (j >= 0 && parts.of[j] < 0 && labels[j] == labels[s]) {
          parts.of[j] = p;
          m.push_back(j);
        }
      }
    }
  }
  const std::int32_t num_parts = parts.count();
  parts.volume_mm3.assign(num_parts, 0.0);
  parts.common.assign(static_cast<std::size_t>(num_parts) * words_, ~0ull);
  parts.neighbours.resize(num_parts);
  for (std::int32_t p = 0; p < num_parts; ++p) {
    std::uint64_t* common = parts.common.data() + static_cast<std::size_t>(p) * words_;
    for (std::int32_t i : parts.members[p]) {
      parts.volume_mm3[p] += volume_mm3_[i];
      const std::uint64_t* row = allowed_.data() + static_cast<std::size_t>(i) * words_;
      for (std::int32_t w = 0; w < words_; ++w) common[w] &= row[w];
      for (std::int32_t j : face_neighbors_[i]) {
        if (j >= 0 && parts.of[j] != p) parts.neighbours[p].push_back(parts.of[j]);
      }
    }
    std::vector<std::int32_t>& nb = parts.neighbours[p];
    std::sort(nb.begin(), nb.end());
    nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
  }
  return parts;
}

bool PartReducer::opens_gaps(const std::vector<std::int32_t>& before,
                             const std::vector<std::int32_t>& after) const {
  if (!problem_.line_steps) return false;
  // Counted on the lines through the nodes that change: from each, along its label's direction
  // both ways, the lines that leave the label and meet it again; and, after the move, the
  // lines of its old label that meet that label on both sides of it (a hole in that label).
  std::int64_t gaps_before = 0, gaps_after = 0, changed = 0;
  for (std::int32_t i = 0; i < n_; ++i) {
    if (before[i] == after[i]) continue;
    ++changed;
    const LineSteps& old_lines = problem_.line_steps(before[i]);
    const LineSteps& new_lines = problem_.line_steps(after[i]);
    gaps_before += line_meets(old_lines.up, i, before[i], before, true) +
                   line_meets(old_lines.down, i, before[i], before, true);
    gaps_after += line_meets(new_lines.up, i, after[i], after, true) +
                  line_meets(new_lines.down, i, after[i], after, true);
    gaps_after += line_meets(old_lines.up, i, before[i], after, false) &&
                  line_meets(old_lines.down, i, before[i], after, false);
  }
  return gaps_after > gaps_before + kMergeGapShare * changed;
}

double PartReducer::relabel_cost(const std::vector<std::int32_t>& nodes,
                                 const std::vector<char>& inside,
                                 const std::vector<std::int32_t>& labels, std::int32_t l) const {
  const double* d_new = problem_.data.data() + static_cast<std::size_t>(l) * n_;
  double delta = 0.0;
  for (std::int32_t i : nodes) {
    const std::int32_t li = labels[i];
    delta += d_new[i] - problem_.data[static_cast<std::size_t>(li) * n_ + i];
    for (std::int32_t p = adj_begin_[i]; p < adj_begin_[i + 1]; ++p) {
      const std::int32_t j = adj_node_[p];
      const std::int32_t lj = labels[j];
      const double w = adj_weight_[p];
      if (inside[j]) {
        if (j > i && li != lj) delta -= w;  // inside edges end up uncut
      } else {
        delta += (lj != l ? w : 0.0) - (lj != li ? w : 0.0);
      }
    }
  }
  return delta;
}

bool PartReducer::absorb_whole(const Parts& parts, std::int32_t p,
                               std::vector<std::int32_t>& labels) const {
  const std::uint64_t* common = parts.common.data() + static_cast<std::size_t>(p) * words_;
  const std::vector<std::int32_t>& nodes = parts.members[p];
  std::vector<char> inside(n_, 0);
  for (std::int32_t i : nodes) inside[i] = 1;
  std::vector<std::pair<double, std::int32_t>> choices;  // cost, label
  for (std::int32_t q : parts.neighbours[p]) {
    const std::int32_t l = parts.label[q];
    if (!((common[l >> 6] >> (l & 63)) & 1u)) continue;
    choices.emplace_back(relabel_cost(nodes, inside, labels, l), l);
  }
  std::sort(choices.begin(), choices.end());
  choices.erase(std::unique(choices.begin(), choices.end()), choices.end());
  for (const auto& [cost, l] : choices) {
    std::vector<std::int32_t> trial = labels;
    for (std::int32_t i : nodes) trial[i] = l;
    if (opens_gaps(labels, trial)) continue;
    labels = std::move(trial);
    return true;
  }
  return false;
}

bool PartReducer::merge_pair(const Parts& parts, std::int32_t p,
                             std::vector<std::int32_t>& labels) const {
  const std::uint64_t* common_p = parts.common.data() + static_cast<std::size_t>(p) * words_;
  std::vector<std::tuple<double, std::int32_t, std::int32_t>> choices;  // cost, part, label
  std::vector<char> inside(n_, 0);
  std::vector<std::int32_t> nodes;
  for (std::int32_t q : parts.neighbours[p]) {
    const std::uint64_t* common_q = parts.common.data() + static_cast<std::size_t>(q) * words_;
    nodes = parts.members[p];
    nodes.insert(nodes.end(), parts.members[q].begin(), parts.members[q].end());
    for (std::int32_t i : nodes) inside[i] = 1;
    for (std::int32_t w = 0; w < words_; ++w) {
      for (std::uint64_t bits = common_p[w] & common_q[w]; bits != 0; bits &= bits - 1) {
        const std::int32_t l = w * 64 + std::countr_zero(bits);
        // A label new to the labeling pays its label cost.
        const double cost = relabel_cost(nodes, inside, labels, l) +
                            (parts.label_nodes[l] == 0 ? problem_.label_cost[l] : 0.0);
        choices.emplace_back(cost, q, l);
      }
    }
    for (std::int32_t i : nodes) inside[i] = 0;
  }
  std::stable_sort(choices.begin(), choices.end(),
                   [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
  for (const auto& [cost, q, l] : choices) {
    std::vector<std::int32_t> trial = labels;
    for (std::int32_t i : parts.members[p]) trial[i] = l;
    for (std::int32_t i : parts.members[q]) trial[i] = l;
    if (opens_gaps(labels, trial)) continue;
    labels = std::move(trial);
    return true;
  }
  return false;
}

bool PartReducer::share_among_neighbours(const Parts& parts, std::int32_t p,
                                         std::vector<std::int32_t>& labels,
                                         std::uint64_t seed) const {
  std::vector<std::int32_t> choices;
  for (std::int32_t q : parts.neighbours[p]) choices.push_back(parts.label[q]);
  std::sort(choices.begin(), choices.end());
  choices.erase(std::unique(choices.begin(), choices.end()), choices.end());
  const std::vector<std::int32_t>& nodes = parts.members[p];
  const auto m = static_cast<std::int32_t>(nodes.size());
  const auto c = static_cast<std::int32_t>(choices.size());
  for (std::int32_t i : nodes) {
    if (std::none_of(choices.begin(), choices.end(), [&](std::int32_t l) { return allowed(i, l); }))
      return false;
  }
  // The part's nodes, with the rest of the labeling fixed: its Potts terms become data.
  std::vector<std::int32_t> local(n_, -1);
  for (std::int32_t a = 0; a < m; ++a) local[nodes[a]] = a;
  LabelProblem sub;
  sub.num_nodes = m;
  sub.num_labels = c;
  sub.data.resize(static_cast<std::size_t>(m) * c);
  sub.label_cost.assign(c, 0.0);  // every choice is in use outside the part already
  for (std::int32_t a = 0; a < m; ++a) {
    const std::int32_t i = nodes[a];
    for (std::int32_t b = 0; b < c; ++b)
      sub.data[static_cast<std::size_t>(b) * m + a] =
          problem_.data[static_cast<std::size_t>(choices[b]) * n_ + i];
    for (std::int32_t q = adj_begin_[i]; q < adj_begin_[i + 1]; ++q) {
      const std::int32_t j = adj_node_[q];
      if (local[j] >= 0) {
        if (j > i) sub.edges.push_back({a, local[j], adj_weight_[q]});
        continue;
      }
      for (std::int32_t b = 0; b < c; ++b)
        if (choices[b] != labels[j])
          sub.data[static_cast<std::size_t>(b) * m + a] += adj_weight_[q];
    }
  }
  const std::vector<std::int32_t> shared = minimize_labeling(sub, seed, 1);
  std::vector<std::int32_t> trial = labels;
  for (std::int32_t a = 0; a < m; ++a) trial[nodes[a]] = choices[shared[a]];
  if (find_parts(trial).count() >= parts.count() || opens_gaps(labels, trial)) return false;
  labels = std::move(trial);
  return true;
}

bool PartReducer::flood_from_neighbours(const Parts& parts, std::int32_t p,
                                        std::vector<std::int32_t>& labels) const {
  // Dijkstra over the part's nodes from its boundary with each neighbouring part; a node is
  // entered only with a label it allows, so every node it settles hangs on to a part of its
  // label and the part disappears without making new ones.
  using Entry = std::tuple<double, std::int32_t, std::int32_t>;  // distance, node, label
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  const std::vector<std::int32_t>& nodes = parts.members[p];
  for (std::int32_t i : nodes) {
    for (std::int32_t j : face_neighbors_[i]) {
      if (j >= 0 && parts.of[j] != p && allowed(i, labels[j]))
        queue.emplace((centre_mm_[i] - centre_mm_[j]).norm(), i, labels[j]);
    }
  }
  std::vector<std::int32_t> taken(n_, -1);
  while (!queue.empty()) {
    const auto [d, i, l] = queue.top();
    queue.pop();
    if (taken[i] >= 0) continue;
    taken[i] = l;
    for (std::int32_t j : face_neighbors_[i]) {
      if (j >= 0 && parts.of[j] == p && taken[j] < 0 && allowed(j, l))
        queue.emplace(d + (centre_mm_[i] - centre_mm_[j]).norm(), j, l);
    }
  }
  if (std::any_of(nodes.begin(), nodes.end(), [&](std::int32_t i) { return taken[i] < 0; }))
    return false;
  std::vector<std::int32_t> trial = labels;
  for (std::int32_t i : nodes) trial[i] = taken[i];
  if (opens_gaps(labels, trial)) return false;
  labels = std::move(trial);
  return true;
}

bool PartReducer::bridge(const Parts& parts, std::int32_t p,
                         std::vector<std::int32_t>& labels) const {
  // The labels the part can join: its own and any other part's label allowed on all of it.
  const std::uint64_t* common = parts.common.data() + static_cast<std::size_t>(p) * words_;
  std::vector<std::int32_t> targets;
  for (std::int32_t q = 0; q < parts.count(); ++q) {
    const std::int32_t l = parts.label[q];
    if (q != p && ((common[l >> 6] >> (l & 63)) & 1u)) targets.push_back(l);
  }
  std::sort(targets.begin(), targets.end());
  targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
  // For each, Dijkstra from the part through nodes allowing the label, up to the first node of
  // another part of that label; the shortest path wins.
  using Entry = std::pair<double, std::int32_t>;
  std::vector<double> dist(n_);
  std::vector<std::int32_t> from(n_);
  std::vector<std::int32_t> best_path;
  std::int32_t best_label = -1;
  double best_length = kInf;
  for (std::int32_t l : targets) {
    std::fill(dist.begin(), dist.end(), kInf);
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
    for (std::int32_t i : parts.members[p]) {
      dist[i] = 0.0;
      queue.emplace(0.0, i);
    }
    std::int32_t reached = -1;
    while (!queue.empty() && reached < 0) {
      const auto [d, i] = queue.top();
      queue.pop();
      if (d >= best_length) break;
      if (d > dist[i]) continue;
      for (std::int32_t j : face_neighbors_[i]) {
        if (j < 0 || parts.of[j] == p || !allowed(j, l)) continue;
        const double dj = d + (centre_mm_[i] - centre_mm_[j]).norm();
        if (dj >= dist[j]) continue;
        dist[j] = dj;
        from[j] = i;
        if (labels[j] == l) {
          reached = j;
          break;
        }
        queue.emplace(dj, j);
      }
    }
    if (reached < 0 || dist[reached] >= best_length) continue;
    best_length = dist[reached];
    best_label = l;
    best_path.clear();
    for (std::int32_t i = from[reached]; parts.of[i] != p; i = from[i]) best_path.push_back(i);
  }
  if (best_label < 0) return false;
  // A path one tet wide makes a thin, fragile tube: widen it where the nodes allow the label.
  for (const bool widen : {true, false}) {
    std::vector<std::int32_t> trial = labels;
    for (std::int32_t i : parts.members[p]) trial[i] = best_label;
    for (std::int32_t i : best_path) {
      trial[i] = best_label;
      if (!widen) continue;
      for (std::int32_t j : face_neighbors_[i])
        if (j >= 0 && allowed(j, best_label)) trial[j] = best_label;
    }
    if (find_parts(trial).count() < parts.count() && !opens_gaps(labels, trial)) {
      labels = std::move(trial);
      return true;
    }
  }
  return false;
}

void PartReducer::reduce(std::vector<std::int32_t>& labels, std::uint64_t seed) const {
  for (;;) {
    const Parts parts = find_parts(labels);
    std::vector<std::int32_t> order(parts.count());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
      return parts.volume_mm3[a] < parts.volume_mm3[b];
    });
    const auto moved = [&] {
      for (std::int32_t p : order)
        if (absorb_whole(parts, p, labels)) return true;
      for (std::int32_t p : order)
        if (merge_pair(parts, p, labels)) return true;
      for (std::int32_t p : order)
        if (share_among_neighbours(parts, p, labels, seed + static_cast<std::uint64_t>(p)))
          return true;
      for (std::int32_t p : order)
        if (flood_from_neighbours(parts, p, labels)) return true;
      for (std::int32_t p : order)
        if (bridge(parts, p, labels)) return true;
      return false;
    };
    if (!moved()) return;
  }
}

}  // namespace dhfcast::detail
