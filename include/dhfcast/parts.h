// Parts: connected components of the labeling, their boundary meshes, and an assembly order.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast {

// Part::triangle_neighbor of a triangle that faces a hole carved out of the solid.
constexpr std::int32_t kCarvedVoid = -2;

// One solid part, cast in its own two-piece mold along `direction`.
struct Part {
  std::int32_t id = 0;
  std::int32_t direction_index = -1;  // index into the direction set
  Vec3 direction = Vec3::UnitZ();     // unit casting / assembly direction d
  std::int32_t region = 0;  // 0: the whole solid; k > 0: the k-th inaccessible region, which was
                            // decomposed again on its own
  std::vector<std::int32_t> tets;  // tets of the tet mesh it is made of, ascending
  TriMesh mesh;  // closed, 2-manifold, outward boundary (vertices duplicated where the part
                 // touches itself at an edge or vertex only)
  // triangle_neighbor[i]: the part on the other side of mesh.triangles[i], -1 when the
  // triangle lies on the solid's outer surface, kCarvedVoid when it faces a carved hole.
  std::vector<std::int32_t> triangle_neighbor;
  double volume_mm3 = 0.0;
};

// Splits the labeled tet mesh into parts: each connected component (through shared faces) of
// tets with the same (region, label) is a part. Parts are ordered by decreasing volume, ties by
// smallest tet index, and numbered 0.. in that order.
// directions[label] is the direction of label `label` (every region labels with the same set).
// Pre: every tet has label >= 0; tets has adjacency. Throws Error{Internal} on a broken mesh.
std::vector<Part> extract_parts(const TetMesh& tets, const std::vector<std::int32_t>& label,
                                const std::vector<std::int32_t>& region,
                                const std::vector<Vec3>& directions);

// Options for absorb_sandwiched_tets().
struct SandwichOptions {
  std::int32_t max_rounds = 40;  // rounds per part (each fills or cuts), and polishing
                                 // rounds; 0: only count
  // A piece a part falls into that is smaller than this share of the solid's volume goes to a
  // neighbouring part even where that part's direction does not allow all of it: a part that
  // small is not worth a mold of its own.
  double tiny_piece_share = 0.01;

  // Throws Error{InvalidOptions} naming the first option out of range.
  void validate() const;
};

// Tets that absorb_sandwiched_tets() moved from one label to another, within one region.
struct SandwichMove {
  std::int32_t region = 0;
  std::int32_t from_label = 0, to_label = 0;
  std::int32_t tets = 0;
  double volume_mm3 = 0.0;
};

// What absorb_sandwiched_tets() did.
struct SandwichRepair {
  // Which labeling was kept: "segmentation" (the start), "largest first" or "smallest first".
  std::string order = "segmentation";
  std::int32_t rounds = 0;      // the most rounds a part took in the labeling kept
  bool converged = false;       // no tet is sandwiched in the labeling kept
  std::int32_t moved_tets = 0;  // tets whose label changed (pieces below included)
  double moved_volume_mm3 = 0.0;
  // Tets still sandwiched in the labeling kept, and the largest volume of them between two tets
  // of one part, as a share of that part's volume (the part is not a DHF there).
  std::int32_t stuck_tets = 0;
  double worst_share = 0.0;
  std::int32_t parts = 0;          // face-connected components of equal (region, label) in it
  double smallest_part_mm3 = 0.0;  // the volume of the smallest of them
  // Pieces a part fell into when it lost tets that went whole to a neighbour, and their tets;
  // of those, the tets the neighbour's direction does not allow (tiny pieces only).
  std::int32_t merged_pieces = 0, merged_tets = 0, forced_tets = 0;
  std::vector<SandwichMove> moves;  // summed by (region, from_label, to_label), in that order
};

// A part under this share of its model's volume is not worth a mold of its own (its sprue alone
// may be larger): decompose() keeps a labeling without one where a candidate allows, and the
// user is warned of any left.
constexpr double kTinyPartShare = 1e-3;
// The ids of the parts under kTinyPartShare of `volume_mm3`, in the parts' order.
std::vector<std::int32_t> tiny_parts(const std::vector<Part>& parts, double volume_mm3);

