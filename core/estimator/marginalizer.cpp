#include "core/estimator/marginalizer.h"

#include "core/common/scalar.h"
#include "core/estimator/system_blocks.h"
#include "core/linalg/flat_qr.h"
#include "core/linalg/landmark_block.h"
#include "core/linalg/schur.h"

namespace marglab {
namespace {

// The linear problem of one marginalization: columns [marginalized | kept], the landmarks to
// eliminate, the rows taken as they are, the old prior at its current δ and the new prior's
// layout (anchored at the kept variables' first estimates).
template <typename Scalar>
struct MargProblem {
  std::vector<LandmarkJacobians<Scalar>> lins;
  std::vector<RowBlock<Scalar>> direct;
  ColumnMap column_of;
  int n_marg = 0;
  int n = 0;
  MargPrior<Scalar> next;
  VecX<Scalar> old_delta, new_delta;
};

// The plan's landmarks over the frames whose observations stay; those with pose information.
template <typename Scalar>
void gatherLandmarks(const Window<Scalar>& w, const MargPlan& plan,
                     const std::set<int64_t>& system_frames,
                     const typename Window<Scalar>::RelativePoses& rel, MargProblem<Scalar>* p) {
  for (int64_t id : plan.landmarks) {
    LandmarkJacobians<Scalar> lin;
    if (!w.linearizeLandmark(id, w.landmarks.at(id), system_frames, rel, &lin)) continue;
    // Rows beyond the three the landmark consumes carry pose information.
    if (lin.r.size() <= 3 || lin.frames.empty()) continue;
    p->lins.push_back(std::move(lin));
  }
}

// Rows stacked as they are: IMU factors, observations whose landmark stays, landmarks of the prior
// that go, recovered factors on marginalized variables.
template <typename Scalar>
void gatherDirectRows(const Window<Scalar>& w, const MargPlan& plan,
                      const std::set<int64_t>& system_frames,
                      const typename Window<Scalar>::RelativePoses& rel, MargProblem<Scalar>* p) {
  for (int64_t from : plan.imu_links) {
    const LinkLinearized<Scalar> lin = w.linearizeLink(from, w.imu_links.at(from));
    p->direct.push_back({lin.vars(), lin.J, lin.r});
  }
  for (const auto& [track, frame] : plan.kept_landmark_obs) {
    RowBlock<Scalar> rows;
    if (w.landmarkRows(track, {frame}, rel, NfrRows::kExclude, &rows))
      p->direct.push_back(std::move(rows));
  }
  for (const VarKey& var : plan.vars) {
    RowBlock<Scalar> rows;
    if (var.block == StateBlock::kLandmark &&
        w.landmarkRows(var.frame_id, system_frames, rel, NfrRows::kInclude, &rows)) {
      p->direct.push_back(std::move(rows));
    }
  }
  for (const auto& f : w.nfr_states) {
    if (f.touches(plan.vars)) p->direct.push_back(w.linearizeNfr(f, -1, nullptr));
  }
  for (const auto& f : w.nfr_joint) {
    if (f.touches(plan.vars)) p->direct.push_back(w.linearizeNfrJoint(f));
  }
  const std::set<int64_t> eliminated(plan.landmarks.begin(), plan.landmarks.end());
  for (const auto& [id, lm] : w.landmarks) {
    if (eliminated.count(id) != 0 || plan.vars.count({id, StateBlock::kLandmark}) != 0) continue;
    for (const auto& f : lm.nfr) {
      if (plan.vars.count(f.var()) != 0) p->direct.push_back(w.linearizeNfr(f, id, &lm));
    }
  }
}

// Columns [plan.vars | kept] and the new prior's layout over the kept variables.
template <typename Scalar>
void layoutColumns(const Window<Scalar>& w, const MargPlan& plan, const MargPrior<Scalar>& prior,
                   PriorStorage storage, MargProblem<Scalar>* p) {
  std::set<VarKey> keep;
  for (const auto& lin : p->lins) {
    for (int64_t f : lin.frames) keep.insert({f, StateBlock::kPose});
    if (lin.stereo_offset) keep.insert(kStereoOffsetVar);
  }
  for (const RowBlock<Scalar>& rows : p->direct) {
    for (const auto& [var, offset] : rows.vars) keep.insert(var);
  }
  for (const auto& block : prior.blocks) keep.insert(block.var);
  for (const VarKey& var : plan.vars) keep.erase(var);
  int col = 0;
  for (const VarKey& var : plan.vars) {
    p->column_of[var] = col;
    col += stateBlockDim(var.block);
  }
  p->n_marg = col;
  p->next.storage = storage;
  for (const VarKey& var : keep) {
    p->column_of[var] = col;
    col += stateBlockDim(var.block);
    if (var.block == StateBlock::kLandmark) {
      p->next.addBlock(var, SE3<Scalar>(), Vec<Scalar, kSpeedBiasDim>::Zero(),
                       w.landmarks.at(var.frame_id).jacobianPoint());
      continue;
    }
    if (var.block == StateBlock::kStereoOffset) {
      // Additive with a constant Jacobian: any anchor is exact; the old prior's if it had one.
      p->next.addBlock(var, SE3<Scalar>(), Vec<Scalar, kSpeedBiasDim>::Zero());
      const int old_index = prior.indexOf(var);
      p->next.blocks.back().c0 =
          old_index >= 0 ? prior.blocks[static_cast<size_t>(old_index)].c0 : w.stereoOffset();
      continue;
    }
    const auto& frame = w.frames.at(var.frame_id);
    p->next.addBlock(var, w.jacobianPoseOf(var.frame_id),
                     frame.speed_bias_linearized ? frame.speed_bias_lin : frame.speed_bias);
  }
  p->n = col;
}

template <typename Scalar>
MargProblem<Scalar> gatherProblem(const Window<Scalar>& w, const MargPlan& plan,
                                  const MargPrior<Scalar>& prior, PriorStorage storage) {
  std::set<int64_t> system_frames;
  for (const auto& [id, frame] : w.frames) {
    if (plan.drop_obs_frames.count(id) == 0) system_frames.insert(id);
  }
  MargProblem<Scalar> p;
  const typename Window<Scalar>::RelativePoses rel = w.relativePoses(WithJacobians::kYes);
  gatherLandmarks(w, plan, system_frames, rel, &p);
  gatherDirectRows(w, plan, system_frames, rel, &p);
  layoutColumns(w, plan, prior, storage, &p);
  p.old_delta = w.priorDelta(prior);
  p.new_delta = w.priorDelta(p.next);
  return p;
}

// Whether the Schur system takes the old prior's term (kOmit: the new factors alone, for
// measuring what each stage of the marginalization rounds; marg_rounding.h).
enum class PriorTerm { kAdd, kOmit };

// The Hessian system over [marginalized | kept] of a gathered problem: the landmarks' Schur
// complements, the direct rows, then the old prior at its current δ (in this order: its rounding
// is the run's).
template <typename Scalar>
Status assemble(const MargProblem<Scalar>& p, const MargPrior<Scalar>& prior, PriorTerm term,
                MatX<Scalar>* H, VecX<Scalar>* b) {
  *H = MatX<Scalar>::Zero(p.n, p.n);
  *b = VecX<Scalar>::Zero(p.n);
  for (const LandmarkJacobians<Scalar>& lin : p.lins) {
    LandmarkBlockSc<Scalar> block;
    Status s = block.setFromJacobians(lin.J_p, lin.J_l, lin.r, blockMap(lin, p.column_of));
    if (!s.ok()) return s;
    // A landmark whose H_ll is singular carries no usable pose information: skip it.
    block.addToReducedSystem(*H, *b).ok();
  }
  for (const RowBlock<Scalar>& d : p.direct) addRows(d, d.vars, p.column_of, *H, *b);
  if (term == PriorTerm::kAdd && !prior.empty()) addPrior(prior, p.old_delta, p.column_of, *H, *b);
  return Status::Ok();
}

template <typename Scalar>
class QrMarginalizer final : public Marginalizer<Scalar> {
 public:
  explicit QrMarginalizer(const EstimatorSettings& config) {
    options_.mode = config.qr_threshold_mode;
    if (config.qr_threshold >= 0) options_.threshold = static_cast<Scalar>(config.qr_threshold);
  }

