#include "dhfcast/viewer.h"

#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "dhfcast/check.h"
#include "dhfcast/error.h"
#include "dhfcast/folder.h"
#include "dhfcast/mesh.h"
#include "report_page.h"

namespace fs = std::filesystem;
using nlohmann::ordered_json;

namespace dhfcast {

namespace {

// Where the page's data goes in the template (src/viewer/report_template.html).
constexpr std::string_view kDataMarker = "@DHFCAST_REPORT_DATA@";

// Distinct part colours (the first ten: Tableau 10); beyond, hues a golden angle apart.
std::string part_color(std::size_t index) {
  static const char* kPalette[] = {"#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                                   "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#17becf"};
  if (index < std::size(kPalette)) return kPalette[index];
  const double hue = std::fmod(index * 137.50776405, 360.0) / 60.0;
  const double lightness = index % 2 ? 0.45 : 0.62, chroma = 0.55;
  const double x = chroma * (1 - std::abs(std::fmod(hue, 2.0) - 1));
  const double rgb_by_sector[6][3] = {{chroma, x, 0}, {x, chroma, 0}, {0, chroma, x},
                                      {0, x, chroma}, {x, 0, chroma}, {chroma, 0, x}};
  const double* rgb = rgb_by_sector[static_cast<int>(hue) % 6];
  char text[8];
  auto channel = [&](int k) {
    return static_cast<int>(
        std::lround(255 * std::clamp(rgb[k] + lightness - chroma / 2, 0.0, 1.0)));
  };
  std::snprintf(text, sizeof text, "#%02x%02x%02x", channel(0), channel(1), channel(2));
  return text;
}

std::string base64(const std::vector<unsigned char>& bytes) {
  static constexpr char kDigits[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::uint32_t n = bytes[i] << 16 | (i + 1 < bytes.size() ? bytes[i + 1] << 8 : 0) |
                            (i + 2 < bytes.size() ? bytes[i + 2] : 0);
    out += kDigits[n >> 18 & 63];
    out += kDigits[n >> 12 & 63];
    out += i + 1 < bytes.size() ? kDigits[n >> 6 & 63] : '=';
    out += i + 2 < bytes.size() ? kDigits[n & 63] : '=';
  }
  return out;
}

template <typename T>
void append_little_endian(std::vector<unsigned char>& out, T value) {
  for (std::size_t b = 0; b < sizeof(T); ++b)
    out.push_back(static_cast<unsigned char>(value >> 8 * b));
}

// A mesh as the page decodes it: positions quantized to 16 bits over the mesh's bounding box
// (x = min + q * step), then the triangles' vertex indices; both delta-coded (positions wrap
// around 2^16, indices as 32-bit differences) so that zlib finds the repetition, then deflated
// and base64-coded. A step is 1/65535 of the mesh's size (1.5 um on 100 mm): far below a pixel.
ordered_json encoded_mesh(const TriMesh& mesh) {
  Box3 box;
  if (!mesh.vertices.empty()) box = bounding_box(mesh.vertices);
  Vec3 step = (box.max - box.min) / 65535.0;
  for (int k = 0; k < 3; ++k)
    if (!(step[k] > 0)) step[k] = 1.0;
  std::vector<unsigned char> raw;
  raw.reserve(mesh.vertices.size() * 6 + mesh.triangles.size() * 12);
  std::uint16_t previous[3] = {0, 0, 0};
  for (const Vec3& v : mesh.vertices)
    for (int k = 0; k < 3; ++k) {
      const auto q = static_cast<std::uint16_t>(
          std::clamp(std::lround((v[k] - box.min[k]) / step[k]), 0L, 65535L));
      append_little_endian(raw, static_cast<std::uint16_t>(q - previous[k]));
      previous[k] = q;
    }
  std::uint32_t previous_index = 0;
  for (const Tri& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const auto index = static_cast<std::uint32_t>(t[k]);
      append_little_endian(raw, static_cast<std::uint32_t>(index - previous_index));
      previous_index = index;
    }
  uLongf size = compressBound(raw.size());
  std::vector<unsigned char> packed(size);
  if (compress2(packed.data(), &size, raw.data(), raw.size(), Z_DEFAULT_COMPRESSION) != Z_OK)
    throw Error(ErrorCode::Internal, "zlib could not compress a mesh for report.html");
  packed.resize(size);
  return {{"vertices", mesh.vertices.size()},
          {"triangles", mesh.triangles.size()},
          {"min", {box.min.x(), box.min.y(), box.min.z()}},
          {"step", {step.x(), step.y(), step.z()}},
          {"data", base64(packed)}};
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorCode::Io, "cannot read " + path.string());
  std::string text(std::istreambuf_iterator<char>(in), {});
  if (in.bad()) throw Error(ErrorCode::Io, "cannot read " + path.string());
  return text;
}

// Reads the page's view of the folder. The contract check has passed: the fields it checks are
// there with the right types, and every file it names is in the folder.
class FolderReader {
 public:
  explicit FolderReader(fs::path folder) : folder_(std::move(folder)) {}

