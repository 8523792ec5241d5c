#include "dhfcast/access.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <thread>

#include "dhfcast/directions.h"
#include "dhfcast/error.h"
#include "support/test_support.h"

namespace dhfcast {
namespace {

using Coords = std::vector<double>;
using test::grid_surface;
using test::grid_tets;

Coords uniform(double lo, double hi, int cells) {
  Coords c;
  for (int i = 0; i <= cells; ++i) c.push_back(lo + (hi - lo) * i / cells);
  return c;
}

// Heights where the vertical line through (x, y) crosses the surface.
std::vector<double> vertical_crossings(const TriMesh& mesh, double x, double y) {
  std::vector<double> zs;
  for (const Tri& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3& b = mesh.vertices[t[1]];
    const Vec3& c = mesh.vertices[t[2]];
    const double d = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (d == 0) continue;
    const double u = ((b.x() - x) * (c.y() - y) - (c.x() - x) * (b.y() - y)) / d;
    const double v = ((c.x() - x) * (a.y() - y) - (a.x() - x) * (c.y() - y)) / d;
    const double w = 1 - u - v;
    if (u < 0 || v < 0 || w < 0) continue;
    zs.push_back(u * a.z() + v * b.z() + w * c.z());
  }
  return zs;
}

// Grid tets of the cells whose centre is inside `surface` (ray parity), cell size h_mm.
TetMesh voxel_tets(const TriMesh& surface, double h_mm) {
  const Box3 box = bounding_box(surface.vertices);
  const Vec3 size = box.max - box.min;
  // Odd offsets keep the parity lines off the surface's vertices and edges.
  const std::array<int, 3> n{static_cast<int>(std::ceil(size.x() / h_mm)) + 1,
                             static_cast<int>(std::ceil(size.y() / h_mm)) + 1,
                             static_cast<int>(std::ceil(size.z() / h_mm)) + 1};
  const Vec3 origin = box.min - Vec3(0.37, 0.29, 0.41) * h_mm;
  Coords xs, ys, zs;
  for (int i = 0; i <= n[0]; ++i) xs.push_back(origin.x() + i * h_mm);
  for (int i = 0; i <= n[1]; ++i) ys.push_back(origin.y() + i * h_mm);
  for (int i = 0; i <= n[2]; ++i) zs.push_back(origin.z() + i * h_mm);
  std::vector<std::vector<double>> columns(n[0] * n[1]);
  for (int i = 0; i < n[0]; ++i)
    for (int j = 0; j < n[1]; ++j) {
      columns[i * n[1] + j] = vertical_crossings(surface, xs[i] + 0.5 * h_mm, ys[j] + 0.5 * h_mm);
    }
  return grid_tets(xs, ys, zs, [&](int i, int j, int k) {
    const double z = zs[k] + 0.5 * h_mm;
    int above = 0;
    for (double c : columns[i * n[1] + j]) above += c > z;
    return above % 2 == 1;
  });
}

// --- an independent, brute-force reference for single samples ---

double segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + s * ab - p).norm();
}

double distance_to_surface(const TriMesh& m, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const Tri& t : m.triangles) {
    const Vec3& a = m.vertices[t[0]];
    const Vec3& b = m.vertices[t[1]];
    const Vec3& c = m.vertices[t[2]];
    const Vec3 n = (b - a).cross(c - a).normalized();
    const Vec3 q = p - n * n.dot(p - a);  // projection on the plane
    const bool inside = (b - a).cross(q - a).dot(n) >= 0 && (c - b).cross(q - b).dot(n) >= 0 &&
                        (a - c).cross(q - c).dot(n) >= 0;
    best = std::min(best, inside ? std::abs(n.dot(p - a))
                                 : std::min({segment_distance(p, a, b), segment_distance(p, b, c),
                                             segment_distance(p, c, a)}));
  }
  return best;
}