  Status marginalize(const Window<Scalar>& w, const MargPlan& plan, MargPrior<Scalar>* prior,
                     int* qr_rank) const override {
    MargProblem<Scalar> p = gatherProblem(w, plan, *prior, PriorStorage{});
    std::vector<LandmarkBlockNs<Scalar>> blocks(p.lins.size());
    int rows = prior->empty() ? 0 : prior->rows();
    for (size_t l = 0; l < p.lins.size(); ++l) {
      const LandmarkJacobians<Scalar>& lin = p.lins[l];
      Status s = blocks[l].setFromJacobians(lin.J_p, lin.J_l, lin.r, blockMap(lin, p.column_of));
      if (!s.ok()) return s;
      rows += blocks[l].numReducedRows();
    }
    for (const RowBlock<Scalar>& d : p.direct) rows += static_cast<int>(d.r.size());
    MatX<Scalar> A = MatX<Scalar>::Zero(rows, p.n + 1);
    stack(blocks, p, *prior, A);
    FlatQrMarginalization<Scalar> qr = flatQrMarginalize<Scalar>(std::move(A), p.n_marg, options_);
    if (!qr.status.ok()) return qr.status;
    if (qr_rank != nullptr) *qr_rank = qr.total_rank;
    VecX<Scalar> r = qr.prior.r - qr.prior.J * p.new_delta;
    p.next.setSqrt(std::move(qr.prior.J), std::move(r));
    *prior = std::move(p.next);
    return Status::Ok();
  }

