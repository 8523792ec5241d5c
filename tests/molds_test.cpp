// Mold halves of single parts: closed solids that release from the part and mould its surface.
#include "dhfcast/molds.h"

#include <gtest/gtest.h>
#include <oneapi/tbb/global_control.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <set>
#include <tuple>

#include "dhfcast/check.h"
#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "dhfcast/pipeline.h"
#include "dhfcast/report.h"
#include "support/test_support.h"

using namespace dhfcast;

namespace {

Part part_of(TriMesh mesh, const Vec3& direction) {
  Part p;
  p.mesh = std::move(mesh);
  p.direction = direction.normalized();
  p.volume_mm3 = signed_volume(p.mesh);
  return p;
}

// A UV sphere (closed, outward), centre c, radius r.
TriMesh make_sphere(const Vec3& c, double r, int rings = 24, int segments = 48) {
  TriMesh m;
  m.vertices.push_back(c + Vec3(0, 0, -r));
  for (int i = 1; i < rings; ++i) {
    const double phi = M_PI * i / rings - M_PI / 2;
    for (int j = 0; j < segments; ++j) {
      const double th = 2 * M_PI * j / segments;
      m.vertices.push_back(c + r * Vec3(std::cos(phi) * std::cos(th),
                                        std::cos(phi) * std::sin(th), std::sin(phi)));
    }
  }
  m.vertices.push_back(c + Vec3(0, 0, r));
  const int top = static_cast<int>(m.vertices.size()) - 1;
  auto ring = [&](int i, int j) { return 1 + (i - 1) * segments + (j % segments); };
  for (int j = 0; j < segments; ++j) {
    m.triangles.push_back({0, ring(1, j + 1), ring(1, j)});
    m.triangles.push_back({top, ring(rings - 1, j), ring(rings - 1, j + 1)});
    for (int i = 1; i + 1 < rings; ++i) {
      m.triangles.push_back({ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)});
    }
  }
  return m;
}

// The independent checker's verdict on one part and its mold, written as an output folder.
CheckItem checked_molds(const Part& part, const Mold& mold) {
  namespace fs = std::filesystem;
  const fs::path dir = test::temp_dir("mold");
  fs::create_directories(dir / "parts");
  fs::create_directories(dir / "molds");
  write_stl((dir / "parts/part_000.stl").string(), part.mesh);
  write_stl((dir / "molds/up.stl").string(), mold.up);
  write_stl((dir / "molds/down.stl").string(), mold.down);
  auto vec = [](const Vec3& v) {
    char text[128];
    std::snprintf(text, sizeof text, "[%.17g, %.17g, %.17g]", v.x(), v.y(), v.z());
    return std::string(text);
  };
  auto channels = [&](const std::vector<MoldChannel>& list) {
    std::string out = "[";
    for (const MoldChannel& c : list)
      out += std::string(out.size() > 1 ? ", " : "") + "{\"mouth\": " + vec(c.mouth) +
             ", \"exit\": " + vec(c.exit) + ", \"diameter_mm\": " + std::to_string(c.diameter_mm) +
             "}";
    return out + "]";
  };
  auto motion = [](const RigidMotion& m) {
    std::string out;
    for (int r = 0; r < 3; ++r) {
      char row[160];
      std::snprintf(row, sizeof row, "[%.17g, %.17g, %.17g, %.17g]", m(r, 0), m(r, 1), m(r, 2),
                    m(r, 3));
      out += std::string(r ? ", " : "[") + row;
    }
    return out + "]";
  };
  std::string keys = "[";
  for (std::size_t k = 0; k < mold.keys.size(); ++k) keys += k ? ", {}" : "{}";
  keys += "]";
  std::ofstream(dir / "decomposition.json")
      << "{\"format\": \"dhfcast-decomposition\", \"version\": 1, \"input\": {\"volume_mm3\": "
      << part.volume_mm3 << "}, \"parts\": [{\"id\": 0, \"mesh\": \"parts/part_000.stl\", "
      << "\"direction\": " << vec(part.direction) << ", \"volume_mm3\": " << part.volume_mm3
      << ", \"molds\": {\"up\": \"molds/up.stl\", \"down\": \"molds/down.stl\", \"up_to_model\": "
      << motion(mold.up_to_model) << ", \"down_to_model\": " << motion(mold.down_to_model)
      << ", \"sprues\": " << channels(mold.sprues) << ", \"vents\": " << channels(mold.vents)
      << ", \"keys\": " << keys << "}}], \"assembly_order\": [0]}\n";
  CheckOptions o;
  o.outdir = dir.string();
  const CheckReport report = check_output(o);
  for (const CheckItem& item : report.items) {
    if (item.name == "contract" || item.name == "solids") {
      EXPECT_TRUE(item.passed) << item.name << ": " << item.summary;
    }
    if (item.name == "molds") return item;
  }
  ADD_FAILURE() << "no molds check";
  return {};
}

