#include <bit>

#include "dhfcast/access.h"

namespace dhfcast {

DirectionBits::DirectionBits(std::int32_t num_tets, std::int32_t num_directions)
    : num_tets_(num_tets),
      num_directions_(num_directions),
      words_per_tet_((num_directions + 63) / 64),
      words_(static_cast<std::size_t>(num_tets) * words_per_tet_, 0) {}

void DirectionBits::set(std::int32_t tet, std::int32_t direction, bool value) {
  std::uint64_t& w = row(tet)[direction >> 6];
  const std::uint64_t bit = std::uint64_t{1} << (direction & 63);
  w = value ? (w | bit) : (w & ~bit);
}

std::int32_t DirectionBits::count(std::int32_t tet) const {
  std::int32_t n = 0;
  const std::uint64_t* r = row(tet);
  for (std::int32_t i = 0; i < words_per_tet_; ++i) n += std::popcount(r[i]);
  return n;
}

}  // namespace dhfcast
