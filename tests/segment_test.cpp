#include "dhfcast/segment.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <set>

#include "dhfcast/access.h"
#include "dhfcast/directions.h"
#include "dhfcast/error.h"
#include "dhfcast/tets.h"
#include "reduce_parts.h"
#include "support/test_support.h"

namespace dhfcast {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// --- generic solver: tiny random problems against brute force ---

LabelProblem random_problem(std::mt19937_64& rng, int nodes, int labels) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  LabelProblem p;
  p.num_nodes = nodes;
  p.num_labels = labels;
  p.data.resize(static_cast<std::size_t>(nodes) * labels);
  for (double& d : p.data) d = u(rng) < 0.25 ? kInf : 3.0 * u(rng);
  for (int i = 0; i < nodes; ++i) {  // every node keeps at least one allowed label
    bool any = false;
    for (int l = 0; l < labels; ++l) any |= std::isfinite(p.data[l * nodes + i]);
    if (!any) p.data[(i % labels) * nodes + i] = u(rng);
  }
  for (int a = 0; a < nodes; ++a)
    for (int b = a + 1; b < nodes; ++b)
      if (u(rng) < 0.5) p.edges.push_back({a, b, 2.0 * u(rng)});
  for (int l = 0; l < labels; ++l) p.label_cost.push_back(2.0 * u(rng));
  return p;
}

// Calls f on every labeling of n nodes with k labels.
void for_each_labeling(int n, int k,
                       const std::function<void(const std::vector<std::int32_t>&)>& f) {
  std::vector<std::int32_t> l(n, 0);
  for (;;) {
    f(l);
    int i = 0;
    while (i < n && ++l[i] == k) l[i++] = 0;
    if (i == n) return;
  }
}

TEST(MinimizeLabeling, ReachesTheBruteForceOptimumOnMostTinyProblems) {
  std::mt19937_64 rng(7);
  const int instances = 300;
  int optimal = 0;
  for (int it = 0; it < instances; ++it) {
    const LabelProblem p = random_problem(rng, 6, 3);
    double best = kInf;
    for_each_labeling(6, 3, [&](const std::vector<std::int32_t>& l) {
      best = std::min(best, labeling_energy(p, l));
    });
    const std::vector<std::int32_t> got = minimize_labeling(p, it, 4);
    const double e = labeling_energy(p, got);
    ASSERT_TRUE(std::isfinite(e)) << "instance " << it << " got a forbidden label";
    ASSERT_GE(e, best - 1e-9);
    if (e <= best + 1e-9) ++optimal;
  }
  EXPECT_GE(optimal, instances * 9 / 10);
}

TEST(MinimizeLabeling, NoSingleExpansionMoveImprovesTheResult) {
  // The defining property of an alpha-expansion local minimum: for every label alpha, no subset
  // of nodes switching to alpha lowers the energy (checked exhaustively).
  std::mt19937_64 rng(11);
  for (int it = 0; it < 100; ++it) {
    const LabelProblem p = random_problem(rng, 6, 4);
    const std::vector<std::int32_t> got = minimize_labeling(p, it, 1);
    const double e = labeling_energy(p, got);
    for (std::int32_t alpha = 0; alpha < 4; ++alpha)
      for (int mask = 1; mask < 64; ++mask) {
        std::vector<std::int32_t> moved = got;
        for (int i = 0; i < 6; ++i)
          if (mask >> i & 1) moved[i] = alpha;
        ASSERT_GE(labeling_energy(p, moved), e - 1e-9 * std::abs(e))
            << "instance " << it << " alpha " << alpha << " mask " << mask;
      }
  }
}

TEST(MinimizeLabeling, WithoutSmoothnessOrLabelCostEachNodeTakesItsCheapestLabel) {
  std::mt19937_64 rng(3);
  LabelProblem p = random_problem(rng, 40, 5);
  p.edges.clear();
  std::fill(p.label_cost.begin(), p.label_cost.end(), 0.0);
  const std::vector<std::int32_t> got = minimize_labeling(p, 1, 1);
  for (int i = 0; i < 40; ++i) {
    double best = kInf;
    for (int l = 0; l < 5; ++l) best = std::min(best, p.data[l * 40 + i]);
    EXPECT_EQ(p.data[got[i] * 40 + i], best) << "node " << i;
  }
}

