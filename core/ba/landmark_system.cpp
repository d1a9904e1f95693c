// Compiled per ISA only (core/isa_kernels.cmake): reached through makeBaLinearSystem.
#include "core/ba/landmark_system.h"

#include <fmt/core.h>

#include <Eigen/Cholesky>
#include <limits>
#include <type_traits>

#include "core/common/scalar.h"
#include "core/linalg/landmark_block.h"

#if !defined(MARGLAB_ISA_NS)
#error "compiled per ISA only: core/isa_kernels.cmake defines MARGLAB_ISA_NS"
#endif

namespace marglab {
namespace {

template <typename Block>
class LandmarkSystem final : public BaLinearSystem<typename Block::Scalar> {
 public:
  using Scalar = typename Block::Scalar;
  explicit LandmarkSystem(const BalProblem& problem);

  Status linearize(const BalState<Scalar>& state, const RobustLoss& loss) override;
  Status solve(Scalar lambda, const CgOptions& cg, BaStep<Scalar>* step) override;
  int numFixedPoints() const override { return num_fixed_points_; }
  Status denseReducedSystem(MatX<Scalar>* S, VecX<Scalar>* g) const override;

 private:
  struct ObservationRows;
  void cameraColumnScaling(const std::vector<ObservationRows>& rows);
  Status setBlock(int point, const std::vector<ObservationRows>& rows, Block* block);
  // The 9×9 camera blocks of S + λI (ns: from the reduced rows; sc: from S).
  std::vector<Mat<Scalar, 9, 9>> cameraBlocks(Scalar lambda, const MatX<Scalar>& S) const;
  Status backSubstitute(const VecX<Scalar>& x, BaStep<Scalar>* step) const;
  CgOperators<Scalar> operators(Scalar lambda, const MatX<Scalar>& S,
                                const std::vector<Mat<Scalar, 9, 9>>& M_inverse) const;

