#include "dhfcast/parts.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "carve.h"
#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "dhfcast/tets.h"
#include "support/test_support.h"

namespace dhfcast {
namespace {

using Cell = std::array<int, 3>;

// A box of nx * ny * nz cubes of side cell_mm, each split into 6 positively oriented tets (the
// Freudenthal split: conforming across cubes). Cells are numbered x fastest, z slowest, and a
// cell's tets are consecutive, so cell c owns tets 6c .. 6c + 5.
struct Grid {
  std::array<int, 3> n;
  TetMesh mesh;
  std::vector<Cell> cell_of_tet;
};

// jitter_rel > 0 moves every vertex by up to jitter_rel * cell_mm along each axis
// (pseudo-randomly), so no ray or face is axis-aligned any more. Vertices are numbered x fastest,
// z slowest, like the cells.
Grid make_grid(int nx, int ny, int nz, double cell_mm, double jitter_rel = 0.0) {
  auto coords = [cell_mm](int cells) {
    std::vector<double> c;
    for (int i = 0; i <= cells; ++i) c.push_back(i * cell_mm);
    return c;
  };
  // Oriented on the undisturbed cubes, so jitter can only show up as a failed check.
  const TetMesh cubes =
      test::grid_tets(coords(nx), coords(ny), coords(nz), [](int, int, int) { return true; });
  Grid g{{nx, ny, nz}, {}, {}};
  std::uint32_t seed = 12345;
  auto jitter = [&] {
    seed = seed * 1664525u + 1013904223u;
    return jitter_rel * cell_mm * (static_cast<double>(seed >> 8) / double(1 << 24) * 2.0 - 1.0);
  };
  for (int z = 0; z <= nz; ++z)
    for (int y = 0; y <= ny; ++y)
      for (int x = 0; x <= nx; ++x) {
        const Vec3 offset(jitter(), jitter(), jitter());
        g.mesh.vertices.push_back(Vec3(x, y, z) * cell_mm + offset);
      }
  auto vertex = [&](const Vec3& p) {
    auto at = [&](double c) { return static_cast<int>(std::lround(c / cell_mm)); };
    return (at(p.z()) * (ny + 1) + at(p.y())) * (nx + 1) + at(p.x());
  };
  // test::grid_tets visits the cells z fastest; take them x fastest.
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x)
        for (int s = 0; s < 6; ++s) {
          Tet tet = cubes.tets[6 * ((x * ny + y) * nz + z) + s];
          for (std::int32_t& v : tet) v = vertex(cubes.vertices[v]);
          g.mesh.tets.push_back(tet);
          EXPECT_GT(tet_volume(g.mesh, static_cast<std::int32_t>(g.mesh.tets.size()) - 1), 0.0);
          g.cell_of_tet.push_back({x, y, z});
        }
  build_tet_adjacency(g.mesh);
  return g;
}

// Per-tet values from a function of the tet's cell.
std::vector<std::int32_t> per_cell(const Grid& g, const std::function<int(const Cell&)>& f) {
  std::vector<std::int32_t> out;
  for (const Cell& c : g.cell_of_tet) out.push_back(f(c));
  return out;
}

std::vector<std::int32_t> zeros_like(const TetMesh& mesh) {
  return std::vector<std::int32_t>(mesh.tets.size(), 0);
}
std::vector<std::int32_t> zeros(const Grid& g) { return zeros_like(g.mesh); }

// Undirected edge -> (uses a -> b with a < b, uses b -> a).
std::map<std::pair<int, int>, std::pair<int, int>> edge_uses(const TriMesh& mesh) {
  std::map<std::pair<int, int>, std::pair<int, int>> uses;
  for (const Tri& t : mesh.triangles)
    for (int c = 0; c < 3; ++c) {
      const int a = t[c], b = t[(c + 1) % 3];
      auto& u = uses[{std::min(a, b), std::max(a, b)}];
      (a < b ? u.first : u.second)++;
    }
  return uses;
}

// Every edge has exactly two faces, one in each direction, and the faces around every vertex
// form a single fan; no degenerate triangles; every vertex used.
void expect_closed_manifold(const TriMesh& mesh) {
  for (const auto& [edge, use] : edge_uses(mesh)) {
    EXPECT_EQ(use.first, 1) << "edge " << edge.first << "-" << edge.second;
    EXPECT_EQ(use.second, 1) << "edge " << edge.first << "-" << edge.second;
  }
  // Around vertex v, face (v, a, b) links a to b; one fan means one cycle through all of them.
  std::vector<std::map<int, int>> next(mesh.vertices.size());
  std::vector<int> faces_at(mesh.vertices.size(), 0);
  for (const Tri& t : mesh.triangles) {
    EXPECT_TRUE(t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
    for (int c = 0; c < 3; ++c) {
      next[t[c]][t[(c + 1) % 3]] = t[(c + 2) % 3];
      ++faces_at[t[c]];
    }
  }
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    ASSERT_GT(faces_at[v], 0) << "unused vertex " << v;
    ASSERT_EQ(static_cast<int>(next[v].size()), faces_at[v]) << "vertex " << v;
    int steps = 0;
    const int first = next[v].begin()->first;
    int a = first;
    do {
      const auto it = next[v].find(a);
      ASSERT_NE(it, next[v].end()) << "open fan at vertex " << v;
      a = it->second;
      ++steps;
    } while (a != first && steps <= faces_at[v]);
    EXPECT_EQ(steps, faces_at[v]) << "vertex " << v << " has several fans";
  }
}

double sum_tet_volumes(const TetMesh& mesh, const std::vector<std::int32_t>& tets) {
  double v = 0;
  for (const std::int32_t t : tets) v += tet_volume(mesh, t);
  return v;
}

int euler_characteristic(const TriMesh& mesh) {
  return static_cast<int>(mesh.vertices.size()) - static_cast<int>(edge_uses(mesh).size()) +
         static_cast<int>(mesh.triangles.size());
}

// Every tet in exactly one part, tets ascending, volumes and meshes consistent.
void expect_valid_parts(const Grid& g, const std::vector<Part>& parts) {
  std::vector<int> owner(g.mesh.tets.size(), -1);
  double total = 0;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    SCOPED_TRACE("part " + std::to_string(p));
    const Part& part = parts[p];
    EXPECT_EQ(part.id, static_cast<std::int32_t>(p));
    EXPECT_TRUE(std::is_sorted(part.tets.begin(), part.tets.end()));
    for (const std::int32_t t : part.tets) {
      EXPECT_EQ(owner[t], -1);
      owner[t] = static_cast<int>(p);
    }
    EXPECT_NEAR(part.volume_mm3, sum_tet_volumes(g.mesh, part.tets), 1e-9);
    EXPECT_NEAR(signed_volume(part.mesh), part.volume_mm3, 1e-6 * part.volume_mm3);
    EXPECT_NEAR(part.direction.norm(), 1.0, 1e-12);
    expect_closed_manifold(part.mesh);
    if (p > 0) {
      EXPECT_TRUE(parts[p - 1].volume_mm3 > part.volume_mm3 + 1e-9 ||
                  (std::abs(parts[p - 1].volume_mm3 - part.volume_mm3) < 1e-9 &&
                   parts[p - 1].tets.front() < part.tets.front()));
    }
    total += part.volume_mm3;
  }
  EXPECT_EQ(std::count(owner.begin(), owner.end(), -1), 0);
  EXPECT_NEAR(total, total_volume(g.mesh), 1e-6 * total_volume(g.mesh));
}

const Vec3 kX = Vec3::UnitX(), kY = Vec3::UnitY(), kZ = Vec3::UnitZ();

TEST(ExtractParts, TwoHalvesOfABoxAreTwoClosedOutwardParts) {
  const Grid g = make_grid(4, 2, 2, 10.0);
  const auto label = per_cell(g, [](const Cell& c) { return c[0] < 2 ? 0 : 1; });
  const auto parts = extract_parts(g.mesh, label, zeros(g), {-kX, 3.0 * kX});
  ASSERT_EQ(parts.size(), 2u);
  expect_valid_parts(g, parts);
  // Equal volumes: the part holding tet 0 (label 0, x < 20) comes first.
  EXPECT_EQ(parts[0].tets.front(), 0);
  EXPECT_EQ(parts[0].direction_index, 0);
  EXPECT_EQ(parts[1].direction_index, 1);
  EXPECT_EQ(parts[0].direction, -kX);
  EXPECT_EQ(parts[1].direction, kX);  // normalized
  for (const Part& p : parts) {
    EXPECT_NEAR(p.volume_mm3, 8000.0, 1e-9);
    EXPECT_EQ(p.mesh.vertices.size(), 26u);  // 27 grid points less the centre
    EXPECT_EQ(euler_characteristic(p.mesh), 2);
  }
}

// A part under 0.1 % of the model's volume is named, one just over it is not.
TEST(TinyParts, PartsUnderATenthOfAPercentOfTheVolumeAreNamed) {
  std::vector<Part> parts(4);
  const double volumes_mm3[] = {5000.0, 4.9, 5.1, 1.0};
  for (std::int32_t i = 0; i < 4; ++i) parts[i].id = 10 + i, parts[i].volume_mm3 = volumes_mm3[i];
  EXPECT_EQ(tiny_parts(parts, 5000.0), (std::vector<std::int32_t>{11, 13}));
  EXPECT_TRUE(tiny_parts(parts, 900.0).empty());
}

TEST(ExtractParts, LargerPartComesFirst) {
  const Grid g = make_grid(3, 1, 1, 5.0);
  const auto label = per_cell(g, [](const Cell& c) { return c[0] == 0 ? 0 : 1; });
  const auto parts = extract_parts(g.mesh, label, zeros(g), {kZ, kZ});
  ASSERT_EQ(parts.size(), 2u);
  expect_valid_parts(g, parts);
  EXPECT_EQ(parts[0].direction_index, 1);
  EXPECT_NEAR(parts[0].volume_mm3, 250.0, 1e-9);
  EXPECT_NEAR(parts[1].volume_mm3, 125.0, 1e-9);
}

int count_vertices_at(const TriMesh& mesh, const Vec3& p) {
  return static_cast<int>(std::count(mesh.vertices.begin(), mesh.vertices.end(), p));
}

TEST(ExtractParts, PartTouchingItselfAlongAnEdgeIsManifold) {
  // In the x-z plane (z up), one cell thick in y; cells (1,1) and (2,2) of part P touch along
  // the edge x = z = 2 only, and P joins them around the left and the top:
  //   P P P 2
  //   P 1 P 2
  //   P P 1 2
  //   2 2 2 2
  const Grid g = make_grid(4, 1, 4, 1.0);
  const auto label = per_cell(g, [](const Cell& c) {
    const int x = c[0], z = c[2];
    if ((x == 2 && z == 1) || (x == 1 && z == 2)) return 1;
    return (x == 3 || z == 0) ? 2 : 0;
  });
  const auto parts = extract_parts(g.mesh, label, zeros(g), {kZ, kZ, kZ});
  ASSERT_EQ(parts.size(), 4u);  // label 1 is two cubes that share an edge only
  expect_valid_parts(g, parts);
  const Part& ring = parts[1];
  ASSERT_EQ(ring.direction_index, 0);
  // The edge's end vertices are on the outside: two fans each, one per cube.
  EXPECT_EQ(count_vertices_at(ring.mesh, Vec3(2, 0, 2)), 2);
  EXPECT_EQ(count_vertices_at(ring.mesh, Vec3(2, 1, 2)), 2);
  // Cut apart along the edge, the loop is a bent bar: a sphere.
  EXPECT_EQ(euler_characteristic(ring.mesh), 2);
  for (const Part& p : {parts[2], parts[3]}) {
    EXPECT_EQ(p.mesh.vertices.size(), 8u);
    EXPECT_EQ(p.mesh.triangles.size(), 12u);
  }
}

TEST(ExtractParts, PartTouchingItselfAtAVertexIsManifold) {
  // Two opposite corner cubes of a 2x2x2 block touch at its centre only (two parts); the other
  // six cubes form a ring whose surface pinches at the centre.
  const Grid g = make_grid(2, 2, 2, 1.0);
  const auto label =
      per_cell(g, [](const Cell& c) { return (c[0] == c[1] && c[1] == c[2]) ? 0 : 1; });
  const auto parts = extract_parts(g.mesh, label, zeros(g), {kZ, kZ});
  ASSERT_EQ(parts.size(), 3u);
  expect_valid_parts(g, parts);
  ASSERT_EQ(parts[0].direction_index, 1);
  EXPECT_EQ(parts[1].mesh.vertices.size(), 8u);
  EXPECT_EQ(parts[2].mesh.vertices.size(), 8u);
  // The ring of six cubes, pinched apart at the centre, is bounded by a sphere.
  EXPECT_EQ(count_vertices_at(parts[0].mesh, Vec3(1, 1, 1)), 2);
  EXPECT_EQ(euler_characteristic(parts[0].mesh), 2);
}

