// Mending the gaps the label-level repairs leave in a part along its direction, on the final
// meshes, patch by patch, as long as that helps: filling, yielding, or the paper's conservative
// carving (§4.3.1).
#include "carve.h"

#include <algorithm>
#include <cstdio>
#include <deque>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "dhfcast/parts.h"

namespace dhfcast {

namespace {

// Halving a refused patch this many times at most, and patches tried per part at most (a try
// costs a few booleans and a dhf_gap_count() per part it changes).
constexpr int kMaxSplits = 3;
constexpr int kMaxTries = 200;
// Rings of lines with shallow gaps a patch of deep ones takes around it.
constexpr int kBorderRings = 2;

std::int32_t sum(const std::vector<std::int32_t>& counts) {
  std::int32_t n = 0;
  for (std::int32_t c : counts) n += c;
  return n;
}

using Patch = std::vector<const detail::CarveLine*>;

// How a patch is mended: the part takes the neighbour's material in its gaps (filling them, or,
// where the neighbour reaches the outer surface there, taking what of it lies in the hull),
// gives its stretches on one side of them to the neighbour across, or loses them to a void.
enum class Way { Fill, Take, Yield, Carve };
constexpr const char* kWayNames[] = {"filling", "taking", "yielding", "carving"};
// The ways in the order tried.
constexpr Way kWays[] = {Way::Fill, Way::Take, Way::Yield, Way::Carve};

// Deep lines whose cells touch (also at a corner) form one patch, in the lines' order; it takes
// the lines with shallow gaps up to kBorderRings cells around it too (not yet taken), where the
// part still continues from the stretches the deep lines lose, between the grid's lines.
std::vector<Patch> patches(const detail::CarveLines& lines) {
  std::map<std::pair<std::int64_t, std::int64_t>, std::size_t> at;
  for (std::size_t i = 0; i < lines.lines.size(); ++i)
    at.emplace(std::make_pair(lines.lines[i].iu, lines.lines[i].iv), i);
  std::vector<char> taken(lines.lines.size(), 0);
  // Calls visit(j) for each untaken line j in the 8 cells around line i.
  auto around = [&](std::size_t i, auto&& visit) {
    const detail::CarveLine& line = lines.lines[i];
    for (std::int64_t du = -1; du <= 1; ++du)
      for (std::int64_t dv = -1; dv <= 1; ++dv)
        if (const auto it = at.find({line.iu + du, line.iv + dv});
            it != at.end() && !taken[it->second])
          visit(it->second);
  };
  std::vector<Patch> out;
  for (std::size_t i = 0; i < lines.lines.size(); ++i) {
    if (taken[i] || !lines.lines[i].deep) continue;
    std::vector<std::size_t> members{i};
    taken[i] = 1;
    for (std::size_t k = 0; k < members.size(); ++k)
      around(members[k], [&](std::size_t j) {
        if (!lines.lines[j].deep) return;
        taken[j] = 1;
        members.push_back(j);
      });
    for (int ring = 0; ring < kBorderRings; ++ring) {
      const std::size_t size = members.size();
      for (std::size_t k = 0; k < size; ++k)
        around(members[k], [&](std::size_t j) {
          taken[j] = 1;
          members.push_back(j);
        });
    }
    Patch patch;
    for (std::size_t j : members) patch.push_back(&lines.lines[j]);
    out.push_back(std::move(patch));
  }
  return out;
}

// The two halves of a patch, split across its longer side.
std::pair<Patch, Patch> halves(Patch patch) {
  std::int64_t u_lo = INT64_MAX, u_hi = INT64_MIN, v_lo = INT64_MAX, v_hi = INT64_MIN;
  for (const detail::CarveLine* l : patch) {
    u_lo = std::min(u_lo, l->iu), u_hi = std::max(u_hi, l->iu);
    v_lo = std::min(v_lo, l->iv), v_hi = std::max(v_hi, l->iv);
  }
  const bool along_u = u_hi - u_lo >= v_hi - v_lo;
  auto key = [&](const detail::CarveLine* l) { return along_u ? l->iu : l->iv; };
  std::stable_sort(patch.begin(), patch.end(),
                   [&](const auto* a, const auto* b) { return key(a) < key(b); });
  const std::size_t middle = patch.size() / 2;
  return {Patch(patch.begin(), patch.begin() + middle), Patch(patch.begin() + middle, patch.end())};
}

// Appends the stretch from a to b of a line, at the four corners of the line's cell.
void add_cell_corners(const Vec3& a, const Vec3& b, const detail::CarveLines& lines,
                      std::vector<Vec3>& points) {
  const double half = 0.5 * lines.spacing_mm;
  for (const Vec3& end : {a, b})
    for (double su : {-half, half})
      for (double sv : {-half, half}) points.push_back(end + su * lines.u + sv * lines.v);
}

// The hull's points for a patch: each line's stretch to remove (reaching epsilon past the part's
// stretches at its far end) at the four corners of the line's cell; empty when no one side
// serves all its deep lines. The side that removes less is taken when both do.
std::vector<Vec3> hull_points(const Patch& patch, const detail::CarveLines& lines,
                              double epsilon_mm) {
  bool above = true, below = true;
  double above_length = 0.0, below_length = 0.0;
  for (const detail::CarveLine* l : patch) {
    if (!l->deep) continue;
    above = above && l->above.has_value();
    below = below && l->below.has_value();
    if (l->above) above_length += (l->above->second - l->above->first).norm();
    if (l->below) below_length += (l->below->second - l->below->first).norm();
  }
  if (!above && !below) return {};
  const bool take_above = above && (!below || above_length <= below_length);
  std::vector<Vec3> points;
  for (const detail::CarveLine* l : patch) {
    const auto& stretch = take_above ? l->above : l->below;
    if (!stretch) continue;  // a line with shallow gaps that this side does not serve
    auto [from, to] = *stretch;
    if (take_above)
      to += epsilon_mm * lines.d;
    else
      from -= epsilon_mm * lines.d;
    add_cell_corners(from, to, lines, points);
  }
  return points;
}

// The hull's points for filling a patch, or yielding it: each line's stretch (CarveLine::fill
// or ::yield) at the four corners of its cell; empty when the deep lines do not all have one
// and the same other part there (`other`).
std::vector<Vec3> exchange_points(const Patch& patch, const detail::CarveLines& lines, bool fill,
                                  std::int32_t& other) {
  auto stretch = [fill](const detail::CarveLine* l) { return fill ? l->fill : l->yield; };
  auto part = [fill](const detail::CarveLine* l) { return fill ? l->fill_from : l->yield_to; };
  other = -1;
  for (const detail::CarveLine* l : patch) {
    if (!l->deep) continue;
    if (!stretch(l) || (other >= 0 && part(l) != other)) return {};
    other = part(l);
  }
  std::vector<Vec3> points;
  for (const detail::CarveLine* l : patch)
    if (stretch(l) && part(l) == other)
      add_cell_corners(stretch(l)->first, stretch(l)->second, lines, points);
  return points;
}

// Whether a refusal came from rounding to float (see carve.h).
bool broken_by_rounding(const std::string& why) {
  return why.find("once rounded") != std::string::npos;
}

// Hull points scaled about their centroid: a hull whose cut passes within a float step of the
// part's corners (which rounding then breaks) is tried again a little larger, then smaller.
constexpr int kVariants = 3;
std::vector<Vec3> varied(std::vector<Vec3> points, int variant) {
  if (variant == 0) return points;
  Vec3 centroid(0, 0, 0);
  for (const Vec3& x : points) centroid += x;
  centroid /= static_cast<double>(points.size());
  const double scale = variant == 1 ? 1.03 : 0.97;
  for (Vec3& x : points) x = centroid + scale * (x - centroid);
  return points;
}

std::string describe(std::int32_t p, const Patch& patch, const std::string& why) {
  const Vec3& at = patch.front()->gap;
  char text[160];
  std::snprintf(text, sizeof text, "part %d, %zu gap line%s near (%.1f, %.1f, %.1f): ", p,
                patch.size(), patch.size() == 1 ? "" : "s", at.x(), at.y(), at.z());
  return text + why;
}

}  // namespace

Carving carve_dhf_gaps(std::vector<Part>& parts, std::int64_t lines, double epsilon_mm,
                       bool exchange, KeptAssembly* assembly) {
  detail::validate_gap_options(lines, epsilon_mm);
  Carving out;
  // Gaps per part; a part's count depends on its own boundary only (dhf_gap_count()).
  std::vector<std::int32_t> gaps;
  for (const Part& part : parts) gaps.push_back(dhf_gap_count(part, lines, epsilon_mm));
  out.gap_lines_before = sum(gaps);
  // Parts that intersect themselves already (where they touch themselves): not held to it.
  std::vector<char> crossed(parts.size());
  for (std::size_t k = 0; k < parts.size(); ++k)
    crossed[k] = !intersecting_triangles(parts[k].mesh, 1).empty();
  for (std::int32_t p = 0; p < static_cast<std::int32_t>(parts.size()); ++p) {
    if (gaps[p] == 0) continue;
    const detail::CarveLines found = detail::carve_lines(parts, p, lines, epsilon_mm);
    std::deque<std::pair<Patch, int>> todo;  // with how often it was halved
    for (Patch& patch : patches(found)) todo.emplace_back(std::move(patch), 0);
    for (int tries = 0; !todo.empty() && tries < kMaxTries; ++tries) {
      auto [patch, splits] = std::move(todo.front());
      todo.pop_front();
      if (std::none_of(patch.begin(), patch.end(), [](const auto* l) { return l->deep; }))
        continue;  // a half with shallow gaps only
      // Filling first (or taking, where filling would reach the outer surface), then yielding,
      // then carving; the first that leaves fewer gap lines is kept.
      std::string why, fill_refusal;
      bool done = false;
      for (const Way way : kWays) {
        if (way != Way::Carve && !exchange) continue;
        // Taking differs from filling only where the hull reaches the outer surface.
        if (way == Way::Take && fill_refusal != detail::kHullReachesOuterSurface) continue;
        std::int32_t other = -1;
        const bool spans_gaps = way == Way::Fill || way == Way::Take;  // else P's short end
        const std::vector<Vec3> points = way == Way::Carve
                                             ? hull_points(patch, found, epsilon_mm)
                                             : exchange_points(patch, found, spans_gaps, other);
        std::string reason;
        std::optional<detail::CarvedHull> changed;
        if (points.empty())
          reason = way == Way::Carve ? "the part reaches its outer surface on both sides"
                                     : "no one other part is there";
        const bool checked = !crossed[p] && (other < 0 || !crossed[other]);
        for (int variant = 0; variant < kVariants && !points.empty(); ++variant) {
          const std::vector<Vec3> hull = varied(points, variant);
          if (way == Way::Fill)
            changed = detail::fill_hull(parts, p, other, hull, checked, reason);
          else if (way == Way::Take)  // the neighbour yields what of it lies in the hull
            changed = detail::yield_hull(parts, other, p, hull, checked, reason);
          else if (way == Way::Yield)
            changed = detail::yield_hull(parts, p, other, hull, checked, reason);
          else
            changed = detail::carve_hull(parts, p, hull, checked, reason);
          // Rounding to float can make the new triangles cross others, in the parts and in the
          // material carved out (written as a solid of its own).
          if (changed)
            for (const auto& [id, part] : changed->changed)
              if (!crossed[id] && !intersecting_triangles(part.mesh, 1).empty()) {
                reason = "part " + std::to_string(id) + " would intersect itself once rounded";
                changed.reset();
                break;
              }
          if (changed && !changed->hole.mesh.triangles.empty() &&
              !intersecting_triangles(changed->hole.mesh, 1).empty()) {
            reason = "the void would intersect itself once rounded";
            changed.reset();
          }
          if (changed || !broken_by_rounding(reason)) break;
        }
        if (changed) {
          std::vector<Part> tried = parts;
          std::vector<std::int32_t> after = gaps;
          for (auto& [id, part] : changed->changed) {
            tried[id] = std::move(part);
            after[id] = dhf_gap_count(tried[id], lines, epsilon_mm);
          }
          bool worse = after[p] >= gaps[p];
          for (std::size_t q = 0; q < parts.size(); ++q) worse = worse || after[q] > gaps[q];
          const char* refusal = worse ? "it leaves as many gap lines or more" : nullptr;
          std::optional<AssemblyPlan> plan;
          if (!refusal && assembly && way != Way::Carve) {
            plan = plan_assembly(tried, assembly->directions, assembly->tolerance_mm);
            if (plan->blocked > assembly->plan.blocked || (assembly->plan.found && !plan->found))
              refusal = "the parts would have no assembly order";
          }
          if (!refusal) {
            if (plan) assembly->plan = std::move(*plan);
            const double moved = tried[p].volume_mm3 - parts[p].volume_mm3;
            if (way == Way::Fill || way == Way::Take)
              out.exchanges.push_back({other, p, moved});
            else if (way == Way::Yield)
              out.exchanges.push_back({p, other, -moved});
            else
              out.voids.push_back(std::move(changed->hole));
            parts = std::move(tried);
            gaps = std::move(after);
            done = true;
            break;
          }
          reason = refusal;
        }
        if (way == Way::Fill) fill_refusal = reason;
        why += (why.empty() ? "" : "; ") + std::string(kWayNames[static_cast<int>(way)]) + ": " +
               reason;
      }
      if (done) continue;
      if (splits < kMaxSplits && patch.size() > 1) {
        auto [a, b] = halves(std::move(patch));
        todo.emplace_back(std::move(a), splits + 1);
        todo.emplace_back(std::move(b), splits + 1);
      } else {
        out.refused.push_back(describe(p, patch, why));
      }
    }
    for (const auto& [patch, splits] : todo)
      out.refused.push_back(describe(p, patch, "not tried (too many patches)"));
  }
  out.gap_lines_after = sum(gaps);
  return out;
}

}  // namespace dhfcast
