#include "dhfcast/report.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <system_error>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"

namespace fs = std::filesystem;
using nlohmann::ordered_json;

namespace dhfcast {

namespace {

ordered_json vec(const Vec3& v) { return ordered_json::array({v.x(), v.y(), v.z()}); }

std::string part_file(std::int32_t id) {
  char name[32];
  std::snprintf(name, sizeof name, "parts/part_%03d.stl", id);
  return name;
}

[[noreturn]] void io_error(const std::string& what, const std::error_code& ec) {
  throw Error(ErrorCode::Io, what + ": " + ec.message());
}

}  // namespace

std::string decomposition_json(const InputInfo& input, const DecomposeOptions& opts,
                               const Decomposition& d, double load_s, double total_s,
                               bool include_timings) {
  ordered_json j;
  j["format"] = "dhfcast-decomposition";
  j["version"] = 1;
  j["input"] = {{"path", input.path},
                {"triangles", input.triangles},
                {"volume_mm3", input.volume_mm3},
                {"bbox_mm", ordered_json::array({vec(input.bbox.min), vec(input.bbox.max)})},
                {"flipped", input.flipped}};
  j["parameters"] = {{"epsilon_mm", opts.access.epsilon_mm},
                     {"directions", opts.directions},
                     {"alpha", opts.segment.alpha},
                     {"c_mm", opts.segment.c_mm},
                     {"beta_mm", opts.segment.beta_mm},
                     {"lambda", opts.segment.lambda},
                     {"restarts", opts.segment.restarts},
                     {"seed", opts.segment.seed},
                     {"target_tets", opts.tets.target_tets},
                     {"facet_distance_mm", opts.tets.facet_distance_mm}};
  j["tetrahedra"] = d.tets.tets.size();
  j["tet_volume_mm3"] = total_volume(d.tets);
  j["tet_boundary_tolerance_mm"] = d.tets.boundary_tolerance_mm;

  ordered_json parts = ordered_json::array();
  for (const Part& p : d.parts) {
    ordered_json jp = {{"id", p.id},
                       {"mesh", part_file(p.id)},
                       {"direction", vec(p.direction)},
                       {"volume_mm3", p.volume_mm3},
                       {"tets", p.tets.size()},
                       {"region", p.region},
                       {"blocked_by", d.assembly.blocks.at(p.id)}};
    parts.push_back(jp);
  }
  j["parts"] = parts;
  j["assembly_order"] = d.assembly.order;
  j["assembly_found"] = d.assembly.found;
  j["assembly_tolerance_mm"] = d.assembly_tolerance_mm;
  if (!d.assembly.found) j["assembly_message"] = d.assembly.message;

  ordered_json regions = ordered_json::array();
  for (const InaccessibleRegion& r : d.inaccessible_regions)
    regions.push_back({{"region", r.id},
                       {"tets", r.tets},
                       {"volume_mm3", r.volume_mm3},
                       {"still_inaccessible_tets", r.still_inaccessible_tets}});
  j["inaccessible_regions"] = regions;
  j["segmentation"] = {{"energy", d.labeling.energy},
                       {"candidate_directions", d.labeling.candidate_labels},
                       {"best_restart", d.labeling.best_restart}};
  if (include_timings) {
    j["timings_s"] = {{"load", load_s},
                      {"tetrahedralize", d.timings.tetrahedralize},
                      {"accessibility", d.timings.accessibility},
                      {"segmentation", d.timings.segmentation},
                      {"parts", d.timings.parts},
                      {"total", total_s}};
  }
  return j.dump(2) + "\n";
}

void check_output_location(const std::string& outdir, bool replace) {
  const fs::path out = fs::absolute(outdir);
  std::error_code ec;
  if (fs::exists(out, ec) && !replace)
    throw Error(ErrorCode::Io, outdir + " already exists; use --force to replace it");
  if (!fs::is_directory(out.parent_path(), ec))
    throw Error(ErrorCode::Io, "cannot create " + outdir + ": folder " +
                                   out.parent_path().string() + " does not exist");
}

void write_output(const std::string& outdir, const std::string& json, const Decomposition& d,
                  bool replace) {
  check_output_location(outdir, replace);
  const fs::path out = fs::absolute(outdir).lexically_normal();
  const fs::path parent = out.parent_path();
  const std::string stem = out.filename().string();
  const fs::path tmp = parent / ("." + stem + ".tmp-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(tmp, ec);
  try {
    fs::create_directories(tmp / "parts", ec);
    if (ec) io_error("cannot create " + tmp.string(), ec);
    for (const Part& p : d.parts) write_stl((tmp / part_file(p.id)).string(), p.mesh);
    std::ofstream f(tmp / "decomposition.json", std::ios::binary);
    f << json;
    f.close();
    if (!f) throw Error(ErrorCode::Io, "cannot write " + (tmp / "decomposition.json").string());

    // Swap in the new folder; the old one (if replacing) is removed only after the rename.
    const fs::path old = parent / ("." + stem + ".old-" + std::to_string(::getpid()));
    const bool had_old = fs::exists(out);
    if (had_old) {
      fs::rename(out, old, ec);
      if (ec) io_error("cannot replace " + outdir, ec);
    }
    fs::rename(tmp, out, ec);
    if (ec) {
      if (had_old) fs::rename(old, out);
      io_error("cannot create " + outdir, ec);
    }
    if (had_old) fs::remove_all(old, ec);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace dhfcast