TEST(ExtractParts, PartPinchedAlongAnEdgeBetweenConnectedEndsIsManifold) {
  // A 2x2x3 block whose middle layer lost two diagonal cubes: the two remaining middle cubes
  // share only the centre edge, and both its end vertices are single fans (the slabs join
  // them). The part is a solid torus whose surface runs twice along that edge.
  const Grid g = make_grid(2, 2, 3, 1.0);
  const auto label = per_cell(g, [](const Cell& c) { return (c[2] == 1 && c[0] != c[1]) ? 1 : 0; });
  const auto parts = extract_parts(g.mesh, label, zeros(g), {kZ, kZ});
  ASSERT_EQ(parts.size(), 3u);  // the two removed cubes share an edge only
  expect_valid_parts(g, parts);
  const TriMesh& mesh = parts[0].mesh;
  EXPECT_EQ(parts[0].direction_index, 0);
  EXPECT_EQ(count_vertices_at(mesh, Vec3(1, 1, 1)), 1);
  EXPECT_EQ(count_vertices_at(mesh, Vec3(1, 1, 2)), 1);
  // One of the two face pairs along the edge gets its own midpoint.
  EXPECT_EQ(count_vertices_at(mesh, Vec3(1, 1, 1.5)), 1);
  EXPECT_EQ(mesh.vertices.size(), 37u);
  EXPECT_EQ(euler_characteristic(mesh), 0);
}

TEST(ExtractParts, SameLabelApartGivesTwoParts) {
  const Grid g = make_grid(3, 1, 1, 2.0);
  const auto label = per_cell(g, [](const Cell& c) { return c[0] == 1 ? 1 : 0; });
  const auto parts = extract_parts(g.mesh, label, zeros(g), {kZ, -kZ});
  ASSERT_EQ(parts.size(), 3u);
  expect_valid_parts(g, parts);
  // Equal volumes: ordered by smallest tet, i.e. by cell x.
  EXPECT_EQ(parts[0].tets.front(), 0);
  EXPECT_EQ(parts[1].tets.front(), 6);
  EXPECT_EQ(parts[2].tets.front(), 12);
  EXPECT_EQ(parts[0].direction_index, 0);
  EXPECT_EQ(parts[1].direction_index, 1);
  EXPECT_EQ(parts[2].direction_index, 0);
}

TEST(ExtractParts, RegionSeparatesEqualLabels) {
  const Grid g = make_grid(2, 1, 1, 2.0);
  const auto region = per_cell(g, [](const Cell& c) { return c[0]; });
  const auto parts = extract_parts(g.mesh, zeros(g), region, {kZ});
  ASSERT_EQ(parts.size(), 2u);
  expect_valid_parts(g, parts);
  EXPECT_EQ(parts[0].region, 0);
  EXPECT_EQ(parts[1].region, 1);
  EXPECT_EQ(parts[1].direction, kZ);
  EXPECT_EQ(parts[1].direction_index, 0);
}

TEST(ExtractParts, MissingDirectionThrows) {
  const Grid g = make_grid(1, 1, 1, 1.0);
  EXPECT_THROW(extract_parts(g.mesh, zeros(g), zeros(g), {}), Error);
}

// Pseudo-random labels per tet: parts touch themselves and each other along edges and at
// vertices everywhere.
std::vector<std::int32_t> scrambled_labels(std::size_t n, int num_labels, std::uint32_t seed) {
  std::vector<std::int32_t> label(n);
  std::uint32_t s = seed;
  for (auto& l : label) {
    s = s * 1664525u + 1013904223u;
    l = static_cast<std::int32_t>((s >> 16) % static_cast<std::uint32_t>(num_labels));
  }
  return label;
}

TEST(ExtractParts, ScrambledLabelsGiveClosedManifoldParts) {
  const Grid g = make_grid(6, 6, 6, 3.0);
  const auto label = scrambled_labels(g.mesh.tets.size(), 3, 7);
  const auto parts = extract_parts(g.mesh, label, zeros(g), {kZ, kX, -kY});
  EXPECT_GT(parts.size(), 10u);
  expect_valid_parts(g, parts);
  // Same result on one thread.
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const auto again = extract_parts(g.mesh, label, zeros(g), {kZ, kX, -kY});
  ASSERT_EQ(again.size(), parts.size());
  for (std::size_t p = 0; p < parts.size(); ++p) {
    EXPECT_EQ(again[p].tets, parts[p].tets);
    EXPECT_EQ(again[p].mesh.triangles, parts[p].mesh.triangles);
    EXPECT_EQ(again[p].mesh.vertices, parts[p].mesh.vertices);
  }
}

// --- sandwiched tets ---

// Slightly oblique directions, so that lines through tet barycentres never run along the grid's
// faces: the repair must not depend on lucky alignments.
const Vec3 kUp = Vec3(0.03, 0.02, 1.0).normalized();
const Vec3 kSide = Vec3(1.0, 0.04, 0.03).normalized();
const auto kAllowAll = [](std::int32_t, std::int32_t, std::int32_t) { return true; };

// A 6x6x6 box whose part 0 (direction up) is wrapped around a tongue of part 1 (direction
// sideways) that comes in from the -x side at mid height: lines along up through the tongue
// meet part 0 below it and above it.
int tongue(const Cell& c) { return c[2] >= 2 && c[2] <= 3 && c[0] <= 3 && c[1] >= 1 && c[1] <= 4; }

TEST(AbsorbSandwichedTets, TongueInsideAnotherPartsColumnJoinsIt) {
  const Grid g = make_grid(6, 6, 6, 10.0, 0.05);
  auto label = per_cell(g, tongue);
  const std::int32_t tongue_tets =
      static_cast<std::int32_t>(std::count(label.begin(), label.end(), 1));
  ASSERT_EQ(tongue_tets, 6 * 4 * 4 * 2);
  // Before: part 0 is not a double height field along its direction.
  const SandwichRepair repair =
      absorb_sandwiched_tets(g.mesh, label, zeros(g), {kUp, kSide}, kAllowAll);
  EXPECT_TRUE(repair.converged);
  EXPECT_EQ(repair.order, "largest first");
  EXPECT_EQ(repair.moved_tets, tongue_tets);
  EXPECT_EQ(repair.stuck_tets, 0);
  EXPECT_EQ(repair.worst_share, 0.0);
  EXPECT_EQ(repair.parts, 1);  // the tongue's part is gone
  EXPECT_EQ(repair.rounds, 1);
  EXPECT_EQ(std::count(label.begin(), label.end(), 1), 0);
  ASSERT_EQ(repair.moves.size(), 1u);
  EXPECT_EQ(repair.moves[0].from_label, 1);
  EXPECT_EQ(repair.moves[0].to_label, 0);
  EXPECT_EQ(repair.moves[0].tets, tongue_tets);
  EXPECT_NEAR(repair.moves[0].volume_mm3,
              sum_tet_volumes(g.mesh,
                              [&] {
                                std::vector<std::int32_t> ts;
                                const auto before = per_cell(g, tongue);
                                for (std::int32_t t = 0;
                                     t < static_cast<std::int32_t>(before.size()); ++t)
                                  if (before[t] == 1) ts.push_back(t);
                                return ts;
                              }()),
              1e-6);
  EXPECT_NEAR(repair.moved_volume_mm3, repair.moves[0].volume_mm3, 1e-9);
}

TEST(AbsorbSandwichedTets, LayerThatSplitsAPartInTwoStays) {
  // Across the whole box the middle layers cut part 0 into a top and a bottom part: each is a
  // double height field, so nothing is sandwiched.
  const Grid g = make_grid(6, 6, 6, 10.0, 0.05);
  auto label = per_cell(g, [](const Cell& c) { return c[2] >= 2 && c[2] <= 3; });
  const auto before = label;
  const SandwichRepair repair =
      absorb_sandwiched_tets(g.mesh, label, zeros(g), {kUp, kSide}, kAllowAll);
  EXPECT_TRUE(repair.converged);
  EXPECT_EQ(repair.parts, 3);  // bottom, layers, top
  EXPECT_EQ(repair.moved_tets, 0);
  EXPECT_EQ(repair.rounds, 0);
  EXPECT_TRUE(repair.moves.empty());
  EXPECT_EQ(label, before);
}

TEST(AbsorbSandwichedTets, TetsTheDirectionDoesNotAllowStayAndAreCounted) {
  const Grid g = make_grid(6, 6, 6, 10.0, 0.05);
  auto label = per_cell(g, tongue);
  const auto before = label;
  const SandwichRepair repair = absorb_sandwiched_tets(
      g.mesh, label, zeros(g), {kUp, kSide},
      [&](std::int32_t t, std::int32_t, std::int32_t l) { return before[t] == l; });
  EXPECT_FALSE(repair.converged);
  EXPECT_EQ(repair.order, "segmentation");
  EXPECT_EQ(repair.moved_tets, 0);
  EXPECT_EQ(repair.stuck_tets, 6 * 4 * 4 * 2);
  // The whole tongue lies within part 0: its share of part 0's volume (cells of nearly equal
  // volume, 32 of the 184 cells that are part 0's).
  EXPECT_NEAR(repair.worst_share, 32.0 / 184.0, 0.01);
  EXPECT_EQ(repair.parts, 2);
  EXPECT_EQ(label, before);
}

TEST(AbsorbSandwichedTets, OtherRegionsAndNoRoundsLeaveLabelsAlone) {
  const Grid g = make_grid(6, 6, 6, 10.0, 0.05);
  auto label = per_cell(g, tongue);
  const auto before = label;
  // The tongue is a region of its own: regions never exchange tets.
  const auto region = per_cell(g, tongue);
  SandwichRepair repair = absorb_sandwiched_tets(g.mesh, label, region, {kUp, kSide}, kAllowAll);
  EXPECT_EQ(repair.moved_tets, 0);
  EXPECT_EQ(label, before);
  // max_rounds = 0 only counts.
  SandwichOptions count_only;
  count_only.max_rounds = 0;
  repair = absorb_sandwiched_tets(g.mesh, label, zeros(g), {kUp, kSide}, kAllowAll, count_only);
  EXPECT_FALSE(repair.converged);
  EXPECT_EQ(repair.moved_tets, 0);
  EXPECT_EQ(repair.stuck_tets, 6 * 4 * 4 * 2);
  EXPECT_EQ(label, before);
  count_only.max_rounds = -1;
  EXPECT_THROW(absorb_sandwiched_tets(g.mesh, label, zeros(g), {kUp, kSide}, kAllowAll, count_only),
               Error);
}

// Every part left by the repair meets each line along its direction through a tet barycentre in
// one run of tets (counted by walking the grid's cells, independently of the repair's walk).
TEST(AbsorbSandwichedTets, ScrambledLabelsEndWithoutSandwichesOnAnyThreadCount) {
  const Grid g = make_grid(8, 8, 8, 5.0);
  // Blocks of 2x2x2 cells with pseudo-random labels: many nested sandwiches.
  const auto blocks = scrambled_labels(64, 3, 11);
  const auto block_label = [&](const Cell& c) {
    return blocks[((c[2] / 2) * 4 + c[1] / 2) * 4 + c[0] / 2];
  };
  auto label = per_cell(g, block_label);
  const std::vector<Vec3> dirs{kUp, kSide, Vec3(0.02, -1.0, 0.05).normalized()};
  const auto start = label;
  const SandwichRepair repair = absorb_sandwiched_tets(g.mesh, label, zeros(g), dirs, kAllowAll);
  EXPECT_GT(repair.moved_tets, 0);
  EXPECT_TRUE(repair.converged);
  EXPECT_EQ(repair.stuck_tets, 0);

  // Independent check on the parts: along each part's (nearly axial) direction, a column of
  // cells through the part must not leave it and come back.
  const auto parts = extract_parts(g.mesh, label, zeros(g), dirs);
  std::map<Cell, std::set<int>> parts_in_cell;
  for (const Part& p : parts)
    for (std::int32_t t : p.tets) parts_in_cell[g.cell_of_tet[t]].insert(p.id);
  int sandwiched_cells = 0;
  for (const Part& p : parts) {
    const int axis = p.direction_index == 0 ? 2 : (p.direction_index == 1 ? 0 : 1);
    for (int a = 0; a < 8; ++a)
      for (int b = 0; b < 8; ++b) {
        // The column's cells in order; is p in some, then not, then again?
        int state = 0;  // 0 before p, 1 in p, 2 left p
        for (int k = 0; k < 8; ++k) {
          Cell c{};
          c[axis] = k;
          c[(axis + 1) % 3] = a;
          c[(axis + 2) % 3] = b;
          // Whole cells only: cells shared with another part are mixed at the tet level.
          const auto& in = parts_in_cell[c];
          const bool only_p = in.size() == 1 && *in.begin() == p.id;
          const bool without_p = !in.count(p.id);
          if (only_p && state == 0) state = 1;
          if (without_p && state == 1) state = 2;
          if (only_p && state == 2) {
            ++sandwiched_cells;
            state = 1;
          }
        }
      }
  }
  EXPECT_EQ(sandwiched_cells, 0);

  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  auto again = start;
  const SandwichRepair repair_one =
      absorb_sandwiched_tets(g.mesh, again, zeros(g), dirs, kAllowAll);
  EXPECT_EQ(again, label);
  EXPECT_EQ(repair_one.moved_tets, repair.moved_tets);
}

