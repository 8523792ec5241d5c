// Parts: connected components of the labeling, their boundary meshes, and an assembly order.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dhfcast/types.h"

namespace dhfcast {

// One solid part, cast in its own two-piece mold along `direction`.
struct Part {
  std::int32_t id = 0;
  std::int32_t direction_index = -1;  // index into the direction set of its region
  Vec3 direction = Vec3::UnitZ();     // unit casting / assembly direction d
  std::int32_t region = 0;  // 0: the whole solid; k > 0: the k-th inaccessible region, which was
                            // decomposed again on its own
  std::vector<std::int32_t> tets;  // tets of the tet mesh it is made of, ascending
  TriMesh mesh;  // closed, 2-manifold, outward boundary (vertices duplicated where the part
                 // touches itself at an edge or vertex only)
  double volume_mm3 = 0.0;
};

// Splits the labeled tet mesh into parts: each connected component (through shared faces) of
// tets with the same (region, label) is a part. Parts are ordered by decreasing volume, ties by
// smallest tet index, and numbered 0.. in that order.
// directions[region][label] is the direction of label `label` in region `region`.
// Pre: every tet has label >= 0; tets has adjacency. Throws Error{Internal} on a broken mesh.
std::vector<Part> extract_parts(const TetMesh& tets, const std::vector<std::int32_t>& label,
                                const std::vector<std::int32_t>& region,
                                const std::vector<std::vector<Vec3>>& directions);

// How the parts go together.
struct AssemblyPlan {
  bool found = false;  // an order exists in which no part collides with those placed before it
  // Parts in the order they are put in place; each slides in along -d from far away (it arrives
  // from +infinity * d). When !found: first the parts that disassembly could take out, in the
  // order they go in (collision-free among themselves, with or without the others in place),
  // then the parts left blocked, by ascending id.
  std::vector<std::int32_t> order;
  // reversed[i]: part i goes in and out along -d_i rather than +d_i. A DHF along d is one along
  // -d too, so the caller flips the part's direction (Part::direction = -direction).
  std::vector<bool> reversed;
  // blocks[i] lists the parts that part i would run into when it leaves along +d_i (-d_i when
  // reversed[i]).
  std::vector<std::vector<std::int32_t>> blocks;
  std::string message;  // when !found: which parts block each other
};

// Finds which parts block which and orders them: disassembly removes a part no remaining part
// blocks (smallest id first); assembly is the reverse.
// Part B is blocked by part A when a ray along +d_B from a point inside B runs through A's
// interior over more than tolerance_mm. The points are the barycentre of each of B's tets and a
// point just inside each of its boundary faces. Contact on shared interfaces, and sliding along
// them, does not block. tolerance_mm >= 0, else Error{InvalidOptions}.
// Pre: `parts` is extract_parts(tets, ...), ids 0..n-1 in order.
AssemblyPlan plan_assembly(const TetMesh& tets, const std::vector<Part>& parts,
                           double tolerance_mm);

}  // namespace dhfcast
