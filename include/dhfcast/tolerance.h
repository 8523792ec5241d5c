// The undercut tolerance epsilon's rule, one for every stage of the pipeline (`dhfcast check`
// keeps its own, as an independent verifier).
#pragma once

#include <algorithm>
#include <cmath>

#include "dhfcast/error.h"
#include "dhfcast/types.h"

namespace dhfcast {

// The undercut tolerance must be a positive number of mm: the accessibility, the gap lines and
// the carving all need one. Throws Error{InvalidOptions} naming --epsilon otherwise.
inline void validate_epsilon(double epsilon_mm) {
  require_option(std::isfinite(epsilon_mm) && epsilon_mm > 0, "--epsilon must be > 0");
}

// Does the stretch (t0, t1) of the line origin + t * dir, whose ends lie on a surface, reach
// deeper than tolerance_mm from that surface? farther(p) says whether the point p is farther than
// tolerance_mm from it. A stretch no longer than 2 * tolerance_mm cannot: each of its points is
// within half its length of an end. A longer one is sampled as `dhfcast check` samples it: its
// middle first (the usual answer), then every tolerance / 2, at most 256 points. With a zero
// tolerance every stretch counts.
template <class Farther>
bool deeper_than(const Vec3& origin, const Vec3& dir, double t0, double t1, double tolerance_mm,
                 const Farther& farther) {
  const double length = t1 - t0;
  if (length <= 2 * tolerance_mm) return false;
  if (tolerance_mm == 0.0 || farther(origin + (t0 + 0.5 * length) * dir)) return true;
  const int n = static_cast<int>(std::min(256.0, std::ceil(length / (0.5 * tolerance_mm)) + 1));
  for (int q = 1; q + 1 < n; ++q)
    if (farther(origin + (t0 + length * q / (n - 1)) * dir)) return true;
  return false;
}

}  // namespace dhfcast