// The accessibility rule written plainly: every triangle intersected (Moller-Trumbore), every
// stretch after the first exit sampled every epsilon / 4.
bool reference_accessible(const TriMesh& m, const Vec3& p, const Vec3& d, double eps) {
  const double merge = 1e-6 * bounding_box(m.vertices).diagonal();
  std::vector<std::pair<double, int>> hits;
  for (const Tri& t : m.triangles) {
    const Vec3& a = m.vertices[t[0]];
    const Vec3 e1 = m.vertices[t[1]] - a, e2 = m.vertices[t[2]] - a;
    const Vec3 h = d.cross(e2);
    const double det = e1.dot(h);
    if (det == 0) continue;
    const Vec3 s = p - a;
    const double u = s.dot(h) / det;
    const Vec3 q = s.cross(e1);
    const double v = d.dot(q) / det;
    if (u < 0 || v < 0 || u + v > 1) continue;
    const double t_hit = e2.dot(q) / det;
    if (t_hit < -merge) continue;
    hits.emplace_back(std::max(t_hit, 0.0), e1.cross(e2).dot(d) > 0 ? 1 : -1);
  }
  std::sort(hits.begin(), hits.end());
  std::vector<std::pair<double, int>> crossings;
  for (std::size_t i = 0; i < hits.size();) {
    std::size_t j = i + 1;
    int net = hits[i].second;
    while (j < hits.size() && hits[j].first - hits[j - 1].first <= merge) net += hits[j++].second;
    if (net != 0) crossings.emplace_back(hits[i].first, net > 0 ? 1 : -1);
    i = j;
  }
  if (crossings.empty()) return true;
  std::vector<double> breaks;
  std::size_t first = 0;
  if (crossings[0].second < 0) {
    if (crossings[0].first <= eps)
      first = 1;
    else
      breaks.push_back(0.0);
  }
  for (std::size_t i = first; i < crossings.size(); ++i) breaks.push_back(crossings[i].first);
  for (std::size_t i = 0; i + 1 < breaks.size(); ++i)  // the middles first: same answer, sooner
    if (distance_to_surface(m, p + 0.5 * (breaks[i] + breaks[i + 1]) * d) > eps) return false;
  for (std::size_t i = 0; i + 1 < breaks.size(); ++i)
    for (double t = breaks[i]; t <= breaks[i + 1]; t += eps / 4)
      if (distance_to_surface(m, p + t * d) > eps) return false;
  return true;
}

const std::vector<Vec3> kAxes = {Vec3::UnitX(),  -Vec3::UnitX(), Vec3::UnitY(),
                                 -Vec3::UnitY(), Vec3::UnitZ(),  -Vec3::UnitZ()};
enum Axis { kPosX = 0, kNegX, kPosY, kNegY, kPosZ, kNegZ };

Vec3 barycentre(const TetMesh& m, std::int32_t t) {
  Vec3 c = Vec3::Zero();
  for (std::int32_t v : m.tets[t]) c += m.vertices[v];
  return c / 4.0;
}

// --- convex solid ---

TEST(Accessibility, EveryTetOfABoxIsFeasibleInEveryDirection) {
  const TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(30, 20, 10));
  const TetMesh tets = grid_tets(uniform(0, 30, 3), uniform(0, 20, 2), uniform(0, 10, 2),
                                 [](int, int, int) { return true; });
  std::vector<Vec3> dirs = kAxes;
  for (const Vec3& d : fibonacci_directions(64)) dirs.push_back(d);
  const AccessibilityField f = compute_accessibility(box, tets, dirs);
  ASSERT_EQ(f.feasible.num_tets(), static_cast<std::int32_t>(tets.tets.size()));
  ASSERT_EQ(f.feasible.num_directions(), static_cast<std::int32_t>(dirs.size()));
  for (std::int32_t t = 0; t < f.feasible.num_tets(); ++t) {
    EXPECT_EQ(f.feasible.count(t), static_cast<std::int32_t>(dirs.size())) << "tet " << t;
    EXPECT_EQ(f.eroded.count(t), static_cast<std::int32_t>(dirs.size())) << "tet " << t;
  }
  EXPECT_GT(f.rays_cast, 0);
}

