// STL parser, binary and ASCII. STL stores three vertices per facet; welding happens later.
#include <algorithm>
#include <bit>
#include <cctype>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "readers.h"

namespace dhfcast::detail {

namespace {

constexpr std::size_t kHeaderBytes = 84;  // 80-byte comment + uint32 triangle count
constexpr std::size_t kFacetBytes = 50;   // normal, 3 vertices (float32 x 12) + uint16

template <class T>
T load_le(const char* p) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, p, sizeof(T));
  if constexpr (std::endian::native == std::endian::big)
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

Soup parse_binary_stl(const std::string& path, std::string_view data) {
  const std::uint32_t count = load_le<std::uint32_t>(data.data() + 80);
  if (count > std::numeric_limits<std::int32_t>::max() / 3)
    fail_input(path, "", "binary STL with too many triangles (" + std::to_string(count) + ")");
  Soup soup;
  soup.vertices.resize(std::size_t{count} * 3);
  soup.triangles.resize(count);
  for (std::size_t t = 0; t < count; ++t) {
    // Skip the stored normal: it is recomputed from the vertices whenever needed.
    const char* p = data.data() + kHeaderBytes + t * kFacetBytes + 12;
    for (int k = 0; k < 3; ++k) {
      Vec3& v = soup.vertices[3 * t + k];
      for (int i = 0; i < 3; ++i) v[i] = load_le<float>(p + 12 * k + 4 * i);
    }
    const auto first = static_cast<std::int32_t>(3 * t);
    soup.triangles[t] = {first, first + 1, first + 2};
  }
  return soup;
}

// Line-oriented: every ASCII STL writer puts one keyword per line.
Soup parse_ascii_stl(const std::string& path, std::string_view data) {
  Soup soup;
  TextLines lines(data);
  std::string_view line;
  std::vector<std::int32_t> facet;  // raw indices of the open facet's vertices
  bool in_facet = false;
  std::int64_t facet_line = 0;
  while (lines.next(line)) {
    Tokens tokens(line);
    std::string_view token;
    if (!tokens.next(token)) continue;
    // Some writers shout: SOLID, FACET NORMAL, VERTEX.
    std::string lowercase(token);
    for (char& c : lowercase) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const std::string_view keyword = lowercase;
    const std::string where = line_location(lines.line_number());
    if (keyword == "solid" || keyword == "endsolid") {
      if (in_facet) fail_input(path, where, "'" + std::string(keyword) + "' inside a facet");
    } else if (keyword == "facet") {
      if (in_facet) fail_input(path, where, "'facet' before the previous facet's 'endfacet'");
      in_facet = true;
      facet_line = lines.line_number();
      facet.clear();
    } else if (keyword == "outer" || keyword == "endloop") {
      if (!in_facet) fail_input(path, where, quoted(keyword) + " outside a facet");
    } else if (keyword == "vertex") {
      if (!in_facet) fail_input(path, where, "'vertex' outside a facet");
      Vec3 p;
      for (int i = 0; i < 3; ++i) {
        std::string_view token;
        if (!tokens.next(token)) fail_input(path, where, "vertex with fewer than 3 coordinates");
        if (!parse_double(token, p[i])) fail_input(path, where, "bad number " + quoted(token));
      }
      if (soup.vertices.size() >=
          static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        fail_input(path, where, "too many vertices");
      facet.push_back(static_cast<std::int32_t>(soup.vertices.size()));
      soup.vertices.push_back(p);
    } else if (keyword == "endfacet") {
      if (!in_facet) fail_input(path, where, "'endfacet' without 'facet'");
      if (facet.size() < 3)
        fail_input(path, where, "facet with " + std::to_string(facet.size()) + " vertices");
      add_polygon(soup, facet);
      in_facet = false;
    } else {
      fail_input(path, where, "unexpected " + quoted(token) + " in ASCII STL");
    }
  }
  if (in_facet)
    fail_input(path, "",
               "unexpected end of file inside the facet starting at " + line_location(facet_line));
  return soup;
}

constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// ASCII STL starts with "solid" (any case, after a byte order mark and blanks) and has no NUL
// byte in that first line; a binary header may start with "solid" too, but is followed by the
// NUL bytes of the triangle count before any line break.
bool looks_like_ascii(std::string_view data) {
  if (data.starts_with(kUtf8Bom)) data.remove_prefix(kUtf8Bom.size());
  const std::size_t start = data.find_first_not_of(" \t\r\n");
  if (start == std::string_view::npos || data.size() - start < 5) return false;
  for (std::size_t i = 0; i < 5; ++i)
    if (std::tolower(static_cast<unsigned char>(data[start + i])) != "solid"[i]) return false;
  const std::string_view first_line = data.substr(start, data.find('\n', start) - start);
  return first_line.find('\0') == std::string_view::npos;
}

// A text file holds no NUL byte: say where it is rather than what the parser makes of it.
void check_no_nul(const std::string& path, std::string_view data) {
  const std::size_t nul = data.find('\0');
  if (nul == std::string_view::npos) return;
  const auto line = std::count(data.begin(), data.begin() + nul, '\n') + 1;
  fail_input(path, line_location(line),
             "NUL byte at byte offset " + std::to_string(nul) + " of an ASCII STL");
}

}  // namespace

// Binary when the size matches the header's triangle count (some binary writers also start
// their header with "solid"), or when the file does not look like ASCII.
Soup parse_stl(const std::string& path, std::string_view data) {
  const std::size_t size = data.size();
  if (size >= kHeaderBytes) {
    const std::uint64_t count = load_le<std::uint32_t>(data.data() + 80);
    const std::uint64_t expected = kHeaderBytes + kFacetBytes * count;
    if (expected == size) return parse_binary_stl(path, data);
    if (!looks_like_ascii(data))
      fail_input(path, "",
                 "truncated binary STL: header says " + std::to_string(count) + " triangles (" +
                     std::to_string(expected) + " bytes) but the file has " + std::to_string(size) +
                     " bytes");
  } else if (!looks_like_ascii(data)) {
    fail_input(path, "",
               "truncated binary STL: the file has " + std::to_string(size) +
                   " bytes, less than the 84-byte header");
  }
  check_no_nul(path, data);
  if (data.starts_with(kUtf8Bom)) data.remove_prefix(kUtf8Bom.size());
  return parse_ascii_stl(path, data);
}

}  // namespace dhfcast::detail
