#pragma once
// C²-continuous trajectory through ground-truth poses, with analytic derivatives, for simulating
// IMU and camera measurements along a real trajectory (docs/design.md §5).
//
// Spline. Two uniform cubic B-splines, each on its own knot grid t_i = t_0 + i Δ (t_0 = first GT
// time; Δ_p for position, Δ_R for rotation), segment i = [t_i, t_{i+1}), u = (t − t_i)/Δ ∈ [0, 1),
// controlled by points i .. i+3:
//
//   position  p(t) = Σ_{j=0..3} B_j(u) c_{i+j}                    (world frame, c ∈ R³)
//   rotation  R(t) = C_i · Π_{j=1..3} exp(B̃_j(u) d_{i+j}),  d_m = log(C_{m−1}ᵀ C_m)
//                                                              (C ∈ SO(3), R = R_w_b)
//
// with the uniform cubic basis and its cumulative form (Sommer et al., "Efficient Derivative
// Computation for Cumulative B-Splines on Lie Groups", CVPR 2020, eq. 4, 16; as in Basalt):
//   B_0 = (1−u)³/6,  B_1 = (3u³ − 6u² + 4)/6,  B_2 = (−3u³ + 3u² + 3u + 1)/6,  B_3 = u³/6,
//   B̃_j = Σ_{l≥j} B_l:  B̃_1 = (5 + 3u − 3u² + u³)/6,  B̃_2 = (1 + 3u + 3u² − 2u³)/6,  B̃_3 = u³/6.
// Both are C² in t (the cumulative form is C² on SO(3)); the position spline's third derivative
// (jerk) is piecewise constant and jumps at the knots.
//
// Derivatives (dot = d/dt = (1/Δ) d/du):
//   v_w = ṗ = Σ Ḃ_j c_{i+j},   a_w = p̈ = Σ B̈_j c_{i+j}.
//   Body angular velocity ω (Rᵀ Ṙ = ω^) and acceleration ω̇ by the recursion of Sommer et al.
//   (eq. 38–39) over the partial products R_j = R_{j−1} A_j, A_j = exp(B̃_j d_{i+j}):
//     ω_0 = 0,   ω_j = A_jᵀ ω_{j−1} + dB̃_j/dt · d_{i+j},
//     ω̇_0 = 0,  ω̇_j = A_jᵀ ω̇_{j−1} + d²B̃_j/dt² · d_{i+j} + dB̃_j/dt · (ω_j × d_{i+j}),
//   and ω_b = ω_3, ω̇_b = ω̇_3. (The last term: d/dt A_jᵀ = −A_j^T (Ḃ̃_j d)^, and
//   A_jᵀ ω_{j−1} = ω_j − Ḃ̃_j d.)
//
// Separate grids because the IMU needs the second derivative of position but only the first of
// rotation: GT jitter is amplified by 1/Δ² in a_w and only by 1/Δ in ω_b, so rotation can follow
// the fast attitude dynamics of a MAV on finer knots than position.
//
// Fit. A B-spline through its control points does not pass through them, and the GT is sampled
// more densely (EuRoC 200 Hz) than the knots (a 200 Hz spline through GT jitter would have
// accelerations of tens of m/s²). The control points are therefore the least-squares fit to all
// GT samples k (times t_k, irregular, gaps allowed), with a tiny second-difference penalty that
// only matters where the data do not determine the points (gaps longer than a knot interval, the
// two ends): there it makes the spline continue with constant velocity.
//   position:  min Σ_k |Σ_j B_j(u_k) c_{i_k+j} − p_k|² + λ Σ_m |c_{m−1} − 2 c_m + c_{m+1}|²,
//              normal equations N c = Aᵀ p, N = AᵀA + λ DᵀD (banded, 7 diagonals), one sparse
//              Cholesky factorization (LDLᵀ) per grid.
//   rotation:  min Σ_k |log(R_k R(t_k)ᵀ)|², by a Gauss–Newton-like iteration with left (world)
//              increments C_m ← exp(δ_m) C_m and the approximate Jacobian ∂r_k/∂δ_m ≈ B_m(u_k) I
//              (exact when all δ_m are equal, since Σ B_m = 1 and a common left factor leaves
//              every d_m unchanged; off by O(|d|) otherwise, so the iteration contracts by O(|d|)
//              per step): N δ = Σ_k b_k r_k, r_k = log(R_k R(t_k)ᵀ) — N as for the position, on
//              the rotation grid; a few iterations reach the fixed point Aᵀ r = 0.
//              C_m starts from the GT slerped at t_0 + (m−1)Δ, the knot where B_m peaks.
// On smooth data this reproduces the trajectory to O(Δ⁴) (test: < 1e-6 m on an analytic
// trajectory); on real GT the residual is the GT's own jitter plus what a Δ-spline cannot follow,
// and is reported by fitReport().
//
// Times are int64 ns; u is computed from integer differences, so evaluation is exact to the ns
// over any sequence length.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "core/data/types.h"

