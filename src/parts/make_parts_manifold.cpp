// Label-level topology repair: a part whose tets meet only along an edge or at a vertex has a
// boundary that touches itself, which exact booleans downstream reject. A few tets around each
// such place change part until every part's boundary is a 2-manifold.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <numeric>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "components.h"
#include "dhfcast/error.h"
#include "dhfcast/parts.h"

namespace dhfcast {
namespace {

// One relabeling: these tets join part `to` (a part id, not a label).
struct Step {
  std::int32_t tet;
  std::int32_t to;
  auto operator<=>(const Step&) const = default;
};
using Move = std::vector<Step>;

class SmallUnionFind {
 public:
  void reset(int n) {
    parent_.resize(n);
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  int find(int x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<int> parent_;
};

class Repair {
 public:
  Repair(const TetMesh& tets, std::vector<std::int32_t>& label,
         const std::vector<std::int32_t>& region, const TetAllowsLabel& allows)
      : tets_(tets), label_(label), region_(region), allows_(allows) {
    const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
    std::int32_t num_parts = 0;
    part_ = detail::label_components(tets, label, region, num_parts);
    part_label_.assign(num_parts, -1);
    part_region_.assign(num_parts, -1);
    for (std::int32_t t = 0; t < n; ++t) {
      part_label_[part_[t]] = label[t];
      part_region_[part_[t]] = region[t];
    }
    // Stars as one flat array: the tets around vertex v are star_[star_start_[v] ..).
    star_start_.assign(tets.vertices.size() + 1, 0);
    for (const Tet& k : tets.tets)
      for (std::int32_t v : k) ++star_start_[v + 1];
    std::partial_sum(star_start_.begin(), star_start_.end(), star_start_.begin());
    star_.resize(star_start_.back());
    std::vector<std::int32_t> fill(star_start_.begin(), star_start_.end() - 1);
    for (std::int32_t t = 0; t < n; ++t)
      for (std::int32_t v : tets.tets[t]) star_[fill[v]++] = t;
    volume_.resize(n);
    for (std::int32_t t = 0; t < n; ++t) volume_[t] = tet_volume(tets, t);
    seen_.assign(n, -1);
  }

  std::int32_t num_vertices() const { return static_cast<std::int32_t>(star_start_.size()) - 1; }

  // Vertices where some part's tets do not form a single disk-like fan, ascending. The scan is
  // parallel; each vertex's answer depends on its star only, so the list does not depend on
  // the thread count.
  std::vector<std::int32_t> bad_vertices() const {
    std::vector<char> bad(num_vertices(), 0);
    tbb::parallel_for(std::int32_t{0}, num_vertices(), [&](std::int32_t v) {
      SmallUnionFind uf;
      bad[v] = defect(v, uf) > 0;
    });
    std::vector<std::int32_t> out;
    for (std::int32_t v = 0; v < num_vertices(); ++v)
      if (bad[v]) out.push_back(v);
    return out;
  }

  // How far the parts around v are from each being one fan there: for every part P among the
  // tets around v, its tets there (connected through faces that contain v) should form one
  // group, and so should the rest (other parts' tets and, on the solid's boundary, the
  // outside). On the sphere of directions around v, P is then a disk: its boundary near v is a
  // single fan, and P does not touch itself along an edge through v either (that would pinch
  // the disk, splitting P's tets or the rest there).
  int defect(std::int32_t v, SmallUnionFind& uf) const {
    const std::int32_t* star = star_.data() + star_start_[v];
    const int m = star_start_[v + 1] - star_start_[v];
    const int outside = m;  // one node for everything outside the solid
    auto local = [&](std::int32_t u) {
      return static_cast<int>(std::find(star, star + m, u) - star);
    };
    // Most stars lie inside one part: nothing to count there.
    if (std::all_of(star, star + m, [&](std::int32_t t) { return part_[t] == part_[star[0]]; }))
      return 0;
    int total = 0;
    for (int i = 0; i < m; ++i) {
      const std::int32_t p = part_[star[i]];
      bool first = true;  // count each part once, at its first tet in the star
      for (int j = 0; j < i && first; ++j) first = part_[star[j]] != p;
      if (!first) continue;
      uf.reset(m + 1);
      bool on_boundary = false;
      for (int a = 0; a < m; ++a) {
        const std::int32_t t = star[a];
        const bool in_a = part_[t] == p;
        for (int f = 0; f < 4; ++f) {
          if (tets_.tets[t][f] == v) continue;  // the face opposite v does not contain it
          const std::int32_t u = tets_.neighbors[t][f];
          if (u < 0) {
            on_boundary = true;
            if (!in_a) uf.unite(a, outside);
          } else if ((part_[u] == p) == in_a) {
            uf.unite(a, local(u));
          }
        }
      }
      int groups_in = 0, groups_out = 0;
      for (int a = 0; a < m; ++a)
        if (uf.find(a) == a) ++(part_[star[a]] == p ? groups_in : groups_out);
      if (on_boundary && uf.find(outside) == outside) ++groups_out;
      total += (groups_in - 1) + std::max(0, groups_out - 1);
    }
    return total;
  }

  // Fixes vertex v with the best move found around it, if any move lowers the defect of the
  // vertices it touches. Returns whether a move was made.
  bool fix(std::int32_t v) {
    std::vector<Move> moves = candidates(v);
    struct Scored {
      int gain;
      double volume_mm3;
      std::size_t index;
    };
    std::vector<Scored> scored;
    for (std::size_t i = 0; i < moves.size(); ++i) {
      Move& move = moves[i];
      std::sort(move.begin(), move.end());
      // Only directions accessible for the tets: the parts stay DHFs at the tet level.
      if (!well_formed(move) || !std::all_of(move.begin(), move.end(), [&](const Step& step) {
            return allows_(step.tet, region_[step.tet], part_label_[step.to]);
          }))
        continue;
      const int gain = defect_gain(move);
      if (gain <= 0) continue;
      Scored s{gain, 0.0, i};
      for (const Step& step : move) s.volume_mm3 += volume_[step.tet];
      scored.push_back(s);
    }
    // The larger gain first, then the smaller volume moved; equal keys fall back to the moves'
    // contents, so the choice is unique.
    std::sort(scored.begin(), scored.end(), [&](const Scored& a, const Scored& b) {
      return std::tie(b.gain, a.volume_mm3, moves[a.index]) <
             std::tie(a.gain, b.volume_mm3, moves[b.index]);
    });
    for (const Scored& s : scored) {
      if (!keeps_parts_whole(moves[s.index])) continue;
      for (const Step& step : moves[s.index]) {
        part_[step.tet] = step.to;
        label_[step.tet] = part_label_[step.to];
      }
      return true;
    }
    return false;
  }

 private:
  // --- candidate moves around v ---
  std::vector<Move> candidates(std::int32_t v) const {
    const std::int32_t* star = star_.data() + star_start_[v];
    const int m = star_start_[v + 1] - star_start_[v];
    std::vector<Move> moves;
    // 1. one tet of the star joins a part it shares a face with
    for (int i = 0; i < m; ++i)
      for (std::int32_t q : neighbour_parts({star[i]})) moves.push_back({{star[i], q}});

    // Groups of the star's tets per part and of the rest, as in defect().
    std::vector<std::int32_t> parts_here;
    for (int i = 0; i < m; ++i)
      if (std::find(parts_here.begin(), parts_here.end(), part_[star[i]]) == parts_here.end())
        parts_here.push_back(part_[star[i]]);
    for (std::int32_t p : parts_here) {
      const std::vector<Group> in = groups(v, p, true);
      const std::vector<Group> out = groups(v, p, false);
      if (in.size() > 1)
        for (const Group& g : in) {
          // 2. a group of P's tets leaves P whole, for a part it touches
          for (std::int32_t q : neighbour_parts(g.tets)) {
            Move move;
            for (std::int32_t t : g.tets) move.push_back({t, q});
            moves.push_back(move);
          }
          // 3. the fewest other tets around v that join this group to another one of P's
          const Path bridge = shortest_path(v, g, p, true);
          if (!bridge.tets.empty()) moves.push_back(steps(bridge.tets, p));
        }
      const bool pocket = std::any_of(out.begin(), out.end(), [](const Group& g) {
        return !g.outer;
      });
      // The rest is in several groups when there are two or more, or one closed group (a
      // pocket) while P reaches the outside itself.
      if (out.size() > 1 || (pocket && touches_outside_in(v, p)))
        for (const Group& g : out) {
          // 4. a pocket of the rest, closed off by P around v, joins P
          if (!g.outer) moves.push_back(steps(g.tets, p));
          // 5. the fewest of P's tets around v that join this group of the rest to another
          // leave P for the part they touch in this group
          const Path cut = shortest_path(v, g, p, false);
          if (!cut.tets.empty()) moves.push_back(steps(cut.tets, cut.start_part));
        }
    }
    return moves;
  }

  // Parts (of the same region) other than the tets' own that share a face with one of them.
  std::vector<std::int32_t> neighbour_parts(const std::vector<std::int32_t>& group) const {
    std::vector<std::int32_t> out;
    for (std::int32_t t : group)
      for (std::int32_t u : tets_.neighbors[t])
        if (u >= 0 && part_[u] != part_[t] && region_[u] == region_[t] &&
            std::find(out.begin(), out.end(), part_[u]) == out.end())
          out.push_back(part_[u]);
    std::sort(out.begin(), out.end());
    return out;
  }

  // Tets around v of part p (inside) or not of it, in groups connected through faces that
  // contain v. Groups of the rest that reach the outside of the solid are one group through it.
  struct Group {
    std::vector<std::int32_t> tets;  // ascending
    bool outer = false;              // reaches the outside through a face that contains v
  };
  std::vector<Group> groups(std::int32_t v, std::int32_t p, bool inside) const {
    const std::int32_t* star = star_.data() + star_start_[v];
    const int m = star_start_[v + 1] - star_start_[v];
    std::vector<int> group_of(m, -1);
    std::vector<Group> out;
    for (int s = 0; s < m; ++s) {
      if ((part_[star[s]] == p) != inside || group_of[s] >= 0) continue;
      const int g = static_cast<int>(out.size());
      out.emplace_back();
      std::vector<int> stack{s};
      group_of[s] = g;
      while (!stack.empty()) {
        const int a = stack.back();
        stack.pop_back();
        out[g].tets.push_back(star[a]);
        out[g].outer |= touches_outside(v, star[a]);
        for (int f = 0; f < 4; ++f) {
          const std::int32_t u = tets_.neighbors[star[a]][f];
          if (tets_.tets[star[a]][f] == v || u < 0 || (part_[u] == p) != inside) continue;
          const int b = static_cast<int>(std::find(star, star + m, u) - star);
          if (group_of[b] < 0) {
            group_of[b] = g;
            stack.push_back(b);
          }
        }
      }
    }
    if (!inside) {
      std::vector<Group> joined;
      Group outer{{}, true};
      for (Group& g : out) {
        if (g.outer)
          outer.tets.insert(outer.tets.end(), g.tets.begin(), g.tets.end());
        else
          joined.push_back(std::move(g));
      }
      if (!outer.tets.empty()) joined.push_back(std::move(outer));
      out = std::move(joined);
    }
    for (Group& g : out) std::sort(g.tets.begin(), g.tets.end());
    return out;
  }

  // Whether tet t (around v) has a face on the solid's boundary that contains v.
  bool touches_outside(std::int32_t v, std::int32_t t) const {
    for (int f = 0; f < 4; ++f)
      if (tets_.tets[t][f] != v && tets_.neighbors[t][f] < 0) return true;
    return false;
  }

  static Move steps(const std::vector<std::int32_t>& tets, std::int32_t to) {
    Move move;
    for (std::int32_t t : tets) move.push_back({t, to});
    return move;
  }

  // Whether some tet of part p around v has a face on the solid's boundary that contains v.
  bool touches_outside_in(std::int32_t v, std::int32_t p) const {
    for (std::int32_t i = star_start_[v]; i < star_start_[v + 1]; ++i)
      if (part_[star_[i]] == p && touches_outside(v, star_[i])) return true;
    return false;
  }

  struct Path {
    std::vector<std::int32_t> tets;  // crossed, from the far end back to the start
    std::int32_t start_part = -1;    // part of the group's tet the path leaves from
  };
  // Breadth-first through the star of v, from the group's tets, across tets of the other kind
  // (not of part p when `inside`, of p otherwise) until a tet of the first kind outside the
  // group is reached, or, across p's tets from a closed group, the outside of the solid.
  // Neighbours are visited in ascending order, so the path found is unique. Empty when none.
  Path shortest_path(std::int32_t v, const Group& from, std::int32_t p, bool inside) const {
    const std::int32_t* star = star_.data() + star_start_[v];
    const int m = star_start_[v + 1] - star_start_[v];
    auto index = [&](std::int32_t u) {
      return static_cast<int>(std::find(star, star + m, u) - star);
    };
    std::vector<int> came_from(m, -2);  // -1: a start
    std::deque<int> queue;
    for (std::int32_t t : from.tets) {
      came_from[index(t)] = -1;
      queue.push_back(index(t));
    }
    auto path_to = [&](int a) {
      Path path;
      int c = a;
      for (; came_from[c] != -1; c = came_from[c]) path.tets.push_back(star[c]);
      path.start_part = part_[star[c]];
      return path;
    };
    while (!queue.empty()) {
      const int a = queue.front();
      queue.pop_front();
      if (!inside && !from.outer && came_from[a] != -1 && touches_outside(v, star[a]))
        return path_to(a);
      std::vector<std::int32_t> next;
      for (int f = 0; f < 4; ++f)
        if (tets_.tets[star[a]][f] != v && tets_.neighbors[star[a]][f] >= 0)
          next.push_back(tets_.neighbors[star[a]][f]);
      std::sort(next.begin(), next.end());
      for (std::int32_t u : next) {
        const int b = index(u);
        if (came_from[b] != -2) continue;
        if ((part_[u] == p) == inside) {
          if (came_from[a] != -1) return path_to(a);
          continue;  // the group's own kind next to the group is in the group
        }
        came_from[b] = a;
        queue.push_back(b);
      }
    }
    return {};
  }

  // --- checks on a move (steps sorted by tet) ---
  // One step per tet, each to another part of its region, no part both gaining and losing.
  bool well_formed(const Move& move) const {
    for (std::size_t i = 0; i < move.size(); ++i) {
      const Step& s = move[i];
      if (i > 0 && move[i - 1].tet == s.tet) return false;
      if (s.to == part_[s.tet] || part_region_[s.to] != region_[s.tet]) return false;
      for (const Step& o : move)
        if (part_[o.tet] == s.to) return false;
    }
    return true;
  }

  // How much the move lowers the defect of the vertices of the tets it moves (the only
  // vertices whose stars change).
  int defect_gain(const Move& move) {
    std::vector<std::int32_t> touched;
    for (const Step& s : move)
      touched.insert(touched.end(), tets_.tets[s.tet].begin(), tets_.tets[s.tet].end());
    std::sort(touched.begin(), touched.end());
    touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
    SmallUnionFind uf;
    int before = 0, after = 0;
    for (std::int32_t u : touched) before += defect(u, uf);
    std::vector<std::int32_t> old;
    for (const Step& s : move) {
      old.push_back(part_[s.tet]);
      part_[s.tet] = s.to;
    }
    for (std::int32_t u : touched) after += defect(u, uf);
    for (std::size_t i = 0; i < move.size(); ++i) part_[move[i].tet] = old[i];
    // A tet that would touch another part of its new label through a face would merge the two
    // parts: not allowed (merged parts may not be DHFs any more).
    for (const Step& s : move)
      for (std::int32_t u : tets_.neighbors[s.tet])
        if (u >= 0 && part_[u] != s.to && label_[u] == part_label_[s.to] &&
            region_[u] == part_region_[s.to] &&
            !std::binary_search(move.begin(), move.end(), Step{u, s.to}))
          return 0;
    return before - after;
  }

  // The move neither splits a part nor makes a new one: the tets joining a part reach it
  // through faces, and what every losing part keeps stays face-connected.
  bool keeps_parts_whole(const Move& move) {
    auto moving = [&](std::int32_t t) {
      const auto it = std::lower_bound(move.begin(), move.end(), Step{t, INT32_MIN});
      return it != move.end() && it->tet == t;
    };
    // --- tets joining a part: each reaches it through moving tets bound there ---
    std::vector<char> reached(move.size(), 0);
    std::vector<std::size_t> stack;
    for (std::size_t i = 0; i < move.size(); ++i)
      for (std::int32_t u : tets_.neighbors[move[i].tet])
        if (u >= 0 && !moving(u) && part_[u] == move[i].to && !reached[i]) {
          reached[i] = 1;
          stack.push_back(i);
        }
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      for (std::size_t j = 0; j < move.size(); ++j)
        if (!reached[j] && move[j].to == move[i].to &&
            std::find(tets_.neighbors[move[i].tet].begin(), tets_.neighbors[move[i].tet].end(),
                      move[j].tet) != tets_.neighbors[move[i].tet].end()) {
          reached[j] = 1;
          stack.push_back(j);
        }
    }
    if (std::count(reached.begin(), reached.end(), 0) > 0) return false;

    // --- parts losing tets: what each keeps next to the move stays connected ---
    std::vector<std::int32_t> losers;
    for (const Step& s : move) losers.push_back(part_[s.tet]);
    std::sort(losers.begin(), losers.end());
    losers.erase(std::unique(losers.begin(), losers.end()), losers.end());
    for (std::int32_t q : losers) {
      std::vector<std::int32_t> seeds;
      for (const Step& s : move)
        for (std::int32_t u : tets_.neighbors[s.tet])
          if (u >= 0 && part_[u] == q && !moving(u)) seeds.push_back(u);
      std::sort(seeds.begin(), seeds.end());
      seeds.erase(std::unique(seeds.begin(), seeds.end()), seeds.end());
      if (!connected_without(q, seeds, moving)) return false;
    }
    return true;
  }

  // Whether the seeds (tets of part q) stay connected through q's tets that do not move. One
  // breadth-first search per seed, advanced in turn, so a piece that would be cut off is
  // found after about its own size in steps, not the whole part's.
  template <class Moving>
  bool connected_without(std::int32_t q, const std::vector<std::int32_t>& seeds,
                         const Moving& moving) {
    if (seeds.size() <= 1) return true;
    const int k = static_cast<int>(seeds.size());
    SmallUnionFind uf;
    uf.reset(k);
    int classes = k;
    std::vector<std::deque<std::int32_t>> queue(k);
    std::vector<std::int32_t> touched;
    for (int g = 0; g < k; ++g) {
      if (seen_[seeds[g]] >= 0) {
        if (uf.find(g) != uf.find(seen_[seeds[g]])) --classes;
        uf.unite(g, seen_[seeds[g]]);
        continue;
      }
      seen_[seeds[g]] = g;
      touched.push_back(seeds[g]);
      queue[g].push_back(seeds[g]);
    }
    bool split = false;
    while (classes > 1 && !split) {
      for (int g = 0; g < k && classes > 1; ++g) {
        if (queue[g].empty()) continue;
        const std::int32_t t = queue[g].front();
        queue[g].pop_front();
        for (std::int32_t u : tets_.neighbors[t]) {
          if (u < 0 || part_[u] != q || moving(u)) continue;
          if (seen_[u] < 0) {
            seen_[u] = g;
            touched.push_back(u);
            queue[g].push_back(u);
          } else if (uf.find(seen_[u]) != uf.find(g)) {
            uf.unite(seen_[u], g);
            --classes;
          }
        }
      }
      // A class whose searches have all run dry is a piece of its own.
      std::vector<char> alive(k, 0);
      for (int g = 0; g < k; ++g)
        if (!queue[g].empty()) alive[uf.find(g)] = 1;
      for (int g = 0; g < k; ++g)
        if (uf.find(g) == g && !alive[g] && classes > 1) split = true;
    }
    for (std::int32_t t : touched) seen_[t] = -1;
    return !split;
  }

  const TetMesh& tets_;
  std::vector<std::int32_t>& label_;
  const std::vector<std::int32_t>& region_;
  const TetAllowsLabel& allows_;
  std::vector<std::int32_t> part_;  // face-connected component of each tet (its part)
  std::vector<std::int32_t> part_label_, part_region_;
  std::vector<std::int32_t> star_start_, star_;
  std::vector<double> volume_;
  std::vector<std::int32_t> seen_;  // search marks of connected_without(), -1 when unmarked
};

}  // namespace

ManifoldRepair make_parts_manifold(const TetMesh& tets, std::vector<std::int32_t>& label,
                                   const std::vector<std::int32_t>& region,
                                   const TetAllowsLabel& allows, std::int32_t max_rounds) {
  if (max_rounds < 0)
    throw Error(ErrorCode::InvalidOptions, "manifold repair: max_rounds must be >= 0");
  if (tets.neighbors.size() != tets.tets.size() || label.size() != tets.tets.size() ||
      region.size() != tets.tets.size())
    throw Error(ErrorCode::Internal, "manifold repair: one label, region and adjacency per tet");
  const std::vector<std::int32_t> initial = label;
  Repair repair(tets, label, region, allows);
  ManifoldRepair out;
  std::vector<std::int32_t> bad = repair.bad_vertices();
  // Every move lowers the summed defect of all vertices, so the rounds end; the bound only
  // caps the time spent on vertices no single move around them improves.
  while (!bad.empty() && out.rounds < max_rounds) {
    ++out.rounds;
    bool moved = false;
    SmallUnionFind uf;
    for (std::int32_t v : bad)
      if (repair.defect(v, uf) > 0) moved |= repair.fix(v);
    bad = repair.bad_vertices();
    if (!moved) break;
  }
  out.nonmanifold_vertices = static_cast<std::int32_t>(bad.size());
  for (std::size_t t = 0; t < label.size(); ++t) {
    if (label[t] == initial[t]) continue;
    ++out.moved_tets;
    out.moved_volume_mm3 += tet_volume(tets, static_cast<std::int32_t>(t));
  }
  return out;
}

}  // namespace dhfcast
