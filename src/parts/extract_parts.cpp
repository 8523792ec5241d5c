#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "components.h"
#include "dhfcast/error.h"
#include "dhfcast/parts.h"

namespace dhfcast {
namespace {

[[noreturn]] void broken(const std::string& what) {
  throw Error(ErrorCode::Internal, "parts: " + what);
}

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) {
    std::iota(parent_.begin(), parent_.end(), std::int32_t{0});
  }
  std::int32_t find(std::int32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  // The smaller index stays the root, so roots do not depend on the order of unions.
  void unite(std::int32_t a, std::int32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<std::int32_t> parent_;
};

int local_vertex(const Tet& tet, std::int32_t v) {
  for (int m = 0; m < 4; ++m)
    if (tet[m] == v) return m;
  return -1;
}

// A boundary face of a part: local face `face` of tet `tet`, oriented out of the tet.
struct BoundaryFace {
  std::int32_t tet;
  int face;
  std::array<std::int32_t, 3> v;  // tet-mesh vertex indices, counter-clockwise seen from outside
  std::int32_t neighbor_part;     // part across the face, -1 on the solid's outer surface
};

// Builds the boundary of one part (`part_tets` ascending, all with part_of == p) as a closed,
// 2-manifold, outward mesh, and the part across each of its triangles.
void part_boundary(const TetMesh& tets, const std::vector<std::int32_t>& part_of, std::int32_t p,
                   const std::vector<std::int32_t>& part_tets, TriMesh& mesh,
                   std::vector<std::int32_t>& triangle_neighbor) {
  // --- 1. boundary faces, and where to find each one from (tet, local face) ---
  std::vector<BoundaryFace> faces;
  std::vector<std::int32_t> face_at(part_tets.size() * 4, -1);  // [position of tet * 4 + face]
  for (std::size_t k = 0; k < part_tets.size(); ++k) {
    const std::int32_t t = part_tets[k];
    for (int i = 0; i < 4; ++i) {
      const std::int32_t u = tets.neighbors[t][i];
      if (u >= 0 && part_of[u] == p) continue;
      face_at[k * 4 + i] = static_cast<std::int32_t>(faces.size());
      const Tet& tet = tets.tets[t];
      faces.push_back({t,
                       i,
                       {tet[kTetFaces[i][0]], tet[kTetFaces[i][1]], tet[kTetFaces[i][2]]},
                       u < 0 ? -1 : part_of[u]});
    }
  }
  auto face_index = [&](std::int32_t t, int i) {
    const auto it = std::lower_bound(part_tets.begin(), part_tets.end(), t);
    const std::int32_t f = face_at[static_cast<std::size_t>(it - part_tets.begin()) * 4 + i];
    if (f < 0) broken("edge rotation ended on an interior face");
    return f;
  };

  // Partner of edge (a, b) of face (t, i): turn about the edge into t and on through the part's
  // own tets until a boundary face of the part is reached. Pairing faces this way, rather than by
  // vertex indices, keeps the surface manifold where the part touches itself along the edge.
  const std::int32_t max_steps = static_cast<std::int32_t>(tets.tets.size());
  auto partner = [&](std::int32_t t, int entry, std::int32_t a, std::int32_t b) {
    for (std::int32_t step = 0; step < max_steps; ++step) {
      const Tet& tet = tets.tets[t];
      int exit = -1;  // the other face through (a, b): opposite the vertex off both faces
      for (int m = 0; m < 4; ++m)
        if (m != entry && tet[m] != a && tet[m] != b) exit = m;
      const std::int32_t u = tets.neighbors[t][exit];
      if (u < 0 || part_of[u] != p) return face_index(t, exit);
      // In u, the shared face is opposite u's only vertex that is not in t.
      const Tet& next = tets.tets[u];
      int back = -1;
      for (int m = 0; m < 4; ++m)
        if (local_vertex(tet, next[m]) < 0) back = m;
      if (back < 0 || local_vertex(next, a) < 0 || local_vertex(next, b) < 0)
        broken("tet adjacency does not match the tets");
      t = u;
      entry = back;
    }
    broken("edge rotation does not end");
  };

  // --- 2. pair every face edge with its partner; join corners around each vertex ---
  const std::int32_t num_faces = static_cast<std::int32_t>(faces.size());
  std::vector<std::int32_t> edge_partner(static_cast<std::size_t>(num_faces) * 3);  // corner ids
  UnionFind corners(static_cast<std::size_t>(num_faces) * 3);
  tbb::parallel_for(std::int32_t{0}, num_faces, [&](std::int32_t f) {
    for (int c = 0; c < 3; ++c) {
      const std::int32_t a = faces[f].v[c];
      const std::int32_t b = faces[f].v[(c + 1) % 3];
      const std::int32_t g = partner(faces[f].tet, faces[f].face, a, b);
      const auto& w = faces[g].v;
      const int cb = static_cast<int>(std::find(w.begin(), w.end(), b) - w.begin());
      if (cb == 3 || w[(cb + 1) % 3] != a) broken("boundary faces are not consistently oriented");
      edge_partner[f * 3 + c] = g * 3 + cb;  // edge b -> a of g starts at its corner cb
    }
  });
  for (std::int32_t e = 0; e < num_faces * 3; ++e) {
    const std::int32_t o = edge_partner[e];
    if (edge_partner[o] != e) broken("edge pairing is not symmetric");
    // e runs a -> b, o runs b -> a: a is e's first corner and o's second, and vice versa.
    corners.unite(e, o - o % 3 + (o + 1) % 3);
    corners.unite(e - e % 3 + (e + 1) % 3, o);
  }

  // --- 3. one vertex per fan of corners, numbered in order of first use ---
  mesh = {};
  triangle_neighbor.clear();
  std::vector<std::int32_t> vertex_of_root(static_cast<std::size_t>(num_faces) * 3, -1);
  std::vector<std::int32_t> corner_vertex(static_cast<std::size_t>(num_faces) * 3);
  for (std::int32_t c = 0; c < num_faces * 3; ++c) {
    std::int32_t& v = vertex_of_root[corners.find(c)];
    if (v < 0) {
      v = static_cast<std::int32_t>(mesh.vertices.size());
      mesh.vertices.push_back(tets.vertices[faces[c / 3].v[c % 3]]);
    }
    corner_vertex[c] = v;
  }

  // --- 4. edges still shared by two pairs of faces ---
  // When the part touches itself along an edge and both end vertices are single fans, two face
  // pairs use the same vertex pair. Each extra pair gets its own midpoint vertex, which splits
  // its two faces, so every edge of the mesh has exactly two faces.
  std::vector<std::int32_t> midpoint(static_cast<std::size_t>(num_faces) * 3, -1);
  std::unordered_map<std::uint64_t, std::int32_t> pair_count;
  for (std::int32_t e = 0; e < num_faces * 3; ++e) {
    const std::int32_t o = edge_partner[e];
    if (o < e) continue;
    const std::uint32_t u = static_cast<std::uint32_t>(corner_vertex[e]);
    const std::uint32_t v = static_cast<std::uint32_t>(corner_vertex[o]);
    const std::uint64_t key = (std::uint64_t{std::min(u, v)} << 32) | std::max(u, v);
    if (pair_count[key]++ == 0) continue;
    const Vec3 middle = 0.5 * (mesh.vertices[u] + mesh.vertices[v]);
    midpoint[e] = midpoint[o] = static_cast<std::int32_t>(mesh.vertices.size());
    mesh.vertices.push_back(middle);
  }

  // --- 5. triangles ---
  mesh.triangles.reserve(faces.size());
  for (std::int32_t f = 0; f < num_faces; ++f) {
    // Rotate the corners so that the cases below cover every face: one split on edge 0, two
    // splits on edges 0 and 1.
    const auto split = [&](int c) { return midpoint[f * 3 + c] >= 0; };
    const int splits = split(0) + split(1) + split(2);
    int shift = 0;
    if (splits == 1) shift = split(0) ? 0 : (split(1) ? 1 : 2);
    if (splits == 2) shift = !split(0) ? 1 : (!split(1) ? 2 : 0);
    std::int32_t v[3], m[3];
    for (int c = 0; c < 3; ++c) {
      v[c] = corner_vertex[f * 3 + (c + shift) % 3];
      m[c] = midpoint[f * 3 + (c + shift) % 3];  // on the edge v[c] -> v[c + 1]
    }
    switch (splits) {
      case 0:
        mesh.triangles.push_back({v[0], v[1], v[2]});
        break;
      case 1:
        mesh.triangles.push_back({v[0], m[0], v[2]});
        mesh.triangles.push_back({m[0], v[1], v[2]});
        break;
      case 2:
        mesh.triangles.push_back({m[0], v[1], m[1]});
        mesh.triangles.push_back({v[0], m[0], m[1]});
        mesh.triangles.push_back({v[0], m[1], v[2]});
        break;
      default:
        mesh.triangles.push_back({v[0], m[0], m[2]});
        mesh.triangles.push_back({m[0], v[1], m[1]});
        mesh.triangles.push_back({m[2], m[1], v[2]});
        mesh.triangles.push_back({m[0], m[1], m[2]});
        break;
    }
    triangle_neighbor.resize(mesh.triangles.size(), faces[f].neighbor_part);
  }
}

}  // namespace

std::vector<Part> extract_parts(const TetMesh& tets, const std::vector<std::int32_t>& label,
                                const std::vector<std::int32_t>& region,
                                const std::vector<Vec3>& directions) {
  const std::size_t n = tets.tets.size();
  if (tets.neighbors.size() != n) broken("the tet mesh has no adjacency");
  if (label.size() != n || region.size() != n) broken("one label and one region per tet expected");
  for (std::size_t t = 0; t < n; ++t) {
    if (region[t] < 0 || label[t] < 0 || static_cast<std::size_t>(label[t]) >= directions.size())
      broken("tet " + std::to_string(t) + " has no direction");
  }

  // --- 1. components, sorted by decreasing volume, ties by smallest tet ---
  std::int32_t num_parts = 0;
  const std::vector<std::int32_t> component =
      detail::label_components(tets, label, region, num_parts);
  std::vector<std::vector<std::int32_t>> members(num_parts);
  for (std::int32_t t = 0; t < static_cast<std::int32_t>(n); ++t)
    members[component[t]].push_back(t);
  std::vector<double> volume_mm3(num_parts, 0.0);
  for (std::int32_t c = 0; c < num_parts; ++c)
    for (const std::int32_t t : members[c]) volume_mm3[c] += tet_volume(tets, t);
  std::vector<std::int32_t> rank(num_parts);
  std::iota(rank.begin(), rank.end(), std::int32_t{0});
  // Components are numbered by their smallest tet, so the index breaks ties.
  std::stable_sort(rank.begin(), rank.end(),
                   [&](std::int32_t a, std::int32_t b) { return volume_mm3[a] > volume_mm3[b]; });

  std::vector<Part> parts(num_parts);
  std::vector<std::int32_t> part_of(n);
  for (std::int32_t id = 0; id < num_parts; ++id) {
    const std::int32_t c = rank[id];
    Part& part = parts[id];
    part.id = id;
    part.tets = std::move(members[c]);
    part.volume_mm3 = volume_mm3[c];
    const std::int32_t t0 = part.tets.front();
    part.region = region[t0];
    part.direction_index = label[t0];
    const Vec3& d = directions[part.direction_index];
    if (!(d.norm() > 0.0)) broken("direction " + std::to_string(label[t0]) + " is zero");
    part.direction = d.normalized();
    for (const std::int32_t t : part.tets) part_of[t] = id;
  }

  // --- 2. boundary meshes; parts are independent ---
  tbb::parallel_for(std::int32_t{0}, num_parts, [&](std::int32_t id) {
    part_boundary(tets, part_of, id, parts[id].tets, parts[id].mesh, parts[id].triangle_neighbor);
  });
  return parts;
}

std::vector<std::int32_t> tiny_parts(const std::vector<Part>& parts, double volume_mm3) {
  std::vector<std::int32_t> out;
  for (const Part& p : parts)
    if (p.volume_mm3 < kTinyPartShare * volume_mm3) out.push_back(p.id);
  return out;
}

}  // namespace dhfcast
