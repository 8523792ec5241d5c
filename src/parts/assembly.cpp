#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "carve.h"
#include "dhfcast/error.h"
#include "dhfcast/parts.h"
#include "dhfcast/tolerance.h"
#include "ray_scene.h"

namespace dhfcast {
namespace {

// Where a ray crosses a part's boundary.
struct Crossing {
  double t_mm;
  std::int32_t part;
  bool exits;  // leaves the part (the face normal points along the ray)
  std::int32_t triangle;
};

// The cosine below which a face counts as parallel to a ray: a few float steps (2^-24), the
// precision of the ray's direction as Embree takes it.
constexpr double kParallel = 1e-6;

// The parts' boundaries in one ray scene, surface number = part id.
std::vector<const TriMesh*> meshes_of(const std::vector<Part>& parts) {
  std::vector<const TriMesh*> meshes;
  for (const Part& part : parts) meshes.push_back(&part.mesh);
  return meshes;
}

class PartScene {
 public:
  explicit PartScene(std::vector<const TriMesh*> meshes)
      : meshes_(std::move(meshes)), scene_(meshes_) {}

  // Whether part q's boundary passes within radius_mm of p. Thread-safe.
  bool near(std::int32_t q, const Vec3& p, double radius_mm) const {
    return scene_.near(q, p, radius_mm);
  }

  // Every crossing of the ray origin + t * dir, t > 0, with the parts' boundaries, sorted by t.
  // Embree only finds the triangles; t and the side are computed in double precision. Faces
  // parallel to the ray are skipped: sliding along them is no crossing. So are faces parallel
  // to it within the precision of the float ray Embree traces: on those, t in double precision
  // can land far from where Embree found the hit, and whether the ray crosses is noise.
  // Thread-safe.
  void crossings(const Vec3& origin, const Vec3& dir, std::vector<std::uint64_t>& hits,
                 std::vector<Crossing>& out) const {
    out.clear();
    scene_.all_hits(origin, dir, hits);
    for (const std::uint64_t h : hits) {
      const auto part = static_cast<std::int32_t>(h >> 32);
      const Tri& tri = meshes_[part]->triangles[static_cast<std::uint32_t>(h)];
      const std::vector<Vec3>& v = meshes_[part]->vertices;
      const Vec3 normal = (v[tri[1]] - v[tri[0]]).cross(v[tri[2]] - v[tri[0]]);
      const double along = normal.dot(dir);
      if (std::abs(along) <= kParallel * normal.norm() * dir.norm()) continue;
      const double t_mm = normal.dot(v[tri[0]] - origin) / along;
      if (t_mm > 0.0)
        out.push_back({t_mm, part, along > 0.0, static_cast<std::int32_t>(std::uint32_t(h))});
    }
    // Along the ray; ties are broken to the end, so equal crossings (an edge hit) come in one
    // order.
    std::sort(out.begin(), out.end(), [](const Crossing& a, const Crossing& b) {
      return std::tie(a.t_mm, a.part, a.exits, a.triangle) <
             std::tie(b.t_mm, b.part, b.exits, b.triangle);
    });
  }

