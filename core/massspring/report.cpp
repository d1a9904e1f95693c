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

double speedup(const Measurements& m, const TwoRow& t) { return m.single.ms / t.total_ms; }

void headerText(Out out, const Measurements& m) {
  const int grid = m.settings.grid, iterations = m.settings.iterations;
  fmt::format_to(out,
                 "marglab massspring: {0}x{0} grid (primer §6), {1} masses, {2} in N (touched by "
                 "p = 4 springs), {3} springs + {4} anchors\n",
                 grid, m.system.num_masses, m.system.nonlinearMasses(), m.system.springs.size(),
                 m.system.anchors.size());
  fmt::format_to(out,
                 "Gauss-Newton, {} iterations in both methods; times are medians of {} runs "
                 "(problem construction not timed)\n",
                 iterations, m.reps);
  fmt::format_to(out,
                 "single stage: all masses, sparse normal Cholesky; two-stage: marginalize the {} "
                 "masses outside N, {} iterations on N (dense normal Cholesky), recover the rest "
                 "by CHOLMOD\n\n",
                 m.system.num_masses - m.system.nonlinearMasses(), iterations);
}

void methodsText(Out out, const Measurements& m) {
  fmt::format_to(out, "| {:<26} | {:>9} | {:>9} | {:>9} | {:>9} | {:>7} | {:>12} | {:>9} |\n",
                 "method", "marg ms", "stage1 ms", "stage2 ms", "total ms", "speedup", "max|dx|",
                 "prior");
  fmt::format_to(out, "|{:-<28}|{:->11}|{:->11}|{:->11}|{:->11}|{:->9}|{:->14}|{:->11}|\n", "", "",
                 "", "", "", "", "", "");
  fmt::format_to(out, "| {:<26} | {:>9} | {:>9} | {:>9} | {:>9.3f} | {:>7} | {:>12} | {:>9} |\n",
                 "single stage", "", "", "", m.single.ms, "1.0", "", "");
  for (const TwoRow& t : m.twos) {
    fmt::format_to(out,
                   "| {:<26} | {:>9.3f} | {:>9.3f} | {:>9.3f} | {:>9.3f} | {:>7.1f} | {:>12.2e} | "
                   "{:>4}x{:<4} |\n",
                   fmt::format("two-stage, {}{}", ceres_marg::toString(t.method),
                               t.method == m.settings.method ? " *" : ""),
                   t.marg_ms, t.stage1_ms, t.stage2_ms, t.total_ms, speedup(m, t), t.max_abs_diff,
                   t.last.marginalization.prior_rows, t.last.marginalization.blanket_dim);
  }
  fmt::format_to(out,
                 "\nfinal energy {:.10g} (single) vs {:.10g} (two-stage); max|dx| is the largest "
                 "coordinate difference of the two final states. * = --method\n",
                 m.single.last.final_cost, m.main().last.final_cost);
}

// Per Gauss–Newton iteration, as the primer reports: the two-stage time (marginalization, stage 1
// and recovery) over the iterations.
void primerText(Out out, const Measurements& m, const PrimerTable& primer) {
  if (!primer.present) return;
  const int iterations = m.settings.iterations;
  const double single_ms = m.single.ms, two_ms = m.main().total_ms;
  fmt::format_to(out,
                 "\nprimer Table 1 beside ours: solve time per Gauss-Newton iteration, ms (ours: "
                 "{0}x{0} grid, the whole solve / {1} iterations)\n\n",
                 m.settings.grid, iterations);
  fmt::format_to(out, "| {:<12} | {:>9} | {:>9} |\n", "method", "primer", "marglab");
  fmt::format_to(out, "|{:-<14}|{:->11}|{:->11}|\n", "", "", "");
  fmt::format_to(out, "| {:<12} | {:>9.1f} | {:>9.3f} |\n", "single stage", primer.single_ms,
                 single_ms / iterations);
  fmt::format_to(out, "| {:<12} | {:>9.1f} | {:>9.3f} |\n", "two-stage", primer.two_ms,
                 two_ms / iterations);
  fmt::format_to(out, "| {:<12} | {:>8.1f}x | {:>8.1f}x |\n", "speedup",
                 primer.single_ms / primer.two_ms, single_ms / two_ms);
}

void scalingText(Out out, const Measurements& m) {
  if (m.scaling.empty()) return;
  fmt::format_to(out, "\nscaling (two-stage with {}):\n\n",
                 ceres_marg::toString(m.settings.method));
  fmt::format_to(
      out, "| {:>9} | {:>6} | {:>4} | {:>10} | {:>9} | {:>9} | {:>9} | {:>10} | {:>7} | {:>9} |\n",
      "grid", "masses", "reps", "single ms", "marg ms", "stage1 ms", "stage2 ms", "2-stage ms",
      "speedup", "max|dx|");
  fmt::format_to(out,
                 "|{:->11}|{:->8}|{:->6}|{:->12}|{:->11}|{:->11}|{:->11}|{:->12}|{:->9}|{:->11}|\n",
                 "", "", "", "", "", "", "", "", "", "");
  for (const ScalingRow& r : m.scaling) {
    fmt::format_to(out,
                   "| {:>9} | {:>6} | {:>4} | {:>10.3f} | {:>9.3f} | {:>9.3f} | {:>9.3f} | "
                   "{:>10.3f} | {:>7.1f} | {:>9.1e} |\n",
                   fmt::format("{0}x{0}", r.n), r.masses, r.reps, r.single.ms, r.two.marg_ms,
                   r.two.stage1_ms, r.two.stage2_ms, r.two.total_ms, r.single.ms / r.two.total_ms,
                   r.two.max_abs_diff);
  }
}

