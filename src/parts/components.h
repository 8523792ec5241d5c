// Private to parts: face-connected components of equally labeled tets, which become the parts.
#pragma once

#include <cstdint>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// Splits the tets into face-connected components of equal (region, label). Components are
// numbered by their smallest tet. Pre: tets has adjacency; one label and region per tet.
std::vector<std::int32_t> label_components(const TetMesh& tets,
                                           const std::vector<std::int32_t>& label,
                                           const std::vector<std::int32_t>& region,
                                           std::int32_t& num_components);

}  // namespace dhfcast::detail
