#pragma once
// The analysis of a sweep folder where researchers work (issue #20): the notebooks
// (notebooks/*.ipynb, executed headlessly by tools/scripts/run_notebooks.py) and the one-page
// HTML report (tools/scripts/make_report.py, checked in headless Chromium by
// tools/scripts/check_report.py). `marglab notebooks` and `marglab report` (cmd_notebooks.cpp,
// cmd_report.cpp) and `marglab reproduce` share these functions.

#include <string>
#include <vector>

namespace marglab::cli {

// notebooks-out/<name of the sweep folder>.
std::string defaultAnalysisOut(const std::string& sweep_dir);

// The first of $MARGLAB_PYTHON, /usr/bin/python3, python3 that imports every module; "" if none.
std::string findPythonWith(const std::vector<std::string>& modules);

// Throws InputError naming <dir>/index.csv when `dir` is not a readable sweep folder.
void requireSweepFolder(const std::string& dir);

struct NotebooksRequest {
  std::string dir;           // sweep folder
  std::string out;           // default notebooks-out/<sweep name>
  std::string runs = "all";  // all | none | comma-separated run ids (one run notebook each)
  int jobs = 0;              // notebooks in parallel, 0: number of cores
};

// Executes the notebooks on the sweep (writing its tables first when it has none). Returns 0, or
// 1 when a notebook failed or Jupyter is missing (the message names the Debian packages).
int runNotebooks(const NotebooksRequest& request);

struct ReportRequest {
  enum class Check { kNo, kIfAvailable, kYes };
  std::string dir;      // sweep folder
  std::string out;      // default notebooks-out/<sweep name>; report.html goes there
  std::string tables;   // folder of tables*.md (default <dir>/tables, written when absent)
  std::string figures;  // folder of the figures (default `out`, drawn when it has none)
  Check check = Check::kNo;
  std::string screenshot;  // default <out>/report.png when checking
};

// Writes <out>/report.html; with a check, opens it in headless Chromium and saves the screenshot.
// Returns 0, or 1 (missing packages or Chromium: the message names the Debian packages; a check
// that found console errors or a page without its tables and figures).
int runReport(const ReportRequest& request);

}  // namespace marglab::cli
