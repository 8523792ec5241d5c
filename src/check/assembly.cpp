// assembly and molds: solids swept along their directions must not go deeper than epsilon into
// the solids they slide past.
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "check_internal.h"
#include "sampling.h"

namespace dhfcast::detail {

Sweep sweep(const SurfaceIndex& solid, const Vec3& p, const Vec3& dir, double epsilon_mm) {
  Vec3 u, v;
  perpendicular_basis(dir, u, v);
  const double shift = 1e-7 * std::max(solid.bbox().diagonal(), 1.0);
  const Vec3 starts[] = {p, p + shift * u, p + shift * v};
  for (const Vec3& q : starts) {
    const std::optional<std::vector<Interval>> in = solid.ray_intervals(q, dir);
    if (!in) continue;
    Sweep s;
    s.resolved = true;
    for (const Interval& i : *in) {
      s.inside_mm += i.end - i.begin;
      if (s.blocked || (i.begin > 0 && i.end - i.begin <= 2 * epsilon_mm)) continue;
      s.blocked = solid.max_distance_along(q, dir, i.begin, i.end, 0.5 * epsilon_mm, epsilon_mm) >
                  epsilon_mm;
    }
    return s;
  }
  return {};
}

bool ray_meets_box(const Vec3& p, const Vec3& dir, const Box3& box) {
  double t_lo = 0.0, t_hi = INFINITY;
  for (int k = 0; k < 3; ++k) {
    if (dir[k] == 0.0) {
      if (p[k] < box.min[k] || p[k] > box.max[k]) return false;
      continue;
    }
    double a = (box.min[k] - p[k]) / dir[k], b = (box.max[k] - p[k]) / dir[k];
    if (a > b) std::swap(a, b);
    t_lo = std::max(t_lo, a);
    t_hi = std::min(t_hi, b);
  }
  return t_lo <= t_hi;
}

namespace {

constexpr std::uint64_t kAssemblyStream = 3;
constexpr std::uint64_t kMoldStream = 4;

// Points just inside a solid's surface: its vertices and `count` random points. Moving them
// inside by a hair keeps them off the faces they share with neighbours (a path along a shared
// face would graze it).
std::vector<SurfaceSample> inner_samples(const TriMesh& mesh, std::int64_t count, Random& random) {
  std::vector<SurfaceSample> s = vertex_samples(mesh);
  const std::vector<SurfaceSample> r = sample_surface(mesh, count, random);
  s.insert(s.end(), r.begin(), r.end());
  push_inside(s, 1e-4 * bounding_box(mesh.vertices).diagonal());
  return s;
}

// Sweeps of many samples against one solid.
struct SweepTally {
  std::int64_t blocked = 0, unresolved = 0;
  double inside_mm = 0.0;             // longest path inside, over blocked samples
  Vec3 first_blocked = Vec3::Zero();  // the first blocked sample, when blocked > 0
};

SweepTally sweep_all(const std::vector<SurfaceSample>& samples, const Vec3& dir,
                     const SurfaceIndex& solid, double eps) {
  Sweep outside;  // what a sample whose ray misses the solid's box gets
  outside.resolved = true;
  std::vector<Sweep> r(samples.size(), outside);
  tbb::parallel_for(std::size_t{0}, samples.size(), [&](std::size_t i) {
    if (ray_meets_box(samples[i].point, dir, solid.bbox()))
      r[i] = sweep(solid, samples[i].point, dir, eps);
  });
  SweepTally t;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const Sweep& s = r[i];
    t.unresolved += !s.resolved;
    if (s.blocked) {
      if (t.blocked == 0) t.first_blocked = samples[i].point;
      ++t.blocked;
      t.inside_mm = std::max(t.inside_mm, s.inside_mm);
    }
  }
  return t;
}

std::string id_list(const CheckContext& c, const std::vector<std::int32_t>& indices) {
  std::string s;
  for (std::int32_t i : indices) {
    if (!s.empty()) s += ' ';
    s += std::to_string(c.parts[i].id);
  }
  return s;
}

const char* ordinal_suffix(std::size_t n) {
  if (n % 100 >= 11 && n % 100 <= 13) return "th";
  return n % 10 == 1 ? "st" : n % 10 == 2 ? "nd" : n % 10 == 3 ? "rd" : "th";
}

}  // namespace

