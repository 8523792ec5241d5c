// Label-level DHF repair (paper §4.3.1, "infeasible volume"): tets of one part that lie between
// two pieces of another part along that part's direction go to that part.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "components.h"
#include "dhfcast/error.h"
#include "dhfcast/parts.h"

namespace dhfcast {
namespace {

// Calls visit(u) for every tet u the ray x + s * d, s > 0, enters after tet t, until it leaves
// the tet mesh. Each step leaves the current tet through the face whose plane the ray reaches
// first among those it points out of, so every step makes progress even when rounding puts x
// slightly off the entry face; the step cap guards against cycling on degenerate tets.
template <class Visit>
void walk_line(const TetMesh& tets, std::int32_t t, Vec3 x, const Vec3& d, Visit&& visit) {
  const std::size_t max_steps = tets.tets.size();
  for (std::size_t step = 0; step < max_steps; ++step) {
    const Tet& k = tets.tets[t];
    int exit = -1;
    double best = INFINITY;
    for (int i = 0; i < 4; ++i) {
      const Vec3& a = tets.vertices[k[kTetFaces[i][0]]];
      const Vec3 n = (tets.vertices[k[kTetFaces[i][1]]] - a)
                         .cross(tets.vertices[k[kTetFaces[i][2]]] - a);
      const double along = n.dot(d);
      if (!(along > 0.0)) continue;
      const double s = std::max(0.0, n.dot(a - x) / along);
      if (s < best) {
        best = s;
        exit = i;
      }
    }
    if (exit < 0) return;
    const std::int32_t u = tets.neighbors[t][exit];
    if (u < 0) return;
    x += best * d;
    visit(u);
    t = u;
  }
}

void add_unique(std::vector<std::int32_t>& list, std::int32_t value) {
  if (std::find(list.begin(), list.end(), value) == list.end()) list.push_back(value);
}

// Moves pieces of parts, smallest first, each whole into the neighbouring part it shares the
// most face area with among those whose label `allows` on all of it, until there are at most
// max_parts parts or no piece can move.
void merge_pieces(const TetMesh& tets, std::vector<std::int32_t>& label,
                  const std::vector<std::int32_t>& region, const std::vector<double>& volume,
                  const TetAllowsLabel& allows, std::int32_t max_parts, SandwichRepair& repair) {
  const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
  for (;;) {
    std::int32_t num_parts = 0;
    const std::vector<std::int32_t> part = detail::label_components(tets, label, region, num_parts);
    if (num_parts <= max_parts) return;
    std::vector<double> part_volume(num_parts, 0.0);
    std::vector<std::vector<std::int32_t>> members(num_parts);
    for (std::int32_t t = 0; t < n; ++t) {
      part_volume[part[t]] += volume[t];
      members[part[t]].push_back(t);
    }
    std::vector<std::int32_t> order(num_parts);
    for (std::int32_t p = 0; p < num_parts; ++p) order[p] = p;
    std::stable_sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
      return part_volume[a] < part_volume[b];
    });
    bool merged = false;
    for (std::int32_t p : order) {
      std::map<std::int32_t, double> shared;
      for (std::int32_t t : members[p])
        for (int i = 0; i < 4; ++i) {
          const std::int32_t u = tets.neighbors[t][i];
          if (u >= 0 && part[u] != p && region[u] == region[t])
            shared[part[u]] += tet_face_area(tets, t, i);
        }
      std::vector<std::pair<double, std::int32_t>> candidates;
      for (const auto& [q, area] : shared) candidates.emplace_back(-area, q);
      std::sort(candidates.begin(), candidates.end());
      for (const auto& [negative_area, q] : candidates) {
        const std::int32_t l = label[members[q].front()];
        const bool fits = std::all_of(members[p].begin(), members[p].end(), [&](std::int32_t t) {
          return allows(t, region[t], l);
        });
        if (!fits) continue;
        for (std::int32_t t : members[p]) label[t] = l;
        ++repair.merged_pieces;
        repair.merged_tets += static_cast<std::int32_t>(members[p].size());
        merged = true;
        break;
      }
      if (merged) break;
    }
    if (!merged) return;
  }
}

}  // namespace