// Below this share of sandwiched volume in its worst part (SandwichRepair::worst_share), a
// labeling counts as a set of double height fields: smoothing the interfaces and cutting the
// parts from the solid then leave about no line that meets a part twice.
constexpr double kCleanSandwichShare = 1e-3;

// Whether tet `tet` may take label `label` of region `region` (its direction is DHF-accessible
// there).
using TetAllowsLabel =
    std::function<bool(std::int32_t tet, std::int32_t region, std::int32_t label)>;

// Makes the parts double height fields at the tet level (the label-level half of paper §4.3.1).
// A part P (a face-connected component of equal (region, label), as in extract_parts()) is not
// a DHF along its direction d where a line along d meets P, leaves it and meets P again inside
// the same stretch of solid: the tets in between lie in P's infeasible volume. Lines are those
// through tet barycentres, walked through the tet mesh until they leave the solid.
// The parts settle one at a time and then keep their tets, except the ends of their columns.
// A part P settling fills: tets of parts not settled yet (or at the end of a settled part's
// column along its direction, when that opens no gap in it), that `allows` gives P's label,
// which reach P along d and -d through such tets only, and that touch P through them, join P.
// When nothing is left to fill, P cuts: its tets beyond a gap it may not fill leave it, on the
// side of the gap with less volume, each face-connected piece whole to a neighbouring part that
// allows all of it and, if settled, gains no sandwich; tets P gave up never come back. Rounds
// repeat until no gap is left, nothing moves, or opts.max_rounds. Afterwards, every piece a part
// fell into other than its largest goes whole to such a neighbour, and a piece under
// opts.tiny_piece_share of the solid (or a whole part under 1e-4 of it, a fragment of a few
// tets) to the neighbour whose direction allows most of it.
// Which parts settle first matters: largest first and smallest first are both tried, and the
// labeling kept, among those and the start, has the smallest worst_share, then fewest parts.
// That labeling is then polished: tets still between two tets of a part P along P's direction,
// that P allows, go to P together with the shorter tail of their own part's column along its
// direction where P allows it (so that part loses a column end, not a middle), one
// face-connected group at a time, when that leaves fewer tets sandwiched in the two parts near
// the group and both stay connected; rounds repeat until no group moves (at most
// opts.max_rounds). The polished labeling is kept when its worst_share is no larger and it has
// no more parts.
// Only tets of the same region are exchanged.
// Deterministic: the result does not depend on the thread count.
// Pre: tets has adjacency; label/region as for extract_parts(). Throws Error{InvalidOptions}
// when opts.validate() does, Error{Internal} on mismatched sizes.
// `lines`, when given, keeps the lines it walks through `tets` for the next call on the same
// tets (the candidate labelings of one decomposition): the result is the same either way.
class TetLines;
SandwichRepair absorb_sandwiched_tets(const TetMesh& tets, std::vector<std::int32_t>& label,
                                      const std::vector<std::int32_t>& region,
                                      const std::vector<Vec3>& directions,
                                      const TetAllowsLabel& allows,
                                      const SandwichOptions& opts = {}, TetLines* lines = nullptr);
// Lines through `tets` for absorb_sandwiched_tets(), shared between calls (from any thread); it
// refers to `tets`, which must outlive it.
std::shared_ptr<TetLines> make_tet_lines(const TetMesh& tets);

// Clears the way out of a part along `dir` at the label level, where plan_assembly() found it
// blocked: the part P is the face-connected component of equal (region, label) holding tet
// part_tet. Tets of other parts that contain one of `obstacle_points` (points of P's way inside
// them, from obstructions()) and that `allows` P's label are seeds; their parts are blockers.
// The blockers' tets in P's way are the seeds and those from which a line along -dir reaches P
// through tets of their own part that P may take; every face-connected piece of them that holds
// a seed goes to P. Every piece a blocker then falls into, other than its largest, goes to P
// when P may take it whole, else whole to a neighbouring part that allows it and gains no
// sandwich, where there is one. The move is made when it leaves no more face-connected parts and no
// part with a larger share of sandwiched volume than before (or than 1e-3). Returns the tets
// moved, ascending; none when refused (label as it was).
// Pre: as for absorb_sandwiched_tets().
std::vector<std::int32_t> clear_way(const TetMesh& tets, std::vector<std::int32_t>& label,
                                    const std::vector<std::int32_t>& region,
                                    const std::vector<Vec3>& directions,
                                    const TetAllowsLabel& allows, std::int32_t part_tet,
                                    const Vec3& dir, const std::vector<Vec3>& obstacle_points);

