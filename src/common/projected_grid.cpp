#include "dhfcast/projected_grid.h"

#include <algorithm>
#include <cmath>

namespace dhfcast {

ProjectedGrid::ProjectedGrid(const std::vector<std::array<double, 4>>& boxes, double slack) {
  if (boxes.empty()) return;
  double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  for (const auto& b : boxes) {
    xmin = std::min(xmin, b[0] - slack), xmax = std::max(xmax, b[1] + slack);
    ymin = std::min(ymin, b[2] - slack), ymax = std::max(ymax, b[3] + slack);
  }
  const double area = std::max((xmax - xmin) * (ymax - ymin), 1e-12);
  const double cell = std::max({std::sqrt(2.0 * area / static_cast<double>(boxes.size())),
                                std::max(xmax - xmin, ymax - ymin) / 2048.0, 1e-12});
  inv_cell_ = 1.0 / cell;
  x0_ = xmin, y0_ = ymin;
  nx_ = static_cast<std::int32_t>((xmax - xmin) * inv_cell_) + 1;
  ny_ = static_cast<std::int32_t>((ymax - ymin) * inv_cell_) + 1;
  const auto for_cells = [&](const std::array<double, 4>& b, auto&& f) {
    const auto at = [&](double w, double w0, std::int32_t m) {
      return std::clamp(static_cast<std::int32_t>((w - w0) * inv_cell_), 0, m - 1);
    };
    const std::int32_t i0 = at(b[0] - slack, x0_, nx_), i1 = at(b[1] + slack, x0_, nx_);
    const std::int32_t j0 = at(b[2] - slack, y0_, ny_), j1 = at(b[3] + slack, y0_, ny_);
    for (std::int32_t j = j0; j <= j1; ++j)
      for (std::int32_t i = i0; i <= i1; ++i) f(static_cast<std::size_t>(j) * nx_ + i);
  };
  cell_begin_.assign(static_cast<std::size_t>(nx_) * ny_ + 1, 0);
  for (const auto& b : boxes) for_cells(b, [&](std::size_t c) { ++cell_begin_[c + 1]; });
  for (std::size_t c = 1; c < cell_begin_.size(); ++c) cell_begin_[c] += cell_begin_[c - 1];
  items_.resize(cell_begin_.back());
  std::vector<std::int32_t> next(cell_begin_.begin(), cell_begin_.end() - 1);
  for (std::size_t k = 0; k < boxes.size(); ++k)
    for_cells(boxes[k], [&](std::size_t c) { items_[next[c]++] = static_cast<std::int32_t>(k); });
}

std::span<const std::int32_t> ProjectedGrid::at(double x, double y) const {
  const double fx = std::floor((x - x0_) * inv_cell_), fy = std::floor((y - y0_) * inv_cell_);
  if (!(fx >= 0 && fy >= 0 && fx < nx_ && fy < ny_)) return {};
  const std::size_t c = static_cast<std::size_t>(fy) * nx_ + static_cast<std::size_t>(fx);
  return {items_.data() + cell_begin_[c], items_.data() + cell_begin_[c + 1]};
}

}  // namespace dhfcast
