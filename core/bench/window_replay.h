#pragma once
// Replaying a captured window (WindowSnapshot): the estimator is rebuilt from the snapshot and runs
// the optimize() that processFrame() ran on that window. With the same build, variant and
// precision, the replayed step is bit-identical to the captured one (compareSteps checks every
// bit of the states after the step).

#include <optional>
#include <string>

#include "core/estimator/estimator.h"

namespace marglab {

struct ReplayResult {
  FrameResult result;
  WindowSnapshot::Step step;  // the states after the replayed optimize()
};

// Variant: the window's own (with precision) unless given. Throws InputError on a bad window.
ReplayResult replayWindow(const WindowSnapshot& window,
                          const std::optional<Variant>& variant = std::nullopt,
                          const std::optional<EstimatorSettings>& config = std::nullopt);

// Empty when `actual` equals `expected` bit for bit (iterations, costs, poses, speed-biases,
// landmark parameters); otherwise the first difference.
std::string compareSteps(const WindowSnapshot::Step& expected, const WindowSnapshot::Step& actual);

}  // namespace marglab