// Fills the gaps of a part along its direction at the label level, where dhf_gaps() found its
// lines leaving it and entering it again deeper than the undercut tolerance through other parts.
// Tets of other parts that contain one of `gap_points` (points of those stretches) and that
// `allows` P's label are seeds; each face-connected piece of them goes to P on its own, grown by
// at most two rings of its part's tets that P may take when it does not touch P (the smoothed
// interfaces are off the tets), and kept when its part does not fall apart. Unlike clear_way(),
// no sandwich share is compared: the caller judges the parts made from the result. Returns the
// tets moved, ascending; none when no piece was kept (label as it was).
// Pre: as for absorb_sandwiched_tets().
std::vector<std::int32_t> fill_gaps(const TetMesh& tets, std::vector<std::int32_t>& label,
                                    const std::vector<std::int32_t>& region,
                                    const std::vector<Vec3>& directions,
                                    const TetAllowsLabel& allows, std::int32_t part_tet,
                                    const std::vector<Vec3>& gap_points);

// What make_parts_manifold() did.
struct ManifoldRepair {
  std::int32_t rounds = 0;      // passes over the vertices that needed a fix
  std::int32_t moved_tets = 0;  // tets whose label changed
  double moved_volume_mm3 = 0.0;
  std::int32_t nonmanifold_vertices = 0;  // tet vertices still non-manifold for some part
};

// Changes the labels of a few tets so that every part (a face-connected component of equal
// (region, label), as in extract_parts()) has a 2-manifold boundary: around each tet vertex, a
// part's tets there are connected through faces that contain the vertex, and so are the other
// tets there together with the outside of the solid. A part whose tets meet only along an edge
// or at a vertex then no longer touches itself there (extract_parts() would duplicate the
// vertex, and exact booleans reject such surfaces). Each fix is the move around a bad vertex
// that lowers the number of such defects around the tets it moves the most (then the one of
// least volume): one tet, a group of a part's tets there, or the fewest tets that join two
// groups, given to a part across one of their faces. Every moved tet must be allowed its new
// label by `allows`. A move never splits a part, makes a new one or merges two parts of one
// label, so the parts never grow in number. Rounds repeat over the vertices still bad until
// none is left, no move helps, or max_rounds is reached. Only tets of the same region are
// exchanged. Deterministic: the result does not depend on the thread count.
// Pre: tets has adjacency; label/region as for extract_parts(). Throws Error{InvalidOptions}
// when max_rounds < 0, Error{Internal} on mismatched sizes.
ManifoldRepair make_parts_manifold(const TetMesh& tets, std::vector<std::int32_t>& label,
                                   const std::vector<std::int32_t>& region,
                                   const TetAllowsLabel& allows, std::int32_t max_rounds = 8);

// Options for smooth_interfaces().
struct SmoothingOptions {
  std::int32_t iterations = 40;  // Taubin step pairs
  double step = 0.5;             // fraction of the way to the neighbours' average per step
  // After each step, move interior interface vertices back out of the infeasible volumes of
  // their parts that they started outside of (paper §4.3.1); see smooth_interfaces().
  bool project = true;

  // Throws Error{InvalidOptions} naming the first option out of range.
  void validate() const;
};

// Whether `tet` may belong to part `part` (its direction is DHF-accessible there).
using TetAllowsPart = std::function<bool(std::int32_t tet, std::int32_t part)>;