TEST(MinimizeLabeling, ALargeLabelCostMergesLabels) {
  // A chain: the left half prefers label 0, the right half label 1; label 2 is allowed
  // everywhere but costs a little more on every node.
  const int n = 30;
  LabelProblem p;
  p.num_nodes = n;
  p.num_labels = 3;
  p.data.resize(3 * n);
  for (int i = 0; i < n; ++i) {
    p.data[0 * n + i] = i < n / 2 ? 0.0 : 1.0;
    p.data[1 * n + i] = i < n / 2 ? 1.0 : 0.0;
    p.data[2 * n + i] = 0.4;
  }
  for (int i = 0; i + 1 < n; ++i) p.edges.push_back({i, i + 1, 0.1});
  p.label_cost = {0.0, 0.0, 0.0};
  std::vector<std::int32_t> got = minimize_labeling(p, 5, 3);
  EXPECT_EQ(std::set<std::int32_t>(got.begin(), got.end()), (std::set<std::int32_t>{0, 1}));
  // Now one label must do: label 2 costs 0.4 per node, labels 0 and 1 cost 1 on half the nodes.
  p.label_cost = {100.0, 100.0, 100.0};
  got = minimize_labeling(p, 5, 3);
  EXPECT_EQ(std::set<std::int32_t>(got.begin(), got.end()), (std::set<std::int32_t>{2}));
}

TEST(MinimizeLabeling, LargeProblemsAreDeterministicAndRespectForbiddenLabels) {
  // Large enough to go through the coarse levels.
  const int side = 30, n = side * side * side, k = 12;
  LabelProblem p;
  p.num_nodes = n;
  p.num_labels = k;
  p.data.assign(static_cast<std::size_t>(n) * k, kInf);
  auto id = [&](int x, int y, int z) { return (x * side + y) * side + z; };
  const std::vector<Vec3> dirs = fibonacci_directions(k);
  for (int l = 0; l < k; ++l)
    for (int x = 0; x < side; ++x)
      for (int y = 0; y < side; ++y)
        for (int z = 0; z < side; ++z) {
          const double s = Vec3(x - 14.5, y - 14.5, z - 14.5).dot(dirs[l]) + 5.0;
          if (s > 0) p.data[static_cast<std::size_t>(l) * n + id(x, y, z)] = std::exp(-s / 8.0);
        }
  for (int x = 0; x < side; ++x)
    for (int y = 0; y < side; ++y)
      for (int z = 0; z < side; ++z) {
        if (x + 1 < side) p.edges.push_back({id(x, y, z), id(x + 1, y, z), 0.5});
        if (y + 1 < side) p.edges.push_back({id(x, y, z), id(x, y + 1, z), 0.5});
        if (z + 1 < side) p.edges.push_back({id(x, y, z), id(x, y, z + 1), 0.5});
      }
  p.label_cost.assign(k, 50.0);
  const std::vector<std::int32_t> many = minimize_labeling(p, 9, 4);
  const double e = labeling_energy(p, many);
  ASSERT_TRUE(std::isfinite(e));
  // Far better than the best single-label-per-node start could be: at most a few labels.
  EXPECT_LE(std::set<std::int32_t>(many.begin(), many.end()).size(), 6u);
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  EXPECT_EQ(minimize_labeling(p, 9, 4), many);
}

