// Tests of the output verifier: hand-made output folders, one good and one broken per kind of
// problem, each failing on its own check; real meshes for the sampling machinery.
#include "dhfcast/check.h"

#include <gtest/gtest.h>
#include <oneapi/tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "support/test_support.h"

namespace dhfcast {
namespace {

namespace fs = std::filesystem;

// --- solids made of the cells of a rectilinear grid ---

using test::grid_surface;

TriMesh box(const Vec3& lo, const Vec3& hi) {
  return grid_surface({lo.x(), hi.x()}, {lo.y(), hi.y()}, {lo.z(), hi.z()},
                      [](int, int, int) { return true; });
}

// Mold halves of the box part [lo, hi] along +z, parted at mid-height, in a block 10 mm wider.
std::array<TriMesh, 2> box_molds(const Vec3& lo, const Vec3& hi) {
  const double mid = 0.5 * (lo.z() + hi.z());
  const std::vector<double> xs = {lo.x() - 10, lo.x(), hi.x(), hi.x() + 10};
  const std::vector<double> ys = {lo.y() - 10, lo.y(), hi.y(), hi.y() + 10};
  auto not_part = [](int k_part) {
    return [k_part](int i, int j, int k) { return !(i == 1 && j == 1 && k == k_part); };
  };
  return {grid_surface(xs, ys, {mid, hi.z(), hi.z() + 10}, not_part(0)),
          grid_surface(xs, ys, {lo.z() - 10, lo.z(), mid}, not_part(1))};
}

// --- output folders ---

struct PartSpec {
  PartSpec(TriMesh m, const Vec3& d = Vec3::UnitZ(), std::vector<TriMesh> halves = {})
      : mesh(std::move(m)), direction(d), molds(std::move(halves)) {}
  TriMesh mesh;
  Vec3 direction = Vec3::UnitZ();
  std::vector<TriMesh> molds;  // empty, or {up, down}
  double volume_mm3 = -1;      // < 0: the mesh's
};

struct Folder {
  std::string outdir;
  std::string input;  // input.stl beside outdir
};

// Writes OUTDIR/decomposition.json, parts/ and molds/ the way the contract describes them.
Folder write_folder(const std::string& tag, const TriMesh& input,
                    const std::vector<PartSpec>& parts, const nlohmann::json& order,
                    const std::function<void(nlohmann::json&)>& edit = {}) {
  const fs::path root = test::temp_dir("check-" + tag);
  const fs::path out = root / "out";
  fs::create_directories(out / "parts");
  fs::create_directories(out / "molds");
  write_stl((root / "input.stl").string(), input);
  const Box3 bbox = bounding_box(input.vertices);
  nlohmann::json j = {{"format", "dhfcast-decomposition"},
                      {"version", 1},
                      {"input",
                       {{"path", "input.stl"},
                        {"triangles", input.triangles.size()},
                        {"volume_mm3", signed_volume(input)},
                        {"bbox_mm",
                         {{bbox.min.x(), bbox.min.y(), bbox.min.z()},
                          {bbox.max.x(), bbox.max.y(), bbox.max.z()}}}}},
                      {"parts", nlohmann::json::array()},
                      {"assembly_order", order}};
  for (std::size_t i = 0; i < parts.size(); ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "parts/part_%03zu.stl", i);
    write_stl((out / name).string(), parts[i].mesh);
    const Vec3& d = parts[i].direction;
    nlohmann::json jp = {{"id", i},
                         {"mesh", name},
                         {"direction", {d.x(), d.y(), d.z()}},
                         {"volume_mm3", parts[i].volume_mm3 >= 0 ? parts[i].volume_mm3
                                                                 : signed_volume(parts[i].mesh)}};
    if (!parts[i].molds.empty()) {
      char up[64], down[64];
      std::snprintf(up, sizeof up, "molds/part_%03zu_up.stl", i);
      std::snprintf(down, sizeof down, "molds/part_%03zu_down.stl", i);
      write_stl((out / up).string(), parts[i].molds[0]);
      write_stl((out / down).string(), parts[i].molds[1]);
      // A sprue far from the part (it serves none of its surface) and three keys.
      jp["molds"] = {
          {"up", up},
          {"down", down},
          {"sprues",
           {{{"mouth", {1e3, 1e3, 1e3}}, {"exit", {1e3, 1e3, 1e3 + 1}}, {"diameter_mm", 1.0}}}},
          {"vents", nlohmann::json::array()},
          {"keys", {nlohmann::json::object(), nlohmann::json::object(), nlohmann::json::object()}}};
    }
    j["parts"].push_back(jp);
  }
  if (edit) edit(j);
  std::ofstream(out / "decomposition.json") << j.dump(2);
  return {out.string(), (root / "input.stl").string()};
}

CheckReport run(const Folder& f, bool with_input = true) {
  CheckOptions o;
  o.outdir = f.outdir;
  if (with_input) o.input_mesh = f.input;
  // Fewer samples than the defaults: these solids are simple, and the suite should stay quick.
  o.coverage_samples = 50000;
  o.fidelity_samples = 20000;
  o.mold_samples = 5000;
  return check_output(o);
}

const CheckItem& item(const CheckReport& r, const std::string& name) {
  for (const CheckItem& i : r.items)
    if (i.name == name) return i;
  throw std::runtime_error("no check named " + name);
}

double figure(const CheckItem& i, const std::string& key) {
  for (const auto& [k, v] : i.figures)
    if (k == key) return v;
  throw std::runtime_error("check " + i.name + " has no figure " + key);
}

// The checks in `failing` fail, every other one passes or is skipped.
void expect_failures(const CheckReport& r, const std::set<std::string>& failing) {
  SCOPED_TRACE(format_text(r));
  EXPECT_FALSE(r.passed());
  for (const CheckItem& i : r.items) {
    if (failing.contains(i.name)) {
      EXPECT_FALSE(i.skipped) << i.name;
      EXPECT_FALSE(i.passed) << i.name;
    } else {
      EXPECT_TRUE(i.skipped || i.passed) << i.name << ": " << i.summary;
    }
  }
}

// The reference decomposition: a 100 x 60 x 40 box cut at z = 20, both halves cast along +z,
// the bottom one placed first.
const Vec3 kLo(0, 0, 0), kHi(100, 60, 40), kCutLo(0, 0, 20), kCutHi(100, 60, 20);

std::vector<PartSpec> two_boxes(bool molds) {
  PartSpec bottom{box(kLo, kCutHi)}, top{box(kCutLo, kHi)};
  if (molds) {
    const auto mb = box_molds(kLo, kCutHi), mt = box_molds(kCutLo, kHi);
    bottom.molds = {mb[0], mb[1]};
    top.molds = {mt[0], mt[1]};
  }
  return {bottom, top};
}

TEST(Check, GoodFolderPassesEveryCheck) {
  const Folder f = write_folder("good", box(kLo, kHi), two_boxes(true), {0, 1});
  const CheckReport r = run(f);
  SCOPED_TRACE(format_text(r));
  EXPECT_TRUE(r.passed());
  ASSERT_EQ(r.items.size(), 7u);
  for (const CheckItem& i : r.items) {
    EXPECT_FALSE(i.skipped) << i.name;
    EXPECT_TRUE(i.passed) << i.name << ": " << i.summary;
  }
  const CheckItem& coverage = item(r, "coverage");
  EXPECT_EQ(figure(coverage, "overlap_fraction"), 0.0);
  EXPECT_EQ(figure(coverage, "gap_fraction"), 0.0);
  EXPECT_EQ(figure(coverage, "outside_fraction"), 0.0);
  EXPECT_EQ(figure(coverage, "covered_once_fraction"), 1.0);
  EXPECT_EQ(figure(coverage, "samples"), 50000.0);
  EXPECT_EQ(figure(item(r, "dhf"), "lines"), 4000.0);
  EXPECT_EQ(figure(item(r, "assembly"), "order_exists"), 1.0);
  EXPECT_GE(figure(item(r, "molds"), "min_surface_coverage"), 0.999);
  EXPECT_LT(figure(item(r, "fidelity"), "parts_to_input_max_mm"), 1e-3);
  EXPECT_LT(figure(item(r, "fidelity"), "input_to_parts_max_mm"), 1e-3);

  const std::string text = format_text(r);
  EXPECT_EQ(text.rfind("PASS contract", 0), 0u) << text;
  EXPECT_NE(text.find("\nPASS: 7 checks passed\n"), std::string::npos) << text;
  const nlohmann::json j = nlohmann::json::parse(format_json(r));
  EXPECT_TRUE(j["passed"].get<bool>());
  ASSERT_EQ(j["checks"].size(), 7u);
  EXPECT_EQ(j["checks"][2]["name"], "coverage");
  EXPECT_EQ(j["checks"][2]["status"], "pass");
  EXPECT_EQ(j["checks"][2]["figures"]["gap_fraction"], 0.0);
}

TEST(Check, SameFiguresOnOneThread) {
  const Folder f = write_folder("threads", box(kLo, kHi), two_boxes(true), {0, 1});
  const std::string many = format_json(run(f));
  oneapi::tbb::global_control one(oneapi::tbb::global_control::max_allowed_parallelism, 1);
  EXPECT_EQ(format_json(run(f)), many);
}

TEST(Check, WithoutInputFidelityIsSkippedAndTheRestStillRuns) {
  const Folder f = write_folder("no-input", box(kLo, kHi), two_boxes(false), {0, 1});
  const CheckReport r = run(f, false);
  SCOPED_TRACE(format_text(r));
  EXPECT_TRUE(r.passed());
  EXPECT_TRUE(item(r, "fidelity").skipped);
  EXPECT_TRUE(item(r, "molds").skipped);
  EXPECT_FALSE(item(r, "coverage").skipped);
  EXPECT_EQ(figure(item(r, "coverage"), "volume_error"), 0.0);  // against the json's input volume
}

// A U: base [0, 30] x [0, 10] x [0, 10] with prongs x in [0, 10] and [20, 30] up to z = 30.
TriMesh u_shape() {
  return grid_surface({0, 10, 20, 30}, {0, 10}, {0, 10, 30},
                      [](int i, int, int k) { return k == 0 || i != 1; });
}

// The point a summary names after `marker` ("x y z").
Vec3 point_after(const std::string& summary, const std::string& marker) {
  const std::size_t at = summary.find(marker);
  if (at == std::string::npos) {
    ADD_FAILURE() << "no \"" << marker << "\" in: " << summary;
    return Vec3::Constant(NAN);
  }
  std::istringstream in(summary.substr(at + marker.size()));
  Vec3 p;
  in >> p.x() >> p.y() >> p.z();
  return p;
}

TEST(Check, PartThatIsNotADoubleHeightFieldFailsOnlyDhf) {
  // Along x, lines through the prongs cross the 10 mm wide opening: 2 intervals, 5 mm deep gap.
  const Folder bad = write_folder("u-x", u_shape(), {{u_shape(), Vec3::UnitX()}}, {0});
  const CheckReport r = run(bad);
  expect_failures(r, {"dhf"});
  const CheckItem& dhf = item(r, "dhf");
  // Lines with z in (10, 30) of the footprint y in [0, 10], z in [0, 30] are violations: 2/3.
  EXPECT_NEAR(figure(dhf, "max_violation_fraction"), 2.0 / 3.0, 0.05);
  EXPECT_NEAR(figure(dhf, "max_depth_mm"), 5.0, 0.2);
  EXPECT_NE(dhf.summary.find("part 0"), std::string::npos) << dhf.summary;
  // The deepest gaps lie midway across the opening, at least 5 mm above the base.
  const Vec3 gap = point_after(dhf.summary, "deepest gap's middle at ");
  EXPECT_NEAR(gap.x(), 15.0, 0.01) << dhf.summary;
  EXPECT_TRUE(gap.y() > 0 && gap.y() < 10 && gap.z() >= 15 - 0.2 && gap.z() < 30) << dhf.summary;

  // The same U along z (its opening) is a double height field.
  const Folder good = write_folder("u-z", u_shape(), {{u_shape(), Vec3::UnitZ()}}, {0});
  EXPECT_TRUE(run(good).passed()) << format_text(run(good));
}

TEST(Check, GapWithinEpsilonIsTolerated) {
  // A U whose opening is 0.5 mm wide: the gap is at most 0.25 mm from the surface.
  const TriMesh narrow = grid_surface({0, 10, 10.5, 20.5}, {0, 10}, {0, 10, 30},
                                      [](int i, int, int k) { return k == 0 || i != 1; });
  const CheckReport r = run(write_folder("narrow", narrow, {{narrow, Vec3::UnitX()}}, {0}));
  SCOPED_TRACE(format_text(r));
  EXPECT_TRUE(item(r, "dhf").passed);
  EXPECT_EQ(figure(item(r, "dhf"), "violating_lines"), 0.0);
}

TEST(Check, OverlappingPartsFailCoverage) {
  // The bottom part reaches z = 25 and the top one starts at z = 15: 10 of 40 mm overlap.
  std::vector<PartSpec> parts = {{box(kLo, Vec3(100, 60, 25))}, {box(Vec3(0, 0, 15), kHi)}};
  const CheckReport r = run(write_folder("overlap", box(kLo, kHi), parts, {0, 1}));
  // The top part also ends inside the bottom one, so its way in is blocked too.
  expect_failures(r, {"coverage", "assembly"});
  EXPECT_NEAR(figure(item(r, "coverage"), "overlap_fraction"), 0.25, 0.02);
  EXPECT_NEAR(figure(item(r, "coverage"), "volume_error"), 0.25, 1e-9);
  EXPECT_EQ(figure(item(r, "coverage"), "gap_fraction"), 0.0);
}

TEST(Check, MissingChunkFailsCoverage) {
  // The top part stops at x = 80: a 20 x 60 x 20 chunk of the input is in no part.
  std::vector<PartSpec> parts = {{box(kLo, kCutHi)}, {box(kCutLo, Vec3(80, 60, 40))}};
  const CheckReport r = run(write_folder("gap", box(kLo, kHi), parts, {0, 1}));
  // The missing chunk also leaves a 20 mm step between the surfaces.
  expect_failures(r, {"coverage", "fidelity"});
  EXPECT_NEAR(figure(item(r, "coverage"), "gap_fraction"), 0.1, 0.01);
  EXPECT_EQ(figure(item(r, "coverage"), "overlap_fraction"), 0.0);
  EXPECT_NEAR(figure(item(r, "fidelity"), "input_to_parts_max_mm"), 20.0, 0.5);
}

// The top part has a 20 x 20 x 5 mm notch in its bottom face, over the bottom part: a void
// inside the assembled object, as carving leaves one.
struct NotchedTop {
  std::vector<PartSpec> parts;
  TriMesh hole;
};

NotchedTop notched_top() {
  const TriMesh top =
      grid_surface({0, 40, 60, 100}, {0, 20, 40, 60}, {20, 25, 40},
                   [](int i, int j, int k) { return !(i == 1 && j == 1 && k == 0); });
  return {{{box(kLo, kCutHi)}, {top}}, box(Vec3(40, 20, 20), Vec3(60, 40, 25))};
}

TEST(Check, CarvedVoidIsCountedApartFromGaps) {
  const NotchedTop n = notched_top();
  auto list_void = [&](const std::string& mesh, double volume) {
    return [=](nlohmann::json& j) {
      j["carving"] = {{"voids", {{{"part", 1}, {"mesh", mesh}, {"volume_mm3", volume}}}}};
    };
  };
  Folder f = write_folder("carved", box(kLo, kHi), n.parts, {0, 1},
                          list_void("parts/void_000.stl", 2000.0));
  write_stl(f.outdir + "/parts/void_000.stl", n.hole);
  CheckReport r = run(f);
  SCOPED_TRACE(format_text(r));
  EXPECT_TRUE(r.passed());
  const CheckItem& coverage = item(r, "coverage");
  EXPECT_NEAR(figure(coverage, "carved_mm3"), 2000.0, 1e-9);
  EXPECT_NEAR(figure(coverage, "carved_fraction"), 2000.0 / 240000.0, 0.002);
  EXPECT_EQ(figure(coverage, "gap_fraction"), 0.0);
  EXPECT_LT(figure(coverage, "volume_error"), 1e-9);
  EXPECT_EQ(figure(item(r, "solids"), "void_meshes"), 1.0);
  // The notch's walls are not outer surface.
  EXPECT_LT(figure(item(r, "fidelity"), "parts_to_input_max_mm"), 1e-3);

  // Unlisted, the same hole is a gap (0.83 % of the input) and a volume error, and its walls
  // are surface that is not the input's.
  r = run(write_folder("uncarved", box(kLo, kHi), n.parts, {0, 1}));
  expect_failures(r, {"coverage", "fidelity"});
  EXPECT_NEAR(figure(item(r, "coverage"), "gap_fraction"), 2000.0 / 240000.0, 0.002);

  // A void that overlaps a part counts as overlap; one whose file is missing breaks the contract.
  f = write_folder("carved-overlap", box(kLo, kHi), n.parts, {0, 1},
                   list_void("parts/void_000.stl", 4000.0));
  write_stl(f.outdir + "/parts/void_000.stl", box(Vec3(40, 20, 15), Vec3(60, 40, 25)));
  r = run(f);
  EXPECT_FALSE(item(r, "coverage").passed);
  EXPECT_NEAR(figure(item(r, "coverage"), "overlap_fraction"), 2000.0 / 240000.0, 0.002);
  r = run(write_folder("carved-missing", box(kLo, kHi), n.parts, {0, 1},
                       list_void("parts/void_009.stl", 2000.0)));
  EXPECT_FALSE(item(r, "contract").passed);
}

TEST(Check, AssemblyOrderThroughAnEarlierPartFails) {
  // Top first: the bottom part then arrives from above, through it.
  const CheckReport r = run(write_folder("order", box(kLo, kHi), two_boxes(false), {1, 0}));
  expect_failures(r, {"assembly"});
  const CheckItem& a = item(r, "assembly");
  EXPECT_GT(figure(a, "blocked_samples"), 0.0);
  EXPECT_EQ(figure(a, "order_exists"), 1.0);
  EXPECT_NE(a.summary.find("a collision-free order exists: 0 1"), std::string::npos) << a.summary;
  EXPECT_NEAR(figure(a, "max_inside_mm"), 20.0, 0.1);
  // The sample named is one of the bottom part's.
  const Vec3 first = point_after(a.summary, "first from ");
  EXPECT_TRUE(first.x() >= 0 && first.x() <= 100 && first.y() >= 0 && first.y() <= 60 &&
              first.z() >= 0 && first.z() <= 20.01)
      << a.summary;

  // With the top part cast along -z it must arrive from below: no order works.
  std::vector<PartSpec> parts = two_boxes(false);
  parts[1].direction = -Vec3::UnitZ();
  const CheckReport none = run(write_folder("no-order", box(kLo, kHi), parts, {0, 1}));
  expect_failures(none, {"assembly"});
  EXPECT_EQ(figure(item(none, "assembly"), "order_exists"), 0.0);

  // The same parts, the top one going in from above as its removal_direction says: it passes.
  const CheckReport removal =
      run(write_folder("removal", box(kLo, kHi), parts, {0, 1}, [](nlohmann::json& j) {
        j["parts"][1]["removal_direction"] = {0, 0, 1};
      }));
  SCOPED_TRACE(format_text(removal));
  EXPECT_TRUE(item(removal, "assembly").passed);
  EXPECT_EQ(figure(item(removal, "assembly"), "order_exists"), 1.0);
}

TEST(Check, SideBySidePartsSlideAlongTheirInterface) {
  // Cut at x = 50, both along +z: each slides down along the shared face without entering.
  std::vector<PartSpec> parts = {{box(kLo, Vec3(50, 60, 40))}, {box(Vec3(50, 0, 0), kHi)}};
  const CheckReport r = run(write_folder("side", box(kLo, kHi), parts, {1, 0}));
  SCOPED_TRACE(format_text(r));
  EXPECT_TRUE(r.passed());
  EXPECT_EQ(figure(item(r, "assembly"), "blocked_samples"), 0.0);
}

TEST(Check, OpenPartMeshFailsSolids) {
  std::vector<PartSpec> parts = two_boxes(false);
  // Drop one triangle of the bottom part's top face, an interface meshed finely enough that
  // the hole does not move the fidelity's 99th percentile.
  parts[0].mesh =
      grid_surface({0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100}, {0, 10, 20, 30, 40, 50, 60},
                   {0, 20}, [](int, int, int) { return true; });
  TriMesh& m = parts[0].mesh;
  const auto top = std::ranges::find_if(m.triangles, [&](const Tri& t) {
    return std::ranges::all_of(t, [&](std::int32_t v) { return m.vertices[v].z() == 20.0; });
  });
  ASSERT_NE(top, m.triangles.end());
  m.triangles.erase(top);
  parts[0].volume_mm3 = 100 * 60 * 20;
  const CheckReport r = run(write_folder("open", box(kLo, kHi), parts, {0, 1}));
  expect_failures(r, {"solids"});
  EXPECT_NE(item(r, "solids").summary.find("not closed"), std::string::npos)
      << item(r, "solids").summary;
}

TEST(Check, WrongVolumeInJsonFailsSolids) {
  std::vector<PartSpec> parts = two_boxes(false);
  parts[1].volume_mm3 = 1.001 * 100 * 60 * 20;
  const CheckReport r = run(write_folder("volume", box(kLo, kHi), parts, {0, 1}));
  expect_failures(r, {"solids"});
  EXPECT_NEAR(figure(item(r, "solids"), "max_volume_error"), 1e-3, 1e-9);
}

TEST(Check, PartTouchingItselfAlongAnEdgeIsASolid) {
  // Two cubes sharing only the edge x = 10, z = 10: welded, that edge has four triangles.
  const TriMesh touching =
      grid_surface({0, 10, 20}, {0, 10}, {0, 10, 20}, [](int i, int, int k) { return i == k; });
  ASSERT_FALSE(validate_mesh(touching).ok());
  const CheckReport r = run(write_folder("touch", touching, {{touching}}, {0}), false);
  SCOPED_TRACE(format_text(r));
  EXPECT_TRUE(item(r, "solids").passed);
}

// An L in the y-z section: a slab y in [0, 60], z in [10, 20], and below it a foot y in [20, 60],
// z in [0, 10]. Cast along +z, the mould's down half must fill the space under the overhang.
const std::vector<double> kLxs = {-10, 0, 100, 110}, kLys = {-10, 0, 20, 60, 70},
                          kLzs = {-10, 0, 10, 20, 30};
bool l_part(int i, int j, int k) {
  return i == 1 && ((j == 1 && k == 2) || (j == 2 && (k == 1 || k == 2)));
}

// The L's mold halves: the block [-10, 110] x [-10, 70] x [-10, 30] above and below z = 10
// (the up half takes z >= 10), less the L.
std::array<TriMesh, 2> l_molds() {
  return {grid_surface(kLxs, kLys, kLzs,
                       [](int i, int j, int k) { return k >= 2 && !l_part(i, j, k); }),
          grid_surface(kLxs, kLys, kLzs,
                       [](int i, int j, int k) { return k <= 1 && !l_part(i, j, k); })};
}

TEST(Check, MoldHalfWithAnUndercutFailsMolds) {
  const TriMesh part = grid_surface(kLxs, kLys, kLzs, l_part);
  const auto [up, down] = l_molds();
  const CheckReport good =
      run(write_folder("molds", part, {{part, Vec3::UnitZ(), {up, down}}}, {0}));
  SCOPED_TRACE(format_text(good));
  EXPECT_TRUE(good.passed());
  EXPECT_FALSE(item(good, "molds").skipped);

  // The up half also takes the layer z in [0, 10] on the overhang's side (y < 20): pulled up, it
  // runs into the overhang.
  auto undercut = [](int i, int j, int k) { return k == 1 && j <= 1 && !l_part(i, j, k); };
  const TriMesh bad_up = grid_surface(kLxs, kLys, kLzs, [&](int i, int j, int k) {
    return (k >= 2 && !l_part(i, j, k)) || undercut(i, j, k);
  });
  const TriMesh bad_down = grid_surface(kLxs, kLys, kLzs, [&](int i, int j, int k) {
    return k <= 1 && !l_part(i, j, k) && !undercut(i, j, k);
  });
  const CheckReport bad =
      run(write_folder("undercut", part, {{part, Vec3::UnitZ(), {bad_up, bad_down}}}, {0}));
  expect_failures(bad, {"molds"});
  EXPECT_GT(figure(item(bad, "molds"), "blocked_samples"), 0.0);

  // Without keys, or with an error instead of halves, the molds check fails (the contract
  // holds).
  const CheckReport no_keys = run(write_folder(
      "nokeys", part, {{part, Vec3::UnitZ(), {up, down}}}, {0},
      [](nlohmann::json& j) { j["parts"][0]["molds"]["keys"] = nlohmann::json::array(); }));
  expect_failures(no_keys, {"molds"});
  EXPECT_NE(item(no_keys, "molds").summary.find("key"), std::string::npos);
  const CheckReport failed = run(write_folder(
      "moldfailed", part, {{part, Vec3::UnitZ(), {up, down}}}, {0}, [](nlohmann::json& j) {
        j["parts"][0]["molds"] = {{"error", "part 0: no luck"}};
      }));
  expect_failures(failed, {"molds"});
  EXPECT_NE(item(failed, "molds").summary.find("no luck"), std::string::npos);

  EXPECT_EQ(figure(item(good, "molds"), "max_channel_served_fraction"), 0.0);
  EXPECT_NE(item(bad, "molds").summary.find("up half"), std::string::npos)
      << item(bad, "molds").summary;

  // A mold file that is not there fails the molds but leaves the parts' checks running.
  const CheckReport missing = run(write_folder(
      "no-mold", part, {{part, Vec3::UnitZ(), {up, down}}}, {0},
      [](nlohmann::json& j) { j["parts"][0]["molds"]["down"] = "molds/nowhere.stl"; }));
  expect_failures(missing, {"contract", "solids", "molds"});
  EXPECT_TRUE(item(missing, "dhf").passed);
}

// Halves whose cavity is wider than the part on its +x side (a tenth of its surface): a
// sliver thinner than epsilon there is an undercut the tolerance accepts, filled by the cast;
// open space reaching further out than epsilon leaves the face unmoulded.
TEST(Check, MoldSliverWithinEpsilonIsToleratedWiderIsNot) {
  const TriMesh part = box(kLo, kHi);
  auto with_cavity_wider_by = [&](const std::string& name, double mm) {
    const auto [up, down] = box_molds(kLo, kHi + Vec3(mm, 0, 0));
    return run(write_folder(name, part, {{part, Vec3::UnitZ(), {up, down}}}, {0}));
  };
  const double face_share = 60.0 * 40.0 / (2 * (100.0 * 60.0 + 100.0 * 40.0 + 60.0 * 40.0));
  const CheckReport sliver = with_cavity_wider_by("sliver", 0.3);  // epsilon is 0.4 mm
  SCOPED_TRACE(format_text(sliver));
  EXPECT_TRUE(sliver.passed());
  EXPECT_NEAR(figure(item(sliver, "molds"), "max_undercut_sliver_fraction"), face_share, 0.02);
  EXPECT_GE(figure(item(sliver, "molds"), "min_surface_coverage"), 0.999);

  const CheckReport fin = with_cavity_wider_by("fin", 1.0);
  expect_failures(fin, {"molds"});
  EXPECT_EQ(figure(item(fin, "molds"), "max_undercut_sliver_fraction"), 0.0);
  EXPECT_NEAR(figure(item(fin, "molds"), "min_surface_coverage"), 1 - face_share, 0.02);
  EXPECT_NE(item(fin, "molds").summary.find("first bare sample at 100.00"), std::string::npos)
      << item(fin, "molds").summary;
}

// Mold halves written in frames of their own (as dhfcast writes them, laid flat to print) are
// checked where decomposition.json's motions put them back around the part.
TEST(Check, MoldHalvesArePlacedByTheirMotions) {
  const TriMesh part = grid_surface(kLxs, kLys, kLzs, l_part);
  const auto [up, down] = l_molds();
  // Each half's file holds it moved by the inverse of its motion to the model.
  using Motion = Eigen::Matrix<double, 3, 4>;
  auto motion = [](double angle, const Vec3& axis, const Vec3& shift) {
    Motion m;
    m << Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix(), shift;
    return m;
  };
  const Motion up_to_model = motion(2.5, Vec3(1, 2, 3), Vec3(40, -7, 12)),
               down_to_model = motion(-0.4, Vec3(0, 1, 0), Vec3(-3, 5, 60));
  auto moved_back = [](TriMesh m, const Motion& to_model) {
    for (Vec3& p : m.vertices) p = to_model.leftCols<3>().transpose() * (p - to_model.col(3));
    return m;
  };
  auto rows = [](const Motion& m) {
    nlohmann::json j = nlohmann::json::array();
    for (int r = 0; r < 3; ++r) j.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
    return j;
  };
  const std::vector<PartSpec> parts = {
      {part, Vec3::UnitZ(), {moved_back(up, up_to_model), moved_back(down, down_to_model)}}};
  auto with_motions = [&](const Motion& up_motion) {
    return [&, up_motion](nlohmann::json& j) {
      j["parts"][0]["molds"]["up_to_model"] = rows(up_motion);
      j["parts"][0]["molds"]["down_to_model"] = rows(down_to_model);
    };
  };
  const CheckReport placed =
      run(write_folder("placed", part, parts, {0}, with_motions(up_to_model)));
  SCOPED_TRACE(format_text(placed));
  EXPECT_TRUE(placed.passed());
  EXPECT_GE(figure(item(placed, "molds"), "min_surface_coverage"), 0.99);

  // Without the motions the halves are taken as they are in the files: far off the part.
  expect_failures(run(write_folder("unplaced", part, parts, {0})), {"molds"});

  // A motion that is not rigid, or not a motion, fails the contract with a one-line reason (and
  // the molds, whose half cannot be placed).
  Motion scaled = up_to_model;
  scaled.leftCols<3>() *= 1.01;
  Motion mirrored = up_to_model;
  mirrored.col(0) *= -1;
  for (const auto& [tag, bad, reason] :
       {std::tuple{"scaled", rows(scaled), "is not rigid"},
        std::tuple{"mirrored", rows(mirrored), "is a reflection"},
        std::tuple{"short", nlohmann::json{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, "is not 3 rows"},
        std::tuple{"text", nlohmann::json{{1, 0, 0, "x"}, {0, 1, 0, 0}, {0, 0, 1, 0}},
                   "has an entry that is not a number"}}) {
    SCOPED_TRACE(tag);
    const nlohmann::json& motion = bad;  // a structured binding: not captured by clang 14
    const CheckReport r = run(write_folder(tag, part, parts, {0}, [&](nlohmann::json& j) {
      with_motions(up_to_model)(j);
      j["parts"][0]["molds"]["up_to_model"] = motion;
    }));
    expect_failures(r, {"contract", "molds"});
    const std::string& summary = item(r, "contract").summary;
    EXPECT_NE(summary.find("parts[0] molds.up_to_model " + std::string(reason)), std::string::npos)
        << summary;
    EXPECT_EQ(summary.find('\n'), std::string::npos);
  }
}

TEST(Check, OrderThatIsNotAPermutationFailsContract) {
  const CheckReport r = run(write_folder("contract", box(kLo, kHi), two_boxes(false), {0, 0}));
  expect_failures(r, {"contract"});
  EXPECT_TRUE(item(r, "assembly").skipped);
  EXPECT_NE(item(r, "contract").summary.find("not a permutation"), std::string::npos);
}

TEST(Check, ContractViolationsAreFoundAndStopTheGeometricChecksWhenNeeded) {
  auto contract_of = [](const std::string& tag, std::function<void(nlohmann::json&)> edit) {
    return item(run(write_folder(tag, box(kLo, kHi), two_boxes(false), {0, 1}, edit)), "contract");
  };
  EXPECT_FALSE(contract_of("fmt", [](nlohmann::json& j) { j["format"] = "other"; }).passed);
  EXPECT_FALSE(contract_of("ver", [](nlohmann::json& j) { j["version"] = 2; }).passed);
  EXPECT_FALSE(contract_of("dir", [](nlohmann::json& j) {
                 j["parts"][1]["direction"] = {0, 0, 2};
               }).passed);
  EXPECT_FALSE(contract_of("removal", [](nlohmann::json& j) {
                 j["parts"][1]["removal_direction"] = {0, 0.5, 0};
               }).passed);
  EXPECT_FALSE(contract_of("ids", [](nlohmann::json& j) { j["parts"][1]["id"] = 5; }).passed);
  EXPECT_FALSE(
      contract_of("vol", [](nlohmann::json& j) { j["parts"][0].erase("volume_mm3"); }).passed);

  // A part file that does not exist: the geometric checks cannot run.
  const CheckReport missing =
      run(write_folder("missing", box(kLo, kHi), two_boxes(false), {0, 1},
                       [](nlohmann::json& j) { j["parts"][1]["mesh"] = "parts/nowhere.stl"; }));
  EXPECT_FALSE(missing.passed());
  EXPECT_FALSE(item(missing, "contract").passed);
  EXPECT_FALSE(item(missing, "solids").passed);
  EXPECT_TRUE(item(missing, "coverage").skipped);

  // Not JSON at all: a failed contract, not an exception.
  const Folder f = write_folder("garbage", box(kLo, kHi), two_boxes(false), {0, 1});
  std::ofstream(fs::path(f.outdir) / "decomposition.json") << "{\"format\": ";
  const CheckReport garbage = run(f);
  EXPECT_FALSE(item(garbage, "contract").passed);
  EXPECT_NE(item(garbage, "contract").summary.find("not valid JSON"), std::string::npos);
  EXPECT_TRUE(item(garbage, "dhf").skipped);
}

TEST(Check, FileNamesLeadingOutOfTheFolderFailContractAndAreNotOpened) {
  // Outside the folder: a copy of part 1 a bad name would reach.
  const Folder outside = write_folder("outside", box(kLo, kHi), two_boxes(false), {0, 1});
  const std::string stray = (fs::path(outside.outdir) / "parts/part_001.stl").string();
  const std::pair<std::string, std::string> names[] = {
      {stray, " is not relative to the folder"},
      {"../../" +
           fs::relative(stray, fs::path(outside.outdir).parent_path().parent_path()).string(),
       " has a '..' component"},
      {"parts/link.stl", " goes through the symlink parts/link.stl"},
      {"linked/part_001.stl", " goes through the symlink linked"}};
  for (const auto& [name, wrong] : names) {
    const Folder f =
        write_folder("escape", box(kLo, kHi), two_boxes(false), {0, 1},
                     [&, &mesh = name](nlohmann::json& j) { j["parts"][1]["mesh"] = mesh; });
    fs::create_symlink(stray, fs::path(f.outdir) / "parts/link.stl");
    fs::create_directory_symlink(fs::path(outside.outdir) / "parts", fs::path(f.outdir) / "linked");
    const CheckReport r = run(f);
    EXPECT_EQ(item(r, "contract").summary, "parts[1] mesh " + name + wrong);
    EXPECT_TRUE(item(r, "coverage").skipped);
  }
  // Mold halves and carved voids go the same way.
  const CheckReport molds = run(
      write_folder("escape_molds", box(kLo, kHi), two_boxes(true), {0, 1}, [&](nlohmann::json& j) {
        j["parts"][0]["molds"]["down"] = "../molds/part_000_down.stl";
        j["carving"] = {{"voids", {{{"part", 0}, {"mesh", stray}, {"volume_mm3", 1.0}}}}};
      }));
  EXPECT_EQ(item(molds, "contract").summary,
            "parts[0] mold ../molds/part_000_down.stl has a '..' component (and 1 more)");
}

TEST(Check, NumbersOutOfRangeAndDeepNestingFailContractNotTheProgram) {
  auto contract_of = [](const std::string& tag, std::function<void(nlohmann::json&)> edit) {
    return item(run(write_folder(tag, box(kLo, kHi), two_boxes(true), {0, 1}, edit)), "contract");
  };
  // 1e308 made the checker die of SIGFPE, 1e20 hang.
  for (double t : {1e308, 1e20}) {
    const CheckItem c = contract_of("translation", [t](nlohmann::json& j) {
      j["parts"][0]["molds"]["up_to_model"] = {{1, 0, 0, t}, {0, 1, 0, 0}, {0, 0, 1, 0}};
    });
    EXPECT_EQ(c.summary,
              "parts[0] molds.up_to_model has an entry that is not a number within "
              "+-1e+06");
  }
  EXPECT_EQ(
      contract_of("volume", [](nlohmann::json& j) { j["parts"][1]["volume_mm3"] = "1"; }).summary,
      "parts[1] has no volume_mm3 within +-1e+18");
  EXPECT_EQ(
      contract_of("input", [](nlohmann::json& j) { j["input"]["volume_mm3"] = 1e300; }).summary,
      "input.volume_mm3 is not a number within +-1e+18");

  const Folder f = write_folder("overflow", box(kLo, kHi), two_boxes(false), {0, 1});
  const fs::path json_path = fs::path(f.outdir) / "decomposition.json";
  std::stringstream text;
  text << std::ifstream(json_path).rdbuf();
  std::string overflow = text.str();
  overflow.replace(overflow.find("\"volume_mm3\":") + 14, 0, "1e400, \"was\": ");
  std::ofstream(json_path) << overflow;
  // nlohmann names the value only: the message names its field too.
  EXPECT_EQ(item(run(f), "contract").summary,
            "decomposition.json: not valid JSON at input.volume_mm3: number overflow parsing "
            "'1e400'");
  overflow = text.str();
  overflow.insert(overflow.find("\"direction\":") + 12, "[0, 0, 1e400], \"was\": ");
  std::ofstream(json_path) << overflow;
  EXPECT_EQ(item(run(f), "contract").summary,
            "decomposition.json: not valid JSON at parts[0].direction[2]: number overflow "
            "parsing '1e400'");
  // Found by fuzzing: nlohmann's message quotes the bytes it read, here no UTF-8; --json's
  // output could not be written (std::terminate).
  std::string bad_utf8 = text.str();
  bad_utf8.replace(bad_utf8.find("\"format\""), 8,
                   "\"f\xee"
                   "mat\"");
  std::ofstream(json_path) << bad_utf8;
  const CheckReport utf8 = run(f);
  EXPECT_NE(item(utf8, "contract").summary.find("not valid JSON"), std::string::npos);
  EXPECT_FALSE(nlohmann::json::parse(format_json(utf8), nullptr, false).is_discarded());
  // Nesting that overflowed the stack.
  std::string deep = text.str();
  deep.insert(deep.rfind('}'),
              ", \"deep\": " + std::string(100000, '[') + std::string(100000, ']'));
  std::ofstream(json_path) << deep;
  EXPECT_NE(item(run(f), "contract").summary.find("deeper than 64 levels"), std::string::npos);
}

TEST(Check, UnreadableFolderOrBadOptionsThrow) {
  CheckOptions o;
  o.outdir = test::temp_dir("check-empty") + "/absent";
  try {
    check_output(o);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Io);
  }
  o.outdir = test::temp_dir("check-empty");  // exists, but has no decomposition.json
  try {
    check_output(o);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Io);
  }
  o.epsilon_mm = 0;
  try {
    check_output(o);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidOptions);
  }
}

