#include "dhfcast/report.h"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>  // renameat2, RENAME_EXCHANGE
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <nlohmann/json.hpp>
#include <system_error>

#include "dhfcast/error.h"
#include "dhfcast/folder.h"
#include "dhfcast/mesh.h"
#include "dhfcast/stop.h"

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

std::string void_file(std::size_t k) {
  char name[48];
  std::snprintf(name, sizeof name, "parts/void_%03zu.stl", k);
  return name;
}

std::string mold_file(std::int32_t id, const char* half) {
  char name[40];
  std::snprintf(name, sizeof name, "molds/part_%03d_%s.stl", id, half);
  return name;
}

// Row by row: [[r00, r01, r02, t0], [r10, ...], [r20, ...]].
ordered_json motion(const RigidMotion& m) {
  ordered_json rows = ordered_json::array();
  for (int r = 0; r < 3; ++r)
    rows.push_back(ordered_json::array({m(r, 0), m(r, 1), m(r, 2), m(r, 3)}));
  return rows;
}

ordered_json mold_json(const Mold& m) {
  if (!m.error.empty()) return {{"error", m.error}};
  auto channels = [](const std::vector<MoldChannel>& list) {
    ordered_json out = ordered_json::array();
    for (const MoldChannel& c : list)
      out.push_back(
          {{"mouth", vec(c.mouth)}, {"exit", vec(c.exit)}, {"diameter_mm", c.diameter_mm}});
    return out;
  };
  ordered_json keys = ordered_json::array();
  for (const MoldKey& k : m.keys)
    keys.push_back({{"base", vec(k.base)},
                    {"base_diameter_mm", k.base_diameter_mm},
                    {"top_diameter_mm", k.top_diameter_mm},
                    {"height_mm", k.height_mm}});
  const FaceSplitStats& s = m.split;
  return {{"up", mold_file(m.part, "up")},
          {"down", mold_file(m.part, "down")},
          {"up_to_model", motion(m.up_to_model)},
          {"down_to_model", motion(m.down_to_model)},
          {"gravity_up", vec(m.gravity_up)},
          {"block_mm", vec(m.block_mm)},
          {"sprues", channels(m.sprues)},
          {"vents", channels(m.vents)},
          {"keys", keys},
          {"face_split",
           {{"up_triangles", s.up_faces},
            {"down_triangles", s.down_faces},
            {"up_area_mm2", s.up_area_mm2},
            {"down_area_mm2", s.down_area_mm2},
            {"both_ways_area_mm2", s.both_area_mm2},
            {"neither_way_area_mm2", s.neither_area_mm2},
            {"parting_line_mm", s.parting_line_mm}}}};
}

[[noreturn]] void io_error(const std::string& what, const std::error_code& ec) {
  throw Error(ErrorCode::Io, what + ": " + ec.message());
}

ordered_json mold_parameters_json(const MoldOptions& o) {
  return {{"wall_mm", o.wall_mm},
          {"sprue_diameter_mm", o.sprue_diameter_mm},
          {"vent_diameter_mm", o.vent_diameter_mm},
          {"key_clearance_mm", o.key_clearance_mm}};
}

