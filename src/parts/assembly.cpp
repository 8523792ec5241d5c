#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/parts.h"

namespace dhfcast {
namespace {

// Where a ray crosses a part's boundary.
struct Crossing {
  double t_mm;
  std::int32_t part;
  bool exits;  // leaves the part (the face normal points along the ray)
};

// Embree context extended with the list that the filter callback fills.
struct CollectContext {
  RTCIntersectContext context;
  std::vector<std::uint64_t>* hits;  // part << 32 | triangle
};

// Records every hit and rejects it, so a single traversal reports all crossings.
void collect_hit(const RTCFilterFunctionNArguments* args) {
  if (args->valid[0] == 0) return;
  const auto* ctx = reinterpret_cast<const CollectContext*>(args->context);
  const RTCHit* hit = reinterpret_cast<const RTCHit*>(args->hit);
  ctx->hits->push_back((std::uint64_t{hit->geomID} << 32) | hit->primID);
  args->valid[0] = 0;
}

// One Embree scene holding every part's boundary; geometry id = part id.
class PartScene {
 public:
  explicit PartScene(const std::vector<Part>& parts) : parts_(parts) {
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw Error(ErrorCode::Internal, "parts: cannot create the ray tracing device");
    scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);  // no missed hits on shared edges
    for (const Part& part : parts) {
      const RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* vertices = static_cast<float*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                  3 * sizeof(float), part.mesh.vertices.size()));
      for (std::size_t v = 0; v < part.mesh.vertices.size(); ++v)
        for (int k = 0; k < 3; ++k)
          vertices[3 * v + k] = static_cast<float>(part.mesh.vertices[v][k]);
      auto* indices = static_cast<std::uint32_t*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                  3 * sizeof(std::uint32_t), part.mesh.triangles.size()));
      for (std::size_t f = 0; f < part.mesh.triangles.size(); ++f)
        for (int k = 0; k < 3; ++k)
          indices[3 * f + k] = static_cast<std::uint32_t>(part.mesh.triangles[f][k]);
      rtcSetGeometryIntersectFilterFunction(geom, collect_hit);
      rtcCommitGeometry(geom);
      rtcAttachGeometryByID(scene_, geom, static_cast<unsigned>(part.id));
      rtcReleaseGeometry(geom);
    }
    rtcCommitScene(scene_);
    if (rtcGetDeviceError(device_) != RTC_ERROR_NONE) {
      rtcReleaseScene(scene_);
      rtcReleaseDevice(device_);
      throw Error(ErrorCode::Internal, "parts: cannot build the ray tracing scene");
    }
  }
  ~PartScene() {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
  }
  PartScene(const PartScene&) = delete;
  PartScene& operator=(const PartScene&) = delete;

  // Every crossing of the ray origin + t * dir, t > 0, with the parts' boundaries, sorted by t.
  // Embree only finds the triangles; t and the side are computed in double precision. Faces
  // parallel to the ray are skipped: sliding along them is no crossing. Thread-safe.
  void crossings(const Vec3& origin, const Vec3& dir, std::vector<std::uint64_t>& hits,
                 std::vector<Crossing>& out) const {
    hits.clear();
    out.clear();
    CollectContext ctx;
    rtcInitIntersectContext(&ctx.context);
    ctx.hits = &hits;
    RTCRayHit rh{};
    rh.ray.org_x = static_cast<float>(origin.x());
    rh.ray.org_y = static_cast<float>(origin.y());
    rh.ray.org_z = static_cast<float>(origin.z());
    rh.ray.dir_x = static_cast<float>(dir.x());
    rh.ray.dir_y = static_cast<float>(dir.y());
    rh.ray.dir_z = static_cast<float>(dir.z());
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = 0xFFFFFFFFu;  // Debian's Embree is built with ray masks
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &ctx.context, &rh);
    for (const std::uint64_t h : hits) {
      const auto part = static_cast<std::int32_t>(h >> 32);
      const Tri& tri = parts_[part].mesh.triangles[static_cast<std::uint32_t>(h)];
      const std::vector<Vec3>& v = parts_[part].mesh.vertices;
      const Vec3 normal = (v[tri[1]] - v[tri[0]]).cross(v[tri[2]] - v[tri[0]]);
      const double along = normal.dot(dir);
      if (along == 0.0) continue;
      const double t_mm = normal.dot(v[tri[0]] - origin) / along;
      if (t_mm > 0.0) out.push_back({t_mm, part, along > 0.0});
    }
    std::sort(out.begin(), out.end(), [](const Crossing& a, const Crossing& b) {
      return a.t_mm != b.t_mm ? a.t_mm < b.t_mm : a.part < b.part;
    });
  }

 private:
  const std::vector<Part>& parts_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

// A point inside part `part`, from which a ray leaves along the part's direction.
struct Sample {
  Vec3 point;
  std::int32_t part;
};

// Barycentres of every tet of every part, plus one point just inside each boundary face (10 %
// of the way to its tet's barycentre: well clear of the face in float precision, close enough to
// catch thin obstacles the barycentres miss).
std::vector<Sample> part_samples(const TetMesh& tets, const std::vector<Part>& parts,
                                 const std::vector<std::int32_t>& part_of) {
  std::vector<Sample> samples;
  for (const Part& part : parts) {
    for (const std::int32_t t : part.tets) {
      const Tet& tet = tets.tets[t];
      const Vec3 centre = 0.25 * (tets.vertices[tet[0]] + tets.vertices[tet[1]] +
                                  tets.vertices[tet[2]] + tets.vertices[tet[3]]);
      samples.push_back({centre, part.id});
      for (int i = 0; i < 4; ++i) {
        const std::int32_t u = tets.neighbors[t][i];
        if (u >= 0 && part_of[u] == part.id) continue;
        const Vec3 face_centre =
            (tets.vertices[tet[kTetFaces[i][0]]] + tets.vertices[tet[kTetFaces[i][1]]] +
             tets.vertices[tet[kTetFaces[i][2]]]) /
            3.0;
        samples.push_back({face_centre + 0.1 * (centre - face_centre), part.id});
      }
    }
  }
  return samples;
}

