// check_output(): read the folder, check the contract and the solids, then run the geometric
// checks on indexed meshes; format_text() / format_json().
#include "dhfcast/check.h"

#include <oneapi/tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "check_internal.h"
#include "dhfcast/error.h"
#include "dhfcast/folder.h"
#include "dhfcast/mesh.h"
#include "dhfcast/stop.h"

namespace dhfcast {

namespace detail {

std::string format(const char* fmt, ...) {
  char text[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(text, sizeof text, fmt, args);
  va_end(args);
  return text;
}

std::string part_name(const CheckedPart& part) { return "part " + std::to_string(part.id); }

}  // namespace detail

namespace {

namespace fs = std::filesystem;
using detail::format;
using nlohmann::json;

void validate_options(const CheckOptions& o) {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw Error(ErrorCode::InvalidOptions, std::string("check: ") + what);
  };
  require(o.epsilon_mm > 0 && std::isfinite(o.epsilon_mm), "epsilon_mm must be > 0");
  require(o.input_scale > 0 && std::isfinite(o.input_scale), "input_scale must be > 0");
  require(o.input_size_mm >= 0 && std::isfinite(o.input_size_mm), "input_size_mm must be >= 0");
  require(o.json_volume_tolerance >= 0, "json_volume_tolerance must be >= 0");
  require(o.max_volume_error >= 0, "max_volume_error must be >= 0");
  require(o.coverage_samples > 0, "coverage_samples must be > 0");
  require(o.max_overlap_fraction >= 0 && o.max_gap_fraction >= 0 && o.max_outside_fraction >= 0,
          "coverage thresholds must be >= 0");
  require(o.dhf_lines > 0, "dhf_lines must be > 0");
  require(o.max_dhf_violation_fraction >= 0, "max_dhf_violation_fraction must be >= 0");
  require(o.assembly_samples >= 0, "assembly_samples must be >= 0");
  require(o.max_blocked_samples >= 0, "max_blocked_samples must be >= 0");
  require(o.mold_samples > 0, "mold_samples must be > 0");
  require(o.min_mold_surface_coverage >= 0 && o.min_mold_surface_coverage <= 1,
          "min_mold_surface_coverage must be in [0, 1]");
  require(o.fidelity_samples > 0, "fidelity_samples must be > 0");
  require(o.max_fidelity_p99_rel >= 0, "max_fidelity_p99_rel must be >= 0");
}

// --- what decomposition.json says, as far as it can be read ---

// A rigid motion [R | t]: p goes to R * p + t.
using Motion = Eigen::Matrix<double, 3, 4>;

struct PartEntry {
  std::int32_t id = -1;
  std::string mesh;
  std::optional<Vec3> direction;
  std::optional<Vec3> removal;  // removal_direction; the direction when absent
  double volume_mm3 = std::numeric_limits<double>::quiet_NaN();
  std::string mold_up, mold_down;  // both empty when the part lists no molds
  std::string mold_error;          // "molds": {"error": ...}
  // From each half's STL to the model's frame; nullopt when decomposition.json's is invalid.
  std::optional<Motion> up_to_model = Motion::Identity(), down_to_model = Motion::Identity();
  std::vector<detail::CheckedPart::Channel> channels;
  std::int32_t sprues = 0, vents = 0, keys = 0;
};

// A hole carved out of a part (carving.voids).
struct VoidEntry {
  std::int32_t part = -1;
  std::string mesh;
  double volume_mm3 = 0.0;
};

struct FolderContents {
  bool parsed = false;
  bool parts_complete = false;  // every part has an id, a mesh file and a direction
  std::vector<PartEntry> parts;
  std::vector<std::int32_t> order;  // assembly_order as written
  bool order_is_permutation = false;
  std::vector<VoidEntry> voids;
  double input_volume_mm3 = 0.0;
  std::optional<Box3> input_bbox;
  std::vector<std::string> problems;  // contract violations, in the order found
};

// A number within +-limit, or nullopt.
std::optional<double> number(const json& j, double limit) {
  if (!j.is_number() || !(std::abs(j.get<double>()) <= limit)) return std::nullopt;
  return j.get<double>();
}

// A point or direction [x, y, z] within kMaxFolderCoordinateMm, or nullopt.
std::optional<Vec3> vec3(const json& j) {
  if (!j.is_array() || j.size() != 3) return std::nullopt;
  Vec3 v;
  for (int k = 0; k < 3; ++k) {
    const std::optional<double> x = number(j[k], kMaxFolderCoordinateMm);
    if (!x) return std::nullopt;
    v[k] = *x;
  }
  return v;
}

// Reads a half's "up_to_model" / "down_to_model": three rows [r0, r1, r2, t] of numbers within
// kMaxFolderCoordinateMm whose 3x3 part is a rotation. Returns what is wrong, or "".
std::string read_motion(const json& j, Motion& m) {
  if (!j.is_array() || j.size() != 3) return "is not 3 rows [r, r, r, t]";
  for (int r = 0; r < 3; ++r) {
    if (!j[r].is_array() || j[r].size() != 4) return "is not 3 rows [r, r, r, t]";
    for (int c = 0; c < 4; ++c) {
      const std::optional<double> x = number(j[r][c], kMaxFolderCoordinateMm);
      if (!x)
        return format("has an entry that is not a number within +-%g", kMaxFolderCoordinateMm);
      m(r, c) = *x;
    }
  }
  const Eigen::Matrix3d rotation = m.leftCols<3>();
  const double off =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off > 1e-6) return format("is not rigid: its rotation is off orthonormal by %.3g", off);
  if (rotation.determinant() < 0) return "is a reflection, not a rotation";
  return {};
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorCode::Io, "cannot read " + path.string());
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw Error(ErrorCode::Io, "cannot read " + path.string());
  return text.str();
}

