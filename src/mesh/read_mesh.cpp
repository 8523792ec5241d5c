// read_mesh(): load the file, pick the parser by extension, weld coincident vertices.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <numeric>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "readers.h"

namespace dhfcast {

namespace detail {

void fail_input(const std::string& path, const std::string& location, const std::string& what) {
  throw Error(ErrorCode::InvalidInput,
              location.empty() ? path + ": " + what : path + ": " + location + ": " + what);
}

std::string line_location(std::int64_t line) { return "line " + std::to_string(line); }

std::string quoted(std::string_view token) {
  constexpr std::size_t kMaxChars = 24;
  std::string out = "'";
  for (std::size_t i = 0; i < token.size() && i < kMaxChars; ++i) {
    const unsigned char c = static_cast<unsigned char>(token[i]);
    out += std::isprint(c) ? static_cast<char>(c) : '?';
  }
  if (token.size() > kMaxChars) out += "...";
  return out + "'";
}

bool parse_double(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  // Out-of-range literals: strtod gives +-inf (reported by validate_mesh()) or an underflow.
  if (ec == std::errc::result_out_of_range && ptr == end) {
    value = std::strtod(std::string(token).c_str(), nullptr);
    return true;
  }
  return ec == std::errc() && ptr == end && !token.empty();
}

bool parse_int(std::string_view token, std::int64_t& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end && !token.empty();
}

void add_polygon(Soup& soup, std::span<const std::int32_t> corners) {
  for (std::size_t k = 1; k + 1 < corners.size(); ++k)
    soup.triangles.push_back({corners[0], corners[k], corners[k + 1]});
}

bool TextLines::next(std::string_view& line) {
  if (pos_ >= text_.size()) return false;
  const std::size_t eol = text_.find('\n', pos_);
  const std::size_t end = eol == std::string_view::npos ? text_.size() : eol;
  line = text_.substr(pos_, end - pos_);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos_ = eol == std::string_view::npos ? text_.size() : eol + 1;
  ++line_;
  return true;
}

bool Tokens::next(std::string_view& token) {
  constexpr std::string_view kBlanks = " \t\r\f\v";
  const std::size_t start = rest_.find_first_not_of(kBlanks);
  if (start == std::string_view::npos) {
    rest_ = {};
    return false;
  }
  const std::size_t end = std::min(rest_.find_first_of(kBlanks, start), rest_.size());
  token = rest_.substr(start, end - start);
  rest_.remove_prefix(end);
  return true;
}

bool TokenStream::next(std::string_view& token) {
  while (!tokens_.next(token)) {
    std::string_view line;
    if (!lines_.next(line)) return false;
    tokens_ = Tokens(line);
  }
  return true;
}

}  // namespace detail

namespace {

// Larger files are refused before reading: no mesh dhfcast can decompose comes near it, and a
// sparse or endless file must not exhaust memory.
constexpr std::uintmax_t kMaxFileBytes = std::uintmax_t{2} << 30;

// Refuses what is not a regular file of sensible size before its extension or content matters.
void check_input_file(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found)
    throw Error(ErrorCode::Io, path + ": no such file");
  if (ec) throw Error(ErrorCode::Io, "cannot open " + path + ": " + ec.message());
  if (fs::is_directory(status)) throw Error(ErrorCode::Io, path + ": is a directory");
  if (!fs::is_regular_file(status)) throw Error(ErrorCode::Io, path + ": is not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw Error(ErrorCode::Io, "cannot open " + path + ": " + ec.message());
  if (size > kMaxFileBytes)
    detail::fail_input(path, "",
                       "file of " + std::to_string(size >> 20) +
                           " MiB; dhfcast reads meshes of at most 2 GiB");
}

std::string read_file(const std::string& path) {
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"),
                                                             &std::fclose);
  if (!file) throw Error(ErrorCode::Io, "cannot open " + path + ": " + std::strerror(errno));
  std::string data;
  char buffer[1 << 16];
  std::size_t got = 0;
  while ((got = std::fread(buffer, 1, sizeof buffer, file.get())) > 0) data.append(buffer, got);
  if (std::ferror(file.get()))
    throw Error(ErrorCode::Io, "cannot read " + path + ": " + std::strerror(errno));
  return data;
}

std::string lowercase_extension(const std::string& path) {
  const std::size_t slash = path.find_last_of("/\\");
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// Merges raw vertices with identical coordinates (exact ==, so -0 equals +0) and drops unused
// ones. Output vertices keep the order of their first raw occurrence. NaN never equals itself:
// such vertices stay separate so validation can point at them.
TriMesh weld(detail::Soup soup) {
  const std::size_t n = soup.vertices.size();
  std::vector<char> used(n, 0);
  for (const Tri& t : soup.triangles)
    for (std::int32_t v : t) used[v] = 1;

  std::vector<std::int32_t> order;
  order.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    if (used[i] && !soup.vertices[i].array().isNaN().any())
      order.push_back(static_cast<std::int32_t>(i));
  // Ties broken by index, so the first raw occurrence leads each group.
  std::sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
    const Vec3& p = soup.vertices[a];
    const Vec3& q = soup.vertices[b];
    if (p.x() != q.x()) return p.x() < q.x();
    if (p.y() != q.y()) return p.y() < q.y();
    if (p.z() != q.z()) return p.z() < q.z();
    return a < b;
  });
  std::vector<std::int32_t> leader(n);
  std::iota(leader.begin(), leader.end(), 0);
  for (std::size_t k = 1; k < order.size(); ++k)
    if (soup.vertices[order[k]] == soup.vertices[order[k - 1]])
      leader[order[k]] = leader[order[k - 1]];

  TriMesh mesh;
  std::vector<std::int32_t> new_index(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (!used[i]) continue;
    if (leader[i] == static_cast<std::int32_t>(i)) {
      new_index[i] = static_cast<std::int32_t>(mesh.vertices.size());
      mesh.vertices.push_back(soup.vertices[i]);
    } else {
      new_index[i] = new_index[leader[i]];
    }
  }
  mesh.triangles = std::move(soup.triangles);
  for (Tri& t : mesh.triangles)
    for (std::int32_t& v : t) v = new_index[v];
  return mesh;
}

using Parser = detail::Soup (*)(const std::string&, std::string_view);

// The parser of `path`'s extension; refuses other extensions.
Parser parser_for(const std::string& path) {
  const std::string ext = lowercase_extension(path);
  if (ext == "stl") return &detail::parse_stl;
  if (ext == "obj") return &detail::parse_obj;
  if (ext == "ply") return &detail::parse_ply;
  if (ext == "off") return &detail::parse_off;
  detail::fail_input(path, "",
                     "unsupported file type " +
                         (ext.empty() ? "(no extension)" : "'." + ext + "'") +
                         "; supported: .stl, .obj, .ply, .off");
}

}  // namespace

namespace detail {

TriMesh mesh_from_data(const std::string& path, std::string_view data) {
  const Parser parser = parser_for(path);
  if (data.empty()) fail_input(path, "", "empty file");
  Soup soup = parser(path, data);
  if (soup.triangles.empty()) fail_input(path, "", "no triangles found");
  return weld(std::move(soup));
}

}  // namespace detail

TriMesh read_mesh(const std::string& path) {
  check_input_file(path);
  parser_for(path);  // an unsupported extension is refused before the file is read
  return detail::mesh_from_data(path, read_file(path));
}

}  // namespace dhfcast
