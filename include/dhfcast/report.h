// The output folder: decomposition.json and the part meshes, written atomically.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dhfcast/pipeline.h"
#include "dhfcast/types.h"

namespace dhfcast {

// What is recorded about the input.
struct InputInfo {
  std::string path;
  std::int64_t triangles = 0;
  double volume_mm3 = 0.0;
  Box3 bbox;
  bool flipped = false;  // it was inward oriented and was flipped
};

// decomposition.json as text (format "dhfcast-decomposition", version 1; see README.md).
// With include_timings == false the "timings_s" object is left out, so two runs can be
// compared byte for byte.
std::string decomposition_json(const InputInfo& input, const DecomposeOptions& opts,
                               const Decomposition& d, double load_s, double total_s,
                               bool include_timings = true);

// Writes decomposition.json and parts/part_NNN.stl into `outdir`: everything goes to a
// temporary folder beside it (".OUTNAME.dhfcast-tmp-PID"; a dead process's are removed), swapped
// with `outdir` in one rename at the end, so a failure or a kill leaves no half-written output.
// An existing `outdir` is replaced only when `replace` is true. `finish`, when given, is called
// with the temporary folder once it is complete, before the swap, to add files of its own (the
// 3D report): what it throws fails the write.
// Throws Error{Io}.
using FolderFinisher = std::function<void(const std::string& folder)>;
void write_output(const std::string& outdir, const std::string& json, const Decomposition& d,
                  bool replace, const FolderFinisher& finish = {});

// Builds the molds of an existing output folder again with `opts` (epsilon_mm is taken from its
// decomposition.json): replaces OUTDIR/molds/ and the molds entries, parameters.molds and
// timings_s.molds of decomposition.json, and drops molds.png and check.json (about the old molds).
// Every part mesh, direction and number read is checked first. The folder's new state is built
// beside it (".OUTNAME.dhfcast-tmp-PID") and swapped in with one rename, so the folder is old or
// new, whole, at every instant; `finish` is called with the new state's temporary folder before the
// swap, as by write_output(). Returns the molds (a part whose mold failed has Mold::error). Throws
// Error{Io} when the folder cannot be read or written, Error{InvalidInput} when it is not a dhfcast
// decomposition or lists a file outside it (see folder_file()), a part that is not a solid or a
// number out of range, Error{InvalidOptions} for bad options.
std::vector<Mold> rebuild_molds(const std::string& outdir, MoldOptions opts,
                                const FolderFinisher& finish = {});

// Throws Error{Io} when `outdir` cannot be written later: it is or holds `input` (when given),
// it exists and is not a folder, it exists and `replace` is false, or its parent folder does not
// exist or cannot be written. Lets the CLI fail before the long computation.
void check_output_location(const std::string& outdir, bool replace, const std::string& input = "");

}  // namespace dhfcast
