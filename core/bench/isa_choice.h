#pragma once
// `--isa auto`: the instruction set whose kernels run one Levenberg–Marquardt iteration fastest on
// this machine, measured once and cached (docs/design.md §ISA dispatch).
//
// Why measure: the widest ISA is not always the fastest. On a Xeon with AVX-512, the AVX2 copies
// ran an LM iteration 7–11 % faster (the 512-bit units lower the clock, and the blocks are small:
// a landmark's [J_p J_l r] has 3 + a few dozen columns). The choice only picks among the copies;
// a run's numbers depend on its ISA alone, and the results file records both the ISA and how it
// was chosen (root attribute isa_choice).
//
// The probe: each shipped captured window (datasets/windows: one VIO window of EuRoC MH_01, one VO
// window of KITTI 00) under the two headline eliminations ns-qr-sqrt-f32 and sc-sc-sq-f64, one
// full iteration (linearize, eliminate, solve) per repetition, the ISAs interleaved so that a
// slower moment of a busy machine does not fall on one ISA; per ISA the sum over the four of the
// fastest repetition. The ISA within 1 % of the fastest that is narrowest is taken: a tie goes
// to the copy that lowers the clock least.
//
// The cache: one TOML table per (CPU model, build revision) in $MARGLAB_ISA_CACHE, else
// $XDG_CACHE_HOME/marglab/isa_choice.toml, else ~/.cache/marglab/isa_choice.toml, read and
// written under flock(2) so that the parallel runs of a sweep measure once and agree. Where it
// cannot be written, the choice is measured for this process only, and says so.

#include <string>
#include <vector>

#include "core/linalg/isa.h"

namespace marglab {

struct IsaTiming {
  Isa isa = Isa::kSse2;
  double seconds = 0;  // the probe's sum of fastest iterations
};

struct IsaChoice {
  Isa isa = Isa::kSse2;
  std::vector<IsaTiming> timings;  // empty when only one ISA is available
  std::string how;                 // the results file's isa_choice: how and where it was decided
};

// Times the probe on every available ISA (restores the active ISA).
std::vector<IsaTiming> timeIsas(int repetitions);
// The narrowest ISA within 1 % of the fastest.
Isa fastestIsa(const std::vector<IsaTiming>& timings);
// The cache file (see above).
std::string isaCachePath();
// The choice of this machine and build: from the cache, else measured and cached.
IsaChoice chooseAutoIsa();
// "auto" → chooseAutoIsa() (measured, cached); a name → that ISA (resolveIsa's errors). Sets the
// process's active ISA and how it was chosen; call it once before any estimator object is built.
void activateIsa(const std::string& name);

}  // namespace marglab
