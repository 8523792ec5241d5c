// The candidate casting directions.
#pragma once

#include <cstdint>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast {

// n unit vectors spread uniformly over the sphere (spherical Fibonacci points, Keinert et al.
// 2015). Deterministic. Throws Error{InvalidOptions} when n < 1.
std::vector<Vec3> fibonacci_directions(std::int32_t n);

}  // namespace dhfcast