// Each half in its print frame: nothing below z = 0, its flat outer face on z = 0 facing -z
// and covering the block's whole footprint (centred on x = y = 0, the block's first axis along
// x); its motion to the model is rigid and turns that face to face +d (up) or -d (down).
void expect_print_frames(const Mold& mold, const Vec3& d) {
  for (const auto& [half, to_model, outward] : {std::tuple{&mold.up, &mold.up_to_model, Vec3(d)},
                                                {&mold.down, &mold.down_to_model, Vec3(-d)}}) {
    const Box3 box = bounding_box(half->vertices);
    EXPECT_EQ(box.min.z(), 0.0);
    EXPECT_NEAR(box.max.x() - box.min.x(), mold.block_mm.x(), 1e-3);
    EXPECT_NEAR(box.max.y() - box.min.y(), mold.block_mm.y(), 1e-3);
    EXPECT_NEAR(box.min.x() + box.max.x(), 0.0, 1e-3);
    EXPECT_NEAR(box.min.y() + box.max.y(), 0.0, 1e-3);
    double bed_mm2 = 0.0;
    for (const Tri& t : half->triangles) {
      const Vec3 &a = half->vertices[t[0]], &b = half->vertices[t[1]], &c = half->vertices[t[2]];
      if (a.z() != 0.0 || b.z() != 0.0 || c.z() != 0.0) continue;
      const Vec3 n = (b - a).cross(c - a);
      EXPECT_LT(n.z(), 0.0);
      bed_mm2 += 0.5 * n.norm();
    }
    EXPECT_NEAR(bed_mm2, mold.block_mm.x() * mold.block_mm.y(), 1e-4 * bed_mm2);
    const Eigen::Matrix3d r = to_model->leftCols<3>();
    EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
    EXPECT_LT((r * -Vec3::UnitZ() - outward.normalized()).norm(), 1e-12);
  }
}

