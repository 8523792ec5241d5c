// The mold stage: per part, a block split by a height-field parting surface, minus the part, with
// a pour sprue, air vents and registration keys (paper §4.3.2).
#include "dhfcast/molds.h"

#include <oneapi/tbb/parallel_for.h>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cfenv>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <tuple>
#include <utility>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "dhfcast/stop.h"
#include "dhfcast/tolerance.h"
#include "molds_internal.h"

namespace dhfcast {

namespace {

using namespace detail;

constexpr int kGravityCandidates = 24;  // directions orthogonal to d tried as "up"
// Cells along the block's longer side: enough for cells no wider than 1.5 times the undercut
// tolerance (a steep wall loses a band about a cell high between the halves' grid triangles; the
// elephant's body at 160 cells left 1.4 % of its surface unmoulded), within these bounds.
constexpr int kMinGridCells = 160, kMaxGridCells = 320;
constexpr int kChannelSegments = 16;
constexpr int kKeySegments = 32;

// Local frame of a mold: x = up x d, y = up (gravity), w = d.
struct Frame {
  Vec3 x, y, w;
  Vec3 world(const Vec3& local) const { return local.x() * x + local.y() * y + local.z() * w; }
  Vec3 local(const Vec3& p) const { return {p.dot(x), p.dot(y), p.dot(w)}; }
};

void to_world(TriMesh& m, const Frame& f) {
  for (Vec3& p : m.vertices) p = f.world(p);
}

// The parting surface: heights w = h(x, y) on a regular grid over the block's footprint, each cell
// split into two triangles along its (i, j)-(i+1, j+1) diagonal.
struct HeightGrid {
  double x0 = 0, y0 = 0, s = 1;
  int nx = 0, ny = 0;              // cells; nodes are (nx + 1) x (ny + 1)
  std::vector<double> h;           // per node
  std::vector<double> lo, hi;      // per node on the part: the interval the surface is in
  std::vector<std::uint8_t> part;  // per node: 1 the line along d through it meets the part,
                                   // 2 its height is fixed although it does not
  int id(int i, int j) const { return j * (nx + 1) + i; }
  double x(int i) const { return x0 + i * s; }
  double y(int j) const { return y0 + j * s; }
  // The grid triangle under (x, y), clamped to the grid: its nodes and the point's barycentric
  // weights on them.
  struct Spot {
    std::array<int, 3> node{};
    std::array<double, 3> weight{};
  };
  Spot spot(double px, double py) const {
    const double u = std::clamp((px - x0) / s, 0.0, double(nx)),
                 v = std::clamp((py - y0) / s, 0.0, double(ny));
    const int i = std::min(int(u), nx - 1), j = std::min(int(v), ny - 1);
    const double fu = u - i, fv = v - j;
    if (fu >= fv) return {{id(i, j), id(i + 1, j), id(i + 1, j + 1)}, {1 - fu, fu - fv, fv}};
    return {{id(i, j), id(i, j + 1), id(i + 1, j + 1)}, {1 - fv, fv - fu, fu}};
  }
  // The piecewise-linear surface's height at (x, y), clamped to the grid.
  double height(double px, double py) const {
    const Spot p = spot(px, py);
    return p.weight[0] * h[p.node[0]] + p.weight[1] * h[p.node[1]] + p.weight[2] * h[p.node[2]];
  }
};

// Fills the heights of the nodes off the part by harmonic extension (discrete Laplace equation,
// the part's nodes fixed, natural boundary at the block's walls): smooth, and between the part's
// heights, so it stays at least a wall away from the block's top and bottom.
void extend_harmonically(HeightGrid& g) {
  const int n = (g.nx + 1) * (g.ny + 1);
  std::vector<int> unknown(n, -1);
  int m = 0;
  for (int k = 0; k < n; ++k)
    if (!g.part[k]) unknown[k] = m++;
  if (m == 0) return;
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(m);
  for (int j = 0; j <= g.ny; ++j)
    for (int i = 0; i <= g.nx; ++i) {
      const int row = unknown[g.id(i, j)];
      if (row < 0) continue;
      const int ni[4] = {i - 1, i + 1, i, i}, nj[4] = {j, j, j - 1, j + 1};
      double degree = 0;
      for (int q = 0; q < 4; ++q) {
        if (ni[q] < 0 || ni[q] > g.nx || nj[q] < 0 || nj[q] > g.ny) continue;
        degree += 1;
        const int k = g.id(ni[q], nj[q]);
        if (unknown[k] >= 0)
          entries.emplace_back(row, unknown[k], -1.0);
        else
          rhs[row] += g.h[k];
      }
      entries.emplace_back(row, row, degree);
    }
  Eigen::SparseMatrix<double> a(m, m);
  a.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(a);
  if (solver.info() != Eigen::Success)
    throw Error(ErrorCode::Internal, "internal error: parting surface: factorization failed");
  const Eigen::VectorXd x = solver.solve(rhs);
  for (int k = 0; k < n; ++k)
    if (unknown[k] >= 0) g.h[k] = x[unknown[k]];
}

// Near the part's outline the surface must meet the part where its parting line is: a cell
// straddling the outline interpolates between its nodes, so both sides of the outline take the
// height of the nearest parting-line point (clamped into the part on lines meeting it), and the
// surface crosses the outline at the parting line's height instead of cutting a sliver off a
// wedge-shaped rim.
void pin_to_parting_line(HeightGrid& g, const TriMesh& part, const FaceSplit& split,
                         const Frame& frame) {
  // Parting-line points (vertices and edge midpoints) binned by cell.
  std::vector<Vec3> points;
  for (const auto& e : split.parting_edges) {
    const Vec3 a = frame.local(part.vertices[e[0]]), b = frame.local(part.vertices[e[1]]);
    points.push_back(a);
    points.push_back(0.5 * (a + b));
  }
  std::vector<std::vector<std::int32_t>> bins((g.nx + 1) * (g.ny + 1));
  auto cell_of = [&](const Vec3& p, int& i, int& j) {
    i = std::clamp(int(std::floor((p.x() - g.x0) / g.s + 0.5)), 0, g.nx);
    j = std::clamp(int(std::floor((p.y() - g.y0) / g.s + 0.5)), 0, g.ny);
  };
  for (std::size_t k = 0; k < points.size(); ++k) {
    int i, j;
    cell_of(points[k], i, j);
    bins[g.id(i, j)].push_back(static_cast<std::int32_t>(k));
  }
  // Nodes within two cells of the outline (a node whose 5x5 neighbourhood has both kinds).
  const int n = (g.nx + 1) * (g.ny + 1);
  std::vector<double> target(n, std::numeric_limits<double>::quiet_NaN()), near_lo(n),
      near_hi(n);
  tbb::parallel_for(0, n, [&](int k) {
    const int i = k % (g.nx + 1), j = k / (g.nx + 1);
    bool in = false, out = false;
    for (int dj = -2; dj <= 2; ++dj)
      for (int di = -2; di <= 2; ++di) {
        const int a = i + di, b = j + dj;
        if (a < 0 || a > g.nx || b < 0 || b > g.ny) continue;
        (g.part[g.id(a, b)] ? in : out) = true;
      }
    if (!in || !out) return;
    // Off the part, the surface keeps to the nearest part node's interval, so that it does not
    // lie in the plane of a face the parting line runs along.
    if (!g.part[k]) {
      double nearest = INFINITY;
      for (int dj = -2; dj <= 2; ++dj)
        for (int di = -2; di <= 2; ++di) {
          const int a = i + di, b = j + dj;
          if (a < 0 || a > g.nx || b < 0 || b > g.ny || !g.part[g.id(a, b)]) continue;
          if (di * di + dj * dj < nearest) {
            nearest = di * di + dj * dj;
            near_lo[k] = g.lo[g.id(a, b)];
            near_hi[k] = g.hi[g.id(a, b)];
          }
        }
    }
    double best = 9.0 * g.s * g.s;  // search three cells around
    for (int dj = -3; dj <= 3; ++dj)
      for (int di = -3; di <= 3; ++di) {
        const int a = i + di, b = j + dj;
        if (a < 0 || a > g.nx || b < 0 || b > g.ny) continue;
        for (std::int32_t q : bins[g.id(a, b)]) {
          const double dx = points[q].x() - g.x(i), dy = points[q].y() - g.y(j);
          const double d2 = dx * dx + dy * dy;
          if (d2 < best || (d2 == best && points[q].z() < target[k])) {
            best = d2;
            target[k] = points[q].z();
          }
        }
      }
  });
  for (int k = 0; k < n; ++k) {
    if (std::isnan(target[k])) continue;
    // Not on the part's faces themselves: a quarter of the line's way in.
    const double lo = g.part[k] ? g.lo[k] : near_lo[k], hi = g.part[k] ? g.hi[k] : near_hi[k];
    g.h[k] = std::clamp(target[k], lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo));
    if (!g.part[k]) g.part[k] = 2;  // fixed, but off the part
  }
}

// One half of the block: the region between the parting surface and the plane w = w_far (the
// top for the up half, the bottom for the down half), in local coordinates, closed and outward.
TriMesh block_half(const HeightGrid& g, double w_far) {
  TriMesh m;
  for (int j = 0; j <= g.ny; ++j)
    for (int i = 0; i <= g.nx; ++i) m.vertices.emplace_back(g.x(i), g.y(j), g.h[g.id(i, j)]);
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const int a = g.id(i, j), b = g.id(i + 1, j), c = g.id(i + 1, j + 1), e = g.id(i, j + 1);
      m.triangles.push_back({a, b, c});
      m.triangles.push_back({a, c, e});
    }
  // The grid's border, counter-clockwise seen from +w, and the same points on the far plane.
  std::vector<int> border;
  for (int i = 0; i < g.nx; ++i) border.push_back(g.id(i, 0));
  for (int j = 0; j < g.ny; ++j) border.push_back(g.id(g.nx, j));
  for (int i = g.nx; i > 0; --i) border.push_back(g.id(i, g.ny));
  for (int j = g.ny; j > 0; --j) border.push_back(g.id(0, j));
  const auto far0 = static_cast<std::int32_t>(m.vertices.size());
  for (int v : border) {
    Vec3 p = m.vertices[v];
    p.z() = w_far;
    m.vertices.push_back(p);
  }
  const auto centre = static_cast<std::int32_t>(m.vertices.size());
  m.vertices.emplace_back(g.x0 + 0.5 * g.nx * g.s, g.y0 + 0.5 * g.ny * g.s, w_far);
  const auto nb = static_cast<std::int32_t>(border.size());
  for (std::int32_t k = 0; k < nb; ++k) {
    const std::int32_t k1 = (k + 1) % nb;
    // Walls, then the far face as a fan around its centre (it is a convex rectangle).
    m.triangles.push_back({border[k1], border[k], far0 + k});
    m.triangles.push_back({border[k1], far0 + k, far0 + k1});
    m.triangles.push_back({centre, far0 + k1, far0 + k});
  }
  orient_outward(m);
  return m;
}

