// Private bridge to CGAL Mesh_3: only cgal_volume_mesher.cpp sees CGAL.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// Mesh_3 criteria, in mm. Angles and the radius-edge ratio are fixed inside the mesher.
struct MeshSizes {
  double facet_size_mm = 0.0;      // upper bound on the surface Delaunay ball radius
  double facet_distance_mm = 0.0;  // upper bound on a facet's distance from the input surface
  double cell_size_mm = 0.0;       // upper bound on a tet's circumradius
};

// What one meshing run made.
struct RefineResult {
  std::int64_t tets = 0;   // tets in the complex
  bool capped = false;     // the run stopped at its vertex budget: the mesh is unfinished
  bool timed_out = false;  // the run stopped at its time budget: the mesh is unfinished
};

// Owns the meshing domain (built once from the input surface) and the last mesh made from it,
// so a size calibration can rerun the mesher without rebuilding the domain's AABB tree.
class VolumeMesher {
 public:
  // Builds the polyhedral domain. Pre: `surface` is a closed, outward, 2-manifold mesh.
  VolumeMesher(const TriMesh& surface, std::uint32_t seed);
  ~VolumeMesher();
  VolumeMesher(const VolumeMesher&) = delete;
  VolumeMesher& operator=(const VolumeMesher&) = delete;

  // Meshes the volume afresh with these sizes (the same seed every time), stopping when the
  // triangulation reaches `max_vertices` (feature protection included) or after `max_seconds`.
  // Throws Error{Stopped} when request_stop() is called meanwhile.
  RefineResult refine(const MeshSizes& sizes, std::size_t max_vertices, double max_seconds);
  // Removes slivers from the last mesh (sliver exudation, deterministic: no time limit).
  void exude();
  // The last mesh's tets in the complex, vertices compactly numbered. Orientation as CGAL gives it.
  TetMesh extract() const;
  // Largest distance (mm) of any of `points` from the input surface.
  double max_distance_to_surface(const std::vector<Vec3>& points) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dhfcast::detail