SandwichRepair absorb_sandwiched_tets(const TetMesh& tets, std::vector<std::int32_t>& label,
                                      const std::vector<std::int32_t>& region,
                                      const std::vector<std::vector<Vec3>>& directions,
                                      const TetAllowsLabel& allows, const SandwichOptions& opts) {
  if (opts.max_rounds < 0 || opts.max_extra_parts < 0)
    throw Error(ErrorCode::InvalidOptions,
                "sandwich repair: max_rounds and max_extra_parts must be >= 0");
  const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
  if (tets.neighbors.size() != tets.tets.size() || label.size() != tets.tets.size() ||
      region.size() != tets.tets.size())
    throw Error(ErrorCode::Internal, "sandwich repair: one label, region and adjacency per tet");
  for (std::int32_t t = 0; t < n; ++t)
    if (region[t] < 0 || static_cast<std::size_t>(region[t]) >= directions.size() || label[t] < 0 ||
        static_cast<std::size_t>(label[t]) >= directions[region[t]].size())
      throw Error(ErrorCode::Internal,
                  "sandwich repair: tet " + std::to_string(t) + " has no direction");

  std::vector<Vec3> centre(n);
  std::vector<double> volume(n);
  for (std::int32_t t = 0; t < n; ++t) {
    const Tet& k = tets.tets[t];
    centre[t] = 0.25 * (tets.vertices[k[0]] + tets.vertices[k[1]] + tets.vertices[k[2]] +
                        tets.vertices[k[3]]);
    volume[t] = tet_volume(tets, t);
  }

  SandwichRepair repair;
  std::vector<char> moved(n, 0);
  std::vector<std::int32_t> target(n, -1);  // label a tet moves to this round, -1: stays
  // Moves can put other tets into other parts' infeasible volumes and split parts, so the
  // labeling kept is the one of the round with the fewest sandwiched tets among those with at
  // most max_extra_parts more parts than at the start (the start itself qualifies).
  const std::vector<std::int32_t> initial = label;
  std::vector<std::int32_t> best = label;
  std::int32_t initial_parts = -1, best_sandwiched = -1;
  SandwichRepair pieces;  // pieces merged so far
  int over_budget = 0;    // consecutive rounds with too many parts
  for (std::int32_t round = 0;; ++round) {
    // --- 1. the parts as they are now: component, its (region, label), volume, first tet ---
    std::int32_t num_parts = 0;
    const std::vector<std::int32_t> part = detail::label_components(tets, label, region, num_parts);
    std::vector<double> part_volume(num_parts, 0.0);
    std::vector<std::int32_t> part_first(num_parts, -1);
    for (std::int32_t t = 0; t < n; ++t) {
      part_volume[part[t]] += volume[t];
      if (part_first[part[t]] < 0) part_first[part[t]] = t;
    }
    // Walks are made once per distinct (region, label) in use: one line serves every part of it.
    std::vector<std::pair<std::int32_t, std::int32_t>> used;
    for (std::int32_t p = 0; p < num_parts; ++p) {
      const std::int32_t t = part_first[p];
      used.emplace_back(region[t], label[t]);
    }
    std::sort(used.begin(), used.end());
    used.erase(std::unique(used.begin(), used.end()), used.end());

    // --- 2. every tet: is it sandwiched by a part of another label, and may it join it? ---
    std::vector<char> stuck(n, 0);
    std::vector<std::int32_t> target_part(n, -1);
    tbb::parallel_for(std::int32_t{0}, n, [&](std::int32_t t) {
      target[t] = -1;
      std::int32_t best = -1;
      std::vector<std::int32_t> ahead, behind;
      for (const auto& [r, l] : used) {
        if (r != region[t] || l == label[t]) continue;
        const Vec3& d = directions[r][l];
        ahead.clear();
        behind.clear();
        auto keep = [&](std::vector<std::int32_t>& list) {
          return [&](std::int32_t u) {
            if (region[u] == r && label[u] == l) add_unique(list, part[u]);
          };
        };
        walk_line(tets, t, centre[t], d, keep(ahead));
        if (ahead.empty()) continue;
        walk_line(tets, t, centre[t], -d, keep(behind));
        for (std::int32_t p : ahead) {
          if (std::find(behind.begin(), behind.end(), p) == behind.end()) continue;
          if (moved[t] || !allows(t, r, l)) {
            stuck[t] = 1;
            continue;
          }
          if (best < 0 || part_volume[p] > part_volume[best] ||
              (part_volume[p] == part_volume[best] && part_first[p] < part_first[best]))
            best = p;
        }
      }
      if (best >= 0) {
        target[t] = label[part_first[best]];
        target_part[t] = best;
        stuck[t] = 0;
      }
    });

    // A tet joins only through tets that join too: moved tets that would not touch the part
    // would make new, separate parts of its label. Those wait for a later round.
    std::vector<char> joined(n, 0);
    std::vector<std::int32_t> queue;
    for (std::int32_t t = 0; t < n; ++t) {
      if (target_part[t] < 0) continue;
      for (std::int32_t u : tets.neighbors[t])
        if (u >= 0 && part[u] == target_part[t] && target_part[u] < 0) {
          joined[t] = 1;
          queue.push_back(t);
          break;
        }
    }
    while (!queue.empty()) {
      const std::int32_t t = queue.back();
      queue.pop_back();
      for (std::int32_t u : tets.neighbors[t])
        if (u >= 0 && !joined[u] && target_part[u] == target_part[t]) {
          joined[u] = 1;
          queue.push_back(u);
        }
    }
    for (std::int32_t t = 0; t < n; ++t)
      if (target_part[t] >= 0 && !joined[t]) {
        target[t] = -1;
        stuck[t] = 1;
      }

    // --- 3. move them all at once, so the outcome does not depend on the visiting order ---
    const std::int32_t found = static_cast<std::int32_t>(
        std::count_if(target.begin(), target.end(), [](std::int32_t l) { return l >= 0; }));
    const std::int32_t sandwiched =
        found + static_cast<std::int32_t>(std::count(stuck.begin(), stuck.end(), char{1}));
    if (round == 0) initial_parts = num_parts;
    const bool few_enough = num_parts <= initial_parts + opts.max_extra_parts;
    if (few_enough && (best_sandwiched < 0 || sandwiched < best_sandwiched)) {
      best_sandwiched = sandwiched;
      best = label;
      repair.rounds = round;
      repair.converged = found == 0;
      repair.stuck_tets = sandwiched;
      repair.merged_pieces = pieces.merged_pieces;
      repair.merged_tets = pieces.merged_tets;
    }
    // Pieces seldom join again once the parts outnumber the budget: two such rounds in a row
    // end the search (the walks are the stage's cost).
    over_budget = few_enough ? 0 : over_budget + 1;
    if (found == 0 || round == opts.max_rounds || over_budget == 2) break;
    const std::vector<std::int32_t> before = label;
    for (std::int32_t t = 0; t < n; ++t)
      if (target[t] >= 0) label[t] = target[t];

    // --- 4. pieces the moves cut off ---
    // A part that lost tets may fall apart; a piece that no neighbour can take whole would be
    // a new part, so the moves out of that part are undone and its tets stay where they are.
    merge_pieces(tets, label, region, volume, allows, num_parts, pieces);
    std::int32_t now_parts = 0;
    std::vector<std::int32_t> now = detail::label_components(tets, label, region, now_parts);
    if (now_parts > num_parts) {
      // Pieces: components made only of tets that stayed in one old part, other than that
      // part's largest one.
      std::vector<std::int32_t> source(now_parts, -2);  // old part, -1 when mixed
      std::vector<double> now_volume(now_parts, 0.0);
      for (std::int32_t t = 0; t < n; ++t) {
        const std::int32_t c = now[t];
        now_volume[c] += volume[t];
        const std::int32_t from = before[t] == label[t] ? part[t] : -1;
        source[c] = source[c] == -2 ? from : (source[c] == from ? from : -1);
      }
      std::vector<std::int32_t> largest(num_parts, -1);
      for (std::int32_t c = 0; c < now_parts; ++c) {
        const std::int32_t q = source[c];
        if (q < 0) continue;
        if (largest[q] < 0 || now_volume[c] > now_volume[largest[q]]) largest[q] = c;
      }
      std::vector<char> undo(num_parts, 0);
      for (std::int32_t c = 0; c < now_parts; ++c)
        if (source[c] >= 0 && largest[source[c]] != c) undo[source[c]] = 1;
      for (std::int32_t t = 0; t < n; ++t)
        if (before[t] != label[t] && undo[part[t]]) {
          label[t] = before[t];
          moved[t] = 1;  // would cut its part again: stays for good
        }
    }

    // --- 5. a tet moves at most once, so two parts cannot trade it back and forth ---
    bool changed = false;
    for (std::int32_t t = 0; t < n; ++t)
      if (before[t] != label[t]) moved[t] = 1, changed = true;
    if (!changed) break;  // every move was undone
  }

  // --- 6. what moved, from the start to the labeling kept ---
  label = best;
  std::map<std::tuple<std::int32_t, std::int32_t, std::int32_t>, SandwichMove> moves;
  for (std::int32_t t = 0; t < n; ++t) {
    if (initial[t] == label[t]) continue;
    SandwichMove& m = moves[{region[t], initial[t], label[t]}];
    m.region = region[t];
    m.from_label = initial[t];
    m.to_label = label[t];
    ++m.tets;
    m.volume_mm3 += volume[t];
    ++repair.moved_tets;
    repair.moved_volume_mm3 += volume[t];
  }
  for (const auto& [key, m] : moves) repair.moves.push_back(m);
  return repair;
}

}  // namespace dhfcast