// A straight channel along y at height w = wc, from y_start to y_end: circular cross-sections
// in the planes y = const, with rings at the grid rows between them (so its faces follow the
// parting surface's cells).
TriMesh channel_tube(const HeightGrid& g, double xc, double wc, double y_start, double y_end,
                     double radius) {
  std::vector<double> stations{y_start};
  for (int j = 0; j <= g.ny; ++j)
    if (g.y(j) > y_start + 0.1 * g.s && g.y(j) < y_end - 0.1 * g.s) stations.push_back(g.y(j));
  stations.push_back(y_end);
  TriMesh m;
  const int n = kChannelSegments;
  for (double y : stations) {
    for (int q = 0; q < n; ++q) {
      const double angle = (q + 0.5) * 2 * std::numbers::pi / n;
      m.vertices.emplace_back(xc + radius * std::cos(angle), y, wc + radius * std::sin(angle));
    }
  }
  const auto rings = static_cast<std::int32_t>(stations.size());
  for (std::int32_t r = 0; r + 1 < rings; ++r)
    for (std::int32_t q = 0; q < n; ++q) {
      const std::int32_t a = r * n + q, b = r * n + (q + 1) % n;
      m.triangles.push_back({a, b, b + n});
      m.triangles.push_back({a, b + n, a + n});
    }
  // Caps: fans from a ring vertex (no centre vertex, which would lie on the parting surface).
  for (std::int32_t q = 1; q + 1 < n; ++q) {
    m.triangles.push_back({0, q + 1, q});
    const std::int32_t last = (rings - 1) * n;
    m.triangles.push_back({last, last + q, last + q + 1});
  }
  orient_outward(m);
  return m;
}

