// Fewer parts after the graph cut: moves that remove a part while every tet keeps a feasible
// label. The segmentation's choice among restarts is "fewest parts first", and the energy of
// eq. 1 often prefers a few more, smaller parts (each lowers the data cost of the tets near its
// neighbours' infeasible regions), so these moves are made even when they raise the energy.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "dhfcast/segment.h"

namespace dhfcast::detail {

class PartReducer {
 public:
  // `problem` is the segmentation's label problem (nodes are tets); face_neighbors[i] lists the
  // nodes sharing a face with node i (-1: none), which is what makes two tets one part.
  // Keeps a reference to `problem`, which must outlive it.
  // centre_mm[i]: a point of node i (its barycentre), for distances along paths of nodes.
  PartReducer(const LabelProblem& problem, std::vector<std::array<std::int32_t, 4>> face_neighbors,
              std::vector<double> volume_mm3, std::vector<Vec3> centre_mm);

  // Removes parts, smallest first, until no move applies.
  // Moves, cheapest first: (1) the whole part takes a neighbouring part's label; (2) the part
  // and a neighbouring part take one label allowed on both; (3) the part is shared among its
  // neighbours' labels by a graph cut of eq. 1 with the rest fixed, kept only when it lowers
  // the part count; (4) the neighbouring parts grow into it, each through nodes that allow its
  // label, nearest first, when together they reach all of it; (5) the part takes its own label
  // or another part's label allowed on all of it, and is joined to the nearest other part of
  // that label by the shortest path of nodes allowing it (widened by one layer where allowed),
  // kept only when it lowers the part count. With the problem's line_steps, a move is made only
  // when it leaves about no more lines through the nodes it relabels meeting one label, leaving
  // it and meeting it again (opens_gaps()): a part is not merged into a label that lies on both
  // sides of another part. Deterministic in (labels, seed).
  void reduce(std::vector<std::int32_t>& labels, std::uint64_t seed) const;

 private:
  struct Parts;
  Parts find_parts(const std::vector<std::int32_t>& labels) const;
  bool absorb_whole(const Parts& parts, std::int32_t p, std::vector<std::int32_t>& labels) const;
  bool merge_pair(const Parts& parts, std::int32_t p, std::vector<std::int32_t>& labels) const;
  bool flood_from_neighbours(const Parts& parts, std::int32_t p,
                             std::vector<std::int32_t>& labels) const;
  bool bridge(const Parts& parts, std::int32_t p, std::vector<std::int32_t>& labels) const;
  bool share_among_neighbours(const Parts& parts, std::int32_t p, std::vector<std::int32_t>& labels,
                              std::uint64_t seed) const;
  // Whether relabeling `before` to `after` leaves more lines through the changed nodes meeting
  // one label, leaving it and meeting it again (see LabelProblem::line_steps); false without
  // lines.
  bool opens_gaps(const std::vector<std::int32_t>& before,
                  const std::vector<std::int32_t>& after) const;
  // Energy change (data and smoothness; label costs are left to the caller) of giving every
  // node of `nodes` (flagged in `inside`) the label `l`.
  double relabel_cost(const std::vector<std::int32_t>& nodes, const std::vector<char>& inside,
                      const std::vector<std::int32_t>& labels, std::int32_t l) const;
  bool allowed(std::int32_t node, std::int32_t l) const {
    return (allowed_[static_cast<std::size_t>(node) * words_ + (l >> 6)] >> (l & 63)) & 1u;
  }

  const LabelProblem& problem_;
  std::int32_t n_ = 0, k_ = 0, words_ = 0;
  std::vector<std::array<std::int32_t, 4>> face_neighbors_;
  std::vector<double> volume_mm3_;
  std::vector<Vec3> centre_mm_;
  // Potts neighbours of node i (faces and seams, weights merged): adj_[adj_begin_[i] ..).
  std::vector<std::int32_t> adj_begin_, adj_node_;
  std::vector<double> adj_weight_;
  std::vector<std::uint64_t> allowed_;  // node-major bitset of finite data costs
};

}  // namespace dhfcast::detail