// How many shells (connected components) a mesh has.
int shells(const TriMesh& m) {
  std::vector<std::int32_t> parent(m.vertices.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](std::int32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (const Tri& t : m.triangles) parent[root(t[1])] = parent[root(t[2])] = root(t[0]);
  std::set<std::int32_t> roots;
  for (const Tri& t : m.triangles) roots.insert(root(t[0]));
  return static_cast<int>(roots.size());
}

void expect_valid_mold(const Mold& mold, const Vec3& d) {
  ASSERT_EQ(mold.error, "");
  expect_print_frames(mold, d);

  for (const TriMesh* half : {&mold.up, &mold.down}) {
    EXPECT_EQ(test::solid_topology_problem(*half), "");
    EXPECT_EQ(shells(*half), 1);  // one solid on the bed, no chip loose in the cavity
    const MeshDiagnostics d = validate_mesh(*half);
    EXPECT_TRUE(d.ok()) << d.first_problem;
    for (const Vec3& p : half->vertices)
      for (int k = 0; k < 3; ++k) EXPECT_EQ(p[k], double(float(p[k])));
  }
  EXPECT_EQ(mold.sprues.size(), 1u);
  EXPECT_GE(mold.keys.size(), 3u);
  EXPECT_NEAR(mold.gravity_up.norm(), 1.0, 1e-9);
}

TEST(Molds, CubeHalvesAreClosedSolids) {
  const Part cube = part_of(test::make_box(Vec3(0, 0, 0), Vec3(10, 10, 10)), Vec3::UnitZ());
  const Mold mold = build_mold(cube, {});
  expect_valid_mold(mold, cube.direction);
  EXPECT_NEAR(mold.gravity_up.dot(Vec3::UnitZ()), 0.0, 1e-12);
  const CheckItem item = checked_molds(cube, mold);
  EXPECT_TRUE(item.passed) << item.summary;
}

TEST(Molds, TiltedSphereHalvesAreClosedSolids) {
  const Part sphere = part_of(make_sphere(Vec3(1, 2, 3), 20), Vec3(0.3, -0.2, 1.0));
  const Mold mold = build_mold(sphere, {});
  expect_valid_mold(mold, sphere.direction);
  const CheckItem item = checked_molds(sphere, mold);
  EXPECT_TRUE(item.passed) << item.summary;
}

// The sprue and the vents leave the block side by side, far enough apart not to merge.
void expect_channels_apart(const Mold& mold, const Vec3& d) {
  std::vector<MoldChannel> all = mold.sprues;
  all.insert(all.end(), mold.vents.begin(), mold.vents.end());
  const Vec3 across = mold.gravity_up.cross(d).normalized();
  for (std::size_t i = 0; i < all.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      EXPECT_GT(std::abs((all[i].mouth - all[j].mouth).dot(across)),
                0.5 * (all[i].diameter_mm + all[j].diameter_mm));
}

// A ring lying across d: its footprint has a hole, so the parting surface spans two loops; the
// hole's rim traps no air.
TEST(Molds, RingHasOneSprueAndReleases) {
  const std::vector<double> xs = {0, 6, 24, 30}, ys = {0, 6, 24, 30}, zs = {0, 8};
  const TriMesh ring = test::grid_surface(
      xs, ys, zs, [](int i, int j, int) { return !(i == 1 && j == 1); });
  const Part part = part_of(ring, Vec3::UnitZ());
  const Mold mold = build_mold(part, {});
  expect_valid_mold(mold, part.direction);
  // One trap (the sprue's); a vent still goes where the way up is clear, apart from the sprue.
  ASSERT_EQ(mold.vents.size(), 1u);
  expect_channels_apart(mold, part.direction);
  const CheckItem item = checked_molds(part, mold);
  EXPECT_TRUE(item.passed) << item.summary;
}

// Two towers on a base, poured with the towers up: each tower's top traps air. The sprue takes
// one, a vent the other, and both lie on the parting line.
TEST(Molds, EveryAirTrapGetsAVent) {
  const std::vector<double> xs = {0, 8, 20, 28}, ys = {0, 10}, zs = {0, 6, 30};
  const TriMesh towers = test::grid_surface(
      xs, ys, zs, [](int i, int, int k) { return k == 0 || i != 1; });
  const Part part = part_of(towers, Vec3::UnitY());  // a height field along y
  MoldOptions opts;
  opts.gravity_up = Vec3(0, 0.3, 1);  // its part along d does not count
  const Mold mold = build_mold(part, opts);
  expect_valid_mold(mold, part.direction);
  EXPECT_NEAR(mold.gravity_up.dot(Vec3::UnitZ()), 1.0, 1e-12);
  ASSERT_EQ(mold.vents.size(), 1u);
  EXPECT_EQ(mold.vents[0].diameter_mm, opts.vent_diameter_mm);
  EXPECT_EQ(mold.sprues[0].diameter_mm, opts.sprue_diameter_mm);
  // One channel above each tower, starting inside it and leaving the block upwards.
  const double x_sprue = mold.sprues[0].mouth.x(), x_vent = mold.vents[0].mouth.x();
  EXPECT_TRUE((x_sprue < 9 && x_vent > 19) || (x_sprue > 19 && x_vent < 9));
  for (const MoldChannel& c : {mold.sprues[0], mold.vents[0]}) {
    EXPECT_LT(c.mouth.z(), 30.0);
    EXPECT_GT(c.exit.z(), 35.0);
  }
  const CheckItem item = checked_molds(part, mold);
  EXPECT_TRUE(item.passed) << item.summary;

  // Chosen automatically, the pouring direction has the fewest traps: one, the sprue's. The
  // vent goes at the highest point of the parting line whose way up the cavity leaves clear.
  const Mold automatic = build_mold(part, {});
  expect_valid_mold(automatic, part.direction);
  ASSERT_EQ(automatic.vents.size(), 1u);
  expect_channels_apart(automatic, part.direction);
}

// A sphere's parting line is its equator, and its top is the one air trap, for the sprue. The
// way up from any point of the equator's upper half is clear, so the vent goes on it, as high as
// it can beside the sprue.
TEST(Molds, OneTrapStillGetsAVentBesideTheSprue) {
  const Part sphere = part_of(make_sphere(Vec3(0, 0, 0), 15), Vec3::UnitZ());
  const Mold mold = build_mold(sphere, {});
  expect_valid_mold(mold, sphere.direction);
  ASSERT_EQ(mold.vents.size(), 1u);
  expect_channels_apart(mold, sphere.direction);
  EXPECT_GT(mold.vents[0].mouth.dot(mold.gravity_up), 10.0);
}

// A 60 x 62 x 10 mm slab with a 2 mm lip, 4 x 3 mm across, over a slit `slit_mm` high; a wall
// at the slit's end holds the lip up.
TriMesh slab_with_slit(double slit_mm) {
  const std::vector<double> xs = {0, 28, 32, 60}, ys = {-2, 0, 3, 60},
                            zs = {0, 10, 10 + slit_mm, 12 + slit_mm};
  return test::grid_surface(xs, ys, zs, [](int i, int j, int k) {
    return k == 0 || (i == 1 && j == 0) || (i == 1 && j == 1 && k == 2);
  });
}

// A slab with a lip over a 0.3 mm slit: lines through the slit meet the part twice, a double
// height field only up to epsilon. A half holding the slit could not be pulled past the lip
// (the parting surface used to cut a tongue into it); the slit is left to the cast instead.
// The lip also ends between the parting surface's nodes.
TEST(Molds, ToleratedSlitUnderALipIsLeftToTheCast) {
  const Part part = part_of(slab_with_slit(0.3), Vec3::UnitZ());
  const Mold mold = build_mold(part, {});
  expect_valid_mold(mold, part.direction);
  const CheckItem item = checked_molds(part, mold);
  EXPECT_TRUE(item.passed) << item.summary;
}

// The same slab with a 2 mm slit, far beyond epsilon: the part is not a double height field
// there. The halves still release (neither holds the slit, which the cast fills), and the
// check finds the slit's faces covered by no half.
TEST(Molds, DeepSlitUnderALipIsLeftToTheCastAndTheHalvesRelease) {
  const Part part = part_of(slab_with_slit(2.0), Vec3::UnitZ());
  const Mold mold = build_mold(part, {});
  expect_valid_mold(mold, part.direction);
  const CheckItem item = checked_molds(part, mold);
  const auto figure = [&](const std::string& name) {
    for (const auto& [key, value] : item.figures)
      if (key == name) return value;
    ADD_FAILURE() << "no figure " << name;
    return -1.0;
  };
  EXPECT_EQ(figure("blocked_samples"), 0.0) << item.summary;
  // The slit's floor and ceiling (4 x 3 mm each) of the part's surface (about 8000 mm2).
  EXPECT_LT(figure("min_surface_coverage"), 0.999) << item.summary;
  EXPECT_GT(figure("min_surface_coverage"), 0.99) << item.summary;
}

TEST(Molds, SameMoldOnAnyThreadCount) {
  const std::vector<Part> parts = {
      part_of(make_sphere(Vec3(0, 0, 0), 12, 12, 24), Vec3(0.3, 0.4, 1.0)),
      part_of(test::make_box(Vec3(0, 0, 0), Vec3(12, 8, 5)), Vec3(1.0, 0.0, 0.2))};
  const std::vector<Mold> many = build_molds(parts, {});
  const std::vector<Mold> again = build_molds(parts, {});
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const std::vector<Mold> single = build_molds(parts, {});
  ASSERT_EQ(many.size(), single.size());
  for (std::size_t i = 0; i < many.size(); ++i) {
    EXPECT_EQ(many[i].up.vertices, again[i].up.vertices) << "part " << i;
    EXPECT_EQ(many[i].up.vertices, single[i].up.vertices);
    EXPECT_EQ(many[i].up.triangles, single[i].up.triangles);
    EXPECT_EQ(many[i].down.vertices, single[i].down.vertices);
    EXPECT_EQ(many[i].down.triangles, single[i].down.triangles);
  }
}

// The extended suite: a shared model decomposed at the default settings, its molds written
// and read back by the checker. Wrench is one part along a tilted direction (its block stood on
// an edge before the halves were laid flat; PrusaSlicer found nothing in the first layer);
// fandisk's booleans left chips of the block loose in its cavities, and its halves did not
// release where the parting surface left a thin part between grid nodes or a half held a
// tolerated undercut (issue #5).
struct ModelCase {
  std::string name;
  bool releases;  // the molds check passes
};

class ModelMolds : public ::testing::TestWithParam<ModelCase> {};

TEST_P(ModelMolds, HalvesLieFlatOnTheBedAndMapBackAroundTheirParts) {
  const std::string path = test::extra_model(GetParam().name + ".stl");
  if (path.empty()) GTEST_SKIP() << "extended models absent (set DHFCAST_MODELS_DIR)";
  const TriMesh input = test::load_scaled(path, 0.0);
  const DecomposeOptions opts;
  const Decomposition d = decompose(input, opts);
  ASSERT_EQ(d.molds.size(), d.parts.size());
  for (const Mold& mold : d.molds) {
    SCOPED_TRACE("part " + std::to_string(mold.part));
    expect_valid_mold(mold, d.parts[mold.part].direction);
  }
  const std::string dir = test::temp_dir(GetParam().name) + "/out";
  const InputInfo info{path, 0, signed_volume(input), bounding_box(input.vertices), false};
  write_output(dir, decomposition_json(info, opts, d, 0, 0), d, false);
  CheckOptions check;
  check.outdir = dir;
  for (const CheckItem& item : check_output(check).items) {
    SCOPED_TRACE(item.name + ": " + item.summary);
    if (item.name == "contract" || item.name == "solids") {
      EXPECT_TRUE(item.passed);
    }
    if (item.name == "molds") {
      EXPECT_EQ(item.passed, GetParam().releases);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Extended, ModelMolds,
                         ::testing::Values(ModelCase{"wrench", true}, ModelCase{"teacup", true},
                                           ModelCase{"fandisk", true}),
                         [](const auto& info) { return info.param.name; });

TEST(Molds, BadOptionsAreNamed) {
  const Part cube = part_of(test::make_box(Vec3(0, 0, 0), Vec3(10, 10, 10)), Vec3::UnitZ());
  MoldOptions o;
  o.wall_mm = 0.5;
  try {
    build_mold(cube, o);
    FAIL() << "accepted a 0.5 mm wall";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidOptions);
    EXPECT_NE(std::string(e.what()).find("--wall"), std::string::npos);
  }
  o = {};
  o.vent_diameter_mm = 8;
  EXPECT_THROW(build_mold(cube, o), Error);
}

}  // namespace