// Scrambled blocks where each block allows its own label and a pseudo-random choice of the others:
// settling the parts one at a time leaves tets between two tets of a part, of a settled part
// whose column goes on beyond them, and only moving them with that column's shorter tail clears
// them.
TEST(AbsorbSandwichedTets, TetsLeftBetweenAPartsTetsGoToItWithTheirColumnsTail) {
  const Grid g = make_grid(8, 8, 8, 5.0);
  const std::vector<Vec3> dirs{kUp, kSide, Vec3(0.02, -1.0, 0.05).normalized()};
  const auto blocks = scrambled_labels(64, 3, 33);
  const auto extra = scrambled_labels(64 * 3, 3, 1033);
  const auto block_of =
      per_cell(g, [](const Cell& c) { return ((c[2] / 2) * 4 + c[1] / 2) * 4 + c[0] / 2; });
  const TetAllowsLabel allows = [&](std::int32_t t, std::int32_t, std::int32_t l) {
    const std::int32_t b = block_of[t];
    return blocks[b] == l || extra[3 * b + l] != 0;
  };
  std::vector<std::int32_t> label;
  for (std::int32_t b : block_of) label.push_back(blocks[b]);
  const auto start = label;
  const std::size_t parts_before = extract_parts(g.mesh, start, zeros(g), dirs).size();
  const SandwichRepair repair = absorb_sandwiched_tets(g.mesh, label, zeros(g), dirs, allows);
  EXPECT_TRUE(repair.converged);
  EXPECT_EQ(repair.stuck_tets, 0);
  EXPECT_EQ(repair.worst_share, 0.0);
  EXPECT_EQ(repair.forced_tets, 0);
  for (std::size_t t = 0; t < label.size(); ++t)
    EXPECT_TRUE(allows(static_cast<std::int32_t>(t), 0, label[t])) << "tet " << t;
  EXPECT_LE(extract_parts(g.mesh, label, zeros(g), dirs).size(), parts_before);

  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  auto again = start;
  absorb_sandwiched_tets(g.mesh, again, zeros(g), dirs, allows);
  EXPECT_EQ(again, label);
}

// --- parts that touch themselves ---

// Positions where some part's mesh has two vertices: where extract_parts() cut a part apart
// because it touches itself there.
std::vector<std::pair<std::int32_t, Vec3>> self_contacts(const std::vector<Part>& parts) {
  std::vector<std::pair<std::int32_t, Vec3>> out;
  for (const Part& p : parts) {
    std::set<std::array<double, 3>> at;
    for (const Vec3& x : p.mesh.vertices)
      if (!at.insert({x.x(), x.y(), x.z()}).second) out.emplace_back(p.id, x);
  }
  return out;
}

// Repairs `label` on the grid and checks the outcome: no part touches itself, none is added, and
// the parts are valid. Returns the repair.
ManifoldRepair expect_repaired(const Grid& g, std::vector<std::int32_t>& label,
                               const TetAllowsLabel& allows, std::size_t num_directions) {
  const std::vector<Vec3> dirs(num_directions, kZ);
  const std::size_t before = extract_parts(g.mesh, label, zeros(g), dirs).size();
  const ManifoldRepair repair = make_parts_manifold(g.mesh, label, zeros(g), allows);
  EXPECT_EQ(repair.nonmanifold_vertices, 0);
  const std::vector<Part> parts = extract_parts(g.mesh, label, zeros(g), dirs);
  EXPECT_LE(parts.size(), before);
  expect_valid_parts(g, parts);
  for (const auto& [part, x] : self_contacts(parts))
    ADD_FAILURE() << "part " << part << " touches itself at " << x.transpose();
  return repair;
}

TEST(MakePartsManifold, PartTouchingItselfAlongAnEdgeNoLongerDoes) {
  // The ring of ExtractParts.PartTouchingItselfAlongAnEdgeIsManifold: label 0 meets itself
  // along the edge x = z = 2, between the two cubes of label 1 that share that edge.
  const Grid g = make_grid(4, 1, 4, 1.0);
  auto label = per_cell(g, [](const Cell& c) {
    const int x = c[0], z = c[2];
    if ((x == 2 && z == 1) || (x == 1 && z == 2)) return 1;
    return (x == 3 || z == 0) ? 2 : 0;
  });
  ASSERT_FALSE(self_contacts(extract_parts(g.mesh, label, zeros(g), {kZ, kZ, kZ})).empty());
  // Where no direction allows a move, nothing moves, and the place is counted.
  auto stuck = label;
  const ManifoldRepair none = make_parts_manifold(
      g.mesh, stuck, zeros(g), [](std::int32_t, std::int32_t, std::int32_t) { return false; });
  EXPECT_EQ(stuck, label);
  EXPECT_EQ(none.moved_tets, 0);
  EXPECT_GT(none.nonmanifold_vertices, 0);
  const ManifoldRepair repair = expect_repaired(g, label, kAllowAll, 3);
  // One cube around the edge changes hands at most.
  EXPECT_GT(repair.moved_tets, 0);
  EXPECT_LE(repair.moved_tets, 6);
}

TEST(MakePartsManifold, PartTouchingItselfAtAVertexNoLongerDoesAndAllowedMovesWin) {
  // As in ExtractParts.PartTouchingItselfAtAVertexIsManifold, a ring of six cubes (label 1)
  // pinched at the block's centre, where two opposite corner cubes touch; here they have labels
  // 0 and 2.
  const Grid g = make_grid(2, 2, 2, 1.0);
  const auto start =
      per_cell(g, [](const Cell& c) { return (c[0] == c[1] && c[1] == c[2]) ? 2 * c[0] : 1; });
  ASSERT_FALSE(self_contacts(extract_parts(g.mesh, start, zeros(g), {kZ, kZ, kZ})).empty());
  // Tets of the ring join a corner through the ring (the fewest that do): whichever corner's
  // label the direction allows.
  for (const std::int32_t allowed : {0, 2}) {
    SCOPED_TRACE("allowed label " + std::to_string(allowed));
    auto label = start;
    const ManifoldRepair repair = expect_repaired(
        g, label, [&](std::int32_t, std::int32_t, std::int32_t l) { return l == allowed; }, 3);
    EXPECT_GT(repair.moved_tets, 0);
    EXPECT_LE(repair.moved_tets, 6);
    for (std::size_t t = 0; t < label.size(); ++t)
      EXPECT_TRUE(label[t] == start[t] || label[t] == allowed) << "tet " << t;
  }
}

TEST(MakePartsManifold, ScrambledCellsEndManifoldOnAnyThreadCount) {
  const Grid g = make_grid(6, 6, 6, 2.0);
  const auto cells = scrambled_labels(216, 3, 5);
  const auto start =
      per_cell(g, [&](const Cell& c) { return cells[(c[2] * 6 + c[1]) * 6 + c[0]]; });
  ASSERT_FALSE(self_contacts(extract_parts(g.mesh, start, zeros(g), {kZ, kZ, kZ})).empty());
  auto label = start;
  const ManifoldRepair repair = expect_repaired(g, label, kAllowAll, 3);
  EXPECT_GT(repair.moved_tets, 0);
  // Far fewer tets move than there are.
  EXPECT_LT(repair.moved_tets, static_cast<std::int32_t>(label.size()) / 5);
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  auto again = start;
  make_parts_manifold(g.mesh, again, zeros(g), kAllowAll);
  EXPECT_EQ(again, label);
}

// A real tet mesh (CGAL's elephant) labeled by 3D blocks with pseudo-random labels: blocks of
// one label meet along edges and at vertices all over the solid, at the mesher's irregular tets.
TEST(MakePartsManifold, BlocksOfTheElephantGiveManifoldParts) {
  const std::string path = test::cgal_mesh("elephant.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set absent (install libcgal-demo)";
  TetOptions topts;
  topts.target_tets = 12000;
  const TetMesh tets = tetrahedralize(test::load_scaled(path, 150.0), topts);
  const Box3 box = bounding_box(tets.vertices);
  const auto blocks = scrambled_labels(64 * 64 * 64, 3, 17);
  std::vector<std::int32_t> label(tets.tets.size());
  for (std::size_t t = 0; t < tets.tets.size(); ++t) {
    Vec3 c = Vec3::Zero();
    for (std::int32_t v : tets.tets[t]) c += 0.25 * tets.vertices[v];
    const Eigen::Vector3i b = ((c - box.min) / 15.0).cast<int>();
    label[t] = blocks[(b.z() * 64 + b.y()) * 64 + b.x()];
  }
  const std::vector<std::int32_t> region(label.size(), 0);
  const std::vector<Vec3> dirs{kX, kY, kZ};
  const std::vector<Part> raw = extract_parts(tets, label, region, dirs);
  ASSERT_FALSE(self_contacts(raw).empty());
  const ManifoldRepair repair = make_parts_manifold(tets, label, region, kAllowAll);
  EXPECT_EQ(repair.nonmanifold_vertices, 0);
  EXPECT_LT(repair.moved_tets, static_cast<std::int32_t>(label.size()) / 20);
  const std::vector<Part> parts = extract_parts(tets, label, region, dirs);
  EXPECT_LE(parts.size(), raw.size());
  for (const auto& [part, x] : self_contacts(parts))
    ADD_FAILURE() << "part " << part << " touches itself at " << x.transpose();
  for (const Part& p : parts) EXPECT_EQ(test::solid_topology_problem(p.mesh), "") << p.id;
}

// --- assembly ---

// Parts of a grid labeled per cell, with one direction per label.
std::vector<Part> grid_parts(const Grid& g, const std::function<int(const Cell&)>& label,
                             const std::vector<Vec3>& directions) {
  return extract_parts(g.mesh, per_cell(g, label), zeros(g), directions);
}

// The part owning each cell of the grid.
std::map<Cell, int> cell_owner(const Grid& g, const std::vector<Part>& parts) {
  std::map<Cell, int> owner;
  for (const Part& p : parts)
    for (const std::int32_t t : p.tets) owner[g.cell_of_tet[t]] = p.id;
  return owner;
}

// Exact blocking for axis directions on a per-cell labeling: B is blocked by A iff some cell of
// A lies further along d_B in the same row of cells as a cell of B (gaps do not matter).
std::vector<std::vector<std::int32_t>> blocks_by_cells(const Grid& g,
                                                       const std::vector<Part>& parts) {
  const auto owner = cell_owner(g, parts);
  std::vector<std::set<std::int32_t>> blocks(parts.size());
  for (const auto& [cell, b] : owner) {
    const Vec3& d = parts[b].direction;
    for (int axis = 0; axis < 3; ++axis) {
      const int step = d[axis] > 0.5 ? 1 : (d[axis] < -0.5 ? -1 : 0);
      if (step == 0) continue;
      for (Cell c = cell; c[axis] >= 0 && c[axis] < g.n[axis]; c[axis] += step) {
        const auto it = owner.find(c);  // cells outside the solid have no owner
        if (it != owner.end() && it->second != b) blocks[b].insert(it->second);
      }
    }
  }
  std::vector<std::vector<std::int32_t>> out;
  for (const auto& s : blocks) out.emplace_back(s.begin(), s.end());
  return out;
}

// The same parts leaving the other way: their blocking along -d.
std::vector<Part> flipped(std::vector<Part> parts) {
  for (Part& p : parts) p.direction = -p.direction;
  return parts;
}

// Which parts leave along -d rather than +d.
std::vector<bool> reversed_parts(const AssemblyPlan& plan, const std::vector<Part>& parts) {
  std::vector<bool> out;
  for (const Part& p : parts) out.push_back(plan.removal.at(p.id) == -p.direction);
  return out;
}

// The plan agrees with the blocking both ways (forward along +d, backward along -d): disassembly
// takes out the smallest-id part that no remaining part blocks along +d, else along -d; blocks
// holds the list along the way each part leaves; order is the disassembly reversed, then the
// parts left blocked by ascending id.
void expect_plan_follows(const AssemblyPlan& plan, const std::vector<Part>& parts,
                         const std::vector<std::vector<std::int32_t>>& forward,
                         const std::vector<std::vector<std::int32_t>>& backward) {
  const std::size_t n = forward.size();
  std::vector<bool> remaining(n, true), reversed(n, false);
  auto free_of = [&](const std::vector<std::int32_t>& blockers) {
    return std::none_of(blockers.begin(), blockers.end(),
                        [&](std::int32_t q) { return remaining[q]; });
  };
  std::vector<std::int32_t> removed;
  for (std::size_t p = 0; p < n;) {
    if (remaining[p] && (free_of(forward[p]) || free_of(backward[p]))) {
      reversed[p] = !free_of(forward[p]);
      remaining[p] = false;
      removed.push_back(static_cast<std::int32_t>(p));
      p = 0;
    } else {
      ++p;
    }
  }
  std::vector<std::int32_t> order(removed.rbegin(), removed.rend());
  for (std::size_t p = 0; p < n; ++p)
    if (remaining[p]) order.push_back(static_cast<std::int32_t>(p));
  std::vector<std::vector<std::int32_t>> blocks;
  for (std::size_t p = 0; p < n; ++p) blocks.push_back(reversed[p] ? backward[p] : forward[p]);
  EXPECT_EQ(plan.found, removed.size() == n);
  EXPECT_EQ(reversed_parts(plan, parts), reversed);
  EXPECT_EQ(plan.blocks, blocks);
  EXPECT_EQ(plan.order, order);
}

// No part collides with the parts placed before it.
void expect_collision_free(const AssemblyPlan& plan, std::size_t num_parts) {
  std::vector<std::int32_t> sorted = plan.order;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::int32_t> all(num_parts);
  std::iota(all.begin(), all.end(), 0);
  EXPECT_EQ(sorted, all);
  std::set<std::int32_t> placed;
  for (const std::int32_t p : plan.order) {
    for (const std::int32_t q : plan.blocks[p]) EXPECT_FALSE(placed.count(q)) << p << " hits " << q;
    placed.insert(p);
  }
}

using Blocks = std::vector<std::vector<std::int32_t>>;
using Flags = std::vector<bool>;

constexpr double kTolerance_mm = 0.5;  // depth; the cells are 2.5 to 10 mm

TEST(PlanAssembly, BlockedBottomOfAStackLeavesDownwards) {
  // Both leave up: the top is in the bottom's way, so the bottom (part 0, smallest id) leaves
  // down instead, before the top; assembly is the reverse.
  const Grid g = make_grid(2, 2, 2, 10.0);
  const auto parts = grid_parts(g, [](const Cell& c) { return c[2]; }, {kZ, kZ});
  ASSERT_EQ(parts.size(), 2u);
  ASSERT_EQ(parts[0].direction_index, 0);  // the bottom holds tet 0
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{true, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{1, 0}));
  EXPECT_TRUE(plan.message.empty());
}

