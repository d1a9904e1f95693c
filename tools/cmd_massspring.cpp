// `marglab massspring`: the mass-spring experiment of Levine's marginalization primer (§6,
// Table 1, Fig. 3): single-stage Gauss–Newton against two-stage optimization with marginalization
// (core/massspring), on one grid and over a range of grid sizes. Prints tables (or JSON with
// --json), writes an HDF5 file with -o, and a figure of the final state to notebooks-out/ through
// tools/scripts/plot_massspring.py.

#include <fmt/core.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/common/subprocess.h"
#include "core/experiment/tables.h"
#include "core/io/hdf5.h"
#include "core/massspring/mass_spring.h"
#include "tools/command.h"
#include "tools/option_checks.h"

namespace marglab {
namespace {

using ceres_marg::Method;
using experiment::PaperCell;
using experiment::PaperTable;
using experiment::PaperValues;
using massspring::MassSpringSystem;

struct Options {
  int grid = 5;
  std::string sizes = "5,10,20,50,100";
  int iterations = 10;
  std::string method = "sparse-schur";
  int reps = 0;  // 0: automatic
  std::string output;
  bool json = false;
  bool no_plot = false;
  std::string plot_dir = "notebooks-out";
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

double maxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

struct SingleRow {
  massspring::SingleStageResult last;
  double ms = 0;
};

struct TwoRow {
  Method method = Method::kQr;
  massspring::TwoStageResult last;
  double marg_ms = 0, stage1_ms = 0, stage2_ms = 0, total_ms = 0;
  double max_abs_diff = 0;
};

SingleRow runSingle(const MassSpringSystem& system, int iterations, int reps) {
  SingleRow row;
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) {
    row.last = massspring::solveSingleStage(system, iterations);
    ms.push_back(row.last.solve_ms);
  }
  row.ms = median(ms);
  return row;
}

TwoRow runTwo(const MassSpringSystem& system, int iterations, int reps, Method method,
              const SingleRow& single) {
  TwoRow row;
  row.method = method;
  std::vector<double> marg, s1, s2, total;
  for (int r = 0; r < reps; ++r) {
    row.last = massspring::solveTwoStage(system, iterations, method);
    if (!row.last.status.ok()) {
      throw InputError("massspring", 0,
                       fmt::format("two-stage ({}) failed: {}", ceres_marg::toString(method),
                                   row.last.status.toString()));
    }
    marg.push_back(row.last.marginalize_ms);
    s1.push_back(row.last.stage1_ms);
    s2.push_back(row.last.stage2_ms);
    total.push_back(row.last.total_ms);
  }
  row.marg_ms = median(marg);
  row.stage1_ms = median(s1);
  row.stage2_ms = median(s2);
  row.total_ms = median(total);
  row.max_abs_diff = maxAbsDiff(row.last.x, single.last.x);
  return row;
}

// Peak memory of one grid: ~5.3 kB per mass (the sparse system, its factorization and the states
// of every iteration; measured at 100² to 600² masses: 0.10, 0.52 and 1.9 GB) over ~50 MB.
constexpr double kBytesPerMass = 5.3e3;
constexpr int kMaxGrid = 500;  // about 1.3 GB

// A grid side within [4, kMaxGrid], else a usage error saying the memory it would take.
void checkGridSize(const char* option, long n) {
  if (n < 4) {
    throw UsageError(
        fmt::format("{} {}: expected at least 4 (the corner sets must not overlap)", option, n));
  }
  if (n > kMaxGrid) {
    const double masses = static_cast<double>(n) * static_cast<double>(n);
    throw UsageError(
        fmt::format("{} {}: {:.0f} masses would take about {:.1f} GB of memory; expected at most "
                    "{} ({:.1f} GB)",
                    option, n, masses, masses * kBytesPerMass * 1e-9, kMaxGrid,
                    kMaxGrid * kMaxGrid * kBytesPerMass * 1e-9));
  }
}

int autoReps(int n) { return std::clamp(2500 / (n * n), 1, 20); }

// Dense QR / dense Schur build an N × (n_m + n_b) dense Jacobian: only for small grids.
bool denseFeasible(int n) { return n <= 30; }

std::string jsonDoubles(const std::vector<double>& v) {
  return fmt::format("[{}]", fmt::join(v, ","));
}

std::string plotJson(const MassSpringSystem& system, const std::vector<double>& final_x) {
  std::vector<int> springs;
  for (const auto& s : system.springs) {
    springs.insert(springs.end(), {s.i, s.j, s.p});
  }
  std::vector<double> anchors;
  std::vector<int> anchor_mass;
  for (const auto& a : system.anchors) {
    anchors.insert(anchors.end(), {a.point.x(), a.point.y()});
    anchor_mass.push_back(a.mass);
  }
  std::vector<int> nonlinear;
  for (int i = 0; i < system.num_masses; ++i)
    nonlinear.push_back(system.in_nonlinear_set[i] ? 1 : 0);
  return fmt::format(
      "{{\"n\":{},\"initial\":{},\"final\":{},\"springs\":[{}],\"energy_initial\":{},"
      "\"energy_final\":{},\"anchors\":{},\"anchor_mass\":[{}],\"nonlinear\":[{}]}}\n",
      system.spec.n, jsonDoubles(system.initial), jsonDoubles(final_x), fmt::join(springs, ","),
      jsonDoubles(system.springEnergies(system.initial)),
      jsonDoubles(system.springEnergies(final_x)), jsonDoubles(anchors),
      fmt::join(anchor_mass, ","), fmt::join(nonlinear, ","));
}

std::string findPythonWithMatplotlib() {
  for (const std::string candidate : {"/usr/bin/python3", "python3"}) {
    if (probeSucceeds({candidate, "-c", "import matplotlib"})) return candidate;
  }
  return {};
}

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
  const std::string data = plotJson(system, final_x);
  const bool written = write(fd, data.data(), data.size()) == static_cast<ssize_t>(data.size());
  close(fd);
  std::string message;
  if (!written) {
    message = "figure skipped: cannot write the temporary file";
  } else {
    const std::vector<std::string> command = {python, script, tmp, opt.plot_dir + "/massspring"};
    message = runHelper(command) == 0
                  ? fmt::format("figure: {0}/massspring.png, {0}/massspring.pdf", opt.plot_dir)
                  : "figure failed: " + fmt::format("{}", fmt::join(command, " "));
  }
  std::remove(tmp);
  return message;
}

// The primer's Table 1 (experiments/paper_values.toml [massspring_table1]): per-iteration solve
// times, single stage and two-stage, ms. Absent file: nothing to compare (installed binary).
struct PrimerTable {
  bool present = false;
  double single_ms = 0, two_ms = 0;
};

PrimerTable loadPrimerTable() {
  PrimerTable primer;
  const std::string path = experiment::defaultPaperValuesPath();
  if (access(path.c_str(), R_OK) != 0) return primer;
  const PaperValues paper = experiment::loadPaperValues(path);
  const auto it = paper.tables.find("massspring_table1");
  const PaperTable::Row* row =
      it == paper.tables.end() ? nullptr : it->second.row("solve_time_per_iteration");
  if (row == nullptr || row->cells.count("time_ms") == 0) {
    throw InputError(path, 0, "[massspring_table1] needs the row solve_time_per_iteration");
  }
  const std::vector<PaperCell>& cells = row->cells.at("time_ms");
  primer.present = cells.size() == 2 && cells[0].state == PaperCell::State::kValue &&
                   cells[1].state == PaperCell::State::kValue;
  if (primer.present) {
    primer.single_ms = cells[0].value;
    primer.two_ms = cells[1].value;
  }
  return primer;
}

// Per Gauss–Newton iteration, as the primer reports: the two-stage time (marginalization, stage 1
// and recovery) over the iterations.
void printPrimerTable(const PrimerTable& primer, int grid, int iterations, double single_ms,
                      double two_ms) {
  if (!primer.present) return;
  fmt::print(
      "\nprimer Table 1 beside ours: solve time per Gauss-Newton iteration, ms (ours: {0}x{0} "
      "grid, the whole solve / {1} iterations)\n\n",
      grid, iterations);
  fmt::print("| {:<12} | {:>9} | {:>9} |\n", "method", "primer", "marglab");
  fmt::print("|{:-<14}|{:->11}|{:->11}|\n", "", "", "");
  fmt::print("| {:<12} | {:>9.1f} | {:>9.3f} |\n", "single stage", primer.single_ms,
             single_ms / iterations);
  fmt::print("| {:<12} | {:>9.1f} | {:>9.3f} |\n", "two-stage", primer.two_ms, two_ms / iterations);
  fmt::print("| {:<12} | {:>8.1f}x | {:>8.1f}x |\n", "speedup", primer.single_ms / primer.two_ms,
             single_ms / two_ms);
}

struct ScalingRow {
  int n = 0;
  int masses = 0;
  SingleRow single;
  TwoRow two;
  int reps = 0;
};

// Grid sizes of the scaling table (--sizes, comma-separated).
std::vector<int> parseSizes(const std::string& list) {
  std::vector<int> sizes;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (item.empty()) continue;
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (*end != '\0') {
      throw UsageError("--sizes: '" + shortToken(item) + "' is not an integer grid size");
    }
    checkGridSize("--sizes", v);
    sizes.push_back(static_cast<int>(v));
  }
  return sizes;
}

