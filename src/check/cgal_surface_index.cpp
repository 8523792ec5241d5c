// SurfaceIndex: the only file of check that includes CGAL.
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <limits>

#include "surface_index.h"

namespace dhfcast::detail {

namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Segment = Kernel::Segment_3;
using Triangle = Kernel::Triangle_3;
using TriangleIterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, TriangleIterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

Point to_point(const Vec3& p) { return Point(p.x(), p.y(), p.z()); }
Vec3 to_vec(const Point& p) { return Vec3(p.x(), p.y(), p.z()); }

// A crossing of the line with the surface: sign -1 enters the solid, +1 leaves it.
struct Crossing {
  double t;
  int sign;
};

// Oblique directions for inside tests: no mesh built on a grid has faces parallel to them.
const std::array<Vec3, 3> kInsideDirections = {Vec3(0.3141, 0.5926, 0.7418).normalized(),
                                               Vec3(-0.6931, 0.4142, 0.5878).normalized(),
                                               Vec3(0.2718, -0.8284, 0.4909).normalized()};
}  // namespace

struct SurfaceIndex::Impl {
  TriMesh mesh;
  Box3 bbox;
  std::vector<Triangle> triangles;
  std::vector<Vec3> normals;  // unnormalized, parallel to triangles
  Tree tree;
  double merge_tolerance = 0.0;  // crossings closer than this along a line are one point

  // Crossings with the segment origin + t * dir, t in [t0, t1], merged and sorted by t.
  std::vector<Crossing> crossings(const Vec3& origin, const Vec3& dir, double t0, double t1) const {
    std::vector<TriangleIterator> hit;
    const Segment segment(to_point(origin + t0 * dir), to_point(origin + t1 * dir));
    tree.all_intersected_primitives(segment, std::back_inserter(hit));
    std::vector<Crossing> raw;
    raw.reserve(hit.size());
    for (TriangleIterator it : hit) {
      const std::size_t i = static_cast<std::size_t>(it - triangles.begin());
      const Vec3& n = normals[i];
      const double nd = n.dot(dir);
      // A triangle containing the line's direction: the crossing, if any, is registered by
      // its neighbours.
      if (std::abs(nd) <= 1e-12 * n.norm()) continue;
      raw.push_back({n.dot(to_vec(triangles[i].vertex(0)) - origin) / nd, nd < 0 ? -1 : 1});
    }
    std::sort(raw.begin(), raw.end(), [](const Crossing& a, const Crossing& b) {
      return a.t != b.t ? a.t < b.t : a.sign < b.sign;
    });
    // Hits of one edge or vertex by several triangles are one crossing when they agree and no
    // crossing when they cancel (a tangent touch).
    std::vector<Crossing> merged;
    for (std::size_t i = 0; i < raw.size();) {
      std::size_t j = i;
      int net = 0;
      while (j < raw.size() && raw[j].t - raw[i].t <= merge_tolerance) net += raw[j++].sign;
      if (net != 0) merged.push_back({raw[i].t, net < 0 ? -1 : 1});
      i = j;
    }
    return merged;
  }

  // Far enough along dir from origin to leave the bounding box on both sides.
  double reach(const Vec3& origin) const {
    return (origin - 0.5 * (bbox.min + bbox.max)).norm() + bbox.diagonal() + 1.0;
  }
};

SurfaceIndex::SurfaceIndex(const TriMesh& mesh) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.mesh = mesh;
  s.bbox = bounding_box(mesh.vertices);
  s.merge_tolerance = 1e-9 * std::max(s.bbox.diagonal(), 1.0);
  s.triangles.reserve(mesh.triangles.size());
  for (const Tri& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3& b = mesh.vertices[t[1]];
    const Vec3& c = mesh.vertices[t[2]];
    const Triangle tri(to_point(a), to_point(b), to_point(c));
    if (tri.is_degenerate()) continue;
    s.triangles.push_back(tri);
    s.normals.push_back((b - a).cross(c - a));
  }
  if (s.triangles.empty()) return;
  s.tree.insert(s.triangles.cbegin(), s.triangles.cend());
  // Build both search structures now: queries run concurrently afterwards.
  s.tree.build();
  s.tree.accelerate_distance_queries();
  s.tree.squared_distance(to_point(s.bbox.min));
}

SurfaceIndex::~SurfaceIndex() = default;
SurfaceIndex::SurfaceIndex(SurfaceIndex&&) noexcept = default;
SurfaceIndex& SurfaceIndex::operator=(SurfaceIndex&&) noexcept = default;

const TriMesh& SurfaceIndex::mesh() const { return impl_->mesh; }
const Box3& SurfaceIndex::bbox() const { return impl_->bbox; }

std::optional<std::vector<Interval>> SurfaceIndex::line_intervals(const Vec3& origin,
                                                                  const Vec3& dir) const {
  std::vector<Interval> out;
  if (impl_->triangles.empty()) return out;
  const double r = impl_->reach(origin);
  const std::vector<Crossing> c = impl_->crossings(origin, dir, -r, r);
  if (c.size() % 2 != 0) return std::nullopt;
  for (std::size_t i = 0; i < c.size(); i += 2) {
    if (c[i].sign != -1 || c[i + 1].sign != 1) return std::nullopt;
    out.push_back({c[i].t, c[i + 1].t});
  }
  return out;
}

std::optional<std::vector<Interval>> SurfaceIndex::ray_intervals(const Vec3& origin,
                                                                 const Vec3& dir) const {
  std::vector<Interval> out;
  if (impl_->triangles.empty()) return out;
  const std::vector<Crossing> c = impl_->crossings(origin, dir, 0.0, impl_->reach(origin));
  std::size_t i = 0;
  if (!c.empty() && c[0].sign == 1) {  // the origin is inside
    out.push_back({0.0, c[0].t});
    i = 1;
  }
  if ((c.size() - i) % 2 != 0) return std::nullopt;
  for (; i < c.size(); i += 2) {
    if (c[i].sign != -1 || c[i + 1].sign != 1) return std::nullopt;
    out.push_back({c[i].t, c[i + 1].t});
  }
  return out;
}

bool SurfaceIndex::contains(const Vec3& p) const {
  const Box3& b = impl_->bbox;
  if ((p.array() < b.min.array()).any() || (p.array() > b.max.array()).any()) return false;
  for (const Vec3& dir : kInsideDirections) {
    const std::optional<std::vector<Interval>> in = ray_intervals(p, dir);
    if (in) return !in->empty() && in->front().begin == 0.0;
  }
  return false;
}

double SurfaceIndex::distance(const Vec3& p) const {
  if (impl_->triangles.empty()) return std::numeric_limits<double>::infinity();
  return std::sqrt(impl_->tree.squared_distance(to_point(p)));
}

double SurfaceIndex::max_distance_along(const Vec3& origin, const Vec3& dir, double t0, double t1,
                                        double step_mm, double stop_above_mm) const {
  const double length = std::max(t1 - t0, 0.0);
  const int n =
      static_cast<int>(std::clamp(std::ceil(length / std::max(step_mm, 1e-12)) + 1.0, 2.0, 256.0));
  double worst = distance(origin + (t0 + 0.5 * length) * dir);
  for (int i = 0; i < n && worst <= stop_above_mm; ++i)
    worst = std::max(worst, distance(origin + (t0 + length * i / (n - 1)) * dir));
  return worst;
}

}  // namespace dhfcast::detail