// Makes the surface flat at `height` within `radius` of the line x = xc, y >= y_from (a
// channel's path), so a straight channel at that height straddles it. Nodes on the part keep
// within a quarter of their interval from its ends, as pin_to_parting_line() does.
void flatten_channel(HeightGrid& g, double xc, double y_from, double radius, double height) {
  for (int j = 0; j <= g.ny; ++j) {
    if (g.y(j) < y_from) continue;
    for (int i = 0; i <= g.nx; ++i) {
      const int k = g.id(i, j);
      if (std::abs(g.x(i) - xc) > radius) continue;
      const double margin = 0.25 * (g.hi[k] - g.lo[k]);
      g.h[k] = g.part[k] == 1 ? std::clamp(height, g.lo[k] + margin, g.hi[k] - margin) : height;
    }
  }
}

void flatten_disc(HeightGrid& g, double xc, double yc, double radius, double height) {
  for (int j = 0; j <= g.ny; ++j)
    for (int i = 0; i <= g.nx; ++i)
      if (std::hypot(g.x(i) - xc, g.y(j) - yc) <= radius && g.part[g.id(i, j)] != 1)
        g.h[g.id(i, j)] = height;
}

// A point of the part's footprint where the surfaces bounding the up and the down half are
// held: each surface's height there is the weighted sum of three grid nodes' heights, and must
// be at least up_min (up half) and at most down_max (down half), heights along d in mm.
struct FitPoint : HeightGrid::Spot {
  double up_min = -INFINITY, down_max = INFINITY;
};