// Reads the part list and checks everything the contract promises about decomposition.json.
FolderContents read_contents(const fs::path& outdir, const std::string& text) {
  FolderContents c;
  auto problem = [&](const std::string& what) { c.problems.push_back(what); };
  // Also numbers no double holds (1e400), named by their field.
  if (const std::string wrong = json_problem(text); !wrong.empty()) {
    problem("decomposition.json: " + wrong);
    return c;
  }
  const json j = json::parse(text);
  if (!j.is_object()) {
    problem("decomposition.json is not a JSON object");
    return c;
  }
  c.parsed = true;
  if (!j.contains("format") || j["format"] != "dhfcast-decomposition")
    problem("format is not \"dhfcast-decomposition\"");
  if (!j.contains("version") || !j["version"].is_number_integer() || j["version"] != 1)
    problem("version is not 1");

  if (j.contains("input") && j["input"].is_object()) {
    const json& in = j["input"];
    if (in.contains("volume_mm3")) {
      if (const std::optional<double> v = number(in["volume_mm3"], kMaxFolderVolumeMm3))
        c.input_volume_mm3 = *v;
      else
        problem(format("input.volume_mm3 is not a number within +-%g", kMaxFolderVolumeMm3));
    }
    if (in.contains("bbox_mm")) {
      const json& box = in["bbox_mm"];
      const std::optional<Vec3> lo =
                                    box.is_array() && box.size() == 2 ? vec3(box[0]) : std::nullopt,
                                hi = lo ? vec3(box[1]) : std::nullopt;
      if (lo && hi && (lo->array() <= hi->array()).all())
        c.input_bbox = Box3{*lo, *hi};
      else
        problem(format("input.bbox_mm is not [[x, y, z], [x, y, z]] within +-%g, min <= max",
                       kMaxFolderCoordinateMm));
    }
  }

  // A file named in decomposition.json: "" when its name may lead out of the folder, so it is
  // never opened.
  auto file_in_folder = [&](const std::string& file, const std::string& what) -> std::string {
    fs::path path;
    if (const std::string wrong = folder_file(outdir, file, path); !wrong.empty()) {
      problem(what + " " + wrong);
      return {};
    }
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) problem(what + " " + file + " does not exist");
    return file;
  };
  if (!j.contains("parts") || !j["parts"].is_array() || j["parts"].empty()) {
    problem("no parts array");
    return c;
  }
  c.parts_complete = true;
  for (std::size_t i = 0; i < j["parts"].size(); ++i) {
    const json& jp = j["parts"][i];
    const std::string where = "parts[" + std::to_string(i) + "]";
    PartEntry p;
    if (!jp.is_object()) {
      problem(where + " is not an object");
      c.parts_complete = false;
      c.parts.push_back(p);
      continue;
    }
    if (jp.contains("id") && jp["id"].is_number_integer() && jp["id"].get<std::int64_t>() >= 0 &&
        jp["id"].get<std::int64_t>() < std::numeric_limits<std::int32_t>::max())
      p.id = jp["id"].get<std::int32_t>();
    else
      problem(where + " has no integer id >= 0");
    if (jp.contains("mesh") && jp["mesh"].is_string()) {
      p.mesh = file_in_folder(jp["mesh"].get<std::string>(), where + " mesh");
    } else {
      problem(where + " has no mesh file name");
    }
    p.direction = jp.contains("direction") ? vec3(jp["direction"]) : std::nullopt;
    if (!p.direction)
      problem(where + " has no direction [x, y, z]");
    else if (std::abs(p.direction->norm() - 1.0) >= 1e-6)
      problem(where + format(" direction has length %.9g, not 1", p.direction->norm()));
    if (p.direction && p.direction->norm() == 0.0) p.direction.reset();
    if (jp.contains("removal_direction")) {
      p.removal = vec3(jp["removal_direction"]);
      if (!p.removal)
        problem(where + " removal_direction is not [x, y, z]");
      else if (std::abs(p.removal->norm() - 1.0) >= 1e-6)
        problem(where + format(" removal_direction has length %.9g, not 1", p.removal->norm()));
      if (p.removal && p.removal->norm() == 0.0) p.removal.reset();
    }
    if (const std::optional<double> v = jp.contains("volume_mm3")
                                            ? number(jp["volume_mm3"], kMaxFolderVolumeMm3)
                                            : std::nullopt)
      p.volume_mm3 = *v;
    else
      problem(where + format(" has no volume_mm3 within +-%g", kMaxFolderVolumeMm3));
    if (jp.contains("molds")) {
      const json& m = jp["molds"];
      if (m.is_object() && m.contains("error") && m["error"].is_string()) {
        p.mold_error = m["error"].get<std::string>();
        if (p.mold_error.empty()) problem(where + " molds error is empty");
      } else if (m.is_object() && m.contains("up") && m["up"].is_string() && m.contains("down") &&
                 m["down"].is_string()) {
        p.mold_up = file_in_folder(m["up"].get<std::string>(), where + " mold");
        p.mold_down = file_in_folder(m["down"].get<std::string>(), where + " mold");
        if (p.mold_up.empty() || p.mold_down.empty()) p.mold_up = p.mold_down = {};
        // Halves are written in their print frames; a folder without the motions (written
        // before they were) has them in the model's frame.
        for (auto [key, motion] : {std::pair{"up_to_model", &p.up_to_model},
                                   std::pair{"down_to_model", &p.down_to_model}}) {
          if (!m.contains(key)) continue;
          const std::string wrong = read_motion(m[key], **motion);
          if (wrong.empty()) continue;
          problem(where + " molds." + key + " " + wrong);
          motion->reset();
        }
        for (const char* kind : {"sprues", "vents"}) {
          if (!m.contains(kind)) continue;
          if (!m[kind].is_array()) {
            problem(where + " molds." + kind + " is not an array");
            continue;
          }
          for (const json& c : m[kind]) {
            const std::optional<Vec3> mouth =
                c.is_object() && c.contains("mouth") ? vec3(c["mouth"]) : std::nullopt;
            const std::optional<Vec3> exit =
                c.is_object() && c.contains("exit") ? vec3(c["exit"]) : std::nullopt;
            const double diameter =
                c.is_object() && c.contains("diameter_mm")
                    ? number(c["diameter_mm"], kMaxFolderCoordinateMm).value_or(0)
                    : 0;
            if (!mouth || !exit || !(diameter > 0)) {
              problem(where + " molds." + kind +
                      " has an entry without mouth, exit and diameter_mm > 0");
              continue;
            }
            p.channels.push_back({*mouth, *exit, diameter});
            (std::string(kind) == "sprues" ? p.sprues : p.vents)++;
          }
        }
        if (m.contains("keys")) {
          if (m["keys"].is_array())
            p.keys = static_cast<std::int32_t>(m["keys"].size());
          else
            problem(where + " molds.keys is not an array");
        }
      } else {
        problem(where + " molds is not {\"up\": file, \"down\": file, ...} or {\"error\": text}");
      }
    }
    if (p.id < 0 || p.mesh.empty() || !p.direction) c.parts_complete = false;
    c.parts.push_back(p);
  }

  const auto n = static_cast<std::int32_t>(c.parts.size());
  std::set<std::int32_t> ids;
  for (const PartEntry& p : c.parts)
    if (p.id >= 0) ids.insert(p.id);
  const bool ids_ok = static_cast<std::int32_t>(ids.size()) == n &&
                      (ids.empty() || (*ids.begin() == 0 && *ids.rbegin() == n - 1));
  if (!ids_ok) problem(format("part ids are not 0..%d, each once", n - 1));

  // Holes carved out of parts (absent in folders written before carving existed).
  if (j.contains("carving")) {
    const json& carving = j["carving"];
    if (!carving.is_object() || !carving.contains("voids") || !carving["voids"].is_array()) {
      problem("carving has no voids array");
    } else {
      for (std::size_t i = 0; i < carving["voids"].size(); ++i) {
        const json& jv = carving["voids"][i];
        const std::string where = "carving.voids[" + std::to_string(i) + "]";
        VoidEntry v;
        if (!jv.is_object() || !jv.contains("part") || !jv["part"].is_number_integer() ||
            !ids.contains(jv["part"].get<std::int32_t>()) || !jv.contains("mesh") ||
            !jv["mesh"].is_string() || !jv.contains("volume_mm3") ||
            !(number(jv["volume_mm3"], kMaxFolderVolumeMm3).value_or(0) > 0)) {
          problem(where + " is not {\"part\": id, \"mesh\": file, \"volume_mm3\": > 0}");
          continue;
        }
        v.part = jv["part"].get<std::int32_t>();
        v.mesh = file_in_folder(jv["mesh"].get<std::string>(), where + " mesh");
        v.volume_mm3 = jv["volume_mm3"].get<double>();
        if (!v.mesh.empty()) c.voids.push_back(v);
      }
    }
  }

  if (!j.contains("assembly_order") || !j["assembly_order"].is_array()) {
    problem("no assembly_order array");
  } else {
    bool integers = true;
    for (const json& e : j["assembly_order"]) {
      if (e.is_number_integer() && std::abs(e.get<std::int64_t>()) < (1 << 30))
        c.order.push_back(e.get<std::int32_t>());
      else
        integers = false;
    }
    std::vector<std::int32_t> sorted = c.order;
    std::sort(sorted.begin(), sorted.end());
    c.order_is_permutation = integers && ids_ok && std::ranges::equal(sorted, ids);
    if (!c.order_is_permutation) {
      std::string list;
      for (const json& e : j["assembly_order"]) {
        if (!list.empty()) list += ", ";
        list += e.dump();
      }
      problem("assembly_order [" + list + "] is not a permutation of the part ids");
    }
  }
  return c;
}