 private:
  std::vector<const TriMesh*> meshes_;
  detail::RayScene scene_;
};

// Does the stretch (t0, t1) of origin + t * dir reach deeper than tolerance_mm into part p?
bool deeper_than(const PartScene& scene, std::int32_t p, const Vec3& origin, const Vec3& dir,
                 double t0, double t1, double tolerance_mm) {
  return dhfcast::deeper_than(origin, dir, t0, t1, tolerance_mm,
                              [&](const Vec3& x) { return !scene.near(p, x, tolerance_mm); });
}

// Points just inside a mesh's boundary, where a moving part first touches another: near each
// corner of each triangle and at the centres of its k x k sub-triangles (k so that they lie at
// most about `spacing` apart), moved `inset` against the triangle's normal. All lie strictly
// inside their triangles: off the edges, where a path along a face of a neighbour would graze
// it.
std::vector<Vec3> boundary_samples(const TriMesh& mesh, double spacing, double inset) {
  constexpr int kMaxSubdivision = 8;
  constexpr double kCorner = 0.02;  // of the way from a corner to the centroid
  std::vector<Vec3> samples;
  for (const Tri& tri : mesh.triangles) {
    const Vec3 &a = mesh.vertices[tri[0]], &b = mesh.vertices[tri[1]], &c = mesh.vertices[tri[2]];
    const Vec3 area_normal = (b - a).cross(c - a);
    const double length = area_normal.norm();
    if (length == 0.0) continue;
    const Vec3 in = -inset / length * area_normal;
    const Vec3 centroid = (a + b + c) / 3.0;
    for (const Vec3* corner : {&a, &b, &c})
      samples.push_back(*corner + kCorner * (centroid - *corner) + in);
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    const int k = std::clamp(static_cast<int>(std::ceil(longest / spacing)), 1, kMaxSubdivision);
    for (int i = 0; i < k; ++i)
      for (int j = 0; i + j < k; ++j) {
        // The sub-triangle at (i, j) pointing like the triangle, and the flipped one beside it.
        samples.push_back(a + (i + 1.0 / 3) / k * (b - a) + (j + 1.0 / 3) / k * (c - a) + in);
        if (i + j + 1 < k)
          samples.push_back(a + (i + 2.0 / 3) / k * (b - a) + (j + 2.0 / 3) / k * (c - a) + in);
      }
  }
  return samples;
}

// A stretch of a ray inside another part.
struct Stretch {
  std::int32_t part;
  double t_in, t_out;
};

// The stretches through other parts' interiors of the ray from a point of part `self`, given its
// crossings sorted by t, where deep(part, t_in, t_out) says the stretch goes deeper than
// tolerance_mm. entered_at (one slot per part, all -1) is scratch space, left all -1 again.
template <class Deep>
void mark_obstacles(const std::vector<Crossing>& crossings, std::int32_t self, double tolerance_mm,
                    const Deep& deep, std::vector<std::int32_t>& entered_at,
                    std::vector<Stretch>& found) {
  found.clear();
  for (std::size_t k = 0; k < crossings.size(); ++k) {
    const Crossing& c = crossings[k];
    if (c.part == self) continue;
    std::int32_t& entry = entered_at[c.part];
    if (!c.exits) {
      // Entering another part where the ray enters its own part again is the ray grazing a seam
      // where the two touch (float hits near a shared edge), not a way into the other part.
      // Exits need no such test: an exit with no entry before it is ignored anyway.
      const bool grazing = std::any_of(crossings.begin(), crossings.end(), [&](const Crossing& o) {
        return o.part == self && !o.exits && std::abs(o.t_mm - c.t_mm) <= tolerance_mm;
      });
      // Repeated entries (a hit on an edge shared by two triangles) count once.
      if (!grazing && entry < 0) entry = static_cast<std::int32_t>(k);
    } else if (entry >= 0) {
      const double t_in = crossings[entry].t_mm;
      if (deep(c.part, t_in, c.t_mm)) found.push_back({c.part, t_in, c.t_mm});
      entry = -1;
    }
  }
  for (const Crossing& c : crossings) entered_at[c.part] = -1;
}

// A cycle among the remaining parts, each blocked by a remaining one, written as
// "part a blocks part b, part b blocks part a".
std::string blocking_cycle(const std::vector<std::vector<std::int32_t>>& blocks,
                           const std::vector<bool>& remaining) {
  const std::int32_t n = static_cast<std::int32_t>(blocks.size());
  auto blocker = [&](std::int32_t p) {  // smallest remaining part that blocks p
    for (const std::int32_t q : blocks[p])
      if (remaining[q]) return q;
    throw Error(ErrorCode::Internal, "parts: a blocked part has no remaining blocker");
  };
  std::int32_t start = 0;
  while (!remaining[start]) ++start;
  // Following blockers from any part must close a loop: walk until a part repeats.
  std::vector<std::int32_t> seen_at(n, -1);
  std::vector<std::int32_t> walk;
  for (std::int32_t p = start; seen_at[p] < 0; p = blocker(p)) {
    seen_at[p] = static_cast<std::int32_t>(walk.size());
    walk.push_back(p);
  }
  // walk[k + 1] blocks walk[k]; reversed, each part blocks the next one.
  std::vector<std::int32_t> cycle(walk.begin() + seen_at[blocker(walk.back())], walk.end());
  std::reverse(cycle.begin(), cycle.end());
  std::rotate(cycle.begin(), std::min_element(cycle.begin(), cycle.end()), cycle.end());
  std::string message = "no assembly order:";
  for (std::size_t k = 0; k < cycle.size(); ++k) {
    message += (k == 0 ? " part " : ", part ") + std::to_string(cycle[k]) + " blocks part " +
               std::to_string(cycle[(k + 1) % cycle.size()]);
  }
  return message;
}

// SplitMix64's finalizer: a fixed scramble of an index.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// What the straight moves of one part run into, from its boundary samples.
class Collisions {
 public:
  Collisions(const std::vector<Part>& parts, double tolerance_mm)
      : scene_(meshes_of(parts)),
        num_parts_(static_cast<std::int32_t>(parts.size())),
        tolerance_mm_(tolerance_mm),
        samples_(assembly_samples(parts)) {
    // In a fixed pseudo-random order, the first few hundred samples already spread over the
    // whole part, so a blocked move is usually found after a few of them.
    for (std::vector<Vec3>& samples : samples_) {
      std::vector<std::pair<std::uint64_t, std::size_t>> keys;
      for (std::size_t i = 0; i < samples.size(); ++i) keys.push_back({mix(i), i});
      std::sort(keys.begin(), keys.end());
      std::vector<Vec3> shuffled;
      for (const auto& key : keys) shuffled.push_back(samples[key.second]);
      samples = std::move(shuffled);
    }
  }

