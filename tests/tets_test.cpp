#include "dhfcast/tets.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "support/test_support.h"

namespace dhfcast {
namespace {

// Smallest dihedral angle of any tet, degrees.
double min_dihedral_deg(const TetMesh& mesh) {
  double min_deg = 180.0;
  for (const Tet& t : mesh.tets)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        // Edge (i, j); the two faces along it contain the other two vertices k and l.
        int other[2], n = 0;
        for (int k = 0; k < 4; ++k)
          if (k != i && k != j) other[n++] = k;
        const Vec3& a = mesh.vertices[t[i]];
        const Vec3 e = (mesh.vertices[t[j]] - a).normalized();
        Vec3 u = mesh.vertices[t[other[0]]] - a;
        Vec3 v = mesh.vertices[t[other[1]]] - a;
        u -= e * e.dot(u);
        v -= e * e.dot(v);
        const double c = std::clamp(u.normalized().dot(v.normalized()), -1.0, 1.0);
        min_deg = std::min(min_deg, std::acos(c) * 180.0 / std::numbers::pi);
      }
  return min_deg;
}

// Every tet positive, every neighbour link mutual and across the same three vertices.
void expect_valid_tets(const TetMesh& mesh) {
  ASSERT_EQ(mesh.neighbors.size(), mesh.tets.size());
  std::int64_t flat = 0, broken_links = 0;
  std::vector<char> used(mesh.vertices.size(), 0);
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(mesh.tets.size()); ++t) {
    if (!(tet_volume(mesh, t) > 0.0)) ++flat;
    for (const std::int32_t v : mesh.tets[t]) used[v] = 1;
    for (int i = 0; i < 4; ++i) {
      const std::int32_t u = mesh.neighbors[t][i];
      if (u < 0) continue;
      const auto back = std::find(mesh.neighbors[u].begin(), mesh.neighbors[u].end(), t);
      if (back == mesh.neighbors[u].end()) {
        ++broken_links;
        continue;
      }
      const int j = static_cast<int>(back - mesh.neighbors[u].begin());
      std::array<std::int32_t, 3> fa, fb;
      for (int k = 0; k < 3; ++k) {
        fa[k] = mesh.tets[t][kTetFaces[i][k]];
        fb[k] = mesh.tets[u][kTetFaces[j][k]];
      }
      std::sort(fa.begin(), fa.end());
      std::sort(fb.begin(), fb.end());
      if (fa != fb) ++broken_links;
    }
  }
  EXPECT_EQ(flat, 0) << "tets with non-positive volume";
  EXPECT_EQ(broken_links, 0) << "asymmetric adjacency";
  EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0) << "unused vertices";
}

// Boundary faces (outward by kTetFaces): total area; closed = every directed edge is matched by
// its reverse.
struct BoundaryStats {
  double area_mm2 = 0.0;
  std::int64_t faces = 0;
  bool closed = true;
};
BoundaryStats boundary_stats(const TetMesh& mesh) {
  BoundaryStats s;
  std::map<std::pair<std::int32_t, std::int32_t>, int> balance;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(mesh.tets.size()); ++t)
    for (int i = 0; i < 4; ++i) {
      if (mesh.neighbors[t][i] >= 0) continue;
      ++s.faces;
      s.area_mm2 += tet_face_area(mesh, t, i);
      for (int e = 0; e < 3; ++e) {
        const std::int32_t a = mesh.tets[t][kTetFaces[i][e]];
        const std::int32_t b = mesh.tets[t][kTetFaces[i][(e + 1) % 3]];
        balance[{std::min(a, b), std::max(a, b)}] += a < b ? 1 : -1;
      }
    }
  for (const auto& [edge, count] : balance)
    if (count != 0) s.closed = false;
  return s;
}

TriMesh elephant_100mm() {
  const std::string path = test::cgal_mesh("elephant.off");
  return path.empty() ? TriMesh{} : test::load_scaled(path, 100.0);
}

TEST(Tetrahedralize, BoxVolumeAndBoundaryAreExact) {
  const TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(40, 30, 20));
  const TetMesh tets = tetrahedralize(box, {.target_tets = 5000});
  expect_valid_tets(tets);
  EXPECT_NEAR(total_volume(tets), 24000.0, 0.005 * 24000.0);
  const BoundaryStats b = boundary_stats(tets);
  EXPECT_TRUE(b.closed);
  EXPECT_NEAR(b.area_mm2, 5200.0, 0.01 * 5200.0);
  // Sharp edges are kept as features, so the boundary lies on the box's faces.
  EXPECT_LE(tets.boundary_tolerance_mm, 0.1);
  EXPECT_GT(min_dihedral_deg(tets), 0.0);
  RecordProperty("min_dihedral_deg", std::to_string(min_dihedral_deg(tets)));
}