TEST(MinimizeLabeling, RejectsMalformedProblems) {
  LabelProblem p;
  p.num_nodes = 2;
  p.num_labels = 2;
  p.data = {1.0, 1.0, kInf, 1.0};
  p.label_cost = {0.0, 0.0};
  p.edges = {{0, 1, 1.0}};
  EXPECT_NO_THROW(minimize_labeling(p, 1, 1));
  LabelProblem bad = p;
  bad.edges[0].weight = -1.0;
  EXPECT_THROW(minimize_labeling(bad, 1, 1), Error);
  bad = p;
  bad.edges[0].b = 2;
  EXPECT_THROW(minimize_labeling(bad, 1, 1), Error);
  bad = p;
  bad.data = {kInf, 1.0, kInf, 1.0};  // node 0 has no allowed label
  EXPECT_THROW(minimize_labeling(bad, 1, 1), Error);
  bad = p;
  bad.data.pop_back();
  EXPECT_THROW(minimize_labeling(bad, 1, 1), Error);
  EXPECT_THROW(minimize_labeling(p, 1, 0), Error);
  EXPECT_EQ(labeling_energy(p, {1, 1}), kInf);  // node 0 may not take label 1
  EXPECT_DOUBLE_EQ(labeling_energy(p, {0, 1}), 1.0 + 1.0 + 1.0);
}

// --- segment() on tet grids ---

// Tets of an nx x ny x nz grid of cubes of side h_mm, six per cube along the main diagonal.
TetMesh grid_tets(int nx, int ny, int nz, double h_mm) {
  auto coords = [h_mm](int cells) {
    std::vector<double> c;
    for (int i = 0; i <= cells; ++i) c.push_back(i * h_mm);
    return c;
  };
  return test::grid_tets(coords(nx), coords(ny), coords(nz), [](int, int, int) { return true; });
}

Vec3 barycentre(const TetMesh& m, std::int32_t t) {
  Vec3 c = Vec3::Zero();
  for (std::int32_t v : m.tets[t]) c += m.vertices[v];
  return c / 4.0;
}

// A field where direction d is feasible exactly where feasible(d, barycentre) holds.
AccessibilityField field_of(const TetMesh& m, int dirs,
                            const std::function<bool(int, const Vec3&)>& feasible) {
  AccessibilityField f;
  const auto n = static_cast<std::int32_t>(m.tets.size());
  f.feasible = DirectionBits(n, dirs);
  for (std::int32_t t = 0; t < n; ++t)
    for (int d = 0; d < dirs; ++d) f.feasible.set(t, d, feasible(d, barycentre(m, t)));
  f.eroded = f.feasible;
  return f;
}

std::int32_t num_tets(const TetMesh& m) { return static_cast<std::int32_t>(m.tets.size()); }

TEST(Segment, TwoOverlappingHalvesMeetInTheMiddle) {
  // 40 mm long bar; direction 0 is feasible for x < 24, direction 1 for x > 16. The data cost
  // pushes each label away from its infeasible side, so the cut lands in the middle.
  const TetMesh bar = grid_tets(20, 5, 5, 2.0);
  const AccessibilityField f =
      field_of(bar, 2, [](int d, const Vec3& p) { return d == 0 ? p.x() < 24.0 : p.x() > 16.0; });
  const Labeling l = segment(bar, f, {}, {.c_mm = 5.0, .restarts = 3});
  // Every candidate is returned, ranked: fewest parts first, and the chosen one leads.
  ASSERT_GE(l.candidates.size(), 3u);
  EXPECT_EQ(l.candidates.front().label, l.label);
  EXPECT_EQ(l.candidates.front().restart, l.best_restart);
  for (std::size_t i = 1; i < l.candidates.size(); ++i)
    EXPECT_LE(l.candidates[i - 1].parts, l.candidates[i].parts);
  EXPECT_EQ(l.num_components, 2);
  EXPECT_EQ(l.num_labels, 2);
  EXPECT_EQ(l.candidate_labels, 2);
  for (std::int32_t t = 0; t < num_tets(bar); ++t) {
    const double x = barycentre(bar, t).x();
    if (x < 18.0) {
      EXPECT_EQ(l.label[t], 0) << "x = " << x;
    } else if (x > 22.0) {
      EXPECT_EQ(l.label[t], 1) << "x = " << x;
    }
  }
  // The boundary is one plane x = const between two layers of cubes: the label of a tet
  // depends only on the layer of its cube.
  std::map<int, std::set<std::int32_t>> labels_of_layer;
  for (std::int32_t t = 0; t < num_tets(bar); ++t)
    labels_of_layer[static_cast<int>(barycentre(bar, t).x() / 2.0)].insert(l.label[t]);
  for (const auto& [layer, labels] : labels_of_layer) EXPECT_EQ(labels.size(), 1u) << layer;
}

