#include "dhfcast/refine.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>

#include "dhfcast/directions.h"
#include "dhfcast/error.h"

namespace dhfcast {

namespace {

// The tets listed in `subset` as a mesh of their own (vertices renumbered, adjacency rebuilt).
TetMesh sub_mesh(const TetMesh& tets, const std::vector<std::int32_t>& subset) {
  TetMesh sub;
  std::map<std::int32_t, std::int32_t> vertex_index;
  for (std::int32_t t : subset) {
    Tet k;
    for (int i = 0; i < 4; ++i) {
      auto [it, added] = vertex_index.emplace(tets.tets[t][i], 0);
      if (added) {
        it->second = static_cast<std::int32_t>(sub.vertices.size());
        sub.vertices.push_back(tets.vertices[tets.tets[t][i]]);
      }
      k[i] = it->second;
    }
    sub.tets.push_back(k);
  }
  build_tet_adjacency(sub);
  return sub;
}

// Connected components (through shared faces) of the tets with label -1.
std::vector<std::vector<std::int32_t>> inaccessible_components(
    const TetMesh& tets, const std::vector<std::int32_t>& label) {
  std::vector<std::vector<std::int32_t>> components;
  std::vector<char> seen(tets.tets.size(), 0);
  for (std::int32_t s = 0; s < static_cast<std::int32_t>(tets.tets.size()); ++s) {
    if (label[s] >= 0 || seen[s]) continue;
    std::vector<std::int32_t> component{s}, stack{s};
    seen[s] = 1;
    while (!stack.empty()) {
      const std::int32_t t = stack.back();
      stack.pop_back();
      for (std::int32_t n : tets.neighbors[t])
        if (n >= 0 && label[n] < 0 && !seen[n]) {
          seen[n] = 1;
          component.push_back(n);
          stack.push_back(n);
        }
    }
    std::sort(component.begin(), component.end());
    components.push_back(std::move(component));
  }
  return components;
}

// Gives every tet still labeled -1 the (region, label) of a labeled face neighbour, growing
// from the labeled tets inward, so no tet is left without a part.
void merge_into_neighbours(const TetMesh& tets, std::vector<std::int32_t>& label,
                           std::vector<std::int32_t>& region) {
  bool changed = true;
  while (changed) {
    changed = false;
    const std::vector<std::int32_t> before = label;
    for (std::size_t t = 0; t < tets.tets.size(); ++t) {
      if (before[t] >= 0) continue;
      for (std::int32_t n : tets.neighbors[t])
        if (n >= 0 && before[n] >= 0) {
          label[t] = before[n];
          region[t] = region[n];
          changed = true;
          break;
        }
    }
  }
}

// A candidate labeling of the segmentation after the sandwich repair.
struct RepairedCandidate {
  std::size_t index = 0;  // in Labeling::candidates (the segmentation's ranking)
  std::vector<std::int32_t> label, region;
  SandwichRepair repair;
};

// The candidates in the order they are kept: those whose worst part has at most twice the
// smallest share of sandwiched volume found (or kCleanSandwichShare, if larger) compete, and come
// first; among them those without a tiny part (kTinyPartShare of `volume_mm3`) first, then the
// fewest parts, then the smaller share, then the segmentation's own order (smaller variance of
// part volumes, then lower energy, then index). Returns indices into `repaired` and, in
// `competing`, how many compete.
std::vector<std::size_t> rank_candidates(const std::vector<RepairedCandidate>& repaired,
                                         const std::vector<LabelingCandidate>& candidates,
                                         double volume_mm3, std::size_t& competing) {
  double least = INFINITY;
  for (const RepairedCandidate& r : repaired) least = std::min(least, r.repair.worst_share);
  const double cap = std::max(kCleanSandwichShare, 2 * least);
  const auto key = [&](std::size_t i) {
    const RepairedCandidate& r = repaired[i];
    const LabelingCandidate& c = candidates[r.index];
    return std::make_tuple(r.repair.worst_share > cap,
                           r.repair.smallest_part_mm3 < kTinyPartShare * volume_mm3, r.repair.parts,
                           r.repair.worst_share, c.volume_variance_mm6, c.energy, c.restart);
  };
  std::vector<std::size_t> order(repaired.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  competing =
      static_cast<std::size_t>(std::count_if(repaired.begin(), repaired.end(), [&](const auto& r) {
        return r.repair.worst_share <= cap;
      }));
  return order;
}

// Whether a part is under kTinyPartShare of `volume_mm3`.
bool has_tiny_part(const std::vector<Part>& parts, double volume_mm3) {
  return std::any_of(parts.begin(), parts.end(),
                     [&](const Part& p) { return p.volume_mm3 < kTinyPartShare * volume_mm3; });
}

// What the parts stage makes of one labeling.
struct PartsStage {
  std::vector<std::int32_t> label;  // after make_parts_manifold()
  ManifoldRepair manifold;
  std::vector<Part> parts;
  std::vector<InterfaceSmoothness> raw_smoothness, smoothness;
  InterfaceSmoothness outer_smoothness;
  SolidCut solid_cut;
  AssemblyPlan assembly;
  double assembly_tolerance_mm = 0.0;
};

// The directions a part may leave along when the object is taken apart, besides its own +-d
// (plan_assembly()'s extra directions): the other parts' +-d, then a coarse set over the sphere.
std::vector<Vec3> removal_directions(const std::vector<Part>& parts,
                                     const std::vector<Vec3>& sphere_directions) {
  std::vector<Vec3> out;
  for (const Part& p : parts) out.insert(out.end(), {p.direction, -p.direction});
  out.insert(out.end(), sphere_directions.begin(), sphere_directions.end());
  return out;
}

// Orders stage.parts for assembly. A part leaves along its own +-d when it can, else along another
// part's (interfaces follow them) or one of a coarse set of directions over the sphere. A move
// counts as blocked when it goes deeper than epsilon / 2 into another part: half what `dhfcast
// check` allows, as check draws other points of the surface. When no order exists with that
// margin, the margin shrinks: an order closer to check's limit is still one that check can confirm.
void plan_stage_assembly(PartsStage& stage, const RefineOptions& opts, double epsilon_mm,
                         const std::vector<Vec3>& sphere_directions) {
  const std::vector<Vec3> removal = removal_directions(stage.parts, sphere_directions);
  for (double share : opts.assembly_margins) {
    stage.assembly_tolerance_mm = share * epsilon_mm;
    stage.assembly = plan_assembly(stage.parts, removal, stage.assembly_tolerance_mm);
    if (stage.assembly.found) break;
  }
}

// Parts of a labeling bounded by the tets: made manifold, extracted, their interfaces smoothed,
// and ordered for assembly.
PartsStage make_parts(const TetMesh& tets, std::vector<std::int32_t> label,
                      const std::vector<std::int32_t>& region, const std::vector<Vec3>& directions,
                      const AccessibilityField& access, const TetAllowsLabel& label_allows,
                      const RefineOptions& opts, double epsilon_mm,
                      const std::vector<Vec3>& sphere_directions) {
  PartsStage out;
  // A part whose tets meet only along an edge or at a vertex would touch itself there.
  out.manifold = make_parts_manifold(tets, label, region, label_allows);
  out.label = std::move(label);
  out.parts = extract_parts(tets, out.label, region, directions);
  // Parts of a region decomposed again carry that region's own accessibility, which is not kept:
  // their interfaces stay as they are.
  const TetAllowsPart allows = [&](std::int32_t t, std::int32_t p) {
    const Part& part = out.parts[p];
    return part.region == 0 && access.feasible.get(t, part.direction_index);
  };
  out.raw_smoothness = interface_smoothness(out.parts);
  smooth_interfaces(tets, out.parts, allows, opts.smoothing);
  out.smoothness = interface_smoothness(out.parts);
  out.outer_smoothness = outer_surface_smoothness(out.parts);
  plan_stage_assembly(out, opts, epsilon_mm, sphere_directions);
  return out;
}

// A way out of a part along a direction, and where it is blocked by parts left blocked.
struct Way {
  std::size_t stretches = 0;  // obstructions() among blocked parts
  std::int32_t part = 0;
  Vec3 dir;
  std::vector<Vec3> points;  // inside the blocking parts, about a tet apart along each stretch
};

// Part p's ways out along each of `dirs`.
std::vector<Way> blocked_ways(const PartsStage& stage, std::int32_t p,
                              const std::vector<Vec3>& dirs, const std::vector<bool>& blocked,
                              double tet_size) {
  const std::vector<std::vector<Obstruction>> found =
      obstructions(stage.parts, p, dirs, stage.assembly_tolerance_mm);
  std::vector<Way> ways;
  for (std::size_t k = 0; k < dirs.size(); ++k) {
    Way& way = ways.emplace_back(Way{0, p, dirs[k], {}});
    for (const Obstruction& o : found[k]) {
      if (!blocked[o.part]) continue;
      ++way.stretches;
      const int steps = std::clamp(static_cast<int>((o.to - o.from).norm() / tet_size), 1, 64);
      for (int i = 0; i < steps; ++i)
        way.points.push_back(o.from + (i + 0.5) / steps * (o.to - o.from));
    }
  }
  return ways;
}

// Which parts a plan leaves blocked.
std::vector<bool> blocked_parts(const AssemblyPlan& plan) {
  std::vector<bool> blocked(plan.order.size(), false);
  for (std::size_t k = plan.order.size() - plan.blocked; k < plan.order.size(); ++k)
    blocked[plan.order[k]] = true;
  return blocked;
}

// What the parts stage works from.
struct PartsContext {
  const TetMesh& tets;
  const std::vector<Vec3>& directions;
  const AccessibilityField& access;
  const RefineOptions& opts;
  double epsilon_mm;
  double tet_size;  // cube root of the mean tet volume
  // Regions decomposed again keep no accessibility here: their tets may take any label of the
  // region, and their parts keep their interfaces as they are.
  TetAllowsLabel label_allows = [&feasible = access.feasible](std::int32_t t, std::int32_t r,
                                                              std::int32_t l) {
    return r != 0 || feasible.get(t, l);
  };
  std::vector<Vec3> sphere = fibonacci_directions(opts.assembly_directions);

  // Parts whose outer surface is the tets' boundary: what candidates, cleared ways and filled
  // gaps are compared on. Only the parts kept are cut from the solid.
  PartsStage make(const std::vector<std::int32_t>& label,
                  const std::vector<std::int32_t>& region) const {
    return make_parts(tets, label, region, directions, access, label_allows, opts, epsilon_mm,
                      sphere);
  }
};

// A candidate made into parts, and the ways cleared on the way.
struct AssembledParts {
  PartsStage parts;
  std::vector<WayClearing> clearings;
  std::vector<GapFilling> fillings;
};

// When the parts have no assembly order, a blocked part takes the tets of other parts in its way
// along +d or -d (clear_way()), the side with fewer blocked stretches first, and the parts are
// made again; kept when fewer parts are left blocked, or the same ones with fewer stretches of
// that way blocked. With `sphere` (for a stage whose +-d ways were cleared already), when no such
// way is kept, the blocked parts' best ways over the sphere are tried likewise. Returns whether
// any way was cleared.
bool clear_ways(const PartsContext& c, const std::vector<std::int32_t>& region, bool sphere,
                AssembledParts& out) {
  PartsStage& stage = out.parts;
  // Whether one of `ways` was cleared, the one with the fewest blocked stretches first.
  auto clear_one = [&](std::vector<Way> ways) {
    std::stable_sort(ways.begin(), ways.end(),
                     [](const Way& a, const Way& b) { return a.stretches < b.stretches; });
    for (const Way& way : ways) {
      std::vector<std::int32_t> cleared_label = stage.label;
      const std::vector<std::int32_t> moved =
          clear_way(c.tets, cleared_label, region, c.directions, c.label_allows,
                    stage.parts[way.part].tets.front(), way.dir, way.points);
      if (moved.empty()) continue;
      PartsStage tried = c.make(cleared_label, region);
      if (tried.assembly.blocked > stage.assembly.blocked) continue;
      if (tried.assembly.blocked == stage.assembly.blocked) {
        const std::int32_t tet = stage.parts[way.part].tets.front();
        const auto same = std::find_if(tried.parts.begin(), tried.parts.end(), [&](const Part& q) {
          return std::binary_search(q.tets.begin(), q.tets.end(), tet);
        });
        if (same == tried.parts.end() ||
            blocked_ways(tried, same->id, {way.dir}, blocked_parts(tried.assembly), c.tet_size)
                    .front()
                    .stretches >= way.stretches)
          continue;
      }
      WayClearing w;
      w.direction = way.dir;
      w.direction_index = stage.parts[way.part].direction_index;
      w.tets = static_cast<std::int32_t>(moved.size());
      for (std::int32_t t : moved) w.volume_mm3 += tet_volume(c.tets, t);
      w.blocked_before = stage.assembly.blocked;
      w.blocked_after = tried.assembly.blocked;
      out.clearings.push_back(w);
      stage = std::move(tried);
      return true;
    }
    return false;
  };
  for (int round = 0; round < c.opts.max_way_clearings && !stage.assembly.found; ++round) {
    const std::vector<bool> blocked = blocked_parts(stage.assembly);
    auto ways_to_clear = [&](bool own) {
      std::vector<Way> ways;
      for (std::int32_t p = 0; p < static_cast<std::int32_t>(stage.parts.size()); ++p) {
        if (!blocked[p] || stage.parts[p].region != 0) continue;
        const Vec3 d = stage.parts[p].direction;
        std::vector<Way> part_ways =
            blocked_ways(stage, p, own ? std::vector<Vec3>{d, -d} : c.sphere, blocked, c.tet_size);
        std::erase_if(part_ways, [](const Way& way) { return way.stretches == 0; });
        // Over the sphere, the part's best few.
        std::stable_sort(part_ways.begin(), part_ways.end(),
                         [](const Way& a, const Way& b) { return a.stretches < b.stretches; });
        const auto most = static_cast<std::size_t>(c.opts.sphere_ways);
        if (!own && part_ways.size() > most) part_ways.resize(most);
        for (Way& way : part_ways) ways.push_back(std::move(way));
      }
      return ways;
    };
    // With `sphere`, the stage given has been through the +-d ways already.
    const bool own_tried = sphere && round == 0;
    if (!(!own_tried && clear_one(ways_to_clear(true))) &&
        !(sphere && clear_one(ways_to_clear(false))))
      break;
  }
  return !out.clearings.empty();
}

std::int32_t count_gaps(const std::vector<std::vector<DhfGap>>& gaps) {
  std::size_t n = 0;
  for (const std::vector<DhfGap>& g : gaps) n += g.size();
  return static_cast<std::int32_t>(n);
}

// Points a quarter tet apart from a to b, ends included: the chain of tets they seed is unbroken.
void add_points_along(const Vec3& a, const Vec3& b, double tet_size, std::vector<Vec3>& points) {
  const int steps = std::clamp(static_cast<int>(4 * (b - a).norm() / tet_size), 1, 256);
  for (int i = 0; i <= steps; ++i) points.push_back(a + double(i) / steps * (b - a));
}

// Where the finished parts are still not double height fields, the tets on the gap lines change
// part and the parts are made again. A gap through other parts (the smoothed interfaces of a part
// wrap around a neighbour's, which the tet-level repair cannot see) is filled by the part, which
// takes its neighbours' tets in it (fill_gaps()). A gap outside the solid (a thin skin of the
// part over a neighbour, with air above it and the part again beyond) is closed by the
// neighbour under the skin, which takes the skin. Each part's gaps of each kind are one move. A
// round tries all moves at once, then the move of the most gap lines alone, and keeps the first
// that leaves fewer gap lines, no more parts and no more of them blocked. `gaps` are the parts'
// dhf_gaps() as given; returns the gap lines left.
std::int32_t fill_gap_rounds(const PartsContext& c, const std::vector<std::int32_t>& region,
                             std::vector<std::vector<DhfGap>> gaps, AssembledParts& assembled) {
  PartsStage& stage = assembled.parts;
  struct Move {
    std::int32_t lines = 0;
    std::int32_t taker = 0;  // the part that takes the tets
    std::vector<Vec3> points;
  };
  for (int round = 0; round < c.opts.max_gap_fills && count_gaps(gaps) > 0; ++round) {
    std::vector<Move> moves;
    for (std::size_t p = 0; p < stage.parts.size(); ++p) {
      std::map<std::int32_t, Move> by_taker;  // the part itself, or the one under a skin of it
      for (const DhfGap& g : gaps[p]) {
        const std::int32_t taker = g.part >= 0 ? static_cast<std::int32_t>(p) : g.below;
        if (taker < 0) continue;  // a skin over nothing: no part can take it
        Move& m = by_taker[taker];
        m.taker = taker;
        ++m.lines;
        if (g.part >= 0)
          add_points_along(g.from, g.to, c.tet_size, m.points);
        else
          add_points_along(g.interval_from, g.from, c.tet_size, m.points);
      }
      for (auto& entry : by_taker) moves.push_back(std::move(entry.second));
    }
    if (moves.empty()) break;
    const auto largest = std::max_element(
        moves.begin(), moves.end(), [](const Move& a, const Move& b) { return a.lines < b.lines; });
    // Tets taken by one move are left alone by the moves after it.
    auto apply = [&](std::vector<std::int32_t>& label, const Move& m) {
      const std::int32_t tet = stage.parts[m.taker].tets.front();
      if (label[tet] != stage.label[tet]) return std::vector<std::int32_t>{};
      return fill_gaps(c.tets, label, region, c.directions, c.label_allows, tet, m.points);
    };
    bool kept = false;
    for (const bool all : {true, false}) {
      if (!all && moves.size() == 1) break;
      std::vector<std::int32_t> label = stage.label, moved;
      for (auto m = all ? moves.begin() : largest; m != (all ? moves.end() : largest + 1); ++m) {
        const std::vector<std::int32_t> t = apply(label, *m);
        moved.insert(moved.end(), t.begin(), t.end());
      }
      if (moved.empty()) continue;
      std::sort(moved.begin(), moved.end());
      moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
      PartsStage tried = c.make(label, region);
      std::vector<std::vector<DhfGap>> tried_gaps =
          dhf_gaps(tried.parts, c.opts.gap_lines, c.epsilon_mm);
      if (count_gaps(tried_gaps) >= count_gaps(gaps) || tried.parts.size() > stage.parts.size() ||
          tried.assembly.blocked > stage.assembly.blocked)
        continue;
      GapFilling f;
      f.tets = static_cast<std::int32_t>(moved.size());
      for (std::int32_t t : moved) f.volume_mm3 += tet_volume(c.tets, t);
      f.gap_lines_before = count_gaps(gaps);
      f.gap_lines_after = count_gaps(tried_gaps);
      assembled.fillings.push_back(f);
      stage = std::move(tried);
      gaps = std::move(tried_gaps);
      kept = true;
      break;
    }
    if (!kept) break;
  }
  return count_gaps(gaps);
}

}  // namespace

void RefineOptions::validate() const {
  require_option(candidates >= 1 && candidates <= 1000, "--candidates must be between 1 and 1000");
  sandwich.validate();
  smoothing.validate();
  require_option(assembly_directions >= 1 && !assembly_margins.empty() &&
                     std::all_of(assembly_margins.begin(), assembly_margins.end(),
                                 [](double m) { return m >= 0.0 && m <= 1.0; }),
                 "refine: assembly directions >= 1 and margins in [0, 1] expected");
  require_option(max_way_clearings >= 0 && sphere_ways >= 0 && max_gap_fills >= 0 &&
                     gap_lines >= 1 && made_candidates >= 1 && gap_candidate_share >= 1.0,
                 "refine: counts must be >= 0 (gap lines and made candidates >= 1, gap candidate "
                 "share >= 1)");
}

Refinement refine(const TriMesh& solid, const TetMesh& tets, const std::vector<Vec3>& directions,
                  const AccessibilityField& access, const Labeling& labeling,
                  const AccessibilityOptions& access_opts, const SegmentOptions& segment_opts,
                  const RefineOptions& opts, const Progress& progress) {
  opts.validate();
  const std::size_t num_tets = tets.tets.size();
  Refinement out;

  // --- 1. tets feasible for no direction ---
  // Tets feasible for no direction (enclosed volumes, paper §6): each connected region of them
  // is decomposed again on its own, with accessibility taken from its own boundary. The parts
  // it gives are DHFs; whether they can be put in place is left to the assembly planner. These
  // tets are the same in every candidate labeling.
  std::vector<std::int32_t> region(num_tets, 0), region_label(num_tets, -1);
  for (const std::vector<std::int32_t>& component : inaccessible_components(tets, labeling.label)) {
    InaccessibleRegion info;
    info.id = static_cast<std::int32_t>(out.inaccessible_regions.size()) + 1;
    info.tets = static_cast<std::int32_t>(component.size());
    for (std::int32_t t : component) info.volume_mm3 += tet_volume(tets, t);

    const TetMesh sub = sub_mesh(tets, component);
    const std::vector<Part> shell =
        extract_parts(sub, std::vector<std::int32_t>(sub.tets.size(), 0),
                      std::vector<std::int32_t>(sub.tets.size(), 0), {{Vec3::UnitZ()}});
    const AccessibilityField sub_field =
        compute_accessibility(shell.at(0).mesh, sub, directions, access_opts);
    const Labeling sub_labeling = segment(sub, sub_field, directions, segment_opts);
    for (std::size_t i = 0; i < component.size(); ++i) {
      region_label[component[i]] = sub_labeling.label[i];
      region[component[i]] = info.id;
      if (sub_labeling.label[i] < 0) ++info.still_inaccessible_tets;
    }
    out.inaccessible_regions.push_back(info);
  }

  // --- 2. the candidates' sandwich repair ---
  // Tets between two pieces of another part along its direction go to that part, so each part
  // meets every line along its direction once (at the tets' resolution). Regions decomposed
  // again keep no accessibility of their own here, so their tets never change label. This
  // repair is run on every candidate labeling, and the one chosen is the one that comes out
  // closest to double height fields (see rank_candidates()): fewer parts are worth little when
  // one of them cannot be cast.
  const TetAllowsLabel region_allows = [&](std::int32_t t, std::int32_t r, std::int32_t l) {
    return r == 0 && access.feasible.get(t, l);
  };
  // The repair takes seconds per candidate: only the candidates the segmentation itself ranks
  // first (fewest parts, most even volumes, lowest energy) are tried. On bunny, dragonstand,
  // elephant and pinion the one kept ranked 2nd to 8th.
  const std::vector<LabelingCandidate>& candidates = labeling.candidates;
  std::vector<std::size_t> distinct;  // the first candidate of each distinct labeling
  for (std::size_t c = 0; c < candidates.size(); ++c)
    if (distinct.size() < static_cast<std::size_t>(opts.candidates) &&
        std::none_of(distinct.begin(), distinct.end(),
                     [&](std::size_t e) { return candidates[e].label == candidates[c].label; }))
      distinct.push_back(c);
  std::vector<RepairedCandidate> repaired(distinct.size());
  std::mutex progress_mutex;
  std::size_t repairs_done = 0;
  const std::shared_ptr<TetLines> lines = make_tet_lines(tets);
  tbb::parallel_for(std::size_t{0}, distinct.size(), [&](std::size_t i) {
    RepairedCandidate& r = repaired[i];
    r.index = distinct[i];
    r.label = candidates[r.index].label;
    r.region = region;
    for (std::size_t t = 0; t < num_tets; ++t)
      if (region[t] > 0) r.label[t] = region_label[t];
    merge_into_neighbours(tets, r.label, r.region);
    if (std::find(r.label.begin(), r.label.end(), -1) != r.label.end())
      throw Error(ErrorCode::Internal, "a tet region has no direction at all");
    r.repair = absorb_sandwiched_tets(tets, r.label, r.region, directions, region_allows,
                                      opts.sandwich, lines.get());
    const std::lock_guard lock(progress_mutex);
    if (progress) progress(0.5 * double(++repairs_done) / double(distinct.size()));
  });

  // --- 3. parts and assembly order ---
  // The candidate ranked first is made into parts (ways cleared, gaps filled). When they have no
  // assembly order, or lines that meet a part twice are left, the next candidates are made in
  // turn: the competing ones while no assembly order is found, and up to opts.made_candidates in
  // all while gap lines are left, of those whose sandwich share is at most
  // opts.gap_candidate_share times the least (elephant's others, at 10 times and more, leave 20
  // to 30 times its gap lines) (one of these that starts with more gap lines than the best has left
  // is dropped before its ways are cleared and its gaps filled). The best is kept: an assembly
  // order first, then the fewest gap lines, then the fewest parts. (Bimba: the first leaves 411 gap
  // lines, the third 13.) Ways over the sphere are cleared only when no candidate has an order:
  // they are tried on the one kept (elephant), as clearing them leaves more gap lines than another
  // candidate's order along +-d does (doubletorus: 80 against 0).
  const double tets_volume = total_volume(tets);
  std::size_t competing = 0;
  const std::vector<std::size_t> ranked =
      rank_candidates(repaired, candidates, tets_volume, competing);
  const PartsContext context{tets,
                             directions,
                             access,
                             opts,
                             access_opts.epsilon_mm,
                             std::cbrt(tets_volume / std::max<double>(1.0, num_tets))};
  struct Made {
    AssembledParts stage;
    std::size_t repaired_index = 0;  // in `repaired`
    std::int32_t gap_lines = 0;
    bool tiny_part = false;  // one of its parts is under kTinyPartShare of the volume
    auto key() const {
      return std::make_tuple(!stage.parts.assembly.found, tiny_part, gap_lines,
                             stage.parts.parts.size());
    }
  };
  double least_share = INFINITY;
  for (const RepairedCandidate& r : repaired)
    least_share = std::min(least_share, r.repair.worst_share);
  const auto made_at_least = static_cast<std::size_t>(opts.made_candidates);
  std::optional<Made> best;
  std::size_t kept = 0;  // in out.made_candidates
  for (std::size_t k = 0; k < ranked.size(); ++k) {
    const RepairedCandidate& r = repaired[ranked[k]];
    const bool found = best && best->stage.parts.assembly.found;
    const bool for_assembly = k < competing && !found;
    // While the best has a tiny part, a candidate without one at the tets is made too.
    const bool for_tiny = best && best->tiny_part &&
                          r.repair.smallest_part_mm3 >= kTinyPartShare * tets_volume &&
                          out.made_candidates.size() < made_at_least;
    if (best) {
      if (found && best->gap_lines == 0 && !best->tiny_part) break;
      const bool for_gaps = out.made_candidates.size() < made_at_least &&
                            r.repair.worst_share <= opts.gap_candidate_share * least_share;
      if (!for_assembly && !for_gaps && !for_tiny) continue;
    }
    Made made{{context.make(r.label, r.region), {}, {}}, ranked[k]};
    auto gaps_of = [&] {
      return dhf_gaps(made.stage.parts.parts, opts.gap_lines, access_opts.epsilon_mm);
    };
    std::vector<std::vector<DhfGap>> gaps = gaps_of();
    made.gap_lines = count_gaps(gaps);
    // Tried for its gaps only, it is dropped when it starts with more than the best has left.
    const bool drop = best && !for_assembly && !for_tiny && made.gap_lines > best->gap_lines;
    if (!drop) {
      if (clear_ways(context, r.region, false, made.stage)) gaps = gaps_of();
      made.gap_lines = fill_gap_rounds(context, r.region, std::move(gaps), made.stage);
      made.tiny_part = has_tiny_part(made.stage.parts.parts, tets_volume);
    }
    MadeCandidate m;
    m.restart = candidates[r.index].restart;
    m.parts = static_cast<std::int32_t>(made.stage.parts.parts.size());
    m.assembly_found = made.stage.parts.assembly.found;
    m.gap_lines = made.gap_lines;
    m.tiny_part = made.tiny_part;
    m.dropped = drop;
    out.made_candidates.push_back(m);
    if (!drop && (!best || made.key() < best->key()))
      best = std::move(made), kept = out.made_candidates.size() - 1;
  }
  // No candidate came apart along its parts' +-d: the one kept tries ways over the sphere, and
  // takes what that gives when it finds an order.
  if (!best->stage.parts.assembly.found) {
    const RepairedCandidate& r = repaired[best->repaired_index];
    AssembledParts tried = best->stage;
    if (clear_ways(context, r.region, true, tried) && tried.parts.assembly.found) {
      std::vector<std::vector<DhfGap>> gaps =
          dhf_gaps(tried.parts.parts, opts.gap_lines, access_opts.epsilon_mm);
      best->gap_lines = fill_gap_rounds(context, r.region, std::move(gaps), tried);
      best->stage = std::move(tried);
      best->tiny_part = has_tiny_part(best->stage.parts.parts, tets_volume);
      MadeCandidate& m = out.made_candidates[kept];
      m.parts = static_cast<std::int32_t>(best->stage.parts.parts.size());
      m.assembly_found = true;
      m.gap_lines = best->gap_lines;
      m.tiny_part = best->tiny_part;
    }
  }
  out.made_candidates[kept].kept = true;
  AssembledParts stage = std::move(best->stage);
  // --- 4. the parts kept, cut from the solid ---
  // Cutting every candidate and every try instead gave the same check verdicts on 23 of 25 CGAL
  // meshes at 150 mm and 10 000 tets (joint failed one check more; 3torus solids and dhf where
  // this fails assembly), and took up to 7 times as long (rotor 1192 s against 166 s; hand at
  // 50 000 tets: parts 514 s against 123 s).
  if (opts.exact_outer_surface) {
    stage.parts.solid_cut = cut_parts_from_solid(solid, stage.parts.parts);
    plan_stage_assembly(stage.parts, opts, access_opts.epsilon_mm, context.sphere);
    best->gap_lines =
        count_gaps(dhf_gaps(stage.parts.parts, opts.gap_lines, access_opts.epsilon_mm));
  }
  // --- 5. carving ---
  // What the label-level repairs leave is mended on the final meshes, keeping an assembly order.
  if (opts.carve && best->gap_lines > 0) {
    KeptAssembly kept_assembly{removal_directions(stage.parts.parts, context.sphere),
                               stage.parts.assembly_tolerance_mm, stage.parts.assembly};
    out.carving = carve_dhf_gaps(stage.parts.parts, opts.gap_lines, access_opts.epsilon_mm, true,
                                 &kept_assembly);
    stage.parts.assembly = std::move(kept_assembly.plan);
  }
  const std::size_t chosen = best->repaired_index;
  out.kept_candidate = static_cast<std::int32_t>(repaired[chosen].index);
  out.sandwich = std::move(repaired[chosen].repair);
  out.manifold = std::move(stage.parts.manifold);
  out.parts = std::move(stage.parts.parts);
  out.raw_smoothness = std::move(stage.parts.raw_smoothness);
  out.smoothness = std::move(stage.parts.smoothness);
  out.outer_smoothness = stage.parts.outer_smoothness;
  out.solid_cut = std::move(stage.parts.solid_cut);
  for (const Part& p : out.parts) {
    std::int32_t inaccessible = 0;
    if (p.region == 0)
      for (std::int32_t t : p.tets)
        inaccessible += !access.feasible.get(t, p.direction_index) &&
                        !std::binary_search(out.solid_cut.dropped_tets.begin(),
                                            out.solid_cut.dropped_tets.end(), t);
    out.inaccessible_tets.push_back(inaccessible);
  }
  out.assembly = std::move(stage.parts.assembly);
  out.assembly_tolerance_mm = stage.parts.assembly_tolerance_mm;
  out.way_clearings = std::move(stage.clearings);
  out.gap_fillings = std::move(stage.fillings);
  return out;
}

}  // namespace dhfcast