void write_mold_files(const std::string& dir, const std::vector<Mold>& molds) {
  if (molds.empty()) return;
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "molds", ec);
  if (ec) io_error("cannot create " + (fs::path(dir) / "molds").string(), ec);
  for (const Mold& m : molds) {
    if (!m.error.empty()) continue;
    write_stl((fs::path(dir) / mold_file(m.part, "up")).string(), m.up);
    write_stl((fs::path(dir) / mold_file(m.part, "down")).string(), m.down);
  }
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
                     {"candidates", opts.refine.candidates},
                     {"smoothing_iterations", opts.refine.smoothing.iterations},
                     {"seed", opts.segment.seed},
                     {"target_tets", opts.tets.target_tets},
                     {"facet_distance_mm", opts.tets.facet_distance_mm},
                     {"exact_outer_surface", opts.refine.exact_outer_surface},
                     {"carve", opts.refine.carve}};
  if (opts.make_molds) j["parameters"]["molds"] = mold_parameters_json(opts.molds);
  j["tetrahedra"] = d.tets.tets.size();
  j["tet_volume_mm3"] = total_volume(d.tets);
  j["tet_boundary_tolerance_mm"] = d.tets.boundary_tolerance_mm;

  ordered_json parts = ordered_json::array();
  for (const Part& p : d.parts) {
    ordered_json jp = {{"id", p.id},
                       {"mesh", part_file(p.id)},
                       {"direction", vec(p.direction)},
                       {"removal_direction", vec(d.assembly.removal.at(p.id))},
                       {"volume_mm3", p.volume_mm3},
                       {"tets", p.tets.size()},
                       {"inaccessible_tets", d.inaccessible_tets.at(p.id)},
                       {"region", p.region},
                       {"blocked_by", d.assembly.blocks.at(p.id)}};
    if (static_cast<std::size_t>(p.id) < d.solid_cut.part_cut.size())
      jp["cut_from_input"] = bool(d.solid_cut.part_cut[p.id]);
    if (static_cast<std::size_t>(p.id) < d.solid_cut.problem.size() &&
        !d.solid_cut.problem[p.id].empty())
      jp["cut_problem"] = d.solid_cut.problem[p.id];
    double carved = 0.0;
    for (const CarvedVoid& v : d.carving.voids) carved += v.part == p.id ? v.volume_mm3 : 0.0;
    jp["carved_mm3"] = carved;
    if (static_cast<std::size_t>(p.id) < d.molds.size()) jp["molds"] = mold_json(d.molds[p.id]);
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

  ordered_json moves = ordered_json::array();
  for (const SandwichMove& m : d.sandwich.moves)
    moves.push_back({{"region", m.region},
                     {"from_direction", m.from_label},
                     {"to_direction", m.to_label},
                     {"tets", m.tets},
                     {"volume_mm3", m.volume_mm3}});
  j["sandwich_repair"] = {{"order", d.sandwich.order},
                          {"rounds", d.sandwich.rounds},
                          {"converged", d.sandwich.converged},
                          {"moved_tets", d.sandwich.moved_tets},
                          {"moved_volume_mm3", d.sandwich.moved_volume_mm3},
                          {"stuck_tets", d.sandwich.stuck_tets},
                          {"worst_share", d.sandwich.worst_share},
                          {"parts", d.sandwich.parts},
                          {"merged_pieces", d.sandwich.merged_pieces},
                          {"merged_tets", d.sandwich.merged_tets},
                          {"forced_tets", d.sandwich.forced_tets},
                          {"moves", moves}};
  ordered_json clearings = ordered_json::array();
  for (const WayClearing& c : d.way_clearings)
    clearings.push_back({{"direction_index", c.direction_index},
                         {"direction", vec(c.direction)},
                         {"tets", c.tets},
                         {"volume_mm3", c.volume_mm3},
                         {"blocked_parts_before", c.blocked_before},
                         {"blocked_parts_after", c.blocked_after}});
  j["assembly_repair"] = clearings;
  ordered_json fillings = ordered_json::array();
  for (const GapFilling& f : d.gap_fillings)
    fillings.push_back({{"tets", f.tets},
                        {"volume_mm3", f.volume_mm3},
                        {"gap_lines_before", f.gap_lines_before},
                        {"gap_lines_after", f.gap_lines_after}});
  j["dhf_repair"] = fillings;
  ordered_json voids = ordered_json::array();
  for (std::size_t k = 0; k < d.carving.voids.size(); ++k)
    voids.push_back({{"part", d.carving.voids[k].part},
                     {"mesh", void_file(k)},
                     {"volume_mm3", d.carving.voids[k].volume_mm3}});
  ordered_json exchanges = ordered_json::array();
  for (const GapExchange& e : d.carving.exchanges)
    exchanges.push_back({{"from", e.from}, {"to", e.to}, {"volume_mm3", e.volume_mm3}});
  j["carving"] = {{"gap_lines_before", d.carving.gap_lines_before},
                  {"gap_lines_after", d.carving.gap_lines_after},
                  {"exchanges", exchanges},
                  {"voids", voids},
                  {"refused", d.carving.refused}};
  ordered_json made = ordered_json::array();
  for (const MadeCandidate& m : d.made_candidates)
    made.push_back({{"restart", m.restart},
                    {"parts", m.parts},
                    {"assembly_found", m.assembly_found},
                    {"gap_lines", m.gap_lines},
                    {"tiny_part", m.tiny_part},
                    {"dropped", m.dropped},
                    {"kept", m.kept}});
  j["candidates_made"] = made;
  j["manifold_repair"] = {{"moved_tets", d.manifold.moved_tets},
                          {"moved_volume_mm3", d.manifold.moved_volume_mm3},
                          {"nonmanifold_vertices", d.manifold.nonmanifold_vertices}};

  if (opts.refine.exact_outer_surface)
    j["outer_surface_cut"] = {{"push_mm", d.solid_cut.push_mm},
                              {"uncovered_triangles", d.solid_cut.uncovered_triangles},
                              {"filled_dents", d.solid_cut.filled_dents},
                              {"dropped_parts", d.solid_cut.dropped_parts},
                              {"closed_seam_hairs", d.solid_cut.closed_seam_hairs}};

  // Normal angles between neighbouring interface triangles, before and after smoothing.
  auto smoothness = [](const InterfaceSmoothness& s) {
    return ordered_json{{"triangles", s.triangles},
                        {"area_mm2", s.area_mm2},
                        {"mean_angle_deg", s.mean_angle_deg},
                        {"p95_angle_deg", s.p95_angle_deg}};
  };
  ordered_json interfaces = ordered_json::array();
  for (const InterfaceSmoothness& s : d.smoothness) {
    ordered_json ji = {{"parts", {s.part_a, s.part_b}}, {"smoothed", smoothness(s)}};
    for (const InterfaceSmoothness& r : d.raw_smoothness)
      if (r.part_a == s.part_a && r.part_b == s.part_b) ji["raw"] = smoothness(r);
    interfaces.push_back(ji);
  }
  j["interfaces"] = interfaces;
  j["outer_surface_smoothness"] = smoothness(d.outer_smoothness);
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
    if (opts.make_molds) j["timings_s"]["molds"] = d.timings.molds;
  }
  // The input's path is the user's bytes, not always UTF-8.
  return j.dump(2, ' ', false, ordered_json::error_handler_t::replace) + "\n";
}