CheckItem contract_item(const FolderContents& c) {
  CheckItem item;
  item.name = "contract";
  item.passed = c.problems.empty();
  item.figures = {{"parts", static_cast<double>(c.parts.size())},
                  {"problems", static_cast<double>(c.problems.size())}};
  if (item.passed) {
    std::string order;
    for (std::int32_t id : c.order) {
      order += ' ';
      order += std::to_string(id);
    }
    item.summary = format("dhfcast-decomposition v1, %zu part%s, assembly order%s, files present",
                          c.parts.size(), c.parts.size() == 1 ? "" : "s", order.c_str());
  } else {
    item.summary = c.problems.front();
    if (c.problems.size() > 1) item.summary += format(" (and %zu more)", c.problems.size() - 1);
  }
  return item;
}

// --- meshes ---

struct LoadedMesh {
  enum class Kind { Part, MoldUp, MoldDown, Void };
  std::string file;  // as named in decomposition.json
  Kind kind = Kind::Part;
  bool is_part() const { return kind == Kind::Part; }
  std::int32_t part = 0;        // index into FolderContents::parts (voids: into ::voids)
  std::optional<TriMesh> mesh;  // mold halves: moved to the model's frame
  std::optional<Motion> to_model = Motion::Identity();  // mold halves: from the file's frame
  std::string problem;        // why it is not a valid solid ("" when it is)
  double volume_error = 0.0;  // parts: |json - mesh| / |mesh|
  bool volume_ok = true;      // within the tolerance
};

