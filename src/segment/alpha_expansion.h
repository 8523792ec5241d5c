// Alpha-expansion with label costs (Delong, Osokin, Isack, Boykov 2012) on Kolmogorov's
// max-flow: the engine of minimize_labeling() and segment().
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "dhfcast/segment.h"
#include "dhfcast/types.h"

namespace dhfcast::detail {

// The outcome of one randomized run.
struct ExpansionRun {
  std::vector<std::int32_t> labels;  // one per node
  double energy = 0.0;               // labeling_energy() of labels
};

// A validated LabelProblem in the form the expansions read it: merged CSR adjacency and a
// node-major bitset of allowed labels. Read-only once built, so concurrent runs share it.
class ExpansionSolver {
 public:
  // Throws like minimize_labeling(). Keeps a reference to `problem`, which must outlive it.
  explicit ExpansionSolver(const LabelProblem& problem);
  ~ExpansionSolver();

  // One run: cycles of expansions in a random label order until a cycle lowers the energy no
  // more. A small problem starts from a random labeling and expands every label on every node.
  // A large one starts from its coarse level's run, projected, and expands only the labels in
  // use on a band around the boundaries. Depends on (problem, seed) only.
  ExpansionRun run(std::uint64_t seed) const;

  // Runs r = 0..restarts-1 seeded by restart_seed(seed, r), in parallel. progress(fraction of
  // runs finished) is called from the calling thread only.
  std::vector<ExpansionRun> run_all(std::uint64_t seed, std::int32_t restarts,
                                    const Progress& progress) const;

 private:
  struct State;
  void build_coarse_level();
  std::vector<std::int32_t> random_labels(std::mt19937_64& rng) const;
  void set_labels(State& s, std::vector<std::int32_t> labels) const;
  void mark_band(State& s) const;
  bool expand(State& s, std::int32_t alpha) const;
  void add_line_constraints(State& s, std::int32_t alpha) const;

  const LabelProblem& problem_;
  std::int32_t n_ = 0, k_ = 0;
  // Neighbors of node i: adj_node_[adj_begin_[i] .. adj_begin_[i + 1]), sorted, each pair's
  // weights summed.
  std::vector<std::int32_t> adj_begin_, adj_node_;
  std::vector<double> adj_weight_;
  // Bit l of row i (words_ words per node): label l is allowed for node i.
  std::int32_t words_ = 0;
  std::vector<std::uint64_t> allowed_;
  // Large problems only: the coarse node of each node, the coarse problem and its solver.
  std::vector<std::int32_t> cluster_;
  std::unique_ptr<LabelProblem> coarse_problem_;
  std::unique_ptr<ExpansionSolver> coarse_;
};

// The seed of run `restart` of a multi-start minimization seeded with `seed`.
std::uint64_t restart_seed(std::uint64_t seed, std::int32_t restart);

}  // namespace dhfcast::detail
