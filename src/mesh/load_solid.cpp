// load_solid(): read, scale to mm, validate, orient outward.
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"

namespace dhfcast {

namespace {

// Outside this range the units are almost certainly wrong (e.g. metres read as mm).
constexpr double kMinDiagonalMm = 0.1;
constexpr double kMaxDiagonalMm = 100000.0;

void check_factor(const char* name, double value) {
  if (!std::isfinite(value) || value <= 0.0) {
    char text[64];
    std::snprintf(text, sizeof text, "%g", value);
    throw Error(ErrorCode::InvalidOptions,
                std::string(name) + " must be a positive finite number, got " + text);
  }
}

// Generalized winding number of the closed surface `triangles` around p: 1 inside, 0 outside
// (sum of the triangles' solid angles, Van Oosterom and Strackee).
double winding_number(const TriMesh& mesh, const std::vector<std::int32_t>& triangles,
                      const Vec3& p) {
  double sum = 0.0;
  for (std::int32_t t : triangles) {
    const Vec3 a = mesh.vertices[mesh.triangles[t][0]] - p,
               b = mesh.vertices[mesh.triangles[t][1]] - p,
               c = mesh.vertices[mesh.triangles[t][2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    sum += 2.0 * std::atan2(a.dot(b.cross(c)),
                            la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb);
  }
  return sum / (4.0 * M_PI);
}

// "" when the outward mesh is one solid: one shell facing outward, and any others facing inward
// inside it (the walls of cavities). Else what is wrong. Pre: validated (closed, manifold, no
// self-intersections), so shells share no vertex and do not cross.
std::string shells_problem(const TriMesh& mesh) {
  std::vector<std::int32_t> root(mesh.vertices.size());
  std::iota(root.begin(), root.end(), 0);
  auto find = [&](std::int32_t v) {
    while (root[v] != v) v = root[v] = root[root[v]];
    return v;
  };
  for (const Tri& t : mesh.triangles) {
    const std::int32_t r = find(t[0]);
    root[find(t[1])] = r;
    root[find(t[2])] = r;
  }
  std::map<std::int32_t, std::vector<std::int32_t>> shells;  // root -> its triangles
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    shells[find(mesh.triangles[t][0])].push_back(static_cast<std::int32_t>(t));
  if (shells.size() == 1) return {};

  std::vector<const std::vector<std::int32_t>*> outward, inward;
  for (const auto& [r, triangles] : shells) {
    double six_v = 0.0;
    for (std::int32_t t : triangles) {
      const Tri& tri = mesh.triangles[t];
      six_v += mesh.vertices[tri[0]].dot(mesh.vertices[tri[1]].cross(mesh.vertices[tri[2]]));
    }
    (six_v > 0 ? outward : inward).push_back(&triangles);
  }
  const std::string count = "has " + std::to_string(shells.size()) + " separate shells";
  if (outward.size() > 1)
    return count + ", " + std::to_string(outward.size()) +
           " of them facing outward (disjoint or nested solids); decompose one solid at a time";
  for (const auto* cavity : inward)
    if (winding_number(mesh, *outward.front(), mesh.vertices[mesh.triangles[cavity->front()][0]]) <
        0.5)
      return count + ": one faces inward but lies outside the outer one";
  return {};
}

}  // namespace

LoadedSolid load_solid(const std::string& path, const LoadOptions& opts) {
  check_factor("scale", opts.scale);
  check_factor("units_to_mm", opts.units_to_mm);
  if (opts.size_mm != 0.0) check_factor("size", opts.size_mm);
  LoadedSolid solid;
  solid.mesh = read_mesh(path);
  double factor = opts.units_to_mm * opts.scale;
  if (opts.size_mm > 0.0) {
    // A box with NaN corners leaves the factor alone: validation names the bad vertex below.
    const Box3 box = bounding_box(solid.mesh.vertices);
    const double longest = (box.max - box.min).maxCoeff();
    if (std::isfinite(longest) && longest > 0.0) factor = opts.size_mm / longest;
  }
  if (factor != 1.0)
    for (Vec3& p : solid.mesh.vertices) p *= factor;

  const MeshDiagnostics diagnostics = validate_mesh(solid.mesh);
  if (!diagnostics.ok())
    throw Error(ErrorCode::InvalidInput, path + ": " + diagnostics.first_problem);

  const double diagonal_mm = bounding_box(solid.mesh.vertices).diagonal();
  if (!(diagonal_mm >= kMinDiagonalMm && diagonal_mm <= kMaxDiagonalMm)) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "absurd scale: bounding box diagonal is %.4g mm; use --scale or --units",
                  diagonal_mm);
    throw Error(ErrorCode::InvalidInput, path + ": " + text);
  }
  // Consistently oriented but inward: the solid is fine, its winding is just reversed.
  if (diagnostics.volume_mm3 < 0.0) {
    flip_orientation(solid.mesh);
    solid.flipped = true;
  }
  if (const std::string problem = shells_problem(solid.mesh); !problem.empty())
    throw Error(ErrorCode::InvalidInput, path + ": " + problem);
  return solid;
}

}  // namespace dhfcast