// Everything one `marglab massspring` measures.
struct Measurements {
  MassSpringSystem system;
  Method method;
  int reps = 0;
  SingleRow single;
  std::vector<TwoRow> twos;  // one per two-stage method that fits the grid
  std::vector<ScalingRow> scaling;
  const TwoRow& main() const {
    return *std::find_if(twos.begin(), twos.end(),
                         [&](const TwoRow& t) { return t.method == method; });
  }
};

std::vector<ScalingRow> measureScaling(const Options& opt, const massspring::GridSpec& spec,
                                       Method method, const std::vector<int>& sizes) {
  std::vector<ScalingRow> scaling;
  for (int n : sizes) {
    if (!opt.json && cli::stderrIsTerminal()) fmt::print(stderr, "\rscaling: {}x{} ...   ", n, n);
    massspring::GridSpec s = spec;
    s.n = n;
    const MassSpringSystem sys = MassSpringSystem::grid(s);
    ScalingRow row;
    row.n = n;
    row.masses = sys.num_masses;
    row.reps = opt.reps > 0 ? opt.reps : autoReps(n);
    row.single = runSingle(sys, opt.iterations, row.reps);
    row.two = runTwo(sys, opt.iterations, row.reps, method, row.single);
    scaling.push_back(row);
  }
  if (!opt.json && cli::stderrIsTerminal() && !sizes.empty()) fmt::print(stderr, "\r{:40}\r", "");
  return scaling;
}