TEST(Tetrahedralize, CupCavityIsKept) {
  const TriMesh cup = test::make_cup(50.0, 10.0);
  const TetMesh tets = tetrahedralize(cup, {.target_tets = 8000});
  expect_valid_tets(tets);
  const double v_in = signed_volume(cup);
  EXPECT_NEAR(total_volume(tets), v_in, 0.005 * v_in);
  EXPECT_TRUE(boundary_stats(tets).closed);
}

TEST(Tetrahedralize, CountFollowsTargetOnElephant) {
  const TriMesh elephant = elephant_100mm();
  if (elephant.triangles.empty()) GTEST_SKIP() << "CGAL data set absent";
  // Coarse targets need a boundary allowance to match: 0.1 mm alone forces ~17k tets here.
  const TetMesh small = tetrahedralize(elephant, {.target_tets = 5000, .facet_distance_mm = 0.3});
  const TetMesh large = tetrahedralize(elephant, {.target_tets = 20000, .facet_distance_mm = 0.3});
  const auto n_small = static_cast<double>(small.tets.size());
  const auto n_large = static_cast<double>(large.tets.size());
  EXPECT_NEAR(n_small, 5000.0, 0.4 * 5000.0);
  EXPECT_NEAR(n_large, 20000.0, 0.4 * 20000.0);
  EXPECT_GT(n_large, 2.0 * n_small);
  expect_valid_tets(small);
  expect_valid_tets(large);
}

TEST(Tetrahedralize, ElephantVolumeAndBoundaryMatchInput) {
  const TriMesh elephant = elephant_100mm();
  if (elephant.triangles.empty()) GTEST_SKIP() << "CGAL data set absent";
  const TetOptions opts{.target_tets = 20000, .facet_distance_mm = 0.1};
  const TetMesh tets = tetrahedralize(elephant, opts);
  expect_valid_tets(tets);
  const double v_in = signed_volume(elephant);
  EXPECT_NEAR(total_volume(tets), v_in, 0.01 * v_in);
  EXPECT_TRUE(boundary_stats(tets).closed);
  EXPECT_GT(tets.boundary_tolerance_mm, 0.0);
  EXPECT_LE(tets.boundary_tolerance_mm, 2.0 * opts.facet_distance_mm);
  const double min_deg = min_dihedral_deg(tets);
  EXPECT_GT(min_deg, 0.0);
  RecordProperty("tets", std::to_string(tets.tets.size()));
  RecordProperty("min_dihedral_deg", std::to_string(min_deg));
}

TEST(Tetrahedralize, SameSeedSameMesh) {
  const TriMesh elephant = elephant_100mm();
  if (elephant.triangles.empty()) GTEST_SKIP() << "CGAL data set absent";
  const TetOptions opts{.target_tets = 5000, .facet_distance_mm = 0.3, .seed = 7};
  const TetMesh a = tetrahedralize(elephant, opts);
  const TetMesh b = tetrahedralize(elephant, opts);
  EXPECT_EQ(a.tets, b.tets);
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.neighbors, b.neighbors);
  EXPECT_EQ(a.boundary_tolerance_mm, b.boundary_tolerance_mm);
}

TEST(Tetrahedralize, InvalidOptionsThrow) {
  const TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(10, 10, 10));
  for (const TetOptions& bad :
       {TetOptions{.target_tets = 0}, TetOptions{.target_tets = -5},
        TetOptions{.facet_distance_mm = 0.0}, TetOptions{.facet_distance_mm = -0.1},
        TetOptions{.facet_distance_mm = std::nan("")},
        TetOptions{.facet_distance_mm = std::numeric_limits<double>::infinity()}}) {
    try {
      tetrahedralize(box, bad);
      ADD_FAILURE() << "no exception for target_tets=" << bad.target_tets
                    << " facet_distance_mm=" << bad.facet_distance_mm;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidOptions) << e.what();
    }
  }
}