std::string mold_problem(const TriMesh& mesh) {
  const MeshDiagnostics d = validate_mesh(mesh);
  if (!d.ok()) return d.first_problem;
  if (d.volume_mm3 <= 0) return format("inward oriented (volume %.6g mm3)", d.volume_mm3);
  return {};
}

// How much the volume can change when the vertices are rounded to float (STL files): each moves
// by less than 2^-23 of the largest coordinate, sweeping at most that times the area.
double float_rounding_mm3(const TriMesh& mesh) {
  double area = 0.0, largest = 0.0;
  for (const Tri& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    area += 0.5 * (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).norm();
  }
  for (const Vec3& p : mesh.vertices) largest = std::max(largest, p.cwiseAbs().maxCoeff());
  return area * largest * 0x1p-23;
}

std::vector<LoadedMesh> load_meshes(const fs::path& outdir, const FolderContents& c,
                                    const CheckOptions& o) {
  std::vector<LoadedMesh> meshes;
  for (std::size_t i = 0; i < c.parts.size(); ++i) {
    const PartEntry& p = c.parts[i];
    const auto part = static_cast<std::int32_t>(i);
    auto add = [&](const std::string& file, LoadedMesh::Kind kind,
                   const std::optional<Motion>& to_model) {
      LoadedMesh m;
      m.file = file;
      m.kind = kind;
      m.part = part;
      m.to_model = to_model;
      meshes.push_back(std::move(m));
    };
    if (!p.mesh.empty()) add(p.mesh, LoadedMesh::Kind::Part, Motion::Identity());
    if (!p.mold_up.empty()) {
      add(p.mold_up, LoadedMesh::Kind::MoldUp, p.up_to_model);
      add(p.mold_down, LoadedMesh::Kind::MoldDown, p.down_to_model);
    }
  }
  for (std::size_t i = 0; i < c.voids.size(); ++i) {
    LoadedMesh m;
    m.file = c.voids[i].mesh;
    m.kind = LoadedMesh::Kind::Void;
    m.part = static_cast<std::int32_t>(i);
    meshes.push_back(std::move(m));
  }
  tbb::parallel_for(std::size_t{0}, meshes.size(), [&](std::size_t i) {
    LoadedMesh& m = meshes[i];
    try {
      m.mesh = read_mesh((outdir / m.file).string());
    } catch (const Error& e) {
      m.problem = e.what();
      return;
    }
    // Far-off coordinates (an STL float reaches 3e38) would overflow the checks' grids.
    for (const Vec3& v : m.mesh->vertices)
      if (v.allFinite() && v.cwiseAbs().maxCoeff() > kMaxFolderCoordinateMm) {
        m.problem = format("a vertex lies beyond +-%g mm", kMaxFolderCoordinateMm);
        m.mesh.reset();
        return;
      }
    const bool solid = m.is_part() || m.kind == LoadedMesh::Kind::Void;
    m.problem = solid ? part_solid_problem(*m.mesh) : mold_problem(*m.mesh);
    if (m.to_model)
      for (Vec3& v : m.mesh->vertices) v = m.to_model->leftCols<3>() * v + m.to_model->col(3);
    const double json_volume =
        m.kind == LoadedMesh::Kind::Void ? c.voids[m.part].volume_mm3 : c.parts[m.part].volume_mm3;
    if (solid && std::isfinite(json_volume)) {
      const double v = signed_volume(*m.mesh);
      m.volume_error = std::abs(json_volume - v) / std::max(std::abs(v), 1e-300);
      m.volume_ok = std::abs(json_volume - v) <=
                    o.json_volume_tolerance * std::abs(v) + float_rounding_mm3(*m.mesh);
    }
  });
  return meshes;
}