TEST(Segment, AThirdLabelThatOnlyLowersTheDataCostIsSharedOut) {
  // 48 mm bar: direction 0 is feasible for x < 26, 1 for x > 22, 2 for 12 < x < 36. Around
  // x = 24, direction 2 is farthest from its infeasible region, so with a strong data cost eq. 1
  // prefers three parts (0 | 2 | 1); two (0 | 1) are possible, and fewest parts wins.
  const TetMesh bar = grid_tets(24, 4, 4, 2.0);
  const AccessibilityField f = field_of(bar, 3, [](int d, const Vec3& p) {
    return d == 0 ? p.x() < 26.0 : d == 1 ? p.x() > 22.0 : p.x() > 12.0 && p.x() < 36.0;
  });
  const SegmentOptions opts{.alpha = 50.0, .c_mm = 5.0, .restarts = 3};
  const Labeling l = segment(bar, f, {}, opts);
  EXPECT_EQ(l.num_components, 2);
  EXPECT_EQ(l.num_labels, 2);
  for (std::int32_t t = 0; t < num_tets(bar); ++t) {
    ASSERT_TRUE(f.feasible.get(t, l.label[t]));
    EXPECT_NE(l.label[t], 2);
  }
  // The three-part labeling that eq. 1 prefers: the reported energy is above it.
  LabelProblem p;
  p.num_nodes = num_tets(bar);
  p.num_labels = 3;
  p.data.assign(3 * static_cast<std::size_t>(p.num_nodes), kInf);
  for (int d = 0; d < 3; ++d) {
    const std::vector<float> dist = InfeasibleDistance(bar)(f.feasible, d, 4.0 * opts.c_mm);
    for (std::int32_t t = 0; t < p.num_nodes; ++t)
      if (f.feasible.get(t, d))
        p.data[d * p.num_nodes + t] =
            tet_volume(bar, t) * opts.alpha * std::exp(-dist[t] * dist[t] / (2.0 * 25.0));
  }
  for (std::int32_t t = 0; t < p.num_nodes; ++t)
    for (int k = 0; k < 4; ++k)
      if (bar.neighbors[t][k] > t)
        p.edges.push_back({t, bar.neighbors[t][k], opts.beta_mm * tet_face_area(bar, t, k)});
  p.label_cost.assign(3, opts.lambda * total_volume(bar));
  std::vector<std::int32_t> three(p.num_nodes);
  for (std::int32_t t = 0; t < p.num_nodes; ++t) {
    const double x = barycentre(bar, t).x();
    three[t] = x < 16.0 ? 0 : x > 32.0 ? 1 : 2;
  }
  EXPECT_NEAR(l.energy, labeling_energy(p, l.label), 1e-6 * l.energy);
  EXPECT_LT(labeling_energy(p, three), l.energy);
}

TEST(Segment, DuplicateAndDominatedDirectionsAreNotCandidates) {
  const TetMesh cube = grid_tets(6, 6, 6, 2.0);
  // 0: everywhere; 1: same as 0; 2: a strict subset of 0; 3: nowhere; 4: x < 6 (a subset too).
  const AccessibilityField f = field_of(cube, 5, [](int d, const Vec3& p) {
    return d == 0 || d == 1 || (d == 2 && p.y() > 4.0) || (d == 4 && p.x() < 6.0);
  });
  const Labeling l = segment(cube, f, {}, {.restarts = 2});
  EXPECT_EQ(l.candidate_labels, 1);
  EXPECT_EQ(l.num_labels, 1);
  EXPECT_EQ(l.num_components, 1);
  for (std::int32_t label : l.label) EXPECT_EQ(label, 0);
  // Two overlapping sets, neither inside the other: both are candidates.
  const AccessibilityField g = field_of(cube, 3, [](int d, const Vec3& p) {
    return (d == 0 && p.x() < 8.0) || (d == 1 && p.x() > 4.0) || (d == 2 && p.x() > 6.0);
  });
  EXPECT_EQ(segment(cube, g, {}, {.restarts = 2}).candidate_labels, 2);
}

