// fidelity: the parts' outer surface against the input surface, both ways (a two-sided,
// sampled Hausdorff distance with its 99th percentile).
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "check_internal.h"
#include "sampling.h"

namespace dhfcast::detail {

namespace {
constexpr std::uint64_t kFidelityStream = 5;
}  // namespace

CheckItem check_fidelity(const CheckContext& c) {
  const CheckOptions& o = c.options;
  CheckItem item;
  item.name = "fidelity";
  if (!c.input) {
    item.skipped = true;
    item.summary = "needs the input mesh (--input)";
    return item;
  }
  Random random(stream_seed(o.seed, kFidelityStream));

  // --- 1. all parts' surfaces in one index; which part each triangle comes from ---
  TriMesh all;
  std::vector<std::int32_t> part_of_triangle;
  for (std::size_t i = 0; i < c.parts.size(); ++i) {
    const TriMesh& m = c.parts[i].solid.mesh();
    const auto offset = static_cast<std::int32_t>(all.vertices.size());
    all.vertices.insert(all.vertices.end(), m.vertices.begin(), m.vertices.end());
    for (const Tri& t : m.triangles) {
      all.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
      part_of_triangle.push_back(static_cast<std::int32_t>(i));
    }
  }
  const SurfaceIndex parts_surface(all);

  // --- 2. input surface -> parts ---
  const std::vector<SurfaceSample> on_input =
      sample_surface(c.input->mesh(), o.fidelity_samples, random);
  std::vector<double> to_parts(on_input.size());
  tbb::parallel_for(std::size_t{0}, on_input.size(), [&](std::size_t i) {
    to_parts[i] = parts_surface.distance(on_input[i].point);
  });

  // --- 3. outer part surface -> input: samples on or in another part are interfaces, on a
  // carved void its walls ---
  const std::vector<SurfaceSample> on_parts = sample_surface(all, o.fidelity_samples, random);
  const double near_mm = 0.25 * o.epsilon_mm;
  std::vector<double> to_input(on_parts.size(), -1.0);
  tbb::parallel_for(std::size_t{0}, on_parts.size(), [&](std::size_t i) {
    const Vec3& p = on_parts[i].point;
    const std::int32_t own = part_of_triangle[on_parts[i].triangle];
    for (std::size_t j = 0; j < c.parts.size(); ++j) {
      if (static_cast<std::int32_t>(j) == own) continue;
      const Box3& b = c.parts[j].solid.bbox();
      if ((p.array() < b.min.array() - near_mm).any() ||
          (p.array() > b.max.array() + near_mm).any())
        continue;
      if (c.parts[j].solid.distance(p) <= near_mm || c.parts[j].solid.contains(p)) return;
    }
    // The walls of a carved void are inside the solid too.
    for (const CheckContext::CarvedVoid& v : c.voids) {
      const Box3& b = v.solid.bbox();
      if ((p.array() >= b.min.array() - near_mm).all() &&
          (p.array() <= b.max.array() + near_mm).all() && v.solid.distance(p) <= near_mm)
        return;
    }
    to_input[i] = c.input->distance(p);
  });
  // Where each side's largest distance is: the place to look at.
  const auto in_worst = std::ranges::max_element(to_parts) - to_parts.begin();
  const auto out_worst = std::ranges::max_element(to_input) - to_input.begin();
  const Vec3 in_at = to_parts.empty() ? Vec3::Zero() : on_input[in_worst].point;
  const Vec3 out_at = to_input.empty() ? Vec3::Zero() : on_parts[out_worst].point;
  std::erase_if(to_input, [](double d) { return d < 0; });

  // --- 4. figures ---
  const double limit_mm = o.max_fidelity_p99_rel * c.input->bbox().diagonal();
  const double in_max = to_parts.empty() ? 0.0 : *std::ranges::max_element(to_parts);
  const double in_p99 = quantile(to_parts, 0.99);
  const double out_max = to_input.empty() ? 0.0 : *std::ranges::max_element(to_input);
  const double out_p99 = quantile(to_input, 0.99);
  item.passed = in_p99 <= limit_mm && out_p99 <= limit_mm;
  item.figures = {{"input_to_parts_max_mm", in_max},
                  {"input_to_parts_p99_mm", in_p99},
                  {"parts_to_input_max_mm", out_max},
                  {"parts_to_input_p99_mm", out_p99},
                  {"outer_part_samples", double(to_input.size())},
                  {"limit_mm", limit_mm}};
  item.summary = format(
      "input to parts: p99 %.3g mm, max %.3g mm (at %.2f %.2f %.2f); outer part surface to "
      "input: p99 %.3g mm, max %.3g mm (at %.2f %.2f %.2f) (limit p99 %.3g mm)",
      in_p99, in_max, in_at.x(), in_at.y(), in_at.z(), out_p99, out_max, out_at.x(), out_at.y(),
      out_at.z(), limit_mm);
  item.at = in_max >= out_max ? in_at : out_at;
  return item;
}

}  // namespace dhfcast::detail
