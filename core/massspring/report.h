#pragma once
// What `marglab massspring` prints and writes from its Measurements (experiment.h): the Markdown
// tables (the compared grid, the primer's Table 1 beside ours, the scaling table), the same as one
// JSON object, the data of the final-state figure (tools/scripts/plot_massspring.py reads it) and
// the HDF5 file of -o.
//
// JSON numbers keep 6 significant digits for times and ratios, 4 for max|dx|, 12 for the energy:
// the timings are medians of repetitions on a shared machine, and more digits would only be noise.
// Each time is a median (key_ms) with its spread (key_ms_iqr, key_ms_range); the speedup is the
// median of the per-repetition ratios (speedup_iqr their quartiles).

#include <string>
#include <vector>

#include "core/massspring/experiment.h"

namespace marglab::massspring {

// The primer's Table 1 (experiments/paper_values.toml [massspring_table1]): runtimes of the whole
// solves, ms — 10 Gauss–Newton iterations in both methods (primer §6), not per iteration.
struct PrimerTable {
  bool present = false;  // false without the file (an installed binary): nothing to compare
  int iterations = 10;
  double single_ms = 0, two_ms = 0;
};

// Reads the primer's Table 1 from the default paper values; throws InputError when the file is
// there but lacks the row.
PrimerTable loadPrimerTable();

// The tables, as `marglab massspring` prints them (ends with a newline).
std::string textReport(const Measurements& m, const PrimerTable& primer);
// One JSON object on one line (ends with a newline).
std::string jsonReport(const Measurements& m, const PrimerTable& primer);
// The figure's input: the grid, the initial and final states, springs, energies and anchors.
std::string figureJson(const MassSpringSystem& system, const std::vector<double>& final_x);
// The states and timings as an HDF5 file at path (atomically; InputError naming it on failure).
void writeResults(const std::string& path, const Measurements& m);

}  // namespace marglab::massspring
