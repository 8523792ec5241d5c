// dhfcast command line: parses options, runs the stages in order, shows progress, maps errors to
// messages and exit codes.
#include <oneapi/tbb/global_control.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "dhfcast/check.h"
#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "dhfcast/pipeline.h"
#include "dhfcast/report.h"
#include "dhfcast/stop.h"
#include "dhfcast/viewer.h"

using namespace dhfcast;

namespace {

enum ExitCode {
  kOk = 0,
  kFailure = 1,
  kUsage = 2,
  kBadInput = 3,
  kIo = 4,
  kCheckFailed = 5,
  kTimedOut = 6
};

int exit_code(ErrorCode code) {
  switch (code) {
    case ErrorCode::InvalidInput:
      return kBadInput;
    case ErrorCode::InvalidOptions:
      return kUsage;
    case ErrorCode::Io:
      return kIo;
    case ErrorCode::Stopped:
      return kTimedOut;
    default:
      return kFailure;
  }
}

using Clock = std::chrono::steady_clock;

// --timeout: a stop is asked of the stages at the deadline; they honour it at their next check
// point (Error{Stopped}, unwinding). A stage that reaches none within the grace period (a long
// CGAL call) is not waited for: the process ends with kTimedOut, unless an output folder is being
// written, which is then let finish (a stop is never honoured within one, so no half-written
// folder is left either way).
class Watchdog {
 public:
  static constexpr double kGraceSeconds = 5.0;

