// PLY parser: ascii, binary_little_endian and binary_big_endian. Reads vertex x/y/z and the face
// list "vertex_indices" (or "vertex_index"); every other property and element is skipped.
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "readers.h"

namespace dhfcast::detail {

namespace {

enum class Scalar { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };
enum class Format { Ascii, BinaryLittleEndian, BinaryBigEndian };

bool scalar_from_name(std::string_view name, Scalar& type) {
  static constexpr std::pair<std::string_view, Scalar> kNames[] = {
      {"char", Scalar::Int8},      {"int8", Scalar::Int8},       {"uchar", Scalar::UInt8},
      {"uint8", Scalar::UInt8},    {"short", Scalar::Int16},     {"int16", Scalar::Int16},
      {"ushort", Scalar::UInt16},  {"uint16", Scalar::UInt16},   {"int", Scalar::Int32},
      {"int32", Scalar::Int32},    {"uint", Scalar::UInt32},     {"uint32", Scalar::UInt32},
      {"float", Scalar::Float32},  {"float32", Scalar::Float32}, {"double", Scalar::Float64},
      {"float64", Scalar::Float64}};
  for (const auto& [n, t] : kNames)
    if (n == name) {
      type = t;
      return true;
    }
  return false;
}

std::size_t scalar_bytes(Scalar type) {
  switch (type) {
    case Scalar::Int8:
    case Scalar::UInt8:
      return 1;
    case Scalar::Int16:
    case Scalar::UInt16:
      return 2;
    case Scalar::Int32:
    case Scalar::UInt32:
    case Scalar::Float32:
      return 4;
    case Scalar::Float64:
      return 8;
  }
  return 0;
}

struct Property {
  std::string name;
  bool is_list = false;
  Scalar count_type = Scalar::UInt8;  // lists only
  Scalar type = Scalar::Float32;      // the value type (of each list item for lists)
};

struct Element {
  std::string name;
  std::int64_t count = 0;
  std::vector<Property> properties;
};

struct Header {
  Format format = Format::Ascii;
  std::vector<Element> elements;
  std::size_t data_offset = 0;    // first byte after "end_header\n"
  std::int64_t header_lines = 0;  // lines before the data, for ASCII line numbers
};

Header parse_header(const std::string& path, std::string_view data) {
  TextLines lines(data);
  std::string_view line;
  if (!lines.next(line) || line != "ply")
    fail_input(path, "", "not a PLY file (no 'ply' magic line)");
  Header header;
  bool has_format = false;
  while (true) {
    if (!lines.next(line)) fail_input(path, "", "unexpected end of file in the PLY header");
    const std::string where = line_location(lines.line_number());
    Tokens tokens(line);
    std::string_view keyword;
    if (!tokens.next(keyword) || keyword == "comment" || keyword == "obj_info") continue;
    std::string_view a, b, c, d;
    if (keyword == "end_header") {
      break;
    } else if (keyword == "format") {
      if (!tokens.next(a)) fail_input(path, where, "format line without a format");
      if (a == "ascii")
        header.format = Format::Ascii;
      else if (a == "binary_little_endian")
        header.format = Format::BinaryLittleEndian;
      else if (a == "binary_big_endian")
        header.format = Format::BinaryBigEndian;
      else
        fail_input(path, where, "unknown PLY format " + quoted(a));
      has_format = true;
    } else if (keyword == "element") {
      Element element;
      if (!tokens.next(a) || !tokens.next(b) || !parse_int(b, element.count) || element.count < 0)
        fail_input(path, where, "bad element line");
      element.name = std::string(a);
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) fail_input(path, where, "property before any element");
      Property property;
      if (!tokens.next(a)) fail_input(path, where, "bad property line");
      if (a == "list") {
        property.is_list = true;
        if (!tokens.next(b) || !tokens.next(c) || !tokens.next(d) ||
            !scalar_from_name(b, property.count_type) || !scalar_from_name(c, property.type))
          fail_input(path, where, "bad list property line");
        property.name = std::string(d);
      } else {
        if (!scalar_from_name(a, property.type))
          fail_input(path, where, "unknown type " + quoted(a));
        if (!tokens.next(b)) fail_input(path, where, "property without a name");
        property.name = std::string(b);
      }
      header.elements.back().properties.push_back(std::move(property));
    } else {
      fail_input(path, where, "unexpected " + quoted(keyword) + " in the PLY header");
    }
  }
  if (!has_format) fail_input(path, "", "PLY header without a format line");
  header.data_offset = lines.offset();
  header.header_lines = lines.line_number();
  return header;
}

// Reads the body's values one by one, in either encoding, and knows where it is for messages.
class ValueReader {
 public:
  ValueReader(const std::string& path, std::string_view data, const Header& header)
      : path_(path),
        data_(data),
        format_(header.format),
        pos_(header.data_offset),
        header_lines_(header.header_lines),
        tokens_(data.substr(header.data_offset)) {}

  // One value of `type`; `element`/`index` name the item being read in error messages.
  double read(Scalar type, const std::string& element, std::int64_t index) {
    if (format_ == Format::Ascii) {
      std::string_view token;
      if (!tokens_.next(token)) fail(element, index, "unexpected end of file");
      double value = 0.0;
      if (!parse_double(token, value)) fail(element, index, "bad number " + quoted(token));
      return value;
    }
    const std::size_t bytes = scalar_bytes(type);
    if (pos_ + bytes > data_.size()) fail(element, index, "unexpected end of file");
    const char* p = data_.data() + pos_;
    pos_ += bytes;
    switch (type) {
      case Scalar::Int8:
        return load<std::int8_t>(p);
      case Scalar::UInt8:
        return load<std::uint8_t>(p);
      case Scalar::Int16:
        return load<std::int16_t>(p);
      case Scalar::UInt16:
        return load<std::uint16_t>(p);
      case Scalar::Int32:
        return load<std::int32_t>(p);
      case Scalar::UInt32:
        return load<std::uint32_t>(p);
      case Scalar::Float32:
        return load<float>(p);
      case Scalar::Float64:
        return load<double>(p);
    }
    return 0.0;
  }

