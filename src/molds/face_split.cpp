// The face split between the two mold halves and the parting line's air traps (paper §4.3.2).
#include <maxflow/graph.h>
#include <oneapi/tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "dhfcast/error.h"
#include "dhfcast/tolerance.h"
#include "molds_internal.h"

namespace dhfcast::detail {

namespace {

void on_maxflow_error(const char* message) {
  throw Error(ErrorCode::Internal, std::string("internal error: max-flow: ") + message);
}

// Does a ray from just outside triangle `f` along `dir` run deeper than epsilon into the part?
bool blocked_along(const LineIndex& index, const Vec3& centroid, const Vec3& dir,
                   double epsilon_mm, double hair_mm) {
  auto farther = [&](const Vec3& p) { return index.distance(p) > epsilon_mm; };
  for (const LineInterval& in : robust_line_intervals(index, centroid, dir, hair_mm))
    if (in.end > 0 &&
        deeper_than(centroid, dir, std::max(in.begin, 0.0), in.end, epsilon_mm, farther))
      return true;
  return false;
}

}  // namespace

FaceSplit split_faces(const TriMesh& part, const LineIndex& index, const Vec3& d,
                      double epsilon_mm) {
  const std::size_t n = part.triangles.size();
  const double diag = bounding_box(part.vertices).diagonal();
  const double hair = 1e-6 * std::max(diag, 1.0);
  std::vector<Vec3> normal(n);
  std::vector<double> area(n);
  std::vector<std::uint8_t> access_up(n), access_down(n);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t f) {
    const Tri& t = part.triangles[f];
    const Vec3 &a = part.vertices[t[0]], &b = part.vertices[t[1]], &c = part.vertices[t[2]];
    const Vec3 cross = (b - a).cross(c - a);
    area[f] = 0.5 * cross.norm();
    normal[f] = area[f] > 0 ? Vec3(cross.normalized()) : Vec3::Zero();
    // Start a hair outside the face, so the face itself counts only when the ray enters there.
    const Vec3 start = (a + b + c) / 3.0 + 1e-5 * std::max(diag, 1.0) * normal[f];
    access_up[f] = !blocked_along(index, start, d, epsilon_mm, hair);
    access_down[f] = !blocked_along(index, start, -d, epsilon_mm, hair);
  });

  // Undirected edges -> the triangles on either side.
  std::map<std::pair<std::int32_t, std::int32_t>, std::vector<std::int32_t>> edge_faces;
  for (std::size_t f = 0; f < n; ++f)
    for (int k = 0; k < 3; ++k) {
      std::int32_t u = part.triangles[f][k], v = part.triangles[f][(k + 1) % 3];
      edge_faces[{std::min(u, v), std::max(u, v)}].push_back(static_cast<std::int32_t>(f));
    }
  double mean_edge = 0.0;
  for (const auto& [e, fs] : edge_faces)
    mean_edge += (part.vertices[e.first] - part.vertices[e.second]).norm();
  mean_edge /= std::max<std::size_t>(edge_faces.size(), 1);

  // Data: a triangle accessible one way only must go that way; otherwise it prefers the side
  // its normal faces (cost: its area times the misalignment). Smoothness: a parting line costs
  // its length times the mean edge length, so it does not zigzag across the both-ways band.
  const double total_area = std::accumulate(area.begin(), area.end(), 0.0);
  const double hard = 1e3 * std::max(total_area, 1.0);
  maxflow::Graph<double, double, double> graph(static_cast<int>(n),
                                               static_cast<int>(edge_faces.size()),
                                               &on_maxflow_error);
  graph.add_node(static_cast<int>(n));
  for (std::size_t f = 0; f < n; ++f) {
    const double align = normal[f].dot(d);
    double cost_up = area[f] * 0.5 * (1 - align), cost_down = area[f] * 0.5 * (1 + align);
    if (access_up[f] && !access_down[f]) cost_down += hard;
    if (access_down[f] && !access_up[f]) cost_up += hard;
    // The source side is "up": a node there pays its sink capacity.
    graph.add_tweights(static_cast<int>(f), cost_down, cost_up);
  }
  for (const auto& [e, fs] : edge_faces)
    if (fs.size() == 2) {
      const double w = mean_edge * (part.vertices[e.first] - part.vertices[e.second]).norm();
      graph.add_edge(fs[0], fs[1], w, w);
    }
  graph.maxflow();

  FaceSplit split;
  split.up.resize(n);
  for (std::size_t f = 0; f < n; ++f) {
    split.up[f] = graph.what_segment(static_cast<int>(f)) ==
                  maxflow::Graph<double, double, double>::SOURCE;
    FaceSplitStats& s = split.stats;
    (split.up[f] ? s.up_faces : s.down_faces)++;
    (split.up[f] ? s.up_area_mm2 : s.down_area_mm2) += area[f];
    if (access_up[f] && access_down[f]) s.both_area_mm2 += area[f];
    if (!access_up[f] && !access_down[f]) s.neither_area_mm2 += area[f];
  }
  for (const auto& [e, fs] : edge_faces)
    if (fs.size() == 2 && split.up[fs[0]] != split.up[fs[1]]) {
      split.parting_edges.push_back({e.first, e.second});
      split.stats.parting_line_mm += (part.vertices[e.first] - part.vertices[e.second]).norm();
    }
  return split;
}

