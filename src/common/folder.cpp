#include "dhfcast/folder.h"

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

}  // namespace dhfcast
