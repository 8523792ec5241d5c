// Label-level DHF repair (paper §4.3.1, "infeasible volume"): tets of one part that lie between
// two pieces of another part along that part's direction go to that part.
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "components.h"
#include "dhfcast/error.h"
#include "dhfcast/parts.h"

namespace dhfcast {
namespace {

// A whole part smaller than this share of the solid is a fragment the repair left (a few tets):
// it goes to a neighbour. Larger small parts stay: forcing them into a neighbour costs that
// neighbour its DHF property, or makes it touch itself.
constexpr double kFragmentShare = 1e-4;

// Per tet, tet_face_normal() of each face: computed once, as every line walk needs them at
// every step.
using FaceNormals = std::vector<std::array<Vec3, 4>>;

FaceNormals face_normals(const TetMesh& tets) {
  FaceNormals normals(tets.tets.size());
  tbb::parallel_for(std::size_t{0}, tets.tets.size(), [&](std::size_t t) {
    for (int i = 0; i < 4; ++i)
      normals[t][i] = tet_face_normal(tets, static_cast<std::int32_t>(t), i);
  });
  return normals;
}

// Calls visit(u) for every tet u the ray x + s * d, s > 0, enters after tet t, until it leaves
// the tet mesh or visit returns false. Each step leaves the current tet through the face whose
// plane the ray reaches first among those it points out of, so every step makes progress even
// when rounding puts x slightly off the entry face; the step cap guards against cycling on
// degenerate tets.
template <class Visit>
void walk_line(const TetMesh& tets, const FaceNormals& normals, std::int32_t t, Vec3 x,
               const Vec3& d, Visit&& visit) {
  const std::size_t max_steps = tets.tets.size();
  for (std::size_t step = 0; step < max_steps; ++step) {
    const Tet& k = tets.tets[t];
    int exit = -1;
    double best = INFINITY;
    for (int i = 0; i < 4; ++i) {
      const Vec3& n = normals[t][i];
      const double along = n.dot(d);
      if (!(along > 0.0)) continue;
      const double s = std::max(0.0, n.dot(tets.vertices[k[kTetFaces[i][0]]] - x) / along);
      if (s < best) {
        best = s;
        exit = i;
      }
    }
    if (exit < 0) return;
    const std::int32_t u = tets.neighbors[t][exit];
    if (u < 0) return;
    x += best * d;
    if (!visit(u)) return;
    t = u;
  }
}

// The tets walk_line() visits from every tet's centre along one direction, in order. They do not
// depend on the labeling, and the repair walks the same lines round after round: read from here,
// a walk is a scan of an array instead of a face test per step.
class LineTable {
 public:
  LineTable(const TetMesh& tets, const FaceNormals& normals, const std::vector<Vec3>& centre,
            const Vec3& d) {
    // Each chunk of tets walks into its own buffer, joined in chunk order after.
    constexpr std::int32_t kChunk = 1024;
    const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
    const std::int32_t chunks = (n + kChunk - 1) / kChunk;
    std::vector<std::vector<std::int32_t>> visited(chunks);
    start_.assign(n + 1, 0);
    tbb::parallel_for(std::int32_t{0}, chunks, [&](std::int32_t c) {
      for (std::int32_t t = c * kChunk; t < std::min(n, (c + 1) * kChunk); ++t) {
        const std::size_t before = visited[c].size();
        walk_line(tets, normals, t, centre[t], d,
                  [&](std::int32_t u) { return visited[c].push_back(u), true; });
        start_[t + 1] = static_cast<std::int64_t>(visited[c].size() - before);
      }
    });
    for (std::int32_t t = 0; t < n; ++t) start_[t + 1] += start_[t];
    tets_.reserve(start_[n]);
    for (const std::vector<std::int32_t>& v : visited)
      tets_.insert(tets_.end(), v.begin(), v.end());
  }
  std::span<const std::int32_t> from(std::int32_t t) const {
    return {tets_.data() + start_[t], tets_.data() + start_[t + 1]};
  }
  std::size_t bytes() const { return 8 * start_.size() + 4 * tets_.size(); }

 private:
  std::vector<std::int64_t> start_;
  std::vector<std::int32_t> tets_;
};

// Each tet's centre (the mean of its vertices): where the repair's lines start.
std::vector<Vec3> tet_centres(const TetMesh& tets) {
  std::vector<Vec3> centre(tets.tets.size());
  for (std::size_t t = 0; t < tets.tets.size(); ++t) {
    const Tet& k = tets.tets[t];
    centre[t] = 0.25 * (tets.vertices[k[0]] + tets.vertices[k[1]] + tets.vertices[k[2]] +
                        tets.vertices[k[3]]);
  }
  return centre;
}

// Line tables take memory in proportion to the tets times the tets a line crosses: past this
// budget, further directions are walked instead.
constexpr std::size_t kLineTableBudgetBytes = std::size_t{1} << 30;

}  // namespace

// The line tables of one tet mesh, by direction, made on first use.
class TetLines {
 public:
  explicit TetLines(const TetMesh& tets)
      : tets_(tets), normals_(face_normals(tets)), centre_(tet_centres(tets)) {}
  const TetMesh& tets() const { return tets_; }
  const FaceNormals& normals() const { return normals_; }
  const std::vector<Vec3>& centres() const { return centre_; }

  // The table along d, or none once the budget is spent.
  std::shared_ptr<const LineTable> along(const Vec3& d) {
    const std::lock_guard lock(mutex_);
    for (const auto& [e, table] : tables_)
      if (e == d) return table;
    if (bytes_ > kLineTableBudgetBytes) return nullptr;
    // Isolated: while it waits for its own loop, this thread must not take up another caller's
    // work that would wait for the lock it holds.
    std::shared_ptr<const LineTable> table;
    tbb::this_task_arena::isolate(
        [&] { table = std::make_shared<const LineTable>(tets_, normals_, centre_, d); });
    bytes_ += table->bytes();
    tables_.emplace_back(d, table);
    return table;
  }