TEST(Segment, TetsFeasibleForNoDirectionAreUnlabeled) {
  const TetMesh bar = grid_tets(12, 3, 3, 2.0);
  const AccessibilityField f =
      field_of(bar, 2, [](int d, const Vec3& p) { return d == 0 ? p.x() < 10.0 : p.x() > 14.0; });
  const Labeling l = segment(bar, f, {}, {.restarts = 2});
  for (std::int32_t t = 0; t < num_tets(bar); ++t) {
    const double x = barycentre(bar, t).x();
    EXPECT_EQ(l.label[t], x < 10.0 ? 0 : x > 14.0 ? 1 : -1) << "x = " << x;
  }
  EXPECT_EQ(l.num_components, 2);  // the unlabeled slab separates the two parts
}

TEST(Segment, NothingFeasibleGivesNoLabels) {
  const TetMesh cube = grid_tets(2, 2, 2, 1.0);
  const Labeling l = segment(cube, field_of(cube, 3, [](int, const Vec3&) { return false; }), {});
  EXPECT_EQ(l.candidate_labels, 0);
  EXPECT_EQ(l.num_components, 0);
  for (std::int32_t label : l.label) EXPECT_EQ(label, -1);
}

TEST(Segment, RejectsBadOptions) {
  const TetMesh cube = grid_tets(2, 2, 2, 1.0);
  const AccessibilityField f = field_of(cube, 1, [](int, const Vec3&) { return true; });
  EXPECT_THROW(segment(cube, f, {}, {.restarts = 0}), Error);
  EXPECT_THROW(segment(cube, f, {}, {.lambda = -1.0}), Error);
  EXPECT_THROW(segment(cube, f, {}, {.beta_mm = -1.0}), Error);
  EXPECT_THROW(segment(cube, f, {}, {.c_mm = 0.0}), Error);
  EXPECT_THROW(segment(grid_tets(1, 1, 1, 1.0), f, {}), Error);  // field of another mesh
}

// Checks a labeling against its field, and returns the parts recounted independently.
void expect_consistent(const TetMesh& tets, const AccessibilityField& f, const Labeling& l) {
  std::set<std::int32_t> used;
  for (std::int32_t t = 0; t < num_tets(tets); ++t) {
    if (f.feasible.count(t) == 0) {
      ASSERT_EQ(l.label[t], -1);
      continue;
    }
    ASSERT_GE(l.label[t], 0);
    ASSERT_TRUE(f.feasible.get(t, l.label[t])) << "tet " << t << " got an infeasible direction";
    used.insert(l.label[t]);
  }
  EXPECT_EQ(l.num_labels, static_cast<std::int32_t>(used.size()));
  EXPECT_GE(l.num_components, l.num_labels);
}

// --- the part reduction keeps every label one stretch per line ---

