#include "outer_columns.h"

#include <algorithm>
#include <cmath>

namespace dhfcast::detail {

OuterColumns::OuterColumns(const std::vector<Vec3>& position, const std::vector<Tri>& triangles,
                           const std::vector<std::int32_t>& owner, const Vec3& d)
    : d_(d.normalized()) {
  u_ = d_.unitOrthogonal();
  w_ = d_.cross(u_);
  // Triangles seen edge-on along d are never crossed by a line along d: left out.
  double u_lo = INFINITY, u_hi = -INFINITY, w_lo = INFINITY, w_hi = -INFINITY;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const Vec3& a = position[triangles[i][0]];
    const Vec3& b = position[triangles[i][1]];
    const Vec3& c = position[triangles[i][2]];
    const Vec3 n = (b - a).cross(c - a);
    if (!(std::abs(n.dot(d_)) > 1e-12 * n.norm())) continue;
    flat_.push_back({a, n, a.dot(u_), a.dot(w_), b.dot(u_), b.dot(w_), c.dot(u_), c.dot(w_),
                     owner[i]});
    for (const Vec3* p : {&a, &b, &c}) {
      u_lo = std::min(u_lo, p->dot(u_)), u_hi = std::max(u_hi, p->dot(u_));
      w_lo = std::min(w_lo, p->dot(w_)), w_hi = std::max(w_hi, p->dot(w_));
    }
  }
  if (flat_.empty()) return;
  // About two triangles per cell: the projected area over the count, bounded in cell count.
  const double area = std::max((u_hi - u_lo) * (w_hi - w_lo), 1e-12);
  cell_ = std::max(std::sqrt(2.0 * area / static_cast<double>(flat_.size())),
                   std::max(u_hi - u_lo, w_hi - w_lo) / 2048.0);
  u0_ = u_lo;
  w0_ = w_lo;
  nu_ = static_cast<std::int32_t>((u_hi - u_lo) / cell_) + 1;
  nw_ = static_cast<std::int32_t>((w_hi - w_lo) / cell_) + 1;
  auto cell_range = [&](const Flat& f, std::int32_t& i0, std::int32_t& i1, std::int32_t& j0,
                        std::int32_t& j1) {
    auto at = [&](double v, double lo, std::int32_t n) {
      return std::clamp(static_cast<std::int32_t>((v - lo) / cell_), 0, n - 1);
    };
    i0 = at(std::min({f.au, f.bu, f.cu}), u0_, nu_), i1 = at(std::max({f.au, f.bu, f.cu}), u0_, nu_);
    j0 = at(std::min({f.aw, f.bw, f.cw}), w0_, nw_), j1 = at(std::max({f.aw, f.bw, f.cw}), w0_, nw_);
  };
  cell_begin_.assign(static_cast<std::size_t>(nu_) * nw_ + 1, 0);
  for (const Flat& f : flat_) {
    std::int32_t i0, i1, j0, j1;
    cell_range(f, i0, i1, j0, j1);
    for (std::int32_t i = i0; i <= i1; ++i)
      for (std::int32_t j = j0; j <= j1; ++j) ++cell_begin_[static_cast<std::size_t>(i) * nw_ + j + 1];
  }
  for (std::size_t c = 1; c < cell_begin_.size(); ++c) cell_begin_[c] += cell_begin_[c - 1];
  cell_triangles_.resize(cell_begin_.back());
  std::vector<std::int32_t> fill(cell_begin_.begin(), cell_begin_.end() - 1);
  for (std::int32_t k = 0; k < static_cast<std::int32_t>(flat_.size()); ++k) {
    std::int32_t i0, i1, j0, j1;
    cell_range(flat_[k], i0, i1, j0, j1);
    for (std::int32_t i = i0; i <= i1; ++i)
      for (std::int32_t j = j0; j <= j1; ++j)
        cell_triangles_[fill[static_cast<std::size_t>(i) * nw_ + j]++] = k;
  }
}

std::pair<std::int32_t, std::int32_t> OuterColumns::ends(const Vec3& x) const {
  std::pair<std::int32_t, std::int32_t> out{-1, -1};
  if (flat_.empty()) return out;
  const double pu = x.dot(u_), pw = x.dot(w_);
  const std::int32_t i = static_cast<std::int32_t>(std::floor((pu - u0_) / cell_));
  const std::int32_t j = static_cast<std::int32_t>(std::floor((pw - w0_) / cell_));
  if (i < 0 || j < 0 || i >= nu_ || j >= nw_) return out;
  const std::size_t c = static_cast<std::size_t>(i) * nw_ + j;
  double above = INFINITY, below = -INFINITY;
  for (std::int32_t k = cell_begin_[c]; k < cell_begin_[c + 1]; ++k) {
    const Flat& f = flat_[cell_triangles_[k]];
    // 2D edge functions: the projected point is inside (or on) the projected triangle when all
    // three have the sign of the triangle's own orientation.
    const double e0 = (f.bu - f.au) * (pw - f.aw) - (f.bw - f.aw) * (pu - f.au);
    const double e1 = (f.cu - f.bu) * (pw - f.bw) - (f.cw - f.bw) * (pu - f.bu);
    const double e2 = (f.au - f.cu) * (pw - f.cw) - (f.aw - f.cw) * (pu - f.cu);
    const bool inside = (e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0);
    if (!inside) continue;
    const double s = f.n.dot(f.a - x) / f.n.dot(d_);
    if (s > 0 && s < above) {
      above = s;
      out.first = f.owner;
    } else if (s < 0 && s > below) {
      below = s;
      out.second = f.owner;
    }
  }
  return out;
}

}  // namespace dhfcast::detail