 private:
  const TetMesh& tets_;
  FaceNormals normals_;
  std::vector<Vec3> centre_;
  std::mutex mutex_;
  std::vector<std::pair<Vec3, std::shared_ptr<const LineTable>>> tables_;
  std::size_t bytes_ = 0;
};

std::shared_ptr<TetLines> make_tet_lines(const TetMesh& tets) {
  return std::make_shared<TetLines>(tets);
}

namespace {

// Added to a footprint's sides, so that rounding on a line that grazes one never matters.
constexpr double kFootprintSlackMm = 1e-6;

// The box that a set of tets covers across a direction d: a line along d through a point
// outside it meets none of them.
struct Footprint {
  explicit Footprint(const Vec3& d) : u(d.unitOrthogonal()), v(d.cross(u)) {}
  Vec3 u, v;
  double u_lo = INFINITY, u_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY;

  void add(const TetMesh& tets, std::int32_t t) {
    for (std::int32_t i : tets.tets[t]) {
      const Vec3& x = tets.vertices[i];
      u_lo = std::min(u_lo, x.dot(u)), u_hi = std::max(u_hi, x.dot(u));
      v_lo = std::min(v_lo, x.dot(v)), v_hi = std::max(v_hi, x.dot(v));
    }
  }
  // Whether x lies within the box grown by `grow` on every side.
  bool contains(const Vec3& x, double grow) const {
    const double a = x.dot(u), b = x.dot(v);
    return a >= u_lo - grow && a <= u_hi + grow && b >= v_lo - grow && b <= v_hi + grow;
  }
};

// The repair's working state: which part owns each tet, and each part's fixed attributes.
// Parts are the face-connected components of the labeling at the start; a part keeps its id
// while it gains and loses tets, even if it falls apart.
struct Parts {
  const TetMesh& tets;
  const FaceNormals& normals;
  const std::vector<std::int32_t>& region;
  const std::vector<Vec3>& directions;
  const TetAllowsLabel& allows;
  std::vector<Vec3> centre;
  std::vector<double> volume;
  std::vector<std::int32_t> owner;
  std::vector<std::int32_t> label_of, region_of;
  std::vector<char> frozen;  // settled parts: their tets never move again
  double tet_radius = 0.0;   // the largest distance from a tet's centre to one of its vertices
  TetLines* line_source = nullptr;
  std::vector<std::pair<Vec3, std::shared_ptr<const LineTable>>> lines;  // by direction

  // Tables of the lines along +-d of every direction `label` uses, within the budget. Called
  // outside parallel loops: the walks read the tables without a lock.
  void prepare_lines(const std::vector<std::int32_t>& label) {
    std::vector<std::pair<std::int32_t, std::int32_t>> used;
    for (std::size_t t = 0; t < label.size(); ++t) used.emplace_back(region[t], label[t]);
    std::sort(used.begin(), used.end());
    used.erase(std::unique(used.begin(), used.end()), used.end());
    for (const auto& [r, l] : used)
      for (const Vec3& d : {directions[l], Vec3(-directions[l])}) {
        if (line_table(d)) continue;
        if (std::shared_ptr<const LineTable> table = line_source->along(d))
          lines.emplace_back(d, std::move(table));
      }
  }
  const LineTable* line_table(const Vec3& d) const {
    for (const auto& [e, table] : lines)
      if (e == d) return table.get();
    return nullptr;
  }
  // Calls visit(u) for the tets walk_line() visits from t's centre along d, until visit returns
  // false.
  template <class Visit>
  void walk_from(std::int32_t t, const Vec3& d, Visit&& visit) const {
    if (const LineTable* table = line_table(d)) {
      for (std::int32_t u : table->from(t))
        if (!visit(u)) return;
      return;
    }
    walk_line(tets, normals, t, centre[t], d, visit);
  }

  std::int32_t size() const { return static_cast<std::int32_t>(label_of.size()); }

  // Makes the parts the face-connected components of `label` (all settled or none); returns
  // how many.
  std::int32_t take_parts(const std::vector<std::int32_t>& label, bool settled) {
    std::int32_t count = 0;
    owner = detail::label_components(tets, label, region, count);
    label_of.assign(count, -1);
    region_of.assign(count, -1);
    frozen.assign(count, settled ? 1 : 0);
    for (std::size_t t = 0; t < owner.size(); ++t)
      if (label_of[owner[t]] < 0) label_of[owner[t]] = label[t], region_of[owner[t]] = region[t];
    return count;
  }
  const Vec3& direction(std::int32_t p) const { return directions[label_of[p]]; }
  bool may_join(std::int32_t t, std::int32_t p) const {
    return region[t] == region_of[p] && allows(t, region_of[p], label_of[p]);
  }

  // Whether walking from tet t along d meets a tet `in` accepts after a run of tets `in`
  // rejects that contains one `passable` rejects.
  template <class In, class Passable>
  bool blocked_gap(std::int32_t t, const Vec3& d, In&& in, Passable&& passable) const {
    bool blocked = false, found = false;
    walk_from(t, d, [&](std::int32_t u) {
      if (in(u)) {
        found = blocked;
        return !found;
      }
      blocked = blocked || !passable(u);
      return true;
    });
    return found;
  }

  // Whether walking from tet t along d meets a tet `in` accepts before any tet `passable`
  // rejects.
  template <class In, class Passable>
  bool reaches(std::int32_t t, const Vec3& d, In&& in, Passable&& passable) const {
    bool found = false;
    walk_from(t, d, [&](std::int32_t u) {
      if (in(u)) {
        found = true;
        return false;
      }
      return static_cast<bool>(passable(u));
    });
    return found;
  }

