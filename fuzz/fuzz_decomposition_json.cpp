// libFuzzer target: decomposition.json as `dhfcast check` reads it, in a folder that also holds a
// one-part decomposition's part (parts/part_000.stl, a 10 mm cube), so well-formed inputs reach
// the geometric checks. Whatever the file holds, check must give a report or a one-line
// Error; a crash, a leak, undefined behaviour or any other exception is a defect.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "dhfcast/check.h"
#include "dhfcast/error.h"
#include "dhfcast/mesh.h"

namespace fs = std::filesystem;

namespace {

// The folder, made once per process.
const fs::path& folder() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("dhfcast-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d / "parts");
    dhfcast::TriMesh cube;
    for (int i = 0; i < 8; ++i)
      cube.vertices.emplace_back(10.0 * (i & 1), 10.0 * ((i >> 1) & 1), 10.0 * ((i >> 2) & 1));
    // Outward triangles of the cube 0..10 mm.
    cube.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                      {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    dhfcast::write_stl((d / "parts" / "part_000.stl").string(), cube);
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(folder(), ec);
    });
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  {
    std::ofstream f(folder() / "decomposition.json", std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  dhfcast::CheckOptions opts;
  opts.outdir = folder().string();
  // Few samples: the reading is fuzzed, not the sampling.
  opts.coverage_samples = 500;
  opts.dhf_lines = 20;
  opts.assembly_samples = 20;
  opts.mold_samples = 50;
  try {
    dhfcast::format_json(dhfcast::check_output(opts));
  } catch (const dhfcast::Error& e) {
    if (e.code() == dhfcast::ErrorCode::Internal) std::abort();
  }
  return 0;
}
