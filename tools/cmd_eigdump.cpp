// `marglab eigdump RUN.h5 [--marg K | --all] [--csv] [--matrix]`: the spectrum of the
// marginalization priors stored in a results file (docs/design.md §6, /marg and /marg/eigenvalues).
//
// Default event: the last one (the prior the run ended with). K counts from 0; a negative K counts
// from the end (−1 = last). --csv prints "marg_index,eig_index,value" rows (full precision);
// --matrix adds the stored prior (H_m, b_m, and J_m, r_m for square-root storage) with its
// variable layout — only events stored with [diagnostics] store_prior_every have one.

#include <fmt/core.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/io/results_file.h"
#include "tools/command.h"
#include "tools/option_checks.h"

namespace marglab::cli {
namespace {

struct EigdumpOptions {
  std::string file;
  std::int64_t marg = -1;
  bool marg_given = false;
  bool all = false;
  bool csv = false;
  bool matrix = false;
};

std::string seconds(std::int64_t t_ns) {
  const std::int64_t m = t_ns < 0 ? -t_ns : t_ns;
  return fmt::format("{}{}.{:09d}", t_ns < 0 ? "-" : "", m / 1'000'000'000, m % 1'000'000'000);
}

std::string joinedEvents(const std::vector<std::int64_t>& ks) {
  if (ks.empty()) return "none";
  std::string text;
  for (std::size_t i = 0; i < ks.size() && i < 20; ++i)
    text += (i ? ", " : "") + std::to_string(ks[i]);
  if (ks.size() > 20) text += fmt::format(", … ({} in all)", ks.size());
  return text;
}

void printFileHeader(const ResultsReader& r) {
  const RunInfo& info = r.info();
  const RunMetadata& m = info.metadata;
  fmt::print("{}: {}/{} variant {} ({}, {}), status {}{}\n", r.path(), m.dataset, m.sequence,
             m.variant, m.mode, m.precision, info.status,
             info.status == "ok"
                 ? ""
                 : fmt::format(" at frame {}: {}", info.failure_frame, info.failure_reason));
}

void printEventText(std::size_t k, std::size_t count, const MargRecord& m) {
  fmt::print(
      "\nmarg {} of {}: frame {}, t {} s\n  prior {} cols, {} rows, rank {}; sigma_min {:.6e}, "
      "sigma_max {:.6e}, n_negative {} (tau {:.3e})\n  dEm:",
      k, count, m.frame_index, seconds(m.t_ns), m.prior_cols, m.prior_rows, m.rank, m.sigma_min,
      m.sigma_max, m.n_negative, m.eig_tolerance);
  for (int d = 0; d < kNumGaugeDirections; ++d) {
    fmt::print(" {} {:.3e}", kGaugeDirectionNames[static_cast<std::size_t>(d)], m.dEm(d));
  }
  fmt::print("\n  eigenvalues (ascending):\n");
  for (Eigen::Index i = 0; i < m.eigenvalues.size(); ++i) {
    fmt::print("  {:>5} {: .16e}\n", i, m.eigenvalues(i));
  }
}

void printEventCsv(std::size_t k, const MargRecord& m) {
  for (Eigen::Index i = 0; i < m.eigenvalues.size(); ++i) {
    fmt::print("{},{},{:.17g}\n", k, i, m.eigenvalues(i));
  }
}

void printMatrix(const char* name, const MatXd& M, bool csv) {
  fmt::print("{} {} ({}x{}):\n", csv ? "#" : " ", name, M.rows(), M.cols());
  for (Eigen::Index i = 0; i < M.rows(); ++i) {
    std::string line = csv ? "" : "   ";
    for (Eigen::Index j = 0; j < M.cols(); ++j) {
      line +=
          csv ? fmt::format("{}{:.17g}", j ? "," : "", M(i, j)) : fmt::format(" {: .9e}", M(i, j));
    }
    fmt::print("{}\n", line);
  }
}

void printPrior(std::int64_t k, const StoredPrior& p, bool csv) {
  const char* lead = csv ? "#" : " ";
  fmt::print("{} prior of marg {} ({} storage), layout:\n", lead, k, p.J_m.size() ? "sqrt" : "sq");
  for (const PriorVariable& v : p.layout) {
    fmt::print("{}   cols {:>3}..{:<3} {:<10} frame {}\n", lead, v.offset,
               v.offset + variableDimension(v.kind) - 1, variableKindName(v.kind), v.frame_id);
  }
  printMatrix("H_m", p.H_m, csv);
  printMatrix("b_m", p.b_m, csv);
  if (p.J_m.size() > 0) {
    printMatrix("J_m", p.J_m, csv);
    printMatrix("r_m", p.r_m, csv);
  }
}

int run(const EigdumpOptions& o) {
  if (o.all && o.marg_given) throw UsageError("--marg and --all exclude each other");
  const ResultsReader reader(o.file);
  const std::size_t count = reader.margCount();
  // With --all too: an empty CSV with exit 0 read as "every event, fine" (issue 38).
  if (count == 0) throw InputError(o.file, 0, "the run has no marginalization events");
  std::vector<std::size_t> events;
  if (o.all) {
    for (std::size_t k = 0; k < count; ++k) events.push_back(k);
  } else {
    const std::int64_t n = static_cast<std::int64_t>(count);
    const std::int64_t k = o.marg < 0 ? n + o.marg : o.marg;
    if (k < 0 || k >= n) {
      throw InputError(o.file, 0,
                       fmt::format("--marg {}: out of range, the run has {} marginalization events "
                                   "(0..{}, or -1..-{} from the end)",
                                   o.marg, n, n - 1, n));
    }
    events.push_back(static_cast<std::size_t>(k));
  }
  const std::vector<std::int64_t> stored =
      o.matrix ? reader.storedPriors() : std::vector<std::int64_t>{};
  if (o.matrix && !o.all) {
    if (!reader.prior(static_cast<std::int64_t>(events.front()))) {
      throw InputError(o.file, 0,
                       fmt::format("marg {}: the prior matrices of this event were not stored "
                                   "(stored events: {}; enable with [diagnostics] "
                                   "store_prior_every)",
                                   events.front(), joinedEvents(stored)));
    }
  }

  if (o.csv) {
    fmt::print("marg_index,eig_index,value\n");
  } else {
    printFileHeader(reader);
  }
  for (const std::size_t k : events) {
    const MargRecord m = reader.marg(k);
    if (o.csv) {
      printEventCsv(k, m);
    } else {
      printEventText(k, count, m);
    }
    if (o.matrix) {
      if (const auto prior = reader.prior(static_cast<std::int64_t>(k))) {
        printPrior(static_cast<std::int64_t>(k), *prior, o.csv);
      } else {
        fmt::print("{} marg {}: prior matrices not stored\n", o.csv ? "#" : " ", k);
      }
    }
  }
  return 0;
}

const bool kRegistered = registerCommand(
    {"eigdump", "Eigenvalues (and stored prior matrices) of the marginalization priors of a run",
     40, [](CLI::App& app) -> CommandRun {
       auto o = std::make_shared<EigdumpOptions>();
       app.add_option("file", o->file, "results file RUN.h5 written by `marglab run`")
           ->required()
           ->check(cli::existingPath("results file", cli::PathKind::kFile));
       app.add_option_function<std::int64_t>(
              "--marg",
              [o](const std::int64_t& k) {
                o->marg = k;
                o->marg_given = true;
              },
              "marginalization event K (0-based; negative counts from the end). Default: the "
              "last event (-1)")
           ->allow_extra_args(false);
       app.add_flag("--all", o->all, "every marginalization event");
       app.add_flag("--csv", o->csv, "machine-readable rows marg_index,eig_index,value");
       app.add_flag("--matrix", o->matrix,
                    "also print the stored prior (H_m, b_m; J_m, r_m for square-root storage) and "
                    "its variable layout");
       return [o] { return run(*o); };
     }});

}  // namespace
}  // namespace marglab::cli
