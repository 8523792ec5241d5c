// OFF parser (Geomview): header, counts, one vertex per line, one polygon per line. Extra values
// on a line (colours, normals, texture coordinates) are skipped, as the [ST][C][N]OFF variants
// put them there.
#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "readers.h"

namespace dhfcast::detail {

namespace {

// Next line with content, '#' comments removed; false at the end of the file.
bool next_content_line(TextLines& lines, Tokens& tokens) {
  std::string_view line;
  while (lines.next(line)) {
    line = line.substr(0, line.find('#'));
    if (line.find_first_not_of(" \t\r\f\v") != std::string_view::npos) {
      tokens = Tokens(line);
      return true;
    }
  }
  return false;
}

bool is_plain_off_keyword(std::string_view keyword) {
  if (keyword.size() < 3 || keyword.substr(keyword.size() - 3) != "OFF") return false;
  return keyword.substr(0, keyword.size() - 3).find_first_not_of("STCN") == std::string_view::npos;
}

}  // namespace

Soup parse_off(const std::string& path, std::string_view data) {
  TextLines lines(data);
  Tokens tokens{std::string_view()};
  std::string_view token;
  if (!next_content_line(lines, tokens) || !tokens.next(token))
    fail_input(path, "", "no OFF header");
  if (token.find("OFF") == std::string_view::npos)
    fail_input(path, line_location(lines.line_number()),
               "expected the 'OFF' header, got " + quoted(token));
  if (!is_plain_off_keyword(token))
    fail_input(path, line_location(lines.line_number()),
               "unsupported OFF variant " + quoted(token) + " (only 3D [ST][C][N]OFF)");

  // Counts: on the header line or on the next content line. The edge count is optional.
  std::int64_t counts[2] = {0, 0};
  if (!tokens.next(token)) {
    if (!next_content_line(lines, tokens) || !tokens.next(token))
      fail_input(path, "", "unexpected end of file before the vertex and face counts");
  }
  if (token == "BINARY")
    fail_input(path, line_location(lines.line_number()), "binary OFF is not supported");
  for (int i = 0; i < 2; ++i) {
    if (i > 0 && !tokens.next(token))
      fail_input(path, line_location(lines.line_number()), "missing face count");
    if (!parse_int(token, counts[i]) || counts[i] < 0 ||
        counts[i] > std::numeric_limits<std::int32_t>::max())
      fail_input(path, line_location(lines.line_number()), "bad count " + quoted(token));
  }
  const std::int64_t num_vertices = counts[0], num_faces = counts[1];

  Soup soup;
  // Every vertex takes at least 6 bytes ("0 0 0\n"): a bogus count must not allocate.
  soup.vertices.reserve(std::min(static_cast<std::size_t>(num_vertices), data.size() / 6));
  for (std::int64_t v = 0; v < num_vertices; ++v) {
    if (!next_content_line(lines, tokens))
      fail_input(path, "",
                 "unexpected end of file: " + std::to_string(num_vertices) +
                     " vertices announced, " + std::to_string(v) + " found");
    const std::string where = line_location(lines.line_number());
    Vec3 p;
    for (int i = 0; i < 3; ++i) {
      if (!tokens.next(token)) fail_input(path, where, "vertex with fewer than 3 coordinates");
      if (!parse_double(token, p[i])) fail_input(path, where, "bad number " + quoted(token));
    }
    soup.vertices.push_back(p);
  }

  std::vector<std::int32_t> face;
  for (std::int64_t f = 0; f < num_faces; ++f) {
    if (!next_content_line(lines, tokens))
      fail_input(path, "",
                 "unexpected end of file: " + std::to_string(num_faces) + " faces announced, " +
                     std::to_string(f) + " found");
    const std::string where = line_location(lines.line_number());
    std::int64_t size = 0;
    if (!tokens.next(token) || !parse_int(token, size))
      fail_input(path, where, "bad face size " + quoted(token));
    if (size < 3) fail_input(path, where, "face with " + std::to_string(size) + " vertices");
    face.clear();
    for (std::int64_t k = 0; k < size; ++k) {
      std::int64_t index = 0;
      if (!tokens.next(token))
        fail_input(
            path, where,
            "face announces " + std::to_string(size) + " vertices but lists " + std::to_string(k));
      if (!parse_int(token, index)) fail_input(path, where, "bad vertex index " + quoted(token));
      if (index < 0 || index >= num_vertices)
        fail_input(path, where,
                   "vertex index " + std::to_string(index) + " out of range (" +
                       std::to_string(num_vertices) + " vertices)");
      face.push_back(static_cast<std::int32_t>(index));
    }
    add_polygon(soup, face);
  }
  return soup;
}

}  // namespace dhfcast::detail