namespace {

// The folder `outdir` names, absolute, without a trailing separator ("out/" is "out").
fs::path folder_path(const std::string& outdir) {
  fs::path out = fs::absolute(outdir).lexically_normal();
  return out.has_filename() ? out : out.parent_path();
}

// Where a folder's replacement is built, beside it so one rename swaps it in. The pid tells a
// dead writer's leftovers (see remove_stale_temps()) from a running one's.
constexpr const char* kTempTag = ".dhfcast-tmp-";

// ".OUTNAME.dhfcast-tmp-" (appended to, not prepended: GCC 12 warns about "." + name).
std::string temp_prefix(const fs::path& out) {
  std::string prefix = ".";
  prefix += out.filename().string();
  return prefix += kTempTag;
}

fs::path temp_beside(const fs::path& out) {
  return out.parent_path() / (temp_prefix(out) + std::to_string(::getpid()));
}

// Removes the temporary folders beside `out` of processes that no longer run (killed while
// writing).
void remove_stale_temps(const fs::path& out) {
  const std::string prefix = temp_prefix(out);
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(out.parent_path(), ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string pid = name.substr(prefix.size());
    if (pid.empty() || pid.size() > 9 || pid.find_first_not_of("0123456789") != std::string::npos)
      continue;
    if (::kill(std::stoi(pid), 0) != 0 && errno == ESRCH) fs::remove_all(e.path(), ec);
  }
}

// Puts the folder `tmp` at `out`, replacing `out` if it exists. With RENAME_EXCHANGE one rename
// swaps them, so `out` is whole, old or new, at every instant; the old one, now at `tmp`, is
// removed after. File systems without it get two renames, the old folder kept until the second.
void swap_in(const fs::path& tmp, const fs::path& out, const std::string& name) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(out, ec))) {
    fs::rename(tmp, out, ec);
    if (ec) io_error("cannot create " + name, ec);
    return;
  }
  if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, out.c_str(), RENAME_EXCHANGE) == 0) {
    fs::remove_all(tmp, ec);
    return;
  }
  if (errno != EINVAL && errno != ENOSYS)
    io_error("cannot replace " + name, std::error_code(errno, std::generic_category()));
  const fs::path old = tmp.string() + "-old";
  fs::rename(out, old, ec);
  if (ec) io_error("cannot replace " + name, ec);
  fs::rename(tmp, out, ec);
  if (ec) {
    fs::rename(old, out);
    io_error("cannot create " + name, ec);
  }
  fs::remove_all(old, ec);
}

// True when `inner` is `outer` or lies inside it (both absolute).
bool is_within(const fs::path& inner, const fs::path& outer) {
  std::error_code ec;
  const fs::path a = fs::weakly_canonical(inner, ec), b = fs::weakly_canonical(outer, ec);
  const auto [end_b, end_a] = std::mismatch(b.begin(), b.end(), a.begin(), a.end());
  return end_b == b.end();
}

}  // namespace

