// coverage: do the parts fill the input, once, and nothing else? Volumes, then points uniform in
// the bounding box classified against the input and every part.
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "check_internal.h"
#include "sampling.h"

namespace dhfcast::detail {

namespace {

constexpr std::uint64_t kCoverageStream = 1;
// Points are drawn on vertical lines, this many per line: one ray query per mesh serves them
// all. Each point is still uniform in the box.
constexpr int kPointsPerLine = 16;

struct Line {
  double x = 0.0, y = 0.0;
  std::array<double, kPointsPerLine> z{};
};

struct Tally {
  bool consistent = true;
  std::int64_t inside = 0;   // inside the input (without one: inside some part)
  std::int64_t once = 0;     // of those, inside exactly one part
  std::int64_t overlap = 0;  // inside two or more parts
  std::int64_t gap = 0;      // inside the input, in no part (nor in a carved void)
  std::int64_t outside = 0;  // in some part, outside the input
  std::int64_t carved = 0;   // inside the input, in a carved void and no part
};

const Tally kInconsistent{false, 0, 0, 0, 0, 0, 0};

bool covers(const std::vector<Interval>& in, double t) {
  return std::ranges::any_of(in, [t](const Interval& i) { return i.begin <= t && t <= i.end; });
}

bool box_covers_xy(const Box3& b, double x, double y) {
  return x >= b.min.x() && x <= b.max.x() && y >= b.min.y() && y <= b.max.y();
}

Tally classify(const CheckContext& c, const Line& line, double z_mid) {
  Tally tally;
  const Vec3 origin(line.x, line.y, z_mid);
  const Vec3 up = Vec3::UnitZ();
  std::optional<std::vector<Interval>> input;
  if (c.input) {
    input = c.input->line_intervals(origin, up);
    if (!input) return kInconsistent;
  }
  std::vector<std::vector<Interval>> parts;
  for (const CheckedPart& p : c.parts) {
    if (!box_covers_xy(p.solid.bbox(), line.x, line.y)) continue;
    std::optional<std::vector<Interval>> in = p.solid.line_intervals(origin, up);
    if (!in) return kInconsistent;
    if (!in->empty()) parts.push_back(std::move(*in));
  }
  // A void counts as one more solid for overlaps: it must lie in no part.
  std::vector<std::vector<Interval>> voids;
  for (const CheckContext::CarvedVoid& v : c.voids) {
    if (!box_covers_xy(v.solid.bbox(), line.x, line.y)) continue;
    std::optional<std::vector<Interval>> in = v.solid.line_intervals(origin, up);
    if (!in) return kInconsistent;
    if (!in->empty()) voids.push_back(std::move(*in));
  }
  for (double z : line.z) {
    const double t = z - z_mid;
    int count = 0;
    for (const std::vector<Interval>& in : parts) count += covers(in, t) ? 1 : 0;
    int carved = 0;
    for (const std::vector<Interval>& in : voids) carved += covers(in, t) ? 1 : 0;
    const bool in_input = input ? covers(*input, t) : count + carved > 0;
    tally.carved += in_input && count == 0 && carved == 1;
    count += carved;
    tally.inside += in_input;
    tally.once += in_input && count == 1;
    tally.overlap += count >= 2;
    tally.gap += in_input && count == 0 && carved == 0;
    tally.outside += !in_input && count > 0;
  }
  return tally;
}

}  // namespace

CheckItem check_coverage(const CheckContext& c) {
  const CheckOptions& o = c.options;
  CheckItem item;
  item.name = "coverage";

  // --- 1. volumes ---
  double parts_volume = 0.0;
  for (const CheckedPart& p : c.parts) parts_volume += p.volume_mm3;
  double carved_volume = 0.0;
  for (const CheckContext::CarvedVoid& v : c.voids) carved_volume += v.volume_mm3;
  const double input_volume = c.input ? signed_volume(c.input->mesh()) : c.json_input_volume_mm3;
  const bool volume_known = input_volume > 0;
  const double reference = volume_known ? input_volume : parts_volume;
  const double volume_error =
      volume_known ? std::abs(parts_volume + carved_volume - input_volume) / input_volume : 0.0;

  // --- 2. sample lines, in a box holding the input and every part ---
  Box3 box = c.input             ? c.input->bbox()
             : c.json_input_bbox ? *c.json_input_bbox
                                 : c.parts.front().solid.bbox();
  for (const CheckedPart& p : c.parts) {
    box.min = box.min.cwiseMin(p.solid.bbox().min);
    box.max = box.max.cwiseMax(p.solid.bbox().max);
  }
  const double z_mid = 0.5 * (box.min.z() + box.max.z());
  const std::int64_t lines_wanted = (o.coverage_samples + kPointsPerLine - 1) / kPointsPerLine;
  // Lines whose crossings are inconsistent (an exact edge hit) are replaced by the next ones; a
  // broken mesh could make most lines so, hence the cap.
  const std::int64_t max_lines = 4 * lines_wanted;
  Random random(stream_seed(o.seed, kCoverageStream));
  Tally total;
  std::int64_t accepted = 0, drawn = 0, inconsistent = 0;
  while (accepted < lines_wanted && drawn < max_lines) {
    const std::int64_t batch = std::min(lines_wanted - accepted + 16, max_lines - drawn);
    std::vector<Line> lines(static_cast<std::size_t>(batch));
    for (Line& l : lines) {
      l.x = random.uniform(box.min.x(), box.max.x());
      l.y = random.uniform(box.min.y(), box.max.y());
      for (double& z : l.z) z = random.uniform(box.min.z(), box.max.z());
    }
    drawn += batch;
    std::vector<Tally> tallies(lines.size());
    tbb::parallel_for(std::size_t{0}, lines.size(),
                      [&](std::size_t i) { tallies[i] = classify(c, lines[i], z_mid); });
    for (const Tally& t : tallies) {
      if (accepted == lines_wanted) break;
      if (!t.consistent) {
        ++inconsistent;
        continue;
      }
      ++accepted;
      total.inside += t.inside;
      total.once += t.once;
      total.overlap += t.overlap;
      total.gap += t.gap;
      total.outside += t.outside;
      total.carved += t.carved;
    }
  }

  // --- 3. fractions of the input's volume ---
  const std::int64_t samples = accepted * kPointsPerLine;
  const Vec3 size = box.max - box.min;
  const double sample_volume = samples > 0 ? size.prod() / static_cast<double>(samples) : 0.0;
  auto fraction = [&](std::int64_t n) { return n * sample_volume / reference; };
  const double overlap = fraction(total.overlap);
  const double gap = fraction(total.gap);
  const double outside = fraction(total.outside);
  const double carved = fraction(total.carved);
  const double once = total.inside > 0 ? double(total.once) / double(total.inside) : 0.0;

  item.figures = {{"input_volume_mm3", volume_known ? input_volume : 0.0},
                  {"parts_volume_mm3", parts_volume},
                  {"volume_error", volume_error},
                  {"samples", static_cast<double>(samples)},
                  {"covered_once_fraction", once},
                  {"overlap_fraction", overlap}};
  if (c.input) {
    item.figures.emplace_back("gap_fraction", gap);
    item.figures.emplace_back("outside_fraction", outside);
  }
  item.figures.emplace_back("carved_mm3", carved_volume);
  if (c.input) item.figures.emplace_back("carved_fraction", carved);
  item.figures.emplace_back("inconsistent_lines", static_cast<double>(inconsistent));

  const bool volume_ok = volume_error <= o.max_volume_error;
  const bool overlap_ok = overlap <= o.max_overlap_fraction;
  const bool gap_ok = !c.input || gap <= o.max_gap_fraction;
  const bool outside_ok = !c.input || outside <= o.max_outside_fraction;
  item.passed = samples > 0 && volume_ok && overlap_ok && gap_ok && outside_ok;

  std::string volumes =
      volume_known ? format("parts%s %.6g mm3 vs %s %.6g mm3 (error %.3f%%%s)",
                            c.voids.empty() ? "" : " + carved", parts_volume + carved_volume,
                            c.input ? "input" : "json input", input_volume, 100 * volume_error,
                            volume_ok ? "" : ", too large")
                   : format("parts %.6g mm3 (input volume unknown)", parts_volume);
  std::string sampled;
  if (samples == 0)
    sampled = "no sample line had consistent crossings";
  else if (c.input)
    sampled = format("%lld samples: overlap %.3f%%%s, gap %.3f%%%s, outside %.3f%%%s",
                     static_cast<long long>(samples), 100 * overlap,
                     overlap_ok ? "" : " (too much)", 100 * gap, gap_ok ? "" : " (too much)",
                     100 * outside, outside_ok ? "" : " (too much)");
  else
    sampled =
        format("%lld samples: overlap %.3f%%%s (no --input: gap and outside not checked)",
               static_cast<long long>(samples), 100 * overlap, overlap_ok ? "" : " (too much)");
  item.summary = volumes + "; " + sampled;
  if (!c.voids.empty())
    item.summary +=
        format("; %zu carved void%s, %.3g mm3 (%.4f%% of the input), counted apart", c.voids.size(),
               c.voids.size() == 1 ? "" : "s", carved_volume, 100 * carved_volume / reference);
  return item;
}

}  // namespace dhfcast::detail