CheckItem solids_item(const std::vector<LoadedMesh>& meshes) {
  CheckItem item;
  item.name = "solids";
  std::int64_t parts = 0, molds = 0, voids = 0, bad = 0;
  double worst_volume_error = 0.0;
  std::string first;
  for (const LoadedMesh& m : meshes) {
    (m.kind == LoadedMesh::Kind::Void ? voids : m.is_part() ? parts : molds)++;
    worst_volume_error = std::max(worst_volume_error, m.volume_error);
    std::string problem = m.problem;
    if (problem.empty() && !m.volume_ok)
      problem = format("volume_mm3 in decomposition.json is off by %.3g (relative) from the mesh's",
                       m.volume_error);
    if (problem.empty()) continue;
    if (bad++ == 0) first = m.file + ": " + problem;
  }
  item.passed = !meshes.empty() && bad == 0;
  item.figures = {{"part_meshes", static_cast<double>(parts)},
                  {"mold_meshes", static_cast<double>(molds)},
                  {"void_meshes", static_cast<double>(voids)},
                  {"bad_meshes", static_cast<double>(bad)},
                  {"max_volume_error", worst_volume_error}};
  if (meshes.empty())
    item.summary = "no part meshes to check";
  else if (bad == 0)
    item.summary =
        format("%lld part%s%s%s: closed, oriented, outward; json volumes match (%.2g relative)",
               static_cast<long long>(parts), parts == 1 ? "" : "s",
               molds ? format(", %lld mold halves", static_cast<long long>(molds)).c_str() : "",
               voids ? format(", %lld carved voids", static_cast<long long>(voids)).c_str() : "",
               worst_volume_error);
  else
    item.summary =
        first + (bad > 1 ? format(" (and %lld more)", static_cast<long long>(bad - 1)) : "");
  return item;
}