  explicit Watchdog(double seconds) : seconds_(seconds) {
    if (seconds > 0) thread_ = std::thread([this] { watch(); });
  }
  ~Watchdog() {
    {
      const std::lock_guard lock(mutex_);
      done_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;

  std::string message() const {
    char text[96];
    std::snprintf(text, sizeof text, "time limit of %g s reached (--timeout); nothing written",
                  seconds_);
    return text;
  }

 private:
  void watch() {
    std::unique_lock lock(mutex_);
    auto wait = [&](double s) {
      return wake_.wait_for(lock, std::chrono::duration<double>(s), [this] { return done_; });
    };
    if (wait(seconds_)) return;
    request_stop();
    if (wait(kGraceSeconds)) return;
    std::unique_lock writing(output_write_mutex(), std::try_to_lock);
    if (!writing.owns_lock()) return;  // a folder is being written: the run is ending
    // Holding the write lock, no folder is begun: none of ours is half-written.
    const std::string line = "dhfcast: error: " + message() + "\n";
    [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, line.data(), line.size());
    std::_Exit(kTimedOut);
  }

  double seconds_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread thread_;
};

// Stage progress on stderr: one line per stage; on a terminal, a live percentage.
class ProgressPrinter {
 public:
  explicit ProgressPrinter(bool quiet) : quiet_(quiet), tty_(::isatty(STDERR_FILENO)) {}
  void operator()(const std::string& stage, double f) {
    if (quiet_) return;
    if (f <= 0.0) {
      stage_start_ = Clock::now();
      last_percent_ = -1;
      if (tty_) std::fprintf(stderr, "  %-15s   0%%", stage.c_str());
      return;
    }
    if (f >= 1.0) {
      const double s = std::chrono::duration<double>(Clock::now() - stage_start_).count();
      std::fprintf(stderr, "%s  %-15s done in %.1f s\n", tty_ ? "\r" : "", stage.c_str(), s);
      return;
    }
    const int percent = static_cast<int>(f * 100);
    const int step = tty_ ? 1 : 25;  // logs get a few lines, terminals a live counter
    if (percent / step == last_percent_ / step) return;
    last_percent_ = percent;
    if (tty_)
      std::fprintf(stderr, "\r  %-15s %3d%%", stage.c_str(), percent);
    else
      std::fprintf(stderr, "  %-15s %3d%%\n", stage.c_str(), percent);
  }

 private:
  bool quiet_, tty_;
  Clock::time_point stage_start_;
  int last_percent_ = -1;
};

// --threads: CLI11's NonNegativeNumber would print DBL_MAX as the upper bound.
const CLI::Range kThreadRange(0, 1024);
// --timeout: 0 (none) to a year.
const CLI::Range kTimeoutRange(0.0, 365.0 * 24 * 3600);
// --size: a longest side load_solid() does not call absurd (0.1 mm to 100 m).
const CLI::Range kSizeRangeMm(0.1, 100000.0);

// The names --units takes, and the size of one unit in mm.
const std::map<std::string, double> kUnitsToMm = {
    {"mm", 1.0}, {"cm", 10.0}, {"m", 1000.0}, {"in", 25.4}};

struct CliOptions {
  std::string input, outdir;
  double scale = 1.0;
  double size_mm = 0.0;
  std::string units = "mm";
  int threads = 0;
  bool quiet = false, force = false;
  DecomposeOptions decompose;
};

// Adds report.html to a folder being written (decompose, molds). The folder is good without it:
// a failure is a warning, not a lost result.
void add_report(const std::string& folder) {
  try {
    write_report(folder);
  } catch (const Error& e) {
    std::fprintf(stderr, "dhfcast: warning: report.html not written: %s\n", e.what());
  }
}

// Warns about each part whose mold could not be built; true when all were.
bool report_molds(const std::vector<Mold>& molds) {
  bool all = true;
  for (const Mold& m : molds)
    if (!m.error.empty()) {
      std::fprintf(stderr, "dhfcast: warning: no mold for part %d: %s\n", m.part, m.error.c_str());
      all = false;
    }
  return all;
}

int run_decompose(const CliOptions& cli) {
  const auto t_start = Clock::now();
  std::unique_ptr<oneapi::tbb::global_control> threads;
  if (cli.threads > 0)
    threads = std::make_unique<oneapi::tbb::global_control>(
        oneapi::tbb::global_control::max_allowed_parallelism, cli.threads);

  validate_options(cli.decompose);
  check_output_location(cli.outdir, cli.force, cli.input);

  LoadOptions load;
  load.scale = cli.scale;
  load.size_mm = cli.size_mm;
  load.units_to_mm = kUnitsToMm.at(cli.units);
  const LoadedSolid solid = load_solid(cli.input, load);
  const double load_s = std::chrono::duration<double>(Clock::now() - t_start).count();
  const Box3 bbox = bounding_box(solid.mesh.vertices);
  const Vec3 size = bbox.max - bbox.min;
  const double volume_mm3 = signed_volume(solid.mesh);
  if (!cli.quiet) {
    std::fprintf(stderr, "dhfcast: %s: %zu triangles, %.1f x %.1f x %.1f mm, %.0f mm3%s\n",
                 cli.input.c_str(), solid.mesh.triangles.size(), size.x(), size.y(), size.z(),
                 volume_mm3, solid.flipped ? " (was inside out: flipped)" : "");
  }

  ProgressPrinter printer(cli.quiet);
  const Decomposition d = decompose(solid.mesh, cli.decompose, std::ref(printer));

  InputInfo info{cli.input, static_cast<std::int64_t>(solid.mesh.triangles.size()), volume_mm3,
                 bbox, solid.flipped};
  const double total_s = std::chrono::duration<double>(Clock::now() - t_start).count();
  write_output(cli.outdir, decomposition_json(info, cli.decompose, d, load_s, total_s), d,
               cli.force, add_report);

  if (!d.assembly.found) std::fprintf(stderr, "dhfcast: warning: %s\n", d.assembly.message.c_str());
  report_molds(d.molds);
  // Carving is part of the result: the user glues around these holes.
  for (const CarvedVoid& v : d.carving.voids)
    std::fprintf(stderr,
                 "dhfcast: note: carved a %.3g mm3 hole inside part %d where it was no double "
                 "height field (paper 4.3.1; see carving in decomposition.json)\n",
                 v.volume_mm3, v.part);
  if (d.carving.gap_lines_after > 0)
    std::fprintf(stderr,
                 "dhfcast: warning: %d lines along their part's direction still meet it more than "
                 "once (%zu patches could not be mended: see carving.refused in "
                 "decomposition.json)\n",
                 d.carving.gap_lines_after, d.carving.refused.size());
  // Such a part's outer surface is the tet mesh's boundary, within a tet of the input's.
  for (std::size_t i = 0; i < d.solid_cut.problem.size(); ++i)
    if (!d.solid_cut.problem[i].empty())
      std::fprintf(stderr,
                   "dhfcast: warning: part %zu was not cut from the input (%s): its outer surface "
                   "is the tet mesh's, up to a tet away from the input's (try another --seed)\n",
                   i, d.solid_cut.problem[i].c_str());
  const std::vector<std::int32_t> tiny = tiny_parts(d.parts, volume_mm3);
  for (const Part& p : d.parts) {
    if (std::find(tiny.begin(), tiny.end(), p.id) == tiny.end()) continue;
    std::fprintf(stderr,
                 "dhfcast: warning: part %d is %.2g %% of the volume (%.3g mm3), too small to be "
                 "worth a mold of its own: every labeling tried has one, and no neighbour's "
                 "direction allows its volume (try another --seed)\n",
                 p.id, 100.0 * p.volume_mm3 / volume_mm3, p.volume_mm3);
  }
  for (const InaccessibleRegion& r : d.inaccessible_regions)
    std::fprintf(stderr,
                 "dhfcast: note: %d tets (%.1f mm3) are accessible from no direction; that "
                 "region was decomposed on its own%s\n",
                 r.tets, r.volume_mm3,
                 r.still_inaccessible_tets ? " (some tets merged into a neighbour part)" : "");
  if (!cli.quiet) {
    std::fprintf(stderr, "dhfcast: %zu parts from %zu tets, written to %s\n", d.parts.size(),
                 d.tets.tets.size(), cli.outdir.c_str());
    for (const Part& p : d.parts) {
      const Vec3& r = d.assembly.removal.at(p.id);
      std::fprintf(stderr,
                   "  part %3d  direction (%+.3f, %+.3f, %+.3f)  leaves along (%+.3f, %+.3f, "
                   "%+.3f)  %10.1f mm3\n",
                   p.id, p.direction.x(), p.direction.y(), p.direction.z(), r.x(), r.y(), r.z(),
                   p.volume_mm3);
    }
    std::string order;
    for (std::int32_t id : d.assembly.order) order += " " + std::to_string(id);
    std::fprintf(stderr, "  assembly order:%s%s\n", order.c_str(),
                 d.assembly.found ? "" : " (not collision-free)");
    std::fprintf(stderr,
                 "  time: load %.1f s, tetrahedralize %.1f s, accessibility %.1f s, "
                 "segmentation %.1f s, parts %.1f s, molds %.1f s, total %.1f s\n",
                 load_s, d.timings.tetrahedralize, d.timings.accessibility, d.timings.segmentation,
                 d.timings.parts, d.timings.molds, total_s);
  }
  return kOk;
}

int run_molds(const std::string& outdir, const MoldOptions& opts, int threads_wanted, bool quiet) {
  std::unique_ptr<oneapi::tbb::global_control> threads;
  if (threads_wanted > 0)
    threads = std::make_unique<oneapi::tbb::global_control>(
        oneapi::tbb::global_control::max_allowed_parallelism, threads_wanted);
  const auto t0 = Clock::now();
  const std::vector<Mold> molds = rebuild_molds(outdir, opts, add_report);
  report_molds(molds);
  if (!quiet)
    std::fprintf(stderr, "dhfcast: molds of %zu parts written to %s/molds in %.1f s\n",
                 molds.size(), outdir.c_str(),
                 std::chrono::duration<double>(Clock::now() - t0).count());
  return kOk;
}

int run_check(const CheckOptions& opts, bool json, bool html) {
  const CheckReport report = check_output(opts);
  std::fputs((json ? format_json(report) : format_text(report)).c_str(), stdout);
  if (html) {
    std::fflush(stdout);
    try {
      write_report(opts.outdir, format_json(report));
    } catch (const Error& e) {
      // A folder too broken for the page has failed its contract check: the verdict says so.
      std::fprintf(stderr, "dhfcast: warning: report.html not written: %s\n", e.what());
    }
  }
  return report.passed() ? kOk : kCheckFailed;
}

// True when `program` is an executable file on PATH.
bool on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "";
  for (std::size_t start = 0; start <= dirs.size();) {
    const std::size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::string file = (end > start ? dirs.substr(start, end - start) : ".") + "/" + program;
    if (::access(file.c_str(), X_OK) == 0) return true;
    start = end + 1;
  }
  return false;
}

int run_report(const std::string& outdir, bool png, bool quiet) {
  // Fail before writing anything when the previews cannot be drawn.
  if (png && !on_path("chromium"))
    throw Error(ErrorCode::Io,
                "--png needs Chromium (Debian package chromium, installed by "
                "scripts/install-deps.sh): no chromium on PATH");
  write_report(outdir);
  if (png) render_previews(outdir);
  if (!quiet)
    std::fprintf(stderr, "dhfcast: wrote %s/report.html%s\n", outdir.c_str(),
                 png ? ", preview.png and molds.png" : "");
  return kOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "dhfcast: split a closed 3D model into parts that each cast in a two-piece "
      "rigid mold"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "dhfcast 0.1.0");
  double timeout_s = 0.0;
  app.add_option("--timeout", timeout_s,
                 "Stop after this many seconds (exit code 6, nothing written; 0: no limit)")
      ->check(kTimeoutRange)
      ->capture_default_str();
  // Given before or after the command's name.
  app.fallthrough();

