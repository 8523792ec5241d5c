// Closest-point and ray queries against triangle surfaces. Owns the Embree device and BVH; this
// pair of files is the only place that sees Embree.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

class RayScene {
 public:
  // Builds the BVH of `surface` (outward triangles) for many rays: a slower build with spatial
  // splits. Throws Error{Internal} when Embree fails.
  explicit RayScene(const TriMesh& surface);
  // One BVH over several surfaces, surface i being number i in the queries, built quickly (no
  // spatial splits), for a scene that serves fewer rays. The surfaces must outlive the scene.
  explicit RayScene(const std::vector<const TriMesh*>& surfaces);
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  // Distance from p to the surface when it is below radius_mm, radius_mm otherwise. Thread-safe.
  double distance_below(const Vec3& p, double radius_mm) const;
  // Is the surface closer than radius_mm to p? Faster than distance_below(). Thread-safe.
  bool near(const Vec3& p, double radius_mm) const;
  // Is surface number `surface` closer than radius_mm to p? Thread-safe.
  bool near(std::int32_t surface, const Vec3& p, double radius_mm) const;
  // True when the ray origin + t * dir, t >= 0, misses the surface. Thread-safe.
  bool escapes(const Vec3& origin, const Vec3& dir) const;
  // Every triangle that the ray origin + t * dir, t >= 0, meets, in no particular order, as
  // surface << 32 | triangle, into `hits` (cleared first). Each comes once: a triangle split
  // among several BVH leaves is reported once per leaf, so the hits are made unique. Thread-safe.
  void all_hits(const Vec3& origin, const Vec3& dir, std::vector<std::uint64_t>& hits) const;
  double diagonal_mm() const { return diagonal_mm_; }

 private:
  RayScene(const std::vector<const TriMesh*>& surfaces, bool many_rays);
  double point_query(const Vec3& p, double radius_mm, bool any, std::int32_t only) const;

  struct Impl;
  std::unique_ptr<Impl> impl_;
  double diagonal_mm_ = 0.0;
};

}  // namespace dhfcast::detail
