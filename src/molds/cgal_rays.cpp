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

#include "dhfcast/projected_grid.h"
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
  // Lines along +-axis (when set) read the triangles of their point's cell of `grid`, whose
  // boxes are grown by far more than rounding: every triangle the exact test accepts is there.
  Vec3 axis = Vec3::Zero(), u, v;
  ProjectedGrid grid;
};

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
  if (axis != Vec3::Zero()) {
    s.axis = axis;
    const auto [u, v] = ProjectedGrid::across(axis);
    s.u = u, s.v = v;
    std::vector<std::array<double, 4>> boxes;
    double largest = 1.0;
    for (const K::Triangle_3& tri : s.triangles) {
      std::array<double, 4>& b = boxes.emplace_back(
          std::array<double, 4>{INFINITY, -INFINITY, INFINITY, -INFINITY});
      for (int k = 0; k < 3; ++k) {
        const Vec3 p(tri.vertex(k).x(), tri.vertex(k).y(), tri.vertex(k).z());
        b[0] = std::min(b[0], p.dot(s.u)), b[1] = std::max(b[1], p.dot(s.u));
        b[2] = std::min(b[2], p.dot(s.v)), b[3] = std::max(b[3], p.dot(s.v));
      }
      largest = std::max({largest, std::abs(b[0]), std::abs(b[1]), std::abs(b[2]), std::abs(b[3])});
    }
    // Rounding of the projections is a few ulps of the coordinates: a generous multiple of it.
    s.grid = ProjectedGrid(boxes, 1e-9 * largest);
  }
}

LineIndex::~LineIndex() = default;
LineIndex::LineIndex(LineIndex&&) noexcept = default;
LineIndex& LineIndex::operator=(LineIndex&&) noexcept = default;

std::optional<std::vector<LineInterval>> LineIndex::line_intervals(const Vec3& origin,
                                                                   const Vec3& dir) const {
  const Impl& s = *impl_;
  const K::Line_3 line(point_of(origin), point_of(origin + dir));
  std::vector<Triangles::const_iterator> hit;
  if (s.axis != Vec3::Zero() && (dir == s.axis || dir == -s.axis)) {
    for (const std::int32_t k : s.grid.at(origin.dot(s.u), origin.dot(s.v))) {
      const auto it = s.triangles.cbegin() + k;
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
