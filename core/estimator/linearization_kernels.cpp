// Compiled once per ISA (core/CMakeLists.txt defines MARGLAB_ISA_NS and MARGLAB_ISA_ENUM); see
// linearization_kernels.h.
#include "core/estimator/linearization_kernels.h"

#include <algorithm>
#include <type_traits>
#include <vector>

#include "core/common/scalar.h"
#include "core/estimator/system_blocks.h"
#include "core/linalg/landmark_block.h"
#include "core/linalg/rcs_solve.h"

#if !defined(MARGLAB_ISA_NS) || !defined(MARGLAB_ISA_ENUM)
#error "compiled per ISA only: core/CMakeLists.txt defines MARGLAB_ISA_NS and MARGLAB_ISA_ENUM"
#endif

namespace marglab {
namespace {

// Change of ½‖r + J s‖² along a step s of the whole system: rᵀJs + ½‖Js‖².
template <typename Scalar>
Scalar rowsModelChange(const RowBlock<Scalar>& rows, const VecX<Scalar>& step,
                       const ColumnMap& column_of) {
  const VecX<Scalar> J_step =
      rows.J * gatherBlocks<Scalar>(rows.vars, static_cast<int>(rows.J.cols()), step, column_of);
  return rows.r.dot(J_step) + Scalar(0.5) * J_step.squaredNorm();
}

template <typename Scalar, typename Block>
class LandmarkLinearization final : public Linearization<Scalar> {
 public:
  using Options = typename Linearization<Scalar>::Options;
  using BlockScalar = typename Block::Scalar;

  explicit LandmarkLinearization(const Options& options) : options_(options) {}

  void linearize(const Window<Scalar>& window) override;
  Status eliminate() override;
  Status solve(Scalar lambda, LinearStep<Scalar>* step) override;

  const ColumnMap& columns() const override { return column_of_; }
  int numColumns() const override { return n_; }
  const std::vector<LandmarkJacobians<Scalar>>& landmarks() const override { return lins_; }
  const MatX<Scalar>& reducedHessian() const override { return H_fixed_; }
  const VecX<Scalar>& reducedGradient() const override { return b_fixed_; }

 private:
  void linearizeLandmarks(const Window<Scalar>& window,
                          const typename Window<Scalar>::RelativePoses& rel);
  void addFixedTerms(const Window<Scalar>& window,
                     const typename Window<Scalar>::RelativePoses& rel);
  void addUndampedLandmarks();
  Status addDampedLandmarks(Scalar lambda);
  Status backSubstitute(const VecX<Scalar>& delta, LinearStep<Scalar>* step);
  Scalar fixedModelChange(const VecX<Scalar>& delta) const;
  Status firstError() const;