// The timings of one two-stage row (the JSON's per-method and scaling entries share them).
void twoStageJson(Json& j, const TwoRow& t, double single_ms) {
  j["marginalize_ms"] = roundedTo(t.marg_ms, 6);
  j["stage1_ms"] = roundedTo(t.stage1_ms, 6);
  j["stage2_ms"] = roundedTo(t.stage2_ms, 6);
  j["two_stage_ms"] = roundedTo(t.total_ms, 6);
  j["speedup"] = roundedTo(single_ms / t.total_ms, 6);
  j["max_abs_diff"] = roundedTo(t.max_abs_diff, 4);
}

Json scalingJson(const Measurements& m) {
  Json rows = Json::array();
  for (const ScalingRow& r : m.scaling) {
    Json row;
    row["grid"] = r.n;
    row["masses"] = r.masses;
    row["reps"] = r.reps;
    row["single_stage_ms"] = roundedTo(r.single.ms, 6);
    twoStageJson(row, r.two, r.single.ms);
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
  writeState(state, "single_stage", m.single.last.x);
  writeState(state, "two_stage", m.main().last.x);
  std::vector<std::int32_t> springs;
  for (const auto& s : m.system.springs) springs.insert(springs.end(), {s.i, s.j, s.p});
  state.write("springs", springs.data(), m.system.springs.size(), 3);
  state.write("energy_final", m.system.springEnergies(m.single.last.x));
}

void writeMethods(const h5::File& file, const Measurements& m) {
  const h5::Group methods = file.group("two_stage");
  for (const TwoRow& t : m.twos) {
    const h5::Group g = methods.group(ceres_marg::toString(t.method));
    g.setAttr("marginalize_ms", t.marg_ms);
    g.setAttr("stage1_ms", t.stage1_ms);
    g.setAttr("stage2_ms", t.stage2_ms);
    g.setAttr("total_ms", t.total_ms);
    g.setAttr("max_abs_diff", t.max_abs_diff);
    g.setAttr("prior_rows", t.last.marginalization.prior_rows);
  }
}

void writeScaling(const h5::File& file, const Measurements& m) {
  if (m.scaling.empty()) return;
  const h5::Group g = file.group("scaling");
  std::vector<std::int64_t> grid, masses;
  std::vector<double> single_ms, marg_ms, s1, s2, total, diff;
  for (const ScalingRow& r : m.scaling) {
    grid.push_back(r.n);
    masses.push_back(r.masses);
    single_ms.push_back(r.single.ms);
    marg_ms.push_back(r.two.marg_ms);
    s1.push_back(r.two.stage1_ms);
    s2.push_back(r.two.stage2_ms);
    total.push_back(r.two.total_ms);
    diff.push_back(r.two.max_abs_diff);
  }
  g.write("grid", grid);
  g.write("masses", masses);
  g.write("single_stage_ms", single_ms);
  g.write("marginalize_ms", marg_ms);
  g.write("stage1_ms", s1);
  g.write("stage2_ms", s2);
  g.write("two_stage_ms", total);
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
      it == paper.tables.end() ? nullptr : it->second.row("solve_time_per_iteration");
  if (row == nullptr || row->cells.count("time_ms") == 0) {
    throw InputError(path, 0, "[massspring_table1] needs the row solve_time_per_iteration");
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
  j["reps"] = m.reps;
  j["method"] = ceres_marg::toString(m.settings.method);
  j["single_stage_ms"] = roundedTo(m.single.ms, 6);
  j["two_stage_ms"] = roundedTo(m.main().total_ms, 6);
  j["speedup"] = roundedTo(speedup(m, m.main()), 6);
  j["max_abs_diff"] = roundedTo(m.main().max_abs_diff, 4);
  j["final_energy"] = roundedTo(m.single.last.final_cost, 12);
  Json& methods = j["two_stage"] = Json::object();
  for (const TwoRow& t : m.twos) {
    Json& method = methods[ceres_marg::toString(t.method)];
    twoStageJson(method, t, m.single.ms);
    method["prior_rows"] = t.last.marginalization.prior_rows;
    method["prior_condition"] = roundedTo(t.last.marginalization.condition_number, 6);
  }
  j["scaling"] = scalingJson(m);
  if (primer.present) {
    j["primer_table1"] = {{"single_stage_ms_per_iteration", primer.single_ms},
                          {"two_stage_ms_per_iteration", primer.two_ms}};
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
  file.setAttr("reps", m.reps);
  file.setAttr("method", ceres_marg::toString(m.settings.method));
  file.setAttr("single_stage_ms", m.single.ms);
  file.setAttr("two_stage_ms", m.main().total_ms);
  file.setAttr("speedup", speedup(m, m.main()));
  file.setAttr("max_abs_diff", m.main().max_abs_diff);
  writeStates(file, m);
  writeMethods(file, m);
  writeScaling(file, m);
  file.commit();
}

}  // namespace marglab::massspring
