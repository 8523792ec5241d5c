// The 15 accessibility samples of every tet (paper §4.1), each shared sample stored once.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// Sample kinds, in the order they are stored and evaluated.
enum SampleKind { kVertexSample = 0, kEdgeSample, kFaceSample, kTetSample, kNumSampleKinds };

struct TetSamples {
  std::vector<Vec3> points;  // grouped by kind, Morton-ordered within a kind
  // Samples of kind k are [kind_begin[k], kind_begin[k + 1]).
  std::array<std::int32_t, kNumSampleKinds + 1> kind_begin{};
  // Sample ids of each tet: slots 0-3 vertices, 4-9 edge midpoints, 10-13 face barycentres,
  // 14 the barycentre.
  std::vector<std::array<std::int32_t, 15>> of_tet;
};

// Slots of of_tet holding samples of kind k: [kSlotBegin[k], kSlotBegin[k + 1]).
inline constexpr std::array<int, kNumSampleKinds + 1> kSlotBegin = {0, 4, 10, 14, 15};

// Builds the samples of `tets`: a vertex by its index, an edge by its sorted vertex pair, a face
// by its sorted vertex triple, so that neighbouring tets share them.
TetSamples tet_samples(const TetMesh& tets);

}  // namespace dhfcast::detail