TEST(PlanAssembly, PartsLeavingAwayFromEachOtherAreFree) {
  // Bottom leaves down, top leaves up: nothing blocks; disassembly takes part 0 first.
  const Grid g = make_grid(2, 2, 2, 10.0);
  const auto parts = grid_parts(g, [](const Cell& c) { return c[2]; }, {-kZ, kZ});
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{false, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{1, 0}));
}

TEST(PlanAssembly, PartsLeavingTowardsEachOtherLeaveOneWayReversed) {
  // Bottom up, top down: each blocks the other. Reversed, the bottom leaves down first; then the
  // top is free to leave down through the room the bottom left.
  const Grid g = make_grid(2, 2, 2, 10.0);
  const auto parts = grid_parts(g, [](const Cell& c) { return c[2]; }, {kZ, -kZ});
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{true, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {0}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{1, 0}));
  EXPECT_TRUE(plan.message.empty());
}

TEST(PlanAssembly, PartsSlidingAlongTheirInterfaceDoNotBlock) {
  const Grid g = make_grid(2, 2, 2, 10.0);
  const auto parts = grid_parts(g, [](const Cell& c) { return c[0]; }, {kZ, kZ});
  const AssemblyPlan plan = plan_assembly(parts, {}, 0.0);
  EXPECT_TRUE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{false, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{1, 0}));
}

TEST(PlanAssembly, LeavingObliquelyIntoANeighbourIsBlocked) {
  // Side by side; the left column tilts towards the wider right part, which leaves straight up.
  // The right part (0, the larger) leaves first, then the left one along +d: blocks[1] still
  // names the part its way runs through.
  const Grid g = make_grid(3, 2, 2, 10.0);
  const auto parts =
      grid_parts(g, [](const Cell& c) { return c[0] == 0 ? 0 : 1; }, {Vec3(0.3, 0, 1), kZ});
  ASSERT_EQ(parts.size(), 2u);
  ASSERT_EQ(parts[0].direction, kZ);
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{false, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {0}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{1, 0}));
}

TEST(PlanAssembly, InterlockingLsComeApartWhenOneLeavesBackwards) {
  // In the x-z plane (z up):   B B A C
  //                            B A A C
  // A leaves along +z (B is above its left cell), B along +x (A is right of both its rows),
  // C along +z, free. Parts: B (holds tet 0) = 0, A = 1, C = 2. Along -x nothing is left of B:
  // B leaves that way first, then A and C are free.
  const Grid g = make_grid(4, 1, 2, 10.0);
  const auto parts = grid_parts(g,
                                [](const Cell& c) {
                                  if (c[0] == 3) return 2;
                                  const bool a =
                                      (c[2] == 0 && c[0] >= 1) || (c[2] == 1 && c[0] == 2);
                                  return a ? 0 : 1;
                                },
                                {kZ, kX, kZ});
  ASSERT_EQ(parts.size(), 3u);
  ASSERT_EQ(parts[0].direction, kX);
  ASSERT_EQ(parts[1].direction, kZ);
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{true, false, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {0}, {}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{2, 1, 0}));
  EXPECT_TRUE(plan.message.empty());
}

TEST(PlanAssembly, EnclosedCubeReportsACycleAndTheRestIsOrdered) {
  // In the x-z plane (z up):   B B B C
  //                            B A B C
  //                            B B B C
  // A leaves along z: B is above and below it. B leaves along x: A is right of its left cell and
  // left of its right cell. C, along z, is free. Parts: B = 0, C = 1, A = 2.
  const Grid g = make_grid(4, 1, 3, 10.0);
  const auto parts = grid_parts(g,
                                [](const Cell& c) {
                                  if (c[0] == 3) return 2;
                                  return c[0] == 1 && c[2] == 1 ? 0 : 1;
                                },
                                {kZ, kX, kZ});
  ASSERT_EQ(parts.size(), 3u);
  ASSERT_EQ(parts[0].direction, kX);
  ASSERT_EQ(parts[1].direction_index, 2);
  ASSERT_EQ(parts[2].direction_index, 0);
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_FALSE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{false, false, false}));
  // B along +x runs into A and C.
  EXPECT_EQ(plan.blocks, (Blocks{{1, 2}, {}, {0}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{1, 0, 2}));
  EXPECT_EQ(plan.message, "no assembly order: part 0 blocks part 2, part 2 blocks part 0");
}

TEST(PlanAssembly, ThreePartCycleIsNamed) {
  // In the x-z plane (z up):   U L K U
  //                            U L L U
  //                            U U U U
  // A cup U holding an L and a cube K. U leaves along x (L and K are in its rows both ways), L
  // along z (K above, U below), K along x (U on its right, L and U on its left). Parts: U = 0,
  // L = 1, K = 2; along +d U is blocked by L first, L by K, K by U.
  const Grid g = make_grid(4, 1, 3, 10.0);
  const auto parts = grid_parts(g,
                                [](const Cell& c) {
                                  const int x = c[0], z = c[2];
                                  if (x == 2 && z == 2) return 2;
                                  return (z >= 1 && x >= 1 && x <= 2) ? 1 : 0;
                                },
                                {kX, kZ, kX});
  ASSERT_EQ(parts.size(), 3u);
  ASSERT_EQ(parts[0].direction_index, 0);
  ASSERT_EQ(parts[1].direction_index, 1);
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_FALSE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{false, false, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{1, 2}, {2}, {0}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{0, 1, 2}));
  EXPECT_EQ(plan.message,
            "no assembly order: part 0 blocks part 2, part 2 blocks part 1, part 1 blocks part 0");
}

TEST(PlanAssembly, ColumnWithOpposedDirectionsComesApartReversed) {
  // A column of three cubes: the lower two leave up, the top one down through both. The bottom
  // leaves down first, then the middle one down through the room it left (running into part 0's
  // former place), then the top.
  const Grid g = make_grid(1, 1, 3, 10.0);
  const auto parts = grid_parts(g, [](const Cell& c) { return c[2]; }, {kZ, kZ, -kZ});
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{true, true, false}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {0}, {0, 1}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{2, 1, 0}));
  expect_collision_free(plan, parts.size());
}

TEST(PlanAssembly, BlockingMatchesCellRowsOnScrambledParts) {
  // Random per-cell labels with axis directions: the blocking relation is known exactly.
  const Grid g = make_grid(6, 5, 4, 4.0);
  const auto cell_label = scrambled_labels(6 * 5 * 4, 4, 11);
  const auto parts =
      grid_parts(g, [&](const Cell& c) { return cell_label[(c[2] * 5 + c[1]) * 6 + c[0]]; },
                 {kZ, -kX, kY, -kZ});
  ASSERT_GT(parts.size(), 5u);
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  expect_plan_follows(plan, parts, blocks_by_cells(g, parts), blocks_by_cells(g, flipped(parts)));
  EXPECT_GT(std::ranges::count(reversed_parts(plan, parts), true), 0);
  if (plan.found) {
    expect_collision_free(plan, parts.size());
  } else {
    EXPECT_NE(plan.message.find("no assembly order: part "), std::string::npos);
  }
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const AssemblyPlan again = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_EQ(again.blocks, plan.blocks);
  EXPECT_EQ(again.removal, plan.removal);
  EXPECT_EQ(again.order, plan.order);
}

TEST(PlanAssembly, AxisAlignedLayersHaveAnOrder) {
  // Per-cell labels by z-layer and a direction per layer that points out of the stack for the
  // outer layers: always solvable, and collision-free. Layer 1 (up, under layers 2 and 3) leaves
  // down once layer 0 is out.
  const Grid g = make_grid(3, 3, 4, 5.0);
  const auto parts = grid_parts(g, [](const Cell& c) { return c[2]; }, {-kZ, kZ, kX, kZ});
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  expect_plan_follows(plan, parts, blocks_by_cells(g, parts), blocks_by_cells(g, flipped(parts)));
  EXPECT_EQ(reversed_parts(plan, parts), (Flags{false, true, false, false}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{3, 2, 1, 0}));
  expect_collision_free(plan, parts.size());
}

TEST(PlanAssembly, AClampedPartComesOffSidewaysAlongAnExtraDirection) {
  // In the x-z plane (z up):   B B B
  //                            A A B
  //                            B B B
  // Both leave along z, and each blocks the other both ways; along +x B slides off A's end.
  // Parts: B (the larger) = 0, A = 1.
  const Grid g = make_grid(3, 1, 3, 10.0);
  const auto parts =
      grid_parts(g, [](const Cell& c) { return c[2] == 1 && c[0] <= 1 ? 1 : 0; }, {kZ, kZ});
  ASSERT_EQ(parts.size(), 2u);
  ASSERT_EQ(2 * parts[0].tets.size(), 7 * parts[1].tets.size());
  const AssemblyPlan stuck = plan_assembly(parts, {}, kTolerance_mm);
  EXPECT_FALSE(stuck.found);
  EXPECT_EQ(stuck.removal, (std::vector<Vec3>{kZ, kZ}));
  EXPECT_EQ(stuck.blocks, (Blocks{{1}, {0}}));

  const AssemblyPlan plan = plan_assembly(parts, {-kX, kX, -kY}, kTolerance_mm);
  EXPECT_TRUE(plan.found);
  // Along -x, B's cell right of A runs into it; +x is free. Then A leaves along its own +z,
  // where B was: B goes in after A.
  EXPECT_EQ(plan.removal, (std::vector<Vec3>{kX, kZ}));
  EXPECT_EQ(plan.blocks, (Blocks{{}, {0}}));
  EXPECT_EQ(plan.order, (std::vector<std::int32_t>{1, 0}));
  expect_collision_free(plan, parts.size());
}

TEST(PlanAssembly, NegativeToleranceThrows) {
  const Grid g = make_grid(1, 1, 1, 1.0);
  const auto parts = extract_parts(g.mesh, zeros(g), zeros(g), {kZ});
  EXPECT_THROW(plan_assembly(parts, {}, -1.0), Error);
}

// --- brute-force reference and real shapes ---

// Blocking by brute force, in double precision: from the same sample points (assembly_samples),
// clip the ray against every tet of every other part, merge the intervals per part, and measure
// their depth against every triangle of that part.
std::vector<std::vector<std::int32_t>> reference_blocks(const TetMesh& mesh,
                                                        const std::vector<Part>& parts,
                                                        double tolerance_mm) {
  std::vector<std::int32_t> part_of(mesh.tets.size());
  for (const Part& p : parts)
    for (const std::int32_t t : p.tets) part_of[t] = p.id;
  auto corner = [&](std::int32_t t, int k) -> const Vec3& {
    return mesh.vertices[mesh.tets[t][k]];
  };
  const std::vector<std::vector<Vec3>> all_samples = assembly_samples(parts);
  // Does the way from o + lo d to o + hi d, taken every tolerance_mm / 2, get farther than
  // tolerance_mm from every triangle of part a?
  auto deep = [&](std::size_t a, const Vec3& o, const Vec3& d, double lo, double hi) {
    const TriMesh& m = parts[a].mesh;
    for (double t = lo + tolerance_mm; t < hi - tolerance_mm; t += 0.5 * tolerance_mm) {
      const Vec3 p = o + t * d;
      double nearest = INFINITY;
      for (const Tri& tri : m.triangles)
        nearest = std::min(
            nearest,
            (closest_on_triangle(p, m.vertices[tri[0]], m.vertices[tri[1]], m.vertices[tri[2]]) - p)
                .norm());
      if (nearest >= tolerance_mm) return true;
    }
    return false;
  };
  std::vector<std::set<std::int32_t>> blocks(parts.size());
  for (const Part& b : parts) {
    const std::vector<Vec3>& samples = all_samples[b.id];
    const Vec3& d = b.direction;
    for (const Vec3& o : samples) {
      std::vector<std::vector<std::pair<double, double>>> spans(parts.size());
      for (std::int32_t u = 0; u < static_cast<std::int32_t>(mesh.tets.size()); ++u) {
        if (part_of[u] == b.id) continue;
        double lo = 0.0, hi = 1e300;
        for (int i = 0; i < 4 && lo < hi; ++i) {
          const Vec3 p = corner(u, kTetFaces[i][0]);
          const Vec3 n = (corner(u, kTetFaces[i][1]) - p).cross(corner(u, kTetFaces[i][2]) - p);
          const double start = n.dot(o - p), rate = n.dot(d);  // inside: start + t rate <= 0
          if (rate > 0)
            hi = std::min(hi, -start / rate);
          else if (rate < 0)
            lo = std::max(lo, -start / rate);
          else if (start > 0)
            hi = lo;
        }
        if (lo < hi) spans[part_of[u]].push_back({lo, hi});
      }
      for (std::size_t a = 0; a < parts.size(); ++a) {
        auto& s = spans[a];
        std::sort(s.begin(), s.end());
        for (std::size_t k = 0; k < s.size();) {
          double lo = s[k].first, hi = s[k].second;
          for (++k; k < s.size() && s[k].first <= hi + 1e-9; ++k) hi = std::max(hi, s[k].second);
          if (hi - lo > 2 * tolerance_mm && deep(a, o, d, lo, hi))
            blocks[b.id].insert(static_cast<std::int32_t>(a));
        }
      }
    }
  }
  std::vector<std::vector<std::int32_t>> out;
  for (const auto& s : blocks) out.emplace_back(s.begin(), s.end());
  return out;
}