  // Tets not in part x that lie between two of its tets along its direction, among those whose
  // line along it passes near `piece`'s tets (the only ones that moving the piece can change):
  // as the parts are, and once the tets of `piece` belong to part `to`. One walk per line
  // answers both.
  std::pair<std::int32_t, std::int32_t> count_sandwiched_by(std::int32_t x,
                                                            const std::vector<std::int32_t>& piece,
                                                            std::int32_t to) const {
    const std::int32_t n = static_cast<std::int32_t>(owner.size());
    const Vec3 d = direction(x);
    // The piece's footprint across d, grown by its largest tet's size.
    Footprint box(d);
    double grow = 0.0;
    std::vector<char> moves(n, 0);
    for (std::int32_t t : piece) {
      box.add(tets, t);
      moves[t] = 1;
      for (std::int32_t i : tets.tets[t])
        grow = std::max(grow, (tets.vertices[i] - centre[t]).norm());
    }
    // Bit 1: in x as the parts are; bit 2: in x once the piece has moved.
    const auto in_x = [&](std::int32_t w) {
      return (owner[w] == x ? 1 : 0) | ((moves[w] ? to : owner[w]) == x ? 2 : 0);
    };
    // x's tets' centres lie within [lo, hi] along d in both states. A walk enters each tet at a
    // point within tet_radius of its centre, and goes on only further along its direction: once
    // a centre lies more than twice that beyond x's range, no tet of x follows.
    double lo = INFINITY, hi = -INFINITY;
    for (std::int32_t t = 0; t < n; ++t)
      if (in_x(t)) lo = std::min(lo, centre[t].dot(d)), hi = std::max(hi, centre[t].dot(d));
    const double beyond = 2.0 * tet_radius + kFootprintSlackMm;
    std::vector<char> out(n, 0);
    tbb::parallel_for(std::int32_t{0}, n, [&](std::int32_t t) {
      if (region[t] != region_of[x] || !box.contains(centre[t], grow)) return;
      const int outside = 3 & ~in_x(t);
      if (!outside) return;
      // The states in `outside` in which the line from t along sign * d meets x.
      const auto meets = [&](double sign) {
        const double last = sign > 0 ? hi + beyond : -(lo - beyond);
        int seen = 0;
        walk_from(t, sign * d, [&](std::int32_t u) {
          return (seen |= in_x(u) & outside) != outside && sign * centre[u].dot(d) <= last;
        });
        return seen;
      };
      const int ahead = meets(1.0);
      out[t] = static_cast<char>(ahead ? ahead & meets(-1.0) : 0);
    });
    std::pair<std::int32_t, std::int32_t> count{0, 0};
    for (const char o : out) count.first += o & 1, count.second += (o >> 1) & 1;
    return count;
  }
};

// Face-connected components of the tets with mark[t], by smallest tet; returns their tets.
std::vector<std::vector<std::int32_t>> marked_components(const TetMesh& tets,
                                                         const std::vector<char>& mark) {
  const std::vector<std::int32_t> as_label(mark.begin(), mark.end());
  std::int32_t count = 0;
  const std::vector<std::int32_t> component =
      detail::label_components(tets, as_label, std::vector<std::int32_t>(mark.size(), 0), count);
  std::vector<std::vector<std::int32_t>> members(count);
  for (std::size_t t = 0; t < mark.size(); ++t)
    if (mark[t]) members[component[t]].push_back(static_cast<std::int32_t>(t));
  std::erase_if(members, [](const auto& c) { return c.empty(); });
  return members;
}

// Gives the tets of `piece` (all owned by one part) to a neighbouring part that allows all of
// them: the unsettled one sharing the most face area with it, else the settled one sharing the
// most area that gains no sandwich along its direction. When `force`, and no such neighbour
// exists, to the neighbour whose direction allows the most of its volume (then the most shared
// area). Returns whether it moved.
bool give_away(Parts& s, const std::vector<std::int32_t>& piece, bool force) {
  const std::int32_t from = s.owner[piece.front()];
  std::map<std::int32_t, double> shared;
  for (std::int32_t t : piece)
    for (int i = 0; i < 4; ++i) {
      const std::int32_t u = s.tets.neighbors[t][i];
      if (u >= 0 && s.owner[u] != from) shared[s.owner[u]] += tet_face_area(s.tets, t, i);
    }
  double piece_volume = 0.0;
  for (std::int32_t t : piece) piece_volume += s.volume[t];
  std::vector<std::tuple<int, double, std::int32_t>> fitting;  // (settled, -area, part)
  std::vector<std::tuple<double, double, std::int32_t>> any;   // (-allowed volume, -area, part)
  for (const auto& [q, area] : shared) {
    double allowed = 0.0;
    for (std::int32_t t : piece)
      if (s.may_join(t, q)) allowed += s.volume[t];
    if (allowed == piece_volume) fitting.emplace_back(s.frozen[q], -area, q);
    if (s.region_of[q] == s.region_of[from]) any.emplace_back(-allowed, -area, q);
  }
  std::sort(fitting.begin(), fitting.end());
  for (const auto& [settled, negative_area, q] : fitting) {
    if (settled) {
      const auto [before, after] = s.count_sandwiched_by(q, piece, q);
      if (after > before) continue;
    }
    for (std::int32_t t : piece) s.owner[t] = q;
    return true;
  }
  if (!force || any.empty()) return false;
  const std::int32_t q = std::get<2>(*std::min_element(any.begin(), any.end()));
  for (std::int32_t t : piece) s.owner[t] = q;
  return true;
}

// Makes part p free of sandwiches along its direction d, then settles it. Each round either
// fills: tets of unsettled parts that p may take and that reach p along d and -d through such
// tets only (and touch p through them) join p; or, when nothing is left to fill, cuts: p's tets
// beyond a gap it may not fill (a settled part, another region, a tet its direction does not
// allow) leave p, on the side of the gap with less volume, each face-connected piece to a
// neighbour (give_away()).
std::int32_t settle(Parts& s, std::int32_t p, std::int32_t max_rounds) {
  const std::int32_t n = static_cast<std::int32_t>(s.owner.size());
  const Vec3 d = s.direction(p);
  const auto in = [&](std::int32_t u) { return s.owner[u] == p; };
  const auto any = [](std::int32_t) { return true; };
  // Tets p gave away never come back, so a give and a fill cannot undo each other. Tets of a
  // settled part may come only from the ends of its columns (it gains no sandwich), and stay
  // where they are once taking them gave their part one anyway.
  std::vector<char> banned(n, 0), end_of_column(n, 0);
  const auto fillable = [&](std::int32_t u) {
    return !banned[u] && (!s.frozen[s.owner[u]] || end_of_column[u]) && s.may_join(u, p);
  };
  // A gap of tets p gave away is not one it could not fill: p gave them up where it had to.
  const auto passable = [&](std::int32_t u) { return banned[u] || fillable(u); };
  std::vector<char> fill(n, 0), above(n, 0), below(n, 0);
  // A line along d through a point outside p's footprint across d meets none of p's tets, and a
  // tet it crosses has its centre within s.tet_radius of it: the walks below start only from
  // tets where they can matter.
  for (std::int32_t round = 0; round < max_rounds; ++round) {
    Footprint box(d);
    for (std::int32_t t = 0; t < n; ++t)
      if (in(t)) box.add(s.tets, t);
    tbb::parallel_for(std::int32_t{0}, n, [&](std::int32_t t) {
      end_of_column[t] = 0;
      const std::int32_t q = s.owner[t];
      if (q == p || !s.frozen[q] || banned[t] ||
          !box.contains(s.centre[t], s.tet_radius + kFootprintSlackMm) || !s.may_join(t, p))
        return;
      const auto in_q = [&](std::int32_t u) { return s.owner[u] == q; };
      end_of_column[t] =
          !(s.reaches(t, s.direction(q), in_q, any) && s.reaches(t, -s.direction(q), in_q, any));
    });
    tbb::parallel_for(std::int32_t{0}, n, [&](std::int32_t t) {
      fill[t] = above[t] = below[t] = 0;
      if (s.region[t] != s.region_of[p]) return;
      if (in(t)) {
        above[t] = s.blocked_gap(t, d, in, passable);
        below[t] = s.blocked_gap(t, -d, in, passable);
      } else if (box.contains(s.centre[t], kFootprintSlackMm) && fillable(t)) {
        fill[t] = s.reaches(t, d, in, fillable) && s.reaches(t, -d, in, fillable);
      }
    });
    // A tet joins only through tets that join too, so p stays one piece.
    std::vector<char> joined(n, 0);
    std::vector<std::int32_t> queue;
    for (std::int32_t t = 0; t < n; ++t)
      if (fill[t])
        for (std::int32_t u : s.tets.neighbors[t])
          if (u >= 0 && in(u)) {
            joined[t] = 1;
            queue.push_back(t);
            break;
          }
    while (!queue.empty()) {
      const std::int32_t t = queue.back();
      queue.pop_back();
      for (std::int32_t u : s.tets.neighbors[t])
        if (u >= 0 && fill[u] && !joined[u]) {
          joined[u] = 1;
          queue.push_back(u);
        }
    }
    // Settled parts that lose tets: undone where they gain sandwiches all the same (several of
    // their column ends going at once can open a gap).
    std::map<std::int32_t, std::vector<std::int32_t>> taken;
    for (std::int32_t t = 0; t < n; ++t)
      if (joined[t] && s.frozen[s.owner[t]]) taken[s.owner[t]].push_back(t);
    for (auto& [q, ts] : taken) {
      const auto [before, after] = s.count_sandwiched_by(q, ts, p);
      for (std::int32_t t : ts) {
        if (after > before)
          banned[t] = 1, joined[t] = 0;
        else
          s.owner[t] = p;
      }
    }
    bool moved = false;
    for (std::int32_t t = 0; t < n; ++t)
      if (joined[t]) s.owner[t] = p, moved = true;
    if (moved || !taken.empty()) continue;

    double above_volume = 0.0, below_volume = 0.0;
    for (std::int32_t t = 0; t < n; ++t) {
      if (above[t]) above_volume += s.volume[t];
      if (below[t]) below_volume += s.volume[t];
    }
    if (above_volume == 0.0 && below_volume == 0.0) return round;
    // Tets with a gap below them are those above it: cutting them keeps p's lower side.
    const bool cut_upper =
        below_volume > 0.0 && (above_volume == 0.0 || below_volume <= above_volume);
    for (const std::vector<char>* side :
         {cut_upper ? &below : &above, cut_upper ? &above : &below}) {
      for (const std::vector<std::int32_t>& piece : marked_components(s.tets, *side))
        if (give_away(s, piece, false)) {
          for (std::int32_t t : piece) banned[t] = 1;
          moved = true;
        }
      if (moved) break;
    }
    if (!moved) return round;
  }
  return max_rounds;
}

// How far a labeling is from double height fields: the tets that lie between two tets of a part
// of another label along that part's direction, and the largest volume of such tets within one
// part, as a share of that part's volume. (The share of a part's lines that leave it and come
// back, estimated from the lines through its tets, chose worse labelings on the test models.)
struct Sandwiches {
  std::int32_t tets = 0;
  double worst_share = 0.0;
  std::int32_t parts = 0;
};
Sandwiches count_sandwiched(const Parts& s, const std::vector<std::int32_t>& label,
                            std::vector<std::int32_t>* within_part = nullptr) {
  const TetMesh& tets = s.tets;
  const std::vector<std::int32_t>& region = s.region;
  const std::vector<Vec3>& directions = s.directions;
  const std::vector<double>& volume = s.volume;
  const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
  Sandwiches out;
  const std::vector<std::int32_t> part = detail::label_components(tets, label, region, out.parts);
  std::vector<std::pair<std::int32_t, std::int32_t>> used;
  for (std::int32_t t = 0; t < n; ++t) used.emplace_back(region[t], label[t]);
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  std::vector<std::int32_t> sandwiching(n, -1);  // a part tet t lies within
  tbb::parallel_for(std::int32_t{0}, n, [&](std::int32_t t) {
    std::vector<std::int32_t> ahead;
    for (const auto& used_label : used) {
      // Named copies, not a structured binding: the walks below capture them (clang 14).
      const std::int32_t r = used_label.first, l = used_label.second;
      if (sandwiching[t] >= 0) return;
      if (r != region[t] || l == label[t]) continue;
      const Vec3& d = directions[l];
      ahead.clear();
      s.walk_from(t, d, [&](std::int32_t u) {
        if (region[u] == r && label[u] == l &&
            std::find(ahead.begin(), ahead.end(), part[u]) == ahead.end())
          ahead.push_back(part[u]);
        return true;
      });
      if (ahead.empty()) continue;
      s.walk_from(t, -d, [&](std::int32_t u) {
        if (region[u] == r && label[u] == l &&
            std::find(ahead.begin(), ahead.end(), part[u]) != ahead.end())
          sandwiching[t] = part[u];
        return sandwiching[t] < 0;
      });
    }
  });
  std::vector<double> part_volume(out.parts, 0.0), within(out.parts, 0.0);
  for (std::int32_t t = 0; t < n; ++t) {
    part_volume[part[t]] += volume[t];
    if (sandwiching[t] >= 0) within[sandwiching[t]] += volume[t], ++out.tets;
  }
  for (std::int32_t p = 0; p < out.parts; ++p)
    out.worst_share = std::max(out.worst_share, within[p] / part_volume[p]);
  if (within_part) *within_part = std::move(sandwiching);
  return out;
}

// Settles the parts in `order` (settle()), then hands out the pieces parts fell into: all but
// a part's largest go to a neighbour that takes them without new sandwiches, or, when tiny, to
// one in any case; so do whole parts that are mere fragments (a few tets at the surface).
// Returns the labeling; counts the pieces in `repair`.
std::vector<std::int32_t> settle_all(Parts s, const std::vector<std::int32_t>& order,
                                     const SandwichOptions& opts, SandwichRepair& repair) {
  const std::int32_t n = static_cast<std::int32_t>(s.owner.size());
  repair.rounds = 0;
  for (std::int32_t p : order) {
    repair.rounds = std::max(repair.rounds, settle(s, p, opts.max_rounds));
    s.frozen[p] = 1;
  }
  const std::vector<std::int32_t> settled_owner = s.owner;
  const std::int32_t num_parts = s.size();
  double total_volume = 0.0;
  for (double v : s.volume) total_volume += v;
  std::vector<std::int32_t> label(n);
  for (;;) {
    for (std::int32_t t = 0; t < n; ++t) label[t] = s.label_of[s.owner[t]];
    const std::int32_t now_parts = s.take_parts(label, true);
    std::vector<double> piece_volume(now_parts, 0.0);
    std::vector<std::vector<std::int32_t>> members(now_parts);
    for (std::int32_t t = 0; t < n; ++t) {
      const std::int32_t c = s.owner[t];
      piece_volume[c] += s.volume[t];
      members[c].push_back(t);
    }
    std::vector<std::int32_t> largest(num_parts, -1);  // per part before the pieces moved
    for (std::int32_t c = 0; c < now_parts; ++c) {
      std::int32_t& l = largest[settled_owner[members[c].front()]];
      if (l < 0 || piece_volume[c] > piece_volume[l]) l = c;
    }
    std::vector<std::int32_t> pieces;
    for (std::int32_t c = 0; c < now_parts; ++c)
      if (largest[settled_owner[members[c].front()]] != c ||
          piece_volume[c] < kFragmentShare * total_volume)
        pieces.push_back(c);
    std::stable_sort(pieces.begin(), pieces.end(), [&](std::int32_t a, std::int32_t b) {
      return piece_volume[a] < piece_volume[b];
    });
    bool moved = false;
    for (std::int32_t c : pieces)
      if (give_away(s, members[c], piece_volume[c] < opts.tiny_piece_share * total_volume)) {
        ++repair.merged_pieces;
        repair.merged_tets += static_cast<std::int32_t>(members[c].size());
        moved = true;
        break;
      }
    if (!moved) return label;
  }
}

// Whether part q's tets are face-connected (an empty part counts as connected).
bool connected(const Parts& s, std::int32_t q) {
  const std::int32_t n = static_cast<std::int32_t>(s.owner.size());
  std::int32_t total = 0, seed = -1;
  for (std::int32_t t = 0; t < n; ++t)
    if (s.owner[t] == q) ++total, seed = seed < 0 ? t : seed;
  if (seed < 0) return true;
  std::vector<char> seen(n, 0);
  std::vector<std::int32_t> stack{seed};
  seen[seed] = 1;
  std::int32_t reached = 1;
  while (!stack.empty()) {
    const std::int32_t t = stack.back();
    stack.pop_back();
    for (std::int32_t u : s.tets.neighbors[t])
      if (u >= 0 && !seen[u] && s.owner[u] == q) seen[u] = 1, ++reached, stack.push_back(u);
  }
  return reached == total;
}

// Gives the tets still lying between two tets of a part P, along P's direction, to P where P's
// direction allows them, together with the shorter tail of their own part's column along that
// part's direction, where P allows it (so that part loses a column end, not a slice of its
// middle, which would sandwich the moved tets in it instead). A face-connected group moves only
// when it leaves fewer tets sandwiched in P and the part it leaves, near the moved tets, and
// both stay connected (no new parts). Rounds repeat until no group moves, at most max_rounds.
void polish(Parts& s, std::vector<std::int32_t>& label, std::int32_t max_rounds) {
  const std::int32_t n = static_cast<std::int32_t>(label.size());
  for (std::int32_t round = 0; round < max_rounds; ++round) {
    std::vector<std::int32_t> within;
    count_sandwiched(s, label, &within);
    s.take_parts(label, true);
    // Groups: face-connected tets of one part sandwiched in the same part P that allows them.
    std::vector<std::int32_t> owner(n, -1), in_part(n, -1);
    for (std::int32_t t = 0; t < n; ++t)
      if (within[t] >= 0 && s.may_join(t, within[t])) owner[t] = s.owner[t], in_part[t] = within[t];
    std::int32_t num_groups = 0;
    const std::vector<std::int32_t> group =
        detail::label_components(s.tets, owner, in_part, num_groups);
    std::vector<std::vector<std::int32_t>> members(num_groups);
    for (std::int32_t t = 0; t < n; ++t)
      if (owner[t] >= 0) members[group[t]].push_back(t);
    std::erase_if(members, [](const auto& g) { return g.empty(); });
    bool moved = false;
    for (const std::vector<std::int32_t>& g : members) {
      const std::int32_t q = s.owner[g.front()], p = within[g.front()];
      if (std::any_of(g.begin(), g.end(), [&](std::int32_t t) { return s.owner[t] != q; }))
        continue;
      std::vector<std::int32_t> move = g;
      std::vector<char> in_move(n, 0);
      for (std::int32_t t : g) in_move[t] = 1;
      const Vec3 dq = s.direction(q);
      for (std::int32_t t : g) {
        std::vector<std::int32_t> tail[2];
        for (int side = 0; side < 2; ++side)
          s.walk_from(t, side == 0 ? dq : Vec3(-dq), [&](std::int32_t u) {
            if (s.owner[u] != q) return false;
            tail[side].push_back(u);
            return true;
          });
        const int shorter = tail[0].size() <= tail[1].size() ? 0 : 1;
        for (std::int32_t u : tail[shorter])
          if (!in_move[u] && s.may_join(u, p)) in_move[u] = 1, move.push_back(u);
      }
      const auto [before_q, after_q] = s.count_sandwiched_by(q, move, p);
      const auto [before_p, after_p] = s.count_sandwiched_by(p, move, p);
      for (std::int32_t t : move) s.owner[t] = p;
      if (after_q + after_p < before_q + before_p && connected(s, q) && connected(s, p)) {
        for (std::int32_t t : move) label[t] = s.label_of[p];
        moved = true;
      } else {
        for (std::int32_t t : move) s.owner[t] = q;
      }
    }
    if (!moved) return;
  }
}

// Finds the tet that contains a point, through a uniform grid of the tets' bounding boxes.
class TetLocator {
 public:
  explicit TetLocator(const TetMesh& tets) : tets_(tets) {
    box_ = {Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)};
    for (const Vec3& v : tets.vertices)
      box_.min = box_.min.cwiseMin(v), box_.max = box_.max.cwiseMax(v);
    // About one tet per cell.
    const Vec3 size = (box_.max - box_.min).cwiseMax(1e-9);
    const double cell = std::cbrt(size.prod() / std::max<std::size_t>(tets.tets.size(), 1));
    for (int k = 0; k < 3; ++k) dims_[k] = std::clamp(static_cast<int>(size[k] / cell), 1, 512);
    cells_.resize(static_cast<std::size_t>(dims_[0]) * dims_[1] * dims_[2]);
    for (std::int32_t t = 0; t < static_cast<std::int32_t>(tets.tets.size()); ++t) {
      Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
      for (std::int32_t i : tets.tets[t])
        lo = lo.cwiseMin(tets.vertices[i]), hi = hi.cwiseMax(tets.vertices[i]);
      const std::array<int, 3> a = cell_of(lo), b = cell_of(hi);
      for (int x = a[0]; x <= b[0]; ++x)
        for (int y = a[1]; y <= b[1]; ++y)
          for (int z = a[2]; z <= b[2]; ++z) cells_[index({x, y, z})].push_back(t);
    }
  }