  // A part among those marked in `among` that part p runs into when leaving along dir, or -1 when
  // there is none. Stops at the first collision: which blocker it names may depend on the thread
  // schedule, whether there is one does not.
  std::int32_t blocker(std::int32_t p, const Vec3& dir, const std::vector<bool>& among) const {
    std::atomic<std::int32_t> found{-1};
    std::atomic<bool> blocked{false};
    for_each_obstacle(
        p, dir,
        [&](std::size_t, const Stretch& stretch) {
          const std::int32_t q = stretch.part;
          if (!among[q]) return;
          std::int32_t none = -1;
          found.compare_exchange_strong(none, q);
          blocked.store(true, std::memory_order_relaxed);
        },
        &blocked);
    return found.load();
  }

  // Every part that part p leaving along dir runs into, ascending.
  std::vector<std::int32_t> blockers(std::int32_t p, const Vec3& dir) const {
    std::vector<std::atomic<bool>> hit(static_cast<std::size_t>(num_parts_));
    for_each_obstacle(
        p, dir,
        [&](std::size_t, const Stretch& stretch) {
          hit[stretch.part].store(true, std::memory_order_relaxed);
        },
        nullptr);
    std::vector<std::int32_t> out;
    for (std::int32_t q = 0; q < num_parts_; ++q)
      if (hit[q].load()) out.push_back(q);
    return out;
  }

  // Every stretch through another part's interior of the ways of part p's samples along dir, in
  // the samples' order.
  std::vector<Obstruction> obstructions(std::int32_t p, const Vec3& dir) const {
    std::vector<std::vector<Stretch>> per_sample(samples_[p].size());
    std::vector<Obstruction> out;
    for_each_obstacle(
        p, dir, [&](std::size_t s, const Stretch& stretch) { per_sample[s].push_back(stretch); },
        nullptr);
    for (std::size_t s = 0; s < per_sample.size(); ++s)
      for (const Stretch& stretch : per_sample[s])
        out.push_back({stretch.part, samples_[p][s] + stretch.t_in * dir,
                       samples_[p][s] + stretch.t_out * dir});
    return out;
  }

 private:
  // Calls obstacle(sample index, stretch), from several threads, for each stretch through
  // another part's interior of the ray from a sample of p along dir; gives up early once *stop
  // is set.
  template <class Obstacle>
  void for_each_obstacle(std::int32_t p, const Vec3& dir, const Obstacle& obstacle,
                         const std::atomic<bool>* stop) const {
    const std::vector<Vec3>& samples = samples_[p];
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        std::vector<std::uint64_t> hits;
                        std::vector<Crossing> crossings;
                        std::vector<std::int32_t> entered_at(num_parts_, -1);
                        std::vector<Stretch> found;
                        for (std::size_t s = range.begin(); s != range.end(); ++s) {
                          if (stop && stop->load(std::memory_order_relaxed)) return;
                          scene_.crossings(samples[s], dir, hits, crossings);
                          const Vec3& origin = samples[s];
                          auto deep = [&](std::int32_t q, double t_in, double t_out) {
                            return deeper_than(scene_, q, origin, dir, t_in, t_out, tolerance_mm_);
                          };
                          mark_obstacles(crossings, p, tolerance_mm_, deep, entered_at, found);
                          for (const Stretch& stretch : found) obstacle(s, stretch);
                        }
                      });
  }