Measurements measure(const Options& opt, Method method, const std::vector<int>& sizes) {
  massspring::GridSpec spec;
  spec.n = opt.grid;
  Measurements m{MassSpringSystem::grid(spec), method, 0, {}, {}, {}};
  m.reps = opt.reps > 0 ? opt.reps : autoReps(opt.grid);
  m.single = runSingle(m.system, opt.iterations, m.reps);
  for (Method two : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
    if (two != method && !denseFeasible(opt.grid)) continue;
    m.twos.push_back(runTwo(m.system, opt.iterations, m.reps, two, m.single));
  }
  m.scaling = measureScaling(opt, spec, method, sizes);
  return m;
}

void printJson(const Options& opt, const Measurements& m, const PrimerTable& primer,
               const std::string& figure) {
  const Method method = m.method;
  const double speedup = m.single.ms / m.main().total_ms;
  std::vector<std::string> methods, rows;
  for (const TwoRow& t : m.twos) {
    methods.push_back(fmt::format(
        "\"{}\":{{\"marginalize_ms\":{:.6g},\"stage1_ms\":{:.6g},\"stage2_ms\":{:.6g},"
        "\"two_stage_ms\":{:.6g},\"speedup\":{:.6g},\"max_abs_diff\":{:.3e},\"prior_rows\":{},"
        "\"prior_condition\":{:.6g}}}",
        ceres_marg::toString(t.method), t.marg_ms, t.stage1_ms, t.stage2_ms, t.total_ms,
        m.single.ms / t.total_ms, t.max_abs_diff, t.last.marginalization.prior_rows,
        t.last.marginalization.condition_number));
  }
  for (const ScalingRow& r : m.scaling) {
    rows.push_back(fmt::format(
        "{{\"grid\":{},\"masses\":{},\"reps\":{},\"single_stage_ms\":{:.6g},"
        "\"marginalize_ms\":{:.6g},\"stage1_ms\":{:.6g},\"stage2_ms\":{:.6g},"
        "\"two_stage_ms\":{:.6g},\"speedup\":{:.6g},\"max_abs_diff\":{:.3e}}}",
        r.n, r.masses, r.reps, r.single.ms, r.two.marg_ms, r.two.stage1_ms, r.two.stage2_ms,
        r.two.total_ms, r.single.ms / r.two.total_ms, r.two.max_abs_diff));
  }
  fmt::print(
      "{{\"grid\":{},\"masses\":{},\"nonlinear_masses\":{},\"iterations\":{},\"reps\":{},"
      "\"method\":\"{}\",\"single_stage_ms\":{:.6g},\"two_stage_ms\":{:.6g},\"speedup\":{:.6g},"
      "\"max_abs_diff\":{:.3e},\"final_energy\":{:.12g},\"two_stage\":{{{}}},\"scaling\":[{}]"
      "{}}}\n",
      opt.grid, m.system.num_masses, m.system.nonlinearMasses(), opt.iterations, m.reps,
      ceres_marg::toString(method), m.single.ms, m.main().total_ms, speedup, m.main().max_abs_diff,
      m.single.last.final_cost, fmt::join(methods, ","), fmt::join(rows, ","),
      primer.present ? fmt::format(",\"primer_table1\":{{\"single_stage_ms_per_iteration\":{},"
                                   "\"two_stage_ms_per_iteration\":{}}}",
                                   primer.single_ms, primer.two_ms)
                     : std::string());
  if (!figure.empty()) fmt::print(stderr, "{}\n", figure);
}

