// LineIndex: lines along a part's direction against the part (CGAL AABB tree). One of the two
// files of the mold stage that include CGAL.
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>

#include "molds_internal.h"

namespace dhfcast::detail {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Triangles = std::vector<K::Triangle_3>;
using Primitive = CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

K::Point_3 point_of(const Vec3& p) { return {p.x(), p.y(), p.z()}; }
}  // namespace

struct LineIndex::Impl {
  Triangles triangles;
  std::vector<Vec3> normals;       // area vectors, parallel to triangles
  std::vector<Vec3> first_vertex;  // parallel to triangles
  Tree tree;
  double same_point_mm = 0.0;  // crossings closer than this are one
  // The grid across `axis` (when set): (x, y) = (p.u, p.v), cells of side 1 / inv_cell from
  // (x0, y0); the triangles whose projected box, grown by `slack`, meets cell c are
  // cell_tris[cell_begin[c] .. cell_begin[c + 1]). The tree answers a line along the axis
  // with the triangles it meets by the exact test, and with a box it meets first: a triangle
  // of the tree's answer has the line's point of the plane within its projected box (up to
  // rounding, which the slack covers), so the grid's cell lists it too.
  Vec3 axis = Vec3::Zero(), u, v;
  double x0 = 0, y0 = 0, inv_cell = 1, slack = 0;
  std::int32_t nx = 0, ny = 0;
  std::vector<std::int32_t> cell_begin, cell_tris;

  std::int64_t cell_of(double x, double y) const {
    const double fx = (x - x0) * inv_cell, fy = (y - y0) * inv_cell;
    if (!(fx >= 0 && fy >= 0 && fx < nx && fy < ny)) return -1;
    return static_cast<std::int64_t>(fy) * nx + static_cast<std::int64_t>(fx);
  }
  void bin(const Vec3& along);
};

void LineIndex::Impl::bin(const Vec3& along) {
  axis = along;
  u = along.unitOrthogonal();
  v = along.cross(u);
  const std::size_t n = triangles.size();
  std::vector<std::array<double, 4>> box(n);  // x min, x max, y min, y max
  double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    box[i] = {INFINITY, -INFINITY, INFINITY, -INFINITY};
    for (int k = 0; k < 3; ++k) {
      const K::Point_3& p = triangles[i].vertex(k);
      const Vec3 q(p.x(), p.y(), p.z());
      box[i][0] = std::min(box[i][0], q.dot(u)), box[i][1] = std::max(box[i][1], q.dot(u));
      box[i][2] = std::min(box[i][2], q.dot(v)), box[i][3] = std::max(box[i][3], q.dot(v));
    }
    xmin = std::min(xmin, box[i][0]), xmax = std::max(xmax, box[i][1]);
    ymin = std::min(ymin, box[i][2]), ymax = std::max(ymax, box[i][3]);
  }
  if (n == 0) return;
  // Rounding of the projections is a few ulps of the coordinates; a generous multiple of it.
  slack = 1e-9 * std::max({std::abs(xmin), std::abs(xmax), std::abs(ymin), std::abs(ymax), 1.0});
  // About two triangles per cell.
  const double side =
      std::max(std::sqrt((xmax - xmin) * (ymax - ymin) / (0.5 * static_cast<double>(n))), 1e-9);
  inv_cell = 1.0 / side;
  x0 = xmin - 2 * slack, y0 = ymin - 2 * slack;
  nx = std::max(1, static_cast<std::int32_t>(std::ceil((xmax - x0 + 2 * slack) * inv_cell)));
  ny = std::max(1, static_cast<std::int32_t>(std::ceil((ymax - y0 + 2 * slack) * inv_cell)));
  const auto cells = [&](std::size_t i, auto&& f) {
    const auto at = [&](double w, double w0, std::int32_t m) {
      return std::clamp(static_cast<std::int32_t>((w - w0) * inv_cell), 0, m - 1);
    };
    const std::int32_t i0 = at(box[i][0] - slack, x0, nx), i1 = at(box[i][1] + slack, x0, nx);
    const std::int32_t j0 = at(box[i][2] - slack, y0, ny), j1 = at(box[i][3] + slack, y0, ny);
    for (std::int32_t j = j0; j <= j1; ++j)
      for (std::int32_t k = i0; k <= i1; ++k) f(static_cast<std::size_t>(j) * nx + k);
  };
  cell_begin.assign(static_cast<std::size_t>(nx) * ny + 1, 0);
  for (std::size_t i = 0; i < n; ++i) cells(i, [&](std::size_t c) { ++cell_begin[c + 1]; });
  for (std::size_t c = 1; c < cell_begin.size(); ++c) cell_begin[c] += cell_begin[c - 1];
  cell_tris.resize(cell_begin.back());
  std::vector<std::int32_t> next(cell_begin.begin(), cell_begin.end() - 1);
  for (std::size_t i = 0; i < n; ++i)
    cells(i, [&](std::size_t c) { cell_tris[next[c]++] = static_cast<std::int32_t>(i); });
}