  CliOptions cli;
  DecomposeOptions& o = cli.decompose;
  CLI::App* dec = app.add_subcommand(
      "decompose", "Split INPUT into double-height-field parts and write them to OUTDIR");
  dec->add_option("input", cli.input, "Closed triangle mesh: .stl, .obj, .ply or .off")->required();
  dec->add_option("-o,--output", cli.outdir, "Output folder (must not exist unless --force)")
      ->required();
  dec->add_option("--epsilon", o.access.epsilon_mm, "Undercut tolerance in mm")
      ->capture_default_str();
  dec->add_option("--directions", o.directions, "Number of candidate directions")
      ->capture_default_str();
  dec->add_option("--tets", o.tets.target_tets, "Target number of tetrahedra")
      ->capture_default_str();
  dec->add_option("--facet-distance", o.tets.facet_distance_mm,
                  "Max distance of the tet mesh boundary from the surface, mm")
      ->capture_default_str();
  dec->add_option("--alpha", o.segment.alpha, "Data cost weight")->capture_default_str();
  dec->add_option("--c", o.segment.c_mm, "Data cost width in mm")->capture_default_str();
  dec->add_option("--beta", o.segment.beta_mm, "Smoothness weight in mm")->capture_default_str();
  dec->add_option("--lambda", o.segment.lambda, "Label cost weight")->capture_default_str();
  dec->add_option("--restarts", o.segment.restarts, "Randomized graph-cut runs")
      ->capture_default_str();
  dec->add_option("--candidates", o.refine.candidates,
                  "Candidate labelings repaired; the one closest to double height fields is kept")
      ->capture_default_str();
  dec->add_option("--seed", o.segment.seed, "Random seed")->capture_default_str();
  dec->add_option("--smoothing", o.refine.smoothing.iterations,
                  "Interface smoothing steps (0: keep the tet faces)")
      ->capture_default_str();
  bool tet_surface = false;
  dec->add_flag("--tet-surface", tet_surface,
                "Keep the tet mesh's boundary as the parts' outer surface instead of cutting "
                "the parts from the exact input solid");
  bool no_molds = false;
  dec->add_flag("--no-molds", no_molds, "Do not build the mold halves");
  bool no_carve = false;
  dec->add_flag("--no-carve", no_carve,
                "Do not mend the lines that still meet a part twice on the final meshes (by "
                "filling, yielding, or carving a void; see README)");
  auto add_mold_options = [](CLI::App* cmd, MoldOptions& m) {
    cmd->add_option("--wall", m.wall_mm, "Mold wall thickness around the cavity, mm")
        ->capture_default_str();
    cmd->add_option("--sprue-diameter", m.sprue_diameter_mm, "Pour sprue diameter, mm")
        ->capture_default_str();
    cmd->add_option("--vent-diameter", m.vent_diameter_mm, "Air vent diameter, mm")
        ->capture_default_str();
    cmd->add_option("--key-clearance", m.key_clearance_mm,
                    "Registration key clearance per side, mm")
        ->capture_default_str();
  };
  add_mold_options(dec, o.molds);
  CLI::Option* dec_scale =
      dec->add_option("--scale", cli.scale, "Multiply the input's coordinates by this")
          ->capture_default_str();
  CLI::Option* dec_units = dec->add_option("--units", cli.units, "Units of the input file")
                               ->check(CLI::IsMember(kUnitsToMm))
                               ->capture_default_str();
  dec->add_option("--size", cli.size_mm,
                  "Scale the input so that its longest bounding-box side is this many mm")
      ->check(kSizeRangeMm)
      ->excludes(dec_scale)
      ->excludes(dec_units);
  dec->add_option("--threads", cli.threads, "Worker threads (0: all cores)")->check(kThreadRange);
  dec->add_flag("-q,--quiet", cli.quiet, "Print only errors and warnings");
  dec->add_flag("-f,--force", cli.force, "Replace OUTDIR if it exists");

