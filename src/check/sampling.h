// Private to check: seeded random numbers and point samples on surfaces.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// Uniform numbers from std::mt19937_64 with our own mapping, so figures do not depend on the
// standard library's distributions.
class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}
  // Uniform in [0, 1).
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }

 private:
  std::mt19937_64 engine_;
};

// An independent seed for stream `stream` of a run seeded with `seed` (splitmix64), so that each
// check and each part draws its own numbers whatever else runs.
std::uint64_t stream_seed(std::uint64_t seed, std::uint64_t stream);

// A point on a surface with its triangle and that triangle's unit outward normal.
struct SurfaceSample {
  Vec3 point;
  Vec3 normal;
  std::int32_t triangle = 0;
};

// `count` points uniform over the surface's area.
std::vector<SurfaceSample> sample_surface(const TriMesh& mesh, std::int64_t count, Random& random);

// One sample per vertex used by a non-degenerate triangle: the vertex moved 0.1 % of the way
// towards the centroid of its first triangle, so that it lies on that triangle and not on an
// edge.
std::vector<SurfaceSample> vertex_samples(const TriMesh& mesh);

// Moves each sample `depth_mm` against its normal (into the solid).
void push_inside(std::vector<SurfaceSample>& samples, double depth_mm);

// Unit vectors u, v with (u, v, d) orthonormal. Pre: d is a unit vector.
void perpendicular_basis(const Vec3& d, Vec3& u, Vec3& v);

// q-quantile (0 <= q <= 1) of `values` by nearest rank; 0 when empty.
double quantile(std::vector<double> values, double q);

}  // namespace dhfcast::detail