// --- the cup: open at +z, walls and floor 10 mm thick, cells of 5 mm ---

struct Cup {
  TriMesh surface = test::make_cup(50, 10);
  TetMesh tets = grid_tets(uniform(0, 50, 10), uniform(0, 50, 10), uniform(0, 50, 10),
                           [](int i, int j, int k) {
                             const bool core = i >= 2 && i < 8 && j >= 2 && j < 8;
                             return !(core && k >= 2);
                           });
};

TEST(Accessibility, CupIsADoubleHeightFieldAlongZButItsWallsAreBlockedInward) {
  const Cup cup;
  const AccessibilityField f = compute_accessibility(cup.surface, cup.tets, kAxes);
  int walls = 0, floor = 0;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(cup.tets.tets.size()); ++t) {
    const Vec3 c = barycentre(cup.tets, t);
    // The whole cup leaves its mold upwards: the floor exits into the open cavity.
    EXPECT_TRUE(f.feasible.get(t, kPosZ)) << "tet at " << c.transpose();
    // The middle of the left wall: +x crosses the cavity and re-enters the right wall.
    if (c.x() < 10 && c.y() > 15 && c.y() < 35 && c.z() > 20 && c.z() < 45) {
      ++walls;
      EXPECT_FALSE(f.feasible.get(t, kPosX)) << "tet at " << c.transpose();
      EXPECT_TRUE(f.feasible.get(t, kNegX)) << "tet at " << c.transpose();
    }
    // The bottom layer of the floor is a slab: every axis leaves it at once.
    if (c.z() < 5) {
      ++floor;
      for (int a = 0; a < 6; ++a) EXPECT_TRUE(f.feasible.get(t, a)) << "axis " << a;
    }
  }
  EXPECT_GT(walls, 0);
  EXPECT_GT(floor, 0);
}

TEST(Accessibility, ErosionRemovesTetsNextToInfeasibleOnes) {
  const Cup cup;
  const AccessibilityField f = compute_accessibility(cup.surface, cup.tets, kAxes);
  const std::int32_t n = static_cast<std::int32_t>(cup.tets.tets.size());
  std::vector<std::vector<std::int32_t>> around(cup.tets.vertices.size());
  for (std::int32_t t = 0; t < n; ++t)
    for (std::int32_t v : cup.tets.tets[t]) around[v].push_back(t);
  int removed = 0;
  for (std::int32_t t = 0; t < n; ++t)
    for (int d = 0; d < 6; ++d) {
      bool expected = f.feasible.get(t, d);
      for (std::int32_t v : cup.tets.tets[t])
        for (std::int32_t u : around[v]) expected = expected && f.feasible.get(u, d);
      EXPECT_EQ(f.eroded.get(t, d), expected) << "tet " << t << " direction " << d;
      removed += f.feasible.get(t, d) && !expected;
    }
  EXPECT_GT(removed, 0);  // the wall band next to the blocked +x region
}

TEST(Accessibility, SeamVisibilityIsLowestInsideTheCup) {
  const Cup cup;
  const AccessibilityField f = compute_accessibility(cup.surface, cup.tets, kAxes);
  ASSERT_FALSE(f.seam_edges.empty());
  double inner_floor = 0, outer_wall = 0;
  int num_inner = 0, num_outer = 0;
  for (const SeamEdge& e : f.seam_edges) {
    EXPECT_LT(e.tet_a, e.tet_b);
    EXPECT_GT(e.length_mm, 0);
    EXPECT_GE(e.visibility, 0.0);
    EXPECT_LE(e.visibility, 1.0);
    const Vec3 c = 0.5 * (barycentre(cup.tets, e.tet_a) + barycentre(cup.tets, e.tet_b));
    if (c.z() > 5 && c.z() < 10 && c.x() > 20 && c.x() < 30 && c.y() > 20 && c.y() < 30)
      inner_floor += e.visibility, ++num_inner;
    if (c.x() < 2 && c.z() > 20 && c.z() < 30) outer_wall += e.visibility, ++num_outer;
  }
  ASSERT_GT(num_inner, 0);
  ASSERT_GT(num_outer, 0);
  EXPECT_LT(inner_floor / num_inner, outer_wall / num_outer);
  EXPECT_NEAR(outer_wall / num_outer, 1.0, 1e-9);  // a flat outer face sees the whole sky
}

