// Morton (Z-order) codes: sorting points by them keeps neighbours in space close in memory.
#pragma once

#include <algorithm>
#include <cstdint>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// Spreads the low 21 bits of x to every third bit.
inline std::uint64_t spread_bits(std::uint64_t x) {
  x &= 0x1FFFFF;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

// 63-bit Morton code of p within `box`.
inline std::uint64_t morton_code(const Vec3& p, const Box3& box) {
  const Vec3 extent = (box.max - box.min).cwiseMax(Vec3::Constant(1e-12));
  const Vec3 u = (p - box.min).cwiseQuotient(extent);
  std::uint64_t c = 0;
  for (int k = 0; k < 3; ++k)
    c |= spread_bits(static_cast<std::uint64_t>(std::clamp(u[k], 0.0, 1.0) * 2097151.0)) << k;
  return c;
}

}  // namespace dhfcast::detail