  MoldOptions mold_opts;
  std::string mold_outdir;
  int mold_threads = 0;
  bool mold_quiet = false;
  CLI::App* mld = app.add_subcommand(
      "molds", "Build the mold halves of an existing OUTDIR again, with other mold options");
  mld->add_option("outdir", mold_outdir, "Folder written by dhfcast decompose")->required();
  add_mold_options(mld, mold_opts);
  mld->add_option("--threads", mold_threads, "Worker threads (0: all cores)")->check(kThreadRange);
  mld->add_flag("-q,--quiet", mold_quiet, "Print only errors and warnings");

  CheckOptions check_opts;
  bool check_json = false;
  CLI::App* chk =
      app.add_subcommand("check",
                         "Verify an output folder independently: contract, solids, coverage, DHF, "
                         "assembly, molds, fidelity");
  chk->add_option("outdir", check_opts.outdir, "Folder written by dhfcast decompose")->required();
  chk->add_option("--input", check_opts.input_mesh,
                  "The decomposed mesh: enables the gap, outside and fidelity figures");
  double check_scale = 1.0;
  std::string check_units = "mm";
  CLI::Option* chk_scale =
      chk->add_option("--scale", check_scale,
                      "As given to decompose: multiplies --input's coordinates")
          ->capture_default_str();
  CLI::Option* chk_units =
      chk->add_option("--units", check_units, "As given to decompose: units of the --input file")
          ->check(CLI::IsMember(kUnitsToMm))
          ->capture_default_str();
  chk->add_option("--size", check_opts.input_size_mm,
                  "As given to decompose: longest bounding-box side of --input, mm")
      ->check(kSizeRangeMm)
      ->excludes(chk_scale)
      ->excludes(chk_units);
  chk->add_flag("--json", check_json, "Print all figures as JSON");
  bool check_html = false;
  chk->add_flag("--html", check_html,
                "Also write OUTDIR/report.html with the verdicts, the places they name marked");
  chk->add_option("--epsilon", check_opts.epsilon_mm, "Undercut / contact tolerance in mm")
      ->capture_default_str();
  chk->add_option("--max-volume-error", check_opts.max_volume_error,
                  "Allowed |sum of part volumes - input volume| / input volume")
      ->capture_default_str();
  chk->add_option("--max-overlap", check_opts.max_overlap_fraction,
                  "Allowed volume inside two or more parts, fraction of the input")
      ->capture_default_str();
  chk->add_option("--max-gap", check_opts.max_gap_fraction,
                  "Allowed input volume inside no part, fraction")
      ->capture_default_str();
  chk->add_option("--max-outside", check_opts.max_outside_fraction,
                  "Allowed part volume outside the input, fraction")
      ->capture_default_str();
  chk->add_option("--max-dhf-violations", check_opts.max_dhf_violation_fraction,
                  "Allowed fraction of lines along d meeting a part in several intervals")
      ->capture_default_str();
  chk->add_option("--min-mold-coverage", check_opts.min_mold_surface_coverage,
                  "Required fraction of the part surface covered by the mold halves")
      ->capture_default_str();
  chk->add_option("--max-fidelity", check_opts.max_fidelity_p99_rel,
                  "Allowed 99th-percentile surface distance, fraction of the bbox diagonal")
      ->capture_default_str();
  chk->add_option("--seed", check_opts.seed, "Seed of the sampling")->capture_default_str();
  int check_threads = 0;
  chk->add_option("--threads", check_threads, "Worker threads (0: all cores)")->check(kThreadRange);