CheckItem skipped(const std::string& name, const std::string& why) {
  CheckItem item;
  item.name = name;
  item.skipped = true;
  item.summary = why;
  return item;
}

}  // namespace

bool CheckReport::passed() const {
  return std::ranges::all_of(items, [](const CheckItem& i) { return i.skipped || i.passed; });
}

namespace {

// decomposition.json of the folder `outdir`. Throws Error{Io} when there is none.
std::string read_decomposition_json(const fs::path& outdir) {
  std::error_code ec;
  if (!fs::is_directory(outdir, ec))
    throw Error(ErrorCode::Io, outdir.string() + " is not a folder");
  return read_file(outdir / "decomposition.json");
}

}  // namespace

CheckItem check_contract(const std::string& outdir) {
  return contract_item(read_contents(outdir, read_decomposition_json(outdir)));
}

CheckReport check_output(const CheckOptions& options) {
  validate_options(options);
  const fs::path outdir(options.outdir);
  const std::string text = read_decomposition_json(outdir);

  detail::CheckContext context;
  context.options = options;
  CheckReport report;
  const FolderContents contents = read_contents(outdir, text);
  if (!options.input_mesh.empty()) {
    LoadOptions load;
    load.scale = options.input_scale;
    load.size_mm = options.input_size_mm;
    const TriMesh input = load_solid(options.input_mesh, load).mesh;
    // A mesh decomposed with --scale or --units and checked without them would give figures
    // that mean nothing.
    const double volume = signed_volume(input), decomposed = contents.input_volume_mm3;
    if (decomposed > 0 && std::abs(volume - decomposed) > 1e-3 * decomposed)
      throw Error(ErrorCode::InvalidInput,
                  format("%s: volume %.6g mm3, but the folder was decomposed from a solid of "
                         "%.6g mm3 (give check the --scale and --units given to decompose)",
                         options.input_mesh.c_str(), volume, decomposed));
    context.input.emplace(input);
  }
  report.items.push_back(contract_item(contents));
  throw_if_stop_requested();
  const std::vector<LoadedMesh> meshes = load_meshes(outdir, contents, options);
  report.items.push_back(solids_item(meshes));

  // --- the geometric checks need every part mesh and its direction ---
  auto usable = [](const LoadedMesh& m) { return m.mesh && !m.mesh->triangles.empty(); };
  std::string cannot_run;
  if (!contents.parsed)
    cannot_run = "decomposition.json could not be read";
  else if (!contents.parts_complete)
    cannot_run = "the parts list is incomplete (see contract)";
  for (const LoadedMesh& m : meshes)
    if (cannot_run.empty() && (m.is_part() || m.kind == LoadedMesh::Kind::Void) && !usable(m))
      cannot_run = m.file + " could not be read (see solids)";
  const char* kGeometric[] = {"coverage", "dhf", "assembly", "molds", "fidelity"};
  if (!cannot_run.empty()) {
    for (const char* name : kGeometric) report.items.push_back(skipped(name, cannot_run));
    return report;
  }

  context.json_input_volume_mm3 = contents.input_volume_mm3;
  context.json_input_bbox = contents.input_bbox;
  // Indices are built in parallel, one mesh each; each is read-only afterwards.
  std::vector<std::optional<detail::SurfaceIndex>> indices(meshes.size());
  tbb::parallel_for(std::size_t{0}, meshes.size(), [&](std::size_t i) {
    // A half that cannot be placed (see contract) is left out like an unreadable one.
    if (usable(meshes[i]) && meshes[i].to_model) indices[i].emplace(*meshes[i].mesh);
  });
  // Each part's mesh comes first in `meshes`, followed by its mold halves (up, down).
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    const LoadedMesh& m = meshes[i];
    if (m.is_part()) {
      const PartEntry& entry = contents.parts[m.part];
      context.parts.push_back(detail::CheckedPart{
          .id = entry.id,
          .mesh_file = entry.mesh,
          .direction = entry.direction->normalized(),
          .removal = entry.removal.value_or(*entry.direction).normalized(),
          .volume_mm3 = std::isfinite(entry.volume_mm3) ? entry.volume_mm3 : signed_volume(*m.mesh),
          .solid = std::move(*indices[i]),
          .molds_listed = !entry.mold_up.empty() || !entry.mold_error.empty(),
          .mold_error = entry.mold_error,
          .channels = entry.channels,
          .sprues = entry.sprues,
          .vents = entry.vents,
          .keys = entry.keys,
          .mold_up = std::nullopt,
          .mold_down = std::nullopt});
    } else if (m.kind == LoadedMesh::Kind::Void) {
      const VoidEntry& v = contents.voids[m.part];
      context.voids.push_back({v.part, v.volume_mm3, std::move(*indices[i])});
    } else if (indices[i]) {
      (m.kind == LoadedMesh::Kind::MoldUp ? context.parts.back().mold_up
                                          : context.parts.back().mold_down) =
          std::move(*indices[i]);
    }
  }
  if (contents.order_is_permutation) {
    std::map<std::int32_t, std::int32_t> index_of_id;
    for (std::size_t i = 0; i < context.parts.size(); ++i)
      index_of_id[context.parts[i].id] = static_cast<std::int32_t>(i);
    for (std::int32_t id : contents.order) context.order.push_back(index_of_id.at(id));
  }

  // A stop (--timeout) is honoured between the checks.
  for (auto* check : {&detail::check_coverage, &detail::check_dhf, &detail::check_assembly,
                      &detail::check_molds, &detail::check_fidelity}) {
    throw_if_stop_requested();
    report.items.push_back(check(context));
  }
  return report;
}

