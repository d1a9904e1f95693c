#pragma once
// Nonlinear factor recovery (NFR): a dense marginalization prior replaced by a sparse set of
// nonlinear factors whose information minimizes the Kullback–Leibler divergence to it, in closed
// form (Hsiung et al., "Information Sparsification in Visual-Inertial Odometry", IROS 2018,
// §IV-B/C, eqs. 9–17; Mazuran et al., "Nonlinear factor recovery for long-term SLAM", IJRR 2016).
//
// Input. The dense prior N(x̄, Λ_t⁻¹) over a Markov blanket x (eq. 9): its information Λ_t (n × n,
// the lower triangle is read) and the linearization point x̄, as a list of variables with their
// columns in Λ_t — every column belongs to exactly one variable:
//   pose      T_w_i = (R, t)   6   δ = [δt; δφ]: t ← t + δt, R ← exp(δφ) R (core/geometry/se3.h ⊞)
//   velocity  v_w              3   additive
//   bias      [b_g; b_a]       6   additive (gyro first, as in core/imu/imu_state.h)
//   landmark  p_w              3   additive, a point in the world frame
// (an estimator speed-bias block [v; b_g; b_a] is a velocity followed by a bias).
//
// Topology (eqs. 11–13). Factors h_i with measurement z_i and residual r_i(x) = h_i(x) ⊟ z_i:
//   unary on a pose   r = T ⊟ z = [t − t_z; log(R R_zᵀ)],   ∂r/∂δ = [I 0; 0 Jl⁻¹(log(R R_zᵀ))]
//   unary on v or b   r = v − z,                            ∂r/∂δ = I
//   pose–landmark     r = Rᵀ(p_w − t) − z,                  ∂r/∂[δt; δφ] = [−Rᵀ  Rᵀ[p_w − t]×],
//                                                           ∂r/∂p_w = Rᵀ
//   relative pose     r = [R_aᵀ(t_b − t_a) − t_z; log(R_aᵀ R_b R_zᵀ)]   (h = T_a⁻¹ T_b, z = (R_z,
//   t_z))
//                     ∂r/∂[δt_a; δφ_a] = [−R_aᵀ  R_aᵀ[t_b − t_a]×; 0  −Jl⁻¹(e) R_aᵀ],
//                     ∂r/∂[δt_b; δφ_b] = [ R_aᵀ  0;                 0   Jl⁻¹(e) R_aᵀ]
// (R' = exp(δφ) R gives R'ᵀa ≈ Rᵀa − Rᵀ[δφ]× a = Rᵀa + Rᵀ[a]× δφ; log(exp(δφ) E) ≈ log E +
// Jl⁻¹(log E) δφ, so3.h; R_aᵀ exp(−δφ_a) exp(δφ_b) R_b R_zᵀ ≈ exp(R_aᵀ(δφ_b − δφ_a)) E with
// e = log E). The relative-pose factor (Mazuran et al.'s pose-graph NFR) is invariant under a rigid
// motion of the world, like the pose–landmark one. The measurements are the values at the
// linearization point, z_i = h_i(x̄): every r_i(x̄) = 0, the sparsified prior has the dense prior's
// mean μ_s = μ_t = x̄ and the mean term of eq. 10 vanishes (as in the paper, the dense prior's
// gradient at x̄ is not carried over). paperTopology() builds the paper's: a unary factor on every
// pose, velocity and bias of the blanket and one pose–landmark factor from an anchor pose to every
// landmark. relativePoseTopology() replaces the unary pose factors by a chain: one unary factor on
// the anchor pose and a relative-pose factor between consecutive poses — with the pose–landmark
// factors a tree, so H_s is square and invertible and eq. 16 is its exact optimum. H_s stacks the
// factors' Jacobians at x̄ (eq. 13); Λ_r = diag(Λ_r^(i)).
//
// Recovery (eqs. 14–17). The sparsified information is Λ_s = H_sᵀ Λ_r H_s (eq. 14), and the KLD
//   D(Λ_r) = KL(N(x̄, Σ_t) ‖ N(x̄, Λ_s⁻¹)) = ½ (⟨Λ_s, Σ_t⟩ − log det Λ_s + log det Λ_t − n)
// (eq. 10, Σ_t = Λ_t⁻¹). With H_s square and invertible, D is convex in Λ_r on Λ_r ≻ 0, its
// gradient (eq. 17, of C = ⟨Λ_s, Σ_t⟩ − log det Λ_s = 2D + const, for symmetric perturbations)
//   ∂C/∂Λ_r^(i) = {H_s [Σ_t − Λ_s⁻¹] H_sᵀ}^(i) = {H_s Σ_t H_sᵀ}^(i) − (Λ_r^(i))⁻¹
// vanishes at the unique minimizer
//   Λ_r^(i) = ({H_s Σ_t H_sᵀ}^(i))⁻¹                                               (eq. 16)
// where ⟨Λ_s, Σ_t⟩ = n and D = ½ (log det Λ_t − log det Λ_s) ≥ 0, with equality iff Λ_s = Λ_t,
// i.e. iff the topology represents Λ_t exactly. Evaluated as ⟨Λ_s, Σ_t⟩ = Σ_i ⟨Λ_r^(i), C_i⟩ with
// C_i = {H_s Σ_t H_sᵀ}^(i) and log det Λ_s = 2 log|det H_s| + Σ_i log det Λ_r^(i). D is taken as
// +∞ when some Λ_r^(i) is not positive definite (the extended-value convention of convex
// optimization: −log det of a matrix that is not ≻ 0 is +∞).
//
// Gauge (rank-deficient Λ_t). A prior marginalized from gauge-invariant residuals only — the
// estimator's gauge-free shadow prior — has a nullspace N (VIO: x, y, z, yaw; VO: 6 dof): Σ_t
// does not exist and D = +∞ for every Λ_s ≻ 0 (the limit of Λ_t + εI, ε → 0). The pose–landmark
// factors are gauge-invariant (h is unchanged by a rigid motion of the world), the unary pose
// factor is not. We fix a reference: the caller names k columns measured by unary factors —
// vioGaugeReference() the position and δφ_z of the anchor pose, for VO all of its 6 —
// that are held at their linearization values. Everything above is then taken on the subspace
// S = {δx : δx_ref = 0}, i.e. for the conditionals of both Gaussians given the reference:
//   Λ̃_t = Λ_t without the reference rows and columns, which must be positive definite (the
//         reference fixes the nullspace: no non-zero nullspace vector vanishes on it);
//   H̃_s = H_s without the reference columns and without the rows of the unary factors that
//         measure a reference coordinate (at x̄ those rows are the unit rows e_cᵀ).
// H̃_s is again square (n − k) and invertible, so eq. 16 is the exact minimizer of the KLD between
// the conditionals, that KLD is ≥ 0, and it is 0 iff the topology represents Λ̃_t. The recovered
// unary factors measure only their non-reference components (RecoveredFactor::rows), so they add
// no information along the reference coordinates: with the paper's one-pose blanket, Λ_s keeps the
// translation gauge in its nullspace, while the world-frame velocity prior still constrains yaw;
// unary factors on further poses constrain the gauge as well (their positions are absolute).
// A Λ_t fixed by a gauge prior (the estimator's prior) is full rank: no reference is needed.
//
// Numerics. Everything is computed in Scalar. Rank decisions use the project's rule
// (NumericTraits<Scalar>::pinvRelativeTolerance, m · ε relative, m = n − k): Λ̃_t needs
// λ_min > m ε λ_max (self-adjoint eigendecomposition, which also gives Σ̃_t and log det Λ̃_t),
// H̃_s a column-pivoted QR rank of m at the same relative threshold. Failures are a Status.
//
// Square-root form. Each recovered factor carries W_i with W_iᵀ W_i = Λ_r^(i) on its measured
// rows (C_i = L Lᵀ Cholesky, W_i = L⁻¹, lower triangular), so an estimator adds it as the
// nonlinear residual W_i S_i (h_i(x) ⊟ z_i), S_i selecting RecoveredFactor::rows.

