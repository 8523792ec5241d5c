// The whole decomposition: tetrahedralize, accessibility, segmentation, parts, assembly order.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dhfcast/access.h"
#include "dhfcast/molds.h"
#include "dhfcast/parts.h"
#include "dhfcast/refine.h"
#include "dhfcast/segment.h"
#include "dhfcast/tets.h"
#include "dhfcast/types.h"

namespace dhfcast {

// Every parameter of decompose(). Defaults are the paper's.
struct DecomposeOptions {
  TetOptions tets;
  std::int32_t directions = 512;  // number of candidate directions
  AccessibilityOptions access;
  SegmentOptions segment;
  RefineOptions refine;
  bool make_molds = true;  // build each part's two-piece mold (molds.epsilon_mm is taken from
                           // access.epsilon_mm)
  MoldOptions molds;
};

// Wall-clock seconds per stage. `parts` is the refinement (refine()): the candidate labelings'
// sandwich repair, the parts, their assembly order and the carving.
struct StageTimes {
  double tetrahedralize = 0, accessibility = 0, segmentation = 0, parts = 0, molds = 0;
};

// The result of decompose(): the refinement's parts (and what it did: see Refinement), with what
// the stages before and after it made.
struct Decomposition : Refinement {
  TetMesh tets;
  std::vector<Vec3> directions;
  AccessibilityField access;  // of the whole solid
  Labeling labeling;  // of the whole solid (label -1: inaccessible); the candidate kept is the
                      // one closest to double height fields after the sandwich repair
  std::vector<Mold> molds;  // one per part, in part order; empty when !make_molds
  StageTimes timings;
};

// Called when a stage starts (fraction 0), as it progresses, and when it ends (fraction 1).
using StageProgress = std::function<void(const std::string& stage, double fraction)>;

// Decomposes the solid bounded by `solid` into DHF parts and orders them for assembly.
// Pre: `solid` passes validate_mesh() and is outward oriented (load_solid() gives such meshes).
// Throws Error{InvalidOptions} for out-of-range options, and what the stages throw.
Decomposition decompose(const TriMesh& solid, const DecomposeOptions& opts = {},
                        const StageProgress& progress = {});

// Checks every option, each options struct by its validate() (the stages call the same ones);
// throws Error{InvalidOptions} naming the first bad one.
void validate_options(const DecomposeOptions& opts);

}  // namespace dhfcast
