// write_stl(): binary STL, float32, little-endian, one unit normal per triangle.
#include <Eigen/Geometry>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"

namespace dhfcast {

namespace {

template <class T>
void store_le(char*& out, T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big)
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  std::memcpy(out, bytes, sizeof(T));
  out += sizeof(T);
}

[[noreturn]] void fail_write(const std::string& path, int error) {
  throw Error(ErrorCode::Io, "cannot write " + path + ": " + std::strerror(error));
}

}  // namespace

void write_stl(const std::string& path, const TriMesh& mesh) {
  if (mesh.triangles.size() > std::numeric_limits<std::uint32_t>::max())
    throw Error(ErrorCode::Io, "cannot write " + path + ": too many triangles for STL");
  // Built in memory first: one write call, and a partial file only on a real I/O error.
  std::vector<char> buffer(84 + 50 * mesh.triangles.size(), 0);
  static constexpr char kHeader[] = "dhfcast binary STL";
  std::memcpy(buffer.data(), kHeader, sizeof kHeader - 1);
  char* out = buffer.data() + 80;
  store_le(out, static_cast<std::uint32_t>(mesh.triangles.size()));
  for (const Tri& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3& b = mesh.vertices[t[1]];
    const Vec3& c = mesh.vertices[t[2]];
    const Vec3 cross = (b - a).cross(c - a);
    const double length = cross.norm();
    // A degenerate triangle has no normal; readers accept a zero vector.
    const Vec3 normal = length > 0.0 ? Vec3(cross / length) : Vec3::Zero();
    for (const Vec3* p : {&normal, &a, &b, &c})
      for (int i = 0; i < 3; ++i) store_le(out, static_cast<float>((*p)[i]));
    store_le(out, std::uint16_t{0});
  }

  errno = 0;
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) fail_write(path, errno);
  const bool written = std::fwrite(buffer.data(), 1, buffer.size(), file) == buffer.size();
  const int write_error = errno;
  if (std::fclose(file) != 0 || !written) fail_write(path, written ? errno : write_error);
}

}  // namespace dhfcast