namespace marglab {

// The state of the body at one instant, in double.
struct TrajectorySample {
  Eigen::Matrix3d R_w_b = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_w_b = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();      // velocity of the body origin, world frame
  Eigen::Vector3d a_w = Eigen::Vector3d::Zero();      // acceleration of the body origin, world
  Eigen::Vector3d omega_b = Eigen::Vector3d::Zero();  // angular velocity, body frame
};

// Anything that yields the body state at a time: the spline, or an analytic test trajectory.
class TrajectoryFunction {
 public:
  virtual ~TrajectoryFunction() = default;
  virtual int64_t startTimeNs() const = 0;
  virtual int64_t endTimeNs() const = 0;
  // Valid for startTimeNs() <= t_ns <= endTimeNs().
  virtual TrajectorySample evaluate(int64_t t_ns) const = 0;
};

// A window [start_ns, end_ns] of another trajectory: the same samples over a shorter span (so that
// IMU synthesis covers only the window). Refers to `base`, which must outlive it.
class TrajectoryWindow : public TrajectoryFunction {
 public:
  TrajectoryWindow(const TrajectoryFunction& base, int64_t start_ns, int64_t end_ns)
      : base_(base), start_ns_(start_ns), end_ns_(end_ns) {}
  int64_t startTimeNs() const override { return start_ns_; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t t_ns) const override { return base_.evaluate(t_ns); }

 private:
  const TrajectoryFunction& base_;
  int64_t start_ns_, end_ns_;
};

struct TrajectorySplineOptions {
  double knot_dt_s = 0.05;           // Δ_p of the position spline
  double rotation_knot_dt_s = 0.05;  // Δ_R of the rotation spline
  // λ of the second-difference penalty, in units of one GT sample's weight. 1e-6 biases a fit of
  // smooth data by ~λ Δ² |a| (nm), yet keeps N positive definite across gaps.
  double smoothing = 1e-6;
  int max_rotation_iterations = 20;
  double rotation_tolerance_rad = 1e-12;  // stop when max |δ_m| falls below
};

// How well the spline reproduces the GT it was fitted to, at the GT samples.
struct SplineFitReport {
  double knot_dt_s = 0, rotation_knot_dt_s = 0;
  std::size_t gt_samples = 0;
  std::size_t control_points = 0, rotation_control_points = 0;
  double position_rms_m = 0, position_max_m = 0;
  double rotation_rms_rad = 0, rotation_max_rad = 0;
  int64_t position_max_t_ns = 0, rotation_max_t_ns = 0;  // where the maxima occur
  int rotation_iterations = 0;
  double max_gt_gap_s = 0;
};

class TrajectorySpline : public TrajectoryFunction {
 public:
  // Fits the spline to gt (≥ 2 samples, strictly increasing times). Throws InputError otherwise.
  explicit TrajectorySpline(const Trajectory& gt, const TrajectorySplineOptions& options = {});

  // Knot spacings <= 0 take defaultOptions(sequence.kind). Throws InputError without a trajectory.
  static TrajectorySpline fromSequence(const Sequence& sequence, double knot_dt_s = 0,
                                       double rotation_knot_dt_s = 0);

  // Knot spacings Δ_p / Δ_R, measured on the shipped sequences (fit residual at the GT samples vs
  // plausibility of a_w, ω_b, and agreement with the real IMU; numbers in test_trajectory_spline):
  //   EuRoC   0.05 s / 0.01 s: 200 Hz GT of a MAV; position jitter needs ≥ 0.05 s to keep |a_w|
  //           plausible, attitude needs 0.01 s to stay within ~0.01° of the GT.
  //   TUM-VI  0.2 s / 0.2 s: 120 Hz mocap with gaps up to 1 s and orientation glitches (jumps of
  //           several degrees over one or two samples); finer knots turn them into |ω_b| spikes
  //           of 20–150 rad/s and |a_w| of 30–140 m/s². At 0.2 s: |a_w| ≤ 10.4, |ω_b| ≤ 4.1
  //           (room1), position rms 1.3 mm, rotation rms 0.5°.
  //   KITTI   0.1 s / 0.1 s: the 10 Hz pose rate; the spline interpolates the poses (µm), and
  //           inherits their occasional cm-level jumps as acceleration spikes.
  static TrajectorySplineOptions defaultOptions(DatasetKind kind);

  int64_t startTimeNs() const override { return start_ns_; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t t_ns) const override;

  // ω̇ in the body frame (d/dt of TrajectorySample::omega_b).
  Eigen::Vector3d angularAccelerationBody(int64_t t_ns) const;

  const SplineFitReport& fitReport() const { return report_; }

  // A uniform knot grid over [t0, t0 + segments Δ] ⊇ [start, end].
  struct Grid {
    int64_t t0_ns = 0, dt_ns = 1;
    std::size_t segments = 1;
    // Segment index of t (clamped to the grid) and u ∈ [0, 1].
    std::size_t segment(int64_t t_ns, double* u) const;
  };
  const Grid& positionGrid() const { return pos_grid_; }
  const Grid& rotationGrid() const { return rot_grid_; }

 private:
  struct Eval;
  Eval evaluateFull(int64_t t_ns, bool angular_acceleration) const;
  void fit(const Trajectory& gt, const TrajectorySplineOptions& options);

  int64_t start_ns_ = 0, end_ns_ = 0;
  Grid pos_grid_, rot_grid_;
  std::vector<Eigen::Vector3d> pos_;       // c_m
  std::vector<Eigen::Quaterniond> rot_;    // C_m
  std::vector<Eigen::Vector3d> rot_diff_;  // d_m = log(C_{m−1}ᵀ C_m), d_0 unused
  SplineFitReport report_;
};

}  // namespace marglab
