// DHF-accessibility of every tet for every direction (paper §4.1), its erosion (§4.3.1), the
// distance to the infeasible region (§4.2.1) and seam visibility (§4.2.2).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast {

// Options for compute_accessibility().
struct AccessibilityOptions {
  double epsilon_mm = 0.4;  // undercut tolerance: a stretch of the ray beyond its first exit that
                            // stays within this distance of the surface is ignored (paper Fig. 5)

  // Throws Error{InvalidOptions} unless epsilon_mm > 0 (validate_epsilon()).
  void validate() const;
};

// One bit per (tet, direction), stored as a row of 64-bit words per tet.
class DirectionBits {
 public:
  DirectionBits() = default;
  DirectionBits(std::int32_t num_tets, std::int32_t num_directions);
  bool get(std::int32_t tet, std::int32_t direction) const {
    return (words_[static_cast<std::size_t>(tet) * words_per_tet_ + (direction >> 6)] >>
            (direction & 63)) & 1u;
  }
  void set(std::int32_t tet, std::int32_t direction, bool value);
  std::int32_t num_tets() const { return num_tets_; }
  std::int32_t num_directions() const { return num_directions_; }
  std::int32_t words_per_tet() const { return words_per_tet_; }
  // The row of tet t: words_per_tet() words, bit d of the row is direction d.
  std::uint64_t* row(std::int32_t tet) {
    return words_.data() + static_cast<std::size_t>(tet) * words_per_tet_;
  }
  const std::uint64_t* row(std::int32_t tet) const {
    return words_.data() + static_cast<std::size_t>(tet) * words_per_tet_;
  }
  // Number of directions set for tet t.
  std::int32_t count(std::int32_t tet) const;

 private:
  std::int32_t num_tets_ = 0, num_directions_ = 0, words_per_tet_ = 0;
  std::vector<std::uint64_t> words_;
};

// A surface edge of the tet mesh whose two boundary faces belong to different tets: a place
// where a seam between two parts can run (paper §4.2.2, the surface-seam term).
struct SeamEdge {
  std::int32_t tet_a = -1, tet_b = -1;  // owners of the two boundary faces, tet_a < tet_b
  double length_mm = 0.0;
  double visibility = 0.0;  // normalized ambient occlusion: 0 on the most occluded edge, 1 on the
                            // least occluded one (the paper's AO(e))
};

// Everything the segmentation needs from the accessibility analysis.
struct AccessibilityField {
  DirectionBits feasible;  // tet t is DHF-accessible along direction d (all 15 samples are)
  DirectionBits eroded;    // feasible and every vertex-adjacent tet is feasible (§4.3.1)
  std::vector<SeamEdge> seam_edges;
  // Ray queries, for benchmarks: per direction, a quick test of every sample plus a full
  // crossing query for each unsettled sample of a still-feasible tet; 64 rays per seam edge.
  std::int64_t rays_cast = 0;
};

// Computes DHF-accessibility: tet t is accessible along d when each of its 15 samples (4
// vertices, 6 edge midpoints, 4 face barycentres, barycentre; shared samples computed once) is:
// the ray from the sample along d, after it first leaves the solid, stays within epsilon of the
// surface until its last exit. Rays hit the exact `surface`, not the tet boundary. A sample that
// lies just outside the surface (tet boundaries approximate it) counts as on the surface.
// Also computes the erosion and the seam edges with their visibility.
// Pre: `surface` is a valid solid, `tets` has adjacency. Throws Error{InvalidOptions} when
// opts.validate() does or `directions` is empty.
AccessibilityField compute_accessibility(const TriMesh& surface, const TetMesh& tets,
                                         const std::vector<Vec3>& directions,
                                         const AccessibilityOptions& opts = {},
                                         const Progress& progress = {});

// dist_d(t) for one direction d (paper §4.2.1): for every tet, the distance (mm) from its
// barycentre to the nearest barycentre of a tet that is not feasible for d, measured along
// paths through face-adjacent tets. Capped at max_mm (tets farther away, or with no infeasible
// tet at all, get max_mm). The steps between adjacent barycentres are measured once, for every
// direction asked (the segmentation asks for hundreds).
class InfeasibleDistance {
 public:
  // Keeps a reference to `tets`, which must have adjacency and outlive it.
  explicit InfeasibleDistance(const TetMesh& tets);
  std::vector<float> operator()(const DirectionBits& feasible, std::int32_t direction,
                                double max_mm) const;

 private:
  const TetMesh& tets_;
  std::vector<std::array<double, 4>> step_mm_;  // per tet and face: to that neighbour's barycentre
};

}  // namespace dhfcast
