// Wavefront OBJ parser: "v" and "f" lines only; everything else (normals, texture coordinates,
// groups, materials) is irrelevant to the solid and skipped.
#include <limits>
#include <string>
#include <vector>

#include "readers.h"

namespace dhfcast::detail {

Soup parse_obj(const std::string& path, std::string_view data) {
  Soup soup;
  TextLines lines(data);
  std::string_view line;
  std::vector<std::int32_t> face;
  while (lines.next(line)) {
    line = line.substr(0, line.find('#'));
    Tokens tokens(line);
    std::string_view keyword;
    if (!tokens.next(keyword)) continue;
    if (keyword == "v") {
      const std::string where = line_location(lines.line_number());
      Vec3 p;
      for (int i = 0; i < 3; ++i) {
        std::string_view token;
        if (!tokens.next(token)) fail_input(path, where, "vertex with fewer than 3 coordinates");
        if (!parse_double(token, p[i])) fail_input(path, where, "bad number " + quoted(token));
      }
      if (soup.vertices.size() >=
          static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        fail_input(path, where, "too many vertices");
      soup.vertices.push_back(p);
    } else if (keyword == "f") {
      const std::string where = line_location(lines.line_number());
      const auto defined = static_cast<std::int64_t>(soup.vertices.size());
      face.clear();
      std::string_view token;
      while (tokens.next(token)) {
        // v, v/vt, v/vt/vn or v//vn: only the position index matters.
        const std::string_view index_text = token.substr(0, token.find('/'));
        std::int64_t index = 0;
        if (!parse_int(index_text, index) || index == 0)
          fail_input(path, where, "bad vertex index " + quoted(token));
        // Negative indices count back from the last vertex defined so far.
        const std::int64_t raw = index > 0 ? index - 1 : defined + index;
        if (raw < 0 || raw >= defined)
          fail_input(path, where,
                     "vertex index " + std::to_string(index) + " out of range (" +
                         std::to_string(defined) + " vertices defined so far)");
        face.push_back(static_cast<std::int32_t>(raw));
      }
      if (face.size() < 3)
        fail_input(path, where, "face with " + std::to_string(face.size()) + " vertices");
      add_polygon(soup, face);
    }
  }
  return soup;
}

}  // namespace dhfcast::detail
