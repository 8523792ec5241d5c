// load_solid(): read, scale to mm, validate, orient outward.
#include <cmath>
#include <cstdio>
#include <string>

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
  return solid;
}

}  // namespace dhfcast