#include <Eigen/Core>
#include <limits>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/status.h"
#include "core/geometry/se3.h"
#include "core/geometry/so3.h"

namespace marglab {

enum class BlanketKind : int { kPose = 0, kVelocity = 1, kBias = 2, kLandmark = 3 };
int blanketKindDim(BlanketKind kind);  // 6, 3, 6, 3

// One variable of the Markov blanket at its linearization point.
template <typename Scalar>
struct BlanketVariable {
  BlanketKind kind = BlanketKind::kPose;
  int offset = 0;      // first column of the variable in Λ_t
  SE3<Scalar> T_w_i;   // kPose
  VecX<Scalar> value;  // kVelocity v_w (3), kBias [b_g; b_a] (6), kLandmark p_w (3)
};
template <typename Scalar>
using Blanket = std::vector<BlanketVariable<Scalar>>;

enum class NfrFactorKind : int { kUnary = 0, kPoseLandmark = 1, kRelativePose = 2 };
struct NfrFactorSpec {
  NfrFactorKind kind = NfrFactorKind::kUnary;
  int var = -1;       // index in the blanket: the measured variable (unary), the pose, or pose a
  int landmark = -1;  // kPoseLandmark: index of the landmark in the blanket
  int pose_b = -1;    // kRelativePose: index of pose b (h = T_a⁻¹ T_b, a = var)
};
using NfrTopology = std::vector<NfrFactorSpec>;

// The paper's topology (eqs. 11–12): unary factors on every pose, velocity and bias, in blanket
// order, then one pose–landmark factor from anchor_pose (a blanket index) to every landmark.
template <typename Scalar>
NfrTopology paperTopology(const Blanket<Scalar>& blanket, int anchor_pose);

// Relative-pose topology (Mazuran et al.'s pose-graph NFR, Hsiung et al. §IV-B topology): a unary
// factor on anchor_pose, a relative-pose factor between consecutive entries of pose_chain (blanket
// indices of every pose, in time order; anchor_pose among them), unary factors on every velocity
// and bias, then one pose–landmark factor from anchor_pose to every landmark.
template <typename Scalar>
NfrTopology relativePoseTopology(const Blanket<Scalar>& blanket, const std::vector<int>& pose_chain,
                                 int anchor_pose);

// The VIO gauge reference of a pose whose columns start at pose_offset: position and δφ_z (yaw
// about the gravity axis z of the world). (VO's would be all 6 of its columns.)
std::vector<int> vioGaugeReference(int pose_offset);

// Residuals of the topology's factors (unweighted, h(x) ⊟ z) and their Jacobians w.r.t. the ⊞
// increments (header comment).
template <typename Scalar>
inline Vec<Scalar, 6> posePriorResidual(const SE3<Scalar>& T_w_i, const SE3<Scalar>& z,
                                        Mat<Scalar, 6, 6>* J = nullptr) {
  const Vec<Scalar, 6> r = boxMinus(T_w_i, z);
  if (J) {
    J->setIdentity();
    J->template bottomRightCorner<3, 3>() =
        leftJacobianInvSO3<Scalar>(Vec3<Scalar>(r.template tail<3>()));
  }
  return r;
}

template <typename Scalar>
inline Vec3<Scalar> poseLandmarkResidual(const SE3<Scalar>& T_w_i, const Vec3<Scalar>& p_w,
                                         const Vec3<Scalar>& z, Mat<Scalar, 3, 6>* J_pose = nullptr,
                                         Mat3<Scalar>* J_landmark = nullptr) {
  const Mat3<Scalar> R_i_w = T_w_i.rotationMatrix().transpose();
  const Vec3<Scalar> d_w = p_w - T_w_i.translation();
  if (J_pose) {
    J_pose->template leftCols<3>() = -R_i_w;
    J_pose->template rightCols<3>() = R_i_w * hat(d_w);
  }
  if (J_landmark) *J_landmark = R_i_w;
  return R_i_w * d_w - z;
}

template <typename Scalar>
inline Vec<Scalar, 6> relativePoseResidual(const SE3<Scalar>& T_w_a, const SE3<Scalar>& T_w_b,
                                           const SE3<Scalar>& z, Mat<Scalar, 6, 6>* J_a = nullptr,
                                           Mat<Scalar, 6, 6>* J_b = nullptr) {
  const Mat3<Scalar> R_a_w = T_w_a.rotationMatrix().transpose();
  const Vec3<Scalar> d_w = T_w_b.translation() - T_w_a.translation();
  Vec<Scalar, 6> r;
  r.template head<3>() = R_a_w * d_w - z.translation();
  r.template tail<3>() = logSO3<Scalar>(T_w_a.unitQuaternion().conjugate() *
                                        T_w_b.unitQuaternion() * z.unitQuaternion().conjugate());
  if (J_a || J_b) {
    const Mat3<Scalar> D_phi =
        leftJacobianInvSO3<Scalar>(Vec3<Scalar>(r.template tail<3>())) * R_a_w;
    if (J_a) {
      J_a->setZero();
      J_a->template topLeftCorner<3, 3>() = -R_a_w;
      J_a->template topRightCorner<3, 3>() = R_a_w * hat(d_w);
      J_a->template bottomRightCorner<3, 3>() = -D_phi;
    }
    if (J_b) {
      J_b->setZero();
      J_b->template topLeftCorner<3, 3>() = R_a_w;
      J_b->template bottomRightCorner<3, 3>() = D_phi;
    }
  }
  return r;
}

// One recovered factor, ready to be inserted as a nonlinear residual.
template <typename Scalar>
struct RecoveredFactor {
  NfrFactorSpec spec;
  std::vector<int> rows;          // measured components of h (all but gauge-reference ones)
  MatX<Scalar> information;       // Λ_r^(i) over `rows` (eq. 16)
  MatX<Scalar> sqrt_information;  // W_i S_i, |rows| × dim h: its Gram matrix is S_iᵀ Λ_r^(i) S_i
  SE3<Scalar> z_pose;             // measurement of a unary pose or relative-pose factor
  VecX<Scalar> z;                 // measurement of the other factors