  PartScene scene_;
  std::int32_t num_parts_;
  double tolerance_mm_;
  std::vector<std::vector<Vec3>> samples_;  // per part
};

}  // namespace

std::vector<std::vector<Vec3>> assembly_samples(const std::vector<Part>& parts) {
  constexpr double kSpacing = 0.01;  // of the parts' bounding-box diagonal
  constexpr double kInset = 1e-5;    // likewise: well above float precision
  Box3 box{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)};
  for (const Part& part : parts)
    for (const Vec3& v : part.mesh.vertices) {
      box.min = box.min.cwiseMin(v);
      box.max = box.max.cwiseMax(v);
    }
  const double size = std::max(parts.empty() ? 1.0 : box.diagonal(), 1e-9);
  std::vector<std::vector<Vec3>> samples;
  for (const Part& part : parts)
    samples.push_back(boundary_samples(part.mesh, kSpacing * size, kInset * size));
  return samples;
}

AssemblyPlan plan_assembly(const std::vector<Part>& parts,
                           const std::vector<Vec3>& extra_directions, double tolerance_mm) {
  if (!(tolerance_mm >= 0.0) || !std::isfinite(tolerance_mm))
    throw Error(ErrorCode::InvalidOptions, "assembly tolerance_mm must be >= 0");
  const std::int32_t n = static_cast<std::int32_t>(parts.size());
  for (std::int32_t p = 0; p < n; ++p)
    if (parts[p].id != p) throw Error(ErrorCode::Internal, "parts: part ids must be 0..n-1");

  AssemblyPlan plan;
  plan.removal.resize(n);
  plan.blocks.assign(n, {});
  const Collisions collisions(parts, tolerance_mm);
  // --- disassembly: take out the smallest-id part that no remaining part blocks along its own
  // +-d; only when there is none, along the extra directions. A move once blocked by a part
  // stays blocked while that part remains: each (part, direction) keeps the blocker it found. ---
  const std::size_t num_directions = 2 + extra_directions.size();
  std::vector<std::vector<std::int32_t>> known_blocker(
      n, std::vector<std::int32_t>(num_directions, -1));
  auto direction = [&](std::int32_t p, std::size_t k) {
    return k < 2 ? (k == 0 ? parts[p].direction : Vec3(-parts[p].direction))
                 : extra_directions[k - 2];
  };
  std::vector<bool> remaining(n, true);
  std::vector<std::int32_t> removed;
  for (bool progress = true; progress;) {
    progress = false;
    for (const bool own : {true, false}) {
      for (std::int32_t p = 0; p < n && !progress; ++p) {
        if (!remaining[p]) continue;
        for (std::size_t k = own ? 0 : 2; k < (own ? 2 : num_directions); ++k) {
          // The extra directions may repeat the part's own, just found blocked.
          const Vec3 dir = direction(p, k);
          if (k >= 2 && (dir == parts[p].direction || dir == -parts[p].direction)) continue;
          std::int32_t& known = known_blocker[p][k];
          if (known >= 0 && remaining[known]) continue;
          known = collisions.blocker(p, dir, remaining);
          if (known >= 0) continue;
          plan.removal[p] = dir;
          remaining[p] = false;
          removed.push_back(p);
          progress = true;
          break;
        }
      }
      if (progress) break;
    }
  }
  for (std::int32_t p = 0; p < n; ++p) {
    if (remaining[p]) plan.removal[p] = parts[p].direction;
    plan.blocks[p] = collisions.blockers(p, plan.removal[p]);
  }
  plan.found = static_cast<std::int32_t>(removed.size()) == n;
  plan.blocked = n - static_cast<std::int32_t>(removed.size());
  plan.order.assign(removed.rbegin(), removed.rend());
  if (!plan.found) {
    plan.message = blocking_cycle(plan.blocks, remaining);
    for (std::int32_t p = 0; p < n; ++p)
      if (remaining[p]) plan.order.push_back(p);
  }
  return plan;
}