  // The tet containing p (the first in index order when p is on a shared face), or -1.
  std::int32_t locate(const Vec3& p) const {
    for (int k = 0; k < 3; ++k)
      if (!(p[k] >= box_.min[k] && p[k] <= box_.max[k])) return -1;
    for (std::int32_t t : cells_[index(cell_of(p))]) {
      const Tet& k = tets_.tets[t];
      const Vec3& a = tets_.vertices[k[0]];
      Eigen::Matrix3d m;
      m << tets_.vertices[k[1]] - a, tets_.vertices[k[2]] - a, tets_.vertices[k[3]] - a;
      const Vec3 w = m.inverse() * (p - a);  // closed form for 3x3; tets are not flat
      constexpr double kSlack = 1e-9;
      if (w.minCoeff() >= -kSlack && w.sum() <= 1.0 + kSlack) return t;
    }
    return -1;
  }

 private:
  std::array<int, 3> cell_of(const Vec3& p) const {
    std::array<int, 3> c;
    for (int k = 0; k < 3; ++k)
      c[k] = std::clamp(
          static_cast<int>((p[k] - box_.min[k]) / (box_.max[k] - box_.min[k]) * dims_[k]), 0,
          dims_[k] - 1);
    return c;
  }
  std::size_t index(const std::array<int, 3>& c) const {
    return (static_cast<std::size_t>(c[2]) * dims_[1] + c[1]) * dims_[0] + c[0];
  }

