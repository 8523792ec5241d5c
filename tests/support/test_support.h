// Shared helpers for the tests: where real meshes are, and small analytic solids.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::test {

// Path of a mesh in CGAL's data set (e.g. "elephant.off"), or "" when the data set is absent.
std::string cgal_mesh(const std::string& name);
// Path of a model of the extended suite (e.g. "bunny.stl"), or "" when absent.
std::string extra_model(const std::string& name);
// The dhfcast executable.
std::string cli_path();
// A fresh, empty temporary folder, removed at exit of the process.
std::string temp_dir(const std::string& tag);

// Loads and validates a mesh, scaling it uniformly so its bounding-box diagonal is diag_mm
// (<= 0: no scaling).
TriMesh load_scaled(const std::string& path, double diag_mm);

// Solids made of the cells of a rectilinear grid: cell (i, j, k) spans
// [xs[i], xs[i+1]] x [ys[j], ys[j+1]] x [zs[k], zs[k+1]] and belongs to the solid when
// filled(i, j, k). Vertices are numbered in order of first use, cells visited i, j, k (k fastest).
using GridFilled = std::function<bool(int i, int j, int k)>;
// Boundary of the union of the filled cells: outward, welded, two triangles per exposed cell
// face. Filled cells must not meet only along an edge or at a vertex (non-manifold).
TriMesh grid_surface(const std::vector<double>& xs, const std::vector<double>& ys,
                     const std::vector<double>& zs, const GridFilled& filled);
// Tets of the same union: six positively oriented tets per filled cell, along its main diagonal
// (conforming across cells), consecutive per cell; adjacency built.
TetMesh grid_tets(const std::vector<double>& xs, const std::vector<double>& ys,
                  const std::vector<double>& zs, const GridFilled& filled);

// Axis-aligned box [min, max], 12 outward triangles.
TriMesh make_box(const Vec3& min, const Vec3& max);
// An open-top cup: box with a box-shaped cavity open at +z (outer size, wall thickness).
TriMesh make_cup(double size_mm, double wall_mm);

}  // namespace dhfcast::test

namespace dhfcast::test {

// Distance from p to triangle (a, b, c), mm.
double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);
// Largest distance from any of `points` to the surface `mesh` (brute force; small inputs only).
double max_distance_to_surface(const std::vector<Vec3>& points, const TriMesh& mesh);
// Empty when `mesh` is closed, every edge used exactly twice in opposite directions, each vertex
// a single fan of triangles, and its volume positive; otherwise what is wrong.
std::string solid_topology_problem(const TriMesh& mesh);

}  // namespace dhfcast::test