// --- real meshes ---

TriMesh translated(TriMesh m, const Vec3& t) {
  for (Vec3& p : m.vertices) p += t;
  return m;
}

TEST(CheckRealMesh, ElephantAsItsOwnPartCoversItExactly) {
  const std::string path = test::cgal_mesh("elephant.off");
  if (path.empty()) GTEST_SKIP() << "CGAL's data set (libcgal-demo) is not installed";
  const TriMesh elephant = test::load_scaled(path, 150.0);
  const CheckReport r = run(write_folder("elephant", elephant, {{elephant}}, {0}));
  SCOPED_TRACE(format_text(r));
  for (const char* name : {"contract", "solids", "coverage", "assembly", "fidelity"})
    EXPECT_TRUE(item(r, name).passed) << name;
  const CheckItem& coverage = item(r, "coverage");
  EXPECT_EQ(figure(coverage, "overlap_fraction"), 0.0);
  EXPECT_EQ(figure(coverage, "gap_fraction"), 0.0);
  EXPECT_EQ(figure(coverage, "outside_fraction"), 0.0);
  // The STL holds float coordinates: the surfaces agree to float precision.
  EXPECT_LT(figure(item(r, "fidelity"), "input_to_parts_max_mm"), 1e-4);

  // Moved by 2 mm, the part leaves some of the input uncovered and sticks out elsewhere.
  const TriMesh moved = translated(elephant, Vec3(2, 0, 0));
  const CheckReport m = run(write_folder("elephant-moved", elephant, {{moved}}, {0}));
  SCOPED_TRACE(format_text(m));
  EXPECT_FALSE(item(m, "coverage").passed);
  EXPECT_GT(figure(item(m, "coverage"), "gap_fraction"), 0.005);
  // A translation keeps the volume: what leaves the input equals what it leaves uncovered, up
  // to sampling noise.
  EXPECT_NEAR(figure(item(m, "coverage"), "gap_fraction"),
              figure(item(m, "coverage"), "outside_fraction"), 0.03);
  EXPECT_FALSE(item(m, "fidelity").passed);
  EXPECT_TRUE(item(m, "solids").passed);
}

TEST(CheckRealMesh, ConvexMeshIsADoubleHeightFieldAlongAnyDirection) {
  const std::string path = test::cgal_mesh("ellipsoid.off");
  if (path.empty()) GTEST_SKIP() << "CGAL's data set (libcgal-demo) is not installed";
  const TriMesh ellipsoid = test::load_scaled(path, 100.0);
  const Vec3 d = Vec3(0.3, -0.5, 0.8).normalized();
  const CheckReport r = run(write_folder("ellipsoid", ellipsoid, {{ellipsoid, d}}, {0}));
  SCOPED_TRACE(format_text(r));
  EXPECT_TRUE(r.passed());
  EXPECT_EQ(figure(item(r, "dhf"), "lines"), 2000.0);
  EXPECT_EQ(figure(item(r, "dhf"), "violating_lines"), 0.0);
}

}  // namespace
}  // namespace dhfcast