  const TetMesh& tets_;
  Box3 box_;
  std::array<int, 3> dims_{1, 1, 1};
  std::vector<std::vector<std::int32_t>> cells_;
};

Parts make_state(const TetMesh& tets, const FaceNormals& normals,
                 const std::vector<std::int32_t>& region, const std::vector<Vec3>& directions,
                 const TetAllowsLabel& allows) {
  const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
  Parts s{tets, normals, region, directions, allows, {}, {}, {}, {}, {}, {}, 0.0, nullptr, {}};
  s.centre = tet_centres(tets);
  s.volume.resize(n);
  for (std::int32_t t = 0; t < n; ++t) {
    s.volume[t] = tet_volume(tets, t);
    for (std::int32_t i : tets.tets[t])
      s.tet_radius = std::max(s.tet_radius, (tets.vertices[i] - s.centre[t]).norm());
  }
  return s;
}

// Settles the parts of `label` largest first and smallest first (settle_all()), keeps the
// labeling whose worst part has the smallest share of sandwiched volume (then the fewest parts;
// `label` as given, counted in `best`, competes too), and polishes it (polish()).
void settle_and_polish(Parts& s, std::vector<std::int32_t>& label, const SandwichOptions& opts,
                       Sandwiches& best, SandwichRepair& repair) {
  const std::int32_t n = static_cast<std::int32_t>(label.size());
  const std::int32_t num_parts = s.take_parts(label, false);
  std::vector<double> part_volume(num_parts, 0.0);
  for (std::int32_t t = 0; t < n; ++t) {
    const std::int32_t p = s.owner[t];
    part_volume[p] += s.volume[t];
  }
  // The parts that settle first keep their shape and later ones give way, so which order
  // wins depends on the shape: largest first, and smallest first, are both tried, and the
  // labeling whose worst part has the smallest share of sandwiched volume is kept (then the
  // one with fewer parts; the labeling given competes too). Components are numbered by their
  // smallest tet, so ties in volume go to the part that comes first.
  std::vector<std::int32_t> order(num_parts);
  for (std::int32_t p = 0; p < num_parts; ++p) order[p] = p;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::int32_t a, std::int32_t b) { return part_volume[a] > part_volume[b]; });
  for (int pass = 0; pass < 2; ++pass) {
    SandwichRepair tried;
    const std::vector<std::int32_t> result = settle_all(s, order, opts, tried);
    const Sandwiches left = count_sandwiched(s, result);
    if (std::make_pair(left.worst_share, left.parts) <
        std::make_pair(best.worst_share, best.parts)) {
      best = left;
      repair.order = pass == 0 ? "largest first" : "smallest first";
      label = result;
      repair.rounds = tried.rounds;
      repair.merged_pieces = tried.merged_pieces;
      repair.merged_tets = tried.merged_tets;
    }
    std::reverse(order.begin(), order.end());
  }
  // Only the labeling kept is polished, and the polish is kept only where its worst part does
  // not get a larger share of sandwiched volume: polishing every labeling before choosing
  // chose, on armadillo, one the checker found worse.
  std::vector<std::int32_t> polished = label;
  polish(s, polished, opts.max_rounds);
  const Sandwiches left = count_sandwiched(s, polished);
  if (polished != label && left.worst_share <= best.worst_share && left.parts <= best.parts) {
    best = left;
    label = std::move(polished);
  }
}

