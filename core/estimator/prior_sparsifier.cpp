#include "core/estimator/prior_sparsifier.h"

#include <algorithm>
#include <chrono>
#include <optional>
#include <vector>

#include "core/common/scalar.h"
#include "core/sparsify/nfr.h"
#include "core/sparsify/rigid_deflation.h"

namespace marglab {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The prior's variables as an nfr blanket, the window variable of each, and the anchor of the
// pose–landmark factors: the newest keyframe pose (keyframes leave the window last).
template <typename Scalar>
struct BlanketVars {
  Blanket<Scalar> x;
  std::vector<VarKey> var_of;
  int anchor = -1;
  // The poses in frame order: the chain of the relative-pose topology.
  std::vector<int> poseChain() const {
    std::vector<int> chain;
    for (int v = 0; v < static_cast<int>(x.size()); ++v) {
      if (x[static_cast<size_t>(v)].kind == BlanketKind::kPose) chain.push_back(v);
    }
    std::sort(chain.begin(), chain.end(), [this](int a, int b) {
      return var_of[static_cast<size_t>(a)].frame_id < var_of[static_cast<size_t>(b)].frame_id;
    });
    return chain;
  }
};

template <typename Scalar>
BlanketVars<Scalar> blanketOf(const Window<Scalar>& w) {
  BlanketVars<Scalar> b;
  int64_t anchor_frame = -1;
  bool anchor_is_kf = false;
  for (const auto& block : w.prior.blocks) {
    const int off = block.offset;
    if (block.var.block == StateBlock::kPose) {
      const bool is_kf = w.frames.at(block.var.frame_id).is_keyframe;
      if (is_kf >= anchor_is_kf && (is_kf > anchor_is_kf || block.var.frame_id > anchor_frame)) {
        b.anchor = static_cast<int>(b.x.size());
        anchor_frame = block.var.frame_id;
        anchor_is_kf = is_kf;
      }
      b.x.push_back({BlanketKind::kPose, off, block.T0, {}});
      b.var_of.push_back(block.var);
    } else if (block.var.block == StateBlock::kSpeedBias) {
      b.x.push_back({BlanketKind::kVelocity, off, SE3<Scalar>(), block.sb0.template head<3>()});
      b.x.push_back({BlanketKind::kBias, off + 3, SE3<Scalar>(), block.sb0.template tail<6>()});
      b.var_of.insert(b.var_of.end(), 2, block.var);
    } else {
      b.x.push_back({BlanketKind::kLandmark, off, SE3<Scalar>(), block.p0});
      b.var_of.push_back(block.var);
    }
  }
  return b;
}

// The joint-states factor: Λ_t marginalized onto the state blocks (landmarks Schur-complemented),
// with its gradient, as ½‖r + Uδ‖², UᵀU = Λ_states, Uᵀr = b_states.
template <typename Scalar>
struct JointFactor {
  Eigen::LLT<MatX<Scalar>> llt;
  VecX<Scalar> b_states;
};

// Replaces the unary factors' share of Λ_s and of the KLD by the joint factor's. Its closed form
// (eq. 16) is the inverse of Σ_t's state block, i.e. Λ_t marginalized onto the states; H_s is the
// same matrix (the unary Jacobians at x⁰ are identities), so the KLD changes only by the
// log-determinants of the state factors. The gradient is kept: the joint factor carries the
// correlations between states the IMU chain makes tight, and dropping it (measurement at x⁰, as
// the unary factors do) would pull them to first estimates taken at different times (MH_02, 600
// frames: ATE 0.27 m).
template <typename Scalar>
std::optional<JointFactor<Scalar>> jointStateFactor(const MargPrior<Scalar>& prior,
                                                    const MatX<Scalar>& Lambda_t,
                                                    const BlanketVars<Scalar>& b,
                                                    const Sparsification<Scalar>& sp, Scalar* kld,
                                                    MatX<Scalar>* Lambda_s) {
  std::vector<int> state_cols, landmark_cols;
  for (const auto& block : prior.blocks) {
    std::vector<int>& cols = block.var.block == StateBlock::kLandmark ? landmark_cols : state_cols;
    for (int c = 0; c < stateBlockDim(block.var.block); ++c) cols.push_back(block.offset + c);
  }
  const VecX<Scalar> b0 = prior.gradientAtAnchor();
  MatX<Scalar> Lambda_states = Lambda_t(state_cols, state_cols);
  JointFactor<Scalar> joint;
  joint.b_states = b0(state_cols);
  if (!landmark_cols.empty()) {
    const MatX<Scalar> Lambda_sl = Lambda_t(state_cols, landmark_cols);
    const Eigen::LDLT<MatX<Scalar>> ldlt_ll(Lambda_t(landmark_cols, landmark_cols));
    Lambda_states -= Lambda_sl * ldlt_ll.solve(Lambda_sl.transpose());
    joint.b_states -= Lambda_sl * ldlt_ll.solve(VecX<Scalar>(b0(landmark_cols)));
  }
  joint.llt.compute(Lambda_states);
  if (joint.llt.info() != Eigen::Success) return std::nullopt;
  const Scalar log_det_joint = Scalar(2) * joint.llt.matrixLLT().diagonal().array().log().sum();
  Scalar log_det_unary = 0;
  for (const RecoveredFactor<Scalar>& f : sp.factors) {
    if (f.spec.kind != NfrFactorKind::kUnary) continue;
    log_det_unary +=
        Scalar(2) *
        Eigen::LLT<MatX<Scalar>>(f.information).matrixLLT().diagonal().array().log().sum();
    const int off = b.x[static_cast<size_t>(f.spec.var)].offset;
    const Eigen::Index dim = f.information.rows();
    Lambda_s->block(off, off, dim, dim) -= f.information;
  }
  *kld -= Scalar(0.5) * (log_det_joint - log_det_unary);
  (*Lambda_s)(state_cols, state_cols) += Lambda_states;
  return joint;
}

// The unary pose and velocity factors, deflated along the rigid motions
// (core/sparsify/rigid_deflation.h): which of sp.factors, and the matrix A that mixes them.
struct RigidDeflationOfEvent {
  std::vector<size_t> members;
  RigidDeflation deflation;
};

// J_u: the whitened Jacobians at x⁰ of the unary pose and velocity factors over the blanket's n
// columns (at z = h(x⁰) the ⊟ Jacobians are the identity, so factor i's rows are W_i S_i);
// *members: their indices in sp.factors.
template <typename Scalar>
MatXd unaryJacobian(const BlanketVars<Scalar>& b, const Sparsification<Scalar>& sp, int n,
                    std::vector<size_t>* members) {
  Eigen::Index m = 0;
  for (size_t i = 0; i < sp.factors.size(); ++i) {
    const RecoveredFactor<Scalar>& f = sp.factors[i];
    const BlanketKind kind = b.x[static_cast<size_t>(f.spec.var)].kind;
    if (f.spec.kind != NfrFactorKind::kUnary ||
        (kind != BlanketKind::kPose && kind != BlanketKind::kVelocity)) {
      continue;
    }
    members->push_back(i);
    m += f.sqrt_information.rows();
  }
  MatXd J_u = MatXd::Zero(m, n);
  m = 0;
  for (const size_t i : *members) {
    const MatX<Scalar>& W = sp.factors[i].sqrt_information;
    J_u.block(m, b.x[static_cast<size_t>(sp.factors[i].spec.var)].offset, W.rows(), W.cols()) =
        W.template cast<double>();
    m += W.rows();
  }
  return J_u;
}

// The deflation of one event; *Lambda_s (double) and *kld updated to the deflated factors:
// Λ_s' = Λ_s − Σ (1 − μ_j) g_j g_jᵀ, g_j = J_uᵀq_j, and the KLD's change
// ½ (⟨Λ_s' − Λ_s, Σ_t⟩ − Σ log μ_j) with Σ_t from the regularized Λ_t the recovery used.
template <typename Scalar>
RigidDeflationOfEvent deflateRigid(const BlanketVars<Scalar>& b, const Sparsification<Scalar>& sp,
                                   const GaugeDirections& dirs, const MatXd& G_d,
                                   const MatX<Scalar>& Lambda_t, MatXd* Lambda_s, double* kld) {
  RigidDeflationOfEvent out;
  const MatXd J_u = unaryJacobian(b, sp, static_cast<int>(Lambda_t.rows()), &out.members);
  out.deflation = rigidDeflation(J_u * dirs.leftCols<kGaugeRandom>(), G_d);
  const RigidDeflation& d = out.deflation;
  if (!d.status.ok() || d.deflated() == 0) return out;
  const MatXd g = J_u.transpose() * d.Q;
  const VecXd removed = VecXd::Ones(d.deflated()) - d.mu;
  *Lambda_s -= g * removed.asDiagonal() * g.transpose();
  const MatXd Sigma_g = Eigen::LLT<MatXd>(Lambda_t.template cast<double>()).solve(g);
  const double trace_change =
      -(g.cwiseProduct(Sigma_g).colwise().sum().transpose()).cwiseProduct(removed).sum();
  *kld += 0.5 * (trace_change - d.logDetChange());
  return out;
}

template <typename Scalar>
typename Window<Scalar>::NfrFactor windowFactor(const BlanketVars<Scalar>& b,
                                                const RecoveredFactor<Scalar>& recovered) {
  typename Window<Scalar>::NfrFactor f;
  f.factor = recovered;
  f.factor.spec.var = 0;
  f.kind = b.x[static_cast<size_t>(recovered.spec.var)].kind;
  f.frame = b.var_of[static_cast<size_t>(recovered.spec.var)].frame_id;
  return f;
}

// The recovered factors into the window: pose–landmark ones to their landmark, unary and
// relative-pose ones to the factor list (not with the joint factor, which replaces them), the
// deflated ones as one joint factor.
template <typename Scalar>
void insertFactors(Window<Scalar>& w, const BlanketVars<Scalar>& b,
                   const Sparsification<Scalar>& sp, bool joint,
                   const RigidDeflationOfEvent* rigid) {
  std::vector<bool> in_joint(sp.factors.size(), false);
  if (rigid != nullptr) {
    typename Window<Scalar>::NfrJointFactor deflated;
    for (const size_t i : rigid->members) {
      in_joint[i] = true;
      deflated.members.push_back(windowFactor(b, sp.factors[i]));
    }
    deflated.A = rigid->deflation.A.template cast<Scalar>();
    w.nfr_joint.push_back(std::move(deflated));
  }
  for (size_t i = 0; i < sp.factors.size(); ++i) {
    if (in_joint[i]) continue;
    const RecoveredFactor<Scalar>& recovered = sp.factors[i];
    typename Window<Scalar>::NfrFactor f = windowFactor(b, recovered);
    if (recovered.spec.kind == NfrFactorKind::kRelativePose) {
      f.factor.spec.pose_b = 1;
      f.frame_b = b.var_of[static_cast<size_t>(recovered.spec.pose_b)].frame_id;
      w.nfr_states.push_back(std::move(f));
    } else if (recovered.spec.kind == NfrFactorKind::kPoseLandmark) {
      f.factor.spec.landmark = 1;
      w.landmarks.at(b.var_of[static_cast<size_t>(recovered.spec.landmark)].frame_id)
          .nfr.push_back(std::move(f));
    } else if (!joint) {
      w.nfr_states.push_back(std::move(f));
    }
  }
}

// The factors replace the prior. paper: no variable is in a linear prior any more, so
// first-estimate Jacobians end (the factors are relinearized like every other residual).
// joint-states: the joint factor is kept as the linear prior over the states (δ = x ⊟ x⁰, the
// unary residuals to first order), its states keep their first estimates.
template <typename Scalar>
void replacePrior(Window<Scalar>& w, const JointFactor<Scalar>* joint) {
  MargPrior<Scalar> states;
  states.storage = w.prior.storage;
  if (joint != nullptr) {
    for (const auto& block : w.prior.blocks) {
      if (block.var.block != StateBlock::kLandmark) states.addBlock(block.var, block.T0, block.sb0);
    }
    // ½‖r + Uδ‖² with UᵀU = Λ, Uᵀr = b; the Hessian storage keeps c = ½‖r‖² (its convention).
    VecX<Scalar> r = joint->llt.matrixL().solve(joint->b_states);
    const Scalar c = Scalar(0.5) * r.squaredNorm();
    states.setSqrt(MatX<Scalar>(joint->llt.matrixU()), std::move(r));
    states.setHessian(MatX<Scalar>(joint->llt.reconstructedMatrix()), joint->b_states, c);
  }
  w.prior = std::move(states);
  for (auto& [id, frame] : w.frames) {
    frame.linearized = frame.linearized && w.prior.indexOf({id, StateBlock::kPose}) >= 0;
    frame.speed_bias_linearized =
        frame.speed_bias_linearized && w.prior.indexOf({id, StateBlock::kSpeedBias}) >= 0;
  }
  for (auto& [id, lm] : w.landmarks) lm.linearized = false;
}

// The gauge directions over the prior's columns, at its linearization points; the random one is
// the same draw for every event of a given size.
template <typename Scalar>
GaugeDirections blanketDirections(const MargPrior<Scalar>& prior) {
  PriorLayout layout;
  GaugeState state;
  prior.gaugeLayout(&layout, &state);
  constexpr std::uint64_t kRandomDirectionSeed = 1;
  return gaugeDirections(layout, prior.cols(), state, kRandomDirectionSeed);
}

}  // namespace