TEST(ReduceParts, RefusesAMergeThatPutsAPartBetweenTwoPiecesOfALabel) {
  // Nodes 0, 1, 2 lie on one line, in that order; node 3 lies beside it, touching 0 and 2.
  // Labels: 0 and 3 take A (one part), 1 takes B, 2 takes C and would also allow A. Merging
  // C's part into A makes the line meet A, leave it at B and meet it again.
  constexpr std::int32_t A = 0, B = 1, C = 2;
  LabelProblem p;
  p.num_nodes = 4;
  p.num_labels = 3;
  p.data.assign(12, kInf);
  const auto allow = [&](std::int32_t node, std::int32_t label) { p.data[label * 4 + node] = 0.0; };
  allow(0, A), allow(1, B), allow(2, C), allow(2, A), allow(3, A);
  p.edges = {{0, 1, 1.0}, {1, 2, 1.0}, {2, 3, 1.0}, {3, 0, 1.0}};
  p.label_cost.assign(3, 0.0);
  const std::vector<std::array<std::int32_t, 4>> faces = {
      {1, 3, -1, -1}, {0, 2, -1, -1}, {1, 3, -1, -1}, {0, 2, -1, -1}};
  const std::vector<Vec3> centres = {{0, 0, 0}, {0, 0, 1}, {0, 0, 2}, {1, 0, 1}};
  const LineSteps column{.up = {1, 2, -1, -1}, .down = {-1, 0, 1, -1}};

  std::vector<std::int32_t> without_lines = {A, B, C, A};
  detail::PartReducer(p, faces, {1.0, 1.0, 1.0, 1.0}, centres).reduce(without_lines, 1);
  EXPECT_EQ(without_lines, (std::vector<std::int32_t>{A, B, A, A}));  // the move exists

  p.line_steps = [&](std::int32_t) -> const LineSteps& { return column; };
  std::vector<std::int32_t> with_lines = {A, B, C, A};
  detail::PartReducer(p, faces, {1.0, 1.0, 1.0, 1.0}, centres).reduce(with_lines, 1);
  EXPECT_EQ(with_lines, (std::vector<std::int32_t>{A, B, C, A}));
}

TEST(SegmentRealMesh, ElephantGivesFewFeasiblePartsWhateverTheThreadCount) {
  const std::string path = test::cgal_mesh("elephant.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set not installed";
  const TriMesh elephant = test::load_scaled(path, 100.0);
  const TetMesh tets = tetrahedralize(elephant, {.target_tets = 15000});
  const std::vector<Vec3> directions = fibonacci_directions(128);
  const AccessibilityField f = compute_accessibility(elephant, tets, directions);
  std::vector<double> seen;
  const Labeling l = segment(tets, f, directions, {}, [&](double x) { seen.push_back(x); });
  expect_consistent(tets, f, l);
  EXPECT_LE(l.candidate_labels, 128);
  EXPECT_LE(l.num_components, 7);  // the paper reports 7 parts for this model
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), 1.0);
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));

  // No part could take a face neighbour's direction: every such merge was made.
  std::vector<std::int32_t> part(tets.tets.size(), -1);
  std::int32_t num_parts = 0;
  for (std::size_t s = 0; s < tets.tets.size(); ++s) {
    if (part[s] >= 0 || l.label[s] < 0) continue;
    std::vector<std::int32_t> stack{static_cast<std::int32_t>(s)};
    part[s] = num_parts;
    while (!stack.empty()) {
      const std::int32_t t = stack.back();
      stack.pop_back();
      for (std::int32_t u : tets.neighbors[t])
        if (u >= 0 && part[u] < 0 && l.label[u] == l.label[t]) {
          part[u] = num_parts;
          stack.push_back(u);
        }
    }
    ++num_parts;
  }
  EXPECT_EQ(num_parts, l.num_components);
  for (std::int32_t p = 0; p < num_parts; ++p) {
    std::set<std::int32_t> neighbour_labels;
    for (std::size_t t = 0; t < tets.tets.size(); ++t)
      if (part[t] == p)
        for (std::int32_t u : tets.neighbors[t])
          if (u >= 0 && part[u] != p && l.label[u] >= 0) neighbour_labels.insert(l.label[u]);
    for (std::int32_t d : neighbour_labels) {
      bool all_feasible = true;
      for (std::size_t t = 0; t < tets.tets.size() && all_feasible; ++t)
        if (part[t] == p) all_feasible = f.feasible.get(static_cast<std::int32_t>(t), d);
      EXPECT_FALSE(all_feasible) << "part " << p << " could merge into direction " << d;
    }
  }

  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const Labeling single = segment(tets, f, directions);
  EXPECT_EQ(single.label, l.label);
  EXPECT_EQ(single.energy, l.energy);
  EXPECT_EQ(single.best_restart, l.best_restart);
}

}  // namespace
}  // namespace dhfcast
