// Private to the mesh stage: the per-format parsers behind read_mesh() and what they share.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast::detail {

// Triangles over raw vertices, as a file states them (not welded, unused vertices kept).
struct Soup {
  std::vector<Vec3> vertices;
  std::vector<Tri> triangles;
};

// Each parser gets the whole file (non-empty) and the path for messages; throws
// Error{InvalidInput} with "PATH: <location>: <what>" on malformed input.
Soup parse_stl(const std::string& path, std::string_view data);
Soup parse_obj(const std::string& path, std::string_view data);
Soup parse_ply(const std::string& path, std::string_view data);
Soup parse_off(const std::string& path, std::string_view data);

// read_mesh() after reading: the parser of `path`'s extension applied to `data`, vertices welded.
// Throws as read_mesh() does for malformed data.
TriMesh mesh_from_data(const std::string& path, std::string_view data);

// Throws Error{InvalidInput} "PATH: LOCATION: WHAT" (or "PATH: WHAT" when location is empty).
[[noreturn]] void fail_input(const std::string& path, const std::string& location,
                             const std::string& what);
// "line N" for messages.
std::string line_location(std::int64_t line);
// A token quoted for a one-line message: shortened, non-printable bytes replaced.
std::string quoted(std::string_view token);

// Whole-token number parsing (a leading '+' is allowed; "nan" and "inf" parse as such).
bool parse_double(std::string_view token, double& value);
bool parse_int(std::string_view token, std::int64_t& value);

// Appends the fan triangulation (c0, ci, ci+1) of a polygon given by raw vertex indices.
void add_polygon(Soup& soup, std::span<const std::int32_t> corners);

// Iterates over the lines of a text (without their "\n" or "\r\n").
class TextLines {
 public:
  explicit TextLines(std::string_view text) : text_(text) {}
  // Next line; false at the end of the text.
  bool next(std::string_view& line);
  // 1-based number of the line last returned.
  std::int64_t line_number() const { return line_; }
  // Byte offset of the first character after the line last returned (and its end of line).
  std::size_t offset() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::int64_t line_ = 0;
};

// Splits a line on blanks (space, tab, \r, \f, \v).
class Tokens {
 public:
  explicit Tokens(std::string_view line) : rest_(line) {}
  // Next token; false when the line is used up.
  bool next(std::string_view& token);

 private:
  std::string_view rest_;
};

// Whitespace-separated tokens across lines, remembering the line of the last token.
class TokenStream {
 public:
  explicit TokenStream(std::string_view text) : lines_(text), tokens_(std::string_view()) {}
  bool next(std::string_view& token);
  std::int64_t line_number() const { return lines_.line_number(); }

 private:
  TextLines lines_;
  Tokens tokens_;
};

}  // namespace dhfcast::detail