// What release asks of the two surfaces on a line meeting the part in `in` (parameters =
// heights along d), where the parting surface is at `parting`: the up half is pulled along +d
// past everything above it, so its surface must be at least the bottom of the topmost
// stretch; the down half's at most the top of the lowest. Gaps between stretches are then left
// to neither half: the cast fills them, where a half holding one could not leave. Within the
// undercut tolerance (no gap deeper than epsilon: the dhf check's rule) that is within epsilon
// of the part; where the part is not a double height field (which the dhf check reports) the
// cast gets a fin there, but the halves still release. A stretch no deeper than epsilon / 2 from
// the part's surface (a line along a wall) asks nothing: a sweep across it does not go deeper than
// epsilon, the molds check's rule, with a margin for lines beside this one. A quarter of epsilon
// inside the stretch, so that float rounding does not move a half's face onto the part's. {up_min,
// down_max}; nullopt when the parting surface already meets both (the fit only raises the up
// surface and lowers the down one). The depth tests run only where a bound would bind.
std::optional<std::pair<double, double>> release_bounds(const std::vector<LineInterval>& in,
                                                        double parting, const LineIndex& index,
                                                        const Vec3& origin, const Vec3& d,
                                                        double epsilon_mm) {
  if (in.empty()) return std::nullopt;
  const double margin = 0.25 * epsilon_mm;
  double up_min = in.back().begin + margin, down_max = in.front().end - margin;
  if (parting >= up_min) up_min = -INFINITY;
  if (parting <= down_max) down_max = INFINITY;
  if (up_min == -INFINITY && down_max == INFINITY) return std::nullopt;
  const double depth_mm = 0.5 * epsilon_mm;
  auto farther = [&](const Vec3& p) { return index.distance(p) > depth_mm; };
  auto holds = [&](const LineInterval& iv) {
    return deeper_than(origin, d, iv.begin, iv.end, depth_mm, farther);
  };
  if (up_min > -INFINITY && !holds(in.back())) up_min = -INFINITY;
  if (down_max < INFINITY && !holds(in.front())) down_max = INFINITY;
  if (up_min == -INFINITY && down_max == INFINITY) return std::nullopt;
  return std::pair{up_min, down_max};
}

// Raises the up half's surface and lowers the down half's (node heights, starting from the
// parting surface) until both meet their bounds at every fit point: the grid's nodes alone do
// not stop a flat cell from leaving a thin or bent part, or the end of a lip, between them.
// Cyclic projections onto each unmet bound (Kaczmarz), in a fixed order so the result does not
// depend on threads. The bounds only push one way, so they can always all be met, and the up
// surface never falls below the down one; nodes stay below `top` and above `bottom`.
void fit_surfaces(std::vector<double>& up, std::vector<double>& down,
                  const std::vector<FitPoint>& points, double bottom, double top) {
  constexpr int kRounds = 200;
  constexpr double kTolerance = 1e-9;  // mm
  for (int round = 0; round < kRounds; ++round) {
    bool moved = false;
    for (const FitPoint& p : points)
      for (auto [h, sign, bound] : {std::tuple{&up, 1.0, p.up_min}, {&down, -1.0, -p.down_max}}) {
        // sign * height >= bound
        double value = 0.0, norm2 = 0.0;
        for (int q = 0; q < 3; ++q) {
          value += p.weight[q] * (*h)[p.node[q]];
          norm2 += p.weight[q] * p.weight[q];
        }
        const double miss = bound - sign * value;
        if (miss <= kTolerance) continue;
        moved = true;
        for (int q = 0; q < 3; ++q) {
          double& node = (*h)[p.node[q]];
          node = std::clamp(node + sign * miss * p.weight[q] / norm2, bottom, top);
        }
      }
    if (!moved) return;
  }
}

// The motion from a half's print frame to the model: print x is the frame's x, and the far face
// (at local w = far_centre.z(), facing +w for the up half, -w for the down half) lies on z = 0
// facing -z, centred on the origin. The up half is turned over about x.
RigidMotion print_to_model(const Frame& f, const Vec3& far_centre, bool up) {
  const double s = up ? -1.0 : 1.0;
  RigidMotion m;
  m << f.x, s * f.y, s * f.w, f.world(far_centre);
  return m;
}

// Moves a half from the model into its print frame. The far face's vertices land within a
// rounding error of z = 0: they are put on it exactly, so the whole face rests on the bed.
void to_print_frame(TriMesh& m, const RigidMotion& to_model, double hair) {
  const Eigen::Matrix3d back = to_model.leftCols<3>().transpose();
  for (Vec3& p : m.vertices) {
    p = back * (p - to_model.col(3));
    if (std::abs(p.z()) <= hair) p.z() = 0.0;
  }
}

void round_to_float(TriMesh& m) {
  for (Vec3& p : m.vertices)
    for (int k = 0; k < 3; ++k) p[k] = to_float(p[k]);
}

// Extent of the part along `up`.
double extent_along(const TriMesh& m, const Vec3& up) {
  double lo = INFINITY, hi = -INFINITY;
  for (const Vec3& p : m.vertices) {
    lo = std::min(lo, p.dot(up));
    hi = std::max(hi, p.dot(up));
  }
  return hi - lo;
}

}  // namespace