std::vector<std::vector<Obstruction>> obstructions(const std::vector<Part>& parts, std::int32_t p,
                                                   const std::vector<Vec3>& dirs,
                                                   double tolerance_mm) {
  if (!(tolerance_mm >= 0.0) || !std::isfinite(tolerance_mm))
    throw Error(ErrorCode::InvalidOptions, "assembly tolerance_mm must be >= 0");
  if (p < 0 || p >= static_cast<std::int32_t>(parts.size()))
    throw Error(ErrorCode::Internal, "parts: no part " + std::to_string(p));
  const Collisions collisions(parts, tolerance_mm);
  std::vector<std::vector<Obstruction>> out;
  for (const Vec3& dir : dirs) out.push_back(collisions.obstructions(p, dir));
  return out;
}

std::vector<Obstruction> obstructions(const std::vector<Part>& parts, std::int32_t p,
                                      const Vec3& dir, double tolerance_mm) {
  return std::move(obstructions(parts, p, std::vector<Vec3>{dir}, tolerance_mm).front());
}

namespace {

// Lines along a part's direction at the centres of square cells over its footprint's bounding
// rectangle, about `lines` of them, starting below the part.
struct LineGrid {
  Vec3 d, u, v;
  double spacing_mm = 0.0;
  std::int64_t nu = 1, nv = 1;
  Vec3 low{0, 0, 0};  // the box's low corner in (u, v, d)

  LineGrid(const Part& part, std::int64_t lines)
      : d(part.direction.normalized()), u(d.unitOrthogonal()), v(d.cross(u)) {
    Box3 box{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)};
    for (const Vec3& x : part.mesh.vertices) {
      const Vec3 local(x.dot(u), x.dot(v), x.dot(d));
      box.min = box.min.cwiseMin(local);
      box.max = box.max.cwiseMax(local);
    }
    const double width = box.max.x() - box.min.x(), depth = box.max.y() - box.min.y();
    spacing_mm =
        std::max(std::sqrt(width * depth / static_cast<double>(lines)), 1e-6 * (width + depth));
    nu = std::max<std::int64_t>(1, std::llround(std::ceil(width / spacing_mm)));
    nv = std::max<std::int64_t>(1, std::llround(std::ceil(depth / spacing_mm)));
    low = box.min;
  }
  std::int64_t size() const { return nu * nv; }
  Vec3 origin(std::int64_t k) const {
    return (low.x() + (static_cast<double>(k % nu) + 0.5) * spacing_mm) * u +
           (low.y() + (static_cast<double>(k / nu) + 0.5) * spacing_mm) * v + (low.z() - 1.0) * d;
  }
};

// The gaps of part p on the line origin + t * dir, bottom to top (see dhf_gaps()).
void line_gaps(const PartScene& scene, std::int32_t p, const Vec3& origin, const Vec3& dir,
               double epsilon_mm, std::vector<std::uint64_t>& hits,
               std::vector<Crossing>& crossings, std::vector<DhfGap>& out) {
  scene.crossings(origin, dir, hits, crossings);
  // The part's intervals along the line; repeated hits on a shared edge count once.
  bool inside = false;
  double left = -INFINITY;               // where the line last left the part
  double began = -INFINITY;              // where the line last entered it
  std::int32_t below = -1;               // the part the line was in just before that
  const Crossing* last_other = nullptr;  // the last crossing of another part's boundary
  for (const Crossing& c : crossings) {
    if (c.part != p) {
      last_other = &c;
      continue;
    }
    if (!c.exits && !inside) {
      inside = true;
      if (left > -INFINITY && deeper_than(scene, p, origin, dir, left, c.t_mm, epsilon_mm)) {
        std::int32_t met = -1;  // the first other part entered in the gap
        for (const Crossing& o : crossings)
          if (o.part != p && !o.exits && o.t_mm >= left && o.t_mm < c.t_mm) {
            met = o.part;
            break;
          }
        out.push_back(
            {met, origin + left * dir, origin + c.t_mm * dir, origin + began * dir, below});
      }
      // The part whose boundary the line leaves by where it enters (a shared face's hits come
      // in either order), else the one it is inside.
      began = c.t_mm;
      below = last_other && !last_other->exits ? last_other->part : -1;
      for (const Crossing& o : crossings)
        if (o.part != p && o.exits && std::abs(o.t_mm - c.t_mm) <= epsilon_mm) {
          below = o.part;
          break;
        }
    } else if (c.exits && inside) {
      inside = false;
      left = c.t_mm;
    }
  }
}