void check_output_location(const std::string& outdir, bool replace, const std::string& input) {
  const fs::path out = folder_path(outdir);
  std::error_code ec;
  if (!input.empty() && is_within(fs::absolute(input), out))
    throw Error(ErrorCode::Io, outdir + " would replace the input " + input +
                                   "; choose an output folder that does not hold it");
  const fs::file_status status = fs::symlink_status(out, ec);
  if (fs::exists(status) && !fs::is_directory(fs::status(out, ec)))
    throw Error(ErrorCode::Io, outdir + " exists and is not a folder");
  if (fs::exists(status) && !replace)
    throw Error(ErrorCode::Io, outdir + " already exists; use --force to replace it");
  if (!fs::is_directory(out.parent_path(), ec))
    throw Error(ErrorCode::Io, "cannot create " + outdir + ": folder " +
                                   out.parent_path().string() + " does not exist");
  // The folder is built beside `out`: find out now, not after the work, if that is allowed.
  const std::lock_guard writing(output_write_mutex());
  const fs::path probe = temp_beside(out);
  fs::remove_all(probe, ec);
  if (!fs::create_directory(probe, ec))
    io_error("cannot create " + outdir + ": cannot write in " + out.parent_path().string(), ec);
  fs::remove(probe, ec);
}

void write_output(const std::string& outdir, const std::string& json, const Decomposition& d,
                  bool replace, const FolderFinisher& finish) {
  check_output_location(outdir, replace);
  const fs::path out = folder_path(outdir);
  // A stop is honoured before the folder is begun, never while it is built.
  const std::lock_guard writing(output_write_mutex());
  throw_if_stop_requested();
  remove_stale_temps(out);
  const fs::path tmp = temp_beside(out);
  std::error_code ec;
  try {
    fs::create_directories(tmp / "parts", ec);
    if (ec) io_error("cannot create " + tmp.string(), ec);
    for (const Part& p : d.parts) write_stl((tmp / part_file(p.id)).string(), p.mesh);
    for (std::size_t k = 0; k < d.carving.voids.size(); ++k)
      write_stl((tmp / void_file(k)).string(), d.carving.voids[k].mesh);
    write_mold_files(tmp.string(), d.molds);
    std::ofstream f(tmp / "decomposition.json", std::ios::binary);
    f << json;
    f.close();
    if (!f) throw Error(ErrorCode::Io, "cannot write " + (tmp / "decomposition.json").string());
    if (finish) finish(tmp.string());
    swap_in(tmp, out, outdir);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace dhfcast

namespace dhfcast {

namespace {

// Fills the new folder `to` with the entries of `from` but those named in `skip`: files are
// hard-linked (copied where the file system cannot link), symlinks copied as links.
void link_folder(const fs::path& from, const fs::path& to,
                 std::initializer_list<const char*> skip) {
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(from, ec)) {
    const fs::path name = e.path().filename();
    if (std::ranges::any_of(skip, [&](const char* s) { return name == s; })) continue;
    constexpr auto kTree = fs::copy_options::recursive | fs::copy_options::copy_symlinks;
    fs::copy(e.path(), to / name, kTree | fs::copy_options::create_hard_links, ec);
    if (ec) {
      fs::remove_all(to / name, ec);
      fs::copy(e.path(), to / name, kTree, ec);
    }
    if (ec) io_error("cannot copy " + e.path().string(), ec);
  }
  if (ec) io_error("cannot read " + from.string(), ec);
}

// A number of decomposition.json within +-limit; else a bad-folder error naming `field`.
double folder_number(const ordered_json& j, double limit, const std::string& field,
                     const std::string& json_name) {
  if (!j.is_number() || !(std::abs(j.get<double>()) <= limit)) {
    char range[32];
    std::snprintf(range, sizeof range, "%g", limit);
    throw Error(ErrorCode::InvalidInput,
                json_name + ": " + field + " is not a number within +-" + range);
  }
  return j.get<double>();
}

// The parts of the folder `out` as its decomposition.json lists them, each mesh read and checked
// to be a solid. Throws Error{InvalidInput} naming what is wrong before anything is built.
std::vector<Part> read_folder_parts(const fs::path& out, const ordered_json& j,
                                    const std::string& json_name) {
  auto bad = [&](const std::string& what) {
    throw Error(ErrorCode::InvalidInput, json_name + ": " + what);
  };
  std::vector<Part> parts;
  for (const auto& jp : j["parts"]) {
    const std::string where = "parts[" + std::to_string(parts.size()) + "]";
    if (!jp.is_object() || !jp.contains("id") || !jp["id"].is_number_integer() ||
        jp["id"] != parts.size())
      bad(where + " has no id " + std::to_string(parts.size()) + " (ids are 0..n-1)");
    if (!jp.contains("mesh") || !jp["mesh"].is_string()) bad(where + " has no mesh file name");
    const ordered_json& d = jp.contains("direction") ? jp["direction"] : ordered_json();
    if (!d.is_array() || d.size() != 3) bad(where + " has no direction [x, y, z]");
    Part p;
    p.id = static_cast<std::int32_t>(parts.size());
    for (int k = 0; k < 3; ++k)
      p.direction[k] = folder_number(d[k], kMaxFolderCoordinateMm, where + ".direction", json_name);
    if (!(p.direction.norm() > 0)) bad(where + ".direction is zero");
    p.direction.normalize();
    fs::path path;
    const std::string name = jp["mesh"].get<std::string>();
    if (const std::string wrong = folder_file(out, name, path); !wrong.empty())
      bad(where + " mesh " + wrong);
    p.mesh = read_mesh(path.string());
    if (const std::string problem = part_solid_problem(p.mesh); !problem.empty())
      bad(where + " mesh " + name + " is not a solid: " + problem);
    p.volume_mm3 = signed_volume(p.mesh);
    parts.push_back(std::move(p));
  }
  return parts;
}

}  // namespace

std::vector<Mold> rebuild_molds(const std::string& outdir, MoldOptions opts,
                                const FolderFinisher& finish) {
  opts.validate();
  std::error_code ec;
  // The real folder, so a symlink to it is not what gets swapped.
  const fs::path out = fs::weakly_canonical(folder_path(outdir), ec);
  const fs::path json_path = out / "decomposition.json";
  const std::string json_name = json_path.string();
  std::ifstream in(json_path, std::ios::binary);
  if (!in) throw Error(ErrorCode::Io, "cannot read " + json_name);
  const std::string text(std::istreambuf_iterator<char>(in), {});
  auto bad = [&](const std::string& what) {
    throw Error(ErrorCode::InvalidInput, json_name + ": " + what);
  };
  // Also numbers no double holds (1e400), named by their field.
  if (const std::string wrong = json_problem(text); !wrong.empty()) bad(wrong);
  ordered_json j = ordered_json::parse(text);
  if (!j.is_object() || j.value("format", "") != "dhfcast-decomposition" || !j.contains("parts") ||
      !j["parts"].is_array())
    bad("not a dhfcast decomposition (format, parts)");
  if (j.contains("parameters") && !j["parameters"].is_object()) bad("parameters is not an object");
  if (j.contains("parameters") && j["parameters"].contains("epsilon_mm")) {
    opts.epsilon_mm = folder_number(j["parameters"]["epsilon_mm"], kMaxFolderCoordinateMm,
                                    "parameters.epsilon_mm", json_name);
    if (!(opts.epsilon_mm > 0)) bad("parameters.epsilon_mm is not > 0");
  }
  if (j.contains("timings_s") && !j["timings_s"].is_object()) bad("timings_s is not an object");
  const std::vector<Part> parts = read_folder_parts(out, j, json_name);

  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Mold> molds = build_molds(parts, opts);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  for (std::size_t i = 0; i < parts.size(); ++i) j["parts"][i]["molds"] = mold_json(molds[i]);
  j["parameters"]["molds"] = mold_parameters_json(opts);
  if (j.contains("timings_s")) j["timings_s"]["molds"] = seconds;

  // The folder's new state is built whole beside it (the part files linked, not copied) and
  // swapped in with one rename: a kill or a failure leaves the old folder or the new one. A stop
  // is honoured before the folder is begun, never while it is built.
  const std::lock_guard writing(output_write_mutex());
  throw_if_stop_requested();
  remove_stale_temps(out);
  const fs::path tmp = temp_beside(out);
  try {
    if (!fs::create_directory(tmp, ec)) io_error("cannot create " + tmp.string(), ec);
    // The molds' preview and check's verdicts (check.json) are about the old molds: they are
    // left out (`dhfcast report --png` and `dhfcast check` make them again).
    link_folder(out, tmp, {"molds", "decomposition.json", "molds.png", "check.json"});
    write_mold_files(tmp.string(), molds);
    fs::create_directories(tmp / "molds", ec);
    std::ofstream f(tmp / "decomposition.json", std::ios::binary);
    f << j.dump(2) << "\n";
    f.close();
    if (!f) throw Error(ErrorCode::Io, "cannot write " + (tmp / "decomposition.json").string());
    if (finish) finish(tmp.string());
    swap_in(tmp, out, outdir);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  return molds;
}

}  // namespace dhfcast