TEST(Accessibility, SeamEdgesOfABoxAreFullyVisible) {
  const TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(20, 20, 20));
  const TetMesh tets = grid_tets(uniform(0, 20, 2), uniform(0, 20, 2), uniform(0, 20, 2),
                                 [](int, int, int) { return true; });
  const AccessibilityField f = compute_accessibility(box, tets, kAxes);
  // 6 sides x 4 squares x 2 triangles, 3 edges each, every edge shared by two triangles; the two
  // triangles of a square always belong to different tets.
  EXPECT_GE(f.seam_edges.size(), 48u);
  EXPECT_LE(f.seam_edges.size(), 72u);
  for (const SeamEdge& e : f.seam_edges) {
    EXPECT_LT(e.tet_a, e.tet_b);
    EXPECT_DOUBLE_EQ(e.visibility, 1.0);  // a convex solid occludes nothing
    EXPECT_TRUE(e.length_mm == 10.0 || std::abs(e.length_mm - 10.0 * std::sqrt(2.0)) < 1e-9);
  }
}

// --- the undercut tolerance, on an I-beam profile ---

// A slab [0,40]x[0,40]x[0,10], a post x in [15,25] of height gap_mm and a plate of thickness
// plate_mm on top; `tets` is one tiny tet around p, so every sample is (almost) p.
struct Beam {
  TriMesh surface;
  TetMesh tets;
  Beam(double gap_mm, double plate_mm, const Vec3& p) {
    const Coords xs{0, 15, 25, 40}, ys{0, 40}, zs{0, 10, 10 + gap_mm, 10 + gap_mm + plate_mm};
    surface = grid_surface(xs, ys, zs, [](int i, int, int k) { return k != 1 || i == 1; });
    const double s = 0.01;
    tets.vertices = {p, p + Vec3(s, 0, 0), p + Vec3(0, s, 0), p + Vec3(0, 0, s)};
    tets.tets = {{0, 1, 2, 3}};
    build_tet_adjacency(tets);
  }
  bool up(double epsilon_mm) const {
    return compute_accessibility(surface, tets, {Vec3::UnitZ()}, {.epsilon_mm = epsilon_mm})
        .feasible.get(0, 0);
  }
};

TEST(Accessibility, ThinGapAndThinPlateAreWithinTolerance) {
  EXPECT_TRUE(Beam(0.3, 0.3, Vec3(7, 20, 5)).up(0.4));
  EXPECT_FALSE(Beam(0.3, 0.3, Vec3(7, 20, 5)).up(0.1));
}

TEST(Accessibility, WideGapBlocksUnlessTheRayRunsAlongTheSurface) {
  EXPECT_FALSE(Beam(3, 0.3, Vec3(7, 20, 5)).up(0.4));
  // 0.2 mm beside the post, the ray stays within tolerance across the whole gap.
  EXPECT_TRUE(Beam(3, 0.3, Vec3(14.8, 20, 5)).up(0.4));
  EXPECT_FALSE(Beam(3, 0.3, Vec3(14.3, 20, 5)).up(0.4));
  EXPECT_TRUE(Beam(3, 0.3, Vec3(7, 20, 5)).up(2));
}

TEST(Accessibility, ThickPlateBlocks) {
  EXPECT_FALSE(Beam(0.3, 3, Vec3(7, 20, 5)).up(0.4));
  EXPECT_TRUE(Beam(0.3, 3, Vec3(7, 20, 5)).up(2));
}