  // W_i S_i (h(x) ⊟ z) at the blanket values x — the layout of the recovery, values may differ —
  // and, if J is given, its Jacobian w.r.t. the ⊞ increments of [spec.var | spec.landmark] or
  // [spec.var | spec.pose_b].
  VecX<Scalar> whitenedResidual(const Blanket<Scalar>& x, MatX<Scalar>* J = nullptr) const;
};

template <typename Scalar>
struct Sparsification {
  std::vector<RecoveredFactor<Scalar>> factors;  // in topology order
  MatX<Scalar> Lambda_s;                         // H_sᵀ Λ_r H_s over all n columns (eq. 14)
  Scalar kld = std::numeric_limits<Scalar>::quiet_NaN();  // D at the closed form (eq. 10, on S)
  Status status;
};

// The recovery problem of one dense prior: validates the layout, the topology and the gauge
// reference, and factorizes Λ̃_t and H̃_s once; then the closed form, D and its gradient for any
// Λ_r (blocks in topology order, each over its factor's measured rows).
template <typename Scalar>
class NfrProblem {
 public:
  NfrProblem(const MatX<Scalar>& Lambda_t, const Blanket<Scalar>& blanket,
             const NfrTopology& topology, const std::vector<int>& gauge_reference = {});

  const Status& status() const { return status_; }
  int dim() const { return n_; }
  int reducedDim() const { return m_; }  // n − k
  // Extreme eigenvalues of Λ̃_t and the rank threshold they were checked against.
  Scalar targetLambdaMin() const { return lambda_min_; }
  Scalar targetLambdaMax() const { return lambda_max_; }
  Scalar rankThreshold() const { return threshold_; }

