#pragma once
// The paper's figures from sweep results: tools/scripts/plot_paper.py (matplotlib, h5py, numpy)
// run by a Python 3 found among $MARGLAB_PYTHON, /usr/bin/python3 and python3 on PATH — the first
// python3 on PATH may lack the packages while the system one has them (docs/design.md §7).

#include <string>
#include <vector>

namespace marglab::experiment {

struct PlotRequest {
  std::vector<std::string> dirs;
  std::string out;  // default notebooks-out/<name of the first folder>
  std::string figures = "fig1,fig4,fig4_yaw,fig5,fig6,fig7,sparsify,ba_convergence,ba_profile";
  std::string vio_dataset = "euroc/MH_01_easy";
  std::string vo_dataset = "kitti/10";
};

// The first candidate interpreter that imports matplotlib, h5py and numpy; "" if none.
std::string findPlottingPython();

// Runs the plotting script; returns its exit code, or 1 (after saying what to install) when no
// suitable Python exists. Throws UsageError for a folder without index.csv or unknown figures.
int runPlot(const PlotRequest& request);

}  // namespace marglab::experiment
