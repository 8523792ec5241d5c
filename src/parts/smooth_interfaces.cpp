// Interface smoothing (paper §4.3.1): the parts' shared surfaces are tet faces, a staircase at
// the scale of the tets; Laplacian smoothing inside each vertex's feasible star removes it.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <numbers>
#include <unordered_map>
#include <utility>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "dhfcast/parts.h"
#include "outer_columns.h"

namespace dhfcast {
namespace {

// Vertices are matched across parts by their exact coordinates: every part copies them from the
// same tet mesh.
struct PositionKey {
  std::array<std::uint64_t, 3> bits;
  explicit PositionKey(const Vec3& p) {
    for (int k = 0; k < 3; ++k) {
      const double c = p[k] + 0.0;  // -0.0 and 0.0 are the same place
      std::memcpy(&bits[k], &c, sizeof c);
    }
  }
  bool operator==(const PositionKey&) const = default;
};
struct PositionHash {
  std::size_t operator()(const PositionKey& k) const {
    std::uint64_t h = 0x9e3779b97f4a7c15ull;
    for (std::uint64_t b : k.bits) h = (h ^ b) * 0x100000001b3ull + (h >> 29);
    return static_cast<std::size_t>(h);
  }
};

std::uint64_t edge_key(std::int32_t a, std::int32_t b) {
  return (std::uint64_t{static_cast<std::uint32_t>(std::min(a, b))} << 32) |
         static_cast<std::uint32_t>(std::max(a, b));
}

// A triangle of the whole arrangement: an outer triangle of one part, or an interface triangle
// listed once, oriented out of part a.
struct Face {
  Tri v;
  std::int32_t a, b;  // b: the part across, -1 on the outer surface
};

enum class Kind : std::uint8_t { Fixed, Surface, Curve, Seam };

Vec3 triangle_normal(const std::vector<Vec3>& p, const Tri& t) {
  return (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);
}

double angle_deg(const Vec3& a, const Vec3& b) {
  const double n = a.norm() * b.norm();
  if (!(n > 0.0)) return 0.0;
  return std::acos(std::clamp(a.dot(b) / n, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

// Angles between the normals of the triangles on either side of each edge that exactly two of
// `tris` share; adds the triangles' count and area to `out`.
std::vector<double> neighbour_angles(const std::vector<Vec3>& p, const std::vector<Tri>& tris,
                                     InterfaceSmoothness& out) {
  std::unordered_map<std::uint64_t, std::array<std::int32_t, 3>> uses;  // 2 faces + count
  for (std::int32_t f = 0; f < static_cast<std::int32_t>(tris.size()); ++f)
    for (int c = 0; c < 3; ++c) {
      auto& u = uses.try_emplace(edge_key(tris[f][c], tris[f][(c + 1) % 3]),
                                 std::array<std::int32_t, 3>{-1, -1, 0}).first->second;
      if (u[2] < 2) u[u[2]] = f;
      ++u[2];
    }
  std::vector<double> angles;
  for (const auto& [key, u] : uses)
    if (u[2] == 2) angles.push_back(angle_deg(triangle_normal(p, tris[u[0]]),
                                              triangle_normal(p, tris[u[1]])));
  out.triangles += static_cast<std::int32_t>(tris.size());
  for (const Tri& t : tris) out.area_mm2 += 0.5 * triangle_normal(p, t).norm();
  return angles;
}

void summarize(std::vector<double> angles, InterfaceSmoothness& out) {
  if (angles.empty()) return;
  double sum = 0.0;
  for (double a : angles) sum += a;
  out.mean_angle_deg = sum / static_cast<double>(angles.size());
  const std::size_t k = std::min(angles.size() - 1, angles.size() * 95 / 100);
  std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(k), angles.end());
  out.p95_angle_deg = angles[k];
}

}  // namespace

void SmoothingOptions::validate() const {
  require_option(iterations >= 0 && iterations <= 10000, "--smoothing must be between 0 and 10000");
  require_option(step > 0 && step <= 1, "smoothing step must be in (0, 1]");
}

void smooth_interfaces(const TetMesh& tets, std::vector<Part>& parts, const TetAllowsPart& allows,
                       const SmoothingOptions& opts) {
  opts.validate();
  const std::int32_t num_parts = static_cast<std::int32_t>(parts.size());

  // --- 1. one vertex per position, one face per outer triangle and per interface ---
  std::unordered_map<PositionKey, std::int32_t, PositionHash> vertex_at;
  std::vector<Vec3> position;
  std::vector<std::vector<std::int32_t>> global_of(num_parts);
  std::vector<Face> faces;
  for (std::int32_t p = 0; p < num_parts; ++p) {
    const Part& part = parts[p];
    if (part.triangle_neighbor.size() != part.mesh.triangles.size())
      throw Error(ErrorCode::Internal, "smoothing: part " + std::to_string(p) +
                                           " has no neighbour per triangle");
    for (const Vec3& x : part.mesh.vertices) {
      auto [it, added] =
          vertex_at.emplace(PositionKey(x), static_cast<std::int32_t>(position.size()));
      if (added) position.push_back(x);
      global_of[p].push_back(it->second);
    }
    for (std::size_t i = 0; i < part.mesh.triangles.size(); ++i) {
      const std::int32_t n = part.triangle_neighbor[i];
      if (n >= 0 && n < p) continue;  // listed by the other part
      const Tri& t = part.mesh.triangles[i];
      faces.push_back({{global_of[p][t[0]], global_of[p][t[1]], global_of[p][t[2]]}, p, n});
    }
  }
  const std::int32_t num_vertices = static_cast<std::int32_t>(position.size());

  // --- 2. edges: which parts and which kind of faces meet along each ---
  struct EdgeInfo {
    std::int32_t a = -1, b = -1;    // its end vertices
    std::int32_t outer_parts = 0;   // distinct parts with outer faces here (counted up to 2)
    std::int32_t first_outer = -1;  // part of the first outer face seen
    std::int32_t patches = 0;       // distinct interface pairs seen
    std::int64_t first_patch = -1;
  };
  std::unordered_map<std::uint64_t, EdgeInfo> edges;
  std::vector<std::vector<std::int32_t>> parts_at(num_vertices);
  std::vector<char> on_outer(num_vertices, 0);
  for (const Face& f : faces) {
    const std::int64_t patch = f.b < 0 ? -1 : std::int64_t{f.a} * num_parts + f.b;
    for (int c = 0; c < 3; ++c) {
      const std::int32_t u = f.v[c], w = f.v[(c + 1) % 3];
      EdgeInfo& e = edges[edge_key(u, w)];
      e.a = std::min(u, w);
      e.b = std::max(u, w);
      if (patch < 0) {
        if (e.first_outer != f.a) ++e.outer_parts;
        if (e.first_outer < 0) e.first_outer = f.a;
      } else {
        if (e.first_patch != patch) ++e.patches;
        if (e.first_patch < 0) e.first_patch = patch;
      }
      for (std::int32_t q : {f.a, f.b})
        if (q >= 0 && std::find(parts_at[u].begin(), parts_at[u].end(), q) == parts_at[u].end())
          parts_at[u].push_back(q);
      if (patch < 0) on_outer[u] = 1;
    }
  }

  // --- 3. what each vertex may do, and along which neighbours ---
  std::vector<std::vector<std::int32_t>> ring(num_vertices), curve(num_vertices);
  std::vector<char> touches_interface(num_vertices, 0);
  for (const auto& [key, e] : edges) {
    ring[e.a].push_back(e.b);
    ring[e.b].push_back(e.a);
    if (e.patches > 0) touches_interface[e.a] = touches_interface[e.b] = 1;
    // Seams: outer faces of two parts meet. Junction curves: two interfaces meet inside.
    const bool seam = e.outer_parts >= 2;
    const bool junction = e.outer_parts == 0 && e.patches >= 2;
    if (seam || junction) {
      curve[e.a].push_back(e.b);
      curve[e.b].push_back(e.a);
    }
  }
  for (auto& r : ring) std::sort(r.begin(), r.end());
  for (auto& c : curve) std::sort(c.begin(), c.end());
  std::vector<Kind> kind(num_vertices, Kind::Fixed);
  for (std::int32_t v = 0; v < num_vertices; ++v) {
    if (!touches_interface[v]) continue;
    const std::size_t np = parts_at[v].size();
    if (on_outer[v])
      kind[v] = (np == 2 && curve[v].size() == 2) ? Kind::Seam : Kind::Fixed;
    else if (curve[v].empty())
      kind[v] = np == 2 ? Kind::Surface : Kind::Fixed;
    else
      kind[v] = (np == 3 && curve[v].size() == 2) ? Kind::Curve : Kind::Fixed;
  }

  // --- 4. the star of each moving vertex: it must allow every part there; how far it reaches ---
  std::unordered_map<PositionKey, std::int32_t, PositionHash> tet_vertex_at;
  for (std::int32_t i = 0; i < static_cast<std::int32_t>(tets.vertices.size()); ++i)
    tet_vertex_at.emplace(PositionKey(tets.vertices[i]), i);
  std::vector<std::vector<std::int32_t>> tets_at(tets.vertices.size());
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(tets.tets.size()); ++t)
    for (std::int32_t v : tets.tets[t]) tets_at[v].push_back(t);
  std::vector<double> reach(num_vertices, 0.0);  // how far v may move from where it started
  std::vector<Vec3> outer_normal(num_vertices, Vec3::Zero());
  for (const Face& f : faces)
    if (f.b < 0) {
      const Vec3 n = triangle_normal(position, f.v);
      for (std::int32_t v : f.v) outer_normal[v] += n;
    }
  tbb::parallel_for(std::int32_t{0}, num_vertices, [&](std::int32_t v) {
    if (kind[v] == Kind::Fixed) return;
    if (kind[v] != Kind::Seam) {
      // Inside the solid the surface may go anywhere near: accessibility does not depend on
      // it. A bound of about an edge keeps smoothing from folding thin interfaces over.
      double edge_sum = 0.0;
      for (std::int32_t w : ring[v]) edge_sum += (position[w] - position[v]).norm();
      reach[v] = 1.5 * edge_sum / static_cast<double>(ring[v].size());
      return;
    }
    const auto it = tet_vertex_at.find(PositionKey(position[v]));
    if (it == tet_vertex_at.end()) {  // a midpoint added to keep a part manifold
      kind[v] = Kind::Fixed;
      return;
    }
    double height = INFINITY;
    for (std::int32_t t : tets_at[it->second]) {
      for (std::int32_t p : parts_at[v])
        if (!allows(t, p)) {
          kind[v] = Kind::Fixed;
          return;
        }
      // Distance from v to the face of t opposite it: the star contains the ball of the
      // smallest such distance.
      const Tet& k = tets.tets[t];
      const int m = static_cast<int>(std::find(k.begin(), k.end(), it->second) - k.begin());
      const auto& face = kTetFaces[m];
      const Vec3 a = tets.vertices[k[face[0]]], b = tets.vertices[k[face[1]]],
                 c = tets.vertices[k[face[2]]];
      const Vec3 n = (b - a).cross(c - a);
      if (n.norm() > 0.0) height = std::min(height, std::abs((position[v] - a).dot(n)) / n.norm());
    }
    reach[v] = 0.9 * height;
    outer_normal[v].normalize();
    if (!(reach[v] > 0.0) || !outer_normal[v].allFinite()) kind[v] = Kind::Fixed;
  });

  // --- 5. each part's infeasible volume (paper §4.3.1) ---
  // A line along a part's direction that enters and leaves the solid through that part's outer
  // surface must stay in the part all the way: an interface point of the part on such a line
  // means the line leaves the part and comes back. Only the outer surface decides; seams slide
  // in it while smoothing, so the columns are rebuilt from the current positions when used.
  std::vector<std::int32_t> column_of(num_parts, -1);
  std::vector<Vec3> column_direction;
  for (std::int32_t p = 0; p < num_parts; ++p) {
    const Vec3& d = parts[p].direction;
    const auto it = std::find(column_direction.begin(), column_direction.end(), d);
    column_of[p] = static_cast<std::int32_t>(it - column_direction.begin());
    if (it == column_direction.end()) column_direction.push_back(d);
  }
  std::vector<Tri> outer;
  std::vector<std::int32_t> owner;
  for (const Face& f : faces)
    if (f.b < 0) {
      outer.push_back(f.v);
      owner.push_back(f.a);
    }
  std::vector<detail::OuterColumns> columns;
  auto build_columns = [&] {
    columns.assign(column_direction.size(), {});
    tbb::parallel_for(std::size_t{0}, columns.size(), [&](std::size_t i) {
      columns[i] = detail::OuterColumns(position, outer, owner, column_direction[i].normalized());
    });
  };
  auto infeasible_for = [&](std::int32_t p, const Vec3& x) {
    const auto [up, down] = columns[column_of[p]].ends(x);
    return up == p && down == p;
  };

  // --- 6. Taubin steps (a shrinking step, then an inflating one), clamped to each reach ---
  // Plain Laplacian steps would shrink small parts to nothing; Taubin's pairs keep volume.
  const std::vector<Vec3> start = position;
  std::vector<Vec3> next = position;
  auto clamp_to_reach = [&](std::int32_t v, const Vec3& x) {
    Vec3 moved = x - start[v];
    if (moved.norm() > reach[v]) moved *= reach[v] / moved.norm();
    return Vec3(start[v] + moved);
  };
  auto relax = [&](double step) {
    tbb::parallel_for(std::int32_t{0}, num_vertices, [&](std::int32_t v) {
      if (kind[v] == Kind::Fixed) return;
      const std::vector<std::int32_t>& nb = kind[v] == Kind::Surface ? ring[v] : curve[v];
      Vec3 mean = Vec3::Zero();
      for (std::int32_t w : nb) mean += position[w];
      mean /= static_cast<double>(nb.size());
      Vec3 x = position[v] + step * (mean - position[v]);
      if (kind[v] == Kind::Seam) {  // stay in the outer surface's tangent plane
        const Vec3& n = outer_normal[v];
        x -= n * n.dot(x - start[v]);
      }
      next[v] = clamp_to_reach(v, x);
    });
    std::swap(position, next);
  };
  // Damped projection out of the infeasible volumes: an interior interface vertex that
  // smoothing carried into the infeasible volume of one of its parts (one it started outside
  // of) moves back towards where it started, to the nearest place on that way outside them
  // (bisection). Seams slide too, so the volumes move: where the start is inside one now, the
  // vertex moves across that part's direction instead, the way the part's outward normal
  // points (the part grows into its neighbour), as far as its reach allows. Volumes a vertex
  // started inside are left to the label level.
  build_columns();
  std::vector<std::array<std::int32_t, 3>> watch(num_vertices, {-1, -1, -1});
  for (std::int32_t v = 0; v < num_vertices; ++v) {
    int k = 0;
    for (std::int32_t p : parts_at[v])
      if (k < 3 && !infeasible_for(p, start[v])) watch[v][k++] = p;
  }
  std::vector<std::vector<std::int32_t>> faces_at(num_vertices);
  for (std::int32_t f = 0; f < static_cast<std::int32_t>(faces.size()); ++f)
    for (std::int32_t v : faces[f].v) faces_at[v].push_back(f);
  constexpr int kMarch = 8, kBisect = 8;
  auto project = [&](double damping) {
    build_columns();
    tbb::parallel_for(std::int32_t{0}, num_vertices, [&](std::int32_t v) {
      next[v] = position[v];
      if (kind[v] != Kind::Surface && kind[v] != Kind::Curve) return;
      const Vec3 x = position[v];
      std::int32_t violated = -1;
      auto clear = [&](const Vec3& y) {
        for (std::int32_t p : watch[v])
          if (p >= 0 && infeasible_for(p, y)) {
            violated = p;
            return false;
          }
        return true;
      };
      if (clear(x)) return;
      const std::int32_t first = violated;
      Vec3 from = start[v], way = x - start[v];  // search from + s * way, s in [0, 1]
      if (!clear(start[v])) {
        Vec3 n = Vec3::Zero();
        for (std::int32_t f : faces_at[v]) {
          const Vec3 area = triangle_normal(position, faces[f].v);
          if (faces[f].a == first) n += area;
          if (faces[f].b == first) n -= area;
        }
        const Vec3 d = parts[first].direction.normalized();
        Vec3 h = n - d * d.dot(n);
        if (!(h.norm() > 0.2 * n.norm())) return;  // faces along d: no way out sideways
        h *= reach[v] / h.norm();
        double hi = -1.0;
        for (int k = 1; k <= kMarch && hi < 0; ++k)
          if (clear(x + (double(k) / kMarch) * h)) hi = double(k) / kMarch;
        if (hi < 0) return;
        from = x + hi * h;  // clear
        way = x - from;
      }
      double lo = 0.0, hi = 1.0;  // from + lo * way is clear, from + hi * way is not
      for (int k = 0; k < kBisect; ++k) {
        const double mid = 0.5 * (lo + hi);
        (clear(from + mid * way) ? lo : hi) = mid;
      }
      next[v] = clamp_to_reach(v, x + damping * (from + lo * way - x));
    });
    std::swap(position, next);
  };
  constexpr int kFinalProjections = 3;

  auto run = [&] {
    position = start;
    next = start;
    for (std::int32_t iter = 0; iter < opts.iterations; ++iter) {
      relax(opts.step);
      relax(-1.06 * opts.step);
      if (opts.project) project(0.5);
    }
    // Undamped at the end, a few times, as each vertex's move changes its neighbours' normals.
    for (int k = 0; k < kFinalProjections && opts.project && opts.iterations > 0; ++k)
      project(1.0);
  };
  run();

  // --- 7. where smoothing folds a part's surface through itself or collapses a part, undo it ---
  // A part a few tets thick can lose most of its volume, and a thin slab's interfaces can cross
  // each other or the outer surface. Only the vertices of the triangles that cross go back to
  // where they started (the tet faces, which do not cross); when that is not enough, their
  // one-rings go back too, ring by ring. Positions are shared, so every part that has such a
  // vertex gets it back the same way.
  constexpr int kMaxRounds = 8;
  std::vector<char> put_back(num_vertices, 0);
  for (int round = 0;; ++round) {
    std::vector<std::vector<std::int32_t>> folded(num_parts);
    tbb::parallel_for(std::int32_t{0}, num_parts, [&](std::int32_t p) {
      // Checked as written to STL, with float coordinates: smoothing can draw vertices so close
      // together that rounding merges them.
      TriMesh moved{{}, parts[p].mesh.triangles};
      for (std::int32_t g : global_of[p])
        moved.vertices.push_back(position[g].cast<float>().cast<double>());
      if (signed_volume(moved) < 0.5 * parts[p].volume_mm3) {
        folded[p] = global_of[p];
        return;
      }
      // Triangles that collapsed to a segment or a point go back first; crossing pairs are
      // looked for once there are none (the exact test needs proper triangles).
      for (const Tri& t : moved.triangles) {
        const Vec3& a = moved.vertices[t[0]];
        if ((moved.vertices[t[1]] - a).cross(moved.vertices[t[2]] - a) != Vec3::Zero()) continue;
        for (std::int32_t c : t) folded[p].push_back(global_of[p][c]);
      }
      if (!folded[p].empty()) return;
      for (const auto& pair : intersecting_triangles(moved, 1u << 20)) {
        // Where a part still touches itself at a point, extract_parts() gave it two vertices
        // there: triangles meeting only at that place are contact, not a fold. Triangles that
        // share a vertex and cross beyond it are a fold.
        bool contact = false;
        for (std::int32_t a : moved.triangles[pair[0]])
          for (std::int32_t b : moved.triangles[pair[1]])
            contact |= a != b && global_of[p][a] == global_of[p][b];
        if (contact) continue;
        for (std::int32_t f : pair)
          for (std::int32_t c : moved.triangles[f]) folded[p].push_back(global_of[p][c]);
      }
    });
    std::vector<std::int32_t> back;
    for (const std::vector<std::int32_t>& list : folded)
      for (std::int32_t g : list)
        if (position[g] != start[g] || put_back[g]) back.push_back(g);
    if (back.empty()) break;
    if (round == kMaxRounds) {  // give up smoothing rather than return folded parts
      position = start;
      break;
    }
    std::sort(back.begin(), back.end());
    back.erase(std::unique(back.begin(), back.end()), back.end());
    // A vertex back at its start for the second time: its one-ring goes back too.
    std::vector<std::int32_t> ring_too;
    for (std::int32_t g : back)
      if (put_back[g]) ring_too.insert(ring_too.end(), ring[g].begin(), ring[g].end());
    for (std::int32_t g : back) put_back[g] = 1;
    for (std::int32_t g : ring_too) put_back[g] = 1;
    for (std::int32_t g = 0; g < num_vertices; ++g)
      if (put_back[g]) position[g] = start[g];
  }

  // --- 8. every part takes the shared positions ---
  tbb::parallel_for(std::int32_t{0}, num_parts, [&](std::int32_t p) {
    for (std::size_t i = 0; i < parts[p].mesh.vertices.size(); ++i)
      parts[p].mesh.vertices[i] = position[global_of[p][i]];
    parts[p].volume_mm3 = signed_volume(parts[p].mesh);
  });
}

std::vector<InterfaceSmoothness> interface_smoothness(const std::vector<Part>& parts) {
  std::map<std::pair<std::int32_t, std::int32_t>, std::vector<Tri>> patches;
  for (std::int32_t p = 0; p < static_cast<std::int32_t>(parts.size()); ++p) {
    const Part& part = parts[p];
    for (std::size_t i = 0; i < part.mesh.triangles.size(); ++i) {
      const std::int32_t n = i < part.triangle_neighbor.size() ? part.triangle_neighbor[i] : -1;
      if (n > p) patches[{p, n}].push_back(part.mesh.triangles[i]);
    }
  }
  std::vector<InterfaceSmoothness> out;
  for (const auto& [pair, tris] : patches) {
    if (tris.size() < 2) continue;
    InterfaceSmoothness s;
    s.part_a = pair.first;
    s.part_b = pair.second;
    summarize(neighbour_angles(parts[pair.first].mesh.vertices, tris, s), s);
    out.push_back(s);
  }
  return out;
}

InterfaceSmoothness outer_surface_smoothness(const std::vector<Part>& parts) {
  InterfaceSmoothness total;
  total.part_a = total.part_b = -1;
  std::vector<double> angles;
  for (const Part& part : parts) {
    std::vector<Tri> tris;
    for (std::size_t i = 0; i < part.mesh.triangles.size(); ++i)
      if (i < part.triangle_neighbor.size() && part.triangle_neighbor[i] == -1)
        tris.push_back(part.mesh.triangles[i]);
    const std::vector<double> a = neighbour_angles(part.mesh.vertices, tris, total);
    angles.insert(angles.end(), a.begin(), a.end());
  }
  summarize(std::move(angles), total);
  return total;
}

}  // namespace dhfcast