  // The mesh file `name` of decomposition.json, encoded. Throws Error{InvalidInput} naming it
  // when it cannot be read.
  ordered_json mesh(const std::string& name) const {
    fs::path path;
    if (const std::string wrong = folder_file(folder_, name, path); !wrong.empty())
      throw Error(ErrorCode::InvalidInput, where() + wrong);
    try {
      return encoded_mesh(read_mesh(path.string()));
    } catch (const Error& e) {
      throw Error(ErrorCode::InvalidInput, where() + "cannot read " + name + ": " + e.what());
    }
  }

  std::string where() const { return (folder_ / "decomposition.json").string() + ": "; }

 private:
  fs::path folder_;
};

// What the page shows about the molds of part `jp`, with the halves' meshes.
ordered_json molds_view(const ordered_json& molds, const FolderReader& reader) {
  if (molds.contains("error")) return {{"error", molds["error"]}};
  ordered_json view = ordered_json::object();
  for (const char* key : {"up_to_model", "down_to_model", "gravity_up", "sprues", "vents", "keys"})
    if (molds.contains(key)) view[key] = molds[key];
  view["up"] = reader.mesh(molds["up"].get<std::string>());
  view["down"] = reader.mesh(molds["down"].get<std::string>());
  return view;
}

// Warnings and notes as `decompose` prints them, from what decomposition.json records.
ordered_json folder_warnings(const ordered_json& j) {
  ordered_json out = ordered_json::array();
  if (j.contains("warnings") && j["warnings"].is_array())
    for (const ordered_json& w : j["warnings"])
      if (w.is_string()) out.push_back(w);
  if (j.value("assembly_found", true) == false)
    out.push_back(j.value("assembly_message", std::string("no collision-free assembly order")));
  for (const ordered_json& p : j["parts"]) {
    const std::string part = "part " + std::to_string(p["id"].get<std::int64_t>());
    if (p.contains("molds") && p["molds"].contains("error"))
      out.push_back("no mold for " + part + ": " + p["molds"]["error"].get<std::string>());
    if (p.contains("cut_problem") && p["cut_problem"].is_string())
      out.push_back(part + " was not cut from the input: " + p["cut_problem"].get<std::string>());
  }
  if (j.contains("carving") && j["carving"].is_object()) {
    const ordered_json& carving = j["carving"];
    const auto gap_lines = carving.value("gap_lines_after", std::int64_t{0});
    if (gap_lines > 0)
      out.push_back(std::to_string(gap_lines) +
                    " lines along their part's direction still meet it more than once "
                    "(carving.refused)");
    for (const ordered_json& v : carving["voids"]) {
      char text[160];
      std::snprintf(text, sizeof text, "carved a %.3g mm3 hole inside part %lld (glue around it)",
                    v["volume_mm3"].get<double>(),
                    static_cast<long long>(v["part"].get<std::int64_t>()));
      out.push_back(text);
    }
  }
  if (j.contains("inaccessible_regions") && j["inaccessible_regions"].is_array())
    for (const ordered_json& r : j["inaccessible_regions"]) {
      char text[160];
      std::snprintf(text, sizeof text,
                    "%lld tets (%.1f mm3) are accessible from no direction; that region was "
                    "decomposed on its own",
                    static_cast<long long>(r.value("tets", std::int64_t{0})),
                    r.value("volume_mm3", 0.0));
      out.push_back(text);
    }
  return out;
}

// The checks of `dhfcast check --json`, as the page lists them. Throws Error{InvalidInput} when
// `text` is not that.
ordered_json checks_view(const std::string& text, const std::string& name) {
  auto bad = [&](const std::string& what) {
    throw Error(ErrorCode::InvalidInput, name + ": " + what);
  };
  if (const std::string wrong = json_problem(text); !wrong.empty()) bad(wrong);
  const ordered_json j = ordered_json::parse(text);
  if (!j.is_object() || !j.contains("checks") || !j["checks"].is_array())
    bad("is not dhfcast check's --json output (no checks array)");
  ordered_json checks = ordered_json::array();
  for (const ordered_json& c : j["checks"]) {
    if (!c.is_object() || !c.contains("name") || !c["name"].is_string() || !c.contains("status") ||
        !c["status"].is_string() || !c.contains("summary") || !c["summary"].is_string())
      bad("a check has no name, status and summary");
    ordered_json view = {{"name", c["name"]}, {"status", c["status"]}, {"summary", c["summary"]}};
    if (c.contains("at")) {
      const ordered_json& at = c["at"];
      if (!at.is_array() || at.size() != 3 || !std::ranges::all_of(at, [](const ordered_json& x) {
            return x.is_number() && std::abs(x.get<double>()) <= kMaxFolderCoordinateMm;
          }))
        bad("check " + c["name"].get<std::string>() + ": at is not [x, y, z]");
      view["at"] = at;
    }
    checks.push_back(view);
  }
  return {{"passed", j.value("passed", false)}, {"checks", checks}};
}

// The page, as report_html() returns it.
std::string report_page(const std::string& folder_name, const std::string& check_json) {
  const fs::path folder(folder_name);
  // The folder is read as `dhfcast check` reads it: a bad one fails here, before any mesh.
  const CheckItem contract = check_contract(folder_name);
  const FolderReader reader(folder);
  if (!contract.passed) throw Error(ErrorCode::InvalidInput, reader.where() + contract.summary);
  const ordered_json j = ordered_json::parse(read_text(folder / "decomposition.json"));

  ordered_json data;
  data["input"] = j.value("input", ordered_json::object());
  data["parameters"] = j.value("parameters", ordered_json::object());
  data["timings_s"] = j.value("timings_s", ordered_json::object());
  ordered_json parts = ordered_json::array();
  for (const ordered_json& jp : j["parts"]) {
    ordered_json part = {{"id", jp["id"]}, {"color", part_color(parts.size())}};
    for (const char* key :
         {"direction", "removal_direction", "volume_mm3", "blocked_by", "region", "carved_mm3"})
      if (jp.contains(key)) part[key] = jp[key];
    part["mesh"] = reader.mesh(jp["mesh"].get<std::string>());
    if (jp.contains("molds")) part["molds"] = molds_view(jp["molds"], reader);
    parts.push_back(part);
  }
  data["parts"] = parts;
  data["assembly_order"] = j["assembly_order"];
  data["assembly_found"] = j.value("assembly_found", true);
  if (j.contains("assembly_message")) data["assembly_message"] = j["assembly_message"];
  data["inaccessible_regions"] = j.value("inaccessible_regions", ordered_json::array());
  ordered_json voids = ordered_json::array();
  if (j.contains("carving"))
    for (const ordered_json& v : j["carving"]["voids"])
      voids.push_back({{"part", v["part"]},
                       {"volume_mm3", v["volume_mm3"]},
                       {"mesh", reader.mesh(v["mesh"].get<std::string>())}});
  data["voids"] = voids;
  data["warnings"] = folder_warnings(j);

  std::string checks_text = check_json, checks_name = "check results";
  fs::path check_path;
  std::error_code ec;
  if (checks_text.empty() && folder_file(folder, "check.json", check_path).empty() &&
      fs::is_regular_file(check_path, ec)) {
    checks_text = read_text(check_path);
    checks_name = check_path.string();
  }
  data["checks"] = checks_text.empty() ? ordered_json() : checks_view(checks_text, checks_name);

  // The data sits in a <script> element: no "</script" or "<!--" may end or bend it. '<' appears
  // in JSON only inside strings, where "\u003c" reads the same.
  const std::string dumped = data.dump(-1, ' ', false, ordered_json::error_handler_t::replace);
  std::string json;
  json.reserve(dumped.size());
  for (const char c : dumped) {
    if (c == '<')
      json += "\\u003c";
    else
      json += c;
  }
  const std::string_view page = report_page_template();
  const std::size_t marker = page.find(kDataMarker);
  std::string html;
  html.reserve(page.size() + json.size());
  html.append(page.substr(0, marker)).append(json).append(page.substr(marker + kDataMarker.size()));
  return html;
}

}  // namespace

std::string report_html(const std::string& folder, const std::string& check_json) {
  try {
    return report_page(folder, check_json);
  } catch (const nlohmann::json::exception& e) {
    // A field the contract check does not cover has an unexpected type.
    throw Error(ErrorCode::InvalidInput,
                (fs::path(folder) / "decomposition.json").string() + ": " + e.what());
  }
}

void write_report(const std::string& folder, const std::string& check_json) {
  const std::string html = report_html(folder, check_json);
  const fs::path path = fs::path(folder) / "report.html";
  const fs::path tmp =
      fs::path(folder) / (".report.html.dhfcast-tmp-" + std::to_string(::getpid()));
  std::ofstream f(tmp, std::ios::binary);
  f << html;
  f.close();
  std::error_code ec;
  if (!f) {
    fs::remove(tmp, ec);
    throw Error(ErrorCode::Io, "cannot write " + tmp.string());
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw Error(ErrorCode::Io, "cannot write " + path.string() + ": " + ec.message());
  }
}

}  // namespace dhfcast