TEST(Accessibility, SampleJustOutsideTheSurfaceCountsAsInside) {
  // 0.1 mm below the slab: the first crossing is the entry right above it.
  EXPECT_TRUE(Beam(0.3, 0.3, Vec3(30, 20, -0.1)).up(0.4));
  // 1 mm below it, the sample is outside and the slab blocks it.
  EXPECT_FALSE(Beam(0.3, 0.3, Vec3(30, 20, -1)).up(0.4));
}

// --- distance to the infeasible region ---

// A chain of tets, each sharing a face with the next, whose barycentres lie on the x axis
// h_mm apart: points p_i = (i h, q_{i mod 4}), tet k = (p_k, ..., p_{k+3}).
TetMesh tet_chain(int n, double h_mm) {
  const std::array<Vec3, 4> q = {Vec3(0, 0, 0), Vec3(0, 3, 0), Vec3(0, 0, 3), Vec3(0, -3, -3)};
  TetMesh m;
  for (int i = 0; i < n + 3; ++i) m.vertices.push_back(Vec3(i * h_mm, 0, 0) + q[i % 4]);
  for (int k = 0; k < n; ++k) {
    m.tets.push_back({k, k + 1, k + 2, k + 3});
    if (tet_volume(m, k) < 0) std::swap(m.tets.back()[2], m.tets.back()[3]);
  }
  build_tet_adjacency(m);
  return m;
}

TEST(DistanceToInfeasible, FollowsTheChainOfBarycentres) {
  const TetMesh chain = tet_chain(20, 2.0);
  for (std::int32_t t = 0; t < 20; ++t) ASSERT_GT(std::abs(tet_volume(chain, t)), 1e-9);
  DirectionBits bits(20, 2);
  for (std::int32_t t = 0; t < 20; ++t) bits.set(t, 1, t != 3 && t != 15);
  const std::vector<float> d = InfeasibleDistance(chain)(bits, 1, 100.0);
  ASSERT_EQ(d.size(), 20u);
  for (int t = 0; t < 20; ++t)
    EXPECT_NEAR(d[t], 2.0 * std::min(std::abs(t - 3), std::abs(t - 15)), 1e-4) << "tet " << t;
  const std::vector<float> capped = InfeasibleDistance(chain)(bits, 1, 5.0);
  for (int t = 0; t < 20; ++t)
    EXPECT_NEAR(capped[t], std::min(5.0, 2.0 * std::min(std::abs(t - 3), std::abs(t - 15))), 1e-4);
}

TEST(DistanceToInfeasible, EverythingFeasibleGivesTheCap) {
  const TetMesh chain = tet_chain(10, 1.0);
  DirectionBits bits(10, 1);
  for (std::int32_t t = 0; t < 10; ++t) bits.set(t, 0, true);
  for (float v : InfeasibleDistance(chain)(bits, 0, 7.5)) EXPECT_EQ(v, 7.5f);
}

// --- options, progress ---

TEST(Accessibility, RejectsBadOptions) {
  const Cup cup;
  for (double eps : {-0.1, std::nan("")}) {
    try {
      compute_accessibility(cup.surface, cup.tets, kAxes, {.epsilon_mm = eps});
      FAIL() << "no exception for epsilon " << eps;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidOptions);
    }
  }
  try {
    compute_accessibility(cup.surface, cup.tets, {});
    FAIL() << "no exception for no directions";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidOptions);
  }
}

TEST(Accessibility, ProgressIsMonotoneOnTheCallingThreadAndEndsAtOne) {
  const Cup cup;
  std::vector<double> seen;
  const std::thread::id caller = std::this_thread::get_id();
  bool other_thread = false;
  compute_accessibility(cup.surface, cup.tets, fibonacci_directions(32), {}, [&](double x) {
    other_thread = other_thread || std::this_thread::get_id() != caller;
    seen.push_back(x);
  });
  EXPECT_FALSE(other_thread);
  ASSERT_FALSE(seen.empty());
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
  EXPECT_GE(seen.front(), 0.0);
  EXPECT_EQ(seen.back(), 1.0);
}