// Part p's gaps (see dhf_gaps()), on the lines of its grid.
std::vector<DhfGap> part_gaps(const PartScene& scene, const Part& part, std::int32_t p,
                              std::int64_t lines, double epsilon_mm) {
  if (part.mesh.vertices.empty()) return {};
  const LineGrid grid(part, lines);
  std::vector<std::vector<DhfGap>> per_line(static_cast<std::size_t>(grid.size()));
  tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, grid.size(), 1024),
                    [&](const tbb::blocked_range<std::int64_t>& range) {
                      std::vector<std::uint64_t> hits;
                      std::vector<Crossing> crossings;
                      for (std::int64_t k = range.begin(); k != range.end(); ++k)
                        line_gaps(scene, p, grid.origin(k), grid.d, epsilon_mm, hits, crossings,
                                  per_line[k]);
                    });
  std::vector<DhfGap> gaps;
  for (const std::vector<DhfGap>& line : per_line)
    gaps.insert(gaps.end(), line.begin(), line.end());
  return gaps;
}

}  // namespace

std::vector<std::vector<DhfGap>> dhf_gaps(const std::vector<Part>& parts, std::int64_t lines,
                                          double epsilon_mm) {
  detail::validate_gap_options(lines, epsilon_mm);
  const PartScene scene(meshes_of(parts));
  std::vector<std::vector<DhfGap>> gaps(parts.size());
  for (std::int32_t p = 0; p < static_cast<std::int32_t>(parts.size()); ++p)
    gaps[p] = part_gaps(scene, parts[p], p, lines, epsilon_mm);
  return gaps;
}

std::int32_t dhf_gap_count(const Part& part, std::int64_t lines, double epsilon_mm) {
  detail::validate_gap_options(lines, epsilon_mm);
  // Whether a stretch is a gap, and how deep, depends on the part's own boundary only.
  const PartScene scene({&part.mesh});
  return static_cast<std::int32_t>(part_gaps(scene, part, 0, lines, epsilon_mm).size());
}

