// check: an independent verifier of an output folder (decomposition.json, part meshes, molds).
// It shares only the mesh readers with the pipeline, so a bug in one cannot hide a bug in the
// other. Every figure comes from ray casting and distance queries on the files themselves.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dhfcast/access.h"  // decompose's default tolerance only: no code is shared

namespace dhfcast {

// Options for check_output(). Fractions are plain ratios (0.005 = 0.5 %).
struct CheckOptions {
  std::string outdir;        // the folder written by `dhfcast decompose`
  std::string input_mesh;    // the decomposed mesh, in mm; "" skips the checks that need it
                             // (gap, outside and fidelity) and takes the input volume from the json
  double input_scale = 1.0;  // multiplies input_mesh's coordinates (decompose's --scale x units)
  double input_size_mm = 0.0;  // when > 0, decompose's --size: replaces input_scale
  // Undercut / contact tolerance, decompose's default (README: --epsilon).
  double epsilon_mm = AccessibilityOptions{}.epsilon_mm;

  // solids: |json volume_mm3 - mesh volume| / mesh volume, per part, allowed on top of what
  // rounding the vertices to float (STL) can change.
  double json_volume_tolerance = 1e-6;
  // coverage: |sum of part volumes - input volume| / input volume.
  double max_volume_error = 0.005;
  std::int64_t coverage_samples = 200000;  // points, uniform in the input's bounding box
  double max_overlap_fraction = 0.001;     // volume inside 2+ parts / input volume
  double max_gap_fraction = 0.005;         // input volume inside no part / input volume
  double max_outside_fraction = 0.005;     // part volume outside the input / input volume
  // dhf: lines parallel to each part's direction through its footprint.
  std::int32_t dhf_lines = 2000;              // per part
  double max_dhf_violation_fraction = 0.005;  // lines meeting the part in 2+ intervals whose
                                              // gap leaves the epsilon band, per part
  // assembly: samples of each part swept along its direction against the parts placed before.
  std::int32_t assembly_samples = 2000;  // random surface points per part, besides its vertices
  std::int64_t max_blocked_samples = 0;  // samples entering an earlier part (or, for molds, a
                                         // half's samples entering its part) deeper than epsilon
  // molds (only when decomposition.json lists them): each half must leave its part (at most
  // max_blocked_samples of its samples deeper than epsilon), part and halves may overlap by at
  // most max_overlap_fraction of the part's volume, and the halves must mould its surface.
  std::int32_t mold_samples = 20000;  // per part and per test (release, overlap, cover)
  // Part-surface samples moulded: a half within epsilon/4, or the point epsilon out along the
  // normal inside a half (an undercut sliver the tolerance accepts, which the cast fills), or
  // opening into a listed sprue or vent.
  double min_mold_surface_coverage = 0.99;
  // fidelity (only with input_mesh): two-sided surface distance, 99th percentile.
  std::int64_t fidelity_samples = 100000;  // per side
  double max_fidelity_p99_rel = 0.001;     // relative to the input's bounding-box diagonal

  std::uint64_t seed = 1;  // all sampling is seeded: same folder, options and seed give the same
                           // figures on any thread count
};

// The outcome of one check.
struct CheckItem {
  std::string name;      // contract, solids, coverage, dhf, assembly, molds, fidelity
  bool passed = false;   // meaningful when !skipped
  bool skipped = false;  // not applicable (e.g. no molds) or impossible (e.g. unreadable parts)
  std::string summary;   // one line: the figures that matter, or the first problem found
  std::vector<std::pair<std::string, double>> figures;  // named figures, in a fixed order
  std::optional<Vec3> at;  // the place the summary names, in the parts' frame (failing dhf,
                           // assembly, molds; fidelity's farthest point)
};

// All checks, in the order they ran.
struct CheckReport {
  std::vector<CheckItem> items;
  // True when no check that ran failed (skipped checks do not count).
  bool passed() const;
};

// Runs every check on options.outdir. Findings, including a malformed decomposition.json or
// unreadable part files, are reported as failed items, never thrown.
// Throws Error{Io} when outdir or its decomposition.json cannot be read at all; what
// load_solid() throws when options.input_mesh cannot be read (Io) or is not a valid solid
// (InvalidInput; an inside-out input is flipped, as decompose does); Error{InvalidOptions}
// naming the first out-of-range option.
CheckReport check_output(const CheckOptions& options);

// One line per check ("PASS contract  dhfcast-decomposition v1, 2 parts, ..."; FAIL, SKIP), then
// the verdict ("PASS: 6 checks passed, 1 skipped" or "FAIL: 2 of 7 checks failed (dhf, molds)").
std::string format_text(const CheckReport& report);
// {"passed": bool, "checks": [{"name", "status": "pass"|"fail"|"skip", "summary",
//  "figures": {key: number}, "at": [x, y, z] when the check names a place}]}, pretty-printed,
// ending with a newline.
std::string format_json(const CheckReport& report);

// The contract check alone (the first item of check_output()): what decomposition.json and the
// presence of the files it names say, no mesh read. For readers of a folder that show it.
// Throws Error{Io} when outdir or its decomposition.json cannot be read.
CheckItem check_contract(const std::string& outdir);

}  // namespace dhfcast
