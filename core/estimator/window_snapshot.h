#pragma once
// A captured window of the estimator, in double, for replaying and benchmarking one optimization
// step outside a run (core/estimator/window_io.h serializes it).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/data/types.h"
#include "core/estimator/estimator_settings.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/variant.h"
#include "core/estimator/window.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"

namespace marglab {

// One window of the estimator as its optimizer reads it, in double (exact for f32 and f64
// states), for replaying and benchmarking one optimization step outside a run
// (core/estimator/window_io.h serializes it). IMU factors are kept as their inputs — the IMU
// samples around the window and each factor's time span and linearization biases — and
// preintegrated again on restore (deterministic, so the factor is the same). `after` holds the
// step the estimator took from this state.
struct WindowSnapshot {
  struct FrameState {
    int64_t id = 0, t_ns = 0;
    bool is_keyframe = false, linearized = false, has_speed_bias = false;
    bool speed_bias_linearized = false;
    SE3<double> T_w_i, T_w_i_lin;
    Vec<double, 9> speed_bias = Vec<double, 9>::Zero(), speed_bias_lin = Vec<double, 9>::Zero();
  };
  struct ObservationState {
    int64_t frame = 0;
    Eigen::Vector2d uv0 = Eigen::Vector2d::Zero(), uv1 = Eigen::Vector2d::Zero();
    bool has_right = false;
  };
  struct LandmarkState {
    int64_t id = 0, host = 0;
    Eigen::Vector3d param = Eigen::Vector3d::Zero();
    std::vector<ObservationState> obs;
  };
  struct ImuLinkState {
    int64_t from = 0, to = 0;
    Eigen::Vector3d bias_gyro_lin = Eigen::Vector3d::Zero(),
                    bias_accel_lin = Eigen::Vector3d::Zero();
  };
  struct PriorBlockState {
    VarKey var;
    int offset = 0;
    SE3<double> T0;
    Vec<double, 9> sb0 = Vec<double, 9>::Zero();
  };
  // The step from this state: the optimizer's outcome and the states after it.
  struct Step {
    bool present = false;
    int lm_iterations = 0;
    double cost_initial = 0, cost_final = 0;
    std::vector<FrameState> frames;        // T_w_i and speed_bias after the step
    std::vector<LandmarkState> landmarks;  // param after the step (no observations)
  };
  // Provenance (informational).
  std::string dataset, variant;
  int64_t frame_index = -1;  // index of the newest frame in the run
  // Setup.
  EstimatorSettings config;
  StereoRig<double> rig;
  bool vio = false;
  ImuNoise imu_noise;
  double imu_sample_period_s = 0.005;
  Eigen::Vector3d g_w = Eigen::Vector3d::Zero();
  ImuData imu;  // the samples the window's IMU factors integrate
  // State.
  int failed_solves = 0;
  std::vector<FrameState> frames;
  std::vector<LandmarkState> landmarks;
  std::vector<ImuLinkState> imu_links;
  Representation prior_representation = Representation::kSqrt;
  std::vector<PriorBlockState> prior_blocks;
  MatXd prior_J, prior_H;
  VecXd prior_r, prior_b;
  double prior_c = 0;
  Step after;
  int numObservations() const;
};

// The window in double (exact widening of f32 states).
template <typename Scalar>
WindowSnapshot snapshotOf(const Window<Scalar>& window);
// The IMU of a captured VIO window (nullopt for VO).
template <typename Scalar>
std::optional<ImuSetup> imuSetupOf(const WindowSnapshot& w);
// Fills an empty window (built from the snapshot's config, rig and IMU) with its frames,
// landmarks, IMU factors and prior in `storage` (a square-root prior may be replayed as a Hessian
// one, not the reverse). Throws InputError on an inconsistent window.
template <typename Scalar>
void restoreWindow(const WindowSnapshot& w, const PriorStorage& storage, Window<Scalar>* window);
// The window of a snapshot as the estimator of `variant` under `config` holds it: built from the
// config and the snapshot's rig and IMU, its prior in the variant's storage (with the config's
// psd_hessian_prior), then restored. Throws InputError on an inconsistent window.
template <typename Scalar>
Window<Scalar> restoredWindow(const WindowSnapshot& w, const Variant& variant,
                              const EstimatorSettings& config);
// The step an optimization took, as WindowSnapshot::after: its outcome and the states of `window`
// after it (landmarks without their observations, which a step does not change).
template <typename Scalar>
WindowSnapshot::Step stepOf(const Window<Scalar>& window, int lm_iterations, double cost_initial,
                            double cost_final);

}  // namespace marglab
