// Closest-point and occlusion queries against a triangle surface. Owns the Embree device and
// BVH; this pair of files is the only place that sees Embree.
#pragma once

#include <memory>

#include "dhfcast/types.h"

namespace dhfcast::detail {

class RayScene {
 public:
  // Builds the BVH of `surface` (outward triangles). Throws Error{Internal} when Embree fails.
  explicit RayScene(const TriMesh& surface);
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  // Distance from p to the surface when it is below radius_mm, radius_mm otherwise. Thread-safe.
  double distance_below(const Vec3& p, double radius_mm) const;
  // Is the surface closer than radius_mm to p? Faster than distance_below(). Thread-safe.
  bool near(const Vec3& p, double radius_mm) const;
  // True when the ray origin + t * dir, t >= 0, misses the surface. Thread-safe.
  bool escapes(const Vec3& origin, const Vec3& dir) const;
  double diagonal_mm() const { return diagonal_mm_; }

 private:
  double point_query(const Vec3& p, double radius_mm, bool any) const;

  struct Impl;
  std::unique_ptr<Impl> impl_;
  double diagonal_mm_ = 0.0;
};

}  // namespace dhfcast::detail