 private:
  // [J | r] of the landmarks' reduced rows, the direct rows and the old prior's rows.
  static void stack(const std::vector<LandmarkBlockNs<Scalar>>& blocks,
                    const MargProblem<Scalar>& p, const MargPrior<Scalar>& prior, MatX<Scalar>& A) {
    int row = 0;
    for (const auto& block : blocks) {
      block.copyReducedRows(A, row);
      row += block.numReducedRows();
    }
    for (const RowBlock<Scalar>& d : p.direct) {
      const int m = static_cast<int>(d.r.size());
      for (const auto& [var, offset] : d.vars) {
        const int dim = stateBlockDim(var.block);
        A.block(row, p.column_of.at(var), m, dim) = d.J.middleCols(offset, dim);
      }
      A.col(p.n).segment(row, m) = d.r;
      row += m;
    }
    if (prior.empty()) return;
    MatX<Scalar> J;
    VecX<Scalar> r;
    prior.sqrtRows(p.old_delta, &J, &r);
    for (const auto& block : prior.blocks) {
      const int dim = stateBlockDim(block.var.block);
      A.block(row, p.column_of.at(block.var), J.rows(), dim) = J.middleCols(block.offset, dim);
    }
    A.col(p.n).segment(row, r.size()) = r;
  }

  FlatQrOptions<Scalar> options_;
};

template <typename Scalar>
class SchurMarginalizer final : public Marginalizer<Scalar> {
 public:
  explicit SchurMarginalizer(const PriorStorage& storage) : storage_(storage) {}

  Status marginalize(const Window<Scalar>& w, const MargPlan& plan, MargPrior<Scalar>* prior,
                     int* /*qr_rank*/) const override {
    MargProblem<Scalar> p = gatherProblem(w, plan, *prior, storage_);
    MatX<Scalar> H;
    VecX<Scalar> b;
    if (Status s = assemble(p, *prior, PriorTerm::kAdd, &H, &b); !s.ok()) return s;
    const Preconditioning kind = preconditioningOf(storage_);
    Status s;
    if (kind == Preconditioning::kNone) {
      SchurMarginalization<Scalar> sc = schurMarginalize<Scalar>(H, b, p.n_marg);
      if (!sc.status.ok()) return sc.status;
      s = store(std::move(sc.prior), p.new_delta, &p.next);
    } else {
      // δ = P y over [μ | κ]: the pseudo-inverse of Ĥ_μμ and the Schur complement in y.
      const BlockScaling<Scalar> P = BlockScaling<Scalar>::fromHessian(H, kind);
      SchurMarginalization<Scalar> sc =
          schurMarginalize<Scalar>(P.scaled(H), P.scaledGradient(b), p.n_marg);
      if (!sc.status.ok()) return sc.status;
      s = storeScaled(std::move(sc.prior), P.tail(p.n_marg), p.new_delta, &p.next);
    }
    if (!s.ok()) return s;
    *prior = std::move(p.next);
    return Status::Ok();
  }