// CGAL's couplingdown is 1 mm wide in its own units: its thin arms are lost at the default facet
// distance, and the message says the likely cause (units) and the fix.
TEST(Tetrahedralize, TinyModelThatFallsApartIsToldToCheckItsUnits) {
  const std::string path = test::cgal_mesh("couplingdown.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set absent (install libcgal-demo)";
  try {
    tetrahedralize(load_solid(path).mesh, {});
    ADD_FAILURE() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::TetrahedralizationFailed) << e.what();
    EXPECT_NE(std::string(e.what()).find("disconnected pieces"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("try --size MM or --units"), std::string::npos)
        << e.what();
  }
}

TEST(Tetrahedralize, TwoSeparateSolidsAreNotOneVolume) {
  TriMesh two = test::make_box(Vec3(0, 0, 0), Vec3(10, 10, 10));
  const TriMesh other = test::make_box(Vec3(20, 0, 0), Vec3(30, 10, 10));
  const auto offset = static_cast<std::int32_t>(two.vertices.size());
  two.vertices.insert(two.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (Tri t : other.triangles) {
    for (std::int32_t& v : t) v += offset;
    two.triangles.push_back(t);
  }
  try {
    tetrahedralize(two, {.target_tets = 1000});
    ADD_FAILURE() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::TetrahedralizationFailed) << e.what();
  }
}

TEST(Tetrahedralize, BunnyAtDefaultTarget) {
  const std::string path = test::extra_model("bunny.stl");
  if (path.empty()) GTEST_SKIP() << "bunny.stl absent";
  const TriMesh bunny = test::load_scaled(path, 0.0);
  const TetMesh tets = tetrahedralize(bunny, {.target_tets = 50000});
  EXPECT_GE(tets.tets.size(), 40000u);
  EXPECT_LE(tets.tets.size(), 65000u);
  expect_valid_tets(tets);
  const double v_in = signed_volume(bunny);
  EXPECT_NEAR(total_volume(tets), v_in, 0.01 * v_in);
  EXPECT_TRUE(boundary_stats(tets).closed);
  EXPECT_LE(tets.boundary_tolerance_mm, 0.25);
  RecordProperty("tets", std::to_string(tets.tets.size()));
  RecordProperty("boundary_tolerance_mm", std::to_string(tets.boundary_tolerance_mm));
  RecordProperty("min_dihedral_deg", std::to_string(min_dihedral_deg(tets)));
}

// CGAL's mpi_triang.off (180 triangles, 20 mm) has sharp edges 1 um apart: the balls protecting
// them shrank for ever and the mesher never returned. The vertex budget now ends each run, and
// the stage stops with a message that names the cause.
TEST(Tetrahedralize, SharpEdgesCloserThanTheTetSizeEndTheMesher) {
  const std::string path = test::cgal_mesh("mpi_triang.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set absent (install libcgal-demo)";
  try {
    const TetMesh tets = tetrahedralize(load_solid(path).mesh, {.target_tets = 100});
    ADD_FAILURE() << "meshed into " << tets.tets.size() << " tets";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::TetrahedralizationFailed) << e.what();
    EXPECT_NE(std::string(e.what()).find("was stopped"), std::string::npos) << e.what();
  }
}

// At a larger target the same edges never reach the vertex budget: the protection loops without
// adding vertices. The run's time budget stops it (here 2 s; by default 60 s + 2 ms per tet).
TEST(Tetrahedralize, MesherThatLoopsStopsAtItsTimeBudget) {
  const std::string path = test::cgal_mesh("mpi_triang.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set absent (install libcgal-demo)";
  try {
    const TetMesh tets =
        tetrahedralize(load_solid(path).mesh, {.target_tets = 5000, .max_mesher_seconds = 2.0});
    ADD_FAILURE() << "meshed into " << tets.tets.size() << " tets";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::TetrahedralizationFailed) << e.what();
    EXPECT_NE(std::string(e.what()).find("ran for over 2 s"), std::string::npos) << e.what();
  }
}

// An icosphere: the icosahedron's faces split `levels` times, vertices pushed to the sphere.
TriMesh icosphere(double radius_mm, int levels) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  TriMesh m;
  m.vertices = {{-1, g, 0},  {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
                {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
  m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> middle;
    auto mid = [&](std::int32_t a, std::int32_t b) {
      const auto [it, added] = middle.emplace(std::minmax(a, b), 0);
      if (added) {
        it->second = static_cast<std::int32_t>(m.vertices.size());
        m.vertices.push_back((m.vertices[a] + m.vertices[b]) / 2.0);
      }
      return it->second;
    };
    std::vector<Tri> finer;
    for (const Tri& t : m.triangles) {
      const std::int32_t ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      finer.insert(finer.end(), {{t[0], ab, ca}, {t[1], bc, ab}, {t[2], ca, bc}, {ab, bc, ca}});
    }
    m.triangles = std::move(finer);
  }
  for (Vec3& v : m.vertices) v = radius_mm * v.normalized();
  return m;
}

// A 50 m sphere (under load_solid()'s 100 m limit) was meshed at the default 0.1 mm facet
// distance: millions of boundary facets, memory growing for ever. The vertex budget stops it, and
// the message says why; the same sphere at 25 mm meshes to about the target.
TEST(Tetrahedralize, FiftyMetreSphereStopsAtTheVertexBudget) {
  const TetMesh tets = tetrahedralize(icosphere(25.0, 3), {.target_tets = 5000});
  EXPECT_GE(tets.tets.size(), 3000u);
  EXPECT_LE(tets.tets.size(), 8000u);
  expect_valid_tets(tets);
  try {
    tetrahedralize(icosphere(25000.0, 3), {.target_tets = 100});
    ADD_FAILURE() << "a 50 m sphere meshed at 0.1 mm";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::TetrahedralizationFailed) << e.what();
    EXPECT_NE(std::string(e.what()).find("50 m long: is it in mm?"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dhfcast