// Smooths the staircase of tet faces between parts (paper §4.3.1) with volume-preserving
// (Taubin) Laplacian steps: seams on the outer surface and the junction curves where three parts
// meet are smoothed as polylines, interface surfaces as membranes. A seam vertex slides in the
// surface's tangent plane, only inside the star of its tet vertex (the tets around it), and only
// when every tet of that star allows both parts there, so the surface a part gains stays
// DHF-accessible for its direction (the paper's tolerance region). Inside the solid a vertex
// moves at most about one edge length. With opts.project, each step is followed by a damped
// projection (paper §4.3.1): a part's infeasible volume is where lines along its direction enter
// and leave the solid through its outer surface; an interior interface vertex that smoothing
// carried into the infeasible volume of one of its parts moves back towards its start, or
// across that part's direction where the seams moved the volume, until it is outside again.
// Where smoothing would make two triangles of a part cross (also when they share a vertex),
// collapse a triangle once coordinates are rounded to float (STL), or collapse a part, the
// vertices of those triangles go back to their start, then their one-rings, for a few rounds
// (all vertices after that). Vertices
// shared by parts move identically in all of them, so interfaces stay shared exactly.
// Pre: `parts` is extract_parts(tets, ...).
void smooth_interfaces(const TetMesh& tets, std::vector<Part>& parts, const TetAllowsPart& allows,
                       const SmoothingOptions& opts = {});

// What cut_parts_from_solid() did.
struct SolidCut {
  double push_mm = 0.0;              // how far the regions' outer surfaces were moved out
  std::vector<bool> part_cut;        // per part: cut from the solid (else left as a union of tets)
  std::vector<std::string> problem;  // per part: why it was not cut, "" when it was
  // Outer triangles of the moved regions whose pieces still lie inside the solid deeper than
  // float noise (1e-7 of the diagonal): dents the parts leave; 0 when they cover the solid.
  std::int32_t uncovered_triangles = 0;
  // Dents that a fold left (its corners could not move out far enough) and that were filled:
  // the region grew over each by a convex hull reaching out past the input surface, less the
  // other parts' regions.
  std::int32_t filled_dents = 0;
  // Parts that were slivers outside the input surface (empty once cut): their tets went to the
  // neighbour they shared the most interface with (which need not be accessible along that
  // neighbour's direction: the cut leaves nothing of them), and the others were renumbered.
  std::int32_t dropped_parts = 0;
  std::vector<std::int32_t> dropped_tets;  // ascending
  // Seam vertices the cut left a few micrometres from the neighbour's (where a region that
  // touched itself at a corner was moved apart there by a hair) and that moved onto it.
  std::int32_t closed_seam_hairs = 0;
};

// Makes the parts' outer surfaces the input surface itself (the tet mesh only decides who owns
// which region): each part becomes solid ∩ region, by exact corefinement, where the region is the
// part with its outer vertices moved out past the input surface along the input's normal
// (twice as far as the input sticks out of the outer triangles around each, plus a margin; less
// where moving that far would fold the region: a dent that leaves is filled, see
// SolidCut::filled_dents, or else counted in SolidCut::uncovered_triangles). Shared vertices move
// alike in every part. Interfaces keep their triangles, cut where they meet the input surface;
// neighbouring parts are cut by the same exact curve, so rounded to double they still share
// their vertices and triangles (except where a filled dent meets a neighbour: the same surface,
// triangulated apart; and where a part touching itself at a corner was moved apart there by a
// hair: the seam vertices the cut leaves a few micrometres from the neighbour's then move onto
// them, see SolidCut::closed_seam_hairs). A part that intersects itself, or whose region CGAL
// rejects, is left as it is, marked in SolidCut::part_cut and SolidCut::problem. A part that is
// empty once cut is dropped (see SolidCut::dropped_parts) and the parts renumbered.
// triangle_neighbor and volume_mm3 are updated. Deterministic, in a canonical vertex and triangle
// order. Pre: `parts` is extract_parts()/smooth_interfaces() output of a tet mesh of `solid`.
SolidCut cut_parts_from_solid(const TriMesh& solid, std::vector<Part>& parts);

// How smooth one interface between two parts is: the angles between the normals of
// neighbouring triangles of the interface.
struct InterfaceSmoothness {
  std::int32_t part_a = 0, part_b = 0;  // part_a < part_b
  std::int32_t triangles = 0;
  double area_mm2 = 0.0;
  double mean_angle_deg = 0.0;
  double p95_angle_deg = 0.0;
};

