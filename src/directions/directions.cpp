#include "dhfcast/directions.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "dhfcast/error.h"

namespace dhfcast {

std::vector<Vec3> fibonacci_directions(std::int32_t n) {
  if (n < 1) throw Error(ErrorCode::InvalidOptions, "directions: count must be at least 1");
  std::vector<Vec3> dirs;
  dirs.reserve(static_cast<std::size_t>(n));
  for (std::int32_t i = 0; i < n; ++i) {
    // Keinert et al. 2015: equal-area bands in z, golden-ratio spiral in phi.
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double golden = i * std::numbers::phi;
    const double phi = 2.0 * std::numbers::pi * (golden - std::floor(golden));
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    dirs.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
  }
  return dirs;
}

}  // namespace dhfcast
