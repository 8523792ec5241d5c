// Mesh input and output: read STL/OBJ/PLY/OFF, weld, validate, write binary STL.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "dhfcast/types.h"

namespace dhfcast {

// Options for load_solid().
struct LoadOptions {
  double scale = 1.0;        // multiply coordinates by this after reading (after the units factor)
  double units_to_mm = 1.0;  // size of one file unit in mm (e.g. 25.4 for inches)
  // When > 0: scale uniformly so that the longest side of the bounding box is this many mm
  // (scale and units_to_mm are then ignored: files come in any unit).
  double size_mm = 0.0;
};

// What validate_mesh() found. Counts are zero for a valid solid; first_problem names a location
// (e.g. "edge (v12, v40)", "triangle 7", vertex indices into the checked mesh).
struct MeshDiagnostics {
  std::int64_t boundary_edges = 0;        // edges used by one triangle
  std::int64_t nonmanifold_edges = 0;     // edges used by three or more triangles
  std::int64_t nonmanifold_vertices = 0;  // vertices whose triangles form several fans
  std::int64_t misoriented_edges = 0;     // edges used twice in the same direction
  std::int64_t degenerate_triangles = 0;  // zero area, repeated vertices
  std::int64_t intersecting_pairs = 0;    // triangle pairs that cross (exact predicates); the
                                          // search stops at 100 pairs, and is skipped when an
                                          // earlier check already failed
  std::int64_t nonfinite_vertices = 0;    // NaN or infinite coordinates
  double volume_mm3 = 0.0;                // signed volume (valid solids: > 0)
  std::string first_problem;              // one line describing the first problem found
  bool ok() const { return first_problem.empty(); }
};

// Reads a triangle soup from STL (binary or ASCII), OBJ, PLY (ASCII or binary) or OFF, chosen by
// the file's extension (case-insensitive). Polygons are fan-triangulated. Coincident vertices
// (identical coordinates) are welded and unused vertices dropped.
// Throws Error{Io} when the file does not exist, is not a regular file or cannot be opened,
// Error{InvalidInput} when it is larger than 2 GiB, or with the file name and a location (line
// number, byte offset, triangle index) when it is malformed or truncated.
TriMesh read_mesh(const std::string& path);

// Checks that `mesh` bounds a solid: closed, 2-manifold (edges and vertices), consistently
// oriented, no degenerate triangles, no self-intersections, finite coordinates, non-zero volume.
// Orientation sign is not a problem here: a negative volume is reported in volume_mm3 only.
// Pre: vertices are welded (as read_mesh() returns them).
MeshDiagnostics validate_mesh(const TriMesh& mesh);

// What keeps `mesh` from being a part of a decomposition, or "": as validate_mesh(), but a part
// may touch itself along edges and at vertices (its welded mesh is then non-manifold there) as
// long as the directed uses of every edge cancel.
std::string part_solid_problem(const TriMesh& mesh);

// Pairs of triangles of `mesh` (ascending indices, at most max_pairs pairs) that intersect other
// than along the vertices or edge they share; exact predicates. Where `mesh` is not a surface mesh
// (an edge in three triangles, a pinched vertex, an edge used twice in one orientation), each
// fan there gets its own copy of the vertex or edge, and the contact counts as an intersection.
std::vector<std::array<std::int32_t, 2>> intersecting_triangles(const TriMesh& mesh,
                                                                unsigned max_pairs);

// Result of load_solid().
struct LoadedSolid {
  TriMesh mesh;          // welded, scaled, outward oriented
  bool flipped = false;  // the file was consistently inward oriented and was flipped
};

// read_mesh() + scaling + validate_mesh(); flips a globally inverted mesh (and says so in the
// result). Throws Error{InvalidInput} with "PATH: <first problem>" when the mesh is not a valid
// solid, when it is several solids (more than one shell facing outward, or an inward one outside
// the outer shell; inward shells inside it are cavities, and fine), or when it is absurdly scaled
// (bounding-box diagonal outside [0.1 mm, 100 m]).
LoadedSolid load_solid(const std::string& path, const LoadOptions& opts = {});

// Writes a binary STL (float32, per-triangle normals). Throws Error{Io}.
void write_stl(const std::string& path, const TriMesh& mesh);

}  // namespace dhfcast