// Parts whose interior the ray from a point of part `self` runs through over more than
// tolerance_mm, given its crossings sorted by t. entered_at (one slot per part, all -1) is
// scratch space, left all -1 again.
void mark_obstacles(const std::vector<Crossing>& crossings, std::int32_t self, double tolerance_mm,
                    std::vector<std::int32_t>& entered_at, std::vector<std::int32_t>& found) {
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
      if (c.t_mm - crossings[entry].t_mm > tolerance_mm) found.push_back(c.part);
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

}  // namespace

AssemblyPlan plan_assembly(const TetMesh& tets, const std::vector<Part>& parts,
                           double tolerance_mm) {
  if (!(tolerance_mm >= 0.0) || !std::isfinite(tolerance_mm))
    throw Error(ErrorCode::InvalidOptions, "assembly tolerance_mm must be >= 0");
  const std::int32_t n = static_cast<std::int32_t>(parts.size());
  std::vector<std::int32_t> part_of(tets.tets.size(), -1);
  for (std::int32_t p = 0; p < n; ++p) {
    if (parts[p].id != p) throw Error(ErrorCode::Internal, "parts: part ids must be 0..n-1");
    for (const std::int32_t t : parts[p].tets) part_of[t] = p;
  }
  if (tets.neighbors.size() != tets.tets.size())
    throw Error(ErrorCode::Internal, "parts: the tet mesh has no adjacency");

  // --- 1. blocking relation: rays from inside each part along +d and along -d ---
  // A part that is a DHF along d is one along -d too, and its mold does not care which way d
  // points, so a part may also go in and out along -d: the planner picks the sign.
  AssemblyPlan plan;
  plan.blocks.assign(n, {});
  std::vector<std::vector<std::int32_t>> blocks_reversed(n);
  if (n > 0) {
    const PartScene scene(parts);
    const std::vector<Sample> samples = part_samples(tets, parts, part_of);
    // Each thread gathers (sign, blocked, blocker) triples; sorted and deduplicated afterwards,
    // they do not depend on the thread schedule.
    tbb::enumerable_thread_specific<std::vector<std::uint64_t>> pairs;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        std::vector<std::uint64_t>& mine = pairs.local();
                        std::vector<std::uint64_t> hits;
                        std::vector<Crossing> crossings;
                        std::vector<std::int32_t> entered_at(n, -1), found;
                        for (std::size_t s = range.begin(); s != range.end(); ++s) {
                          const Sample& sample = samples[s];
                          for (const std::uint64_t reversed : {0u, 1u}) {
                            const Vec3& d = parts[sample.part].direction;
                            scene.crossings(sample.point, reversed ? Vec3(-d) : d, hits,
                                            crossings);
                            mark_obstacles(crossings, sample.part, tolerance_mm, entered_at,
                                           found);
                            for (const std::int32_t a : found)
                              mine.push_back((reversed << 62) |
                                             (std::uint64_t(sample.part) << 31) |
                                             std::uint32_t(a));
                          }
                        }
                      });
    std::vector<std::uint64_t> all;
    for (const auto& mine : pairs) all.insert(all.end(), mine.begin(), mine.end());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    for (const std::uint64_t triple : all) {
      const auto blocked = static_cast<std::int32_t>((triple >> 31) & 0x7FFFFFFFu);
      const auto blocker = static_cast<std::int32_t>(triple & 0x7FFFFFFFu);
      (triple >> 62 ? blocks_reversed : plan.blocks)[blocked].push_back(blocker);
    }
  }

  // --- 2. disassembly: take out the smallest-id part that no remaining part blocks, along +d
  // if it can, else along -d. Taking a part out never blocks another, so this greedy order
  // finds a complete order whenever one exists. ---
  std::vector<bool> remaining(n, true);
  std::vector<std::int32_t> removed;
  plan.reversed.assign(n, false);
  auto free_of = [&](const std::vector<std::int32_t>& blockers) {
    return std::none_of(blockers.begin(), blockers.end(),
                        [&](std::int32_t q) { return remaining[q]; });
  };
  for (bool progress = true; progress;) {
    progress = false;
    for (std::int32_t p = 0; p < n && !progress; ++p) {
      if (!remaining[p]) continue;
      const bool forward = free_of(plan.blocks[p]);
      if (forward || free_of(blocks_reversed[p])) {
        if (!forward) {
          plan.reversed[p] = true;
          std::swap(plan.blocks[p], blocks_reversed[p]);
        }
        remaining[p] = false;
        removed.push_back(p);
        progress = true;
      }
    }
  }
  plan.found = static_cast<std::int32_t>(removed.size()) == n;
  plan.order.assign(removed.rbegin(), removed.rend());
  if (!plan.found) {
    plan.message = blocking_cycle(plan.blocks, remaining);
    for (std::int32_t p = 0; p < n; ++p)
      if (remaining[p]) plan.order.push_back(p);
  }
  return plan;
}

}  // namespace dhfcast