std::string format_text(const CheckReport& report) {
  std::string out;
  std::vector<std::string> failed;
  int skipped_count = 0;
  for (const CheckItem& item : report.items) {
    const char* status = item.skipped ? "SKIP" : item.passed ? "PASS" : "FAIL";
    out += format("%s %-9s %s\n", status, item.name.c_str(), item.summary.c_str());
    if (item.skipped)
      ++skipped_count;
    else if (!item.passed)
      failed.push_back(item.name);
  }
  const int ran = static_cast<int>(report.items.size()) - skipped_count;
  if (failed.empty()) {
    out += format("PASS: %d check%s passed", ran, ran == 1 ? "" : "s");
  } else {
    std::string names;
    for (const std::string& n : failed) {
      if (!names.empty()) names += ", ";
      names += n;
    }
    out += format("FAIL: %zu of %d checks failed (%s)", failed.size(), ran, names.c_str());
  }
  out += skipped_count ? format(", %d skipped\n", skipped_count) : "\n";
  return out;
}

std::string format_json(const CheckReport& report) {
  nlohmann::ordered_json checks = nlohmann::ordered_json::array();
  for (const CheckItem& item : report.items) {
    nlohmann::ordered_json figures = nlohmann::ordered_json::object();
    for (const auto& [key, value] : item.figures) figures[key] = value;
    checks.push_back({{"name", item.name},
                      {"status", item.skipped  ? "skip"
                                 : item.passed ? "pass"
                                               : "fail"},
                      {"summary", item.summary},
                      {"figures", figures}});
    if (item.at) checks.back()["at"] = {item.at->x(), item.at->y(), item.at->z()};
  }
  const nlohmann::ordered_json j = {{"passed", report.passed()}, {"checks", checks}};
  // Messages may quote bytes of the folder's files that are no UTF-8.
  return j.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) + "\n";
}

}  // namespace dhfcast
