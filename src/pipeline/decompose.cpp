#include <algorithm>
#include <chrono>
#include <string>

#include "dhfcast/directions.h"
#include "dhfcast/error.h"
#include "dhfcast/pipeline.h"
#include "dhfcast/refine.h"
#include "dhfcast/stop.h"

namespace dhfcast {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Distinct directions a labeling uses.
std::int32_t count_labels(std::vector<std::int32_t> label) {
  std::sort(label.begin(), label.end());
  label.erase(std::unique(label.begin(), label.end()), label.end());
  return static_cast<std::int32_t>(
      std::count_if(label.begin(), label.end(), [](std::int32_t l) { return l >= 0; }));
}

}  // namespace

void validate_options(const DecomposeOptions& o) {
  o.tets.validate();
  require_option(o.directions >= 6 && o.directions <= 4096,
                 "--directions must be between 6 and 4096");
  o.access.validate();
  o.segment.validate();
  o.refine.validate();
  if (o.make_molds) o.molds.validate();
}

Decomposition decompose(const TriMesh& solid, const DecomposeOptions& opts,
                        const StageProgress& progress) {
  validate_options(opts);
  // Each progress report is also where a stop (--timeout) is honoured.
  auto report = [&](const std::string& stage, double f) {
    throw_if_stop_requested();
    if (progress) progress(stage, f);
  };
  // Stages report their own progress strictly inside (0, 1): start and end are said here.
  auto inner = [&](const std::string& stage) {
    return [&, stage](double f) { report(stage, std::clamp(f, 1e-6, 0.999)); };
  };
  Decomposition d;

  // --- 1. tetrahedralize ---
  auto t0 = Clock::now();
  report("tetrahedralize", 0.0);
  d.tets = tetrahedralize(solid, opts.tets);
  report("tetrahedralize", 1.0);
  d.timings.tetrahedralize = seconds_since(t0);

  // --- 2. accessibility ---
  t0 = Clock::now();
  d.directions = fibonacci_directions(opts.directions);
  report("accessibility", 0.0);
  d.access =
      compute_accessibility(solid, d.tets, d.directions, opts.access, inner("accessibility"));
  report("accessibility", 1.0);
  d.timings.accessibility = seconds_since(t0);

  // --- 3. segmentation ---
  t0 = Clock::now();
  report("segmentation", 0.0);
  d.labeling = segment(d.tets, d.access, d.directions, opts.segment, inner("segmentation"));
  report("segmentation", 1.0);
  d.timings.segmentation = seconds_since(t0);

  // --- 4. parts: the candidates refined, the best kept ---
  t0 = Clock::now();
  report("parts", 0.0);
  static_cast<Refinement&>(d) = refine(solid, d.tets, d.directions, d.access, d.labeling,
                                       opts.access, opts.segment, opts.refine, inner("parts"));
  const LabelingCandidate& kept = d.labeling.candidates.at(d.kept_candidate);
  d.labeling.best_restart = kept.restart;
  d.labeling.energy = kept.energy;
  d.labeling.num_components = kept.parts;
  d.labeling.num_labels = count_labels(kept.label);
  d.labeling.label = kept.label;
  report("parts", 1.0);
  d.timings.parts = seconds_since(t0);

  // --- 5. molds ---
  if (opts.make_molds) {
    t0 = Clock::now();
    report("molds", 0.0);
    MoldOptions molds = opts.molds;
    molds.epsilon_mm = opts.access.epsilon_mm;
    d.molds = build_molds(d.parts, molds);
    report("molds", 1.0);
    d.timings.molds = seconds_since(t0);
  }
  return d;
}

}  // namespace dhfcast