LineIndex::LineIndex(const TriMesh& mesh, const Vec3& axis) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.same_point_mm = 1e-9 * std::max(bounding_box(mesh.vertices).diagonal(), 1.0);
  for (const Tri& t : mesh.triangles) {
    const Vec3 &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    K::Triangle_3 tri(point_of(a), point_of(b), point_of(c));
    if (tri.is_degenerate()) continue;
    s.triangles.push_back(tri);
    s.normals.push_back((b - a).cross(c - a));
    s.first_vertex.push_back(a);
  }
  s.tree.insert(s.triangles.cbegin(), s.triangles.cend());
  // Both search structures now, so that concurrent queries only read.
  s.tree.build();
  s.tree.accelerate_distance_queries();
  if (axis != Vec3::Zero()) s.bin(axis);
}

LineIndex::~LineIndex() = default;
LineIndex::LineIndex(LineIndex&&) noexcept = default;
LineIndex& LineIndex::operator=(LineIndex&&) noexcept = default;

std::optional<std::vector<LineInterval>> LineIndex::line_intervals(const Vec3& origin,
                                                                   const Vec3& dir) const {
  const Impl& s = *impl_;
  const K::Line_3 line(point_of(origin), point_of(origin + dir));
  std::vector<Triangles::const_iterator> hit;
  if (s.nx > 0 && (dir == s.axis || dir == -s.axis)) {
    const std::int64_t c = s.cell_of(origin.dot(s.u), origin.dot(s.v));
    if (c >= 0)
      for (std::int32_t k = s.cell_begin[c]; k < s.cell_begin[c + 1]; ++k) {
        const auto it = s.triangles.cbegin() + s.cell_tris[k];
        if (CGAL::do_intersect(line, *it)) hit.push_back(it);
      }
  } else {
    s.tree.all_intersected_primitives(line, std::back_inserter(hit));
  }
  // (t, +1 leaving / -1 entering)
  std::vector<std::pair<double, int>> raw;
  for (auto it : hit) {
    const auto i = static_cast<std::size_t>(it - s.triangles.cbegin());
    const double nd = s.normals[i].dot(dir);
    if (std::abs(nd) <= 1e-12 * s.normals[i].norm()) return std::nullopt;  // in the face's plane
    raw.emplace_back(s.normals[i].dot(s.first_vertex[i] - origin) / nd, nd > 0 ? 1 : -1);
  }
  std::sort(raw.begin(), raw.end());
  std::vector<LineInterval> out;
  bool inside = false;
  for (std::size_t i = 0; i < raw.size();) {
    // Several triangles meeting at the crossing point (an edge or vertex) count once when they
    // agree and not at all when they cancel (a tangent touch).
    int net = 0;
    std::size_t j = i;
    for (; j < raw.size() && raw[j].first - raw[i].first <= s.same_point_mm; ++j)
      net += raw[j].second;
    if (net < 0) {
      if (inside) return std::nullopt;
      out.push_back({raw[i].first, raw[i].first});
      inside = true;
    } else if (net > 0) {
      if (!inside) return std::nullopt;
      out.back().end = raw[i].first;
      inside = false;
    }
    i = j;
  }
  if (inside) return std::nullopt;
  return out;
}

double LineIndex::distance(const Vec3& p) const {
  return std::sqrt(impl_->tree.squared_distance(point_of(p)));
}

std::vector<LineInterval> robust_line_intervals(const LineIndex& index, const Vec3& origin,
                                                const Vec3& dir, double hair_mm) {
  Vec3 a = dir.unitOrthogonal();
  const Vec3 b = dir.cross(a).normalized();
  const Vec3 shifts[] = {Vec3::Zero(), hair_mm * a, hair_mm * (0.6 * a + 0.8 * b),
                         hair_mm * (-0.28 * a + 0.96 * b)};
  for (const Vec3& shift : shifts)
    if (auto in = index.line_intervals(origin + shift, dir)) return *in;
  return {};
}

}  // namespace dhfcast::detail
