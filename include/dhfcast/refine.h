// Refinement: from the segmentation's candidate labelings to solid parts that are double height
// fields and come apart (paper §4.3 and §6, and the label-level repairs between them). Every
// tolerance and count of this stage lives in RefineOptions.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "dhfcast/access.h"
#include "dhfcast/parts.h"
#include "dhfcast/segment.h"
#include "dhfcast/types.h"

namespace dhfcast {

// Options for refine(). The first five are the user's (on the command line, written to
// decomposition.json); the others are fixed by design, in units of epsilon or counts, and named
// here so that each has one home.
struct RefineOptions {
  // Candidate labelings of the segmentation that go through the sandwich repair, those the
  // segmentation ranks first; the one closest to double height fields is kept (1: the
  // segmentation's own choice).
  std::int32_t candidates = 10;
  SandwichOptions sandwich;
  SmoothingOptions smoothing;
  // Cut each part from the exact input solid (cut_parts_from_solid), so its outer surface is the
  // input surface rather than the tet mesh's boundary.
  bool exact_outer_surface = true;
  // Mend the gap lines the label-level repairs leave on the final meshes (carve_dhf_gaps()).
  bool carve = true;

  // Directions over the sphere a part may leave along when its own +-d are blocked.
  std::int32_t assembly_directions = 64;
  // How deep (as shares of epsilon, tried in turn) a move may go into another part without
  // counting as blocked: half of what `dhfcast check` allows first, as check draws other points
  // of the surface; closer to its limit only when no order exists with that margin.
  std::vector<double> assembly_margins{0.5, 0.75, 0.95};
  // Ways out cleared at most, one per round, when no assembly order exists (clear_way()), and
  // the directions over the sphere tried per blocked part besides its +-d.
  std::int32_t max_way_clearings = 8;
  std::int32_t sphere_ways = 2;
  // Rounds of gap filling at most (fill_gaps()), and the lines per part that look for gaps: 100
  // times `dhfcast check`'s, so a gap that check meets once is met about 100 times.
  std::int32_t max_gap_fills = 4;
  std::int64_t gap_lines = 200'000;
  // While gap lines are left, candidate labelings made into parts at least, among those whose
  // sandwich share at the tets is at most gap_candidate_share times the least.
  std::int32_t made_candidates = 3;
  double gap_candidate_share = 4.0;

  // Throws Error{InvalidOptions} naming the first option out of range.
  void validate() const;
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
// Its figures are those of its parts bounded by the tets, which the candidates are compared on;
// the parts written are the kept one's cut from the solid (Refinement::solid_cut).
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

// What refine() makes.
struct Refinement {
  std::int32_t kept_candidate = 0;  // index into Labeling::candidates of the labeling kept
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
  double assembly_tolerance_mm = 0.0;      // depth into a part below which a move does not block
  std::vector<WayClearing> way_clearings;  // in the order they were made
  std::vector<GapFilling> gap_fillings;    // likewise, after the ways were cleared
  // Holes carved where gaps were still left (paper §4.3.1), after the label-level repairs.
  Carving carving;
  std::vector<MadeCandidate> made_candidates;  // the one kept is marked
};

// Makes the parts of one of `labeling`'s candidates:
// 1. Tets feasible for no direction (enclosed volumes, paper §6): each connected region of them
//    is decomposed again on its own (accessibility from its own boundary, `access_opts`,
//    `segment_opts`); these tets are the same in every candidate.
// 2. The candidates the segmentation ranks first (opts.candidates distinct ones) go through the
//    sandwich repair (absorb_sandwiched_tets()), and are ranked by how close to double height
//    fields they come (see refine.cpp).
// 3. The candidate ranked first is made into parts bounded by the tets (made manifold,
//    extracted, interfaces smoothed, ordered for assembly; ways cleared, gaps filled); when they
//    have no assembly order, gap lines or a tiny part, the next ones in turn, and the best kept.
// 4. The parts kept are made again, cut from the solid (cut_parts_from_solid()): the exact cut
//    runs once.
// 5. What the label-level repairs leave is mended on the final meshes (carve_dhf_gaps()).
// `directions` are the labels' directions; `access` was computed on `tets` for them with
// access_opts, and `labeling` is segment()'s. `progress` gets fractions in [0, 1).
// Deterministic: the result does not depend on the thread count.
// Throws Error{InvalidOptions} when an options struct's validate() does.
Refinement refine(const TriMesh& solid, const TetMesh& tets, const std::vector<Vec3>& directions,
                  const AccessibilityField& access, const Labeling& labeling,
                  const AccessibilityOptions& access_opts, const SegmentOptions& segment_opts,
                  const RefineOptions& opts, const Progress& progress = {});

}  // namespace dhfcast
