// `marglab reproduce [--quick]`: the paper on the shipped data in one command — the sweeps, the
// tables beside the paper's values, the figures, the executed notebooks and the report.
//   --quick  experiments/quick.toml → results/quick (tables in results/quick/tables) and
//            quick_figs_basalt.toml → results/quick_figs_basalt; figures, notebooks (`marglab
//            notebooks`) and report.html (`marglab report`, checked in headless Chromium when it
//            is installed) in notebooks-out/quick (< 10 min on 2 cores)
//   full     experiments/paper_vo.toml → results/paper_vo, paper_vio.toml → results/paper_vio and
//            paper_figs_basalt.toml → results/paper_figs_basalt; tables in results/paper/tables,
//            figures in notebooks-out/paper
// In both, the tables come from every sweep but the last, the VO figures (Figs. 5–7) from the
// first and the VIO figures (Figs. 1 and 4) from the last, whose VIO-32 survives MH_01 with
// Basalt's IMU densities (with the Kalibr densities of the table sweeps it fails at frame 9, so
// Fig. 4's finding cannot show: issue #40 §3); notebooks and report of each sweep in
// notebooks-out/<sweep>.

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <memory>

#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/common/subprocess.h"
#include "core/experiment/plotting.h"
#include "core/experiment/sweep_def.h"
#include "core/experiment/sweep_runner.h"
#include "core/experiment/tables.h"
#include "tools/analysis.h"
#include "tools/command.h"
#include "tools/option_checks.h"

