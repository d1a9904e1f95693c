#include "core/estimator/levenberg_marquardt.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/common/scalar.h"

namespace marglab {

template <typename Scalar>
LevenbergMarquardt<Scalar>::LevenbergMarquardt(const EstimatorSettings& config,
                                               const Variant& variant)
    : config_(config), variant_(variant), lambda_(static_cast<Scalar>(config.lambda_init)) {}

template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> LevenbergMarquardt<Scalar>::makeLinearization() const {
  typename Linearization<Scalar>::Options options;
  options.damp_landmarks = config_.lm_landmark_damping;
  options.lambda_min = static_cast<Scalar>(config_.lambda_min);
  options.preconditioning = preconditioningOf(variant_.storage);
  options.solve_indefinite = config_.lm_indefinite_system == IndefiniteSystem::kSolve;
  return marglab::makeLinearization<Scalar>(variant_, options);
}

template <typename Scalar>
LmSummary LevenbergMarquardt<Scalar>::optimize(Window<Scalar>* window) {
  LmSummary summary;
  lambda_ = static_cast<Scalar>(config_.lambda_init);
  nu_ = Scalar(2);
  Scalar cost = window->totalCost();
  summary.cost_initial = static_cast<double>(cost);
  if (!std::isfinite(cost)) {
    summary.status =
        Status::Error(Status::Code::kNotFinite, "the cost of the window is not finite");
    return summary;
  }
  // Basalt counts every cost evaluation (`it <= vio_max_iterations`), rejected λ trials too.
  const bool basalt = config_.lm_stop_rule == LmStopRule::kBasalt;
  evaluations_left_ = basalt ? config_.lm_max_iterations + 1 : std::numeric_limits<int>::max();
  const int max_linearizations = basalt ? evaluations_left_ : config_.lm_max_iterations;
  const std::unique_ptr<Linearization<Scalar>> lin = makeLinearization();
  for (int it = 0; it < max_linearizations; ++it) {
    lin->linearize(*window);
    bool stop = false;
    Status s = lin->eliminate();
    if (s.ok()) s = iteration(*lin, window, &cost, &stop);
    if (!s.ok()) {
      summary.status = std::move(s);
      return summary;
    }
    ++summary.lm_iterations;
    if (stop) break;
  }
  summary.cost_final = static_cast<double>(cost);
  summary.status = checkFinite(*window);
  return summary;
}

template <typename Scalar>
Status LevenbergMarquardt<Scalar>::iteration(Linearization<Scalar>& lin, Window<Scalar>* window,
                                             Scalar* cost, bool* stop) {
  const Scalar lambda_min = static_cast<Scalar>(config_.lambda_min);
  const Scalar lambda_max = static_cast<Scalar>(config_.lambda_max);
  while (true) {
    LinearStep<Scalar> step;
    if (Status status = lin.solve(lambda_, &step); !status.ok()) {
      if (++failed_solves_ >= config_.max_failed_solves) {
        return Status::Error(status.code(), fmt::format("linear solve failed {} times in a row: {}",
                                                        failed_solves_, status.message()));
      }
      increaseDamping();
      continue;
    }
    failed_solves_ = 0;
    StepBackup backup;
    const Scalar max_step = applyStep(lin, step, window, &backup);
    const Scalar new_cost = window->totalCost();
    --evaluations_left_;
    if (std::isfinite(new_cost) && new_cost < *cost) {
      const Scalar model_change = step.model_change;
      const Scalar rho = model_change < 0 ? (*cost - new_cost) / -model_change : Scalar(1);
      const Scalar f = Scalar(2) * rho - Scalar(1);
      lambda_ *= std::max(Scalar(1) / Scalar(3), Scalar(1) - f * f * f);
      lambda_ = std::clamp(lambda_, lambda_min, lambda_max);
      nu_ = Scalar(2);
      *stop = converged(*cost, new_cost, max_step);
      *cost = new_cost;
      return Status::Ok();
    }
    undoStep(lin, std::move(backup), window);
    // No decrease even with maximal damping (converged as far as LM can tell), or the evaluation
    // budget of the basalt rule spent.
    if (lambda_ >= lambda_max || evaluations_left_ <= 0) {
      *stop = true;
      return Status::Ok();
    }
    increaseDamping();
  }
}

template <typename Scalar>
bool LevenbergMarquardt<Scalar>::converged(Scalar cost, Scalar new_cost, Scalar max_step) const {
  const bool small_step = max_step < static_cast<Scalar>(config_.stop_max_step);
  if (config_.lm_stop_rule == LmStopRule::kBasalt) {
    return cost - new_cost < static_cast<Scalar>(kBasaltStopCost) || small_step ||
           evaluations_left_ <= 0;
  }
  const Scalar relative_decrease = (cost - new_cost) / cost;
  return relative_decrease < static_cast<Scalar>(config_.stop_relative_cost) || small_step;
}

template <typename Scalar>
void LevenbergMarquardt<Scalar>::increaseDamping() {
  lambda_ = std::min(lambda_ * nu_, static_cast<Scalar>(config_.lambda_max));
  nu_ *= Scalar(2);
}

template <typename Scalar>
Scalar LevenbergMarquardt<Scalar>::applyStep(const Linearization<Scalar>& lin,
                                             const LinearStep<Scalar>& step, Window<Scalar>* window,
                                             StepBackup* backup) {
  const ColumnMap& column_of = lin.columns();
  const VecX<Scalar>& delta = step.delta;
  backup->frames = window->frames;
  for (auto& [id, frame] : window->frames) {
    frame.T_w_i = boxPlus<Scalar>(
        frame.T_w_i, delta.template segment<kPoseDim>(column_of.at({id, StateBlock::kPose})));
    if (frame.has_speed_bias) {
      frame.speed_bias +=
          delta.template segment<kSpeedBiasDim>(column_of.at({id, StateBlock::kSpeedBias}));
    }
  }
  const std::vector<LandmarkJacobians<Scalar>>& lins = lin.landmarks();
  backup->params.resize(lins.size());
  Scalar max_step = delta.size() ? delta.cwiseAbs().maxCoeff() : Scalar(0);
  for (size_t l = 0; l < lins.size(); ++l) {
    auto& lm = window->landmarks.at(lins[l].track_id);
    backup->params[l] = lm.param;
    lm.param += step.delta_l[l];
    if (!lm.world()) lm.param.z() = std::max(lm.param.z(), Scalar(0));
    max_step = std::max(max_step, step.delta_l[l].cwiseAbs().maxCoeff());
  }
  for (int64_t track : window->priorLandmarks()) {
    Vec3S& p_w = window->landmarks.at(track).param;
    backup->reduced[track] = p_w;
    p_w += delta.template segment<kPointDim>(column_of.at({track, StateBlock::kLandmark}));
  }
  backup->stereo_offset = window->stereoOffset();
  if (window->estimatesStereoOffset()) {
    window->setStereoOffset(window->stereoOffset() + delta[column_of.at(kStereoOffsetVar)]);
  }
  return max_step;
}

template <typename Scalar>
void LevenbergMarquardt<Scalar>::undoStep(const Linearization<Scalar>& lin, StepBackup&& backup,
                                          Window<Scalar>* window) {
  window->frames = std::move(backup.frames);
  const std::vector<LandmarkJacobians<Scalar>>& lins = lin.landmarks();
  for (size_t l = 0; l < lins.size(); ++l) {
    window->landmarks.at(lins[l].track_id).param = backup.params[l];
  }
  for (const auto& [track, p_w] : backup.reduced) window->landmarks.at(track).param = p_w;
  if (window->estimatesStereoOffset()) window->setStereoOffset(backup.stereo_offset);
}

template <typename Scalar>
Status LevenbergMarquardt<Scalar>::checkFinite(const Window<Scalar>& window) {
  for (const auto& [id, frame] : window.frames) {
    if (!frame.T_w_i.translation().allFinite() ||
        !frame.T_w_i.unitQuaternion().coeffs().allFinite() || !frame.speed_bias.allFinite()) {
      return Status::Error(Status::Code::kNotFinite, "a state turned non-finite");
    }
  }
  if (!std::isfinite(window.stereoOffset())) {
    return Status::Error(Status::Code::kNotFinite, "the stereo offset turned non-finite");
  }
  return Status::Ok();
}

#define MARGLAB_INST(S) template class LevenbergMarquardt<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