  Options options_;
  ThreadPool* pool_ = nullptr;
  std::set<int64_t> system_;
  ColumnMap column_of_;
  int n_ = 0;
  // Kept across linearizations: the Jacobians and blocks keep their storage (same sizes from one
  // linearization to the next), so the loop does not allocate per landmark.
  std::vector<LandmarkJacobians<Scalar>> lins_;
  std::vector<Block> blocks_;
  std::vector<char> active_;
  std::vector<LinkLinearized<Scalar>> links_;
  std::vector<RowBlock<Scalar>> direct_;
  const MargPrior<Scalar>* prior_ = nullptr;  // the window's; unchanged during the iterations
  VecX<Scalar> prior_delta_;
  MatX<Scalar> H_base_, H_fixed_, H_;  // fixed terms; + undamped landmarks; damped system
  VecX<Scalar> b_base_, b_fixed_, b_;
  // Per-chunk results of the pool, combined in chunk order (deterministic for a thread count).
  std::vector<Status> chunk_status_;
  std::vector<Scalar> chunk_change_;
  std::vector<MatX<Scalar>> chunk_H_;
  std::vector<VecX<Scalar>> chunk_b_;
};

template <typename Scalar, typename Block>
void LandmarkLinearization<Scalar, Block>::linearize(const Window<Scalar>& window) {
  pool_ = &window.pool();
  const size_t n_chunks = static_cast<size_t>(pool_->threads());
  chunk_status_.assign(n_chunks, Status::Ok());
  chunk_change_.assign(n_chunks, Scalar(0));
  chunk_H_.resize(n_chunks - 1);
  chunk_b_.resize(n_chunks - 1);
  system_.clear();
  for (const auto& [id, frame] : window.frames) system_.insert(id);
  column_of_.clear();
  n_ = window.windowColumns(&column_of_);
  const typename Window<Scalar>::RelativePoses rel = window.relativePoses(WithJacobians::kYes);
  linearizeLandmarks(window, rel);
  addFixedTerms(window, rel);
}

template <typename Scalar, typename Block>
void LandmarkLinearization<Scalar, Block>::linearizeLandmarks(
    const Window<Scalar>& window, const typename Window<Scalar>::RelativePoses& rel) {
  using Landmark = typename Window<Scalar>::Landmark;
  const std::set<int64_t> reduced = window.priorLandmarks();
  std::vector<std::pair<int64_t, const Landmark*>> lms;
  for (const auto& [id, lm] : window.landmarks) {
    if (reduced.count(id) == 0) lms.emplace_back(id, &lm);
  }
  lins_.resize(lms.size());
  std::vector<char> linearized(lms.size(), 0);
  pool_->forChunks(lms.size(), [&](size_t begin, size_t end, int) {
    for (size_t i = begin; i < end; ++i) {
      linearized[i] =
          window.linearizeLandmark(lms[i].first, *lms[i].second, system_, rel, &lins_[i]);
    }
  });
  size_t n_lins = 0;
  for (size_t i = 0; i < lins_.size(); ++i) {
    if (!linearized[i]) continue;
    if (i != n_lins) std::swap(lins_[n_lins], lins_[i]);
    ++n_lins;
  }
  lins_.resize(n_lins);
}

template <typename Scalar, typename Block>
void LandmarkLinearization<Scalar, Block>::addFixedTerms(
    const Window<Scalar>& window, const typename Window<Scalar>::RelativePoses& rel) {
  H_base_ = MatX<Scalar>::Zero(n_, n_);
  b_base_ = VecX<Scalar>::Zero(n_);
  links_.clear();
  for (const auto& [from, link] : window.imu_links) {
    links_.push_back(window.linearizeLink(from, link));
    addRows(links_.back(), links_.back().vars(), column_of_, H_base_, b_base_);
  }
  direct_ = window.directRows(system_, rel);
  for (const RowBlock<Scalar>& rows : direct_)
    addRows(rows, rows.vars, column_of_, H_base_, b_base_);
  prior_ = window.prior.empty() ? nullptr : &window.prior;
  if (prior_ != nullptr) {
    prior_delta_ = window.priorDelta(*prior_);
    addPrior(*prior_, prior_delta_, column_of_, H_base_, b_base_);
  }
}

// The Jacobians in the block's precision: a reference when it is the system's, else a per-thread
// copy.
template <typename To, typename Matrix>
decltype(auto) inPrecision(const Matrix& m) {
  if constexpr (std::is_same_v<typename Matrix::Scalar, To>) {
    return (m);
  } else {
    thread_local Eigen::Matrix<To, Matrix::RowsAtCompileTime, Matrix::ColsAtCompileTime> copy;
    copy = m.template cast<To>();
    return static_cast<const decltype(copy)&>(copy);
  }
}

// x itself when the precisions agree, else its cast.
template <typename T, typename U>
const U& select(const T& x, const U& cast) {
  if constexpr (std::is_same_v<T, U>) {
    return x;
  } else {
    return cast;
  }
}

template <typename Scalar, typename Block>
Status LandmarkLinearization<Scalar, Block>::eliminate() {
  blocks_.resize(std::max(blocks_.size(), lins_.size()));
  std::fill(chunk_status_.begin(), chunk_status_.end(), Status::Ok());
  pool_->forChunks(lins_.size(), [&](size_t begin, size_t end, int chunk) {
    for (size_t l = begin; l < end; ++l) {
      const LandmarkJacobians<Scalar>& lin = lins_[l];
      Status s = blocks_[l].setFromJacobians(
          inPrecision<BlockScalar>(lin.J_p), inPrecision<BlockScalar>(lin.J_l),
          inPrecision<BlockScalar>(lin.r), blockMap(lin, column_of_));
      if (!s.ok()) {
        chunk_status_[static_cast<size_t>(chunk)] = s;
        return;
      }
    }
  });
  if (Status s = firstError(); !s.ok()) return s;
  H_fixed_ = H_base_;
  b_fixed_ = b_base_;
  active_.assign(lins_.size(), 1);
  if (!options_.damp_landmarks) addUndampedLandmarks();
  return Status::Ok();
}

template <typename Scalar, typename Block>
void LandmarkLinearization<Scalar, Block>::addUndampedLandmarks() {
  // Chunk 0 adds into the system itself, the others into their own, summed in chunk order.
  for (size_t c = 1; c <= chunk_H_.size(); ++c) {
    chunk_H_[c - 1].setZero(n_, n_);
    chunk_b_[c - 1].setZero(n_);
  }
  pool_->forChunks(lins_.size(), [&](size_t begin, size_t end, int chunk) {
    MatX<Scalar>& H = chunk == 0 ? H_fixed_ : chunk_H_[static_cast<size_t>(chunk) - 1];
    VecX<Scalar>& b = chunk == 0 ? b_fixed_ : chunk_b_[static_cast<size_t>(chunk) - 1];
    for (size_t l = begin; l < end; ++l) active_[l] = blocks_[l].addToReducedSystem(H, b).ok();
  });
  for (size_t c = 1; c <= chunk_H_.size(); ++c) {
    H_fixed_ += chunk_H_[c - 1];
    b_fixed_ += chunk_b_[c - 1];
  }
}

template <typename Scalar, typename Block>
Status LandmarkLinearization<Scalar, Block>::addDampedLandmarks(Scalar lambda) {
  const BlockScalar lambda_b = static_cast<BlockScalar>(lambda);
  const BlockScalar lambda_min_b = static_cast<BlockScalar>(options_.lambda_min);
  Status status = Status::Ok();
  for (size_t l = 0; l < lins_.size(); ++l) {
    Block& block = blocks_[l];
    Vec3<BlockScalar> d;
    for (int i = 0; i < 3; ++i) {
      d[i] = lmDamping(block.landmarkHessianDiagonal()[i], lambda_b, lambda_min_b);
    }
    block.setLandmarkDamping(d);
    if (status.ok()) status = block.addToReducedSystem(H_, b_);
  }
  return status;
}

template <typename Scalar, typename Block>
Status LandmarkLinearization<Scalar, Block>::solve(Scalar lambda, LinearStep<Scalar>* step) {
  H_ = H_fixed_;
  b_ = b_fixed_;
  Status status = Status::Ok();
  if (options_.damp_landmarks && !lins_.empty()) status = addDampedLandmarks(lambda);
  if (status.ok()) {
    DampedSolve<Scalar> solve = solveDampedLdlt<Scalar>(
        H_, b_, lambda, options_.lambda_min, options_.preconditioning, options_.solve_indefinite);
    status = solve.status;
    step->delta = std::move(solve.delta);
  }
  if (status.ok()) status = backSubstitute(step->delta, step);
  if (!status.ok()) return status;
  step->model_change = fixedModelChange(step->delta);
  return Status::Ok();
}

template <typename Scalar, typename Block>
Status LandmarkLinearization<Scalar, Block>::backSubstitute(const VecX<Scalar>& delta,
                                                            LinearStep<Scalar>* step) {
  step->delta_l.assign(lins_.size(), Vec3<Scalar>::Zero());
  std::fill(chunk_change_.begin(), chunk_change_.end(), Scalar(0));
  std::fill(chunk_status_.begin(), chunk_status_.end(), Status::Ok());
  // The step in the blocks' precision, cast once for all landmarks.
  VecX<BlockScalar> delta_cast;
  if constexpr (!std::is_same_v<BlockScalar, Scalar>)
    delta_cast = delta.template cast<BlockScalar>();
  const VecX<BlockScalar>& delta_b = select(delta, delta_cast);
  pool_->forChunks(lins_.size(), [&](size_t begin, size_t end, int chunk) {
    const size_t c = static_cast<size_t>(chunk);
    for (size_t l = begin; l < end; ++l) {
      if (!active_[l]) continue;
      Vec3<BlockScalar> delta_l;
      Status s = blocks_[l].backSubstitute(delta_b, &delta_l);
      if (!s.ok()) {
        chunk_status_[c] = s;
        return;
      }
      step->delta_l[l] = delta_l.template cast<Scalar>();
      chunk_change_[c] += static_cast<Scalar>(blocks_[l].linearizedCostChange(delta_b, delta_l));
    }
  });
  return firstError();
}

template <typename Scalar, typename Block>
Scalar LandmarkLinearization<Scalar, Block>::fixedModelChange(const VecX<Scalar>& delta) const {
  Scalar model_change = 0;
  for (const Scalar change : chunk_change_) model_change += change;
  for (const LinkLinearized<Scalar>& lin : links_) {
    const Vec<Scalar, 15> J_step = lin.J * gatherBlocks<Scalar>(lin.vars(), 30, delta, column_of_);
    model_change += lin.r.dot(J_step) + Scalar(0.5) * J_step.squaredNorm();
  }
  for (const RowBlock<Scalar>& rows : direct_) {
    model_change += rowsModelChange<Scalar>(rows, delta, column_of_);
  }
  if (prior_ != nullptr) {
    model_change += prior_->costChange(
        prior_delta_, gatherBlocks<Scalar>(priorVars(*prior_), prior_->cols(), delta, column_of_));
  }
  return model_change;
}

template <typename Scalar, typename Block>
Status LandmarkLinearization<Scalar, Block>::firstError() const {
  for (const Status& s : chunk_status_) {
    if (!s.ok()) return s;
  }
  return Status::Ok();
}

template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> ofElimination(
    OptElimination elimination, const typename Linearization<Scalar>::Options& options) {
  if (elimination == OptElimination::kNullspace) {
    return std::make_unique<LandmarkLinearization<Scalar, LandmarkBlockNs<Scalar>>>(options);
  }
  return std::make_unique<LandmarkLinearization<Scalar, LandmarkBlockSc<Scalar>>>(options);
}

template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> ofVariant(
    const Variant& variant, const typename Linearization<Scalar>::Options& options) {
#if defined(MARGLAB_WITH_FLOAT)
  if constexpr (std::is_same_v<Scalar, double>) {
    if (variant.precision == Precision::kMixed) {
      return std::make_unique<LandmarkLinearization<double, LandmarkBlockNs<float>>>(options);
    }
  }
#endif
  return ofElimination<Scalar>(variant.opt, options);
}

template <typename Scalar>
bool landmarkQr(const std::vector<LandmarkJacobians<Scalar>>& lins,
                const std::vector<PoseBlockMap>& maps) {
  thread_local LandmarkBlockNs<Scalar> block;
  for (size_t i = 0; i < lins.size(); ++i) {
    if (!block.setFromJacobians(lins[i].J_p, lins[i].J_l, lins[i].r, maps[i]).ok()) return false;
  }
  return true;
}

template <typename Scalar>
LinearizationKernels<Scalar> kernelsIn() {
  LinearizationKernels<Scalar> k;
  k.of_variant = &ofVariant<Scalar>;
  k.of_elimination = &ofElimination<Scalar>;
  k.landmark_qr = &landmarkQr<Scalar>;
  return k;
}

IsaKernels makeKernels() {
  IsaKernels k;
  k.isa = Isa::MARGLAB_ISA_ENUM;
#if defined(MARGLAB_WITH_FLOAT)
  k.f32 = kernelsIn<float>();
  k.ba_f32 = baKernelsIn<float>();
#endif
  k.f64 = kernelsIn<double>();
  k.ba_f64 = baKernelsIn<double>();
  return k;
}

}  // namespace

namespace MARGLAB_ISA_NS {

const IsaKernels& kernels() {
  static const IsaKernels k = makeKernels();
  return k;
}

}  // namespace MARGLAB_ISA_NS
}  // namespace marglab
