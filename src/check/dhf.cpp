// dhf: is each part a double height field along its direction? Lines parallel to d through its
// footprint must meet it in one interval, up to gaps that stay within epsilon of its surface
// (the undercut tolerance of the paper, §4.1).
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "check_internal.h"
#include "sampling.h"

namespace dhfcast::detail {

namespace {

constexpr std::uint64_t kDhfStream = 2;
// Candidate lines are drawn over the part's projected bounding rectangle; a thin diagonal part
// may fill a small share of it.
constexpr std::int64_t kMaxCandidatesPerLine = 50;

enum class LineKind { Miss, Inconsistent, Single, Tolerated, Violation };

struct LineResult {
  LineKind kind = LineKind::Miss;
  double depth_mm = 0.0;     // violations: deepest gap point, distance to the surface
  Vec3 gap_middle{0, 0, 0};  // violations: the middle of the deepest gap
};

LineResult trace(const SurfaceIndex& solid, const Vec3& origin, const Vec3& d, double eps) {
  const std::optional<std::vector<Interval>> in = solid.line_intervals(origin, d);
  if (!in) return {LineKind::Inconsistent};
  if (in->empty()) return {LineKind::Miss};
  if (in->size() == 1) return {LineKind::Single};
  LineResult r{LineKind::Tolerated};
  for (std::size_t i = 0; i + 1 < in->size(); ++i) {
    const double t0 = (*in)[i].end, t1 = (*in)[i + 1].begin;
    // Every gap point is within half the gap's length of its two ends, which are on the surface.
    if (t1 - t0 <= 2 * eps) continue;
    const double depth = solid.max_distance_along(origin, d, t0, t1, 0.5 * eps);
    if (depth > eps && depth > r.depth_mm) {
      r.kind = LineKind::Violation;
      r.depth_mm = depth;
      r.gap_middle = origin + (0.5 * (t0 + t1)) * d;
    }
  }
  return r;
}

struct PartResult {
  std::int64_t lines = 0, multi = 0, violations = 0, inconsistent = 0;
  double depth_mm = 0.0;
  Vec3 gap_middle{0, 0, 0};  // of the deepest gap
  double fraction() const { return lines > 0 ? double(violations) / double(lines) : 0.0; }
};

PartResult check_part(const CheckedPart& part, const CheckOptions& o, std::uint64_t stream) {
  const Vec3& d = part.direction;
  Vec3 u, v;
  perpendicular_basis(d, u, v);
  double u_lo = INFINITY, u_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY, w_mid = 0.0;
  for (const Vec3& p : part.solid.mesh().vertices) {
    u_lo = std::min(u_lo, p.dot(u)), u_hi = std::max(u_hi, p.dot(u));
    v_lo = std::min(v_lo, p.dot(v)), v_hi = std::max(v_hi, p.dot(v));
    w_mid += p.dot(d);
  }
  w_mid /= static_cast<double>(std::max<std::size_t>(part.solid.mesh().vertices.size(), 1));

  Random random(stream_seed(o.seed, stream));
  PartResult r;
  const std::int64_t wanted = o.dhf_lines;
  const std::int64_t max_candidates = kMaxCandidatesPerLine * wanted;
  std::int64_t drawn = 0;
  while (r.lines < wanted && drawn < max_candidates) {
    const std::int64_t batch = std::min(2 * (wanted - r.lines) + 16, max_candidates - drawn);
    std::vector<Vec3> origins(static_cast<std::size_t>(batch));
    for (Vec3& origin : origins)
      origin = random.uniform(u_lo, u_hi) * u + random.uniform(v_lo, v_hi) * v + w_mid * d;
    drawn += batch;
    std::vector<LineResult> results(origins.size());
    tbb::parallel_for(std::size_t{0}, origins.size(), [&](std::size_t i) {
      results[i] = trace(part.solid, origins[i], d, o.epsilon_mm);
    });
    for (const LineResult& line : results) {
      if (r.lines == wanted) break;
      if (line.kind == LineKind::Miss) continue;
      if (line.kind == LineKind::Inconsistent) {
        ++r.inconsistent;
        continue;
      }
      ++r.lines;
      r.multi += line.kind != LineKind::Single;
      if (line.kind == LineKind::Violation) {
        ++r.violations;
        if (line.depth_mm > r.depth_mm) r.depth_mm = line.depth_mm, r.gap_middle = line.gap_middle;
      }
    }
  }
  return r;
}

}  // namespace

CheckItem check_dhf(const CheckContext& c) {
  const CheckOptions& o = c.options;
  CheckItem item;
  item.name = "dhf";
  std::vector<PartResult> results;
  for (std::size_t i = 0; i < c.parts.size(); ++i)
    results.push_back(check_part(c.parts[i], o, kDhfStream + 16 * (i + 1)));

  std::int64_t lines = 0, multi = 0, violations = 0, inconsistent = 0, failing = 0;
  double depth = 0.0;
  std::size_t worst = 0;
  for (std::size_t i = 0; i < results.size(); ++i) {
    const PartResult& r = results[i];
    lines += r.lines;
    multi += r.multi;
    violations += r.violations;
    inconsistent += r.inconsistent;
    depth = std::max(depth, r.depth_mm);
    if (r.lines == 0 || r.fraction() > o.max_dhf_violation_fraction) ++failing;
    if (r.fraction() > results[worst].fraction() || (results[worst].lines > 0 && r.lines == 0))
      worst = i;
  }
  item.passed = failing == 0;
  const PartResult& w = results[worst];
  item.figures = {{"lines", double(lines)},
                  {"violating_lines", double(violations)},
                  {"max_violation_fraction", w.fraction()},
                  {"max_depth_mm", depth},
                  {"inconsistent_lines", double(inconsistent)}};
  for (std::size_t i = 0; i < results.size(); ++i) {
    const std::string key = "part_" + std::to_string(c.parts[i].id);
    item.figures.emplace_back(key + "_violation_fraction", results[i].fraction());
    item.figures.emplace_back(key + "_max_depth_mm", results[i].depth_mm);
  }

  const std::string worst_name = part_name(c.parts[worst]);
  if (w.lines == 0)
    item.summary = worst_name + ": no line along its direction met it consistently";
  else if (item.passed)
    item.summary = format(
        "%zu part%s, %lld lines: worst %s, %.2f%% of its lines cross a gap "
        "deeper than %.3g mm (%lld lines in all have gaps within it)",
        results.size(), results.size() == 1 ? "" : "s", static_cast<long long>(lines),
        worst_name.c_str(), 100 * w.fraction(), o.epsilon_mm,
        static_cast<long long>(multi - violations));
  else
    item.summary = format(
        "%lld part%s not a double height field: worst %s, %.2f%% of its lines "
        "(%lld/%lld) meet it in several intervals, gaps up to %.3g mm deep (its deepest gap's "
        "middle at %.2f %.2f %.2f)",
        static_cast<long long>(failing), failing == 1 ? " is" : "s are", worst_name.c_str(),
        100 * w.fraction(), static_cast<long long>(w.violations), static_cast<long long>(w.lines),
        w.depth_mm, w.gap_middle.x(), w.gap_middle.y(), w.gap_middle.z());
  if (!item.passed && w.lines > 0) item.at = w.gap_middle;
  return item;
}

}  // namespace dhfcast::detail
