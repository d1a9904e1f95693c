// `marglab report results/NAME [--out DIR] [--check]`: one self-contained HTML page of a sweep
// (notebooks-out/<sweep>/report.html) — its configuration, git revision, failure matrix, the
// paper's tables with ours beside them, the figures embedded, and links to each run's notebook —
// written by tools/scripts/make_report.py. With --check the page is opened in headless Chromium
// (tools/scripts/check_report.py over the DevTools protocol), screenshotted, and fails on console
// errors, network requests, or a page without its tables and figures.

#include <fmt/core.h>

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/common/subprocess.h"
#include "core/experiment/plotting.h"
#include "core/experiment/sweep_runner.h"
#include "core/experiment/tables.h"
#include "tools/analysis.h"
#include "tools/command.h"

namespace marglab::cli {

namespace fs = std::filesystem;

namespace {

bool hasFigures(const std::string& dir) {
  if (!fs::is_directory(dir)) return false;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".png" &&
        (name.rfind("fig", 0) == 0 || name.rfind("sparsify", 0) == 0)) {
      return true;
    }
  }
  return false;
}

bool chromiumAvailable() {
  for (const char* name : {"chromium", "chromium-browser", "google-chrome"}) {
    if (probeSucceeds({"sh", "-c", std::string("command -v ") + name})) return true;
  }
  return false;
}

}  // namespace

int runReport(const ReportRequest& request) {
  requireSweepFolder(request.dir);
  const std::string scripts = std::string(sourceDir()) + "/tools/scripts";
  const std::string make_report = scripts + "/make_report.py";
  if (access(make_report.c_str(), R_OK) != 0) throw InputError(make_report, 0, "no such file");
  const std::string python = findPythonWith({"pandas", "h5py", "numpy"});
  if (python.empty()) {
    fmt::print(stderr,
               "marglab report: no Python 3 with pandas, h5py and numpy (tried $MARGLAB_PYTHON, "
               "/usr/bin/python3, python3). Install the Debian packages:\n"
               "  sudo apt-get install python3-pandas python3-h5py python3-numpy\n"
               "(or run scripts/setup.sh; another interpreter: set MARGLAB_PYTHON)\n");
    return 1;
  }
  const std::string out = request.out.empty() ? defaultAnalysisOut(request.dir) : request.out;
  const std::string tables =
      request.tables.empty() ? (fs::path(request.dir) / "tables").string() : request.tables;
  prepareOutputFolder(out, "--out");
  prepareOutputFolder(tables, "--tables");
  if (!request.figures.empty()) prepareOutputFolder(request.figures, "--figures");
  if (!fs::is_regular_file(fs::path(tables) / "tables.md")) {
    experiment::TablesRequest write;
    write.dirs = {request.dir};
    write.out = tables;
    experiment::writeTables(write, nullptr);
  }
  const std::string figures = request.figures.empty() ? out : request.figures;
  if (!hasFigures(figures)) {
    experiment::PlotRequest plot;
    plot.dirs = {request.dir};
    plot.out = figures;
    if (experiment::runPlot(plot) != 0) {
      fmt::print(stderr, "marglab report: no figures (see above); the report says so\n");
    }
  }
  if (runHelper({python, make_report, "--sweep", request.dir, "--out", out, "--tables", tables,
                 "--figures", figures}) != 0) {
    fmt::print(stderr, "marglab report: {} failed\n", make_report);
    return 1;
  }
  const std::string page = (fs::path(out) / "report.html").string();

  if (request.check == ReportRequest::Check::kNo) return 0;
  const bool have_browser = chromiumAvailable() && !findPythonWith({"websocket"}).empty();
  if (!have_browser && request.check == ReportRequest::Check::kIfAvailable) {
    fmt::print(
        "report: not checked in a browser (install the Debian packages chromium "
        "python3-websocket)\n");
    return 0;
  }
  const std::string browser_python = findPythonWith({"websocket"});
  const std::string screenshot =
      request.screenshot.empty() ? (fs::path(out) / "report.png").string() : request.screenshot;
  // The checker and its headless Chromium end with this process (subprocess.h).
  const int code = runHelper({browser_python.empty() ? python : browser_python,
                              scripts + "/check_report.py", page, "--report", "--min-tables", "2",
                              "--min-figures", "1", "--screenshot", screenshot});
  if (code == 3) {
    fmt::print(stderr,
               "marglab report: cannot check the page in a browser: install the Debian packages\n"
               "  sudo apt-get install chromium python3-websocket\n");
    return 1;
  }
  if (code != 0) {
    fmt::print(stderr, "marglab report: {} failed the browser check (see above)\n", page);
    return 1;
  }
  fmt::print("report: checked in headless Chromium, screenshot {}\n", screenshot);
  return 0;
}

namespace {

const bool kRegistered = registerCommand(
    {"report",
     "One self-contained HTML page of a sweep (configuration, failure matrix, tables beside the "
     "paper's, figures, notebook links): notebooks-out/<sweep>/report.html",
     44, [](CLI::App& sub) -> CommandRun {
       auto request = std::make_shared<ReportRequest>();
       sub.add_option("dir", request->dir, "Sweep folder (results/NAME)")->required();
       sub.add_option("-o,--out", request->out,
                      "Output folder of report.html (default: notebooks-out/<name of the sweep "
                      "folder>)");
       sub.add_option("--tables", request->tables,
                      "Folder of the tables (default: <sweep>/tables, written when absent)");
       sub.add_option("--figures", request->figures,
                      "Folder of the figures (default: the output folder, drawn when it has none)");
       auto* check = sub.add_flag("--check",
                                  "Open the page in headless Chromium, save a screenshot, fail on "
                                  "console errors or a page without its tables and figures");
       sub.add_option("--screenshot", request->screenshot,
                      "Screenshot of --check (default: <out>/report.png)");
       return [request, check] {
         ReportRequest r = *request;
         if (check->count() > 0 || !r.screenshot.empty()) r.check = ReportRequest::Check::kYes;
         const int code = runReport(r);
         if (code == 0) {
           fmt::print("report: {}\n",
                      (fs::path(r.out.empty() ? defaultAnalysisOut(r.dir) : r.out) / "report.html")
                          .string());
         }
         return code;
       };
     }});

}  // namespace
}  // namespace marglab::cli
