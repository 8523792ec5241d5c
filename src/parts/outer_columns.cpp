#include "outer_columns.h"

#include <algorithm>
#include <cmath>

namespace dhfcast::detail {

OuterColumns::OuterColumns(const std::vector<Vec3>& position, const std::vector<Tri>& triangles,
                           const std::vector<std::int32_t>& owner, const Vec3& d)
    : d_(d.normalized()) {
  const auto [u, w] = ProjectedGrid::across(d_);
  u_ = u, w_ = w;
  // Triangles seen edge-on along d are never crossed by a line along d: left out.
  std::vector<std::array<double, 4>> boxes;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const Vec3& a = position[triangles[i][0]];
    const Vec3& b = position[triangles[i][1]];
    const Vec3& c = position[triangles[i][2]];
    const Vec3 n = (b - a).cross(c - a);
    if (!(std::abs(n.dot(d_)) > 1e-12 * n.norm())) continue;
    const Flat& f = flat_.emplace_back(Flat{a, n, a.dot(u_), a.dot(w_), b.dot(u_), b.dot(w_),
                                            c.dot(u_), c.dot(w_), owner[i]});
    boxes.push_back({std::min({f.au, f.bu, f.cu}), std::max({f.au, f.bu, f.cu}),
                     std::min({f.aw, f.bw, f.cw}), std::max({f.aw, f.bw, f.cw})});
  }
  grid_ = ProjectedGrid(boxes, 0.0);
}

std::pair<std::int32_t, std::int32_t> OuterColumns::ends(const Vec3& x) const {
  std::pair<std::int32_t, std::int32_t> out{-1, -1};
  if (flat_.empty()) return out;
  const double pu = x.dot(u_), pw = x.dot(w_);
  double above = INFINITY, below = -INFINITY;
  for (const std::int32_t k : grid_.at(pu, pw)) {
    const Flat& f = flat_[k];
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