std::vector<std::int32_t> trapped_maxima(const TriMesh& part, const FaceSplit& split,
                                         const Vec3& up, double min_prominence_mm) {
  // Vertices of the parting line and their neighbours along it.
  std::map<std::int32_t, std::vector<std::int32_t>> next;
  for (const auto& e : split.parting_edges) {
    next[e[0]].push_back(e[1]);
    next[e[1]].push_back(e[0]);
  }
  // The part's outward normal at each vertex (area-weighted), to tell whether the cavity lies
  // below a maximum (air is trapped) or above it (a hole's rim: the air escapes).
  std::map<std::int32_t, Vec3> vertex_normal;
  for (const auto& [v, ns] : next) vertex_normal.emplace(v, Vec3::Zero());
  for (const Tri& t : part.triangles) {
    const Vec3 area = (part.vertices[t[1]] - part.vertices[t[0]])
                          .cross(part.vertices[t[2]] - part.vertices[t[0]]);
    for (std::int32_t v : t)
      if (auto it = vertex_normal.find(v); it != vertex_normal.end()) it->second += area;
  }

  // 0-dimensional persistence of the height along the line: visit vertices from the highest
  // down; each one starts a component or joins its visited neighbours' components; when two
  // meet, the one with the lower peak dies with prominence peak - here.
  std::vector<std::int32_t> order;
  for (const auto& [v, ns] : next) order.push_back(v);
  auto height = [&](std::int32_t v) { return part.vertices[v].dot(up); };
  std::sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
    return height(a) != height(b) ? height(a) > height(b) : a < b;
  });
  std::map<std::int32_t, std::int32_t> parent, peak;  // union-find over visited vertices
  auto find = [&](std::int32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  auto higher = [&](std::int32_t a, std::int32_t b) {  // peak a above peak b
    return height(a) != height(b) ? height(a) > height(b) : a < b;
  };
  std::vector<std::int32_t> peaks;
  for (std::int32_t v : order) {
    parent[v] = v;
    peak[v] = v;
    for (std::int32_t w : next[v]) {
      if (!parent.count(w)) continue;
      std::int32_t a = find(v), b = find(w);
      if (a == b) continue;
      if (higher(peak[b], peak[a])) std::swap(a, b);
      // b's peak dies here.
      if (peak[b] != v && height(peak[b]) - height(v) >= min_prominence_mm)
        peaks.push_back(peak[b]);
      parent[b] = a;
    }
  }
  for (std::int32_t v : order)
    if (find(v) == v) peaks.push_back(peak[v]);  // each loop's highest point
  std::vector<std::int32_t> trapped;
  for (std::int32_t v : peaks)
    if (vertex_normal.at(v).dot(up) > 0) trapped.push_back(v);
  std::sort(trapped.begin(), trapped.end(), higher);
  return trapped;
}

}  // namespace dhfcast::detail
