// The whole decomposition: tetrahedralize, accessibility, segmentation, parts, assembly order.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dhfcast/access.h"
#include "dhfcast/molds.h"
#include "dhfcast/parts.h"
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
  SandwichOptions sandwich;
  // Candidate labelings of the segmentation that go through the sandwich repair, those the
  // segmentation ranks first; the one closest to double height fields is kept (1: the
  // segmentation's own choice).
  std::int32_t candidates = 10;
  SmoothingOptions smoothing;
  // Cut each part from the exact input solid (cut_parts_from_solid), so its outer surface is the
  // input surface rather than the tet mesh's boundary.
  bool exact_outer_surface = true;
  // Mend the gap lines the label-level repairs leave on the final meshes (carve_dhf_gaps()).
  bool carve = true;
  bool make_molds = true;  // build each part's two-piece mold (molds.epsilon_mm is taken from
                           // access.epsilon_mm)
  MoldOptions molds;
};

// Wall-clock seconds per stage. Segmentation includes the sandwich repair of the candidate
// labelings tried (DecomposeOptions::candidates), which chooses the one kept.
struct StageTimes {
  double tetrahedralize = 0, accessibility = 0, segmentation = 0, parts = 0, molds = 0;
};

// A tet region that was feasible for no direction and was decomposed again on its own.
struct InaccessibleRegion {
  std::int32_t id = 0;    // its region number (Part::region)
  std::int32_t tets = 0;  // tets in it
  double volume_mm3 = 0.0;
  std::int32_t still_inaccessible_tets = 0;  // tets still feasible for no direction of the
                                             // region's own surface; merged into a neighbour
};

// Tets given to a part blocked on its way out (clear_way()), when no assembly order existed.
struct WayClearing {
  std::int32_t direction_index = 0;  // of the part whose way was cleared
  Vec3 direction;                    // the way: that part's +d or -d, or one over the sphere
  std::int32_t tets = 0;
  double volume_mm3 = 0.0;
  std::int32_t blocked_before = 0, blocked_after = 0;  // parts left blocked
};

// One move kept of tets given to a part in its gaps along d, or to the part under a skin of
// another over air (fill_gaps()), where the finished parts were not double height fields.
struct GapFilling {
  std::int32_t tets = 0;
  double volume_mm3 = 0.0;
  // Lines a tet apart over the parts' footprints that cross a gap deeper than epsilon.
  std::int32_t gap_lines_before = 0, gap_lines_after = 0;
};

// A candidate labeling made into parts (ways cleared, gaps filled), in the order they were made.
struct MadeCandidate {
  std::int32_t restart = 0;  // the segmentation restart it came from
  std::int32_t parts = 0;
  bool assembly_found = false;
  // Left after the gap filling, as GapFilling counts them; when dropped, as first made: a
  // candidate tried for its gaps only is not pursued when it starts with more than the best has
  // left.
  std::int32_t gap_lines = 0;
  bool tiny_part = false;  // one of its parts is under kTinyPartShare of the volume
  bool dropped = false;
  bool kept = false;
};

// The result of decompose().
struct Decomposition {
  TetMesh tets;
  std::vector<Vec3> directions;
  AccessibilityField access;  // of the whole solid
  Labeling labeling;  // of the whole solid (label -1: inaccessible); the candidate kept is the
                      // one closest to double height fields after the sandwich repair
  std::vector<InaccessibleRegion> inaccessible_regions;
  SandwichRepair sandwich;  // tets moved into the part they were sandwiched in (label level),
                            // in the candidate kept
  ManifoldRepair manifold;  // tets moved so that no part touches itself (label level)
  SolidCut solid_cut;       // parts cut from the exact input solid (empty when not asked)
  std::vector<Part> parts;
  // Per part: its tets its direction is not accessible for (tiny pieces the sandwich repair
  // forced on it), less those of slivers the cut dropped (outside the input: nothing of them is
  // cast); 0 for parts of inaccessible regions.
  std::vector<std::int32_t> inaccessible_tets;
  // Normal angles across each interface before and after smoothing, and over the outer surface
  // at the same resolution.
  std::vector<InterfaceSmoothness> raw_smoothness, smoothness;
  InterfaceSmoothness outer_smoothness;
  AssemblyPlan assembly;
  std::vector<WayClearing> way_clearings;  // in the order they were made
  std::vector<GapFilling> gap_fillings;    // likewise, after the ways were cleared
  // Holes carved where gaps were still left (paper §4.3.1), after the label-level repairs.
  Carving carving;
  std::vector<MadeCandidate> made_candidates;  // the one kept is marked
  std::vector<Mold> molds;             // one per part, in part order; empty when !make_molds
  double assembly_tolerance_mm = 0.0;  // depth into a part below which a move does not block
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
