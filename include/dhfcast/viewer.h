// The 3D report of an output folder: OUTDIR/report.html, one self-contained page (three.js
// inlined, the meshes embedded) that shows the parts, their assembly and their molds offline, and
// its PNG previews rendered by headless Chromium.
#pragma once

#include <string>

namespace dhfcast {

// The page for the output folder `folder`: decomposition.json, the meshes it names (parts, carved
// voids, mold halves) and the checks of `check_json` (`dhfcast check --json`'s text; when "", the
// folder's check.json if there is one). The same folder gives the same bytes.
// Throws Error{Io} when the folder or its decomposition.json cannot be read, Error{InvalidInput}
// naming the first problem when it is no valid decomposition (check's contract: corrupt JSON, a
// missing or outside file, ...), a mesh cannot be read, or the checks are not check's JSON.
std::string report_html(const std::string& folder, const std::string& check_json = "");

// Writes report_html(folder, check_json) to folder/report.html through a temporary file renamed
// over it: the old report or the new one, whole, is there at every instant; nothing is written
// when it throws (as report_html(), or Error{Io} when the file cannot be written).
void write_report(const std::string& folder, const std::string& check_json = "");

// Renders folder/report.html in headless Chromium into folder/preview.png (the parts, exploded)
// and folder/molds.png (the largest part with a mold, its halves opened), each through a
// temporary file renamed over it. `chromium` names the browser program (found on PATH).
// Throws Error{Io} when Chromium is absent, fails or takes over `timeout_s` seconds per picture.
void render_previews(const std::string& folder, const std::string& chromium = "chromium",
                     double timeout_s = 120.0);

}  // namespace dhfcast