 private:
  // The preconditioned storages: the marginal over y_κ (δ_κ = P_κ y_κ) is scaled once more by its
  // own diagonal blocks, y_κ = P₂ z, so that Ĥ_m has a unit-scale diagonal; the shift to x⁰ and the
  // LDLT run on Ĥ_m. sqp / sqj store (Ĥ_m, b̂_m, c = ½‖r‖²); sqrtp stores the LDLT's square root
  // mapped to δ: ½‖r + J_z z‖² with z = Q δ is ½‖r + (J_z Q) δ‖².
  Status storeScaled(HessianPrior<Scalar> marginal, const BlockScaling<Scalar>& P_kept,
                     const VecX<Scalar>& new_delta, MargPrior<Scalar>* next) const {
    const BlockScaling<Scalar> P2 =
        BlockScaling<Scalar>::fromHessian(marginal.H, preconditioningOf(storage_));
    BlockScaling<Scalar> P = P_kept.then(P2);
    MatX<Scalar> H_m = P2.scaled(marginal.H);
    VecX<Scalar> b_m = P2.scaledGradient(marginal.b) - H_m * P.toScaled(new_delta);
    LdltSqrt<Scalar> ldlt = factorize(H_m, b_m);
    if (!ldlt.status.ok()) {
      return Status::Error(ldlt.status.code(),
                           "the preconditioned prior's LDLT: " + ldlt.status.message());
    }
    if (sqrtStorage(storage_)) {
      next->setSqrt(P.unscaledRows(ldlt.prior.J), std::move(ldlt.prior.r));
      return Status::Ok();
    }
    const Scalar c = Scalar(0.5) * ldlt.prior.r.squaredNorm();
    if (storage_.psd != PsdProjection::kNone) psdHessian(ldlt.prior, &H_m, &b_m);
    next->setScaledHessian(std::move(H_m), std::move(b_m), c, std::move(P));
    return Status::Ok();
  }

  // The prior anchored at x⁰ in the storage. Its square root ½‖r + Jδ‖² is the LDLT of H; a
  // Hessian prior keeps its value at δ = 0 as the constant c = ½ b_mᵀ H⁺ b_m, so that both
  // storages are the same function and the flat QR's (rows without Jacobian carry no constant
  // either). The energy of the marginalized residuals themselves would grow with every
  // marginalization and loosen the relative-decrease stopping rule for the Hessian storage alone.
  Status store(HessianPrior<Scalar> marginal, const VecX<Scalar>& new_delta,
               MargPrior<Scalar>* next) const {
    VecX<Scalar> b_m = marginal.b - marginal.H * new_delta;
    LdltSqrt<Scalar> ldlt = factorize(marginal.H, b_m);
    if (!ldlt.status.ok()) {
      return hessianStorage(storage_)
                 ? Status::Error(ldlt.status.code(),
                                 "the constant of the Hessian prior: " + ldlt.status.message())
                 : ldlt.status;
    }
    if (hessianStorage(storage_)) {
      const Scalar c = Scalar(0.5) * ldlt.prior.r.squaredNorm();
      if (storage_.psd != PsdProjection::kNone) psdHessian(ldlt.prior, &marginal.H, &b_m);
      next->setHessian(std::move(marginal.H), std::move(b_m), c);
    } else {
      next->setSqrt(std::move(ldlt.prior.J), std::move(ldlt.prior.r));
    }
    return Status::Ok();
  }

