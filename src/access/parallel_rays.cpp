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
  tris_.resize(nt);
  tri_z_.resize(nt);
  float xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  for (std::size_t i = 0; i < nt; ++i) {
    const Tri& t = surface.triangles[i];
    boxes_[i] = {
        std::min({px_[t[0]], px_[t[1]], px_[t[2]]}), std::max({px_[t[0]], px_[t[1]], px_[t[2]]}),
        std::min({py_[t[0]], py_[t[1]], py_[t[2]]}), std::max({py_[t[0]], py_[t[1]], py_[t[2]]})};
    xmin = std::min(xmin, boxes_[i][0]), xmax = std::max(xmax, boxes_[i][1]);
    ymin = std::min(ymin, boxes_[i][2]), ymax = std::max(ymax, boxes_[i][3]);
  }

  // A fine grid for depth bounds, so that settle() decides most
  // rays, and a coarser one listing triangles for crossings(): a ray there tests ~10 of them.
  depth_grid_.fit(xmin, xmax, ymin, ymax, kDepthCellsPerTriangle * static_cast<double>(nt));
  tri_grid_.fit(xmin, xmax, ymin, ymax, static_cast<double>(nt));
  depth_.assign(depth_grid_.size(), {-INFINITY, INFINITY});
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
    ProjectedTri& pt = tris_[k];
    pt.flip = pt.tie_up = 0;
    for (int j = 0; j < 3; ++j) {
      // From the lower vertex index, so the two triangles along an edge see the same numbers.
      const bool flip = t[j] > t[(j + 1) % 3];
      const std::int32_t lo = flip ? t[(j + 1) % 3] : t[j], hi = flip ? t[j] : t[(j + 1) % 3];
      pt.a[j] = py_[lo] - py_[hi];
      pt.b[j] = px_[hi] - px_[lo];
      pt.x[j] = px_[lo];
      pt.y[j] = py_[lo];
      tri_z_[k][j] = pz_[t[j]];
      const bool up = pt.a[j] > 0 || (!(pt.a[j] < 0) && pt.b[j] > 0);
      pt.flip |= static_cast<std::uint32_t>(flip) << j;
      pt.tie_up |= static_cast<std::uint32_t>(up) << j;
    }
    // Slivers count as both: the sign of their area is not to be trusted.
    const float bw = box[1] - box[0], bh = box[3] - box[2];
    const float sliver = 1e-5f * (bw * bw + bh * bh);
    if (area2 < sliver) {
      const float top = std::max({pz_[t[0]], pz_[t[1]], pz_[t[2]]});
      depth_grid_.for_rows(box, [&, top](std::size_t first, std::size_t n) {
        DepthBounds* row = depth_.data() + first;
        for (std::size_t j = 0; j < n; ++j) row[j].entry_top = std::max(row[j].entry_top, top);
      });
    }
    if (area2 > -sliver) {
      const float bottom = std::min({pz_[t[0]], pz_[t[1]], pz_[t[2]]});
      depth_grid_.for_rows(box, [&, bottom](std::size_t first, std::size_t n) {
        DepthBounds* row = depth_.data() + first;
        for (std::size_t j = 0; j < n; ++j)
          row[j].exit_bottom = std::min(row[j].exit_bottom, bottom);
      });
    }
    tri_grid_.for_rows(box, [&](std::size_t first, std::size_t n) {
      for (std::size_t j = 0; j < n; ++j) ++cell_start_[first + j + 1];
    });
  }
  for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_tris_.resize(cell_start_.back());
  cell_top_.resize(cell_start_.back());
  for (std::size_t k = 0; k < nt; ++k)
    if (boxes_[k][0] <= boxes_[k][1]) {
      const float top = std::max({tri_z_[k][0], tri_z_[k][1], tri_z_[k][2]});
      tri_grid_.for_rows(boxes_[k], [&](std::size_t first, std::size_t n) {
        for (std::size_t c = first; c < first + n; ++c) {
          cell_top_[cell_start_[c]] = top;
          cell_tris_[cell_start_[c]++] = static_cast<std::int32_t>(k);
        }
      });
    }
  // The fill advanced every start to the next cell's: shift back.
  for (std::size_t c = cell_start_.size() - 1; c > 0; --c) cell_start_[c] = cell_start_[c - 1];
  cell_start_[0] = 0;

  float z_scale = 0;
  for (float z : pz_) z_scale = std::max(z_scale, std::abs(z));
  // Far above the round-off of a depth interpolated in double from float corners.
  depth_slack_mm_ = 1e-9 * (1.0 + z_scale);
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

