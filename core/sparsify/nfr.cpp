#include "core/sparsify/nfr.h"

#include <fmt/core.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/common/scalar.h"

namespace marglab {

int blanketKindDim(BlanketKind kind) {
  switch (kind) {
    case BlanketKind::kPose:
    case BlanketKind::kBias:
      return 6;
    case BlanketKind::kVelocity:
    case BlanketKind::kLandmark:
      return 3;
  }
  return 0;
}

namespace {

// "pose", "velocity", "bias", "landmark" (error messages).
const char* blanketKindName(BlanketKind kind) {
  switch (kind) {
    case BlanketKind::kPose:
      return "pose";
    case BlanketKind::kVelocity:
      return "velocity";
    case BlanketKind::kBias:
      return "bias";
    case BlanketKind::kLandmark:
      return "landmark";
  }
  return "?";
}

}  // namespace

template <typename Scalar>
NfrTopology paperTopology(const Blanket<Scalar>& blanket, int anchor_pose) {
  NfrTopology topology;
  for (int v = 0; v < static_cast<int>(blanket.size()); ++v) {
    if (blanket[v].kind != BlanketKind::kLandmark) {
      topology.push_back({NfrFactorKind::kUnary, v, -1});
    }
  }
  for (int v = 0; v < static_cast<int>(blanket.size()); ++v) {
    if (blanket[v].kind == BlanketKind::kLandmark) {
      topology.push_back({NfrFactorKind::kPoseLandmark, anchor_pose, v});
    }
  }
  return topology;
}

template <typename Scalar>
NfrTopology relativePoseTopology(const Blanket<Scalar>& blanket, const std::vector<int>& pose_chain,
                                 int anchor_pose) {
  NfrTopology topology;
  topology.push_back({NfrFactorKind::kUnary, anchor_pose, -1, -1});
  for (size_t k = 1; k < pose_chain.size(); ++k) {
    topology.push_back({NfrFactorKind::kRelativePose, pose_chain[k - 1], -1, pose_chain[k]});
  }
  for (int v = 0; v < static_cast<int>(blanket.size()); ++v) {
    const BlanketKind kind = blanket[v].kind;
    if (kind == BlanketKind::kVelocity || kind == BlanketKind::kBias) {
      topology.push_back({NfrFactorKind::kUnary, v, -1, -1});
    }
  }
  for (int v = 0; v < static_cast<int>(blanket.size()); ++v) {
    if (blanket[v].kind == BlanketKind::kLandmark) {
      topology.push_back({NfrFactorKind::kPoseLandmark, anchor_pose, v, -1});
    }
  }
  return topology;
}

std::vector<int> vioGaugeReference(int pose_offset) {
  return {pose_offset, pose_offset + 1, pose_offset + 2, pose_offset + 5};
}

template <typename Scalar>
VecX<Scalar> RecoveredFactor<Scalar>::whitenedResidual(const Blanket<Scalar>& x,
                                                       MatX<Scalar>* J) const {
  const BlanketVariable<Scalar>& var = x[spec.var];
  VecX<Scalar> r;
  MatX<Scalar> J_h;
  if (spec.kind == NfrFactorKind::kPoseLandmark) {
    Mat<Scalar, 3, 6> J_pose;
    Mat3<Scalar> J_landmark;
    r.resize(3);  // then a fixed-size assignment: GCC 12 warns (-Warray-bounds) on Vec3 → VecX
    r.template head<3>() = poseLandmarkResidual<Scalar>(
        var.T_w_i, Vec3<Scalar>(x[spec.landmark].value), Vec3<Scalar>(z), &J_pose, &J_landmark);
    J_h.resize(3, 9);
    J_h << J_pose, J_landmark;
  } else if (spec.kind == NfrFactorKind::kRelativePose) {
    Mat<Scalar, 6, 6> J_a, J_b;
    r = relativePoseResidual<Scalar>(var.T_w_i, x[spec.pose_b].T_w_i, z_pose, &J_a, &J_b);
    J_h.resize(6, 12);
    J_h << J_a, J_b;
  } else if (var.kind == BlanketKind::kPose) {
    Mat<Scalar, 6, 6> J_pose;
    r = posePriorResidual<Scalar>(var.T_w_i, z_pose, &J_pose);
    J_h = J_pose;
  } else {
    r = var.value - z;
    J_h = MatX<Scalar>::Identity(r.size(), r.size());
  }
  if (J) *J = sqrt_information * J_h;
  return sqrt_information * r;
}

template <typename Scalar>
NfrProblem<Scalar>::NfrProblem(const MatX<Scalar>& Lambda_t, const Blanket<Scalar>& blanket,
                               const NfrTopology& topology, const std::vector<int>& gauge_reference)
    : blanket_(blanket) {
  status_ = setUp(Lambda_t, topology, gauge_reference);
}

namespace {

Status invalidArgument(std::string message) {
  return Status::Error(Status::Code::kInvalidArgument, "NFR: " + std::move(message));
}

}  // namespace

template <typename Scalar>
Status NfrProblem<Scalar>::checkLayout(std::vector<int>* owner) const {
  const int n_vars = static_cast<int>(blanket_.size());
  owner->assign(n_, -1);
  for (int v = 0; v < n_vars; ++v) {
    const BlanketVariable<Scalar>& var = blanket_[v];
    const int d = blanketKindDim(var.kind);
    if (var.offset < 0 || var.offset + d > n_) {
      return invalidArgument(
          fmt::format("variable {} ({}) spans columns [{}, {}) outside Λ_t ({} columns)", v,
                      blanketKindName(var.kind), var.offset, var.offset + d, n_));
    }
    bool finite = true;
    if (var.kind == BlanketKind::kPose) {
      finite =
          var.T_w_i.unitQuaternion().coeffs().allFinite() && var.T_w_i.translation().allFinite();
    } else if (var.value.size() != d) {
      return invalidArgument(fmt::format("variable {} ({}) has {} values, expected {}", v,
                                         blanketKindName(var.kind), var.value.size(), d));
    } else {
      finite = var.value.allFinite();
    }
    if (!finite) {
      return Status::Error(Status::Code::kNotFinite,
                           fmt::format("NFR: variable {} has a non-finite value", v));
    }
    for (int c = var.offset; c < var.offset + d; ++c) {
      if ((*owner)[c] >= 0) {
        return invalidArgument(
            fmt::format("variables {} and {} overlap at column {}", (*owner)[c], v, c));
      }
      (*owner)[c] = v;
    }
  }
  for (int c = 0; c < n_; ++c) {
    if ((*owner)[c] < 0) {
      return invalidArgument(fmt::format("column {} of Λ_t belongs to no variable", c));
    }
  }
  return Status::Ok();
}

template <typename Scalar>
Status NfrProblem<Scalar>::checkTopology(const NfrTopology& topology,
                                         std::vector<int>* unary_of) const {
  const int n_vars = static_cast<int>(blanket_.size());
  const auto is = [&](int v, BlanketKind kind) {
    return v >= 0 && v < n_vars && blanket_[v].kind == kind;
  };
  unary_of->assign(n_vars, -1);
  int n_rows = 0;
  for (int f = 0; f < static_cast<int>(topology.size()); ++f) {
    const NfrFactorSpec& spec = topology[f];
    if (spec.kind == NfrFactorKind::kUnary) {
      if (spec.var < 0 || spec.var >= n_vars || is(spec.var, BlanketKind::kLandmark)) {
        return invalidArgument(
            fmt::format("factor {}: a unary factor needs a pose, velocity or bias variable, got {}",
                        f, spec.var));
      }
      if ((*unary_of)[spec.var] >= 0) {
        return invalidArgument(fmt::format("factors {} and {} are both unary on variable {}",
                                           (*unary_of)[spec.var], f, spec.var));
      }
      (*unary_of)[spec.var] = f;
      n_rows += blanketKindDim(blanket_[spec.var].kind);
    } else if (spec.kind == NfrFactorKind::kRelativePose) {
      if (!is(spec.var, BlanketKind::kPose) || !is(spec.pose_b, BlanketKind::kPose) ||
          spec.var == spec.pose_b) {
        return invalidArgument(fmt::format(
            "factor {}: a relative-pose factor needs two different poses, got {} and {}", f,
            spec.var, spec.pose_b));
      }
      n_rows += 6;
    } else {
      if (!is(spec.var, BlanketKind::kPose) || !is(spec.landmark, BlanketKind::kLandmark)) {
        return invalidArgument(fmt::format(
            "factor {}: a pose–landmark factor needs a pose and a landmark, got {} and {}", f,
            spec.var, spec.landmark));
      }
      n_rows += 3;
    }
  }
  if (n_rows != n_) {
    return invalidArgument(fmt::format(
        "the topology has {} rows for {} columns; the closed form (eq. 16) needs H_s square",
        n_rows, n_));
  }
  return Status::Ok();
}

template <typename Scalar>
Status NfrProblem<Scalar>::factorizeTarget(const MatX<Scalar>& Lambda_t,
                                           const std::vector<int>& kept) {
  const MatX<Scalar> Lambda_full = Lambda_t.template selfadjointView<Eigen::Lower>();
  const MatX<Scalar> Lambda_red = Lambda_full(kept, kept);
  Eigen::SelfAdjointEigenSolver<MatX<Scalar>> eig(Lambda_red);
  if (eig.info() != Eigen::Success) {
    return Status::Error(Status::Code::kSolveFailed,
                         "NFR: the eigendecomposition of Λ_t did not converge");
  }
  const VecX<Scalar>& lambda = eig.eigenvalues();  // ascending
  lambda_min_ = lambda[0];
  lambda_max_ = lambda[m_ - 1];
  threshold_ = NumericTraits<Scalar>::pinvRelativeTolerance(m_) *
               std::max(std::abs(lambda_min_), std::abs(lambda_max_));
  if (!(lambda_min_ > threshold_)) {
    const int k = n_ - m_;
    return Status::Error(
        Status::Code::kRankDeficient,
        fmt::format("NFR: Λ_t{} is not positive definite: λ_min = {:.3g} ≤ {:.3g} = {}·ε·λ_max; {}",
                    k > 0 ? " without its gauge reference" : "", lambda_min_, threshold_, m_,
                    k > 0 ? "the reference does not fix its nullspace"
                          : "a gauge-free prior needs a gauge reference (e.g. vioGaugeReference)"));
  }
  Sigma_red_ =
      eig.eigenvectors() * lambda.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
  log_det_target_ = lambda.array().log().sum();
  return Status::Ok();
}

// One factor's Jacobian ∂h/∂δ at x̄ over its variables' columns, and its measurement h(x̄).
template <typename Scalar>
typename NfrProblem<Scalar>::FactorRows NfrProblem<Scalar>::linearizeFactor(
    const NfrFactorSpec& spec, const std::vector<bool>& is_reference) const {
  FactorRows fr;
  fr.spec = spec;
  const BlanketVariable<Scalar>& var = blanket_[spec.var];
  const auto add_cols = [&fr](const BlanketVariable<Scalar>& v) {
    for (int j = 0; j < blanketKindDim(v.kind); ++j) fr.cols.push_back(v.offset + j);
  };
  MatX<Scalar> J_h;
  add_cols(var);
  if (spec.kind == NfrFactorKind::kPoseLandmark) {
    const BlanketVariable<Scalar>& landmark = blanket_[spec.landmark];
    Mat<Scalar, 3, 6> J_pose;
    Mat3<Scalar> J_landmark;
    fr.z.resize(3);  // as in whitenedResidual
    fr.z.template head<3>() = poseLandmarkResidual<Scalar>(
        var.T_w_i, Vec3<Scalar>(landmark.value), Vec3<Scalar>::Zero(), &J_pose, &J_landmark);
    J_h.resize(3, 9);
    J_h << J_pose, J_landmark;
    add_cols(landmark);
    fr.dim = 3;
    fr.rows = {0, 1, 2};
  } else if (spec.kind == NfrFactorKind::kRelativePose) {
    const BlanketVariable<Scalar>& pose_b = blanket_[spec.pose_b];
    fr.z_pose = var.T_w_i.inverse() * pose_b.T_w_i;
    Mat<Scalar, 6, 6> J_a, J_b;
    relativePoseResidual<Scalar>(var.T_w_i, pose_b.T_w_i, fr.z_pose, &J_a, &J_b);
    J_h.resize(6, 12);
    J_h << J_a, J_b;
    add_cols(pose_b);
    fr.dim = 6;
    fr.rows = {0, 1, 2, 3, 4, 5};
  } else {
    fr.dim = blanketKindDim(var.kind);
    if (var.kind == BlanketKind::kPose) {
      fr.z_pose = var.T_w_i;
      Mat<Scalar, 6, 6> J_pose;
      posePriorResidual<Scalar>(var.T_w_i, fr.z_pose, &J_pose);  // I at the measurement
      J_h = J_pose;
    } else {
      fr.z = var.value;
      J_h = MatX<Scalar>::Identity(fr.dim, fr.dim);
    }
    for (int j = 0; j < fr.dim; ++j) {
      if (!is_reference[var.offset + j]) fr.rows.push_back(j);
    }
  }
  fr.J = J_h(fr.rows, Eigen::all);
  return fr;
}

template <typename Scalar>
Status NfrProblem<Scalar>::setUp(const MatX<Scalar>& Lambda_t, const NfrTopology& topology,
                                 const std::vector<int>& gauge_reference) {
  n_ = static_cast<int>(Lambda_t.rows());
  if (Lambda_t.cols() != n_ || n_ == 0) {
    return invalidArgument(fmt::format("Λ_t is {}x{}, not a non-empty square matrix",
                                       Lambda_t.rows(), Lambda_t.cols()));
  }
  if (!Lambda_t.allFinite()) {
    return Status::Error(Status::Code::kNotFinite, "NFR: Λ_t has a non-finite entry");
  }
  std::vector<int> owner, unary_of;
  Status status = checkLayout(&owner);
  if (status.ok()) status = checkTopology(topology, &unary_of);
  if (!status.ok()) return status;

  // Gauge reference: columns measured by a unary factor, held fixed.
  std::vector<bool> is_reference(n_, false);
  for (int c : gauge_reference) {
    if (c < 0 || c >= n_ || is_reference[c]) {
      return invalidArgument(
          fmt::format("gauge reference column {} is out of range or repeated", c));
    }
    if (unary_of[owner[c]] < 0) {
      return invalidArgument(fmt::format(
          "gauge reference column {} ({} variable {}) is not measured by a unary factor", c,
          blanketKindName(blanket_[owner[c]].kind), owner[c]));
    }
    is_reference[c] = true;
  }
  std::vector<int> reduced(n_, -1);
  std::vector<int> kept;
  for (int c = 0; c < n_; ++c) {
    if (!is_reference[c]) {
      reduced[c] = static_cast<int>(kept.size());
      kept.push_back(c);
    }
  }
  m_ = static_cast<int>(kept.size());
  if (m_ == 0) return invalidArgument("every column is a gauge reference");
  status = factorizeTarget(Lambda_t, kept);
  if (!status.ok()) return status;

  // The factors linearized at x̄, their rows of H̃_s and C_i = {H̃_s Σ̃_t H̃_sᵀ}^(i).
  MatX<Scalar> H_red = MatX<Scalar>::Zero(m_, m_);
  int row = 0;
  for (const NfrFactorSpec& spec : topology) {
    FactorRows fr = linearizeFactor(spec, is_reference);
    std::vector<int> kept_local;
    for (int j = 0; j < static_cast<int>(fr.cols.size()); ++j) {
      if (reduced[fr.cols[j]] >= 0) {
        kept_local.push_back(j);
        fr.red_cols.push_back(reduced[fr.cols[j]]);
      }
    }
    fr.J_red = fr.J(Eigen::all, kept_local);
    H_red(Eigen::seqN(row, static_cast<int>(fr.rows.size())), fr.red_cols) = fr.J_red;
    row += static_cast<int>(fr.rows.size());
    const MatX<Scalar> C = fr.J_red * Sigma_red_(fr.red_cols, fr.red_cols) * fr.J_red.transpose();
    fr.C = Scalar(0.5) * (C + C.transpose());  // symmetric up to rounding
    factors_.push_back(std::move(fr));
  }

  // H̃_s invertible (then Λ̃_s ≻ 0 for every Λ_r ≻ 0 and eq. 16 is the minimizer).
  Eigen::ColPivHouseholderQR<MatX<Scalar>> qr(H_red);
  qr.setThreshold(NumericTraits<Scalar>::pinvRelativeTolerance(m_));
  if (qr.rank() < m_) {
    return Status::Error(Status::Code::kRankDeficient,
                         fmt::format("NFR: H_s is singular (rank {} of {}): the topology does not "
                                     "determine every variable",
                                     qr.rank(), m_));
  }
  log_abs_det_H_ = qr.logAbsDeterminant();
  return Status::Ok();
}

template <typename Scalar>
bool NfrProblem<Scalar>::fits(const std::vector<MatX<Scalar>>& Lambda_r) const {
  if (Lambda_r.size() != factors_.size()) return false;
  for (size_t i = 0; i < factors_.size(); ++i) {
    const Eigen::Index d = static_cast<Eigen::Index>(factors_[i].rows.size());
    if (Lambda_r[i].rows() != d || Lambda_r[i].cols() != d) return false;
  }
  return true;
}

template <typename Scalar>
Sparsification<Scalar> NfrProblem<Scalar>::recover() const {
  Sparsification<Scalar> out;
  out.status = status_;
  if (!status_.ok()) return out;
  std::vector<MatX<Scalar>> Lambda_r;
  for (size_t i = 0; i < factors_.size(); ++i) {
    const FactorRows& fr = factors_[i];
    const Eigen::LLT<MatX<Scalar>> llt(fr.C);
    if (llt.info() != Eigen::Success) {
      out.status = Status::Error(
          Status::Code::kRankDeficient,
          fmt::format("NFR: factor {}: {{H_s Σ_t H_sᵀ}}^(i) is not positive definite", i));
      return out;
    }
    const Eigen::Index d = fr.C.rows();
    // C = L Lᵀ ⇒ Λ_r^(i) = C⁻¹ = L⁻ᵀ L⁻¹ = Wᵀ W with W = L⁻¹.
    const MatX<Scalar> W = llt.matrixL().solve(MatX<Scalar>::Identity(d, d));
    RecoveredFactor<Scalar> rf;
    rf.spec = fr.spec;
    rf.rows = fr.rows;
    rf.information = W.transpose() * W;
    rf.sqrt_information = MatX<Scalar>::Zero(d, fr.dim);
    rf.sqrt_information(Eigen::all, fr.rows) = W;
    rf.z_pose = fr.z_pose;
    rf.z = fr.z;
    Lambda_r.push_back(rf.information);
    out.factors.push_back(std::move(rf));
  }
  out.Lambda_s = sparseInformation(Lambda_r);
  out.kld = kld(Lambda_r);
  if (!out.Lambda_s.allFinite() || !std::isfinite(out.kld)) {
    out.status = Status::Error(Status::Code::kNotFinite,
                               "NFR: the recovered information or its KLD is not finite");
  }
  return out;
}

template <typename Scalar>
Scalar NfrProblem<Scalar>::kld(const std::vector<MatX<Scalar>>& Lambda_r) const {
  if (!status_.ok() || !fits(Lambda_r)) return std::numeric_limits<Scalar>::quiet_NaN();
  Scalar trace = 0;
  Scalar log_det_r = 0;
  for (size_t i = 0; i < factors_.size(); ++i) {
    const Eigen::LLT<MatX<Scalar>> llt(Lambda_r[i]);
    if (llt.info() != Eigen::Success) return std::numeric_limits<Scalar>::infinity();
    log_det_r += Scalar(2) * llt.matrixLLT().diagonal().array().log().sum();
    trace += Lambda_r[i].cwiseProduct(factors_[i].C).sum();  // ⟨Λ_r^(i), C_i⟩, both symmetric
  }
  const Scalar log_det_s = Scalar(2) * log_abs_det_H_ + log_det_r;
  return Scalar(0.5) * (trace - log_det_s + log_det_target_ - static_cast<Scalar>(m_));
}

template <typename Scalar>
Status NfrProblem<Scalar>::kldGradient(const std::vector<MatX<Scalar>>& Lambda_r,
                                       std::vector<MatX<Scalar>>* gradient) const {
  if (!status_.ok()) return status_;
  if (!fits(Lambda_r)) {
    return Status::Error(Status::Code::kInvalidArgument,
                         "NFR: the Λ_r blocks do not fit the topology");
  }
  MatX<Scalar> Lambda_s_red = MatX<Scalar>::Zero(m_, m_);
  for (size_t i = 0; i < factors_.size(); ++i) {
    const FactorRows& fr = factors_[i];
    Lambda_s_red(fr.red_cols, fr.red_cols) += fr.J_red.transpose() * Lambda_r[i] * fr.J_red;
  }
  const Eigen::LLT<MatX<Scalar>> llt(Lambda_s_red);
  if (llt.info() != Eigen::Success) {
    return Status::Error(Status::Code::kSolveFailed, "NFR: Λ_s is not positive definite");
  }
  const MatX<Scalar> Sigma_s_red = llt.solve(MatX<Scalar>::Identity(m_, m_));
  gradient->clear();
  for (const FactorRows& fr : factors_) {
    gradient->push_back(fr.C -
                        fr.J_red * Sigma_s_red(fr.red_cols, fr.red_cols) * fr.J_red.transpose());
  }
  return Status::Ok();
}

template <typename Scalar>
MatX<Scalar> NfrProblem<Scalar>::sparseInformation(
    const std::vector<MatX<Scalar>>& Lambda_r) const {
  if (!status_.ok() || !fits(Lambda_r)) return MatX<Scalar>();
  MatX<Scalar> Lambda_s = MatX<Scalar>::Zero(n_, n_);
  for (size_t i = 0; i < factors_.size(); ++i) {
    const FactorRows& fr = factors_[i];
    Lambda_s(fr.cols, fr.cols) += fr.J.transpose() * Lambda_r[i] * fr.J;
  }
  return Lambda_s;
}

template <typename Scalar>
Sparsification<Scalar> sparsify(const MatX<Scalar>& Lambda_t, const Blanket<Scalar>& blanket,
                                const NfrTopology& topology,
                                const std::vector<int>& gauge_reference) {
  return NfrProblem<Scalar>(Lambda_t, blanket, topology, gauge_reference).recover();
}

#define MARGLAB_INST(S)                                                                          \
  template NfrTopology paperTopology<S>(const Blanket<S>&, int);                                 \
  template NfrTopology relativePoseTopology<S>(const Blanket<S>&, const std::vector<int>&, int); \
  template struct RecoveredFactor<S>;                                                            \
  template class NfrProblem<S>;                                                                  \
  template Sparsification<S> sparsify<S>(const MatX<S>&, const Blanket<S>&, const NfrTopology&,  \
                                         const std::vector<int>&);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
