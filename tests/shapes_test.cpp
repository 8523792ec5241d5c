// The shapes with a known answer (tests/shapes/*.scad): each renders with OpenSCAD to a valid
// closed solid of the size its proof speaks of, and states its minimum number of parts. A broken
// source fails here rather than in bench/shapes.sh. Skipped when OpenSCAD is absent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "support/test_support.h"

namespace fs = std::filesystem;

namespace dhfcast {
namespace {

// The shapes' names (file stems), sorted; listed when the test program starts.
std::vector<std::string> shape_names() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(DHFCAST_SHAPES_DIR, ec)) {
    if (entry.path().extension() == ".scad") names.push_back(entry.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// The N of the source's "// minimum_parts: N" line, or 0 when there is none.
int minimum_parts(const fs::path& source) {
  std::ifstream in(source);
  const std::regex line(R"(^// minimum_parts: ([0-9]+)\s*$)");
  std::smatch m;
  for (std::string s; std::getline(in, s);) {
    if (std::regex_match(s, m, line)) return std::stoi(m[1]);
  }
  return 0;
}

class Shape : public testing::TestWithParam<std::string> {};

TEST_P(Shape, RendersToAValidSolidOfItsStatedSize) {
  const std::string openscad = DHFCAST_OPENSCAD;
  if (openscad.empty() || !fs::exists(openscad)) {
    GTEST_SKIP() << "OpenSCAD is absent (Debian package openscad; configure again after installing)";
  }
  const fs::path source = fs::path(DHFCAST_SHAPES_DIR) / (GetParam() + ".scad");
  const int minimum = minimum_parts(source);
  EXPECT_GE(minimum, 1) << source << " has no '// minimum_parts: N' line";
  EXPECT_LE(minimum, 3);

  const std::string stl = test::temp_dir("shape") + "/" + GetParam() + ".stl";
  const std::string log = stl + ".log";
  const std::string cmd = "'" + openscad + "' -o '" + stl + "' '" + source.string() + "' > '" +
                          log + "' 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "openscad failed on " << source;
  std::string warnings;
  {
    std::ifstream in(log);
    for (std::string s; std::getline(in, s);) {
      if (s.find("WARNING") != std::string::npos || s.find("ERROR") != std::string::npos) {
        warnings += s + "\n";
      }
    }
  }
  EXPECT_TRUE(warnings.empty()) << warnings;

  LoadedSolid solid;
  try {
    solid = load_solid(stl);
  } catch (const Error& e) {
    FAIL() << e.what();
  }
  EXPECT_FALSE(solid.flipped);
  EXPECT_GT(signed_volume(solid.mesh), 0.0);
  // Moderate resolution, and millimetres: the longest side is 60 to 150 mm.
  EXPECT_LE(solid.mesh.triangles.size(), 20000u);
  const Box3 box = bounding_box(solid.mesh.vertices);
  const Vec3 size = box.max - box.min;
  EXPECT_GE(size.maxCoeff(), 60.0);
  EXPECT_LE(size.maxCoeff(), 150.0);
}

INSTANTIATE_TEST_SUITE_P(Shapes, Shape, testing::ValuesIn(shape_names()),
                         [](const testing::TestParamInfo<std::string>& info) { return info.param; });

TEST(Shapes, AtLeastTwelveShapes) { EXPECT_GE(shape_names().size(), 12u); }

}  // namespace
}  // namespace dhfcast