  // Eq. 16 for every factor, the factors in square-root form, Λ_s and D.
  Sparsification<Scalar> recover() const;
  // D(Λ_r) (eq. 10 on S): +∞ if a block is not positive definite, NaN if the blocks do not fit
  // the topology or the problem failed.
  Scalar kld(const std::vector<MatX<Scalar>>& Lambda_r) const;
  // ∂C/∂Λ_r^(i) = {H̃_s [Σ̃_t − Λ̃_s⁻¹] H̃_sᵀ}^(i) (eq. 17, first line, with Λ̃_s⁻¹ formed directly).
  Status kldGradient(const std::vector<MatX<Scalar>>& Lambda_r,
                     std::vector<MatX<Scalar>>* gradient) const;
  // Λ_s = H_sᵀ Λ_r H_s over all n columns (eq. 14); empty if the blocks do not fit.
  MatX<Scalar> sparseInformation(const std::vector<MatX<Scalar>>& Lambda_r) const;

 private:
  // One factor linearized at x̄.
  struct FactorRows {
    NfrFactorSpec spec;
    int dim = 0;                // dim h_i
    std::vector<int> rows;      // measured rows of h_i
    std::vector<int> cols;      // columns of Λ_t its variables span
    MatX<Scalar> J;             // ∂r_i/∂δx at x̄: |rows| × |cols|
    std::vector<int> red_cols;  // columns of Λ̃_t it touches (the non-reference `cols`)
    MatX<Scalar> J_red;         // J restricted to red_cols: its rows of H̃_s
    MatX<Scalar> C;             // {H̃_s Σ̃_t H̃_sᵀ}^(i)
    SE3<Scalar> z_pose;
    VecX<Scalar> z;
  };

