// Tetrahedralization of the input volume at a chosen size.
#pragma once

#include <cstdint>

#include "dhfcast/types.h"

namespace dhfcast {

// Options for tetrahedralize().
struct TetOptions {
  std::int32_t target_tets = 50000;  // aimed-for number of tets (the result is within ~30 %,
                                     // or above when facet_distance_mm needs more boundary tets)
  double facet_distance_mm = 0.1;    // max distance of boundary facets from the input surface
  std::uint32_t seed = 1;            // the mesher's random seed (deterministic output)
  // A meshing run that takes longer is stopped with an error (a runaway, not a result that
  // depends on the machine's speed). 0: 60 s plus 2 ms per target tet.
  double max_mesher_seconds = 0.0;

  // Throws Error{InvalidOptions} naming the first option out of range.
  void validate() const;
};

// Meshes the volume bounded by `surface` with quality tets (CGAL Mesh_3, sliver exudation) whose
// size is chosen so their count is close to opts.target_tets, whatever the input's triangle
// count. Sharp input edges (dihedral angle above 70 degrees) are kept. The boundary approximates
// the input surface; TetMesh::boundary_tolerance_mm reports the largest distance of a boundary
// face's vertex or centroid from the input surface. Tets are positively oriented, vertices are
// all used, adjacency is filled. The output depends only on the input and opts (sequential
// mesher, seeded random).
// Pre: `surface` passes validate_mesh() and is outward oriented. Throws
// Error{InvalidOptions} when opts.validate() does;
// Error{TetrahedralizationFailed} when the surface encloses no volume, the mesher fails or its tets
// are not one connected volume with a closed boundary (e.g. the input is several separate solids).
TetMesh tetrahedralize(const TriMesh& surface, const TetOptions& opts = {});

}  // namespace dhfcast
