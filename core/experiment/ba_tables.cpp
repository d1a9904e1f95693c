// The tables of `marglab ba` runs (ba_tables.h): the solvers of each problem and seed compared,
// then reduced over the seeds.

#include "core/experiment/ba_tables.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <set>

#include "core/ba/ba_options.h"
#include "core/ba/bal_problem.h"
#include "core/common/error.h"
#include "core/common/statistics.h"
#include "core/experiment/table_cells.h"

namespace marglab::experiment {

namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kTaus[] = {0.1, 0.01, 0.001};
constexpr double kSpeedupTau = 0.01;  // #39's speed target is at τ = 0.01

// The runs of one problem and seed (one start), by solver, and the lowest final cost among them.
struct Instance {
  std::map<std::string, const BaRunData*> by_solver;
  double best = kInf;
};

// One sweep group: its problems (by name) and the solvers that ran, in `marglab ba`'s order.
struct Group {
  std::string name;
  std::string protocol;
  std::vector<std::string> solvers;
  std::map<std::string, std::map<std::uint64_t, Instance>> problems;  // problem → seed → runs
};

double maximum(const std::vector<double>& v) {
  return v.empty() ? kNaN : *std::max_element(v.begin(), v.end());
}

// The per-seed samples of one problem × solver: values[q] over the seeds that gave a value,
// `failed` the seeds that count as failed (x k/n), `runs` the seeds that ran.
struct Samples {
  std::vector<std::vector<double>> values;
  int failed = 0;
  int runs = 0;
};

using Reduce = std::function<double(const std::vector<double>&)>;

TableCell cellOf(const Samples& s, const std::vector<Reduce>& reduce, bool spread_first) {
  TableCell cell;
  cell.seed_stats = true;
  cell.n_runs = s.runs;
  cell.n_failed = s.failed;
  const bool any = !s.values.empty() && !s.values.front().empty();
  if (!any) {
    cell.state = s.failed > 0 ? TableCell::State::kFailed : TableCell::State::kMissing;
    return cell;
  }
  cell.state = TableCell::State::kValue;
  for (std::size_t q = 0; q < reduce.size(); ++q) {
    cell.numbers.push_back(reduce[q](s.values[q]));
    cell.spread.push_back(q == 0 && spread_first ? sampleStdOf(s.values[q]) : kNaN);
  }
  return cell;
}

// What one run of an instance gives a cell: its quantities, or nothing (std::nullopt-like: an
// empty vector) when it has no such value; *failed when the seed counts as failed.
using Sample = std::function<std::vector<double>(const Instance&, const BaRunData&, bool* failed)>;

struct TableDef {
  std::string id, title;
  std::vector<std::string> columns;  // "" = every solver of the group
  // The run of an instance a column reads (default: the column's solver).
  std::function<const BaRunData*(const Instance&, const std::string&)> run_of;
  Sample sample;
  std::vector<std::string> quantities;  // the CSV's name of each number of a cell
  std::vector<Reduce> reduce;
  bool spread_first = false;
  bool scientific = false;
  int decimals = 3;
  bool ranked = false;
  std::vector<std::string> notes;
};

const BaRunData* solverRun(const Instance& instance, const std::string& solver) {
  const auto it = instance.by_solver.find(solver);
  return it == instance.by_solver.end() ? nullptr : it->second;
}

Table buildTable(const Group& g, const TableDef& def) {
  Table t;
  t.id = def.id;
  t.title = def.title;
  t.row_header = "problem";
  t.has_paper = false;
  t.quantities = def.quantities;
  const std::vector<std::string> columns = def.columns.empty() ? g.solvers : def.columns;
  for (const std::string& c : columns) t.columns.push_back({c, c, c, -1, ""});
  const auto run_of = def.run_of ? def.run_of : solverRun;
  for (const auto& [problem, seeds] : g.problems) {
    TableRow row;
    row.key = row.label = problem;
    row.ours_decimals = def.decimals;
    row.scientific = def.scientific;
    for (const std::string& column : columns) {
      Samples s;
      s.values.resize(def.reduce.size());
      for (const auto& [seed, instance] : seeds) {
        const BaRunData* run = run_of(instance, column);
        if (run == nullptr) continue;
        bool failed = false;
        const std::vector<double> v = def.sample(instance, *run, &failed);
        if (v.empty() && !failed) continue;
        ++s.runs;
        if (failed) ++s.failed;
        if (failed || v.empty()) continue;
        for (std::size_t q = 0; q < v.size(); ++q) s.values[q].push_back(v[q]);
      }
      row.ours.push_back(cellOf(s, def.reduce, def.spread_first));
      row.paper.emplace_back();
    }
    if (def.ranked) {
      markBest(row.ours, def.reduce.size(), def.decimals, false,
               std::vector<bool>(columns.size(), true));
    }
    t.rows.push_back(std::move(row));
  }
  t.notes = def.notes;
  return t;
}

bool hasValue(const Table& t) {
  for (const TableRow& row : t.rows) {
    for (const TableCell& cell : row.ours) {
      if (cell.state != TableCell::State::kMissing) return true;
    }
  }
  return false;
}

std::string tauText(double tau) { return fmt::format("{}", tau); }

TableDef tauTable(const Group& g, double tau) {
  TableDef d;
  d.id = fmt::format("ba_{}_tau{}", g.name, tauText(tau));
  d.title = fmt::format("Time to τ = {} [s] / ×fastest, {} ({})", tauText(tau), g.name, g.protocol);
  d.sample = [tau](const Instance& instance, const BaRunData& run, bool* failed) {
    if (!run.has_file) return std::vector<double>{};
    const auto threshold = [&](const BaRunData& r) {
      return instance.best + tau * (r.file.initial_cost - instance.best);
    };
    double fastest = kInf;
    for (const auto& [solver, other] : instance.by_solver) {
      if (other->has_file) fastest = std::min(fastest, timeToCost(other->file, threshold(*other)));
    }
    const double t = timeToCost(run.file, threshold(run));
    *failed = !std::isfinite(t);
    return std::vector<double>{t, t / fastest};
  };
  d.quantities = {"time_s", "over_fastest"};
  d.reduce = {median, median};
  d.ranked = true;
  d.notes = {fmt::format(
      "Performance profile (Demmel et al., CVPR 2021, after Dolan and Moré): per problem and "
      "seed, best is the lowest final cost any solver reached and the threshold best + {} "
      "(initial − best); a cell is the time [s] of the first iteration at or below it, then "
      "that time over the fastest solver's on the same problem and seed, medians over the "
      "seeds that reached it; `x k/n`: k of the n seeds never reached it. Times are wall-clock "
      "of the solve (after loading), on the machine and load of the sweep.",
      tauText(tau))};
  return d;
}

// #39's speed target: each elimination solver against the fastest Ceres solver of the same
// problem and seed, at τ = 0.01.
TableDef speedupTable(const Group& g) {
  TableDef d;
  d.id = "ba_" + g.name + "_speedup";
  d.title = fmt::format("Fastest Ceres time / own time to τ = {}, median / min, {} ({})",
                        tauText(kSpeedupTau), g.name, g.protocol);
  for (const std::string& solver : g.solvers) {
    if (solver.rfind("ceres", 0) != 0) d.columns.push_back(solver);
  }
  d.sample = [](const Instance& instance, const BaRunData& run, bool* failed) {
    if (!run.has_file) return std::vector<double>{};
    const auto timeOf = [&](const BaRunData& r) {
      return timeToCost(r.file,
                        instance.best + kSpeedupTau * (r.file.initial_cost - instance.best));
    };
    double ceres = kInf;
    for (const auto& [solver, other] : instance.by_solver) {
      if (solver.rfind("ceres", 0) == 0 && other->has_file) ceres = std::min(ceres, timeOf(*other));
    }
    if (!std::isfinite(ceres)) return std::vector<double>{};
    const double t = timeOf(run);
    *failed = !std::isfinite(t);
    return std::vector<double>(2, ceres / t);
  };
  d.quantities = {"median", "min"};
  d.reduce = {median, [](const std::vector<double>& v) {
                return v.empty() ? kNaN : *std::min_element(v.begin(), v.end());
              }};
  d.decimals = 2;
  d.notes = {
      "Per problem and seed, the time of the fastest Ceres solver (implicit, explicit or sparse "
      "Schur) to reach best + 0.01 (initial − best) over the solver's own (#39's target for "
      "ns-f32: ≥ 2 on every problem); > 1: faster than every Ceres solver. Median / smallest "
      "over the seeds; `x k/n`: the solver never reached the threshold on k seeds. Both on the "
      "same machine under the same load, one after the other."};
  return d;
}

TableDef finalTable(const Group& g) {
  TableDef d;
  d.id = "ba_" + g.name + "_final";
  d.title = fmt::format("Final cost, {} ({})", g.name, g.protocol);
  d.sample = [](const Instance&, const BaRunData& run, bool* failed) {
    *failed = run.failed;
    return std::vector<double>{run.file.final_cost};
  };
  d.quantities = {"final_cost"};
  d.reduce = {mean};
  d.spread_first = true;
  d.scientific = true;
  d.decimals = 6;
  d.notes = {
      "½ Σ ρ(‖r‖²) after the last iteration, mean ± sample std over the seeds (each seed a "
      "different perturbation, so the spread is that of the starts); `x k/n`: the solver "
      "stopped with status failed on k seeds (counted, not in the mean)."};
  return d;
}

TableDef gapTable(const Group& g) {
  TableDef d;
  d.id = "ba_" + g.name + "_gap";
  d.title = fmt::format("(final − best) / best, mean / max, {} ({})", g.name, g.protocol);
  d.sample = [](const Instance& instance, const BaRunData& run, bool* failed) {
    *failed = run.failed;
    return std::vector<double>(2, (run.file.final_cost - instance.best) / instance.best);
  };
  d.quantities = {"mean", "max"};
  d.reduce = {mean, maximum};
  d.scientific = true;
  d.decimals = 1;
  d.notes = {
      "best: the lowest final cost of any solver on the same problem and seed; mean / max over "
      "the seeds. 0 for the solver that reached best."};
  return d;
}

TableDef precisionTable(const Group& g) {
  TableDef d;
  d.id = "ba_" + g.name + "_precision";
  d.title = fmt::format(
      "f32 against f64: (final_f32 − final_f64) / final_f64, mean / max |·|, {} "
      "({})",
      g.name, g.protocol);
  d.columns = {"ns", "nsx", "sc"};
  d.run_of = [](const Instance& instance, const std::string& method) {
    return solverRun(instance, method + "-f32");
  };
  d.sample = [](const Instance& instance, const BaRunData& run, bool* failed) {
    // The f64 twin of "<method>-f32".
    const std::string method = run.solver.substr(0, run.solver.rfind('-'));
    const BaRunData* twin = solverRun(instance, method + "-f64");
    if (twin == nullptr) return std::vector<double>{};
    *failed = run.failed || twin->failed;
    const double r = (run.file.final_cost - twin->file.final_cost) / twin->file.final_cost;
    return std::vector<double>{r, std::abs(r)};
  };
  d.quantities = {"mean", "max_abs"};
  d.reduce = {mean, maximum};
  d.scientific = true;
  d.decimals = 1;
  d.notes = {
      "The same start (problem, seed) solved in single and in double precision by the same "
      "elimination; #39's target for ns: |·| ≤ 1e-3 on every problem and seed. `x k/n`: one "
      "of the two stopped with status failed on k seeds."};
  return d;
}

TableDef stepsTable(const Group& g) {
  TableDef d;
  d.id = "ba_" + g.name + "_steps";
  d.title = fmt::format("Failed / rejected steps, {} ({})", g.name, g.protocol);
  d.sample = [](const Instance&, const BaRunData& run, bool*) {
    if (!run.has_file) return std::vector<double>{};
    double failed = 0, rejected = 0;
    for (std::size_t i = 1; i < run.file.iterations.size(); ++i) {
      const BaIteration& it = run.file.iterations[i];
      if (!it.accepted) (it.message.empty() ? rejected : failed) += 1;
    }
    return std::vector<double>{failed, rejected};
  };
  d.quantities = {"failed", "rejected"};
  d.reduce = {mean, mean};
  d.decimals = 1;
  d.notes = {
      "Per run, of its LM trials: failed — the step could not be computed or evaluated (a "
      "landmark's H_ll not positive definite in the precision, a CG breakdown, a non-finite "
      "cost; the reason is in /iterations messages) — and rejected — computed, but the cost did "
      "not decrease; means over the seeds. Ceres: failed is its invalid step (its linear solver "
      "failed, e.g. CHOLMOD's \"Matrix not positive definite\" for ceres-sparse), rejected its "
      "other unsuccessful steps."};
  return d;
}

TableDef conditioningTable(const Group& g) {
  TableDef d;
  d.id = "ba_" + g.name + "_conditioning";
  d.title = fmt::format(
      "κ of the preconditioned reduced camera system (Ritz), median / max, {} "
      "({})",
      g.name, g.protocol);
  d.sample = [](const Instance&, const BaRunData& run, bool*) {
    std::vector<double> kappa;
    if (!run.has_file) return kappa;
    for (const BaIteration& it : run.file.iterations) {
      if (std::isfinite(it.ritz_min) && std::isfinite(it.ritz_max) && it.ritz_min > 0) {
        kappa.push_back(it.ritz_max / it.ritz_min);
      }
    }
    if (kappa.empty()) return kappa;
    return std::vector<double>{median(kappa), maximum(kappa)};
  };
  d.quantities = {"kappa_median", "kappa_max"};
  d.reduce = {median, median};
  d.scientific = true;
  d.decimals = 1;
  d.notes = {
      "Largest over smallest Ritz value of each CG solve (an estimate of the condition number of "
      "the Schur-Jacobi preconditioned, damped reduced system), median over the run's solves / "
      "their maximum, then medians over the seeds. `–`: the solver reports none (Ceres)."};
  return d;
}

TableDef memoryTable(const Group& g) {
  TableDef d;
  d.id = "ba_" + g.name + "_memory";
  d.title = fmt::format("Peak memory [MB] / total time [s], {} ({})", g.name, g.protocol);
  d.sample = [](const Instance&, const BaRunData& run, bool*) {
    return std::vector<double>{run.file.peak_rss_mb, run.file.total_time_s};
  };
  d.quantities = {"peak_rss_mb", "total_time_s"};
  d.reduce = {median, median};
  d.decimals = 1;
  d.notes = {
      "Peak resident set size of the `marglab ba` process (loading and the problem included), "
      "and the solve's wall time for all its iterations; medians over the seeds."};
  return d;
}

std::string protocolOf(const BaRunData& run) {
  if (!run.has_file) return "settings in the results files";
  const BaResultsFile& f = run.file;
  return fmt::format("{} iterations, Huber {} px, normalized to {}, σ = {}, {} thread{}",
                     f.max_iterations, f.huber_px, f.normalize_scale, f.perturb_sigma, f.threads,
                     f.threads == 1 ? "" : "s");
}

std::vector<Group> groupRuns(const std::vector<BaRunData>& runs) {
  std::vector<Group> groups;
  const std::vector<std::string> order = baSolverNames();
  for (const BaRunData& run : runs) {
    auto g = std::find_if(groups.begin(), groups.end(),
                          [&](const Group& x) { return x.name == run.group; });
    if (g == groups.end()) {
      groups.push_back({run.group, protocolOf(run), {}, {}});
      g = groups.end() - 1;
    }
    if (g->protocol == "settings in the results files" && run.has_file)
      g->protocol = protocolOf(run);
    if (std::find(g->solvers.begin(), g->solvers.end(), run.solver) == g->solvers.end()) {
      g->solvers.push_back(run.solver);
    }
    Instance& instance = g->problems[run.problem][run.seed];
    instance.by_solver[run.solver] = &run;
    if (std::isfinite(run.file.final_cost)) {
      instance.best = std::min(instance.best, run.file.final_cost);
    }
  }
  for (Group& g : groups) {
    std::sort(g.solvers.begin(), g.solvers.end(), [&](const auto& a, const auto& b) {
      return std::find(order.begin(), order.end(), a) < std::find(order.begin(), order.end(), b);
    });
  }
  return groups;
}

// A finished ba row of an index, from its results file when that is there, else from the row.
bool readRun(const std::string& dir, const IndexRow& row, BaRunData* run,
             std::vector<std::string>* warnings) {
  run->dir = dir;
  run->group = row.get("group");
  run->solver = row.get("variant");
  run->seed = std::stoull(row.get("seed").empty() ? "0" : row.get("seed"));
  run->failed = row.get("status") == "failed";
  const std::string path = (fs::path(dir) / row.get("results")).string();
  if (!row.get("results").empty() && fs::is_regular_file(path)) {
    try {
      run->file = readBaResults(path);
      run->has_file = true;
      run->problem = run->file.problem;
      run->failed = run->file.status == "failed";
      return true;
    } catch (const InputError& e) {
      warnings->push_back(
          fmt::format("{}: not a ba results file ({}); read from the index", path, e.what()));
    }
  }
  run->problem = balProblemName(row.get("dataset"));
  run->file.final_cost = row.number("final_cost");
  run->file.initial_cost = row.number("initial_cost");
  run->file.total_time_s = row.number("total_time_s");
  run->file.peak_rss_mb = row.number("peak_rss_mb");
  if (std::isfinite(run->file.final_cost)) return true;
  warnings->push_back(
      fmt::format("{}: run {} is finished but neither its results file nor its "
                  "index row holds a final cost; left out",
                  dir, row.get("id")));
  return false;
}

}  // namespace

