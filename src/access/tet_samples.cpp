#include "tet_samples.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <numeric>

#include "morton.h"

namespace dhfcast::detail {

namespace {

// Sorts the samples in [begin, end) along a Morton curve, so that consecutive rays start close
// together and traverse the same BVH nodes. Returns old index -> new index for that range.
std::vector<std::int32_t> morton_order(std::vector<Vec3>& points, std::int32_t begin,
                                       std::int32_t end, const Box3& box) {
  const std::int32_t n = end - begin;
  std::vector<std::uint64_t> code(n);
  for (std::int32_t i = 0; i < n; ++i) code[i] = morton_code(points[begin + i], box);
  std::vector<std::int32_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::int32_t a, std::int32_t b) { return code[a] < code[b]; });
  std::vector<Vec3> sorted(n);
  std::vector<std::int32_t> new_index(n);
  for (std::int32_t i = 0; i < n; ++i) {
    sorted[i] = points[begin + order[i]];
    new_index[order[i]] = begin + i;
  }
  std::copy(sorted.begin(), sorted.end(), points.begin() + begin);
  return new_index;
}

constexpr std::array<std::array<int, 2>, 6> kTetEdges = {
    {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};

}  // namespace

TetSamples tet_samples(const TetMesh& tets) {
  const std::int32_t num_tets = static_cast<std::int32_t>(tets.tets.size());
  TetSamples s;
  s.of_tet.resize(num_tets);

  // Unique vertices, edges and faces in sorted-key order.
  std::vector<std::int32_t> verts;
  std::vector<std::array<std::int32_t, 2>> edges;
  std::vector<std::array<std::int32_t, 3>> faces;
  verts.reserve(4 * num_tets);
  edges.reserve(6 * num_tets);
  faces.reserve(4 * num_tets);
  for (const Tet& t : tets.tets) {
    for (int i = 0; i < 4; ++i) verts.push_back(t[i]);
    for (const auto& e : kTetEdges)
      edges.push_back({std::min(t[e[0]], t[e[1]]), std::max(t[e[0]], t[e[1]])});
    for (const auto& f : kTetFaces) {
      std::array<std::int32_t, 3> k{t[f[0]], t[f[1]], t[f[2]]};
      std::sort(k.begin(), k.end());
      faces.push_back(k);
    }
  }
  auto make_unique = [](auto& v) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  };
  make_unique(verts);
  make_unique(edges);
  make_unique(faces);

  const auto& x = tets.vertices;
  s.kind_begin[kVertexSample] = 0;
  for (std::int32_t v : verts) s.points.push_back(x[v]);
  s.kind_begin[kEdgeSample] = static_cast<std::int32_t>(s.points.size());
  for (const auto& e : edges) s.points.push_back(0.5 * (x[e[0]] + x[e[1]]));
  s.kind_begin[kFaceSample] = static_cast<std::int32_t>(s.points.size());
  for (const auto& f : faces) s.points.push_back((x[f[0]] + x[f[1]] + x[f[2]]) / 3.0);
  s.kind_begin[kTetSample] = static_cast<std::int32_t>(s.points.size());
  for (const Tet& t : tets.tets) s.points.push_back(0.25 * (x[t[0]] + x[t[1]] + x[t[2]] + x[t[3]]));
  s.kind_begin[kNumSampleKinds] = static_cast<std::int32_t>(s.points.size());

  // Sample ids before reordering, by key lookup.
  tbb::parallel_for(std::int32_t{0}, num_tets, [&](std::int32_t ti) {
    const Tet& t = tets.tets[ti];
    auto& slots = s.of_tet[ti];
    for (int i = 0; i < 4; ++i)
      slots[i] = static_cast<std::int32_t>(std::lower_bound(verts.begin(), verts.end(), t[i]) -
                                           verts.begin());
    for (int i = 0; i < 6; ++i) {
      const std::array<std::int32_t, 2> k{std::min(t[kTetEdges[i][0]], t[kTetEdges[i][1]]),
                                          std::max(t[kTetEdges[i][0]], t[kTetEdges[i][1]])};
      slots[4 + i] = s.kind_begin[kEdgeSample] +
                     static_cast<std::int32_t>(std::lower_bound(edges.begin(), edges.end(), k) -
                                               edges.begin());
    }
    for (int i = 0; i < 4; ++i) {
      std::array<std::int32_t, 3> k{t[kTetFaces[i][0]], t[kTetFaces[i][1]], t[kTetFaces[i][2]]};
      std::sort(k.begin(), k.end());
      slots[10 + i] = s.kind_begin[kFaceSample] +
                      static_cast<std::int32_t>(std::lower_bound(faces.begin(), faces.end(), k) -
                                                faces.begin());
    }
    slots[14] = s.kind_begin[kTetSample] + ti;
  });

  const Box3 box = bounding_box(s.points);
  for (int k = 0; k < kNumSampleKinds; ++k) {
    const std::int32_t begin = s.kind_begin[k];
    const std::vector<std::int32_t> new_index =
        morton_order(s.points, begin, s.kind_begin[k + 1], box);
    for (auto& slots : s.of_tet)
      for (int i = kSlotBegin[k]; i < kSlotBegin[k + 1]; ++i)
        slots[i] = new_index[slots[i] - begin];
  }
  return s;
}

}  // namespace dhfcast::detail
