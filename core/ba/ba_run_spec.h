#pragma once
// One `marglab ba` run, typed: what `marglab ba` is given by its options or by a spec file, and
// what a sweep plans for a `kind = "ba"` group (core/experiment/sweep_def.h) — the one description
// that the verb, the sweep planner, its local children and its Slurm tasks share, validated once
// (baRunProblems) before any work.
//
// A spec file (runs/<id>.spec.toml in a sweep folder):
//
//   [ba]
//   problem = "/abs/datasets/bal/ladybug-problem-49-7776-pre.txt.bz2"
//   solver = "ns-f32"             # ns-f32 | ns-f64 | sc-f32 | sc-f64 | ceres-implicit | ...
//   iterations = 50               # LM trials (rootba's protocol: 50)
//   huber_px = 1.0                # 0: no robust loss
//   perturb_sigma = 0.01          # 0: no perturbation
//   seed = 38401                  # seed of the perturbation
//   normalize_scale = 100.0       # 0: no normalization
//   threads = 1                   # ns / sc: landmark blocks in parallel; Ceres: num_threads
//   isa = "auto"                  # the kernels of ns / sc: auto | sse2 | avx2 | avx512
//   output = "runs/x.h5"
//
// `marglab ba --spec FILE` runs it (a -o given beside it replaces `output`).

#include <string>
#include <vector>

#include "core/ba/ba_options.h"
#include "core/common/error.h"

namespace marglab {

struct BaRunSpec {
  std::string problem;  // a BAL file, plain or .bz2
  BaOptions options;    // the solver and the settings the verb exposes; the LM defaults otherwise
  std::string output;   // the HDF5 results file
  std::string isa = "auto";  // core/linalg/isa.h; `auto` is measured (core/bench/isa_choice.h)

  // The spec file's text (above); fromTomlString(toToml()) gives the same spec.
  std::string toToml() const;
  // Reads a spec file; throws InputError naming the file and the key's line (unknown keys, wrong
  // types, an unknown solver).
  static BaRunSpec fromTomlFile(const std::string& path);
  static BaRunSpec fromTomlString(const std::string& text, const std::string& name);

  // The `marglab ba` options that give this spec (without "ba"), e.g. a sweep index's command.
  std::vector<std::string> arguments() const;
};

// Everything wrong with a spec before any work: the problem file missing or unreadable, settings
// out of their range (validate(BaOptions)), no output. Does not parse the problem (loadBalProblem
// does, naming the line).
std::vector<Problem> baRunProblems(const BaRunSpec& spec);

}  // namespace marglab
