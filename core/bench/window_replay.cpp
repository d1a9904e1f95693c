#include "core/bench/window_replay.h"

#include <fmt/core.h>

#include <cstring>

#include "core/estimator/estimator_probe.h"
namespace marglab {
namespace {

template <typename Scalar>
ReplayResult replayAs(const WindowSnapshot& window, const Variant& variant,
                      const std::optional<EstimatorSettings>& config) {
  auto estimator = SlidingWindowEstimator<Scalar>::fromSnapshot(window, variant, config);
  ReplayResult out;
  using Probe = EstimatorProbe<Scalar>;
  out.result.status = Probe::optimize(estimator, &out.result);
  WindowSnapshot after;
  Probe::recordStep(estimator, out.result, &after);
  out.step = std::move(after.after);
  return out;
}

template <typename Derived>
bool sameBits(const Eigen::MatrixBase<Derived>& a, const Eigen::MatrixBase<Derived>& b) {
  if (a.size() != b.size()) return false;
  const auto ea = a.eval();
  const auto eb = b.eval();
  return std::memcmp(ea.data(), eb.data(), sizeof(double) * static_cast<size_t>(ea.size())) == 0;
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

}  // namespace

ReplayResult replayWindow(const WindowSnapshot& window, const std::optional<Variant>& variant,
                          const std::optional<EstimatorSettings>& config) {
  const Variant v = variant ? *variant : Variant::parse(window.variant);
  return v.precision == Precision::kF32 ? replayAs<float>(window, v, config)
                                        : replayAs<double>(window, v, config);
}

std::string compareSteps(const WindowSnapshot::Step& e, const WindowSnapshot::Step& a) {
  if (e.lm_iterations != a.lm_iterations) {
    return fmt::format("LM iterations {} != {}", e.lm_iterations, a.lm_iterations);
  }
  if (!sameBits(e.cost_initial, a.cost_initial)) {
    return fmt::format("initial cost {:.17g} != {:.17g}", e.cost_initial, a.cost_initial);
  }
  if (!sameBits(e.cost_final, a.cost_final)) {
    return fmt::format("final cost {:.17g} != {:.17g}", e.cost_final, a.cost_final);
  }
  if (e.frames.size() != a.frames.size()) return "number of frames differs";
  for (size_t i = 0; i < e.frames.size(); ++i) {
    const auto& fe = e.frames[i];
    const auto& fa = a.frames[i];
    if (fe.id != fa.id) return fmt::format("frame id {} != {}", fe.id, fa.id);
    if (!sameBits(fe.T_w_i.unitQuaternion().coeffs(), fa.T_w_i.unitQuaternion().coeffs()) ||
        !sameBits(fe.T_w_i.translation(), fa.T_w_i.translation())) {
      return fmt::format("pose of frame {} differs", fe.id);
    }
    if (!sameBits(fe.speed_bias, fa.speed_bias)) {
      return fmt::format("speed-bias of frame {} differs", fe.id);
    }
  }
  if (e.landmarks.size() != a.landmarks.size()) return "number of landmarks differs";
  for (size_t i = 0; i < e.landmarks.size(); ++i) {
    if (e.landmarks[i].id != a.landmarks[i].id ||
        !sameBits(e.landmarks[i].param, a.landmarks[i].param)) {
      return fmt::format("landmark {} differs", e.landmarks[i].id);
    }
  }
  return "";
}

}  // namespace marglab