  const BalProblem& problem_;
  std::vector<std::vector<int>> point_observations_;  // observation indices of each point
  std::vector<int> point_block_;                      // block index of a point, −1 when fixed
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
constexpr bool kIsNullspace = std::is_same_v<Block, LandmarkBlockNs<typename Block::Scalar>>;

// 1 / (ε + ‖column‖), ε of the scalar (rootba's jacobi_scaling_epsilon = 0 default).
template <typename Scalar, typename Derived>
auto inverseColumnScale(const Eigen::ArrayBase<Derived>& squared_norms) {
  return (NumericTraits<Scalar>::kEpsilon + squared_norms.sqrt()).inverse();
}

// ns: g = Σ_l (Q2ᵀJ_p)ᵀ Q2ᵀr over each landmark's reduced rows.
template <typename Scalar>
VecX<Scalar> nullspaceGradient(const std::vector<LandmarkBlockNs<Scalar>>& blocks, Eigen::Index n) {
  VecX<Scalar> g = VecX<Scalar>::Zero(n);
  for (const auto& block : blocks) {
    const VecX<Scalar> g_local = block.reducedJp().transpose() * block.reducedR();
    const std::vector<int>& offsets = block.map().rcs_offset;
    for (size_t j = 0; j < offsets.size(); ++j) {
      g.template segment<kBalCameraDim>(offsets[j]) +=
          g_local.template segment<kBalCameraDim>(kBalCameraDim * j);
    }
  }
  return g;
}

// ns: D_c += (Q2ᵀJ_p)_cᵀ (Q2ᵀJ_p)_c, the camera blocks of S from the reduced rows.
template <typename Scalar>
void addNullspaceCameraBlocks(const std::vector<LandmarkBlockNs<Scalar>>& blocks,
                              std::vector<Mat<Scalar, 9, 9>>* D) {
  for (const auto& block : blocks) {
    const auto Jr = block.reducedJp();
    const std::vector<int>& offsets = block.map().rcs_offset;
    for (size_t j = 0; j < offsets.size(); ++j) {
      const auto Jr_j = Jr.middleCols(kBalCameraDim * j, kBalCameraDim);
      (*D)[offsets[j] / kBalCameraDim].noalias() += Jr_j.transpose() * Jr_j;
    }
  }
}

// ns, matrix-free: Ax += Σ_l (Q2ᵀJ_p)ᵀ((Q2ᵀJ_p) x_l), never forming S.
template <typename Scalar>
void addNullspaceProduct(const std::vector<LandmarkBlockNs<Scalar>>& blocks, const VecX<Scalar>& x,
                         VecX<Scalar>* Ax) {
  VecX<Scalar> x_local, y_local, t;
  for (const auto& block : blocks) {
    const std::vector<int>& offsets = block.map().rcs_offset;
    x_local.resize(kBalCameraDim * static_cast<Eigen::Index>(offsets.size()));
    for (size_t j = 0; j < offsets.size(); ++j) {
      x_local.template segment<kBalCameraDim>(kBalCameraDim * j) =
          x.template segment<kBalCameraDim>(offsets[j]);
    }
    t.noalias() = block.reducedJp() * x_local;
    y_local.noalias() = block.reducedJp().transpose() * t;
    for (size_t j = 0; j < offsets.size(); ++j) {
      Ax->template segment<kBalCameraDim>(offsets[j]) +=
          y_local.template segment<kBalCameraDim>(kBalCameraDim * j);
    }
  }
}

template <typename Block>
LandmarkSystem<Block>::LandmarkSystem(const BalProblem& problem) : problem_(problem) {
  point_observations_.resize(problem.points.size());
  for (int i = 0; i < problem.numObservations(); ++i) {
    point_observations_[problem.observations[i].point].push_back(i);
  }
}

template <typename Block>
Status LandmarkSystem<Block>::linearize(const BalState<Scalar>& state, const RobustLoss& loss) {
  std::vector<ObservationRows> rows(problem_.observations.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    const BalObservation& obs = problem_.observations[i];
    ObservationRows& row = rows[i];
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
  }
  cameraColumnScaling(rows);
  blocks_.clear();
  point_block_.assign(problem_.points.size(), -1);
  point_scaling_.assign(problem_.points.size(), Vec3<Scalar>::Zero());
  num_fixed_points_ = 0;
  for (size_t l = 0; l < point_observations_.size(); ++l) {
    if (point_observations_[l].size() < 2) {
      ++num_fixed_points_;
      continue;
    }
    point_block_[l] = static_cast<int>(blocks_.size());
    Status status = setBlock(static_cast<int>(l), rows, &blocks_.emplace_back());
    if (!status.ok()) return status;
  }
  return Status::Ok();
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
Status LandmarkSystem<Block>::setBlock(int point, const std::vector<ObservationRows>& rows,
                                       Block* block) {
  const std::vector<int>& obs = point_observations_[point];
  const int n = static_cast<int>(obs.size());
  MatX<Scalar> J_p = MatX<Scalar>::Zero(2 * n, kBalCameraDim * n);
  Mat<Scalar, Eigen::Dynamic, 3> J_l(2 * n, 3);
  VecX<Scalar> r(2 * n);
  PoseBlockMap map;
  map.pose_dim = kBalCameraDim;
  for (int j = 0; j < n; ++j) {
    const int camera = problem_.observations[obs[j]].camera;
    J_p.template block<2, kBalCameraDim>(2 * j, kBalCameraDim * j) =
        rows[obs[j]].J_camera *
        camera_scaling_.template segment<kBalCameraDim>(kBalCameraDim * camera).asDiagonal();
    J_l.template middleRows<2>(2 * j) = rows[obs[j]].J_point;
    r.template segment<2>(2 * j) = rows[obs[j]].r;
    map.rcs_offset.push_back(kBalCameraDim * camera);
  }
  point_scaling_[point] =
      inverseColumnScale<Scalar>(J_l.colwise().squaredNorm().array()).transpose();
  J_l = J_l * point_scaling_[point].asDiagonal();
  return block->setFromJacobians(J_p, J_l, r, std::move(map));
}

template <typename Block>
auto LandmarkSystem<Block>::cameraBlocks(Scalar lambda, const MatX<Scalar>& S) const
    -> std::vector<Mat<Scalar, 9, 9>> {
  std::vector<Mat<Scalar, 9, 9>> D(problem_.cameras.size(), lambda * Mat<Scalar, 9, 9>::Identity());
  if constexpr (kIsNullspace<Block>) {
    addNullspaceCameraBlocks(blocks_, &D);
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
  for (const Block& block : blocks_) {
    Status status = block.addToReducedSystem(*S, *g);
    if (!status.ok()) return status;
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
      addNullspaceProduct(blocks_, x, Ax);
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
  for (Block& block : blocks_) block.setLandmarkDamping(Vec3<Scalar>::Constant(lambda));
  MatX<Scalar> S;
  VecX<Scalar> g;
  if constexpr (kIsNullspace<Block>) {
    g = nullspaceGradient(blocks_, camera_scaling_.size());
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
  step->model_change = 0;
  for (size_t l = 0; l < point_block_.size(); ++l) {
    if (point_block_[l] < 0) continue;
    const Block& block = blocks_[point_block_[l]];
    Vec3<Scalar> delta_l;
    Status status = block.backSubstitute(x, &delta_l);
    if (!status.ok()) return status;
    step->model_change += double(block.linearizedCostChange(x, delta_l));
    step->delta_points[l] = point_scaling_[l].cwiseProduct(delta_l);
  }
  return Status::Ok();
}

template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeSystem(const BalProblem& problem,
                                                   BaElimination elimination) {
  if (elimination == BaElimination::kNullspace) {
    return std::make_unique<LandmarkSystem<LandmarkBlockNs<Scalar>>>(problem);
  }
  return std::make_unique<LandmarkSystem<LandmarkBlockSc<Scalar>>>(problem);
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