void check_labeling(const TetMesh& tets, const std::vector<std::int32_t>& label,
                    const std::vector<std::int32_t>& region, const std::vector<Vec3>& directions) {
  if (tets.neighbors.size() != tets.tets.size() || label.size() != tets.tets.size() ||
      region.size() != tets.tets.size())
    throw Error(ErrorCode::Internal, "sandwich repair: one label, region and adjacency per tet");
  for (std::size_t t = 0; t < tets.tets.size(); ++t)
    if (region[t] < 0 || label[t] < 0 || static_cast<std::size_t>(label[t]) >= directions.size())
      throw Error(ErrorCode::Internal,
                  "sandwich repair: tet " + std::to_string(t) + " has no direction");
}

}  // namespace

void SandwichOptions::validate() const {
  require_option(max_rounds >= 0, "sandwich max_rounds must be >= 0");
  require_option(tiny_piece_share >= 0 && tiny_piece_share <= 1,
                 "sandwich tiny_piece_share must be in [0, 1]");
}

SandwichRepair absorb_sandwiched_tets(const TetMesh& tets, std::vector<std::int32_t>& label,
                                      const std::vector<std::int32_t>& region,
                                      const std::vector<Vec3>& directions,
                                      const TetAllowsLabel& allows, const SandwichOptions& opts,
                                      TetLines* lines) {
  opts.validate();
  const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
  check_labeling(tets, label, region, directions);
  std::shared_ptr<TetLines> own_lines;
  if (!lines || &lines->tets() != &tets) lines = (own_lines = make_tet_lines(tets)).get();
  Parts s = make_state(tets, lines->normals(), region, directions, allows);
  s.line_source = lines;
  s.prepare_lines(label);
  const std::vector<std::int32_t> initial = label;
  SandwichRepair repair;
  Sandwiches best = count_sandwiched(s, label);
  if (opts.max_rounds > 0) settle_and_polish(s, label, opts, best, repair);
  repair.stuck_tets = best.tets;
  repair.worst_share = best.worst_share;
  repair.parts = best.parts;
  repair.converged = best.tets == 0;
  std::int32_t num_parts = 0;
  const std::vector<std::int32_t> part = detail::label_components(tets, label, region, num_parts);
  std::vector<double> part_volume(num_parts, 0.0);
  for (std::int32_t t = 0; t < n; ++t) part_volume[part[t]] += s.volume[t];
  if (num_parts > 0)
    repair.smallest_part_mm3 = *std::min_element(part_volume.begin(), part_volume.end());
  std::map<std::tuple<std::int32_t, std::int32_t, std::int32_t>, SandwichMove> moves;
  for (std::int32_t t = 0; t < n; ++t) {
    if (initial[t] == label[t]) continue;
    SandwichMove& m = moves[{region[t], initial[t], label[t]}];
    m.region = region[t];
    m.from_label = initial[t];
    m.to_label = label[t];
    ++m.tets;
    m.volume_mm3 += s.volume[t];
    ++repair.moved_tets;
    repair.moved_volume_mm3 += s.volume[t];
    repair.forced_tets += !allows(t, region[t], label[t]);
  }
  for (const auto& [key, m] : moves) repair.moves.push_back(m);
  return repair;
}

