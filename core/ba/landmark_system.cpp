// Compiled per ISA only (core/isa_kernels.cmake): reached through makeBaLinearSystem.
#include "core/ba/landmark_system.h"

#include <fmt/core.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <functional>
#include <limits>
#include <type_traits>

#include "core/common/scalar.h"
#include "core/common/thread_pool.h"
#include "core/linalg/landmark_block.h"
#include "core/linalg/landmark_block_implicit.h"

#if !defined(MARGLAB_ISA_NS)
#error "compiled per ISA only: core/isa_kernels.cmake defines MARGLAB_ISA_NS"
#endif

namespace marglab {
namespace {

template <typename Block>
class LandmarkSystem final : public BaLinearSystem<typename Block::Scalar> {
 public:
  using Scalar = typename Block::Scalar;
  LandmarkSystem(const BalProblem& problem, ThreadPool* pool);

  Status linearize(const BalState<Scalar>& state, const RobustLoss& loss) override;
  Status solve(Scalar lambda, const CgOptions& cg, BaStep<Scalar>* step) override;
  int numFixedPoints() const override { return num_fixed_points_; }
  Status denseReducedSystem(MatX<Scalar>* S, VecX<Scalar>* g) const override;

 private:
  struct ObservationRows;
  // Where each camera's 9 entries sit in the landmarks' local vectors (a block's 9n entries at
  // local_offset_ of the block, camera slot j at +9j), in landmark order: the per-camera sums
  // (gradient, CG product, preconditioner) add the landmarks' terms in the order of the serial
  // loop, so every thread count gives the same bits.
  struct CameraSlot {
    int block, slot;
    Eigen::Index position;
  };
  void indexBlocks();
  Status observationRows(const BalState<Scalar>& state, const RobustLoss& loss,
                         std::vector<ObservationRows>* rows) const;
  void cameraColumnScaling(const std::vector<ObservationRows>& rows);
  // Scratch of one thread's local products, sized once for the longest track (no allocation per
  // landmark and product).
  struct LocalScratch {
    VecX<Scalar> x, t, y;
  };
  // local(block, scratch, y) writes the block's 9n entries to y (its segment of local_), for every
  // block in parallel; then out_c += the camera's slots, in landmark order.
  template <typename LocalFn>
  void gatherOverCameras(const LocalFn& local, VecX<Scalar>* out) const;
  VecX<Scalar> nullspaceGradient() const;
  void addNullspaceCameraBlocks(std::vector<Mat<Scalar, 9, 9>>* D) const;
  void addNullspaceProduct(const VecX<Scalar>& x, VecX<Scalar>* Ax) const;
  Status reducedSystemInChunks(MatX<Scalar>* S, VecX<Scalar>* g) const;
  Status setBlock(size_t b, const std::vector<ObservationRows>& rows);
  // The 9×9 camera blocks of S + λI (ns: from the reduced rows; sc: from S).
  std::vector<Mat<Scalar, 9, 9>> cameraBlocks(Scalar lambda, const MatX<Scalar>& S) const;
  Status backSubstitute(const VecX<Scalar>& x, BaStep<Scalar>* step) const;
  CgOperators<Scalar> operators(Scalar lambda, const MatX<Scalar>& S,
                                const std::vector<Mat<Scalar, 9, 9>>& M_inverse) const;

