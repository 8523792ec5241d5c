// Volume segmentation: one direction per tet by multi-label graph cut (paper §4.2, §4.3.3).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "dhfcast/access.h"
#include "dhfcast/types.h"

namespace dhfcast {

// Options for segment(). Defaults are the paper's and are written to decomposition.json.
struct SegmentOptions {
  double alpha = 5.0;          // data-cost scale (eq. 3)
  double c_mm = 10.0;          // width of the data-cost Gaussian (eq. 3)
  double beta_mm = 6.0;        // smoothness: beta * shared face area, beta^2 (1 + AO len) on seams
  double lambda = 0.01;        // label cost: lambda * total volume per label used
  std::int32_t restarts = 15;  // randomized alpha-expansion runs; the best one is kept
  std::uint32_t seed = 1;      // seeds the restarts; same seed, same result on any thread count

  // Throws Error{InvalidOptions} naming the first option out of range.
  void validate() const;
};

// One candidate labeling of segment(), its parts already reduced.
struct LabelingCandidate {
  std::vector<std::int32_t> label;  // as Labeling::label
  std::int32_t restart = 0;         // its number, as Labeling::best_restart
  std::int32_t parts = 0;           // face-connected components of equal label
  double volume_variance_mm6 = 0.0;
  double energy = 0.0;  // eq. 1
};

// The chosen labeling.
struct Labeling {
  // label[t]: index of t's direction, or -1 for a tet that is feasible for no direction.
  std::vector<std::int32_t> label;
  std::int32_t num_labels = 0;        // distinct directions used
  std::int32_t num_components = 0;    // connected components of equal label through shared faces
                                      // (= parts); tets labeled -1 belong to none
  double energy = 0.0;                // eq. 1 of the best restart (infeasible tets excluded)
  std::int32_t candidate_labels = 0;  // directions left after removing duplicate and dominated
                                      // feasibility sets
  std::int32_t best_restart = 0;      // the chosen candidate: r < restarts is randomized restart r,
                                      // restarts + c the c-th covering candidate (see segment())
  // Every candidate, best first in segment()'s ranking (the chosen one is candidates[0]), for a
  // caller that chooses by what comes later (how far each is from double height fields once
  // repaired, say).
  std::vector<LabelingCandidate> candidates;
};

// Minimizes eq. 1: smooth data cost (eq. 3) + face-area and seam smoothness + label cost, by
// alpha-expansion with label costs (Delong et al. 2012) on Kolmogorov's max-flow. Runs
// opts.restarts times with randomized initial labelings and label orders (in parallel), plus a
// few candidates minimized with only a small set of labels that together allow every tet (greedy
// covers by volume). Eq. 1 often prefers more, smaller parts than needed (a part near its
// neighbours' infeasible regions lowers their data cost), so each candidate's part count is then
// lowered by moves that keep every tet feasible (merging parts, sharing a part among its
// neighbours, joining two parts of one label). Parts are kept double height fields as they are
// formed: with `directions` (those `field` was computed for), the lines of each label along its
// direction (LineSteps) constrain every expansion move and every part-removing move, so neither
// puts a part between two pieces of a label along that label's direction. The best candidate
// has the fewest parts, ties
// broken by the smallest variance of part volumes, then by energy, then by index (decompose()
// chooses again among the first-ranked candidates, by how close to double height fields each
// comes once repaired). Labels are
// the candidate directions only: a direction whose feasible set equals a lower-indexed one's,
// or lies strictly inside another's, can be replaced by it without raising the energy, and is
// dropped. Tets feasible for no direction take no part in eq. 1.
// Pre: field was computed on `tets`, which has adjacency. Throws Error{InvalidOptions} when
// opts.validate() does, Error{InvalidInput} when the field's or the adjacency's size does not
// match the tets.
Labeling segment(const TetMesh& tets, const AccessibilityField& field,
                 const std::vector<Vec3>& directions, const SegmentOptions& opts = {},
                 const Progress& progress = {});

// --- The multi-label solver under segment(), usable on any graph ---

// A Potts term: `weight` is paid when nodes a and b get different labels.
struct PottsEdge {
  std::int32_t a = 0, b = 0;
  double weight = 0.0;  // >= 0
};

// Lines through the nodes along one label's direction: up[i] is the node the line from node i
// along the direction enters next, down[i] the one against it; -1 where the line leaves the
// nodes. A part of one label is a double height field along its direction when no line meets
// it, leaves it and meets it again.
struct LineSteps {
  std::vector<std::int32_t> up, down;
};

// Minimize over labelings l: sum_i data(i, l_i) + sum_edges weight [l_a != l_b]
//                           + sum over the distinct labels used of label_cost[label].
struct LabelProblem {
  std::int32_t num_nodes = 0, num_labels = 0;
  // data[l * num_nodes + i]: cost of giving node i label l; +infinity forbids it. Label-major,
  // so the costs of one label are contiguous. Every node needs at least one finite cost.
  std::vector<double> data;
  std::vector<PottsEdge> edges;    // a pair may appear several times: its weights add up
  std::vector<double> label_cost;  // num_labels values, >= 0
  // Optional lines per label (see LineSteps); when set, an expansion move opens no gap in a
  // label's nodes along its lines: a node taking label a brings along the nodes between it and
  // a's nodes ahead or behind it, and a node leaving label b from inside b's stretch of a line
  // takes the rest of that stretch, ahead of it, along. Called from several threads.
  std::function<const LineSteps&(std::int32_t label)> line_steps;
};

// Energy of `labels` (one per node); +infinity when a node has a forbidden or out-of-range
// label or the sizes do not match.
double labeling_energy(const LabelProblem& problem, const std::vector<std::int32_t>& labels);

// Alpha-expansion with label costs (Delong et al. 2012) from `restarts` random initial
// labelings, in parallel; returns the labeling of lowest energy (ties: first restart). Problems
// over 500 nodes are first solved on recursively clustered versions of themselves (a cluster
// allows only the labels all its nodes allow), then refined level by level with expansions of
// the labels in use on a band around the label boundaries. The result depends on (problem, seed,
// restarts) only, not on the thread count.
// Throws Error{InvalidInput} when the sizes do not match, an edge is out of range or a node has
// no allowed label, Error{InvalidOptions} for a negative weight or label cost or restarts < 1.
std::vector<std::int32_t> minimize_labeling(const LabelProblem& problem, std::uint64_t seed,
                                            std::int32_t restarts = 1);

}  // namespace dhfcast
