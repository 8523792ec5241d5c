#include "parallel_rays.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "morton.h"

namespace dhfcast::detail {

namespace {
constexpr double kDepthCellsPerTriangle = 8.0;
}  // namespace

TriMesh morton_sorted(const TriMesh& surface) {
  const Box3 box = bounding_box(surface.vertices);
  std::vector<std::pair<std::uint64_t, std::int32_t>> order(surface.triangles.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    const Tri& t = surface.triangles[i];
    const Vec3 c = (surface.vertices[t[0]] + surface.vertices[t[1]] + surface.vertices[t[2]]) / 3.0;
    order[i] = {morton_code(c, box), static_cast<std::int32_t>(i)};
  }
  std::sort(order.begin(), order.end());
  TriMesh sorted;
  sorted.vertices = surface.vertices;
  sorted.triangles.reserve(order.size());
  for (const auto& o : order) sorted.triangles.push_back(surface.triangles[o.second]);
  return sorted;
}

void ParallelRays::project(const TriMesh& surface, const Vec3& dir) {
  surface_ = &surface;
  d_ = dir.normalized();
  const Vec3 helper = std::abs(d_.x()) < 0.6 ? Vec3::UnitX() : Vec3::UnitY();
  u_ = helper.cross(d_).normalized();
  v_ = d_.cross(u_);  // (u, v, d) is right-handed: counter-clockwise in (u, v) means an exit

  // Each vertex is projected once, so the triangles sharing an edge see identical coordinates.
  const std::size_t nv = surface.vertices.size();
  px_.resize(nv), py_.resize(nv), pz_.resize(nv);
  for (std::size_t i = 0; i < nv; ++i) {
    const Vec3& p = surface.vertices[i];
    px_[i] = static_cast<float>(u_.dot(p));
    py_[i] = static_cast<float>(v_.dot(p));
    pz_[i] = static_cast<float>(d_.dot(p));
  }
  const std::size_t nt = surface.triangles.size();
  boxes_.resize(nt);
  float xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  for (std::size_t i = 0; i < nt; ++i) {
    const Tri& t = surface.triangles[i];
    boxes_[i] = {
        std::min({px_[t[0]], px_[t[1]], px_[t[2]]}), std::max({px_[t[0]], px_[t[1]], px_[t[2]]}),
        std::min({py_[t[0]], py_[t[1]], py_[t[2]]}), std::max({py_[t[0]], py_[t[1]], py_[t[2]]})};
    xmin = std::min(xmin, boxes_[i][0]), xmax = std::max(xmax, boxes_[i][1]);
    ymin = std::min(ymin, boxes_[i][2]), ymax = std::max(ymax, boxes_[i][3]);
  }

  // A fine grid for depth bounds, so that surely_accessible() settles most
  // rays, and a coarser one listing triangles for crossings(): a ray there tests ~10 of them.
  depth_grid_.fit(xmin, xmax, ymin, ymax, kDepthCellsPerTriangle * static_cast<double>(nt));
  tri_grid_.fit(xmin, xmax, ymin, ymax, static_cast<double>(nt));
  entry_top_.assign(depth_grid_.size(), -INFINITY);
  exit_bottom_.assign(depth_grid_.size(), INFINITY);
  cell_start_.assign(tri_grid_.size() + 1, 0);
  for (std::size_t k = 0; k < nt; ++k) {
    const Tri& t = surface.triangles[k];
    auto& box = boxes_[k];
    // Twice the projected signed area: negative when the triangle faces the ray (an entry);
    // zero when it is seen edge-on, and then no perturbed ray crosses it.
    const float area2 = (px_[t[1]] - px_[t[0]]) * (py_[t[2]] - py_[t[0]]) -
                        (py_[t[1]] - py_[t[0]]) * (px_[t[2]] - px_[t[0]]);
    if (area2 == 0) {
      box = {1, 0, 1, 0};  // empty: binned nowhere
      continue;
    }
    // Slivers count as both: the sign of their area is not to be trusted.
    const float bw = box[1] - box[0], bh = box[3] - box[2];
    const float sliver = 1e-5f * (bw * bw + bh * bh);
    const float top = area2 < sliver ? std::max({pz_[t[0]], pz_[t[1]], pz_[t[2]]}) : -INFINITY;
    const float bottom = area2 > -sliver ? std::min({pz_[t[0]], pz_[t[1]], pz_[t[2]]}) : INFINITY;
    depth_grid_.for_cells(box, [&](std::size_t c) {
      entry_top_[c] = std::max(entry_top_[c], top);
      exit_bottom_[c] = std::min(exit_bottom_[c], bottom);
    });
    tri_grid_.for_cells(box, [&](std::size_t c) { ++cell_start_[c + 1]; });
  }
  for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_tris_.resize(cell_start_.back());
  for (std::size_t k = 0; k < nt; ++k)
    if (boxes_[k][0] <= boxes_[k][1])
      tri_grid_.for_cells(boxes_[k], [&](std::size_t c) {
        cell_tris_[cell_start_[c]++] = static_cast<std::int32_t>(k);
      });
  // The fill advanced every start to the next cell's: shift back.
  for (std::size_t c = cell_start_.size() - 1; c > 0; --c) cell_start_[c] = cell_start_[c - 1];
  cell_start_[0] = 0;
}

void ParallelRays::Grid::fit(float xmin, float xmax, float ymin, float ymax, double cells) {
  const double w = std::max<double>(xmax - xmin, 1e-9), h = std::max<double>(ymax - ymin, 1e-9);
  const double side = std::sqrt(w * h / std::max(cells, 1.0));
  nx = std::clamp(static_cast<std::int32_t>(w / side) + 1, 1, 8192);
  ny = std::clamp(static_cast<std::int32_t>(h / side) + 1, 1, 8192);
  x0 = xmin;
  y0 = ymin;
  inv_cell = static_cast<float>(1.0 / std::max(w / (nx - 0.5), h / (ny - 0.5)));
}

std::int64_t ParallelRays::Grid::cell_of(float x, float y) const {
  const float fx = (x - x0) * inv_cell, fy = (y - y0) * inv_cell;
  if (!(fx >= 0 && fy >= 0 && fx < nx && fy < ny)) return -1;
  return static_cast<std::int64_t>(fx) * ny + static_cast<std::int64_t>(fy);
}

bool ParallelRays::surely_accessible(const Vec3& origin, double epsilon_mm) const {
  const std::int64_t c =
      depth_grid_.cell_of(static_cast<float>(u_.dot(origin)), static_cast<float>(v_.dot(origin)));
  if (c < 0) return true;
  const double z = d_.dot(origin);
  return z > entry_top_[c] || (z + epsilon_mm >= entry_top_[c] && z + epsilon_mm < exit_bottom_[c]);
}

void ParallelRays::crossings(const Vec3& origin, double merge_tolerance_mm,
                             std::vector<Crossing>& out) const {
  out.clear();
  const float qx = static_cast<float>(u_.dot(origin)), qy = static_cast<float>(v_.dot(origin));
  const std::int64_t c = tri_grid_.cell_of(qx, qy);
  if (c < 0) return;
  const double qz = d_.dot(origin);
  hits_.clear();
  for (std::int32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
    const Tri& t = surface_->triangles[cell_tris_[k]];
    // Edge j (corner j to j + 1) as a x + b y + c, positive inside a counter-clockwise
    // triangle. Computed from its lower vertex index and negated when the edge runs the other
    // way, so the two triangles along an edge get exactly opposite values and exactly one
    // claims a ray through it. A point exactly on the line is moved by (delta, delta^2).
    float e[3];
    int side[3];
    for (int j = 0; j < 3; ++j) {
      const bool flip = t[j] > t[(j + 1) % 3];
      const std::int32_t lo = flip ? t[(j + 1) % 3] : t[j], hi = flip ? t[j] : t[(j + 1) % 3];
      const float a = py_[lo] - py_[hi], b = px_[hi] - px_[lo];
      const float value = a * (qx - px_[lo]) + b * (qy - py_[lo]);
      const int s = value > 0 ? 1 : value < 0 ? -1 : a > 0 ? 1 : a < 0 ? -1 : b > 0 ? 1 : -1;
      e[j] = flip ? -value : value;
      side[j] = flip ? -s : s;
    }
    if (side[0] != side[1] || side[1] != side[2]) continue;
    // Depth by barycentric interpolation: edge j is opposite corner (j + 2) % 3.
    const double sum = static_cast<double>(e[0]) + e[1] + e[2];
    const double z =
        sum != 0 ? (e[1] * static_cast<double>(pz_[t[0]]) + e[2] * static_cast<double>(pz_[t[1]]) +
                    e[0] * static_cast<double>(pz_[t[2]])) /
                       sum
                 : (static_cast<double>(pz_[t[0]]) + pz_[t[1]] + pz_[t[2]]) / 3.0;
    const double depth = z - qz;
    if (depth < -merge_tolerance_mm) continue;
    hits_.push_back({static_cast<float>(std::max(depth, 0.0)), side[0], cell_tris_[k]});
  }
  if (hits_.empty()) return;
  std::sort(hits_.begin(), hits_.end(),
            [](const Hit& a, const Hit& b) { return a.t != b.t ? a.t < b.t : a.id < b.id; });
  for (std::size_t i = 0; i < hits_.size();) {
    std::size_t j = i + 1;
    int net = hits_[i].sign;
    while (j < hits_.size() && hits_[j].t - hits_[j - 1].t <= merge_tolerance_mm)
      net += hits_[j++].sign;
    if (net != 0) out.push_back({static_cast<double>(hits_[i].t), net > 0 ? 1 : -1});
    i = j;
  }
}

}  // namespace dhfcast::detail