void ParallelRays::settle(const std::vector<Vec3>& points, double epsilon_mm,
                          std::uint8_t* state) const {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3& p = points[i];
    const std::int64_t c =
        depth_grid_.cell_of(static_cast<float>(u_.dot(p)), static_cast<float>(v_.dot(p)));
    bool open = true;
    if (c >= 0) {
      const double z = d_.dot(p);
      const DepthBounds b = depth_[c];
      open = z > b.entry_top || (z + epsilon_mm >= b.entry_top && z + epsilon_mm < b.exit_bottom);
    }
    state[i] = open ? kOpen : kUnknown;
  }
}

void ParallelRays::crossings(const Vec3& origin, double merge_tolerance_mm,
                             std::vector<Crossing>& out) const {
  out.clear();
  const float qx = static_cast<float>(u_.dot(origin)), qy = static_cast<float>(v_.dot(origin));
  const std::int64_t c = tri_grid_.cell_of(qx, qy);
  if (c < 0) return;
  const double qz = d_.dot(origin);
  hits_.clear();
  // Edge j as a x + b y + c, positive inside a counter-clockwise triangle. Computed from its
  // lower vertex index and negated when the edge runs the other way, so the two triangles
  // along an edge get exactly opposite values and exactly one claims a ray through it. A point
  // exactly on the line is moved by (delta, delta^2). Returns whether the point is on the
  // positive side, the value in e.
  auto side = [qx, qy](const ProjectedTri& pt, int j, float& e) {
    const float value = pt.a[j] * (qx - pt.x[j]) + pt.b[j] * (qy - pt.y[j]);
    const bool flip = (pt.flip >> j) & 1;
    const bool tie = (pt.tie_up >> j) & 1;
    const bool up = (value > 0) | ((!(value < 0)) & tie);
    e = flip ? -value : value;
    return up != flip;
  };
  // A triangle's interpolated depth is at most its deepest corner's (plus round-off).
  const double behind = qz - merge_tolerance_mm - depth_slack_mm_;
  // The triangles are scattered in memory: ask for all of them before testing any, so their
  // cache misses overlap.
  for (std::int32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k)
    if (!(cell_top_[k] < behind)) __builtin_prefetch(&tris_[cell_tris_[k]]);
  for (std::int32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
    if (cell_top_[k] < behind) continue;  // wholly behind the origin
    const ProjectedTri& pt = tris_[cell_tris_[k]];
    float e[3];
    const bool s0 = side(pt, 0, e[0]), s1 = side(pt, 1, e[1]), s2 = side(pt, 2, e[2]);
    if (!((s0 == s1) & (s1 == s2))) continue;
    const std::int32_t id = cell_tris_[k];
    // Depth by barycentric interpolation: edge j is opposite corner (j + 2) % 3.
    const std::array<float, 3>& z = tri_z_[id];
    const double sum = static_cast<double>(e[0]) + e[1] + e[2];
    const double zq =
        sum != 0 ? (e[1] * static_cast<double>(z[0]) + e[2] * static_cast<double>(z[1]) +
                    e[0] * static_cast<double>(z[2])) /
                       sum
                 : (static_cast<double>(z[0]) + z[1] + z[2]) / 3.0;
    const double depth = zq - qz;
    if (depth < -merge_tolerance_mm) continue;
    hits_.push_back({static_cast<float>(std::max(depth, 0.0)), s0 ? 1 : -1, id});
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
