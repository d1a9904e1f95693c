#include "core/experiment/plotting.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <unistd.h>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <sstream>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/common/subprocess.h"
#include "core/experiment/sweep_runner.h"

namespace marglab::experiment {

std::string findPlottingPython() {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("MARGLAB_PYTHON"); env != nullptr && env[0] != '\0') {
    candidates.push_back(env);
  }
  candidates.insert(candidates.end(), {"/usr/bin/python3", "python3"});
  for (const std::string& candidate : candidates) {
    if (probeSucceeds({candidate, "-c", "import matplotlib, h5py, numpy"})) return candidate;
  }
  return {};
}

// Runs the plotting script; returns the exit code (1 when no suitable Python exists).
int runPlot(const PlotRequest& request) {
  namespace fs = std::filesystem;
  for (const std::string& dir : request.dirs) {
    if (!fs::is_regular_file(fs::path(dir) / "index.csv")) {
      throw InputError((fs::path(dir) / "index.csv").string(), 0,
                       "no such file: not a sweep folder (run `marglab sweep` first)");
    }
  }
  std::stringstream list(request.figures);
  for (std::string f; std::getline(list, f, ',');) {
    static const std::set<std::string> kFigures = {
        "fig1", "fig4",     "fig4_yaw",    "fig5",           "fig6",
        "fig7", "sparsify", "noise_sigma", "ba_convergence", "ba_profile"};
    if (kFigures.count(f) == 0) {
      throw UsageError(
          "--figure takes fig1, fig4, fig4_yaw, fig5, fig6, fig7, sparsify, noise_sigma, "
          "ba_convergence, ba_profile (comma-separated), not '" +
          f + "'");
    }
  }
  const std::string script = std::string(sourceDir()) + "/tools/scripts/plot_paper.py";
  if (access(script.c_str(), R_OK) != 0) throw InputError(script, 0, "plotting script not found");
  const std::string python = findPlottingPython();
  if (python.empty()) {
    fmt::print(stderr,
               "marglab plot: no Python with matplotlib, h5py and numpy (tried $MARGLAB_PYTHON, "
               "/usr/bin/python3, python3). Install them:\n"
               "  sudo apt-get install python3-matplotlib python3-h5py python3-numpy\n"
               "or: python3 -m pip install matplotlib h5py numpy  (then set MARGLAB_PYTHON to that "
               "interpreter if it is not /usr/bin/python3)\n");
    return 1;
  }
  const std::string out =
      request.out.empty()
          ? "notebooks-out/" + fs::path(request.dirs.front()).lexically_normal().filename().string()
          : request.out;
  prepareOutputFolder(out, "--out");
  std::vector<std::string> args = {python,          script,
                                   "--out",         out,
                                   "--figures",     request.figures,
                                   "--vio-dataset", request.vio_dataset,
                                   "--vo-dataset",  request.vo_dataset};
  args.insert(args.end(), request.dirs.begin(), request.dirs.end());
  const int code = runHelper(args);
  if (code != 0) {
    fmt::print(stderr, "marglab plot: {} failed (exit {})\n", script, code);
    return 1;
  }
  return 0;
}

}  // namespace marglab::experiment