// Smoothness of every interface (triangles with triangle_neighbor >= 0), by (part_a, part_b);
// interfaces of fewer than two triangles are left out.
std::vector<InterfaceSmoothness> interface_smoothness(const std::vector<Part>& parts);

// The same angles over the parts' outer triangles (triangle_neighbor == -1): what the outer
// surface itself has at the same mesh resolution. p95 in deg; mean in mean_angle_deg.
InterfaceSmoothness outer_surface_smoothness(const std::vector<Part>& parts);

// How the parts go together.
struct AssemblyPlan {
  bool found = false;  // an order exists in which no part collides with those placed before it
  // Parts in the order they are put in place; each slides in along -removal[i] from far away
  // (it arrives from +infinity * removal[i]). When !found: first the parts that disassembly
  // could take out, in the order they go in (collision-free among themselves, with or without
  // the others in place), then the parts left blocked, by ascending id.
  std::vector<std::int32_t> order;
  // removal[i]: the unit direction part i leaves along when the object is taken apart: +d_i or
  // -d_i when either is free (a DHF along d is one along -d too), else the first free one of the
  // other directions tried; +d_i for a part left blocked.
  std::vector<Vec3> removal;
  // blocks[i] lists the parts that part i would run into when it leaves along removal[i].
  std::vector<std::vector<std::int32_t>> blocks;
  std::string message;       // when !found: which parts block each other
  std::int32_t blocked = 0;  // parts left blocked (0 when found)
};

// The points plan_assembly() moves, per part: points just inside each part's boundary, near the
// corners of every triangle and at the centres of a subdivision of it into sub-triangles about
// 1 % of the parts' bounding-box diagonal across, moved a hair (1e-5 of it) against the
// triangle's normal.
std::vector<std::vector<Vec3>> assembly_samples(const std::vector<Part>& parts);

// Finds which parts block which and orders them: disassembly takes out a part that no remaining
// part blocks; assembly is the reverse. A part may leave along +d, then -d (smallest id first);
// only when no remaining part can, along `extra_directions`, in their order. Taking a part out
// never blocks another, so this finds a complete order whenever one of these straight moves
// exists for each part in turn.
// Part B is blocked by part A when a ray from one of B's assembly_samples() goes deeper than
// tolerance_mm into A: a point of its way through A, taken every tolerance_mm / 2 as
// `dhfcast check` does, lies farther than that from A's boundary. Contact on shared interfaces,
// and sliding along them, does not block.
// tolerance_mm >= 0, else Error{InvalidOptions}. Pre: parts have ids 0..n-1 in order and closed
// meshes.
AssemblyPlan plan_assembly(const std::vector<Part>& parts,
                           const std::vector<Vec3>& extra_directions, double tolerance_mm);

// A stretch of a part's way out that runs through another part deeper than the tolerance.
struct Obstruction {
  std::int32_t part = -1;  // the part run into
  Vec3 from, to;           // where the way enters and leaves it
};

// Where part p, leaving along dir, runs into other parts, as plan_assembly() finds it (the same
// samples, rays and tolerance): every such stretch of every sample's way, in the samples' order.
std::vector<Obstruction> obstructions(const std::vector<Part>& parts, std::int32_t p,
                                      const Vec3& dir, double tolerance_mm);
// The same along each of `dirs`: the parts' scene and samples are made once for all of them.
std::vector<std::vector<Obstruction>> obstructions(const std::vector<Part>& parts, std::int32_t p,
                                                   const std::vector<Vec3>& dirs,
                                                   double tolerance_mm);

// A stretch of a line along a part's direction between two of the part's intervals.
struct DhfGap {
  std::int32_t part = -1;  // the first other part it enters; -1: none (it is outside the solid)
  Vec3 from, to;           // where the line leaves the part and enters it again
  // The part's interval that ends at `from`: where it begins, and the part the line was in just
  // before it (-1: none, the line came from outside the solid).
  Vec3 interval_from;
  std::int32_t below = -1;
};

