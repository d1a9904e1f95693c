// `marglab notebooks results/NAME [--out DIR]`: executes the notebooks (notebooks/run.ipynb once
// per run, sweep.ipynb, precision.ipynb) headlessly on a sweep folder into
// notebooks-out/<sweep>/*.html and *.ipynb (with outputs), through tools/scripts/run_notebooks.py
// (Jupyter's nbclient + nbconvert) with a Python 3 that has Jupyter, pandas, h5py, numpy and
// matplotlib (found among $MARGLAB_PYTHON, /usr/bin/python3 and python3 on PATH).

#include <fmt/core.h>
#include <fmt/format.h>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/common/subprocess.h"
#include "core/experiment/sweep_index.h"
#include "core/experiment/sweep_runner.h"
#include "core/experiment/tables.h"
#include "tools/analysis.h"
#include "tools/command.h"
#include "tools/option_checks.h"

namespace marglab::cli {

namespace fs = std::filesystem;

std::string defaultAnalysisOut(const std::string& sweep_dir) {
  return "notebooks-out/" + fs::path(sweep_dir).lexically_normal().filename().string();
}

std::string findPythonWith(const std::vector<std::string>& modules) {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("MARGLAB_PYTHON"); env != nullptr && env[0] != '\0') {
    candidates.push_back(env);
  }
  candidates.insert(candidates.end(), {"/usr/bin/python3", "python3"});
  // find_spec, not import: as fast as a directory lookup even for Jupyter's heavy modules.
  const std::string probe = fmt::format(
      "import importlib.util, sys; sys.exit(any(importlib.util.find_spec(m) is None for m in "
      "['{}']))",
      fmt::join(modules, "', '"));
  for (const std::string& candidate : candidates) {
    if (probeSucceeds({candidate, "-c", probe})) return candidate;
  }
  return {};
}

void requireSweepFolder(const std::string& dir) {
  const std::string index = (fs::path(dir) / "index.csv").string();
  if (!fs::is_regular_file(index)) {
    throw InputError(index, 0,
                     fs::is_directory(dir)
                         ? "no such file: not a sweep folder (run `marglab sweep` first)"
                         : "no such file: the sweep folder does not exist");
  }
  const auto rows = experiment::readIndex(index);  // throws InputError(index, line, ...)
  if (rows.empty()) throw InputError(index, 0, "the sweep has no runs");
}

int runNotebooks(const NotebooksRequest& request) {
  requireSweepFolder(request.dir);
  const std::string out = request.out.empty() ? defaultAnalysisOut(request.dir) : request.out;
  prepareOutputFolder(out, "--out");  // before the minutes of notebooks, not after
  const std::string source = sourceDir();
  const std::string script = source + "/tools/scripts/run_notebooks.py";
  if (access(script.c_str(), R_OK) != 0) throw InputError(script, 0, "no such file");
  for (const char* name : {"run", "sweep", "precision"}) {
    const std::string notebook = source + "/notebooks/" + name + ".ipynb";
    if (access(notebook.c_str(), R_OK) != 0) throw InputError(notebook, 0, "no such notebook");
  }
  const std::string python = findPythonWith(
      {"nbformat", "nbclient", "nbconvert", "ipykernel", "pandas", "h5py", "numpy", "matplotlib"});
  if (python.empty()) {
    fmt::print(stderr,
               "marglab notebooks: no Python 3 with Jupyter (nbconvert, nbclient, ipykernel), "
               "pandas, h5py, numpy and matplotlib (tried $MARGLAB_PYTHON, /usr/bin/python3, "
               "python3). Install the Debian packages:\n"
               "  sudo apt-get install jupyter-nbconvert python3-ipykernel python3-pandas "
               "python3-h5py python3-numpy python3-matplotlib\n"
               "(or run scripts/setup.sh; another interpreter: set MARGLAB_PYTHON)\n");
    return 1;
  }
  // The sweep notebook shows the paper's tables beside ours: write them when the sweep has none.
  if (!fs::is_regular_file(fs::path(request.dir) / "tables" / "tables.csv")) {
    experiment::TablesRequest tables;
    tables.dirs = {request.dir};
    experiment::writeTables(tables, nullptr);
  }
  // The runner and its Jupyter kernels end with this process (subprocess.h).
  const int code = runHelper({python, script, "--sweep", request.dir, "--out", out, "--notebooks",
                              source + "/notebooks", "--runs", request.runs, "--jobs",
                              std::to_string(request.jobs)});
  if (code == 2) throw UsageError("marglab notebooks: see the message above");
  if (code != 0) {
    fmt::print(stderr, "marglab notebooks: {} failed (exit {})\n", script, code);
    return 1;
  }
  fmt::print("notebooks: {}/sweep.html, precision.html, runs/*.html (and .ipynb)\n", out);
  return 0;
}

namespace {

const bool kRegistered = registerCommand(
    {"notebooks",
     "Execute the notebooks (one run, the sweep, f32 vs f64) on a sweep folder into "
     "notebooks-out/<sweep>/*.html and .ipynb",
     42, [](CLI::App& sub) -> CommandRun {
       auto request = std::make_shared<NotebooksRequest>();
       sub.add_option("dir", request->dir, "Sweep folder (results/NAME)")->required();
       sub.add_option("-o,--out", request->out,
                      "Output folder (default: notebooks-out/<name of the sweep folder>)");
       sub.add_option("--runs", request->runs,
                      "Runs that get their own notebook: all, none, or comma-separated run ids")
           ->capture_default_str();
       sub.add_option("-j,--jobs", request->jobs, "Notebooks in parallel (0: number of cores)")
           ->capture_default_str()
           ->check(cli::jobCount());
       return [request] {
         const auto start = std::chrono::steady_clock::now();
         const int code = runNotebooks(*request);
         fmt::print(
             "notebooks: {:.1f} s\n",
             std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
         return code;
       };
     }});

}  // namespace
}  // namespace marglab::cli