void printText(const Options& opt, const Measurements& m, const PrimerTable& primer,
               const std::string& figure) {
  const Method method = m.method;
  const int reps = m.reps;
  fmt::print(
      "marglab massspring: {0}x{0} grid (primer §6), {1} masses, {2} in N (touched by p = 4 "
      "springs), {3} springs + {4} anchors\n",
      opt.grid, m.system.num_masses, m.system.nonlinearMasses(), m.system.springs.size(),
      m.system.anchors.size());
  fmt::print(
      "Gauss-Newton, {} iterations in both methods; times are medians of {} runs (problem "
      "construction not timed)\n",
      opt.iterations, reps);
  fmt::print(
      "single stage: all masses, sparse normal Cholesky; two-stage: marginalize the {} masses "
      "outside N, {} iterations on N (dense normal Cholesky), recover the rest by CHOLMOD\n\n",
      m.system.num_masses - m.system.nonlinearMasses(), opt.iterations);
  fmt::print("| {:<26} | {:>9} | {:>9} | {:>9} | {:>9} | {:>7} | {:>12} | {:>9} |\n", "method",
             "marg ms", "stage1 ms", "stage2 ms", "total ms", "speedup", "max|dx|", "prior");
  fmt::print("|{:-<28}|{:->11}|{:->11}|{:->11}|{:->11}|{:->9}|{:->14}|{:->11}|\n", "", "", "", "",
             "", "", "", "");
  fmt::print("| {:<26} | {:>9} | {:>9} | {:>9} | {:>9.3f} | {:>7} | {:>12} | {:>9} |\n",
             "single stage", "", "", "", m.single.ms, "1.0", "", "");
  for (const TwoRow& t : m.twos) {
    fmt::print(
        "| {:<26} | {:>9.3f} | {:>9.3f} | {:>9.3f} | {:>9.3f} | {:>7.1f} | {:>12.2e} | "
        "{:>4}x{:<4} |\n",
        fmt::format("two-stage, {}{}", ceres_marg::toString(t.method),
                    t.method == method ? " *" : ""),
        t.marg_ms, t.stage1_ms, t.stage2_ms, t.total_ms, m.single.ms / t.total_ms, t.max_abs_diff,
        t.last.marginalization.prior_rows, t.last.marginalization.blanket_dim);
  }
  fmt::print(
      "\nfinal energy {:.10g} (single) vs {:.10g} (two-stage); max|dx| is the largest coordinate "
      "difference of the two final states. * = --method\n",
      m.single.last.final_cost, m.main().last.final_cost);
  printPrimerTable(primer, opt.grid, opt.iterations, m.single.ms, m.main().total_ms);
  if (!m.scaling.empty()) {
    fmt::print("\nscaling (two-stage with {}):\n\n", ceres_marg::toString(method));
    fmt::print(
        "| {:>9} | {:>6} | {:>4} | {:>10} | {:>9} | {:>9} | {:>9} | {:>10} | {:>7} | {:>9} |\n",
        "grid", "masses", "reps", "single ms", "marg ms", "stage1 ms", "stage2 ms", "2-stage ms",
        "speedup", "max|dx|");
    fmt::print("|{:->11}|{:->8}|{:->6}|{:->12}|{:->11}|{:->11}|{:->11}|{:->12}|{:->9}|{:->11}|\n",
               "", "", "", "", "", "", "", "", "", "");
    for (const ScalingRow& r : m.scaling) {
      fmt::print(
          "| {:>9} | {:>6} | {:>4} | {:>10.3f} | {:>9.3f} | {:>9.3f} | {:>9.3f} | {:>10.3f} | "
          "{:>7.1f} | {:>9.1e} |\n",
          fmt::format("{0}x{0}", r.n), r.masses, r.reps, r.single.ms, r.two.marg_ms,
          r.two.stage1_ms, r.two.stage2_ms, r.two.total_ms, r.single.ms / r.two.total_ms,
          r.two.max_abs_diff);
    }
  }
  if (!figure.empty()) fmt::print("\n{}\n", figure);
}

