// Private to the parts stage: the pieces of carve_dhf_gaps(), the line analysis (Embree) and the
// exact cut (CGAL), which live in different files.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dhfcast/parts.h"

namespace dhfcast::detail {

// A line along a part's direction that meets it in several stretches.
struct CarveLine {
  std::int64_t iu = 0, iv = 0;  // its grid cell
  Vec3 gap{0, 0, 0};            // the middle of its first deep gap (else of its first gap)
  bool deep = true;             // false: its gaps are within the tolerance (it borders deep lines)
  // The stretch of the line to remove, from low to high along d, so that it meets the part
  // once: `above` from the middle of the first deep gap to the end of the part's last stretch,
  // `below` from the beginning of the first to the middle of the last deep gap. Empty when
  // a stretch of the part in it reaches the outer surface (or a carved void).
  std::optional<std::pair<Vec3, Vec3>> above, below;
  // The stretch between the part's first and last groups of stretches (reaching a little into
  // both) and the one other part met there; empty when several are, or none.
  std::optional<std::pair<Vec3, Vec3>> fill;
  std::int32_t fill_from = -1;
  // The shorter of the part's first and last groups of stretches, from epsilon past its far end
  // to the middle of its gap, and the part across that gap; empty when none is (air).
  std::optional<std::pair<Vec3, Vec3>> yield;
  std::int32_t yield_to = -1;
};

struct CarveLines {
  Vec3 d{0, 0, 1}, u{1, 0, 0}, v{0, 1, 0};
  double spacing_mm = 0.0;  // grid cells are squares this wide in (u, v)
  std::vector<CarveLine> lines;
};

// The options of dhf_gaps(), dhf_gap_count() and carve_dhf_gaps(): lines in 1..1e8 and a
// positive epsilon (validate_epsilon()); throws Error{InvalidOptions} otherwise.
void validate_gap_options(std::int64_t lines, double epsilon_mm);

// Part p's lines that meet it in several stretches, on the grid of dhf_gaps() (about `lines`
// lines).
CarveLines carve_lines(const std::vector<Part>& parts, std::int32_t p, std::int64_t lines,
                       double epsilon_mm);

// fill_hull()'s reason when the hull reaches the outer surface (carving then has the neighbour
// yield what of it lies in the hull instead).
inline constexpr const char* kHullReachesOuterSurface = "its hull would reach the outer surface";

// The functions below refuse with a reason in `why`; a reason that rounding the exact result to
// float caused ends in "once rounded" (carving then tries the hull a little larger or smaller).
// `checked`: the parts they change are known not to intersect themselves
// (intersecting_triangles() found none), so CGAL need not check them again.

// Part p and its neighbours once the convex hull of `hull` is carved out of p, or filled by p.
// An exchange (filling, yielding) that cuts pieces off one of its two parts gives them to the
// other when they touch it; a third part across them is then among the changed, facing it.
struct CarvedHull {
  std::vector<std::pair<std::int32_t, Part>> changed;  // (id, new part), p first
  CarvedVoid hole;                                     // carving only
};

// Carves the convex hull of `hull` out of part p: p becomes p minus the hull, and each
// neighbour whose interface with p the hull reaches takes, in place of its triangles there, p's
// new triangles facing it (reversed) and those of the material removed (facing kCarvedVoid).
// Refused (the reason in `why`) when the hull meets p's outer surface, or an edge of p between
// two triangles facing different neighbours, or when CGAL rejects it or a part would not be
// closed.
std::optional<CarvedHull> carve_hull(const std::vector<Part>& parts, std::int32_t p,
                                     const std::vector<Vec3>& hull, bool checked, std::string& why);

// Fills the convex hull of `hull` with part p, taking it from part q: p becomes p ∪ hull and q
// becomes q minus the hull. Refused (the reason in `why`) when the hull meets the outer surface
// (or a carved void), any other part, or when CGAL rejects it or q would fall apart.
std::optional<CarvedHull> fill_hull(const std::vector<Part>& parts, std::int32_t p, std::int32_t q,
                                    const std::vector<Vec3>& hull, bool checked, std::string& why);

// Gives part q the part of p inside the convex hull of `hull`: p becomes p minus the hull and q
// becomes q ∪ (p ∩ hull); the outer surface stays where it is. Refused (the reason in `why`)
// when the hull meets a third part, when CGAL rejects it or a part would fall apart.
std::optional<CarvedHull> yield_hull(const std::vector<Part>& parts, std::int32_t p, std::int32_t q,
                                     const std::vector<Vec3>& hull, bool checked, std::string& why);

}  // namespace dhfcast::detail