  const BalProblem& problem_;
  ThreadPool* pool_;
  std::vector<std::vector<int>> point_observations_;  // observation indices of each point
  std::vector<int> point_block_;                      // block index of a point, −1 when fixed
  std::vector<int> block_point_;                      // point of each block
  std::vector<PoseBlockMap> block_maps_;              // cameras of each block
  std::vector<Eigen::Index> local_offset_;            // of each block in local_
  Eigen::Index max_track_ = 0;                        // the most observations of a block
  std::vector<std::vector<CameraSlot>> camera_slots_;
  std::vector<ObservationRows> rows_;  // of the last linearization, storage kept
  mutable VecX<Scalar> local_;  // the blocks' local vectors (9n each), reused by every product
  mutable std::vector<MatX<Scalar>> chunk_S_;  // sc: the reduction chunks 1, 2, ... (0 adds to S)
  mutable std::vector<VecX<Scalar>> chunk_g_;
  std::vector<Block> blocks_;
  std::vector<Vec3<Scalar>> point_scaling_;
  VecX<Scalar> camera_scaling_;
  int num_fixed_points_ = 0;
};

template <typename Block>
struct LandmarkSystem<Block>::ObservationRows {
  Mat<Scalar, 2, 9> J_camera;
  Mat<Scalar, 2, 3> J_point;
  Vec<Scalar, 2> r;
};

template <typename Block>
constexpr bool kIsImplicit =
    std::is_same_v<Block, LandmarkBlockNsImplicit<typename Block::Scalar, kBalCameraDim>>;
template <typename Block>
constexpr bool kIsNullspace =
    kIsImplicit<Block> || std::is_same_v<Block, LandmarkBlockNs<typename Block::Scalar>>;

// 1 / (ε + ‖column‖), ε of the scalar (rootba's jacobi_scaling_epsilon = 0 default).
template <typename Scalar, typename Derived>
auto inverseColumnScale(const Eigen::ArrayBase<Derived>& squared_norms) {
  return (NumericTraits<Scalar>::kEpsilon + squared_norms.sqrt()).inverse();
}

// fn(i) for every i in [0, n) on the pool's threads; the failure of the smallest i (the pool's
// chunks are contiguous and in order), the same for every thread count.
Status forEachIndex(ThreadPool& pool, size_t n, const std::function<Status(size_t)>& fn) {
  std::vector<Status> first(static_cast<size_t>(pool.threads()), Status::Ok());
  pool.forChunks(n, [&](size_t begin, size_t end, int chunk) {
    for (size_t i = begin; i < end; ++i) {
      Status status = fn(i);
      if (!status.ok()) {
        first[static_cast<size_t>(chunk)] = std::move(status);
        return;
      }
    }
  });
  for (Status& status : first) {
    if (!status.ok()) return status;
  }
  return Status::Ok();
}

// sc's reduced system is summed in this many fixed chunks of landmarks, each into its own S, then
// in chunk order: the result depends on the chunks only, not on the threads running them.
constexpr size_t kReductionChunks = 8;

template <typename Block>
LandmarkSystem<Block>::LandmarkSystem(const BalProblem& problem, ThreadPool* pool)
    : problem_(problem), pool_(pool) {
  point_observations_.resize(problem.points.size());
  for (int i = 0; i < problem.numObservations(); ++i) {
    point_observations_[problem.observations[i].point].push_back(i);
  }
  indexBlocks();
}

// A point seen only once (2 rows for 3 unknowns) cannot be eliminated: it stays fixed.
template <typename Block>
void LandmarkSystem<Block>::indexBlocks() {
  point_block_.assign(problem_.points.size(), -1);
  camera_slots_.assign(problem_.cameras.size(), {});
  Eigen::Index offset = 0;
  for (size_t l = 0; l < point_observations_.size(); ++l) {
    const std::vector<int>& obs = point_observations_[l];
    if (obs.size() < 2) {
      ++num_fixed_points_;
      continue;
    }
    const int block = static_cast<int>(block_point_.size());
    point_block_[l] = block;
    block_point_.push_back(static_cast<int>(l));
    local_offset_.push_back(offset);
    PoseBlockMap& map = block_maps_.emplace_back();
    map.pose_dim = kBalCameraDim;
    for (size_t j = 0; j < obs.size(); ++j) {
      map.rcs_offset.push_back(kBalCameraDim * problem_.observations[obs[j]].camera);
      camera_slots_[problem_.observations[obs[j]].camera].push_back(
          {block, static_cast<int>(j), offset + kBalCameraDim * static_cast<Eigen::Index>(j)});
    }
    offset += kBalCameraDim * static_cast<Eigen::Index>(obs.size());
    max_track_ = std::max(max_track_, static_cast<Eigen::Index>(obs.size()));
  }
  local_.resize(offset);
}

template <typename Block>
Status LandmarkSystem<Block>::linearize(const BalState<Scalar>& state, const RobustLoss& loss) {
  std::vector<ObservationRows>& rows = rows_;
  rows.resize(problem_.observations.size());
  Status status = observationRows(state, loss, &rows);
  if (!status.ok()) return status;
  cameraColumnScaling(rows);
  blocks_.resize(block_point_.size());  // every block is set anew; their storage is kept
  point_scaling_.assign(problem_.points.size(), Vec3<Scalar>::Zero());
  return forEachIndex(*pool_, blocks_.size(), [&](size_t b) { return setBlock(b, rows); });
}

template <typename Block>
Status LandmarkSystem<Block>::observationRows(const BalState<Scalar>& state, const RobustLoss& loss,
                                              std::vector<ObservationRows>* rows) const {
  return forEachIndex(*pool_, rows->size(), [&](size_t i) {
    const BalObservation& obs = problem_.observations[i];
    ObservationRows& row = (*rows)[i];
    snavelyResidual<Scalar>(state.cameras[obs.camera], state.points[obs.point],
                            obs.z.cast<Scalar>(), &row.r, &row.J_camera, &row.J_point);
    const Scalar sqrt_w = loss.costAndSqrtWeight(row.r.squaredNorm()).second;
    row.r *= sqrt_w;
    row.J_camera *= sqrt_w;
    row.J_point *= sqrt_w;
    if (!row.r.allFinite() || !row.J_camera.allFinite() || !row.J_point.allFinite()) {
      return Status::Error(Status::Code::kNotFinite,
                           fmt::format("observation {}: non-finite residual or Jacobian", i));
    }
    return Status::Ok();
  });
}

template <typename Block>
void LandmarkSystem<Block>::cameraColumnScaling(const std::vector<ObservationRows>& rows) {
  Eigen::Array<Scalar, Eigen::Dynamic, 1> squared =
      Eigen::Array<Scalar, Eigen::Dynamic, 1>::Zero(kBalCameraDim * problem_.numCameras());
  for (size_t i = 0; i < rows.size(); ++i) {
    squared.template segment<kBalCameraDim>(kBalCameraDim * problem_.observations[i].camera) +=
        rows[i].J_camera.colwise().squaredNorm().transpose().array();
  }
  camera_scaling_ = inverseColumnScale<Scalar>(squared).matrix();
}

template <typename Block>
Status LandmarkSystem<Block>::setBlock(size_t b, const std::vector<ObservationRows>& rows) {
  const int point = block_point_[b];
  const std::vector<int>& obs = point_observations_[point];
  const int n = static_cast<int>(obs.size());
  const Eigen::Index m = 2 * n;
  // The implicit block takes each observation's 2 × 9 rows stacked; the explicit one the dense
  // J_p over the landmark's cameras. Per-thread buffers for the longest track, kept.
  const Eigen::Index max_cols = kIsImplicit<Block> ? kBalCameraDim : kBalCameraDim * max_track_;
  thread_local MatX<Scalar> J_p_buffer;
  thread_local Mat<Scalar, Eigen::Dynamic, 3> J_l_buffer;
  thread_local VecX<Scalar> r_buffer;
  if (J_p_buffer.rows() < 2 * max_track_ || J_p_buffer.cols() < max_cols) {
    J_p_buffer.resize(2 * max_track_, max_cols);
    J_l_buffer.resize(2 * max_track_, 3);
    r_buffer.resize(2 * max_track_);
  }
  auto J_p = J_p_buffer.topLeftCorner(m, kIsImplicit<Block> ? kBalCameraDim : kBalCameraDim * n);
  auto J_l = J_l_buffer.topRows(m);
  auto r = r_buffer.head(m);
  J_p.setZero();
  for (int j = 0; j < n; ++j) {
    const int camera = problem_.observations[obs[j]].camera;
    J_p.template block<2, kBalCameraDim>(2 * j, kIsImplicit<Block> ? 0 : kBalCameraDim * j) =
        rows[obs[j]].J_camera *
        camera_scaling_.template segment<kBalCameraDim>(kBalCameraDim * camera).asDiagonal();
    J_l.template middleRows<2>(2 * j) = rows[obs[j]].J_point;
    r.template segment<2>(2 * j) = rows[obs[j]].r;
  }
  point_scaling_[point] =
      inverseColumnScale<Scalar>(J_l.colwise().squaredNorm().array()).transpose();
  J_l *= point_scaling_[point].asDiagonal();
  if constexpr (kIsImplicit<Block>) {
    return blocks_[b].setFromJacobians(J_p, J_l, r, block_maps_[b]);
  } else {
    return blocks_[b].setFromJacobians(MatX<Scalar>(J_p), Mat<Scalar, Eigen::Dynamic, 3>(J_l),
                                       VecX<Scalar>(r), block_maps_[b]);
  }
}

template <typename Block>
template <typename LocalFn>
void LandmarkSystem<Block>::gatherOverCameras(const LocalFn& local, VecX<Scalar>* out) const {
  pool_->forChunks(blocks_.size(), [&](size_t begin, size_t end, int) {
    LocalScratch scratch{VecX<Scalar>(kBalCameraDim * max_track_), VecX<Scalar>(2 * max_track_ + 3),
                         VecX<Scalar>(kBalCameraDim * max_track_)};
    for (size_t b = begin; b < end; ++b) {
      const Eigen::Index n =
          kBalCameraDim * static_cast<Eigen::Index>(blocks_[b].map().rcs_offset.size());
      // The explicit block's products go through the scratch (aligned, as Eigen's kernels have
      // always seen them); the implicit one writes its slots in place.
      local(blocks_[b], scratch, local_.segment(local_offset_[b], n));
    }
  });
  pool_->forChunks(camera_slots_.size(), [&](size_t begin, size_t end, int) {
    for (size_t c = begin; c < end; ++c) {
      for (const CameraSlot& slot : camera_slots_[c]) {
        out->template segment<kBalCameraDim>(kBalCameraDim * static_cast<Eigen::Index>(c)) +=
            local_.template segment<kBalCameraDim>(slot.position);
      }
    }
  });
}

// ns: g = Σ_l (Q2ᵀJ_p)ᵀ Q2ᵀr over each landmark's reduced rows.
template <typename Block>
VecX<typename Block::Scalar> LandmarkSystem<Block>::nullspaceGradient() const {
  VecX<Scalar> g = VecX<Scalar>::Zero(camera_scaling_.size());
  gatherOverCameras(
      [](const Block& block, LocalScratch& s, auto y) {
        if constexpr (kIsImplicit<Block>) {
          block.reducedGradient(y.data());
        } else {
          s.y.head(y.size()).noalias() = block.reducedJp().transpose() * block.reducedR();
          y = s.y.head(y.size());
        }
      },
      &g);
  return g;
}

// ns: D_c += (Q2ᵀJ_p)_cᵀ (Q2ᵀJ_p)_c, the camera blocks of S from the reduced rows, each camera's
// in landmark order.
template <typename Block>
void LandmarkSystem<Block>::addNullspaceCameraBlocks(std::vector<Mat<Scalar, 9, 9>>* D) const {
  pool_->forChunks(camera_slots_.size(), [&](size_t begin, size_t end, int) {
    for (size_t c = begin; c < end; ++c) {
      for (const CameraSlot& slot : camera_slots_[c]) {
        const Block& block = blocks_[static_cast<size_t>(slot.block)];
        if constexpr (kIsImplicit<Block>) {
          (*D)[c] += block.reducedCameraBlock(slot.slot);
        } else {
          const auto Jr_j = block.reducedJp().middleCols(kBalCameraDim * slot.slot, kBalCameraDim);
          (*D)[c].noalias() += Jr_j.transpose() * Jr_j;
        }
      }
    }
  });
}

// ns, matrix-free: Ax += Σ_l (Q2ᵀJ_p)ᵀ((Q2ᵀJ_p) x_l), never forming S.
template <typename Block>
void LandmarkSystem<Block>::addNullspaceProduct(const VecX<Scalar>& x, VecX<Scalar>* Ax) const {
  gatherOverCameras(
      [&x](const Block& block, LocalScratch& s, auto y) {
        if constexpr (kIsImplicit<Block>) {
          block.reducedProduct(x, s.t.data(), y.data());
        } else {
          const std::vector<int>& offsets = block.map().rcs_offset;
          for (size_t j = 0; j < offsets.size(); ++j) {
            s.x.template segment<kBalCameraDim>(kBalCameraDim * j) =
                x.template segment<kBalCameraDim>(offsets[j]);
          }
          const auto Jr = block.reducedJp();
          s.t.head(Jr.rows()).noalias() = Jr * s.x.head(Jr.cols());
          s.y.head(Jr.cols()).noalias() = Jr.transpose() * s.t.head(Jr.rows());
          y = s.y.head(y.size());
        }
      },
      Ax);
}

template <typename Block>
auto LandmarkSystem<Block>::cameraBlocks(Scalar lambda, const MatX<Scalar>& S) const
    -> std::vector<Mat<Scalar, 9, 9>> {
  std::vector<Mat<Scalar, 9, 9>> D(problem_.cameras.size(), lambda * Mat<Scalar, 9, 9>::Identity());
  if constexpr (kIsNullspace<Block>) {
    addNullspaceCameraBlocks(&D);
  } else {
    for (size_t c = 0; c < D.size(); ++c) {
      D[c] += S.template block<kBalCameraDim, kBalCameraDim>(kBalCameraDim * c, kBalCameraDim * c);
    }
  }
  return D;
}

template <typename Block>
Status LandmarkSystem<Block>::denseReducedSystem(MatX<Scalar>* S, VecX<Scalar>* g) const {
  const Eigen::Index n = camera_scaling_.size();
  S->setZero(n, n);
  g->setZero(n);
  chunk_S_.resize(kReductionChunks - 1);
  chunk_g_.resize(kReductionChunks - 1);
  std::vector<Status> status(kReductionChunks, Status::Ok());
  const size_t num_blocks = blocks_.size();
  pool_->forChunks(kReductionChunks, [&](size_t begin, size_t end, int) {
    for (size_t k = begin; k < end; ++k) {
      if (k > 0) {
        chunk_S_[k - 1].setZero(n, n);
        chunk_g_[k - 1].setZero(n);
      }
      MatX<Scalar>& S_k = k == 0 ? *S : chunk_S_[k - 1];
      VecX<Scalar>& g_k = k == 0 ? *g : chunk_g_[k - 1];
      for (size_t b = k * num_blocks / kReductionChunks;
           b < (k + 1) * num_blocks / kReductionChunks && status[k].ok(); ++b) {
        status[k] = blocks_[b].addToReducedSystem(S_k, g_k);
      }
    }
  });
  for (size_t k = 0; k < kReductionChunks; ++k) {
    if (!status[k].ok()) return status[k];
    if (k > 0) {
      *S += chunk_S_[k - 1];
      *g += chunk_g_[k - 1];
    }
  }
  return Status::Ok();
}

template <typename Block>
auto LandmarkSystem<Block>::operators(Scalar lambda, const MatX<Scalar>& S,
                                      const std::vector<Mat<Scalar, 9, 9>>& M_inverse) const
    -> CgOperators<Scalar> {
  CgOperators<Scalar> ops;
  ops.apply_M_inverse = [&M_inverse](const VecX<Scalar>& r, VecX<Scalar>* z) {
    z->resize(r.size());
    for (size_t c = 0; c < M_inverse.size(); ++c) {
      z->template segment<kBalCameraDim>(kBalCameraDim * c).noalias() =
          M_inverse[c] * r.template segment<kBalCameraDim>(kBalCameraDim * c);
    }
  };
  if constexpr (kIsNullspace<Block>) {
    ops.apply_A = [this, lambda](const VecX<Scalar>& x, VecX<Scalar>* Ax) {
      *Ax = lambda * x;
      addNullspaceProduct(x, Ax);
    };
  } else {
    ops.apply_A = [&S, lambda](const VecX<Scalar>& x, VecX<Scalar>* Ax) {
      Ax->noalias() = S * x;
      *Ax += lambda * x;
    };
  }
  return ops;
}

// The inverses of the Schur-Jacobi blocks, by Cholesky in the system's precision.
template <typename Scalar>
Status invertCameraBlocks(std::vector<Mat<Scalar, 9, 9>>* blocks) {
  for (size_t c = 0; c < blocks->size(); ++c) {
    Eigen::LLT<Mat<Scalar, 9, 9>> llt((*blocks)[c]);
    if (llt.info() != Eigen::Success) {
      return Status::Error(Status::Code::kSolveFailed,
                           fmt::format("Schur-Jacobi preconditioner: the block of camera {} is "
                                       "not positive definite in {}",
                                       c, NumericTraits<Scalar>::name()));
    }
    (*blocks)[c] = llt.solve(Mat<Scalar, 9, 9>::Identity());
  }
  return Status::Ok();
}

template <typename Block>
Status LandmarkSystem<Block>::solve(Scalar lambda, const CgOptions& cg, BaStep<Scalar>* step) {
  pool_->forChunks(blocks_.size(), [&](size_t begin, size_t end, int) {
    for (size_t b = begin; b < end; ++b) {
      blocks_[b].setLandmarkDamping(Vec3<Scalar>::Constant(lambda));
    }
  });
  MatX<Scalar> S;
  VecX<Scalar> g;
  if constexpr (kIsNullspace<Block>) {
    g = nullspaceGradient();
  } else {
    Status status = denseReducedSystem(&S, &g);
    if (!status.ok()) return status;
  }
  std::vector<Mat<Scalar, 9, 9>> M_inverse = cameraBlocks(lambda, S);
  Status status = invertCameraBlocks(&M_inverse);
  if (!status.ok()) return status;
  VecX<Scalar> x;
  status = preconditionedCg(operators(lambda, S, M_inverse), VecX<Scalar>(-g), cg, &x, &step->cg);
  if (!status.ok()) return status;
  return backSubstitute(x, step);
}

template <typename Block>
Status LandmarkSystem<Block>::backSubstitute(const VecX<Scalar>& x, BaStep<Scalar>* step) const {
  step->delta_cameras.resize(problem_.cameras.size());
  for (size_t c = 0; c < step->delta_cameras.size(); ++c) {
    step->delta_cameras[c] =
        camera_scaling_.template segment<kBalCameraDim>(kBalCameraDim * c)
            .cwiseProduct(x.template segment<kBalCameraDim>(kBalCameraDim * c));
  }
  step->delta_points.assign(problem_.points.size(), Vec3<Scalar>::Zero());
  std::vector<double> change(blocks_.size());
  const Status status = forEachIndex(*pool_, blocks_.size(), [&](size_t b) {
    const int l = block_point_[b];
    Vec3<Scalar> delta_l;
    Status s = blocks_[b].backSubstitute(x, &delta_l);
    if (!s.ok()) return s;
    change[b] = double(blocks_[b].linearizedCostChange(x, delta_l));
    step->delta_points[l] = point_scaling_[l].cwiseProduct(delta_l);
    return Status::Ok();
  });
  if (!status.ok()) return status;
  step->model_change = 0;
  for (const double c : change) step->model_change += c;  // in landmark order
  return Status::Ok();
}

template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeSystem(const BalProblem& problem,
                                                   BaElimination elimination, ThreadPool& pool) {
  if (elimination == BaElimination::kNullspace) {
    return std::make_unique<LandmarkSystem<LandmarkBlockNsImplicit<Scalar, kBalCameraDim>>>(problem,
                                                                                            &pool);
  }
  if (elimination == BaElimination::kNullspaceExplicit) {
    return std::make_unique<LandmarkSystem<LandmarkBlockNs<Scalar>>>(problem, &pool);
  }
  return std::make_unique<LandmarkSystem<LandmarkBlockSc<Scalar>>>(problem, &pool);
}

}  // namespace

template <typename Scalar>
BaKernels<Scalar> baKernelsIn() {
  BaKernels<Scalar> k;
  k.make_system = &makeSystem<Scalar>;
  return k;
}

template BaKernels<double> baKernelsIn<double>();
#if defined(MARGLAB_WITH_FLOAT)
template BaKernels<float> baKernelsIn<float>();
#endif

}  // namespace marglab