double timeToCost(const BaResultsFile& run, double threshold) {
  for (const BaIteration& it : run.iterations) {
    if (it.cost <= threshold) return it.time_s;
  }
  return kInf;
}

std::vector<BaRunData> loadBaRuns(const std::vector<std::string>& dirs,
                                  std::vector<std::string>* warnings) {
  std::vector<BaRunData> runs;
  std::map<std::string, std::size_t> seen;  // group/problem/solver/seed → index in runs
  for (const std::string& dir : dirs) {
    for (const IndexRow& row : readIndex((fs::path(dir) / "index.csv").string())) {
      const std::string& status = row.get("status");
      if (row.get("kind") != "ba" || (status != "ok" && status != "failed")) continue;
      BaRunData run;
      if (!readRun(dir, row, &run, warnings)) continue;
      const std::string key =
          fmt::format("{}/{}/{}/{}", run.group, run.problem, run.solver, run.seed);
      const auto [it, fresh] = seen.emplace(key, runs.size());
      if (fresh) {
        runs.push_back(std::move(run));
        continue;
      }
      warnings->push_back(fmt::format("{}: run {} is also in {}; the later folder's is used", dir,
                                      row.get("id"), runs[it->second].dir));
      runs[it->second] = std::move(run);
    }
  }
  return runs;
}

std::vector<Table> buildBaTables(const std::vector<BaRunData>& runs,
                                 std::vector<std::string>* skipped) {
  std::vector<Table> tables;
  for (const Group& g : groupRuns(runs)) {
    std::vector<TableDef> defs;
    for (const double tau : kTaus) defs.push_back(tauTable(g, tau));
    if (std::any_of(g.solvers.begin(), g.solvers.end(),
                    [](const std::string& s) { return s.rfind("ceres", 0) == 0; })) {
      defs.push_back(speedupTable(g));
    }
    for (auto make :
         {finalTable, gapTable, precisionTable, stepsTable, conditioningTable, memoryTable}) {
      defs.push_back(make(g));
    }
    for (const TableDef& def : defs) {
      Table t = buildTable(g, def);
      if (hasValue(t)) {
        tables.push_back(std::move(t));
      } else {
        skipped->push_back(def.id +
                           ": no run with the values it needs (results files, or f32 "
                           "and f64 twins)");
      }
    }
  }
  return tables;
}

}  // namespace marglab::experiment