void writeResults(const Options& opt, const Measurements& m) {
  const Method method = m.method;
  const double speedup = m.single.ms / m.main().total_ms;
  h5::File file = h5::File::create(opt.output);
  file.setAttr("experiment", "massspring");
  file.setAttr("grid", opt.grid);
  file.setAttr("iterations", opt.iterations);
  file.setAttr("reps", m.reps);
  file.setAttr("method", ceres_marg::toString(method));
  file.setAttr("single_stage_ms", m.single.ms);
  file.setAttr("two_stage_ms", m.main().total_ms);
  file.setAttr("speedup", speedup);
  file.setAttr("max_abs_diff", m.main().max_abs_diff);
  const auto asRows = [](const std::vector<double>& x) {
    return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>(
        x.data(), static_cast<Eigen::Index>(x.size() / 2), 2);
  };
  const h5::Group state = file.group("state");
  state.writeMatrix("rest", asRows(m.system.rest));
  state.writeMatrix("initial", asRows(m.system.initial));
  state.writeMatrix("single_stage", asRows(m.single.last.x));
  state.writeMatrix("two_stage", asRows(m.main().last.x));
  std::vector<std::int32_t> springs;
  for (const auto& s : m.system.springs) springs.insert(springs.end(), {s.i, s.j, s.p});
  state.write("springs", springs.data(), m.system.springs.size(), 3);
  state.write("energy_final", m.system.springEnergies(m.single.last.x));
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
  if (!m.scaling.empty()) {
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
  file.commit();
}

int runMassSpring(const Options& opt, bool sizes_given, bool grid_given) {
  Method method;
  if (!ceres_marg::parseMethod(opt.method, &method)) {
    throw UsageError("--method must be qr, schur or sparse-schur, not '" + opt.method + "'");
  }
  checkGridSize("--grid", opt.grid);
  if (opt.iterations < 1) throw UsageError("--iterations must be at least 1");
  const std::vector<int> sizes =
      sizes_given || !grid_given ? parseSizes(opt.sizes) : std::vector<int>{};
  if (!denseFeasible(opt.grid) && method != Method::kSparseSchur) {
    throw UsageError(fmt::format(
        "--method {} builds a dense Jacobian; use sparse-schur above {}x{}", opt.method, 30, 30));
  }
  const Measurements m = measure(opt, method, sizes);
  std::string figure;
  if (!opt.no_plot) figure = writeFigure(opt, m.system, m.main().last.x);
  const PrimerTable primer = loadPrimerTable();
  if (opt.json) {
    printJson(opt, m, primer, figure);
  } else {
    printText(opt, m, primer, figure);
  }
  if (!opt.output.empty()) writeResults(opt, m);
  return 0;
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
           ->capture_default_str()
           ->check(cli::intRange("Gauss-Newton iterations", 1, 1000));
       sub.add_option("--method", opt->method, "Marginalization: qr, schur or sparse-schur")
           ->capture_default_str();
       sub.add_option("--reps", opt->reps, "Timing repetitions (0: automatic, median reported)")
           ->capture_default_str()
           ->check(cli::intRange("timing repetitions (0: automatic)", 0, 10000));
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
