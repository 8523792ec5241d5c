// Molds: for each part, the two halves of a rigid mold that is printed (or milled), closed,
// filled through a sprue and opened again along the part's direction d (paper §4.3.2).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dhfcast/access.h"
#include "dhfcast/parts.h"
#include "dhfcast/types.h"

namespace dhfcast {

// Options for build_molds(). Defaults are the values written to decomposition.json.
struct MoldOptions {
  double wall_mm = 5.0;            // least thickness of the block around the cavity
  double sprue_diameter_mm = 6.0;  // pour channel
  double vent_diameter_mm = 2.0;   // air vents
  double key_clearance_mm = 0.2;   // per side, between a registration bump and its socket
  // Pouring direction (the mold stands with it up). Zero: chosen per part among directions
  // orthogonal to d (fewest air traps, then the shortest fall). Otherwise its component
  // orthogonal to d is used (it must have one).
  Vec3 gravity_up = Vec3::Zero();
  // Undercut tolerance of the face split and the release; decompose() passes its own
  // (AccessibilityOptions::epsilon_mm).
  double epsilon_mm = AccessibilityOptions{}.epsilon_mm;

  // Throws Error{InvalidOptions} naming the first option out of range.
  void validate() const;
};

// A channel cut half into each half along the parting surface: from its mouth in the cavity
// straight along gravity_up to the block's outside.
struct MoldChannel {
  Vec3 mouth = Vec3::Zero();  // where it opens into the cavity, on the parting line
  Vec3 exit = Vec3::Zero();   // where it leaves the block
  double diameter_mm = 0.0;
};

// A registration key: a truncated cone on the down half standing along +d from the parting
// surface, and a socket of the same shape grown by the clearance in the up half.
struct MoldKey {
  Vec3 base = Vec3::Zero();  // centre of the cone's base, on the parting surface
  double base_diameter_mm = 0.0, top_diameter_mm = 0.0, height_mm = 0.0;
};

// How the part's surface was split between the halves (paper §4.3.2).
struct FaceSplitStats {
  std::int64_t up_faces = 0, down_faces = 0;
  double up_area_mm2 = 0.0, down_area_mm2 = 0.0;
  double both_area_mm2 = 0.0;     // accessible along +d and -d (assigned by the graph cut)
  double neither_area_mm2 = 0.0;  // accessible along neither (the part is a DHF only up to
                                  // epsilon): assigned to the better-aligned side
  double parting_line_mm = 0.0;   // length of the boundary between the two sides
};

// A rigid motion [R | t]: a point p goes to R * p + t (R a rotation).
using RigidMotion = Eigen::Matrix<double, 3, 4>;

// The mold of one part. When `error` is not empty the halves are empty and nothing else is set.
// Each half is in its print frame: its flat outer block face (normal +d for up, -d for down)
// lies on z = 0 facing -z with the rest above it, the block's gravity_up x d axis along x and its
// footprint centred on x = y = 0. Everything else (channels, keys, directions) is in the model's
// frame.
struct Mold {
  std::int32_t part = 0;
  TriMesh up;    // pulled off the cast part along +d
  TriMesh down;  // pulled off along -d
  // Take each half from its print frame back to where it sits around the part.
  RigidMotion up_to_model = RigidMotion::Identity(), down_to_model = RigidMotion::Identity();
  Vec3 gravity_up = Vec3::UnitY();  // unit, orthogonal to d: the mold stands with this up
  Vec3 block_mm = Vec3::Zero();     // block size along (gravity_up x d, gravity_up, d)
  std::vector<MoldChannel> sprues, vents;
  std::vector<MoldKey> keys;
  FaceSplitStats split;
  std::string error;  // one line: why this part has no mold
};

// Builds the mold of every part, in part order. Each half is a closed, 2-manifold, outward
// oriented solid whose vertices are exactly representable in float (what an STL stores), so
// what is validated is what is written. A part whose mold cannot be built gets Mold::error and
// the others are still built. Same parts and options give identical molds on any thread count.
// Throws Error{InvalidOptions} when opts.validate() does.
std::vector<Mold> build_molds(const std::vector<Part>& parts, const MoldOptions& opts = {});

// The mold of one part; throws Error{BooleanFailed} (or Internal) when it cannot be built.
Mold build_mold(const Part& part, const MoldOptions& opts = {});

}  // namespace dhfcast