  [[noreturn]] void fail(const std::string& element, std::int64_t index, const std::string& what) {
    const std::string where = format_ == Format::Ascii
                                  ? line_location(header_lines_ + tokens_.line_number())
                                  : "byte offset " + std::to_string(pos_);
    fail_input(path_, where + " (" + element + " " + std::to_string(index) + ")", what);
  }

 private:
  template <class T>
  T load(const char* p) const {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, p, sizeof(T));
    const bool file_little = format_ == Format::BinaryLittleEndian;
    if (file_little != (std::endian::native == std::endian::little))
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
    T value;
    std::memcpy(&value, bytes, sizeof(T));
    return value;
  }

  const std::string& path_;
  std::string_view data_;
  Format format_;
  std::size_t pos_;
  std::int64_t header_lines_;
  TokenStream tokens_;
};

// Position of property `name` in `element`, or -1.
int find_property(const Element& element, std::string_view name) {
  for (std::size_t i = 0; i < element.properties.size(); ++i)
    if (element.properties[i].name == name) return static_cast<int>(i);
  return -1;
}

}  // namespace

Soup parse_ply(const std::string& path, std::string_view data) {
  const Header header = parse_header(path, data);
  ValueReader reader(path, data, header);
  Soup soup;
  bool has_vertices = false, has_faces = false;
  std::vector<std::int64_t> face_of_triangle;  // for messages about out-of-range indices
  std::vector<std::int32_t> face;
  for (const Element& element : header.elements) {
    const bool is_vertex = element.name == "vertex";
    int coordinate[3] = {-1, -1, -1};  // property index of x, y, z
    int face_list = -1;
    if (is_vertex) {
      has_vertices = true;
      static constexpr std::string_view kAxes = "xyz";
      for (int i = 0; i < 3; ++i) {
        coordinate[i] = find_property(element, kAxes.substr(i, 1));
        if (coordinate[i] < 0 || element.properties[coordinate[i]].is_list)
          fail_input(
              path, "",
              "vertex element without a scalar '" + std::string(kAxes.substr(i, 1)) + "' property");
      }
      // Every vertex takes at least one byte: a bogus count must not allocate.
      if (element.count > std::numeric_limits<std::int32_t>::max() ||
          static_cast<std::size_t>(element.count) > data.size())
        fail_input(path, "",
                   "the header announces " + std::to_string(element.count) +
                       " vertices but the file has only " + std::to_string(data.size()) + " bytes");
      soup.vertices.resize(static_cast<std::size_t>(element.count));
    } else if (element.name == "face") {
      face_list = find_property(element, "vertex_indices");
      if (face_list < 0) face_list = find_property(element, "vertex_index");
      if (face_list >= 0 && !element.properties[face_list].is_list)
        fail_input(path, "",
                   "face property '" + element.properties[face_list].name + "' is not a list");
      has_faces = face_list >= 0;
    }
    // An element without properties has nothing to read, however many items it announces
    // (66666666666 of them looped for minutes); any other item takes at least one byte.
    if (element.properties.empty()) continue;
    if (static_cast<std::uint64_t>(element.count) > data.size())
      fail_input(path, "",
                 "the header announces " + std::to_string(element.count) + " " +
                     quoted(element.name) + " elements but the file has only " +
                     std::to_string(data.size()) + " bytes");
    for (std::int64_t item = 0; item < element.count; ++item) {
      for (int k = 0; k < static_cast<int>(element.properties.size()); ++k) {
        const Property& property = element.properties[k];
        if (!property.is_list) {
          const double value = reader.read(property.type, element.name, item);
          for (int i = 0; i < 3; ++i)
            if (k == coordinate[i]) soup.vertices[item][i] = value;
          continue;
        }
        const double count = reader.read(property.count_type, element.name, item);
        if (!(count >= 0 && count == std::floor(count) && count < 1e9))
          reader.fail(element.name, item, "bad list size " + std::to_string(count));
        if (k == face_list) {
          if (count < 3)
            reader.fail(element.name, item,
                        "face with " + std::to_string(static_cast<int>(count)) + " vertices");
          face.clear();
        }
        for (std::int64_t j = 0; j < static_cast<std::int64_t>(count); ++j) {
          const double value = reader.read(property.type, element.name, item);
          if (k != face_list) continue;
          if (!(value >= 0 && value == std::floor(value) &&
                value <= std::numeric_limits<std::int32_t>::max()))
            reader.fail(element.name, item, "bad vertex index " + std::to_string(value));
          face.push_back(static_cast<std::int32_t>(value));
        }
        if (k == face_list) {
          add_polygon(soup, face);
          face_of_triangle.resize(soup.triangles.size(), item);
        }
      }
    }
  }
  if (!has_vertices) fail_input(path, "", "no 'vertex' element");
  if (!has_faces) fail_input(path, "", "no 'face' element with a 'vertex_indices' list");
  // Checked at the end: the face element may come before the vertex element.
  const auto num_vertices = static_cast<std::int32_t>(soup.vertices.size());
  for (std::size_t t = 0; t < soup.triangles.size(); ++t)
    for (std::int32_t v : soup.triangles[t])
      if (v >= num_vertices)
        fail_input(path, "face " + std::to_string(face_of_triangle[t]),
                   "vertex index " + std::to_string(v) + " out of range (" +
                       std::to_string(num_vertices) + " vertices)");
  return soup;
}

}  // namespace dhfcast::detail