CheckItem check_assembly(const CheckContext& c) {
  const CheckOptions& o = c.options;
  const std::size_t n = c.parts.size();
  CheckItem item;
  item.name = "assembly";

  // --- 1. who blocks whom: tally[m][p] for part m arriving along -removal_m past part p ---
  std::vector<std::vector<SweepTally>> tally(n, std::vector<SweepTally>(n));
  std::vector<std::int64_t> sample_count(n, 0);
  for (std::size_t m = 0; m < n && n > 1; ++m) {
    Random random(stream_seed(o.seed, kAssemblyStream + 16 * (m + 1)));
    const std::vector<SurfaceSample> samples =
        inner_samples(c.parts[m].solid.mesh(), o.assembly_samples, random);
    sample_count[m] = static_cast<std::int64_t>(samples.size());
    for (std::size_t p = 0; p < n; ++p)
      if (p != m)
        tally[m][p] = sweep_all(samples, c.parts[m].removal, c.parts[p].solid, o.epsilon_mm);
  }

  // --- 2. does any order work? q must come before m when q runs into m (topological sort,
  // smallest index first) ---
  std::vector<std::int32_t> valid_order;
  std::vector<bool> placed(n, false);
  while (valid_order.size() < n) {
    std::size_t next = n;
    for (std::size_t m = 0; m < n && next == n; ++m) {
      if (placed[m]) continue;
      bool free = true;
      for (std::size_t q = 0; q < n && free; ++q)
        free = placed[q] || q == m || tally[q][m].blocked == 0;
      if (free) next = m;
    }
    if (next == n) break;
    placed[next] = true;
    valid_order.push_back(static_cast<std::int32_t>(next));
  }
  const bool order_exists = valid_order.size() == n;
  std::vector<std::int32_t> stuck;
  for (std::size_t m = 0; m < n; ++m)
    if (!placed[m]) stuck.push_back(static_cast<std::int32_t>(m));
  const std::string exists_text =
      order_exists
          ? "a collision-free order exists: " + id_list(c, valid_order)
          : "no collision-free order exists (parts " + id_list(c, stuck) + " block each other)";

  // --- 3. the order of decomposition.json ---
  std::int64_t unresolved = 0;
  for (std::size_t m = 0; m < n; ++m)
    for (std::size_t p = 0; p < n; ++p) unresolved += tally[m][p].unresolved;
  item.figures = {{"parts", double(n)}, {"order_exists", order_exists ? 1.0 : 0.0}};
  if (c.order.empty()) {
    item.skipped = true;
    item.summary =
        "assembly_order is not a permutation of the part ids (see contract); " + exists_text;
    return item;
  }
  std::int64_t blocked = 0, pairs = 0;
  double inside_mm = 0.0;
  std::string first;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < i; ++j) {
      const SweepTally& t = tally[c.order[i]][c.order[j]];
      if (t.blocked == 0) continue;
      blocked += t.blocked;
      ++pairs;
      inside_mm = std::max(inside_mm, t.inside_mm);
      if (first.empty()) {
        item.at = t.first_blocked;
        first = format(
            "%s (placed %zu%s) runs into %s on its way in: %lld of %lld samples, "
            "up to %.3g mm inside (first from %.2f %.2f %.2f)",
            part_name(c.parts[c.order[i]]).c_str(), i + 1, ordinal_suffix(i + 1),
            part_name(c.parts[c.order[j]]).c_str(), static_cast<long long>(t.blocked),
            static_cast<long long>(sample_count[c.order[i]]), t.inside_mm, t.first_blocked.x(),
            t.first_blocked.y(), t.first_blocked.z());
      }
    }
  std::int64_t samples = 0;
  for (std::int64_t s : sample_count) samples += s;
  item.figures.insert(item.figures.end(), {{"samples", double(samples)},
                                           {"blocked_samples", double(blocked)},
                                           {"blocking_pairs", double(pairs)},
                                           {"max_inside_mm", inside_mm},
                                           {"unresolved_samples", double(unresolved)}});
  item.passed = blocked <= o.max_blocked_samples;
  if (n == 1)
    item.summary = "1 part: nothing to collide with";
  else if (blocked == 0)
    item.summary = format("order %s: no part runs into one placed before it (%lld samples)",
                          id_list(c, c.order).c_str(), static_cast<long long>(samples));
  else
    item.summary = first +
                   (pairs > 1 ? format(" (%lld blocking pairs)", static_cast<long long>(pairs))
                              : std::string()) +
                   "; " + exists_text;
  return item;
}