// --- a real mesh ---

TEST(AccessibilityRealMesh, AgreesWithABruteForceReference) {
  const std::string path = test::cgal_mesh("elephant.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set not installed";
  const TriMesh elephant = test::load_scaled(path, 100.0);
  const TetMesh all = voxel_tets(elephant, 2.5);
  // Every 97th tet, kept whole: its samples are the ones the reference tests.
  TetMesh some;
  some.vertices = all.vertices;
  for (std::size_t t = 0; t < all.tets.size(); t += 97) some.tets.push_back(all.tets[t]);
  build_tet_adjacency(some);
  const std::vector<Vec3> dirs = fibonacci_directions(16);
  const double eps = 0.4;
  const AccessibilityField f = compute_accessibility(elephant, some, dirs, {.epsilon_mm = eps});
  int mismatches = 0, infeasible = 0, total = 0;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(some.tets.size()); ++t) {
    const Tet& k = some.tets[t];
    std::array<Vec3, 4> v;
    for (int i = 0; i < 4; ++i) v[i] = some.vertices[k[i]];
    std::vector<Vec3> pts(v.begin(), v.end());
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) pts.push_back(0.5 * (v[i] + v[j]));
    for (int i = 0; i < 4; ++i) pts.push_back((v[0] + v[1] + v[2] + v[3] - v[i]) / 3.0);
    pts.push_back(0.25 * (v[0] + v[1] + v[2] + v[3]));
    for (std::int32_t d = 0; d < static_cast<std::int32_t>(dirs.size()); ++d) {
      bool expected = true;
      for (const Vec3& p : pts)
        expected = expected && reference_accessible(elephant, p, dirs[d], eps);
      mismatches += expected != f.feasible.get(t, d);
      infeasible += !expected;
      ++total;
    }
  }
  EXPECT_GT(infeasible, total / 20);  // the comparison covers both outcomes
  // Only the sampling of long stretches differs; it decides almost nothing.
  EXPECT_LE(mismatches, total / 200) << mismatches << " of " << total;
}

TEST(AccessibilityRealMesh, ElephantIsMostlyAccessibleAndDeterministic) {
  const std::string path = test::cgal_mesh("elephant.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set not installed";
  const TriMesh elephant = test::load_scaled(path, 100.0);
  const TetMesh tets = voxel_tets(elephant, 2.5);
  ASSERT_GT(tets.tets.size(), 5000u);
  const std::vector<Vec3> dirs = fibonacci_directions(64);
  const AccessibilityField many = compute_accessibility(elephant, tets, dirs);

  double covered = 0, total = 0;
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(tets.tets.size()); ++t) {
    total += tet_volume(tets, t);
    if (many.feasible.count(t) > 0) covered += tet_volume(tets, t);
    for (int d = 0; d < 64; ++d)
      if (many.eroded.get(t, d)) {
        ASSERT_TRUE(many.feasible.get(t, d));
      }
  }
  EXPECT_GT(covered / total, 0.9);

  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const AccessibilityField single = compute_accessibility(elephant, tets, dirs);
  EXPECT_EQ(single.rays_cast, many.rays_cast);
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(tets.tets.size()); ++t)
    for (int d = 0; d < 64; ++d) {
      ASSERT_EQ(single.feasible.get(t, d), many.feasible.get(t, d));
      ASSERT_EQ(single.eroded.get(t, d), many.eroded.get(t, d));
    }
  ASSERT_EQ(single.seam_edges.size(), many.seam_edges.size());
  for (std::size_t i = 0; i < many.seam_edges.size(); ++i) {
    EXPECT_EQ(single.seam_edges[i].tet_a, many.seam_edges[i].tet_a);
    EXPECT_EQ(single.seam_edges[i].tet_b, many.seam_edges[i].tet_b);
    EXPECT_EQ(single.seam_edges[i].visibility, many.seam_edges[i].visibility);
  }
}

}  // namespace
}  // namespace dhfcast
