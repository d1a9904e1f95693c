#pragma once
// Gauge test directions of a marginalization prior and the prior cost change along them
// (docs/design.md §4, paper §5.2 eq. 27).
//
// Why these directions. Visual and inertial residuals do not change when the whole window is moved
// by a rigid transform of the world frame: reprojections depend on relative poses only, so VO has
// a 6-dof gauge (translation, rotation); with an IMU gravity g_w fixes roll and pitch, leaving the
// 4-dof gauge x, y, z, yaw (yaw = rotation about the gravity axis z). A prior marginalized from
// such residuals (without the initial gauge prior, i.e. the "shadow" prior of docs/design.md §3)
// must therefore have these directions in its nullspace: ΔE_m ≈ 0 along them. A squared f32 prior
// loses this (paper Figs. 4–6): ΔE_m grows along the gauge directions.
//
// Layout. The prior's columns are blocks (PriorVariable): a pose δ = [δt; δφ] (6, the ⊞ increment
// of se3.h: t ← t + δt, R ← exp(δφ) R), a velocity δv (3), a gyro bias (3), an accel bias (3), and
// in the dense prior of a keyframe event (docs/sparsification.md) a world point δp (3, additive).
//
// The directions, linearized at the prior's linearization point (poses T_w_i = (R_i, t_i),
// velocities v_i), before normalization:
//   translation e_a (a = x, y, z):  every pose δt = e_a, δφ = 0; velocities and biases 0.
//   rotation ω = e_x, e_y, e_z about the centre c: the world moved by R_θ = exp(θω) about c maps
//     R_i → R_θ R_i, t_i → R_θ (t_i − c) + c, v_i → R_θ v_i, so to first order in θ
//       δφ_i = ω,   δt_i = [ω]× (t_i − c) = −[t_i − c]× ω,   δv_i = −[v_i]× ω,
//     biases (body-frame quantities) 0, world points δp = [ω]× (p − c) (and δp = e_a for the
//     translations). c defaults to the centroid of the prior's pose positions;
//     any c gives a gauge direction, c only decides how translation and rotation mix.
//   random: i.i.d. N(0, 1) entries (std::mt19937_64 with the given seed, Box–Muller), so that it
//     is identical across platforms and standard libraries; almost surely not in the nullspace.
// Each direction ε is normalized to ‖ε‖ = 1; a direction that is zero on the layout (e.g. no pose
// block) stays zero and its ΔE_m is reported as NaN.
//
// ΔE_m = E_m(x⁰ + ε) − E_m(x⁰) = ½ εᵀH_mε + εᵀb_m   (eq. 27), in double.
// The information along a direction, εᵀΛε, compares two approximations of one distribution (the
// dense prior and the factors nfr recovers from it) along the window's rigid motions.

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/geometry/se3.h"

namespace marglab {

enum class PriorVariableKind : int {
  kPose = 0,
  kVelocity = 1,
  kGyroBias = 2,
  kAccelBias = 3,
  kPoint = 4,
  kCalibration = 5  // a scalar the rigid motions leave unchanged (the stereo cx offset)
};
int variableDimension(PriorVariableKind kind);  // 6, 3, 3, 3, 3, 1
const char* variableKindName(
    PriorVariableKind kind);  // "pose", "velocity", "bias_gyro", "bias_accel", "point",
                              // "calibration"

// One block of the prior's columns: [offset, offset + variableDimension(kind)).
struct PriorVariable {
  PriorVariableKind kind = PriorVariableKind::kPose;
  std::int64_t frame_id = 0;  // the estimator's frame id (e.g. its t_ns), a point's track id;
                              // keys GaugeState
  int offset = 0;
};
using PriorLayout = std::vector<PriorVariable>;

// Size n the layout spans (max offset + dimension). Throws std::invalid_argument when blocks
// overlap or an offset is negative.
int layoutDimension(const PriorLayout& layout);

// Values at the prior's linearization point (the first estimates the prior is anchored at, not
// the current estimates: a pose moved by Δt since linearization tilts the rotation direction by
// [Δt]× ω and adds ≈ ½‖J_m [Δt]× ω‖² to ΔE_m), by frame_id. Every pose block needs T_w_i, every
// velocity block v_w, every point block p_w (else std::invalid_argument).
struct GaugeState {
  std::map<std::int64_t, SE3d> T_w_i;
  std::map<std::int64_t, Eigen::Vector3d> v_w;
  std::map<std::int64_t, Eigen::Vector3d> p_w;  // by track id
  std::optional<Eigen::Vector3d> center;  // rotation centre c; default: centroid of pose positions
};

enum GaugeDirection : int {
  kGaugeX,
  kGaugeY,
  kGaugeZ,
  kGaugeRoll,
  kGaugePitch,
  kGaugeYaw,
  kGaugeRandom
};
inline constexpr int kNumGaugeDirections = 7;
// "x", "y", "z", "roll", "pitch", "yaw", "random" (the columns of /marg/dEm).
inline constexpr std::array<const char*, kNumGaugeDirections> kGaugeDirectionNames = {
    "x", "y", "z", "roll", "pitch", "yaw", "random"};

using GaugeDirections = Eigen::Matrix<double, Eigen::Dynamic, kNumGaugeDirections>;
using Vec7d = Eigen::Matrix<double, kNumGaugeDirections, 1>;

// The 7 unit directions (columns, in GaugeDirection order) over n = layoutDimension(layout)
// columns; n may be passed larger than the layout span (unlisted columns get 0).
GaugeDirections gaugeDirections(const PriorLayout& layout, int n, const GaugeState& state,
                                std::uint64_t seed);

// n i.i.d. standard normal samples from std::mt19937_64(seed) via Box–Muller, normalized to 1.
VecXd randomUnitVector(int n, std::uint64_t seed);

// ΔE_m = ½ εᵀH_mε + εᵀb_m for each column ε of directions (NaN for a zero column).
Vec7d priorCostChange(const MatXd& H_m, const VecXd& b_m, const GaugeDirections& directions);

// εᵀΛε for each column ε of directions (NaN for a zero column).
Vec7d directionInformation(const MatXd& Lambda, const GaugeDirections& directions);

}  // namespace marglab