// Where each part is not a double height field along its direction: on about `lines` lines along
// d, a square grid over the part's footprint's bounding rectangle, every stretch between two of
// its intervals whose deepest point is farther than epsilon_mm from its boundary (`dhfcast
// check`'s rule), bottom to top; per part. Deterministic. Throws Error{InvalidOptions} unless
// lines is in 1..1e8 and epsilon_mm > 0.
std::vector<std::vector<DhfGap>> dhf_gaps(const std::vector<Part>& parts, std::int64_t lines,
                                          double epsilon_mm);

// How many gaps dhf_gaps() finds in this part: the same count, from the part's own boundary
// alone (which parts a gap passes through is not traced), so faster.
std::int32_t dhf_gap_count(const Part& part, std::int64_t lines, double epsilon_mm);

// A hole carved out of a part where it was no double height field (paper §4.3.1).
struct CarvedVoid {
  std::int32_t part = -1;  // the part it was carved from
  TriMesh mesh;            // closed, outward: the material removed
  double volume_mm3 = 0.0;
};

// Material one part gave another to mend a gap (see carve_dhf_gaps()).
struct GapExchange {
  std::int32_t from = -1, to = -1;
  double volume_mm3 = 0.0;
};

// What carve_dhf_gaps() did.
struct Carving {
  std::int32_t gap_lines_before = 0, gap_lines_after = 0;  // of dhf_gaps(), all parts
  std::vector<GapExchange> exchanges;
  std::vector<CarvedVoid> voids;
  // Patches of gap lines left as they were, and why (one line each).
  std::vector<std::string> refused;
};

// The assembly order carving must keep (see carve_dhf_gaps()).
struct KeptAssembly {
  std::vector<Vec3> directions;  // plan_assembly()'s extra_directions
  double tolerance_mm = 0.0;
  AssemblyPlan plan;  // of the parts as given; updated as carving changes them
};

// The paper's conservative carving (§4.3.1), and better, for what the label-level repairs leave:
// where lines along a part P's direction meet it in several stretches deeper apart than
// epsilon_mm (dhf_gaps() on about `lines` lines). Neighbouring such lines form a patch (with
// the lines of shallow gaps two cells around it), handled by one convex hull over the lines'
// grid cells:
// - filling first: when one part Q lies in the gaps, the hull spans them, from P's first
//   stretches to its last, and P takes it from Q (P ∪ hull, Q minus the hull);
// - taking, where that hull would reach the outer surface: P takes what of Q lies in it
//   (P ∪ (Q ∩ hull), Q minus the hull);
// - then yielding: the hull spans the shorter of P's first and last groups of stretches, from
//   epsilon_mm past its far end to the middle of the gap, and the part across the gap takes
//   what of P lies in it;
// - else carving: when P's stretches past the first gap (or before the last) lie inside the
//   solid, bounded by P's interfaces only, the hull spans from the middle of the gap to
//   epsilon_mm past them: P becomes P minus the hull, and the material removed a void, whose
//   walls the neighbours across it keep (their triangles there face kCarvedVoid).
// None ever moves the outer surface: a filling or carving hull that would reach it is refused
// (so is, carving, one that reaches a curve where P meets two other parts, and, exchanging, one
// that reaches a third part), as is one CGAL rejects, one that makes a part fall apart, and one
// after which P has no fewer gap lines or another part more. Where an exchange cuts pieces off
// a part, those that touch the other part go to it as well (a third part across them then faces
// it); a part falls apart only when one does not.
// A hull whose cut float rounding breaks (a part no longer closed, or crossing itself) is tried
// again 3 % larger, then 3 % smaller, about its centroid. A refused patch is halved, up to three
// times. Interfaces stay shared exactly. Deterministic.
// Filling, taking and yielding move material between parts, which can put one in another's
// way: with `assembly` given, such a change is kept only when plan_assembly() still finds an
// order (or, when assembly->plan has none, leaves no more parts blocked), and assembly->plan
// becomes that plan. (Carving only removes material: no part runs into more.)
// Pre: parts have ids 0..n-1 in order and closed meshes with triangle_neighbor.
// With exchange false, only carving is tried.
Carving carve_dhf_gaps(std::vector<Part>& parts, std::int64_t lines, double epsilon_mm,
                       bool exchange = true, KeptAssembly* assembly = nullptr);

}  // namespace dhfcast
