// `marglab bench`: the benchmark suite's key measurements in one process, side by side on the
// shipped captured windows, plus whole runs (core/bench/bench_report.h). Writes a Markdown table
// (and the JSON) to results/perf/; --json prints the JSON object on stdout.

#include <fmt/core.h>
#include <unistd.h>

#include <climits>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/bench/bench_report.h"
#include "core/bench/isa_choice.h"
#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/estimator/variant.h"
#include "core/linalg/isa.h"
#include "tools/command.h"
#include "tools/option_checks.h"

namespace marglab {
namespace {

struct BenchArgs {
  bool json = false;
  std::string out = "results/perf";
  int rounds = 5;
  double batch_ms = 30;
  int frames = 0;
  bool no_runs = false;
  bool quick = false;
  std::string isa = "auto";
  std::vector<std::string> variants;
};

std::string selfExe() {
  char buf[PATH_MAX];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) throw InputError("/proc/self/exe", 0, "cannot find the marglab executable");
  buf[n] = '\0';
  return buf;
}

int runBenchCommand(const BenchArgs& a) {
  activateIsa(a.isa);
  BenchOptions o;
  o.rounds = a.quick ? 1 : a.rounds;
  o.batch_s = (a.quick ? 2 : a.batch_ms) * 1e-3;
  o.run_frames = a.frames;
  o.verbose = !a.json || cli::stderrIsTerminal();
  std::filesystem::create_directories(a.out);
  o.work_dir = a.out;
  if (!a.no_runs) o.run_exe = selfExe();
  for (const std::string& v : a.variants) o.variants.push_back(Variant::parse(v));
  const BenchReport report = runBench(o);
  const std::string md = benchMarkdown(report);
  const std::string json = benchJson(report);
  const std::filesystem::path md_path = std::filesystem::path(a.out) / "bench.md";
  const std::filesystem::path json_path = std::filesystem::path(a.out) / "bench.json";
  writeFileAtomically(md_path.string(), md);
  writeFileAtomically(json_path.string(), json + "\n");
  if (a.json) {
    fmt::print("{}\n", json);
  } else {
    fmt::print("{}\nwritten: {} and {}\n", md, md_path.string(), json_path.string());
  }
  return 0;
}

const bool kRegistered = cli::registerCommand(
    {"bench",
     "Benchmarks on the captured windows (LM iteration ns/sc x f32/f64, Ceres peer, "
     "marginalization, QR kernel vs peak) and whole runs; writes results/perf/",
     85, [](CLI::App& sub) -> cli::CommandRun {
       auto a = std::make_shared<BenchArgs>();
       sub.add_flag("--json", a->json, "Print one JSON object instead of the table");
       CLI::Option* out =
           sub.add_option("--out", a->out,
                          "Folder of bench.md / bench.json (--quick: results/perf/quick, so that "
                          "the noisy numbers never replace the committed ones)")
               ->capture_default_str();
       sub.add_option("--rounds", a->rounds, "Rounds per side-by-side measurement (best kept)")
           ->capture_default_str()
           ->check(cli::intRange("the number of rounds", 1, 1000));
       sub.add_option("--batch-ms", a->batch_ms, "Minimum batch duration per candidate and round")
           ->capture_default_str()
           ->check(cli::positiveReal("a duration in ms", 60000));
       sub.add_option("--frames", a->frames,
                      "Whole runs: only the first N frames of EuRoC MH_01 and KITTI 00 (0: all)")
           ->capture_default_str()
           ->check(cli::nonNegativeInt("the number of frames (0: all)"));
       sub.add_option("--isa", a->isa,
                      "Instruction set of the kernels for the iteration, marginalization and "
                      "convergence timings and the whole runs (the QR kernel is timed for every "
                      "ISA the CPU has)")
           ->check(CLI::IsMember({"auto", "sse2", "avx2", "avx512"}))
           ->capture_default_str();
       sub.add_option("--variant", a->variants,
                      "Also time this variant's LM iteration and marginalization on every window, "
                      "beside ns-qr-sqrt-f32 (repeatable), e.g. --variant sc-sc-sqp-f32");
       sub.add_flag("--no-runs", a->no_runs, "Skip the whole runs");
       sub.add_flag("--quick", a->quick, "One round, short batches (for tests; noisy)");
       return [a, out] {
         if (a->quick && out->count() == 0) a->out = "results/perf/quick";
         return runBenchCommand(*a);
       };
     }});

}  // namespace
}  // namespace marglab