namespace {

// clear_way() and fill_gaps(): the tets of other parts at `points` that part p may take, and with
// `ahead`, those of their parts in p's way along *ahead.
std::vector<std::int32_t> take_over(const TetMesh& tets, std::vector<std::int32_t>& label,
                                    const std::vector<std::int32_t>& region,
                                    const std::vector<Vec3>& directions,
                                    const TetAllowsLabel& allows, std::int32_t part_tet,
                                    const Vec3* ahead_dir, const std::vector<Vec3>& points,
                                    bool keep_sandwich_share) {
  const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
  check_labeling(tets, label, region, directions);
  if (part_tet < 0 || part_tet >= n) throw Error(ErrorCode::Internal, "take_over: no such tet");
  const FaceNormals normals = face_normals(tets);
  Parts s = make_state(tets, normals, region, directions, allows);
  const std::int32_t num_parts = s.take_parts(label, true);
  const std::int32_t p = s.owner[part_tet];

  std::vector<char> seed(n, 0), blocker(num_parts, 0);
  const TetLocator locator(tets);
  for (const Vec3& x : points) {
    const std::int32_t t = locator.locate(x);
    if (t >= 0 && s.owner[t] != p && s.may_join(t, p)) seed[t] = 1, blocker[s.owner[t]] = 1;
  }
  // Tets of the blockers that p's way along dir runs into through tets of their own part that p
  // may take, and that p may take.
  std::vector<char> ahead(n, 0);
  tbb::parallel_for(std::int32_t{0}, n, [&](std::int32_t t) {
    const std::int32_t q = s.owner[t];
    if (!blocker[q] || !s.may_join(t, p)) return;
    ahead[t] =
        seed[t] ||
        (ahead_dir && s.reaches(
                          t, -*ahead_dir, [&](std::int32_t u) { return s.owner[u] == p; },
                          [&](std::int32_t u) { return s.owner[u] == q && s.may_join(u, p); }));
  });
  std::vector<std::vector<std::int32_t>> pieces;
  for (std::vector<std::int32_t>& piece : marked_components(tets, ahead))
    // Whole face-connected pieces where the way is found blocked.
    if (std::any_of(piece.begin(), piece.end(), [&](std::int32_t t) { return seed[t] != 0; }))
      pieces.push_back(std::move(piece));
  if (pieces.empty()) return {};

  // Moves tets to p. Clearing a way, the pieces the blockers then fall into, other than the
  // largest of each, go to p when it may take them all (slivers left between the tets moved and
  // the surface), else to a neighbour that can (give_away()); filling a gap, they stay (a part
  // that falls apart was no thin skin over the gap). Undone, and false, when that leaves more
  // parts.
  auto take = [&](const std::vector<std::int32_t>& move) {
    const std::vector<std::int32_t> owner_before = s.owner;
    for (std::int32_t t : move) s.owner[t] = p;
    std::vector<std::int32_t> moved_label(n);
    for (std::int32_t t = 0; t < n; ++t) moved_label[t] = s.label_of[s.owner[t]];
    if (ahead_dir) {
      std::int32_t num_pieces = 0;
      const std::vector<std::int32_t> piece_of =
          detail::label_components(tets, moved_label, region, num_pieces);
      std::vector<double> piece_volume(num_pieces, 0.0);
      std::vector<std::vector<std::int32_t>> members(num_pieces);
      for (std::int32_t t = 0; t < n; ++t)
        if (blocker[s.owner[t]] && s.owner[t] != p)
          piece_volume[piece_of[t]] += s.volume[t], members[piece_of[t]].push_back(t);
      std::vector<std::int32_t> largest(num_parts, -1);
      for (std::int32_t c = 0; c < num_pieces; ++c) {
        if (members[c].empty()) continue;
        std::int32_t& l = largest[s.owner[members[c].front()]];
        if (l < 0 || piece_volume[c] > piece_volume[l]) l = c;
      }
      for (std::int32_t c = 0; c < num_pieces; ++c) {
        if (members[c].empty() || largest[s.owner[members[c].front()]] == c) continue;
        if (std::all_of(members[c].begin(), members[c].end(),
                        [&](std::int32_t t) { return s.may_join(t, p); })) {
          for (std::int32_t t : members[c]) s.owner[t] = p;
        } else {
          give_away(s, members[c], false);
        }
      }
      for (std::int32_t t = 0; t < n; ++t) moved_label[t] = s.label_of[s.owner[t]];
    }
    std::int32_t parts_after = 0;
    detail::label_components(tets, moved_label, region, parts_after);
    if (parts_after <= num_parts) return true;
    s.owner = owner_before;
    return false;
  };

  bool taken = false;
  if (ahead_dir) {
    // The whole way at once: clearing part of it frees nothing.
    std::vector<std::int32_t> move;
    for (const std::vector<std::int32_t>& piece : pieces)
      move.insert(move.end(), piece.begin(), piece.end());
    taken = take(move);
  } else {
    // Gaps one piece at a time, each reaching p through at most two rings of its part's tets
    // that p may take when it does not touch p (smoothing moved the interface off the tets).
    for (std::vector<std::int32_t>& piece : pieces) {
      const std::int32_t q = s.owner[piece.front()];
      std::vector<char> in_piece(n, 0);
      for (std::int32_t t : piece) in_piece[t] = 1;
      auto touches_p = [&] {
        for (std::int32_t t : piece)
          for (std::int32_t u : tets.neighbors[t])
            if (u >= 0 && s.owner[u] == p) return true;
        return false;
      };
      for (int ring = 0; ring < 2 && !touches_p(); ++ring) {
        std::vector<std::int32_t> grown;
        for (std::int32_t t : piece)
          for (std::int32_t u : tets.neighbors[t])
            if (u >= 0 && !in_piece[u] && s.owner[u] == q && s.may_join(u, p))
              in_piece[u] = 1, grown.push_back(u);
        piece.insert(piece.end(), grown.begin(), grown.end());
      }
      if (touches_p()) taken |= take(piece);
    }
  }
  if (!taken) return {};
  std::vector<std::int32_t> moved_label(n), move;
  for (std::int32_t t = 0; t < n; ++t) {
    moved_label[t] = s.label_of[s.owner[t]];
    if (moved_label[t] != label[t]) move.push_back(t);
  }
  // The share before is counted only when the one after exceeds kCleanSandwichShare: counting
  // takes a walk per tet and direction used.
  if (keep_sandwich_share) {
    const double share_after = count_sandwiched(s, moved_label).worst_share;
    if (share_after > kCleanSandwichShare && share_after > count_sandwiched(s, label).worst_share)
      return {};
  }
  label = std::move(moved_label);
  return move;
}

}  // namespace

std::vector<std::int32_t> clear_way(const TetMesh& tets, std::vector<std::int32_t>& label,
                                    const std::vector<std::int32_t>& region,
                                    const std::vector<Vec3>& directions,
                                    const TetAllowsLabel& allows, std::int32_t part_tet,
                                    const Vec3& dir, const std::vector<Vec3>& obstacle_points) {
  return take_over(tets, label, region, directions, allows, part_tet, &dir, obstacle_points, true);
}

std::vector<std::int32_t> fill_gaps(const TetMesh& tets, std::vector<std::int32_t>& label,
                                    const std::vector<std::int32_t>& region,
                                    const std::vector<Vec3>& directions,
                                    const TetAllowsLabel& allows, std::int32_t part_tet,
                                    const std::vector<Vec3>& gap_points) {
  return take_over(tets, label, region, directions, allows, part_tet, nullptr, gap_points, false);
}

}  // namespace dhfcast