  std::string report_outdir;
  bool report_png = false, report_quiet = false;
  CLI::App* rep = app.add_subcommand(
      "report",
      "Write OUTDIR/report.html, a 3D view of the parts, their assembly and molds "
      "that works offline");
  rep->add_option("outdir", report_outdir, "Folder written by dhfcast decompose")->required();
  rep->add_flag("--png", report_png,
                "Also write preview.png (the parts) and molds.png, rendered by headless Chromium");
  rep->add_flag("-q,--quiet", report_quiet, "Print only errors and warnings");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kOk : kUsage;
  }

  Watchdog watchdog(timeout_s);
  try {
    if (dec->parsed()) {
      o.tets.seed = o.segment.seed;
      o.make_molds = !no_molds;
      o.refine.exact_outer_surface = !tet_surface;
      o.refine.carve = !no_carve;
      return run_decompose(cli);
    }
    if (mld->parsed()) return run_molds(mold_outdir, mold_opts, mold_threads, mold_quiet);
    if (rep->parsed()) return run_report(report_outdir, report_png, report_quiet);
    if (chk->parsed()) {
      std::unique_ptr<oneapi::tbb::global_control> threads;
      if (check_threads > 0)
        threads = std::make_unique<oneapi::tbb::global_control>(
            oneapi::tbb::global_control::max_allowed_parallelism, check_threads);
      check_opts.input_scale = check_scale * kUnitsToMm.at(check_units);
      return run_check(check_opts, check_json, check_html);
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "dhfcast: error: %s\n",
                 e.code() == ErrorCode::Stopped ? watchdog.message().c_str() : e.what());
    return exit_code(e.code());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "dhfcast: error: out of memory (try fewer --tets)\n");
    return kFailure;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dhfcast: error: internal: %s\n", e.what());
    return kFailure;
  }
  return kUsage;
}