TEST(PlanAssembly, MatchesBruteForceOnAJitteredGridWithObliqueDirections) {
  const Grid g = make_grid(6, 5, 4, 4.0, 0.15);
  const auto cell_label = scrambled_labels(6 * 5 * 4, 4, 5);
  const auto parts = grid_parts(
      g, [&](const Cell& c) { return cell_label[(c[2] * 5 + c[1]) * 6 + c[0]]; },
      {Vec3(0.2, -0.3, 1.0), Vec3(-1.0, 0.5, 0.1), Vec3(0.1, 1.0, -0.4), Vec3(0.6, 0.6, -0.5)});
  ASSERT_GT(parts.size(), 5u);
  expect_valid_parts(g, parts);
  constexpr double kDepth_mm = 0.3;  // of 4 mm cells: shallow paths near edges do not block
  const AssemblyPlan plan = plan_assembly(parts, {}, kDepth_mm);
  expect_plan_follows(plan, parts, reference_blocks(g.mesh, parts, kDepth_mm),
                      reference_blocks(g.mesh, flipped(parts), kDepth_mm));
  EXPECT_GT(std::ranges::count(reversed_parts(plan, parts), true), 0);
  std::size_t pairs = 0;
  for (const auto& b : plan.blocks) pairs += b.size();
  EXPECT_GT(pairs, 0u);
}

// Cells of a grid (cell_mm) whose centre is inside a closed mesh, by ray parity along z.
std::set<Cell> voxelize(const TriMesh& mesh, double cell_mm, std::array<int, 3>& n) {
  const Box3 box = bounding_box(mesh.vertices);
  for (int k = 0; k < 3; ++k)
    n[k] = static_cast<int>(std::ceil((box.max[k] - box.min[k]) / cell_mm));
  std::set<Cell> inside;
  for (int x = 0; x < n[0]; ++x)
    for (int y = 0; y < n[1]; ++y) {
      // Off-centre by an irrational fraction, so the column misses every edge and vertex.
      const double px = box.min.x() + (x + 0.5 + 1e-4 * std::sqrt(2.0)) * cell_mm;
      const double py = box.min.y() + (y + 0.5 + 1e-4 * std::sqrt(3.0)) * cell_mm;
      std::vector<double> zs;
      for (const Tri& t : mesh.triangles) {
        const Vec3 &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
        const double w0 = (b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px);
        const double w1 = (c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px);
        const double w2 = (a.x() - px) * (b.y() - py) - (a.y() - py) * (b.x() - px);
        if (!((w0 > 0 && w1 > 0 && w2 > 0) || (w0 < 0 && w1 < 0 && w2 < 0))) continue;
        zs.push_back((w0 * a.z() + w1 * b.z() + w2 * c.z()) / (w0 + w1 + w2));
      }
      std::sort(zs.begin(), zs.end());
      for (int z = 0; z < n[2]; ++z) {
        const double pz = box.min.z() + (z + 0.5) * cell_mm;
        const auto below = std::lower_bound(zs.begin(), zs.end(), pz) - zs.begin();
        if (below % 2 == 1) inside.insert({x, y, z});
      }
    }
  return inside;
}

TEST(PartsRealShape, VoxelizedElephantGivesManifoldPartsAndExactBlocking) {
  const std::string path = test::cgal_mesh("elephant.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set not installed";
  std::array<int, 3> n;
  const std::set<Cell> inside = voxelize(test::load_scaled(path, 100.0), 2.5, n);
  // Keep the tets of the inside cells only: a real shape, with rows of cells broken by gaps.
  const Grid full = make_grid(n[0], n[1], n[2], 2.5);
  Grid g{n, {}, {}};
  g.mesh.vertices = full.mesh.vertices;
  for (std::size_t t = 0; t < full.mesh.tets.size(); ++t) {
    if (!inside.count(full.cell_of_tet[t])) continue;
    g.mesh.tets.push_back(full.mesh.tets[t]);
    g.cell_of_tet.push_back(full.cell_of_tet[t]);
  }
  build_tet_adjacency(g.mesh);
  ASSERT_GT(inside.size(), 1000u);
  // Octants around the grid centre, every 8th cell scrambled; axis directions.
  const auto noise = scrambled_labels(static_cast<std::size_t>(n[0]) * n[1] * n[2], 64, 9);
  const auto label = per_cell(g, [&](const Cell& c) {
    const int r = noise[(c[2] * n[1] + c[1]) * n[0] + c[0]];
    if (r < 8) return r % 6;
    return (2 * c[0] >= n[0]) + 2 * (2 * c[1] >= n[1]) + 2 * (2 * c[2] >= n[2]);
  });
  const std::vector<Vec3> directions = {-kX, kX, -kY, kY, -kZ, kZ, kX, kZ};
  const auto parts = extract_parts(g.mesh, label, zeros(g), directions);
  ASSERT_GT(parts.size(), 20u);
  expect_valid_parts(g, parts);
  const AssemblyPlan plan = plan_assembly(parts, {}, kTolerance_mm);
  expect_plan_follows(plan, parts, blocks_by_cells(g, parts), blocks_by_cells(g, flipped(parts)));
  if (plan.found) expect_collision_free(plan, parts.size());
  // The same on one thread.
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const auto again = extract_parts(g.mesh, label, zeros(g), directions);
  ASSERT_EQ(again.size(), parts.size());
  for (std::size_t p = 0; p < parts.size(); ++p)
    EXPECT_EQ(again[p].mesh.triangles, parts[p].mesh.triangles);
  const AssemblyPlan plan_one = plan_assembly(again, {}, kTolerance_mm);
  EXPECT_EQ(plan_one.blocks, plan.blocks);
  EXPECT_EQ(plan_one.removal, plan.removal);
  EXPECT_EQ(plan_one.order, plan.order);
}

// A real tet mesh cut into three 120-degree sectors about an axis: three interfaces, a junction
// curve where they meet and seams on the surface. Smoothing must flatten the tet-face staircase of
// every interface while keeping the parts closed, sharing their interfaces exactly and keeping
// their volume.
TEST(SmoothInterfaces, SectorsOfTheElephantBecomeSmoothAndStayShared) {
  const std::string path = test::cgal_mesh("elephant.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set absent (install libcgal-demo)";
  const TriMesh solid = test::load_scaled(path, 150.0);
  TetOptions topts;
  topts.target_tets = 30000;
  const TetMesh tets = tetrahedralize(solid, topts);
  const Box3 box = bounding_box(tets.vertices);
  const Vec3 centre = 0.5 * (box.min + box.max);
  std::vector<std::int32_t> label(tets.tets.size());
  for (std::size_t t = 0; t < tets.tets.size(); ++t) {
    Vec3 c = Vec3::Zero();
    for (std::int32_t v : tets.tets[t]) c += 0.25 * tets.vertices[v];
    const double turn = std::atan2(c.z() - centre.z(), c.x() - centre.x()) / (2 * M_PI) + 0.5;
    label[t] = std::min(2, static_cast<int>(3 * turn));
  }
  const std::vector<Vec3> dirs{Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  std::vector<Part> parts =
      extract_parts(tets, label, std::vector<std::int32_t>(label.size(), 0), dirs);
  const std::vector<InterfaceSmoothness> raw = interface_smoothness(parts);
  double raw_volume = 0.0;
  for (const Part& p : parts) raw_volume += p.volume_mm3;

  smooth_interfaces(tets, parts, [](std::int32_t, std::int32_t) { return true; });
  const std::vector<InterfaceSmoothness> smooth = interface_smoothness(parts);
  ASSERT_EQ(smooth.size(), raw.size());
  double volume = 0.0;
  for (const Part& p : parts) {
    EXPECT_EQ(test::solid_topology_problem(p.mesh), "") << "part " << p.id;
    // Triangles may only meet where the part touches itself at a point (a duplicated vertex);
    // two that share a vertex and cross beyond it are a fold.
    for (const auto& pair : intersecting_triangles(p.mesh, 1000)) {
      bool contact = false;
      for (std::int32_t a : p.mesh.triangles[pair[0]])
        for (std::int32_t b : p.mesh.triangles[pair[1]])
          contact |= a != b && p.mesh.vertices[a] == p.mesh.vertices[b];
      EXPECT_TRUE(contact) << "part " << p.id << ": triangles " << pair[0] << ", " << pair[1];
    }
    EXPECT_NEAR(signed_volume(p.mesh), p.volume_mm3, 1e-9 * raw_volume);
    volume += p.volume_mm3;
  }
  EXPECT_NEAR(volume, raw_volume, 2e-3 * raw_volume);
  // Area-weighted over the interfaces: the staircase of tet faces is gone.
  auto weighted = [](const std::vector<InterfaceSmoothness>& all, double InterfaceSmoothness::*f) {
    double sum = 0.0, area = 0.0;
    for (const InterfaceSmoothness& s : all) {
      sum += s.*f * s.area_mm2;
      area += s.area_mm2;
    }
    return sum / area;
  };
  const double raw_mean = weighted(raw, &InterfaceSmoothness::mean_angle_deg);
  const double smooth_mean = weighted(smooth, &InterfaceSmoothness::mean_angle_deg);
  EXPECT_LT(smooth_mean, 0.6 * raw_mean);
  EXPECT_LT(weighted(smooth, &InterfaceSmoothness::p95_angle_deg),
            0.9 * weighted(raw, &InterfaceSmoothness::p95_angle_deg));

  // Both sides of an interface have the same triangles on the same coordinates.
  auto interface_of = [&](std::int32_t a, std::int32_t b, bool flip) {
    std::set<std::array<double, 9>> tris;
    const Part& p = parts[a];
    for (std::size_t i = 0; i < p.mesh.triangles.size(); ++i) {
      if (p.triangle_neighbor[i] != b) continue;
      Tri t = p.mesh.triangles[i];
      if (flip) std::swap(t[1], t[2]);
      std::rotate(t.begin(),
                  std::min_element(t.begin(), t.end(),
                                   [&](std::int32_t x, std::int32_t y) {
                                     return std::lexicographical_compare(
                                         p.mesh.vertices[x].data(), p.mesh.vertices[x].data() + 3,
                                         p.mesh.vertices[y].data(), p.mesh.vertices[y].data() + 3);
                                   }),
                  t.end());
      std::array<double, 9> key;
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) key[3 * c + k] = p.mesh.vertices[t[c]][k];
      tris.insert(key);
    }
    return tris;
  };
  for (const InterfaceSmoothness& s : smooth)
    EXPECT_EQ(interface_of(s.part_a, s.part_b, false), interface_of(s.part_b, s.part_a, true))
        << "interface " << s.part_a << "|" << s.part_b;
}

}  // namespace
}  // namespace dhfcast