  Status setUp(const MatX<Scalar>& Lambda_t, const NfrTopology& topology,
               const std::vector<int>& gauge_reference);
  // owner[c]: the variable of column c; every column exactly one.
  Status checkLayout(std::vector<int>* owner) const;
  // Kinds of every factor and H_s square; unary_of[v]: the unary factor on variable v, or −1.
  Status checkTopology(const NfrTopology& topology, std::vector<int>* unary_of) const;
  // Λ̃_t = Λ_t(kept, kept) positive definite at the rank threshold; Σ̃_t and log det Λ̃_t.
  Status factorizeTarget(const MatX<Scalar>& Lambda_t, const std::vector<int>& kept);
  FactorRows linearizeFactor(const NfrFactorSpec& spec,
                             const std::vector<bool>& is_reference) const;
  bool fits(const std::vector<MatX<Scalar>>& Lambda_r) const;

  Blanket<Scalar> blanket_;
  std::vector<FactorRows> factors_;
  int n_ = 0;
  int m_ = 0;
  MatX<Scalar> Sigma_red_;     // Σ̃_t = Λ̃_t⁻¹
  Scalar log_det_target_ = 0;  // log det Λ̃_t
  Scalar log_abs_det_H_ = 0;   // log |det H̃_s|
  Scalar lambda_min_ = 0;
  Scalar lambda_max_ = 0;
  Scalar threshold_ = 0;
  Status status_;
};

// NfrProblem(...).recover().
template <typename Scalar>
Sparsification<Scalar> sparsify(const MatX<Scalar>& Lambda_t, const Blanket<Scalar>& blanket,
                                const NfrTopology& topology,
                                const std::vector<int>& gauge_reference = {});

}  // namespace marglab
