// Reading an output folder back (check, molds): which file names of decomposition.json may be
// opened, and how large its numbers may be.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace dhfcast {

// Largest |coordinate| or translation (mm) and |volume| (mm3) decomposition.json may hold: ten
// times the largest solid load_solid() accepts (100 m across), far from where the geometry's
// arithmetic overflows or stops resolving a millimetre.
inline constexpr double kMaxFolderCoordinateMm = 1e6;
inline constexpr double kMaxFolderVolumeMm3 = 1e18;
// Deepest nesting of arrays and objects read: nlohmann's dump() recurses once per level.
inline constexpr int kMaxJsonDepth = 64;

// Resolves `name`, a file name from decomposition.json, inside `folder`: "" and `path` set when
// it is relative, has no ".." and no component of it is a symlink (so it cannot lead out of the
// folder); else what is wrong, naming it. The file need not exist.
std::string folder_file(const std::filesystem::path& folder, const std::string& name,
                        std::filesystem::path& path);

// "" when `text` nests arrays and objects at most kMaxJsonDepth deep, else where it does not.
// Checked on the text, before parsing builds anything that deep.
std::string json_nesting_problem(std::string_view text);

// "" when `text` is JSON that parses into doubles and nests at most kMaxJsonDepth deep; else what
// is wrong and the field where (its JSON path, e.g. "not valid JSON at parts[1].volume_mm3:
// number overflow parsing '1e400'"). Builds no document.
std::string json_problem(std::string_view text);

}  // namespace dhfcast