namespace dhfcast {
namespace {

// Interface vertices of each part inside the solid that lie in its infeasible volume (paper
// §4.3.1): the line along the part's direction through the vertex enters and leaves the solid
// through that part's outer triangles. Brute force over the outer triangles of all parts, as
// (part, vertex).
std::set<std::pair<std::int32_t, std::int32_t>> vertices_in_infeasible_volumes(
    const std::vector<Part>& parts) {
  struct Outer {
    Vec3 a, b, c;
    std::int32_t part;
  };
  std::vector<Outer> outer;
  for (const Part& p : parts)
    for (std::size_t i = 0; i < p.mesh.triangles.size(); ++i)
      if (p.triangle_neighbor[i] < 0) {
        const Tri& t = p.mesh.triangles[i];
        outer.push_back(
            {p.mesh.vertices[t[0]], p.mesh.vertices[t[1]], p.mesh.vertices[t[2]], p.id});
      }
  std::set<std::pair<std::int32_t, std::int32_t>> out;
  for (const Part& p : parts) {
    const Vec3 d = p.direction.normalized();
    std::set<std::int32_t> interface_vertices, outer_vertices;
    for (std::size_t i = 0; i < p.mesh.triangles.size(); ++i)
      for (std::int32_t v : p.mesh.triangles[i])
        (p.triangle_neighbor[i] >= 0 ? interface_vertices : outer_vertices).insert(v);
    for (std::int32_t v : outer_vertices) interface_vertices.erase(v);
    for (std::int32_t v : interface_vertices) {
      const Vec3& x = p.mesh.vertices[v];
      double above = INFINITY, below = -INFINITY;
      std::int32_t up = -1, down = -1;
      for (const Outer& o : outer) {
        // Line x + s d against the triangle (Moller-Trumbore, both signs of s).
        const Vec3 e1 = o.b - o.a, e2 = o.c - o.a, h = d.cross(e2);
        const double det = e1.dot(h);
        if (std::abs(det) < 1e-12) continue;
        const Vec3 q = x - o.a;
        const double u = q.dot(h) / det;
        const Vec3 r = q.cross(e1);
        const double w = d.dot(r) / det;
        if (u < 0 || w < 0 || u + w > 1) continue;
        const double s = e2.dot(r) / det;
        if (s > 1e-9 && s < above) above = s, up = o.part;
        if (s < -1e-9 && s > below) below = s, down = o.part;
      }
      if (up == p.id && down == p.id) out.insert({p.id, v});
    }
  }
  return out;
}

// A box-shaped column of part 0, cast along (nearly) +z, in a corner of part 1: every line
// along +z through the column enters and leaves the solid through part 0, so the whole column
// is part 0's infeasible volume. Smoothing rounds the column's convex vertical edge inwards,
// into the column, where part 1 would then sit between part 0's top and bottom; the projection
// keeps every interface vertex that started outside the infeasible volumes outside them.
TEST(SmoothInterfaces, InterfacesStayOutOfInfeasibleVolumes) {
  const Grid g = make_grid(8, 6, 6, 5.0);
  // Both parts are cast along the same direction, so their infeasible volumes are their own
  // columns, which meet without overlapping.
  const std::vector<Vec3> dirs{kUp, kUp};
  const auto label = per_cell(g, [](const Cell& c) { return c[0] < 4 && c[1] < 3 ? 0 : 1; });
  const std::vector<Part> raw = extract_parts(g.mesh, label, zeros(g), dirs);
  ASSERT_EQ(raw.size(), 2u);
  const auto before = vertices_in_infeasible_volumes(raw);
  EXPECT_TRUE(before.empty());
  auto moved_in = [&](bool project) {
    std::vector<Part> parts = raw;
    SmoothingOptions opts;
    opts.project = project;
    smooth_interfaces(
        g.mesh, parts, [](std::int32_t, std::int32_t) { return true; }, opts);
    for (const Part& p : parts) EXPECT_EQ(test::solid_topology_problem(p.mesh), "");
    return vertices_in_infeasible_volumes(parts).size();
  };
  const std::size_t plain = moved_in(false);
  const std::size_t projected = moved_in(true);
  // Plain smoothing moves a dozen; a few stay where the sliding seams left no room.
  EXPECT_GE(plain, 8u);
  EXPECT_LE(3 * projected, plain) << projected << " of " << plain << " are still inside";
}

}  // namespace
}  // namespace dhfcast

namespace dhfcast {
namespace {

// A triangle as its corner coordinates, rotated to start at the smallest corner: equal for
// equal triangles whatever their numbering.
std::array<double, 9> canonical(const TriMesh& m, const Tri& t, bool reversed) {
  std::array<std::array<double, 3>, 3> c;
  for (int i = 0; i < 3; ++i) {
    const Vec3& p = m.vertices[t[reversed ? (3 - i) % 3 : i]];
    c[i] = {p.x(), p.y(), p.z()};
  }
  std::rotate(c.begin(), std::min_element(c.begin(), c.end()), c.end());
  std::array<double, 9> out;
  for (int i = 0; i < 9; ++i) out[i] = c[i / 3][i % 3];
  return out;
}

TEST(CutPartsFromSolid, OuterSurfaceIsTheInputAndInterfacesStayShared) {
  const std::string path = test::cgal_mesh("blobby.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set absent (install libcgal-demo)";
  const TriMesh solid = test::load_scaled(path, 100.0);
  TetOptions topts;
  topts.target_tets = 8000;
  const TetMesh tets = tetrahedralize(solid, topts);
  ASSERT_GT(tets.boundary_tolerance_mm, 1e-3);  // the tet boundary is not the input surface
  const Box3 box = bounding_box(tets.vertices);
  const double mid_x = 0.5 * (box.min.x() + box.max.x());
  std::vector<std::int32_t> label(tets.tets.size());
  for (std::size_t t = 0; t < tets.tets.size(); ++t) {
    double x = 0.0;
    for (std::int32_t v : tets.tets[t]) x += 0.25 * tets.vertices[v].x();
    label[t] = x < mid_x ? 0 : 1;
  }
  make_parts_manifold(tets, label, std::vector<std::int32_t>(label.size(), 0),
                      [](std::int32_t, std::int32_t, std::int32_t) { return true; });
  std::vector<Part> parts = extract_parts(tets, label, std::vector<std::int32_t>(label.size(), 0),
                                          {Vec3::UnitX(), Vec3::UnitY()});
  ASSERT_EQ(parts.size(), 2u);
  smooth_interfaces(tets, parts, [](std::int32_t, std::int32_t) { return true; });

  const SolidCut cut = cut_parts_from_solid(solid, parts);
  ASSERT_EQ(cut.part_cut, std::vector<bool>(2, true)) << cut.problem[0] << cut.problem[1];
  EXPECT_EQ(cut.uncovered_triangles, 0);
  EXPECT_GE(cut.push_mm, tets.boundary_tolerance_mm);

  double volume = 0.0;
  std::vector<std::array<double, 9>> sides[2];
  for (const Part& p : parts) {
    EXPECT_EQ(test::solid_topology_problem(p.mesh), "") << "part " << p.id;
    EXPECT_NEAR(p.volume_mm3, signed_volume(p.mesh), 1e-9 * p.volume_mm3);
    volume += p.volume_mm3;
    std::vector<Vec3> outer;
    for (std::size_t t = 0; t < p.mesh.triangles.size(); ++t) {
      if (p.triangle_neighbor[t] < 0) {
        for (std::int32_t v : p.mesh.triangles[t]) outer.push_back(p.mesh.vertices[v]);
      } else {
        EXPECT_EQ(p.triangle_neighbor[t], 1 - p.id);
        sides[p.id].push_back(canonical(p.mesh, p.mesh.triangles[t], p.id == 1));
      }
    }
    // Every corner of the outer surface lies on the input surface, to float rounding.
    EXPECT_LE(test::max_distance_to_surface(outer, solid), 1e-4) << "part " << p.id;
  }
  // Together the parts are the input solid, not the tet mesh.
  EXPECT_NEAR(volume, signed_volume(solid), 1e-9 * volume);
  EXPECT_GT(std::abs(total_volume(tets) - volume), 1e-6 * volume);
  // The interface is one surface: part 1's triangles are part 0's, reversed.
  for (auto& side : sides) std::sort(side.begin(), side.end());
  EXPECT_FALSE(sides[0].empty());
  EXPECT_TRUE(sides[0] == sides[1]);
}

// A part touching itself along an edge of the outer surface, with a neighbour between its two
// sheets that reaches the surface only along that edge: 3x3x3 unit cells without the column
// x, z in [2, 3] (air). In the middle layer along y, P's cells (1, 1, 2) and (2, 1, 1) meet
// along the edge x = z = 2 only, Q's cell (1, 1, 1) between them below; elsewhere P joins them
// up. Extracting P splits one sheet at the edge's midpoint, so across the seam on the surface no
// outer edge runs from end to end. The cut used to stop there on the missing edge ("internal:
// map::at", CGAL's elephant at 8000 tets); now Q is cut and P, whose two sheets still touch
// along the edge, keeps its own surface (which here is the input's) and says why.
TEST(CutPartsFromSolid, PartTouchingItselfAlongAnOuterEdgeDoesNotStopTheCut) {
  const std::vector<double> c = {0.0, 1.0, 2.0, 3.0};
  const test::GridFilled filled = [](int i, int, int k) { return !(i == 2 && k == 2); };
  const TetMesh tets = test::grid_tets(c, c, c, filled);
  std::vector<std::int32_t> label(tets.tets.size(), 0);
  for (std::size_t t = 0; t < tets.tets.size(); ++t) {
    Vec3 centre = Vec3::Zero();
    for (std::int32_t v : tets.tets[t]) centre += 0.25 * tets.vertices[v];
    if (centre.x() > 1.0 && centre.x() < 2.0 && centre.y() > 1.0 && centre.y() < 2.0 &&
        centre.z() > 1.0 && centre.z() < 2.0)
      label[t] = 1;
  }
  std::vector<Part> parts = extract_parts(tets, label, zeros_like(tets), {kX, kZ});
  ASSERT_EQ(parts.size(), 2u);
  ASSERT_EQ(count_vertices_at(parts[0].mesh, Vec3(2.0, 1.5, 2.0)), 1);  // the midpoint

  const TriMesh solid = test::grid_surface(c, c, c, filled);
  const SolidCut cut = cut_parts_from_solid(solid, parts);
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_EQ(cut.part_cut, (std::vector<bool>{false, true}));
  EXPECT_NE(cut.problem[0].find("intersects itself"), std::string::npos) << cut.problem[0];
  for (const Part& p : parts) EXPECT_EQ(test::solid_topology_problem(p.mesh), "") << p.id;
  EXPECT_NEAR(parts[0].volume_mm3, 23.0, 1e-9);
  // Q's corners on the edge move out a hair with P's, so its side tilts by about that much.
  EXPECT_NEAR(parts[1].volume_mm3, 1.0, 1e-3);
  EXPECT_EQ(cut.uncovered_triangles, 0);
}

// --- clearing a blocked part's way ---

// A 3x3x3 box locked together: part P (label 0, leaves along z) is the middle layer but for
// the cell (1, 0, 1), which joins part Q's top and bottom layers (label 1, leaves along x). P
// runs into Q both up and down; Q's middle cell runs into P both ways along x.
int locked_layers(const Cell& c) { return c[2] == 1 && !(c[0] == 1 && c[1] == 0) ? 0 : 1; }

// Points inside the other parts on part p's way along dir: the middle of each stretch.
std::vector<Vec3> obstacle_points(const std::vector<Part>& parts, std::int32_t p, const Vec3& dir) {
  std::vector<Vec3> points;
  for (const Obstruction& o : obstructions(parts, p, dir, kTolerance_mm))
    points.push_back(0.5 * (o.from + o.to));
  return points;
}

TEST(ClearWay, LockedLayersComeApartOnceTheTopIsInTheMiddlePartsWay) {
  const Grid g = make_grid(3, 3, 3, 10.0);
  const std::vector<Vec3> dirs{kZ, kX};
  auto label = per_cell(g, locked_layers);
  const auto parts = extract_parts(g.mesh, label, zeros(g), dirs);
  ASSERT_EQ(parts.size(), 2u);
  const std::int32_t p = parts[0].direction_index == 0 ? 0 : 1;
  EXPECT_FALSE(plan_assembly(parts, {}, kTolerance_mm).found);
  const std::vector<Vec3> points = obstacle_points(parts, p, kZ);
  ASSERT_FALSE(points.empty());
  for (const Vec3& x : points) EXPECT_GT(x.z(), 20.0);  // in Q's top layer

  const std::vector<std::int32_t> moved =
      clear_way(g.mesh, label, zeros(g), dirs, kAllowAll, parts[p].tets.front(), kZ, points);
  // The top layer goes to P, but for the cell above Q's middle cell: no line down from it
  // reaches P.
  std::vector<std::int32_t> expected;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(label.size()); ++t) {
    const Cell& c = g.cell_of_tet[t];
    if (c[2] == 2 && !(c[0] == 1 && c[1] == 0)) expected.push_back(t);
  }
  EXPECT_EQ(moved, expected);
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(label.size()); ++t) {
    const Cell& c = g.cell_of_tet[t];
    EXPECT_EQ(label[t], (c[2] >= 1 && !(c[0] == 1 && c[1] == 0)) ? 0 : 1) << "tet " << t;
  }
  const auto cleared = extract_parts(g.mesh, label, zeros(g), dirs);
  ASSERT_EQ(cleared.size(), 2u);
  const AssemblyPlan plan = plan_assembly(cleared, {}, kTolerance_mm);
  EXPECT_TRUE(plan.found) << plan.message;
}

TEST(ClearWay, MovesThatWouldSplitAPartOrThatItsDirectionForbidsAreRefused) {
  const Grid g = make_grid(3, 3, 3, 10.0);
  const std::vector<Vec3> dirs{kZ, kX};
  const auto start = per_cell(g, locked_layers);
  const auto parts = extract_parts(g.mesh, start, zeros(g), dirs);
  const std::int32_t p = parts[0].direction_index == 0 ? 0 : 1;
  const std::vector<Vec3> points = obstacle_points(parts, p, kZ);
  // P may not take the top layer's corner cell (2, 2, 2): taking the rest would leave it a
  // piece of Q of its own.
  const TetAllowsLabel corner_forbidden = [&](std::int32_t t, std::int32_t, std::int32_t l) {
    const Cell& c = g.cell_of_tet[t];
    return l != 0 || !(c[0] == 2 && c[1] == 2 && c[2] == 2);
  };
  auto label = start;
  EXPECT_TRUE(
      clear_way(g.mesh, label, zeros(g), dirs, corner_forbidden, parts[p].tets.front(), kZ, points)
          .empty());
  EXPECT_EQ(label, start);
  // P may take nothing above its layer.
  const TetAllowsLabel top_forbidden = [&](std::int32_t t, std::int32_t, std::int32_t l) {
    return l != 0 || g.cell_of_tet[t][2] < 2;
  };
  EXPECT_TRUE(
      clear_way(g.mesh, label, zeros(g), dirs, top_forbidden, parts[p].tets.front(), kZ, points)
          .empty());
  EXPECT_EQ(label, start);
}

// --- filling a part's gaps along its direction ---

// A 4x3x3 box: part P (label 0, along z) is a C over the first three columns of cells (bottom
// and top layers, and the x = 0 wall); part Q (label 1, along x) is the middle layer inside the
// C and the whole last column. Lines along z through the C's mouth meet P, Q, P.
int c_around_a_tongue(const Cell& c) { return c[0] <= 2 && (c[2] != 1 || c[0] == 0) ? 0 : 1; }

constexpr std::int64_t kGapLines = 900;  // over a part's footprint

// Part p's gaps on kGapLines lines, which must cross two thirds of its footprint.
std::vector<DhfGap> gaps_over_two_thirds(const std::vector<Part>& parts, std::int32_t p) {
  const std::vector<DhfGap> gaps = dhf_gaps(parts, kGapLines, kTolerance_mm)[p];
  EXPECT_GT(gaps.size(), 0.6 * kGapLines);
  EXPECT_LT(gaps.size(), 0.72 * kGapLines);
  return gaps;
}

TEST(DhfGaps, LinesThroughAPartsMouthCrossTheNeighbourBetweenItsJaws) {
  const Grid g = make_grid(4, 3, 3, 10.0);
  const std::vector<Vec3> dirs{kZ, kX};
  const auto parts = extract_parts(g.mesh, per_cell(g, c_around_a_tongue), zeros(g), dirs);
  ASSERT_EQ(parts.size(), 2u);
  const std::int32_t p = parts[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  // The mouth is two thirds of P's footprint.
  const std::vector<DhfGap> gaps = gaps_over_two_thirds(parts, p);
  for (const DhfGap& o : gaps) {
    EXPECT_EQ(o.part, q);
    EXPECT_NEAR(o.from.z(), 10.0, 1e-6);
    EXPECT_NEAR(o.to.z(), 20.0, 1e-6);
    EXPECT_GT(o.from.x(), 10.0);
    EXPECT_LT(o.from.x(), 30.0);
  }
  // Along x, Q is one interval on every line; a gap no deeper than epsilon is none.
  EXPECT_TRUE(dhf_gaps(parts, kGapLines, kTolerance_mm)[q].empty());
  EXPECT_TRUE(dhf_gaps(parts, kGapLines, 5.0)[p].empty());
  // Counted from each part's own boundary alone, the gaps are the same.
  EXPECT_EQ(dhf_gap_count(parts[p], kGapLines, kTolerance_mm), std::ssize(gaps));
  EXPECT_EQ(dhf_gap_count(parts[q], kGapLines, kTolerance_mm), 0);
  EXPECT_EQ(dhf_gap_count(parts[p], kGapLines, 5.0), 0);
}

TEST(FillGaps, TheTongueBetweenThePartsJawsJoinsIt) {
  const Grid g = make_grid(4, 3, 3, 10.0);
  const std::vector<Vec3> dirs{kZ, kX};
  auto label = per_cell(g, c_around_a_tongue);
  const auto parts = extract_parts(g.mesh, label, zeros(g), dirs);
  const std::int32_t p = parts[0].direction_index == 0 ? 0 : 1;
  std::vector<Vec3> points;  // along each gap, 1 mm apart, as the pipeline seeds them
  const std::vector<std::vector<DhfGap>> gaps = dhf_gaps(parts, 100, kTolerance_mm);
  for (const DhfGap& o : gaps[p])
    for (int i = 0; i <= 10; ++i) points.push_back(o.from + 0.1 * i * (o.to - o.from));
  const std::vector<std::int32_t> moved =
      fill_gaps(g.mesh, label, zeros(g), dirs, kAllowAll, parts[p].tets.front(), points);
  std::vector<std::int32_t> expected;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(label.size()); ++t) {
    const Cell& c = g.cell_of_tet[t];
    EXPECT_EQ(label[t], c[0] <= 2 ? 0 : 1) << "tet " << t;
    if (c[0] >= 1 && c[0] <= 2 && c[2] == 1) expected.push_back(t);
  }
  EXPECT_EQ(moved, expected);
  const auto filled = extract_parts(g.mesh, label, zeros(g), dirs);
  ASSERT_EQ(filled.size(), 2u);
  for (std::int32_t k = 0; k < 2; ++k) EXPECT_TRUE(dhf_gaps(filled, 900, kTolerance_mm)[k].empty());
  // A part that may not take the tongue keeps its gap.
  auto kept = per_cell(g, c_around_a_tongue);
  const TetAllowsLabel tongue_forbidden = [&](std::int32_t t, std::int32_t, std::int32_t l) {
    return l != 0 || g.cell_of_tet[t][2] != 1;
  };
  EXPECT_TRUE(
      fill_gaps(g.mesh, kept, zeros(g), dirs, tongue_forbidden, parts[p].tets.front(), points)
          .empty());
  EXPECT_EQ(kept, per_cell(g, c_around_a_tongue));
}

// A 30 x 10 x 40 mm column of 10 mm cells with a slot cut into it from +x at height 20..30 (the
// cells at x >= 10 there are missing): part Q (sideways) is the bottom layer; part P (up) is the
// rest, so on lines along up at x > 10, P has a skin (z 10..20) on Q with air over it and then P
// again.
struct SkinOverAir {
  TetMesh mesh;
  std::vector<std::int32_t> label;  // P: 0, Q: 1
  std::vector<Cell> cell;
};

SkinOverAir skin_over_air() {
  const std::vector<double> xs{0, 10, 20, 30}, ys{0, 10}, zs{0, 10, 20, 30, 40};
  SkinOverAir s;
  s.mesh = test::grid_tets(xs, ys, zs, [](int i, int, int k) { return k != 2 || i == 0; });
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(s.mesh.tets.size()); ++t) {
    Vec3 centre = Vec3::Zero();
    for (std::int32_t v : s.mesh.tets[t]) centre += 0.25 * s.mesh.vertices[v];
    const Cell c{static_cast<int>(centre.x() / 10), static_cast<int>(centre.y() / 10),
                 static_cast<int>(centre.z() / 10)};
    s.cell.push_back(c);
    s.label.push_back(c[2] == 0 ? 1 : 0);
  }
  return s;
}

