#include "ray_scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "dhfcast/error.h"

namespace dhfcast::detail {

namespace {

// A triangle's corners side by side: a distance query reads one record, not three scattered
// vertices.
struct TriCorners {
  Vec3 a, b, c;
};

struct DistanceQuery {
  const std::vector<std::vector<TriCorners>>* tris;  // per surface
  Vec3 p;
  double best;
  bool any;           // stop at the first triangle closer than the radius
  std::int32_t only;  // the one surface looked at; -1: all
};

bool shrink_to_triangle(RTCPointQueryFunctionArguments* args) {
  auto* q = static_cast<DistanceQuery*>(args->userPtr);
  if (q->only >= 0 && args->geomID != static_cast<unsigned>(q->only)) return false;
  const TriCorners& t = (*q->tris)[args->geomID][args->primID];
  const double d = (closest_on_triangle(q->p, t.a, t.b, t.c) - q->p).norm();
  if (d >= q->best) return false;
  q->best = d;
  args->query->radius = q->any ? 0.0f : static_cast<float>(d);
  return true;
}

RTCRay make_ray(const Vec3& origin, const Vec3& dir) {
  RTCRay ray;
  ray.org_x = static_cast<float>(origin.x());
  ray.org_y = static_cast<float>(origin.y());
  ray.org_z = static_cast<float>(origin.z());
  ray.dir_x = static_cast<float>(dir.x());
  ray.dir_y = static_cast<float>(dir.y());
  ray.dir_z = static_cast<float>(dir.z());
  ray.tnear = 0.0f;
  ray.tfar = std::numeric_limits<float>::infinity();
  ray.time = 0.0f;
  ray.mask = 0xFFFFFFFFu;  // Debian's Embree is built with ray masks: 0 would hit nothing
  ray.id = 0;
  ray.flags = 0;
  return ray;
}

// Embree's context, extended with the list that collect_hit() fills.
struct CollectContext {
  RTCIntersectContext context;
  std::vector<std::uint64_t>* hits;  // surface << 32 | triangle
};

// Records every hit and rejects it, so a single traversal reports all of them. Set on every
// geometry, but only all_hits() traces rays that report hits (escapes() tests occlusion).
void collect_hit(const RTCFilterFunctionNArguments* args) {
  if (args->valid[0] == 0) return;
  const auto* ctx = reinterpret_cast<const CollectContext*>(args->context);
  const RTCHit* hit = reinterpret_cast<const RTCHit*>(args->hit);
  ctx->hits->push_back((std::uint64_t{hit->geomID} << 32) | hit->primID);
  args->valid[0] = 0;
}

}  // namespace

struct RayScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<std::vector<TriCorners>> tris;  // per surface, for exact distances
};

RayScene::RayScene(const TriMesh& surface) : RayScene({&surface}, true) {}

RayScene::RayScene(const std::vector<const TriMesh*>& surfaces) : RayScene(surfaces, false) {}

RayScene::RayScene(const std::vector<const TriMesh*>& surfaces, bool many_rays)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  Box3 box{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)};
  for (const TriMesh* surface : surfaces) {
    std::vector<TriCorners>& tris = m.tris.emplace_back();
    tris.reserve(surface->triangles.size());
    for (const Tri& t : surface->triangles)
      tris.push_back({surface->vertices[t[0]], surface->vertices[t[1]], surface->vertices[t[2]]});
    for (const Vec3& v : surface->vertices) {
      box.min = box.min.cwiseMin(v);
      box.max = box.max.cwiseMax(v);
    }
  }
  diagonal_mm_ = box.min.x() <= box.max.x() ? box.diagonal() : 0.0;

  m.device = rtcNewDevice(nullptr);
  if (!m.device) throw Error(ErrorCode::Internal, "access: cannot create the Embree device");
  m.scene = rtcNewScene(m.device);
  rtcSetSceneFlags(m.scene, RTC_SCENE_FLAG_ROBUST);
  if (many_rays) rtcSetSceneBuildQuality(m.scene, RTC_BUILD_QUALITY_HIGH);
  for (std::size_t s = 0; s < surfaces.size(); ++s) {
    const TriMesh& surface = *surfaces[s];
    RTCGeometry geom = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (many_rays) rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0,
                                                           RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                           surface.vertices.size()));
    auto* ib = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(unsigned), surface.triangles.size()));
    if (!vb || !ib) throw Error(ErrorCode::Internal, "access: cannot allocate the Embree buffers");
    for (std::size_t i = 0; i < surface.vertices.size(); ++i)
      for (int k = 0; k < 3; ++k) vb[3 * i + k] = static_cast<float>(surface.vertices[i][k]);
    for (std::size_t i = 0; i < surface.triangles.size(); ++i)
      for (int k = 0; k < 3; ++k) ib[3 * i + k] = static_cast<unsigned>(surface.triangles[i][k]);
    rtcSetGeometryIntersectFilterFunction(geom, collect_hit);
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(m.scene, geom, static_cast<unsigned>(s));
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(m.scene);
  if (rtcGetDeviceError(m.device) != RTC_ERROR_NONE)
    throw Error(ErrorCode::Internal, "access: Embree could not build the surface BVH");
}

RayScene::~RayScene() {
  if (impl_->scene) rtcReleaseScene(impl_->scene);
  if (impl_->device) rtcReleaseDevice(impl_->device);
}

double RayScene::distance_below(const Vec3& p, double radius_mm) const {
  return point_query(p, radius_mm, false, -1);
}

bool RayScene::near(const Vec3& p, double radius_mm) const {
  return point_query(p, radius_mm, true, -1) < radius_mm;
}

bool RayScene::near(std::int32_t surface, const Vec3& p, double radius_mm) const {
  return point_query(p, radius_mm, true, surface) < radius_mm;
}

double RayScene::point_query(const Vec3& p, double radius_mm, bool any, std::int32_t only) const {
  DistanceQuery q{&impl_->tris, p, radius_mm, any, only};
  RTCPointQuery query;
  query.x = static_cast<float>(p.x());
  query.y = static_cast<float>(p.y());
  query.z = static_cast<float>(p.z());
  query.time = 0.0f;
  query.radius = static_cast<float>(radius_mm);
  RTCPointQueryContext ctx;
  rtcInitPointQueryContext(&ctx);
  rtcPointQuery(impl_->scene, &query, &ctx, shrink_to_triangle, &q);
  return q.best;
}

bool RayScene::escapes(const Vec3& origin, const Vec3& dir) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay ray = make_ray(origin, dir);
  rtcOccluded1(impl_->scene, &ctx, &ray);
  return ray.tfar >= 0.0f;  // Embree sets tfar to -inf on a hit
}

void RayScene::all_hits(const Vec3& origin, const Vec3& dir,
                        std::vector<std::uint64_t>& hits) const {
  hits.clear();
  CollectContext ctx;
  rtcInitIntersectContext(&ctx.context);
  ctx.hits = &hits;
  RTCRayHit rh{};
  rh.ray = make_ray(origin, dir);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &ctx.context, &rh);
  std::sort(hits.begin(), hits.end());
  hits.erase(std::unique(hits.begin(), hits.end()), hits.end());
}

}  // namespace dhfcast::detail