template <typename Scalar>
MatX<Scalar> describeBlanket(const Window<Scalar>& w, SparsifyEvent* event) {
  MatX<Scalar> Lambda_t = w.prior.hessianAtAnchor();
  event->blanket_cols = w.prior.cols();
  event->n_blanket_poses = 0;
  event->n_blanket_landmarks = 0;
  for (const auto& block : w.prior.blocks) {
    event->n_blanket_poses += block.var.block == StateBlock::kPose ? 1 : 0;
    event->n_blanket_landmarks += block.var.block == StateBlock::kLandmark ? 1 : 0;
  }
  event->nnz_dense = (Lambda_t.array() != Scalar(0)).count();
  event->nnz_sparse = event->nnz_dense;
  event->info_dense =
      directionInformation(Lambda_t.template cast<double>(), blanketDirections(w.prior));
  event->info_sparse = event->info_dense;
  return Lambda_t;
}

template <typename Scalar>
void sparsifyPrior(Window<Scalar>& w, SparsifyTopology topology, bool rigid_deflation,
                   SparsifyEvent* event) {
  MatX<Scalar> Lambda_t = describeBlanket(w, event);
  const GaugeDirections dirs = blanketDirections(w.prior);
  const bool joint = topology == SparsifyTopology::kJointStates;
  // The dense prior's information along the rigid motions, before the regularization below.
  MatXd G_d;
  if (rigid_deflation && topology == SparsifyTopology::kPaper) {
    const auto E = dirs.leftCols<kGaugeRandom>();
    G_d = E.transpose() * Lambda_t.template cast<double>() * E;
  }
  Lambda_t.diagonal().array() +=
      Scalar(10) * NumericTraits<Scalar>::pinvRelativeTolerance(static_cast<int>(Lambda_t.rows())) *
      Lambda_t.trace();
  const auto t0 = Clock::now();
  auto fallback = [event, t0](const std::string& reason) {
    event->t_recovery_s = secondsSince(t0);
    event->fallback_reason = reason;
  };
  // The factors measure h at the prior's linearization point x⁰ (the paper's choice: z = h(μ_t)
  // with μ_t the linearization point); the dense prior's gradient there is not carried over.
  // Taking them at the dense prior's minimizer x⁰ ⊞ δ*, (Λ_t + εI) δ* = −b, instead was far
  // worse (MH_02, 600 frames: ATE 0.023 m against 0.004 m) — presumably because δ* is ill
  // determined along the directions Λ_t leaves (nearly) free.
  const BlanketVars<Scalar> b = blanketOf(w);
  if (b.anchor < 0) return fallback("no pose in the blanket");
  const NfrTopology factors = topology == SparsifyTopology::kRelativePose
                                  ? relativePoseTopology(b.x, b.poseChain(), b.anchor)
                                  : paperTopology(b.x, b.anchor);
  const Sparsification<Scalar> sp = sparsify<Scalar>(Lambda_t, b.x, factors);
  if (!sp.status.ok()) return fallback(sp.status.toString());
  Scalar kld = sp.kld;
  MatX<Scalar> Lambda_s = sp.Lambda_s;
  std::optional<JointFactor<Scalar>> joint_factor;
  if (joint) {
    joint_factor = jointStateFactor(w.prior, Lambda_t, b, sp, &kld, &Lambda_s);
    if (!joint_factor) {
      return fallback("the joint state factor's information is not positive definite");
    }
  }
  MatXd Lambda_s_d = Lambda_s.template cast<double>();
  double kld_d = static_cast<double>(kld);
  std::optional<RigidDeflationOfEvent> rigid;
  if (G_d.size() != 0) {
    rigid = deflateRigid(b, sp, dirs, G_d, Lambda_t, &Lambda_s_d, &kld_d);
    if (!rigid->deflation.status.ok()) return fallback(rigid->deflation.status.toString());
    if (rigid->deflation.deflated() == 0) rigid.reset();
  }
  event->t_recovery_s = secondsSince(t0);
  const Vec7d info_sparse = directionInformation(Lambda_s_d, dirs);

  const auto t1 = Clock::now();
  insertFactors(w, b, sp, joint, rigid ? &*rigid : nullptr);
  replacePrior(w, joint_factor ? &*joint_factor : nullptr);
  event->t_insert_s = secondsSince(t1);
  event->recovered = true;
  event->kld = kld_d;
  event->info_sparse = info_sparse;
  event->nnz_sparse = (Lambda_s_d.array() != 0.0).count();
}

#define MARGLAB_INST(S)                                                  \
  template MatX<S> describeBlanket<S>(const Window<S>&, SparsifyEvent*); \
  template void sparsifyPrior<S>(Window<S>&, SparsifyTopology, bool, SparsifyEvent*);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