TEST(DhfGaps, ASkinOverAirSaysWhichPartItLiesOn) {
  const SkinOverAir s = skin_over_air();
  const std::vector<Vec3> dirs{kZ, kX};
  const auto parts = extract_parts(s.mesh, s.label, zeros_like(s.mesh), dirs);
  ASSERT_EQ(parts.size(), 2u);
  const std::int32_t p = parts[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  // The slot is two thirds of P's footprint.
  const std::vector<DhfGap> gaps = gaps_over_two_thirds(parts, p);
  for (const DhfGap& g : gaps) {
    EXPECT_EQ(g.part, -1);  // outside the solid
    EXPECT_EQ(g.below, q);
    EXPECT_NEAR(g.interval_from.z(), 10.0, 1e-6);
    EXPECT_NEAR(g.from.z(), 20.0, 1e-6);
    EXPECT_NEAR(g.to.z(), 30.0, 1e-6);
    EXPECT_GT(g.from.x(), 10.0);
  }
}

TEST(FillGaps, ThePartUnderASkinOverAirTakesIt) {
  SkinOverAir s = skin_over_air();
  const std::vector<Vec3> dirs{kZ, kX};
  const auto parts = extract_parts(s.mesh, s.label, zeros_like(s.mesh), dirs);
  const std::int32_t p = parts[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  std::vector<Vec3> points;  // along each skin, as the pipeline seeds them
  const std::vector<std::vector<DhfGap>> gaps = dhf_gaps(parts, 100, kTolerance_mm);
  ASSERT_FALSE(gaps[p].empty());
  for (const DhfGap& g : gaps[p])
    for (int i = 0; i <= 4; ++i)
      points.push_back(g.interval_from + 0.25 * i * (g.from - g.interval_from));
  const std::vector<std::int32_t> moved = fill_gaps(s.mesh, s.label, zeros_like(s.mesh), dirs,
                                                    kAllowAll, parts[q].tets.front(), points);
  std::vector<std::int32_t> expected;  // the skin: the cells under the slot
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(s.label.size()); ++t)
    if (s.cell[t][2] == 1 && s.cell[t][0] >= 1) expected.push_back(t);
  EXPECT_EQ(moved, expected);
  const auto filled = extract_parts(s.mesh, s.label, zeros_like(s.mesh), dirs);
  ASSERT_EQ(filled.size(), 2u);
  for (std::int32_t k = 0; k < 2; ++k) EXPECT_TRUE(dhf_gaps(filled, 900, kTolerance_mm)[k].empty());
}

// Part P (label 0, along z): the bottom layer, the x = 0 wall, and a 20 x 30 x 10 mm tongue
// reaching from the wall at height 20..30, inside part Q (label 1, along x: everything else).
// Lines along z through the tongue meet P, Q, P, Q: the tongue touches only Q, so carving it out
// leaves the outer surface as it is.
int tongue_inside_the_neighbour(const Cell& c) {
  const bool tongue = c[2] == 2 && c[0] >= 1 && c[0] <= 2 && c[1] >= 1 && c[1] <= 3;
  return c[2] == 0 || c[0] == 0 || tongue ? 0 : 1;
}

// The parts' triangles facing `neighbor`, as canonical corner lists.
std::multiset<std::array<double, 9>> facing(const Part& part, std::int32_t neighbor,
                                            bool reversed = false) {
  std::multiset<std::array<double, 9>> out;
  for (std::size_t t = 0; t < part.mesh.triangles.size(); ++t)
    if (part.triangle_neighbor[t] == neighbor)
      out.insert(canonical(part.mesh, part.mesh.triangles[t], reversed));
  return out;
}

double outer_area(const std::vector<Part>& parts) {
  double area = 0.0;
  for (const Part& part : parts)
    for (std::size_t t = 0; t < part.mesh.triangles.size(); ++t)
      if (part.triangle_neighbor[t] == -1) {
        const Tri& tri = part.mesh.triangles[t];
        const std::vector<Vec3>& v = part.mesh.vertices;
        area += 0.5 * (v[tri[1]] - v[tri[0]]).cross(v[tri[2]] - v[tri[0]]).norm();
      }
  return area;
}

// What carve_dhf_gaps() must keep, whatever it did: closed parts whose interfaces are shared
// triangle for triangle, the outer surface's area, and the volume (parts and voids).
void expect_sound(const std::vector<Part>& before, const std::vector<Part>& after,
                  const Carving& carving) {
  double volume_before = 0.0, volume_after = 0.0;
  for (const Part& part : before) volume_before += part.volume_mm3;
  for (const Part& part : after) volume_after += part.volume_mm3;
  for (const CarvedVoid& v : carving.voids) volume_after += v.volume_mm3;
  EXPECT_NEAR(volume_after, volume_before, 1e-6 * volume_before);
  EXPECT_NEAR(outer_area(after), outer_area(before), 1e-6 * outer_area(before));
  for (std::int32_t a = 0; a < static_cast<std::int32_t>(after.size()); ++a) {
    expect_closed_manifold(after[a].mesh);
    EXPECT_NEAR(after[a].volume_mm3, signed_volume(after[a].mesh), 1e-9);
    for (std::int32_t b = a + 1; b < static_cast<std::int32_t>(after.size()); ++b)
      EXPECT_EQ(facing(after[a], b), facing(after[b], a, true)) << a << " and " << b;
  }
}

// The parts of tongue_inside_the_neighbour() in 10 mm cells, 40 x 50 x 40 mm, and the lines
// to look for their gaps on (a 0.9 mm grid).
std::vector<Part> tongue_parts() {
  const Grid g = make_grid(4, 5, 4, 10.0);
  return extract_parts(g.mesh, per_cell(g, tongue_inside_the_neighbour), zeros(g), {kZ, kX});
}
constexpr std::int64_t kTongueLines = 2500;

// Carving mended every gap line by one exchange, no void: `volume_mm3` (up to `margin_mm3`
// more) went from part `from` to part `to`.
void expect_one_exchange(const Carving& carving, std::int32_t from, std::int32_t to,
                         double volume_mm3, double margin_mm3) {
  EXPECT_TRUE(carving.voids.empty());
  ASSERT_EQ(carving.exchanges.size(), 1u) << (carving.refused.empty() ? "" : carving.refused[0]);
  EXPECT_EQ(carving.exchanges[0].from, from);
  EXPECT_EQ(carving.exchanges[0].to, to);
  EXPECT_GE(carving.exchanges[0].volume_mm3, volume_mm3 - 1e-6);
  EXPECT_LT(carving.exchanges[0].volume_mm3, volume_mm3 + margin_mm3);
  EXPECT_GT(carving.gap_lines_before, 500);
  EXPECT_EQ(carving.gap_lines_after, 0);
}

TEST(CarveDhfGaps, TheGapUnderATongueIsFilledByThePart) {
  const std::vector<Part> before = tongue_parts();
  ASSERT_EQ(before.size(), 2u);
  const std::int32_t p = before[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  std::vector<Part> parts = before;
  const Carving carving = carve_dhf_gaps(parts, kTongueLines, kTolerance_mm);
  // The 20 x 30 x 10 mm of Q under the tongue, and less than half a line spacing (0.45 mm)
  // around it.
  expect_one_exchange(carving, q, p, 6000.0, 0.45 * (2 * 31 + 2 * 21) * 10);
  for (std::int32_t k : {p, q})
    EXPECT_TRUE(dhf_gaps(parts, 4 * kTongueLines, kTolerance_mm)[k].empty());
  // Filled inside the solid: the outer surface is the same triangles, and no wall faces a void.
  for (std::int32_t k : {p, q}) {
    EXPECT_EQ(facing(parts[k], -1), facing(before[k], -1));
    EXPECT_TRUE(facing(parts[k], kCarvedVoid).empty());
  }
  expect_sound(before, parts, carving);
}

// The tongue of tongue_inside_the_neighbour() reaching the y = 0 side: Q under it does too, so a
// hull filling P's gaps would reach the outer surface.
int tongue_to_the_side(const Cell& c) {
  const bool tongue = c[2] == 2 && c[0] >= 1 && c[0] <= 2 && c[1] <= 3;
  return c[2] == 0 || c[0] == 0 || tongue ? 0 : 1;
}

TEST(CarveDhfGaps, WhereFillingWouldReachTheOuterSurfaceThePartTakesTheNeighboursPiece) {
  const Grid g = make_grid(4, 5, 4, 10.0);
  const std::vector<Part> before =
      extract_parts(g.mesh, per_cell(g, tongue_to_the_side), zeros(g), {kZ, kX});
  ASSERT_EQ(before.size(), 2u);
  const std::int32_t p = before[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  std::vector<Part> parts = before;
  const Carving carving = carve_dhf_gaps(parts, kTongueLines, kTolerance_mm);
  // P takes Q's 20 x 40 x 10 mm under the tongue (yielding the tongue to Q would mend the lines
  // too, the other way round).
  expect_one_exchange(carving, q, p, 8000.0, 0.45 * (2 * 41 + 21) * 10);
  for (std::int32_t k : {p, q})
    EXPECT_TRUE(dhf_gaps(parts, 4 * kTongueLines, kTolerance_mm)[k].empty());
  // The outer surface stays where it was (its area, in expect_sound()); P's now covers the side
  // of the piece it took.
  EXPECT_GT(facing(parts[p], -1).size(), facing(before[p], -1).size());
  expect_sound(before, parts, carving);
}

TEST(CarveDhfGaps, ATongueInsideTheNeighbourIsCarvedIntoAVoidAndTheOuterSurfaceStays) {
  const std::vector<Part> before = tongue_parts();
  ASSERT_EQ(before.size(), 2u);
  const std::int32_t p = before[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  ASSERT_GT(dhf_gaps(before, kTongueLines, kTolerance_mm)[p].size(), 500u);

  std::vector<Part> parts = before;
  const Carving carving = carve_dhf_gaps(parts, kTongueLines, kTolerance_mm, false);
  EXPECT_TRUE(carving.exchanges.empty());
  ASSERT_EQ(carving.voids.size(), 1u) << (carving.refused.empty() ? "" : carving.refused[0]);
  EXPECT_EQ(carving.gap_lines_after, 0);
  EXPECT_GT(carving.gap_lines_before, 500);
  EXPECT_TRUE(dhf_gaps(parts, 4 * kTongueLines, kTolerance_mm)[p].empty());
  const CarvedVoid& hole = carving.voids[0];
  EXPECT_EQ(hole.part, p);
  // The tongue, and a sliver of the wall less than half a line spacing (0.45 mm) thick.
  EXPECT_GE(hole.volume_mm3, 6000.0 - 1e-6);
  EXPECT_LT(hole.volume_mm3, 6000.0 + 0.45 * 31 * 16);
  EXPECT_NEAR(hole.volume_mm3, signed_volume(hole.mesh), 1e-9 * hole.volume_mm3);
  expect_closed_manifold(hole.mesh);
  for (const Part& part : parts) expect_closed_manifold(part.mesh);
  EXPECT_NEAR(parts[p].volume_mm3, before[p].volume_mm3 - hole.volume_mm3, 1e-6);
  EXPECT_NEAR(parts[q].volume_mm3, before[q].volume_mm3, 1e-6);
  // The outer surface is the same triangles; the interface is shared exactly; Q's walls of the
  // void face it, as the void's faces that came from Q do.
  for (std::int32_t k : {p, q}) EXPECT_EQ(facing(parts[k], -1), facing(before[k], -1));
  EXPECT_EQ(facing(parts[p], q), facing(parts[q], p, true));
  EXPECT_FALSE(facing(parts[q], kCarvedVoid).empty());
  EXPECT_FALSE(facing(parts[p], kCarvedVoid).empty());  // the sliver's wall
  // What P lost is the void: its triangles are P's new walls and Q's, reversed.
  std::multiset<std::array<double, 9>> walls = facing(parts[q], kCarvedVoid, true);
  for (const auto& t : facing(parts[p], kCarvedVoid, true)) walls.insert(t);
  std::multiset<std::array<double, 9>> hole_triangles;
  for (const Tri& t : hole.mesh.triangles) hole_triangles.insert(canonical(hole.mesh, t, false));
  EXPECT_EQ(hole_triangles, walls);
  expect_sound(before, parts, carving);
}

// Every triangle of a part with the part across it, by corner positions.
std::multiset<std::pair<std::array<double, 9>, std::int32_t>> surface(const Part& part) {
  std::multiset<std::pair<std::array<double, 9>, std::int32_t>> out;
  for (std::size_t t = 0; t < part.mesh.triangles.size(); ++t)
    out.emplace(canonical(part.mesh, part.mesh.triangles[t], false), part.triangle_neighbor[t]);
  return out;
}

// CGAL triangulates a facet with co-circular corners (the hull's rectangles here, or a square
// a boolean splits) by the order it meets them in, which can follow memory addresses that
// differ from run to run. The parts made must not: here the same hull, its points listed in
// two orders, fills the same tongue.
TEST(CarveDhfGaps, AHullGivesTheSamePartsWhateverOrderItsPointsComeIn) {
  const std::vector<Part> parts = tongue_parts();
  const std::int32_t p = parts[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  // A lattice over the box under the tongue (Q's), reaching into P's floor and tongue.
  std::vector<Vec3> points;
  for (double x : {10.5, 17.0, 23.0, 29.5})
    for (double y : {10.5, 20.0, 30.0, 39.5})
      for (double z : {9.5, 15.0, 20.5}) points.emplace_back(x, y, z);
  std::vector<Vec3> shuffled = points;
  std::mt19937 random(7);
  std::shuffle(shuffled.begin(), shuffled.end(), random);
  std::string why;
  const std::optional<detail::CarvedHull> filled =
      detail::fill_hull(parts, p, q, points, true, why);
  ASSERT_TRUE(filled) << why;
  for (int order = 0; order < 4; ++order) {
    std::shuffle(shuffled.begin(), shuffled.end(), random);
    const std::optional<detail::CarvedHull> again =
        detail::fill_hull(parts, p, q, shuffled, true, why);
    ASSERT_TRUE(again) << why;
    ASSERT_EQ(again->changed.size(), filled->changed.size());
    for (std::size_t k = 0; k < filled->changed.size(); ++k)
      EXPECT_EQ(surface(again->changed[k].second), surface(filled->changed[k].second))
          << "part " << filled->changed[k].first << ", order " << order;
  }
}

// A 60 x 30 x 30 mm box: part P (label 0) a rod of five 10 mm cells along x through its middle,
// from the x = 0 side; part R (label 2) the cell on the rod's last; part Q (label 1) the rest.
int rod_under_a_cap(const Cell& c) {
  if (c[1] == 1 && c[2] == 1 && c[0] <= 4) return 0;
  return c[0] == 4 && c[1] == 1 && c[2] == 2 ? 2 : 1;
}

TEST(CarveDhfGaps, APieceAnExchangeCutsOffGoesToThePartAroundIt) {
  const Grid g = make_grid(6, 3, 3, 10.0);
  const std::vector<Part> before =
      extract_parts(g.mesh, per_cell(g, rod_under_a_cap), zeros(g), {kZ, kX, kY});
  ASSERT_EQ(before.size(), 3u);
  std::array<std::int32_t, 3> id{};  // by label
  for (const Part& part : before) id[part.direction_index] = part.id;
  const std::int32_t p = id[0], q = id[1], r = id[2];
  // P yields Q a slab across the rod's fourth cell (x 30.5 to 39.5, reaching into Q around the
  // rod but not R): what is left of P beyond it, the last cell and a half-millimetre, touches
  // only Q and R.
  std::vector<Vec3> slab;
  for (double x : {30.5, 39.5})
    for (double y : {9.0, 21.0})
      for (double z : {9.0, 21.0}) slab.emplace_back(x, y, z);
  std::string why;
  const std::optional<detail::CarvedHull> yielded =
      detail::yield_hull(before, p, q, slab, true, why);
  ASSERT_TRUE(yielded) << why;
  std::vector<Part> after = before;
  for (const auto& [k, part] : yielded->changed) after[k] = part;
  // P keeps the rod up to x = 30.5; Q takes the slab and the piece beyond it; R, untouched,
  // now faces Q where it faced P.
  EXPECT_NEAR(after[p].volume_mm3, 30.5 * 100.0, 1e-6);
  EXPECT_NEAR(after[q].volume_mm3, before[q].volume_mm3 + 19.5 * 100.0, 1e-6);
  ASSERT_EQ(yielded->changed.size(), 3u);
  EXPECT_EQ(yielded->changed[2].first, r);
  EXPECT_EQ(after[r].mesh.vertices, before[r].mesh.vertices);
  EXPECT_EQ(after[r].mesh.triangles, before[r].mesh.triangles);
  EXPECT_TRUE(facing(after[r], p).empty());
  EXPECT_FALSE(facing(after[r], q).empty());
  expect_sound(before, after, Carving{});
}

TEST(CarveDhfGaps, JawsOnTheOuterSurfaceAreNotCarvedButOneGoesToThePartBetweenThem) {
  const Grid g = make_grid(4, 3, 3, 10.0);
  const std::vector<Vec3> dirs{kZ, kX};
  const auto before = extract_parts(g.mesh, per_cell(g, c_around_a_tongue), zeros(g), dirs);
  const std::int32_t p = before[0].direction_index == 0 ? 0 : 1, q = 1 - p;
  // Both jaws reach the outer surface: nothing can be carved.
  std::vector<Part> parts = before;
  Carving carving = carve_dhf_gaps(parts, kGapLines, kTolerance_mm, false);
  EXPECT_TRUE(carving.voids.empty());
  EXPECT_GT(carving.gap_lines_after, 0);
  EXPECT_EQ(carving.gap_lines_after, carving.gap_lines_before);
  ASSERT_FALSE(carving.refused.empty());
  for (const std::string& why : carving.refused)
    EXPECT_NE(why.find("outer surface on both sides"), std::string::npos) << why;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    EXPECT_EQ(parts[k].mesh.vertices, before[k].mesh.vertices);
    EXPECT_EQ(parts[k].mesh.triangles, before[k].mesh.triangles);
  }
  // Exchanging material mends it: the tongue reaches the outer surface, so P cannot take all
  // of it, but pieces of it or of the lower jaw under the mouth change hands.
  carving = carve_dhf_gaps(parts, kGapLines, kTolerance_mm);
  EXPECT_TRUE(carving.voids.empty());
  EXPECT_FALSE(carving.exchanges.empty());
  for (const GapExchange& e : carving.exchanges) {
    EXPECT_TRUE((e.from == p && e.to == q) || (e.from == q && e.to == p));
    EXPECT_GT(e.volume_mm3, 0.0);
  }
  EXPECT_LT(carving.gap_lines_after, carving.gap_lines_before);
  expect_sound(before, parts, carving);
  EXPECT_THROW(carve_dhf_gaps(parts, 0, kTolerance_mm), Error);
}

}  // namespace
}  // namespace dhfcast