namespace marglab {
namespace cli {

// Defined in cmd_sweep.cpp: checks a sweep's extra `run` options with the real `run` verb.
experiment::ParseOptions sweepParseOptions();

}  // namespace cli

namespace {

namespace fs = std::filesystem;

struct ReproduceArgs {
  bool quick = false;
  int jobs = 0;
  bool resume = false;
  bool no_analysis = false;  // skip the notebooks and the report
  std::string experiments = std::string(sourceDir()) + "/experiments";
  std::string results = "results";
  std::string figures = "notebooks-out";
  std::string backend = "local";
  std::vector<std::string> slurm_args;
};

// The Markdown of one table out of the combined tables file, for the closing summary.
std::string extractTable(const std::string& markdown, const std::string& title_prefix) {
  const auto start = markdown.find("### " + title_prefix);
  if (start == std::string::npos) return {};
  const auto end = markdown.find("\n### ", start + 1);
  const std::string table = markdown.substr(start, end == std::string::npos ? end : end - start);
  // Keep the heading and the table rows, not the notes.
  std::string out;
  std::size_t pos = 0;
  while (pos < table.size()) {
    const auto nl = table.find('\n', pos);
    const std::string line = table.substr(pos, nl == std::string::npos ? nl : nl - pos + 1);
    if (line.rfind("###", 0) == 0) out += line + "\n";
    if (line.rfind("|", 0) == 0) out += line;
    if (nl == std::string::npos) break;
    pos = nl + 1;
  }
  return out;
}

// Whether a sweep's exit code says SIGINT or SIGTERM stopped it (128 + signal): then nothing
// after it runs, neither the next sweep nor the tables, figures and notebooks of a part.
bool interruptedExit(int code) {
  return code == exitCodeForSignal(SIGINT) || code == exitCodeForSignal(SIGTERM);
}

// Runs the sweeps (validated before any runs) and returns the worst exit code, 128 + signal at
// once on an interrupt; dirs gets each sweep's folder.
int runSweeps(const ReproduceArgs& args, const std::vector<std::string>& files,
              std::vector<std::string>* dirs) {
  std::vector<experiment::SweepPlan> plans;
  for (const std::string& f : files) {
    plans.push_back(experiment::loadSweepFile((fs::path(args.experiments) / f).string(),
                                              cli::sweepParseOptions()));
  }
  int worst = 0;
  for (std::size_t i = 0; i < plans.size(); ++i) {
    experiment::SweepOptions options;
    options.out_dir = (fs::path(args.results) / plans[i].name).string();
    options.jobs = args.jobs;
    options.resume = args.resume;
    options.force = !args.resume;  // reproduce recomputes unless asked to continue
    options.status_line = cli::stderrIsTerminal();
    options.backend = args.backend;
    options.slurm.extra = args.slurm_args;
    options.slurm.wait = true;  // the tables need the runs
    const int code = experiment::runSweepAndReport(
        plans[i], (fs::path(args.experiments) / files[i]).string(), options);
    if (interruptedExit(code)) return code;
    worst = std::max(worst, code);
    dirs->push_back(options.out_dir);
  }
  return worst;
}

// The notebooks and the report of each sweep (issue #20).
struct Analysis {
  int code = 0;
  double notebook_seconds = 0;
  std::vector<std::string> reports, notebook_dirs;
};

Analysis runAnalysis(const ReproduceArgs& args, const std::vector<std::string>& dirs,
                     const std::string& tables, const std::string& figures) {
  Analysis analysis;
  for (const std::string& dir : dirs) {
    const std::string out = (fs::path(args.figures) / fs::path(dir).filename()).string();
    cli::NotebooksRequest notebooks;
    notebooks.dir = dir;
    notebooks.out = out;
    notebooks.jobs = args.jobs;
    const auto nb_start = std::chrono::steady_clock::now();
    const int nb_code = cli::runNotebooks(notebooks);
    analysis.notebook_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - nb_start).count();
    if (nb_code == 0) analysis.notebook_dirs.push_back(out);
    cli::ReportRequest report;
    report.dir = dir;
    report.out = out;
    report.tables = tables;
    report.figures = figures;
    report.check = cli::ReportRequest::Check::kIfAvailable;
    const int report_code = cli::runReport(report);
    if (report_code == 0) analysis.reports.push_back((fs::path(out) / "report.html").string());
    analysis.code = std::max({analysis.code, nb_code, report_code});
  }
  return analysis;
}

// Figs. 5–7 from the first sweep, Figs. 1 and 4 from the last (see the top of this file).
int drawFigures(const std::vector<std::string>& dirs, const std::string& out) {
  experiment::PlotRequest vo;
  vo.dirs = {dirs.front()};
  vo.out = out;
  vo.figures = "fig5,fig6,fig7";
  experiment::PlotRequest vio = vo;
  vio.dirs = {dirs.back()};
  vio.figures = "fig1,fig4,fig4_yaw";
  const int vo_code = experiment::runPlot(vo);
  return std::max(vo_code, experiment::runPlot(vio));
}

int runReproduce(const ReproduceArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<std::string> files =
      args.quick
          ? std::vector<std::string>{"quick.toml", "quick_figs_basalt.toml"}
          : std::vector<std::string>{"paper_vo.toml", "paper_vio.toml", "paper_figs_basalt.toml"};
  std::vector<std::string> dirs;
  const int worst = runSweeps(args, files, &dirs);
  if (interruptedExit(worst)) return worst;

  const std::string name = args.quick ? "quick" : "paper";
  experiment::TablesRequest tables;
  tables.dirs.assign(dirs.begin(), dirs.end() - 1);
  tables.out = (fs::path(args.results) / name / "tables").string();
  std::string markdown;
  const std::vector<std::string> table_files = experiment::writeTables(tables, &markdown);

  const std::string figures = (fs::path(args.figures) / name).string();
  const int plot_code = drawFigures(dirs, figures);
  const Analysis analysis =
      runAnalysis(args, args.no_analysis ? std::vector<std::string>{} : dirs, tables.out, figures);

  const double minutes =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60.0;
  fmt::print("\n{}\n{}", extractTable(markdown, "Table 2:"), extractTable(markdown, "Table 1:"));
  fmt::print("\nreproduce{} finished in {:.1f} min\n", args.quick ? " --quick" : "", minutes);
  fmt::print("  results  {}  (index.csv: one row per run, HDF5 files in runs/)\n",
             fmt::join(dirs, ", "));
  fmt::print("  tables   {}\n", fmt::join(table_files, ", "));
  fmt::print(
      "  figures  {}{}\n", figures,
      plot_code == 0 ? "  (fig1, fig4, fig4_yaw-fig7 as PNG and PDF)" : "  (NOT drawn, see above)");
  if (!args.no_analysis) {
    fmt::print("  notebooks {}  ({}; executed in {:.0f} s)\n",
               analysis.notebook_dirs.empty()
                   ? std::string("NOT executed, see above")
                   : fmt::format("{}", fmt::join(analysis.notebook_dirs, ", ")),
               "sweep.html, precision.html, runs/<id>.html and .ipynb", analysis.notebook_seconds);
    fmt::print("  report   {}\n", analysis.reports.empty()
                                      ? std::string("NOT written, see above")
                                      : fmt::format("{}", fmt::join(analysis.reports, ", ")));
  }
  return std::max({worst, plot_code, analysis.code});
}

const bool kRegistered = cli::registerCommand(
    {"reproduce", "The paper on the shipped data: sweeps, tables and figures in one command", 50,
     [](CLI::App& sub) -> cli::CommandRun {
       auto args = std::make_shared<ReproduceArgs>();
       sub.add_flag("--quick", args->quick,
                    "experiments/quick.toml (KITTI 10 all variants, KITTI 05 and EuRoC MH_01 "
                    "headline variants) and quick_figs_basalt.toml (MH_01 for Figs. 1 and 4); "
                    "< 10 min on 2 cores, instead of every sequence and variant");
       sub.add_option("-j,--jobs", args->jobs, "Runs in parallel (0: number of cores)")
           ->capture_default_str()
           ->check(cli::jobCount());
       sub.add_flag("--resume", args->resume,
                    "Keep complete runs of an earlier, interrupted reproduction (default: start "
                    "over)");
       sub.add_option("--experiments", args->experiments, "Folder of the sweep definitions")
           ->capture_default_str()
           ->check(cli::existingPath("--experiments", cli::PathKind::kFolder));
       sub.add_option("--results", args->results, "Folder for the sweep results and tables")
           ->capture_default_str();
       sub.add_option("--figures", args->figures, "Folder for the figures, notebooks and report")
           ->capture_default_str();
       sub.add_flag("--no-analysis", args->no_analysis,
                    "Skip the notebooks and the report (`marglab notebooks`, `marglab report`)");
       sub.add_option("--backend", args->backend, "Sweep backend: local or slurm (see sweep)")
           ->capture_default_str()
           ->check(CLI::IsMember({"local", "slurm"}));
       sub.add_option("--slurm-arg", args->slurm_args,
                      "slurm: a further sbatch option, verbatim (repeatable)")
           ->allow_extra_args(false);
       return [args] { return runReproduce(*args); };
     }});

}  // namespace
}  // namespace marglab