void MoldOptions::validate() const {
  require_option(std::isfinite(wall_mm) && wall_mm >= 1 && wall_mm <= 200,
                 "--wall must be between 1 and 200 mm");
  require_option(
      std::isfinite(sprue_diameter_mm) && sprue_diameter_mm > 0 && sprue_diameter_mm < 2 * wall_mm,
      "--sprue-diameter must be > 0 and less than twice --wall");
  require_option(std::isfinite(vent_diameter_mm) && vent_diameter_mm > 0 &&
                     vent_diameter_mm <= sprue_diameter_mm,
                 "--vent-diameter must be > 0 and at most --sprue-diameter");
  require_option(
      std::isfinite(key_clearance_mm) && key_clearance_mm >= 0 && key_clearance_mm <= 0.2 * wall_mm,
      "--key-clearance must be between 0 and a fifth of --wall");
  validate_epsilon(epsilon_mm);
  require_option(gravity_up.allFinite(), "the pouring direction must be finite");
}

namespace {

// One try at a mold; `attempt` moves the parting surface's grid by a fraction of a cell, which
// changes every triangle the booleans make.
Mold try_mold(const Part& part, const MoldOptions& opts, int attempt) {
  // Worker threads may inherit another rounding mode (TBB copies the creating thread's
  // floating-point settings); constructions must round the same way on every thread.
  std::fesetround(FE_TONEAREST);
  const std::string name = "part " + std::to_string(part.id);
  Mold mold;
  mold.part = part.id;
  // The cavity is the part exactly as its STL stores it.
  TriMesh cavity = part.mesh;
  round_to_float(cavity);
  cavity = unweld_nonmanifold(cavity);
  const Vec3 d = part.direction.normalized();
  const double diag = bounding_box(cavity.vertices).diagonal();
  const double hair = 1e-6 * std::max(diag, 1.0);

  // --- 1. face split and parting line ---
  const LineIndex index(cavity, d);
  const FaceSplit split = split_faces(cavity, index, d, opts.epsilon_mm);
  mold.split = split.stats;

  // --- 2. gravity: orthogonal to d, so every air trap is on the parting line (paper Fig. 9);
  // fewest traps, then the shortest fall ---
  const double prominence = std::max(0.5 * opts.vent_diameter_mm, opts.epsilon_mm);
  const Vec3 e1 = d.unitOrthogonal(), e2 = d.cross(e1).normalized();
  Vec3 up = e1;
  std::vector<std::int32_t> traps;
  double best_extent = INFINITY;
  const Vec3 wanted = opts.gravity_up - opts.gravity_up.dot(d) * d;
  const bool automatic = opts.gravity_up.isZero();
  if (!automatic && wanted.norm() < 1e-6 * opts.gravity_up.norm())
    throw Error(ErrorCode::InvalidOptions, name + ": the pouring direction is parallel to d");
  for (int k = 0; k < (automatic ? kGravityCandidates : 1); ++k) {
    const double angle = 2 * std::numbers::pi * k / kGravityCandidates;
    const Vec3 candidate =
        automatic ? Vec3(std::cos(angle) * e1 + std::sin(angle) * e2) : wanted.normalized();
    std::vector<std::int32_t> t = trapped_maxima(cavity, split, candidate, prominence);
    const double extent = extent_along(cavity, candidate);
    if (k == 0 || t.size() < traps.size() ||
        (t.size() == traps.size() && extent < best_extent - 1e-9)) {
      up = candidate;
      traps = std::move(t);
      best_extent = extent;
    }
  }
  // The parting line's vertices, highest first (ties by index).
  std::vector<std::int32_t> by_height;
  for (const auto& e : split.parting_edges) by_height.insert(by_height.end(), e.begin(), e.end());
  std::sort(by_height.begin(), by_height.end());
  by_height.erase(std::unique(by_height.begin(), by_height.end()), by_height.end());
  std::sort(by_height.begin(), by_height.end(), [&](std::int32_t a, std::int32_t b) {
    const double ha = cavity.vertices[a].dot(up), hb = cavity.vertices[b].dot(up);
    return ha != hb ? ha > hb : a < b;
  });
  // No trap (the pouring direction with the fewest has none): the sprue still goes at the
  // parting line's highest point, where the last air leaves as the cavity fills.
  if (traps.empty() && !by_height.empty()) traps.assign(1, by_height.front());
  const Frame frame{up.cross(d).normalized(), up, d};
  mold.gravity_up = up;

  // --- 3. block and parting surface ---
  Box3 local;
  local.min = local.max = frame.local(cavity.vertices.front());
  for (const Vec3& p : cavity.vertices) {
    const Vec3 q = frame.local(p);
    local.min = local.min.cwiseMin(q);
    local.max = local.max.cwiseMax(q);
  }
  const double wall = opts.wall_mm;
  const double key_base_r = 0.6 * wall, key_top_r = 0.35 * wall, key_h = 0.6 * wall;
  const double c = opts.key_clearance_mm;
  const double margin = 2 * wall + 2 * key_base_r;  // room for keys a wall from cavity and edge
  HeightGrid g;
  const double span_x = local.max.x() - local.min.x() + 2 * margin;
  const double span_y = local.max.y() - local.min.y() + 2 * margin;
  const double span = std::max(span_x, span_y);
  const double wanted_cells = std::ceil(span / (1.5 * opts.epsilon_mm));
  g.s = span / std::clamp(wanted_cells, double{kMinGridCells}, double{kMaxGridCells});
  // A fraction of a cell off the part's bounding box, so grid lines do not run along its walls.
  const double shift_x = std::fmod(0.37 + 0.31 * attempt, 1.0),
               shift_y = std::fmod(0.29 + 0.43 * attempt, 1.0);
  g.x0 = local.min.x() - margin - shift_x * g.s;
  g.y0 = local.min.y() - margin - shift_y * g.s;
  g.nx = static_cast<int>(std::ceil((span_x + 2 * shift_x * g.s) / g.s));
  g.ny = static_cast<int>(std::ceil((span_y + 2 * shift_y * g.s) / g.s));
  const int nodes = (g.nx + 1) * (g.ny + 1);
  g.h.assign(nodes, 0.0);
  g.part.assign(nodes, 0);
  g.lo.assign(nodes, 0.0);
  g.hi.assign(nodes, 0.0);
  // On a line meeting the part, the surface passes through it (bottom <= h <= top): then the
  // up half holds only what lies above the part and the down half what lies below, and both
  // release. Where the part is a DHF only up to epsilon (several intervals), the thickest one.
  std::vector<std::vector<LineInterval>> node_lines(nodes);
  tbb::parallel_for(0, nodes, [&](int k) {
    const int i = k % (g.nx + 1), j = k / (g.nx + 1);
    const std::vector<LineInterval>& in = node_lines[k] =
        robust_line_intervals(index, frame.world(Vec3(g.x(i), g.y(j), 0.0)), d, hair);
    double best = -1;
    for (const LineInterval& iv : in)
      if (iv.end - iv.begin > best) {
        best = iv.end - iv.begin;
        g.h[k] = 0.5 * (iv.begin + iv.end);
        g.lo[k] = iv.begin;
        g.hi[k] = iv.end;
        g.part[k] = 1;
      }
  });
  pin_to_parting_line(g, cavity, split, frame);
  extend_harmonically(g);
  const double w_top = local.max.z() + wall, w_bottom = local.min.z() - wall;
  mold.block_mm = Vec3(g.nx * g.s, g.ny * g.s, w_top - w_bottom);

  // --- 4. keys: four, in the block's corners, a wall from the cavity's box and the edges ---
  TriMesh bumps, sockets;
  const double kx[2] = {local.min.x() - wall - key_base_r, local.max.x() + wall + key_base_r};
  const double ky[2] = {local.min.y() - wall - key_base_r, local.max.y() + wall + key_base_r};
  const double embed = 0.25 * wall;  // how far a bump reaches into the down half
  const double slope = (key_base_r - key_top_r) / key_h;
  for (double yk : ky)
    for (double xk : kx) {
      const double hk = g.height(xk, yk);
      flatten_disc(g, xk, yk, key_base_r + slope * embed + c + g.s, hk);
      TriMesh bump = make_frustum(Vec3(xk, yk, hk - embed), Vec3::UnitZ(),
                                  key_base_r + slope * embed, key_top_r, key_h + embed,
                                  kKeySegments);
      TriMesh socket = make_frustum(Vec3(xk, yk, hk - embed), Vec3::UnitZ(),
                                    key_base_r + slope * embed + c, key_top_r + c,
                                    key_h + embed + c, kKeySegments);
      append_mesh(bumps, bump);
      append_mesh(sockets, socket);
      MoldKey key;
      key.base = frame.world(Vec3(xk, yk, hk));
      key.base_diameter_mm = 2 * key_base_r;
      key.top_diameter_mm = 2 * key_top_r;
      key.height_mm = key_h;
      mold.keys.push_back(key);
    }

  // --- 5. sprue at the highest trap, a vent at every other; straight up to the block's edge ---
  TriMesh channels;
  std::vector<std::array<double, 2>> taken;  // (x, radius) of the channels kept
  const double y_exit = g.y(g.ny) + wall;    // past the block's edge
  // Where a channel's axis starts, in the frame: a fraction of a cell across from its parting
  // line vertex, so that it does not run along the part's edges or walls.
  auto channel_start = [&](std::int32_t v) {
    return Vec3(frame.local(cavity.vertices[v]) + Vec3(0.123 * g.s, 0, 0));
  };
  // Cuts a channel from parting line vertex v unless it would merge with one already cut.
  auto add_channel = [&](std::int32_t v, bool sprue) {
    const double radius = 0.5 * (sprue ? opts.sprue_diameter_mm : opts.vent_diameter_mm);
    const Vec3 p = channel_start(v);
    // Two channels side by side would merge; the higher one vents this trap's neighbourhood.
    for (const auto& [x, r] : taken)
      if (std::abs(p.x() - x) < r + radius + 2 * g.s) return false;
    taken.push_back({p.x(), radius});
    // Level with the parting surface where the channel leaves the cavity; it starts a radius
    // inside the cavity, so it opens into it over its full width.
    const double wc = g.height(p.x(), p.y());
    const double y_start = p.y() - radius;
    flatten_channel(g, p.x(), y_start - g.s, radius + g.s, wc);
    append_mesh(channels, channel_tube(g, p.x(), wc, y_start, y_exit, radius));
    MoldChannel ch;
    ch.mouth = frame.world(Vec3(p.x(), y_start, wc));
    ch.exit = frame.world(Vec3(p.x(), y_exit, wc));
    ch.diameter_mm = 2 * radius;
    (sprue ? mold.sprues : mold.vents).push_back(ch);
    return true;
  };
  for (std::size_t t = 0; t < traps.size(); ++t) add_channel(traps[t], t == 0);
  // One trap only (the sprue's): a vent still goes at the highest point of the parting line
  // whose way up is clear of the cavity, so the air the pour pushes up has a way out besides
  // the sprue the resin fills.
  if (mold.vents.empty()) {
    const double r = 0.5 * opts.vent_diameter_mm;
    auto clear_above = [&](std::int32_t v) {
      for (const double across : {-r, 0.0, r}) {
        const Vec3 origin = frame.world(channel_start(v) + Vec3(across, 0, 0));
        for (const LineInterval& in : robust_line_intervals(index, origin, up, hair))
          if (in.end > r) return false;
      }
      return true;
    };
    for (std::int32_t v : by_height)
      if (clear_above(v) && add_channel(v, false)) break;
  }

  // --- 6. the surfaces bounding each half: the parting surface, the up half's raised and the
  // down half's lowered where release needs it on the line through a grid node or a point of
  // the part's faces (the part bends and ends between nodes), so they part across the gaps the
  // tolerance accepts ---
  // Points of the part's faces, half a cell apart across d, and where the faces' edges cross the
  // grid's lines and cells' diagonals: between those crossings both the part's face and the
  // surface's triangle are planar, so the gap between them is least at one of them. A hair
  // inside each face, so that their lines do not run along the walls its edges may top; a face
  // smaller than half a cell gives its centroid. Walls (faces along d) are left out: lines along
  // them bind nothing, and the faces above and below them give the lines beside them.
  std::vector<Vec3> on_part;
  for (const Tri& t : cavity.triangles) {
    const Vec3 &a = cavity.vertices[t[0]], &b = cavity.vertices[t[1]], &c = cavity.vertices[t[2]];
    const Vec3 normal = (b - a).cross(c - a);
    if (std::abs(normal.dot(d)) <= 0.05 * normal.norm()) continue;
    const Vec3 centroid = (a + b + c) / 3.0;
    auto across = [&](const Vec3& e) { return (e - e.dot(d) * d).norm(); };
    const double longest = std::max({across(b - a), across(c - b), across(a - c)});
    const int n = std::min(static_cast<int>(longest / (0.5 * g.s)), 64);
    if (n == 0) on_part.push_back(centroid);
    for (int i = 0; i <= n && n > 0; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const Vec3 p = (i * a + j * b + (n - i - j) * c) / double(n);
        on_part.push_back(centroid + 0.98 * (p - centroid));
      }
    for (const auto& [p, q] : {std::pair{&a, &b}, {&b, &c}, {&c, &a}}) {
      const Vec3 lp = frame.local(*p), lq = frame.local(*q);
      const double u0 = (lp.x() - g.x0) / g.s, v0 = (lp.y() - g.y0) / g.s;
      const double u1 = (lq.x() - g.x0) / g.s, v1 = (lq.y() - g.y0) / g.s;
      for (const auto& [f0, f1] : {std::pair{u0, u1}, {v0, v1}, {u0 - v0, u1 - v1}}) {
        const double k_lo = std::floor(std::min(f0, f1)) + 1, k_hi = std::max(f0, f1);
        for (double k = k_lo; k < k_hi && k < k_lo + 64; ++k) {
          const Vec3 crossing = *p + (k - f0) / (f1 - f0) * (*q - *p);
          on_part.push_back(centroid + 0.98 * (crossing - centroid));
        }
      }
    }
  }
  const std::size_t num_on_part = on_part.size();
  std::vector<std::optional<FitPoint>> candidates(num_on_part + nodes);
  tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t k) {
    const bool surface_point = k < num_on_part;
    const int node = static_cast<int>(k - num_on_part);
    const Vec3 at = surface_point ? frame.local(on_part[k])
                                  : Vec3(g.x(node % (g.nx + 1)), g.y(node / (g.nx + 1)), 0.0);
    const Vec3 origin = frame.world(Vec3(at.x(), at.y(), 0.0));
    const std::vector<LineInterval> in =
        surface_point ? robust_line_intervals(index, origin, d, hair) : node_lines[node];
    if (const auto bounds =
            release_bounds(in, g.height(at.x(), at.y()), index, origin, d, opts.epsilon_mm)) {
      FitPoint p{g.spot(at.x(), at.y())};
      std::tie(p.up_min, p.down_max) = *bounds;
      candidates[k] = p;
    }
  });
  std::vector<FitPoint> fit;
  for (const std::optional<FitPoint>& p : candidates)
    if (p) fit.push_back(*p);
  HeightGrid up_surface = g, down_surface = g;
  fit_surfaces(up_surface.h, down_surface.h, fit, w_bottom + 0.5 * wall, w_top - 0.5 * wall);

  // --- 7. halves: block halves minus the cavity and channels; bumps on down, sockets in up ---
  TriMesh up_block = block_half(up_surface, w_top), down_block = block_half(down_surface, w_bottom);
  for (TriMesh* m : {&up_block, &down_block, &channels, &bumps, &sockets}) to_world(*m, frame);
  // The cavity is cut last: the other operands are simple closed shapes made here, and only
  // the part can intersect or touch itself.
  mold.up = carve(up_block, {{BooleanOp::Difference, &sockets, name + ": sockets"},
                             {BooleanOp::Difference, &channels, name + ": up half channels"},
                             {BooleanOp::Difference, &cavity, name + ": up half"}});
  mold.down = carve(down_block, {{BooleanOp::Union, &bumps, name + ": keys"},
                                 {BooleanOp::Difference, &channels, name + ": down half channels"},
                                 {BooleanOp::Difference, &cavity, name + ": down half"}});

  // --- 8. each half laid on its flat outer face, to print as it is; what is written (rounded
  // to float there) is what is checked ---
  const double cx = g.x0 + 0.5 * g.nx * g.s, cy = g.y0 + 0.5 * g.ny * g.s;
  mold.up_to_model = print_to_model(frame, Vec3(cx, cy, w_top), true);
  mold.down_to_model = print_to_model(frame, Vec3(cx, cy, w_bottom), false);
  to_print_frame(mold.up, mold.up_to_model, hair);
  to_print_frame(mold.down, mold.down_to_model, hair);
  for (auto [half, label] : {std::pair{&mold.up, "up"}, std::pair{&mold.down, "down"}}) {
    canonicalize(*half);  // the clean-up visits triangles in order: make the order the geometry's
    const std::string problem = finish_solid(*half);
    canonicalize(*half);
    if (!problem.empty())
      throw Error(ErrorCode::BooleanFailed, name + ": " + label + " half " + problem);
    // Where the parting surface dips past the part near its outline, the booleans leave chips
    // of the block loose in the cavity: they would neither print (nothing under them) nor come
    // out with the half. Only the shell resting on the bed is the half.
    keep_shells_on_bed(*half);
    if (half->triangles.empty())
      throw Error(ErrorCode::Internal, name + ": " + label + " half has no face on z = 0");
    const MeshDiagnostics diag_half = validate_mesh(weld_exact(*half));
    if (!diag_half.ok())
      throw Error(ErrorCode::BooleanFailed,
                  name + ": " + label + " half: " + diag_half.first_problem);
  }
  return mold;
}

}  // namespace

Mold build_mold(const Part& part, const MoldOptions& opts) {
  opts.validate();
  constexpr int kAttempts = 4;
  for (int attempt = 0;; ++attempt) {
    throw_if_stop_requested();
    try {
      return try_mold(part, opts, attempt);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::BooleanFailed || attempt + 1 == kAttempts) throw;
    }
  }
}

std::vector<Mold> build_molds(const std::vector<Part>& parts, const MoldOptions& opts) {
  opts.validate();
  std::vector<Mold> molds(parts.size());
  tbb::parallel_for(std::size_t{0}, parts.size(), [&](std::size_t i) {
    try {
      molds[i] = build_mold(parts[i], opts);
    } catch (const Error& e) {
      if (e.code() == ErrorCode::Stopped) throw;  // the run's, not this part's
      molds[i] = Mold{};
      molds[i].part = parts[i].id;
      molds[i].error = e.what();
    } catch (const std::exception& e) {  // a CGAL precondition: this part's mold only
      molds[i] = Mold{};
      molds[i].part = parts[i].id;
      molds[i].error = "part " + std::to_string(parts[i].id) + ": geometry kernel: " + e.what();
    }
  });
  return molds;
}

}  // namespace dhfcast
