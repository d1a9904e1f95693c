// `marglab massspring`: the mass-spring experiment of Levine's marginalization primer (§6,
// Table 1, Fig. 3) — core/massspring/experiment.h measures, core/massspring/report.h builds the
// tables, JSON and HDF5 file. This verb parses the options, runs it, prints the tables (or JSON
// with --json), writes the HDF5 file with -o, and a figure of the final state to notebooks-out/
// through tools/scripts/plot_massspring.py.

#include <fmt/core.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/common/subprocess.h"
#include "core/massspring/experiment.h"
#include "core/massspring/report.h"
#include "tools/command.h"
#include "tools/option_checks.h"
#include "tools/output_checks.h"

namespace marglab {
namespace {

using massspring::MassSpringSystem;

struct Options {
  int grid = 5;
  std::string sizes = "5,10,20,50,100";
  int iterations = 10;
  std::string method = "sparse-schur";
  std::string single_solver = "sparse-cholesky";
  int reps = 0;  // 0: automatic
  double budget_s = 1.0;
  std::string output;
  bool json = false;
  bool no_plot = false;
  std::string plot_dir = "notebooks-out";
};

std::string findPythonWithMatplotlib() {
  for (const std::string candidate : {"/usr/bin/python3", "python3"}) {
    if (probeSucceeds({candidate, "-c", "import matplotlib"})) return candidate;
  }
  return {};
}

// The start of writeFigure's line when the script failed: the command then exits 1.
const std::string kFigureFailed = "figure failed: ";

// Returns a line to print (what was written, or why not).
std::string writeFigure(const Options& opt, const MassSpringSystem& system,
                        const std::vector<double>& final_x) {
  const std::string script = std::string(sourceDir()) + "/tools/scripts/plot_massspring.py";
  if (access(script.c_str(), R_OK) != 0) return "figure skipped: " + script + " not found";
  const std::string python = findPythonWithMatplotlib();
  if (python.empty()) {
    return "figure skipped: no Python with matplotlib among /usr/bin/python3 and python3 "
           "(install it: apt-get install python3-matplotlib, or pip install matplotlib)";
  }
  char tmp[] = "/tmp/marglab-massspring-XXXXXX";
  const int fd = mkstemp(tmp);
  if (fd < 0) return "figure skipped: cannot create a temporary file";
  const std::string data = massspring::figureJson(system, final_x);
  const bool written = write(fd, data.data(), data.size()) == static_cast<ssize_t>(data.size());
  close(fd);
  std::string message;
  if (!written) {
    message = "figure skipped: cannot write the temporary file";
  } else {
    const std::vector<std::string> command = {python, script, tmp, opt.plot_dir + "/massspring"};
    message = runHelper(command) == 0
                  ? fmt::format("figure: {0}/massspring.png, {0}/massspring.pdf", opt.plot_dir)
                  : kFigureFailed + fmt::format("{}", fmt::join(command, " "));
  }
  std::remove(tmp);
  return message;
}

// The experiment's settings from the options: the scaling table by default, with --grid only if
// --sizes is given too.
massspring::ExperimentSettings settingsOf(const Options& opt, bool sizes_given, bool grid_given) {
  massspring::ExperimentSettings settings;
  if (!ceres_marg::parseMethod(opt.method, &settings.method)) {
    throw UsageError("--method must be qr, schur or sparse-schur, not '" + opt.method + "'");
  }
  if (!massspring::parseSingleSolver(opt.single_solver, &settings.single_solver)) {
    throw UsageError("--single-solver must be sparse-cholesky, dense-cholesky or dense-qr, not '" +
                     opt.single_solver + "'");
  }
  settings.grid = opt.grid;
  settings.iterations = opt.iterations;
  settings.reps = opt.reps;
  settings.budget_s = opt.budget_s;
  if (sizes_given || !grid_given) settings.sizes = massspring::parseSizes(opt.sizes);
  massspring::checkSettings(settings);
  return settings;
}

int runMassSpring(const Options& opt, bool sizes_given, bool grid_given) {
  const massspring::ExperimentSettings settings = settingsOf(opt, sizes_given, grid_given);
  // The outputs before the measurements (issue 38: a read-only folder was found at the end).
  if (!opt.output.empty()) cli::checkOutputFile(opt.output, "-o");
  if (!opt.no_plot) prepareOutputFolder(opt.plot_dir, "--plot-dir");
  const bool progress = !opt.json && cli::stderrIsTerminal();
  const massspring::Measurements m = massspring::measure(settings, [&](int n) {
    if (progress) fmt::print(stderr, "\rscaling: {}x{} ...   ", n, n);
  });
  if (progress && !settings.sizes.empty()) fmt::print(stderr, "\r{:40}\r", "");
  std::string figure;
  if (!opt.no_plot) figure = writeFigure(opt, m.system, m.main().last.x);
  const bool figure_failed = figure.rfind(kFigureFailed, 0) == 0;
  const massspring::PrimerTable primer = massspring::loadPrimerTable();
  if (opt.json) {
    fmt::print("{}", massspring::jsonReport(m, primer));
    if (!figure.empty()) fmt::print(stderr, "{}\n", figure);
  } else {
    fmt::print("{}", massspring::textReport(m, primer));
    if (!figure.empty()) fmt::print("\n{}\n", figure);
  }
  if (!opt.output.empty()) massspring::writeResults(opt.output, m);
  return figure_failed ? 1 : 0;
}

const bool kRegistered = cli::registerCommand(
    {"massspring",
     "Mass-spring experiment (primer §6): single-stage Gauss-Newton vs two-stage with "
     "marginalization",
     80, [](CLI::App& sub) -> cli::CommandRun {
       auto opt = std::make_shared<Options>();
       CLI::Option* grid =
           sub.add_option("--grid", opt->grid, "Masses per side of the compared grid (>= 4)")
               ->capture_default_str();
       CLI::Option* sizes =
           sub.add_option("--sizes", opt->sizes,
                          "Comma-separated grid sizes of the scaling table (default when --grid is "
                          "not given; with --grid only if given)")
               ->capture_default_str();
       sub.add_option("--iterations", opt->iterations, "Gauss-Newton iterations")
           ->check(cli::intRange("a Gauss-Newton iteration count", 1, massspring::kMaxIterations))
           ->capture_default_str();
       sub.add_option("--method", opt->method, "Marginalization: qr, schur or sparse-schur")
           ->capture_default_str();
       sub.add_option("--single-solver", opt->single_solver,
                      "Linear solver of the single stage: sparse-cholesky, dense-cholesky or "
                      "dense-qr (dense: grids up to 30x30)")
           ->capture_default_str();
       sub.add_option("--reps", opt->reps,
                      "Timing repetitions per grid (0: automatic, to --budget; median and IQR "
                      "reported)")
           ->check(cli::intRange("a repetition count", 0, massspring::kMaxReps))
           ->capture_default_str();
       sub.add_option("--budget", opt->budget_s,
                      "Automatic repetitions: seconds of solves per grid (at least 11 "
                      "repetitions, at most 1000)")
           ->capture_default_str();
       sub.add_option("-o,--output", opt->output, "Write the states and timings to FILE.h5");
       sub.add_flag("--json", opt->json, "Print one JSON object instead of tables");
       sub.add_flag("--no-plot", opt->no_plot, "Do not write the figure");
       sub.add_option("--plot-dir", opt->plot_dir, "Directory of the figure")
           ->capture_default_str();
       return [opt, grid, sizes] {
         return runMassSpring(*opt, sizes->count() > 0, grid->count() > 0);
       };
     }});

}  // namespace
}  // namespace marglab