  // The new prior's LDLT square root, its pivots clamped as the psd projection says.
  LdltSqrt<Scalar> factorize(const MatX<Scalar>& H, const VecX<Scalar>& b) const {
    return hessianToSqrtLdlt<Scalar>(H, b, ldltPivotFloor<Scalar>(storage_.psd, H.rows()));
  }

  // A psd projection of a Hessian prior (c, g): the Hessian of the clamped LDLT square root
  // instead of the Schur complement itself, ½‖r + Jδ‖² = c + (Jᵀr)ᵀδ + ½ δᵀ JᵀJ δ. It differs
  // from H by the rounding of the Schur complement and the pivots the LDLT set to zero: the stored
  // prior is positive semidefinite, as a square-root prior is, while the storage stays a Hessian.
  static void psdHessian(const SqrtPrior<Scalar>& sqrt, MatX<Scalar>* H, VecX<Scalar>* b) {
    *H = sqrt.J.transpose() * sqrt.J;
    *b = sqrt.J.transpose() * sqrt.r;
  }

  PriorStorage storage_;
};

}  // namespace

template <typename Scalar>
Scalar ldltPivotFloor(PsdProjection psd, Eigen::Index n) {
  return psd == PsdProjection::kGaugeExact
             ? NumericTraits<Scalar>::ldltPivotRelativeTolerance(static_cast<int>(n))
             : Scalar(0);
}

template <typename Scalar>
std::unique_ptr<Marginalizer<Scalar>> makeMarginalizer(MargMethod method,
                                                       const PriorStorage& storage,
                                                       const EstimatorSettings& config) {
  if (method == MargMethod::kQr) return std::make_unique<QrMarginalizer<Scalar>>(config);
  return std::make_unique<SchurMarginalizer<Scalar>>(storage);
}

template <typename Scalar>
Status schurSystem(const Window<Scalar>& window, const MargPlan& plan,
                   const MargPrior<Scalar>& prior, bool add_prior, SchurSystem<Scalar>* out) {
  MargProblem<Scalar> p = gatherProblem(window, plan, prior, prior.storage);
  Status s = assemble(p, prior, add_prior ? PriorTerm::kAdd : PriorTerm::kOmit, &out->H, &out->b);
  out->n_marg = p.n_marg;
  out->new_delta = std::move(p.new_delta);
  out->layout = std::move(p.next);
  return s;
}

template <typename Scalar>
Status trialMarginalization(const Window<Scalar>& window, MargPrior<Scalar> prior,
                            const MargPlan& plan, MargMethod method, MatXd* H_m) {
  const PriorStorage storage =
      method == MargMethod::kQr
          ? PriorStorage{}
          : withPsdHessianPrior({Representation::kHessian}, window.config().psd_hessian_prior);
  if (method == MargMethod::kQr && hessianStorage(prior.storage) && !prior.empty()) {
    return Status::Error(Status::Code::kInvalidArgument,
                         "qr marginalization needs a square-root prior");
  }
  Status s = makeMarginalizer<Scalar>(method, storage, window.config())
                 ->marginalize(window, plan, &prior, nullptr);
  if (!s.ok()) return s;
  if (sqrtStorage(storage)) {
    MatX<Scalar> J;
    VecX<Scalar> r;
    prior.sqrtRows(VecX<Scalar>::Zero(prior.cols()), &J, &r);
    const MatXd J_d = J.template cast<double>();
    *H_m = J_d.transpose() * J_d;
  } else {
    *H_m = prior.hessianAtAnchor().template cast<double>();
  }
  return Status::Ok();
}

#define MARGLAB_INST(S)                                                                          \
  template S ldltPivotFloor<S>(PsdProjection, Eigen::Index);                                     \
  template std::unique_ptr<Marginalizer<S>> makeMarginalizer<S>(MargMethod, const PriorStorage&, \
                                                                const EstimatorSettings&);       \
  template Status trialMarginalization<S>(const Window<S>&, MargPrior<S>, const MargPlan&,       \
                                          MargMethod, MatXd*);                                   \
  template Status schurSystem<S>(const Window<S>&, const MargPlan&, const MargPrior<S>&, bool,   \
                                 SchurSystem<S>*);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