namespace detail {

void validate_gap_options(std::int64_t lines, double epsilon_mm) {
  require_option(lines >= 1 && lines <= 100'000'000, "gap lines must be in 1..1e8");
  validate_epsilon(epsilon_mm);
}

namespace {

// Part p's stretches along a line, bottom to top, and whether each end lies on an interface.
struct PartStretch {
  double begin = 0.0, end = 0.0;
  bool inner = true;  // both ends on interfaces with other parts
};

std::vector<PartStretch> part_stretches(const std::vector<Part>& parts, std::int32_t p,
                                        const std::vector<Crossing>& crossings) {
  const std::vector<std::int32_t>& neighbor = parts[p].triangle_neighbor;
  // Every hit of p where the line crosses at t (several on a shared edge) must be an interface.
  auto inner_at = [&](double t) {
    const double tolerance = 1e-9 * (1.0 + std::abs(t));
    for (const Crossing& c : crossings)
      if (c.part == p && std::abs(c.t_mm - t) <= tolerance && neighbor[c.triangle] < 0)
        return false;
    return true;
  };
  std::vector<PartStretch> out;
  bool inside = false;
  for (const Crossing& c : crossings) {
    if (c.part != p) continue;
    if (!c.exits && !inside) {
      inside = true;
      out.push_back({c.t_mm, c.t_mm, inner_at(c.t_mm)});
    } else if (c.exits && inside) {
      inside = false;
      out.back().end = c.t_mm;
      out.back().inner = out.back().inner && inner_at(c.t_mm);
    }
  }
  if (inside) out.pop_back();  // inconsistent crossings: the line is left alone
  return out;
}

}  // namespace

CarveLines carve_lines(const std::vector<Part>& parts, std::int32_t p, std::int64_t lines,
                       double epsilon_mm) {
  const PartScene scene(meshes_of(parts));
  const LineGrid grid(parts[p], lines);
  CarveLines out;
  out.d = grid.d, out.u = grid.u, out.v = grid.v, out.spacing_mm = grid.spacing_mm;
  std::vector<std::optional<CarveLine>> per_line(static_cast<std::size_t>(grid.size()));
  tbb::parallel_for(
      tbb::blocked_range<std::int64_t>(0, grid.size(), 1024),
      [&](const tbb::blocked_range<std::int64_t>& range) {
        std::vector<std::uint64_t> hits;
        std::vector<Crossing> crossings;
        for (std::int64_t k = range.begin(); k != range.end(); ++k) {
          const Vec3 origin = grid.origin(k);
          scene.crossings(origin, grid.d, hits, crossings);
          const std::vector<PartStretch> stretches = part_stretches(parts, p, crossings);
          // Stretches closer than a deep gap form one group (each is one when no gap is deep:
          // such a line may border deep ones); the groups' first stretches.
          if (stretches.size() < 2) continue;
          std::vector<std::size_t> first{0}, every{0};
          for (std::size_t i = 1; i < stretches.size(); ++i) {
            const double t0 = stretches[i - 1].end, t1 = stretches[i].begin;
            if (deeper_than(scene, p, origin, grid.d, t0, t1, epsilon_mm)) first.push_back(i);
            every.push_back(i);
          }
          CarveLine line;
          line.deep = first.size() >= 2;
          if (!line.deep) first = std::move(every);
          auto inner = [&](std::size_t from, std::size_t to) {
            for (std::size_t i = from; i < to; ++i)
              if (!stretches[i].inner) return false;
            return true;
          };
          auto at = [&](double t) { return origin + t * grid.d; };
          const std::size_t second = first[1], last = first.back();
          line.iu = k % grid.nu, line.iv = k / grid.nu;
          line.gap = at(0.5 * (stretches[second - 1].end + stretches[second].begin));
          if (inner(second, stretches.size()))
            line.above = std::make_pair(line.gap, at(stretches.back().end));
          if (inner(0, last))
            line.below =
                std::make_pair(at(stretches.front().begin),
                               at(0.5 * (stretches[last - 1].end + stretches[last].begin)));
          // Filling: from the end of the first group to the beginning of the last, reaching a
          // little into both (so no sliver of the neighbour is left), when one part fills it.
          const double t0 = stretches[second - 1].end, t1 = stretches[last].begin;
          // The part entered where the gaps begin, which every crossing in them must be of.
          const double slack = 1e-9 * (1.0 + std::abs(t0) + std::abs(t1));
          std::int32_t only = -1;  // -1: none entered yet
          bool several = false;
          for (const Crossing& c : crossings)
            if (c.part != p && c.t_mm >= t0 - slack && c.t_mm <= t1 + slack) {
              if (only == -1 && !c.exits) only = c.part;
              if (c.part != only && c.t_mm > t0 + slack && c.t_mm < t1 - slack) several = true;
            }
          if (only >= 0 && !several) {
            const double reach =
                std::min({0.25 * epsilon_mm, 0.5 * (t0 - stretches[second - 1].begin),
                          0.5 * (stretches[last].end - t1)});
            line.fill = std::make_pair(at(t0 - reach), at(t1 + reach));
            line.fill_from = only;
          }
          // Yielding: the shorter of the first and last groups, to the part across its gap, else
          // to the one on its other side.
          const double first_length = stretches[second - 1].end - stretches.front().begin;
          const double last_length = stretches.back().end - stretches[last].begin;
          const bool yield_first = first_length <= last_length;
          const double inner_edge = yield_first ? stretches[second - 1].end : stretches[last].begin;
          const double outer_edge = yield_first ? stretches.front().begin : stretches.back().end;
          // The part the line enters at or after t (leaves at or before it, going down).
          auto next_part = [&](double t, bool up) {
            const double tolerance = 1e-9 * (1.0 + std::abs(t));
            std::int32_t found = -1;
            for (const Crossing& c : crossings) {
              if (c.part == p) continue;
              if (up && !c.exits && c.t_mm >= t - tolerance) return c.part;
              if (!up && c.exits && c.t_mm <= t + tolerance) found = c.part;
            }
            return found;
          };
          std::int32_t across = next_part(inner_edge, yield_first);
          if (across < 0) {  // the part on the group's other side, where it touches the group
            const std::int32_t beyond = next_part(outer_edge, !yield_first);
            for (const Crossing& c : crossings)
              if (c.part == beyond &&
                  std::abs(c.t_mm - outer_edge) <= 1e-9 * (1.0 + std::abs(outer_edge)))
                across = beyond;
          }
          if (across >= 0) {
            line.yield = yield_first
                             ? std::make_pair(at(stretches.front().begin - epsilon_mm), line.gap)
                             : std::make_pair(at(0.5 * (stretches[last - 1].end + inner_edge)),
                                              at(stretches.back().end + epsilon_mm));
            line.yield_to = across;
          }
          per_line[k] = line;
        }
      });
  for (std::optional<CarveLine>& line : per_line)
    if (line) out.lines.push_back(*line);
  return out;
}

}  // namespace detail

}  // namespace dhfcast
