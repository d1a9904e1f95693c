#include "core/massspring/report.h"

#include <fmt/format.h>
#include <unistd.h>

#include <Eigen/Core>
#include <cstdint>
#include <iterator>

#include "core/common/error.h"
#include "core/common/json.h"
#include "core/experiment/tables.h"
#include "core/io/hdf5.h"

namespace marglab::massspring {
namespace {

using ceres_marg::Method;
using Out = std::back_insert_iterator<std::string>;

std::string iqr(const Timing& t) { return fmt::format("{:.3f}-{:.3f}", t.q1, t.q3); }

void headerText(Out out, const Measurements& m) {
  const int grid = m.settings.grid, iterations = m.settings.iterations;
  fmt::format_to(out,
                 "marglab massspring: {0}x{0} grid (primer §6), {1} masses, {2} in N (touched by "
                 "p = 4 springs), {3} springs + {4} anchors\n",
                 grid, m.system.num_masses, m.system.nonlinearMasses(), m.system.springs.size(),
                 m.system.anchors.size());
  fmt::format_to(out,
                 "Gauss-Newton, {} iterations in both methods; times of the whole solve, ms: "
                 "median and interquartile range (IQR) of {} repetitions{}, the methods "
                 "interleaved, after one warm-up (problem construction not timed); speedup: the "
                 "median of the per-repetition ratios\n",
                 iterations, m.compared.reps,
                 m.settings.reps > 0 ? std::string()
                                     : fmt::format(" (at least {} and {:g} s per grid)",
                                                   kMinAutoReps, m.settings.budget_s));
  fmt::format_to(out,
                 "single stage: all masses, {}; two-stage: marginalize the {} masses outside N, {} "
                 "iterations on N (dense normal Cholesky), recover the rest by CHOLMOD\n\n",
                 m.settings.single_solver == SingleSolver::kSparseCholesky
                     ? std::string("sparse normal Cholesky")
                     : toString(m.settings.single_solver),
                 m.system.num_masses - m.system.nonlinearMasses(), iterations);
}

void methodsText(Out out, const Measurements& m) {
  const SingleRow& single = m.compared.single;
  fmt::format_to(out,
                 "| {:<26} | {:>9} | {:>9} | {:>9} | {:>9} | {:>13} | {:>7} | {:>12} | {:>9} |\n",
                 "method", "marg ms", "stage1 ms", "stage2 ms", "total ms", "IQR ms", "speedup",
                 "max|dx|", "prior");
  fmt::format_to(out, "|{:-<28}|{:->11}|{:->11}|{:->11}|{:->11}|{:->15}|{:->9}|{:->14}|{:->11}|\n",
                 "", "", "", "", "", "", "", "", "");
  fmt::format_to(
      out, "| {:<26} | {:>9} | {:>9} | {:>9} | {:>9.3f} | {:>13} | {:>7} | {:>12} | {:>9} |\n",
      "single stage", "", "", "", single.time.median, iqr(single.time), "1.0", "", "");
  for (const TwoRow& t : m.compared.twos) {
    fmt::format_to(out,
                   "| {:<26} | {:>9.3f} | {:>9.3f} | {:>9.3f} | {:>9.3f} | {:>13} | {:>7.2f} | "
                   "{:>12.2e} | {:>4}x{:<4} |\n",
                   fmt::format("two-stage, {}{}", ceres_marg::toString(t.method),
                               t.method == m.settings.method ? " *" : ""),
                   t.marg.median, t.stage1.median, t.stage2.median, t.total.median, iqr(t.total),
                   t.speedup.median, t.max_abs_diff, t.last.marginalization.prior_rows,
                   t.last.marginalization.blanket_dim);
  }
  fmt::format_to(out,
                 "\nfinal energy {:.10g} (single) vs {:.10g} (two-stage); max|dx| is the largest "
                 "coordinate difference of the two final states. * = --method\n",
                 single.last.final_cost, m.main().last.final_cost);
}

// Where the Ceres calls' time goes (Solver::Summary, medians): on a small grid the per-call
// overhead, not the iterations, decides the comparison.
void splitText(Out out, const Measurements& m) {
  fmt::format_to(out,
                 "\nwhere the time of the Ceres solves goes (Solver::Summary, medians, ms; "
                 "overhead = total - evaluation - linear solver):\n\n");
  fmt::format_to(out, "| {:<24} | {:>9} | {:>10} | {:>10} | {:>13} | {:>9} | {:>8} |\n", "solve",
                 "total", "preprocess", "evaluation", "linear solver", "overhead", "overhead");
  fmt::format_to(out, "|{:-<26}|{:->11}|{:->12}|{:->12}|{:->15}|{:->11}|{:->10}|\n", "", "", "", "",
                 "", "", "");
  const auto row = [&](const std::string& name, const CeresSplit& s) {
    fmt::format_to(
        out, "| {:<24} | {:>9.3f} | {:>10.3f} | {:>10.3f} | {:>13.3f} | {:>9.3f} | {:>7.0f}% |\n",
        name, s.total_ms, s.preprocess_ms, s.evaluate_ms, s.linear_solve_ms, s.overheadMs(),
        100.0 * s.overheadMs() / s.total_ms);
  };
  row("single stage", m.compared.single.split);
  row(fmt::format("stage 1 ({})", ceres_marg::toString(m.settings.method)), m.main().stage1_split);
}

// The primer's Table 1 reports whole solves (10 Gauss–Newton iterations in both methods).
void primerText(Out out, const Measurements& m, const PrimerTable& primer) {
  if (!primer.present) return;
  const SingleRow& single = m.compared.single;
  const TwoRow& two = m.main();
  fmt::format_to(out,
                 "\nprimer Table 1 beside ours: runtime of the whole solve ({} Gauss-Newton "
                 "iterations), ms (ours: {}x{} grid, {} iterations; median [IQR])\n\n",
                 primer.iterations, m.settings.grid, m.settings.grid, m.settings.iterations);
  fmt::format_to(out, "| {:<12} | {:>9} | {:>25} |\n", "method", "primer", "marglab");
  fmt::format_to(out, "|{:-<14}|{:->11}|{:->27}|\n", "", "", "");
  fmt::format_to(out, "| {:<12} | {:>9.1f} | {:>25} |\n", "single stage", primer.single_ms,
                 fmt::format("{:.3f} [{}]", single.time.median, iqr(single.time)));
  fmt::format_to(out, "| {:<12} | {:>9.1f} | {:>25} |\n", "two-stage", primer.two_ms,
                 fmt::format("{:.3f} [{}]", two.total.median, iqr(two.total)));
  fmt::format_to(
      out, "| {:<12} | {:>8.1f}x | {:>25} |\n", "speedup", primer.single_ms / primer.two_ms,
      fmt::format("{:.2f}x [{:.2f}-{:.2f}]", two.speedup.median, two.speedup.q1, two.speedup.q3));
}

// The marginalization's cost in single-stage Gauss–Newton iterations: with the same iteration
// count in both methods the speedup stays below iterations / this.
double margPerIteration(const Measurements& m, const ScalingRow& r) {
  return r.two.marg.median / (r.single.time.median / m.settings.iterations);
}

void scalingText(Out out, const Measurements& m) {
  if (m.scaling.empty()) return;
  fmt::format_to(out,
                 "\nscaling (two-stage with {}; median and IQR, ms; N %: share of masses in N; "
                 "marg/iter: the marginalization in single-stage iterations):\n\n",
                 ceres_marg::toString(m.settings.method));
  fmt::format_to(out,
                 "| {:>9} | {:>6} | {:>6} | {:>4} | {:>10} | {:>19} | {:>9} | {:>9} | {:>9} | "
                 "{:>9} | {:>10} | {:>19} | {:>16} | {:>9} |\n",
                 "grid", "masses", "N %", "reps", "single ms", "single IQR", "marg ms", "marg/iter",
                 "stage1 ms", "stage2 ms", "2-stage ms", "2-stage IQR", "speedup (IQR)", "max|dx|");
  fmt::format_to(out,
                 "|{:->11}|{:->8}|{:->8}|{:->6}|{:->12}|{:->21}|{:->11}|{:->11}|{:->11}|{:->11}|"
                 "{:->12}|{:->21}|{:->18}|{:->11}|\n",
                 "", "", "", "", "", "", "", "", "", "", "", "", "", "");
  for (const ScalingRow& r : m.scaling) {
    fmt::format_to(out,
                   "| {:>9} | {:>6} | {:>6.3g} | {:>4} | {:>10.3f} | {:>19} | {:>9.3f} | "
                   "{:>9.2f} | {:>9.3f} | {:>9.3f} | {:>10.3f} | {:>19} | {:>16} | {:>9.1e} |\n",
                   fmt::format("{0}x{0}", r.n), r.masses, 100.0 * r.nonlinear / r.masses, r.reps,
                   r.single.time.median, iqr(r.single.time), r.two.marg.median,
                   margPerIteration(m, r), r.two.stage1.median, r.two.stage2.median,
                   r.two.total.median, iqr(r.two.total),
                   fmt::format("{:.2f} ({:.2f}-{:.2f})", r.two.speedup.median, r.two.speedup.q1,
                               r.two.speedup.q3),
                   r.two.max_abs_diff);
  }
}

// A timing's spread beside its median (key_ms): key_ms_iqr = [q1, q3], key_ms_range = [min, max].
void timingJson(Json& j, const std::string& key, const Timing& t) {
  j[key + "_ms"] = roundedTo(t.median, 6);
  j[key + "_ms_iqr"] = {roundedTo(t.q1, 6), roundedTo(t.q3, 6)};
  j[key + "_ms_range"] = {roundedTo(t.min, 6), roundedTo(t.max, 6)};
}

// The timings of one two-stage row (the JSON's per-method and scaling entries share them).
void twoStageJson(Json& j, const TwoRow& t) {
  j["marginalize_ms"] = roundedTo(t.marg.median, 6);
  j["stage1_ms"] = roundedTo(t.stage1.median, 6);
  j["stage2_ms"] = roundedTo(t.stage2.median, 6);
  timingJson(j, "two_stage", t.total);
  j["speedup"] = roundedTo(t.speedup.median, 6);
  j["speedup_iqr"] = {roundedTo(t.speedup.q1, 6), roundedTo(t.speedup.q3, 6)};
  j["max_abs_diff"] = roundedTo(t.max_abs_diff, 4);
}

Json splitJson(const CeresSplit& s) {
  return {{"total_ms", roundedTo(s.total_ms, 6)},
          {"preprocess_ms", roundedTo(s.preprocess_ms, 6)},
          {"evaluate_ms", roundedTo(s.evaluate_ms, 6)},
          {"linear_solve_ms", roundedTo(s.linear_solve_ms, 6)},
          {"overhead_ms", roundedTo(s.overheadMs(), 6)}};
}

Json scalingJson(const Measurements& m) {
  Json rows = Json::array();
  for (const ScalingRow& r : m.scaling) {
    Json row;
    row["grid"] = r.n;
    row["masses"] = r.masses;
    row["nonlinear_masses"] = r.nonlinear;
    row["reps"] = r.reps;
    timingJson(row, "single_stage", r.single.time);
    row["marginalize_per_single_iteration"] = roundedTo(margPerIteration(m, r), 6);
    twoStageJson(row, r.two);
    rows.push_back(std::move(row));
  }
  return rows;
}

// A state (x_0, y_0, x_1, y_1, ...) as a masses × 2 dataset.
void writeState(const h5::Group& state, const std::string& name, const std::vector<double>& x) {
  using Rows = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;
  state.writeMatrix(name,
                    Eigen::Map<const Rows>(x.data(), static_cast<Eigen::Index>(x.size() / 2), 2));
}

void writeStates(const h5::File& file, const Measurements& m) {
  const h5::Group state = file.group("state");
  writeState(state, "rest", m.system.rest);
  writeState(state, "initial", m.system.initial);
  writeState(state, "single_stage", m.compared.single.last.x);
  writeState(state, "two_stage", m.main().last.x);
  std::vector<std::int32_t> springs;
  for (const auto& s : m.system.springs) springs.insert(springs.end(), {s.i, s.j, s.p});
  state.write("springs", springs.data(), m.system.springs.size(), 3);
  state.write("energy_final", m.system.springEnergies(m.compared.single.last.x));
}

void writeMethods(const h5::File& file, const Measurements& m) {
  const h5::Group methods = file.group("two_stage");
  for (const TwoRow& t : m.compared.twos) {
    const h5::Group g = methods.group(ceres_marg::toString(t.method));
    g.setAttr("marginalize_ms", t.marg.median);
    g.setAttr("stage1_ms", t.stage1.median);
    g.setAttr("stage2_ms", t.stage2.median);
    g.setAttr("total_ms", t.total.median);
    g.setAttr("total_ms_q1", t.total.q1);
    g.setAttr("total_ms_q3", t.total.q3);
    g.setAttr("speedup", t.speedup.median);
    g.setAttr("max_abs_diff", t.max_abs_diff);
    g.setAttr("prior_rows", t.last.marginalization.prior_rows);
  }
}

void writeScaling(const h5::File& file, const Measurements& m) {
  if (m.scaling.empty()) return;
  const h5::Group g = file.group("scaling");
  std::vector<std::int64_t> grid, masses, reps;
  std::vector<double> single_ms, single_q1, single_q3, marg_ms, s1, s2, total, total_q1, total_q3,
      speedup, diff;
  for (const ScalingRow& r : m.scaling) {
    grid.push_back(r.n);
    masses.push_back(r.masses);
    reps.push_back(r.reps);
    single_ms.push_back(r.single.time.median);
    single_q1.push_back(r.single.time.q1);
    single_q3.push_back(r.single.time.q3);
    marg_ms.push_back(r.two.marg.median);
    s1.push_back(r.two.stage1.median);
    s2.push_back(r.two.stage2.median);
    total.push_back(r.two.total.median);
    total_q1.push_back(r.two.total.q1);
    total_q3.push_back(r.two.total.q3);
    speedup.push_back(r.two.speedup.median);
    diff.push_back(r.two.max_abs_diff);
  }
  g.write("grid", grid);
  g.write("masses", masses);
  g.write("reps", reps);
  g.write("single_stage_ms", single_ms);
  g.write("single_stage_ms_q1", single_q1);
  g.write("single_stage_ms_q3", single_q3);
  g.write("marginalize_ms", marg_ms);
  g.write("stage1_ms", s1);
  g.write("stage2_ms", s2);
  g.write("two_stage_ms", total);
  g.write("two_stage_ms_q1", total_q1);
  g.write("two_stage_ms_q3", total_q3);
  g.write("speedup", speedup);
  g.write("max_abs_diff", diff);
}

}  // namespace

PrimerTable loadPrimerTable() {
  PrimerTable primer;
  const std::string path = experiment::defaultPaperValuesPath();
  if (access(path.c_str(), R_OK) != 0) return primer;
  const experiment::PaperValues paper = experiment::loadPaperValues(path);
  const auto it = paper.tables.find("massspring_table1");
  const experiment::PaperTable::Row* row =
      it == paper.tables.end() ? nullptr : it->second.row("solve_time");
  if (row == nullptr || row->cells.count("time_ms") == 0) {
    throw InputError(path, 0, "[massspring_table1] needs the row solve_time (time_ms)");
  }
  const std::vector<experiment::PaperCell>& cells = row->cells.at("time_ms");
  const auto value = experiment::PaperCell::State::kValue;
  primer.present = cells.size() == 2 && cells[0].state == value && cells[1].state == value;
  if (primer.present) {
    primer.single_ms = cells[0].value;
    primer.two_ms = cells[1].value;
  }
  return primer;
}

std::string textReport(const Measurements& m, const PrimerTable& primer) {
  std::string text;
  headerText(std::back_inserter(text), m);
  methodsText(std::back_inserter(text), m);
  splitText(std::back_inserter(text), m);
  primerText(std::back_inserter(text), m, primer);
  scalingText(std::back_inserter(text), m);
  return text;
}

std::string jsonReport(const Measurements& m, const PrimerTable& primer) {
  Json j;
  j["grid"] = m.settings.grid;
  j["masses"] = m.system.num_masses;
  j["nonlinear_masses"] = m.system.nonlinearMasses();
  j["iterations"] = m.settings.iterations;
  j["reps"] = m.compared.reps;
  j["budget_s"] = m.settings.reps > 0 ? Json(nullptr) : Json(m.settings.budget_s);
  j["method"] = ceres_marg::toString(m.settings.method);
  j["single_solver"] = toString(m.settings.single_solver);
  timingJson(j, "single_stage", m.compared.single.time);
  timingJson(j, "two_stage", m.main().total);
  j["speedup"] = roundedTo(m.main().speedup.median, 6);
  j["speedup_iqr"] = {roundedTo(m.main().speedup.q1, 6), roundedTo(m.main().speedup.q3, 6)};
  j["max_abs_diff"] = roundedTo(m.main().max_abs_diff, 4);
  j["final_energy"] = roundedTo(m.compared.single.last.final_cost, 12);
  Json& methods = j["two_stage"] = Json::object();
  for (const TwoRow& t : m.compared.twos) {
    Json& method = methods[ceres_marg::toString(t.method)];
    twoStageJson(method, t);
    method["prior_rows"] = t.last.marginalization.prior_rows;
    method["prior_condition"] = roundedTo(t.last.marginalization.condition_number, 6);
  }
  j["ceres_split"] = {{"single_stage", splitJson(m.compared.single.split)},
                      {"stage1", splitJson(m.main().stage1_split)}};
  j["scaling"] = scalingJson(m);
  if (primer.present) {
    j["primer_table1"] = {{"iterations", primer.iterations},
                          {"single_stage_solve_ms", primer.single_ms},
                          {"two_stage_solve_ms", primer.two_ms}};
  }
  return j.dump() + "\n";
}

std::string figureJson(const MassSpringSystem& system, const std::vector<double>& final_x) {
  std::vector<int> springs, anchor_mass, nonlinear;
  for (const auto& s : system.springs) springs.insert(springs.end(), {s.i, s.j, s.p});
  std::vector<double> anchors;
  for (const auto& a : system.anchors) {
    anchors.insert(anchors.end(), {a.point.x(), a.point.y()});
    anchor_mass.push_back(a.mass);
  }
  for (int i = 0; i < system.num_masses; ++i) nonlinear.push_back(system.in_nonlinear_set[i]);
  Json j;
  j["n"] = system.spec.n;
  j["initial"] = system.initial;
  j["final"] = final_x;
  j["springs"] = springs;
  j["energy_initial"] = system.springEnergies(system.initial);
  j["energy_final"] = system.springEnergies(final_x);
  j["anchors"] = anchors;
  j["anchor_mass"] = anchor_mass;
  j["nonlinear"] = nonlinear;
  return j.dump() + "\n";
}

void writeResults(const std::string& path, const Measurements& m) {
  h5::File file = h5::File::create(path);
  file.setAttr("experiment", "massspring");
  file.setAttr("grid", m.settings.grid);
  file.setAttr("iterations", m.settings.iterations);
  file.setAttr("reps", m.compared.reps);
  file.setAttr("method", ceres_marg::toString(m.settings.method));
  file.setAttr("single_solver", toString(m.settings.single_solver));
  file.setAttr("single_stage_ms", m.compared.single.time.median);
  file.setAttr("single_stage_ms_q1", m.compared.single.time.q1);
  file.setAttr("single_stage_ms_q3", m.compared.single.time.q3);
  file.setAttr("two_stage_ms", m.main().total.median);
  file.setAttr("two_stage_ms_q1", m.main().total.q1);
  file.setAttr("two_stage_ms_q3", m.main().total.q3);
  file.setAttr("speedup", m.main().speedup.median);
  file.setAttr("max_abs_diff", m.main().max_abs_diff);
  writeStates(file, m);
  writeMethods(file, m);
  writeScaling(file, m);
  file.commit();
}

}  // namespace marglab::massspring
