#include "dhfcast/folder.h"

#include <nlohmann/json.hpp>
#include <vector>

namespace fs = std::filesystem;

namespace dhfcast {

std::string folder_file(const fs::path& folder, const std::string& name, fs::path& path) {
  const fs::path relative(name);
  if (name.empty()) return "file name is empty";
  if (relative.has_root_path()) return name + " is not relative to the folder";
  fs::path walked;
  for (const fs::path& part : relative) {
    if (part == "..") return name + " has a '..' component";
    walked /= part;
    std::error_code ec;
    if (fs::is_symlink(fs::symlink_status(folder / walked, ec)))
      return name + " goes through the symlink " + walked.string();
  }
  path = folder / walked;
  return {};
}

std::string json_nesting_problem(std::string_view text) {
  int depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth)
        return "nests arrays and objects deeper than " + std::to_string(kMaxJsonDepth) +
               " levels (byte " + std::to_string(i) + ")";
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return {};
}

namespace {

// Follows where nlohmann's parser is, as a JSON path, so its errors can name the field.
class JsonPathTracker : public nlohmann::json::json_sax_t {
 public:
  std::string problem;

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override { return open(false); }
  bool start_array(std::size_t) override { return open(true); }
  bool end_object() override { return close(); }
  bool end_array() override { return close(); }
  bool key(string_t& k) override {
    frames_.back().key = k;
    return true;
  }
  bool parse_error(std::size_t, const std::string&,
                   const nlohmann::json::exception& e) override {
    // e.what() is "[json.exception.<kind>.<id>] <message>": keep the message.
    std::string what = e.what();
    if (const std::size_t end = what.find("] "); what.starts_with("[json.") && end != what.npos)
      what.erase(0, end + 2);
    const std::string where = path();
    problem = "not valid JSON" + (where.empty() ? "" : " at " + where) + ": " + what;
    return false;
  }

 private:
  struct Frame {
    bool array = false;
    std::size_t index = 0;  // in an array: the element being parsed
    std::string key;        // in an object: the last key read
  };
  std::vector<Frame> frames_;

  // A value ended: the next one of its array starts.
  bool value() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    return true;
  }
  bool open(bool array) {
    frames_.push_back({.array = array, .index = 0, .key = {}});
    return true;
  }
  bool close() {
    frames_.pop_back();
    return value();
  }
  std::string path() const {
    std::string p;
    for (const Frame& f : frames_) {
      if (f.array) {
        p += '[';
        p += std::to_string(f.index);
        p += ']';
      } else if (!f.key.empty()) {
        if (!p.empty()) p += '.';
        p += f.key;
      }
    }
    return p;
  }
};

}  // namespace

std::string json_problem(std::string_view text) {
  if (std::string deep = json_nesting_problem(text); !deep.empty()) return deep;
  JsonPathTracker tracker;
  nlohmann::json::sax_parse(text, &tracker);
  return tracker.problem;
}

}  // namespace dhfcast