CheckItem check_molds(const CheckContext& c) {
  const CheckOptions& o = c.options;
  CheckItem item;
  item.name = "molds";
  std::int64_t with_molds = 0, blocked = 0, unresolved = 0;
  double inside_mm = 0.0, worst_overlap = 0.0, worst_cover = 1.0, most_sliver = 0.0,
         most_served = 0.0;
  std::int32_t min_sprues = std::numeric_limits<std::int32_t>::max(), min_keys = min_sprues,
               min_vents = min_sprues;
  std::int64_t vents = 0;
  std::string first;
  for (std::size_t i = 0; i < c.parts.size(); ++i) {
    const CheckedPart& part = c.parts[i];
    if (!part.molds_listed) continue;
    ++with_molds;
    if (!part.mold_error.empty()) {
      if (first.empty()) first = part_name(part) + " has no mold: " + part.mold_error;
      continue;
    }
    if (!part.mold_up || !part.mold_down) {
      if (first.empty())
        first = part_name(part) +
                ": its mold halves could not be read or placed (see solids, contract)";
      continue;
    }
    Random random(stream_seed(o.seed, kMoldStream + 16 * (i + 1)));
    std::string problem;
    std::optional<Vec3> problem_at;

    // --- release: up leaves along +d, down along -d ---
    const SurfaceIndex* halves[2] = {&*part.mold_up, &*part.mold_down};
    for (int h = 0; h < 2; ++h) {
      const std::vector<SurfaceSample> s = inner_samples(halves[h]->mesh(), o.mold_samples, random);
      const SweepTally t =
          sweep_all(s, h == 0 ? part.direction : Vec3(-part.direction), part.solid, o.epsilon_mm);
      blocked += t.blocked;
      unresolved += t.unresolved;
      inside_mm = std::max(inside_mm, t.inside_mm);
      if (t.blocked > o.max_blocked_samples && problem.empty()) {
        problem_at = t.first_blocked;
        problem = format(
            "the %s half runs into the part when pulled along %sd (%lld samples, up "
            "to %.3g mm inside; first at %.2f %.2f %.2f)",
            h == 0 ? "up" : "down", h == 0 ? "+" : "-", static_cast<long long>(t.blocked),
            t.inside_mm, t.first_blocked.x(), t.first_blocked.y(), t.first_blocked.z());
      }
    }

    // --- overlap: points of the block inside two of part, up, down ---
    Box3 box = part.solid.bbox();
    for (const SurfaceIndex* half : halves) {
      box.min = box.min.cwiseMin(half->bbox().min);
      box.max = box.max.cwiseMax(half->bbox().max);
    }
    std::vector<Vec3> points(static_cast<std::size_t>(o.mold_samples));
    for (Vec3& p : points)
      for (int k = 0; k < 3; ++k) p[k] = random.uniform(box.min[k], box.max[k]);
    std::vector<char> overlapping(points.size(), 0);
    tbb::parallel_for(std::size_t{0}, points.size(), [&](std::size_t k) {
      const int count = part.solid.contains(points[k]) + halves[0]->contains(points[k]) +
                        halves[1]->contains(points[k]);
      overlapping[k] = count >= 2;
    });
    const double overlap = double(std::ranges::count(overlapping, 1)) * (box.max - box.min).prod() /
                           double(points.size()) / part.volume_mm3;
    worst_overlap = std::max(worst_overlap, overlap);
    if (overlap > o.max_overlap_fraction && problem.empty())
      problem =
          format("the halves and the part overlap (%.3f%% of the part's volume)", 100 * overlap);

    // --- cover: the part's surface is moulded by the halves. Where the part is a double height
    // field only up to the undercut tolerance, a half cannot hold the undercut and leave, so the
    // cast fills it: a sample counts as moulded within the tolerance when the point epsilon out
    // along its normal is inside a half (the sliver between is thinner than epsilon; a fin of
    // open space reaching further out is not). A sample that opens into a listed channel (within
    // the channel's radius of its axis: the sprue or vent stub is cut off after casting) is
    // served by it. Both are counted apart. ---
    const std::vector<SurfaceSample> surface =
        sample_surface(part.solid.mesh(), o.mold_samples, random);
    enum : char { kBare, kMoulded, kSliver, kChannel };
    std::vector<char> state(surface.size(), kBare);
    const double near_mm = 0.25 * o.epsilon_mm;
    tbb::parallel_for(std::size_t{0}, surface.size(), [&](std::size_t k) {
      const Vec3& p = surface[k].point;
      if (halves[0]->distance(p) <= near_mm || halves[1]->distance(p) <= near_mm) {
        state[k] = kMoulded;
        return;
      }
      const Vec3 out = p + o.epsilon_mm * surface[k].normal;
      if (halves[0]->contains(out) || halves[1]->contains(out)) {
        state[k] = kSliver;
        return;
      }
      for (const CheckedPart::Channel& ch : part.channels) {
        const Vec3 axis = ch.exit - ch.mouth;
        const double t = std::clamp((p - ch.mouth).dot(axis) / axis.squaredNorm(), 0.0, 1.0);
        if ((ch.mouth + t * axis - p).norm() <= 0.5 * ch.diameter_mm + near_mm) state[k] = kChannel;
      }
    });
    const double n_surface = std::max<double>(1.0, double(surface.size()));
    const double cover = double(std::ranges::count(state, kMoulded)) / n_surface;
    const double sliver = double(std::ranges::count(state, kSliver)) / n_surface;
    const double served = double(std::ranges::count(state, kChannel)) / n_surface;
    worst_cover = std::min(worst_cover, cover + sliver + served);
    most_sliver = std::max(most_sliver, sliver);
    most_served = std::max(most_served, served);
    if (cover + sliver + served < o.min_mold_surface_coverage && problem.empty()) {
      const auto bare = std::ranges::find(state, kBare) - state.begin();
      const Vec3& at = surface[bare].point;
      problem_at = at;
      problem = format(
          "only %.2f%% of the part's surface is within %.3g mm of a half (%.2f%% more within "
          "the undercut tolerance, %.2f%% opens into a channel; first bare sample at %.2f %.2f "
          "%.2f)",
          100 * cover, near_mm, 100 * sliver, 100 * served, at.x(), at.y(), at.z());
    }

    // --- fittings: a sprue to pour through, keys to close the mold in register ---
    min_sprues = std::min(min_sprues, part.sprues);
    min_keys = std::min(min_keys, part.keys);
    vents += part.vents;
    min_vents = std::min(min_vents, part.vents);
    if ((part.sprues < 1 || part.keys < 3) && problem.empty())
      problem =
          format("the mold lists %d sprue%s and %d key%s (at least 1 and 3 needed)", part.sprues,
                 part.sprues == 1 ? "" : "s", part.keys, part.keys == 1 ? "" : "s");

    if (!problem.empty() && first.empty()) {
      first = part_name(part) + ": " + problem;
      item.at = problem_at;
    }
  }
  if (with_molds == 0) {
    item.skipped = true;
    item.summary = "no mold halves listed in decomposition.json";
    return item;
  }
  item.passed = first.empty();
  item.figures = {
      {"parts_with_molds", double(with_molds)},
      {"blocked_samples", double(blocked)},
      {"max_inside_mm", inside_mm},
      {"max_overlap_fraction", worst_overlap},
      {"min_surface_coverage", worst_cover},
      {"max_undercut_sliver_fraction", most_sliver},
      {"max_channel_served_fraction", most_served},
      {"min_sprues",
       min_sprues == std::numeric_limits<std::int32_t>::max() ? 0.0 : double(min_sprues)},
      {"min_keys", min_keys == std::numeric_limits<std::int32_t>::max() ? 0.0 : double(min_keys)},
      {"vents", double(vents)},
      {"min_vents",
       min_vents == std::numeric_limits<std::int32_t>::max() ? 0.0 : double(min_vents)},
      {"unresolved_samples", double(unresolved)}};
  item.summary = item.passed
                     ? format(
                           "%lld part%s: halves release along +-d, overlap at most %.3f%%, surface "
                           "covered at least %.2f%% (undercut slivers at most %.2f%%, channels "
                           "at most %.2f%%), sprues, %lld vents (>= %d per mold), >= %d keys",
                           static_cast<long long>(with_molds), with_molds == 1 ? "" : "s",
                           100 * worst_overlap, 100 * worst_cover, 100 * most_sliver,
                           100 * most_served, static_cast<long long>(vents), min_vents, min_keys)
                     : first;
  return item;
}

}  // namespace dhfcast::detail
