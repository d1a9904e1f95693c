#include "core/estimator/marg_prior.h"

#include <algorithm>
#include <utility>

#include "core/common/scalar.h"

namespace marglab {

template <typename Scalar>
int MargPrior<Scalar>::rows() const {
  if (empty()) return 0;
  return sqrtStorage(storage) ? static_cast<int>(sqrt.J.rows()) : cols();
}

template <typename Scalar>
int MargPrior<Scalar>::cols() const {
  return blocks.empty() ? 0 : blocks.back().offset + stateBlockDim(blocks.back().var.block);
}

template <typename Scalar>
void MargPrior<Scalar>::addBlock(const VarKey& var, const SE3<Scalar>& T0, const Vec9S& sb0,
                                 const Vec3<Scalar>& p0) {
  blocks.push_back(Block{var, cols(), T0, sb0, p0});
}

template <typename Scalar>
bool MargPrior<Scalar>::hasLandmarks() const {
  return std::any_of(blocks.begin(), blocks.end(),
                     [](const Block& block) { return block.var.block == StateBlock::kLandmark; });
}

template <typename Scalar>
int MargPrior<Scalar>::indexOf(const VarKey& var) const {
  auto it = std::find_if(blocks.begin(), blocks.end(),
                         [&var](const Block& block) { return block.var == var; });
  return it == blocks.end() ? -1 : static_cast<int>(it - blocks.begin());
}

template <typename Scalar>
VecX<Scalar> MargPrior<Scalar>::delta(const std::function<SE3<Scalar>(int64_t)>& pose_of,
                                      const std::function<Vec9S(int64_t)>& speed_bias_of,
                                      const std::function<Vec3<Scalar>(int64_t)>& point_of,
                                      Scalar stereo_offset) const {
  VecX<Scalar> d(cols());
  for (const Block& block : blocks) {
    if (block.var.block == StateBlock::kStereoOffset) {
      d[block.offset] = stereo_offset - block.c0;
    } else if (block.var.block == StateBlock::kPose) {
      d.template segment<kPoseDim>(block.offset) = boxMinus(pose_of(block.var.frame_id), block.T0);
    } else if (block.var.block == StateBlock::kLandmark) {
      d.template segment<kPointDim>(block.offset) = point_of(block.var.frame_id) - block.p0;
    } else {
      d.template segment<kSpeedBiasDim>(block.offset) =
          speed_bias_of(block.var.frame_id) - block.sb0;
    }
  }
  return d;
}

template <typename Scalar>
MatX<Scalar> MargPrior<Scalar>::hessianAtAnchor() const {
  if (sqrtStorage(storage)) return sqrt.J.transpose() * sqrt.J;
  return scaled() ? scaling.unscaled(hessian.H) : hessian.H;
}

template <typename Scalar>
VecX<Scalar> MargPrior<Scalar>::gradientAtAnchor() const {
  if (sqrtStorage(storage)) return sqrt.J.transpose() * sqrt.r;
  return scaled() ? scaling.unscaledGradient(hessian.b) : hessian.b;
}

template <typename Scalar>
void MargPrior<Scalar>::setSqrt(MatX<Scalar> J, VecX<Scalar> r) {
  sqrt.J = std::move(J);
  sqrt.r = std::move(r);
}

template <typename Scalar>
void MargPrior<Scalar>::setHessian(MatX<Scalar> H, VecX<Scalar> b, Scalar c) {
  hessian.H = std::move(H);
  hessian.b = std::move(b);
  hessian.c = c;
  scaling = BlockScaling<Scalar>();
}

template <typename Scalar>
void MargPrior<Scalar>::setScaledHessian(MatX<Scalar> H_s, VecX<Scalar> b_s, Scalar c,
                                         BlockScaling<Scalar> P) {
  setHessian(std::move(H_s), std::move(b_s), c);
  scaling = std::move(P);
}

template <typename Scalar>
void MargPrior<Scalar>::precondition() {
  const Preconditioning kind = preconditioningOf(storage);
  if (kind == Preconditioning::kNone || !hessianStorage(storage) || empty() || scaled()) return;
  BlockScaling<Scalar> P = BlockScaling<Scalar>::fromHessian(hessian.H, kind);
  setScaledHessian(P.scaled(hessian.H), P.scaledGradient(hessian.b), hessian.c, P);
}

template <typename Scalar>
Scalar MargPrior<Scalar>::cost(const VecX<Scalar>& d) const {
  if (empty()) return Scalar(0);
  if (sqrtStorage(storage)) return Scalar(0.5) * (sqrt.r + sqrt.J * d).squaredNorm();
  if (scaled()) {
    const VecX<Scalar> y = scaling.toScaled(d);
    return Scalar(0.5) * y.dot(hessian.H * y) + hessian.b.dot(y) + hessian.c;
  }
  return Scalar(0.5) * d.dot(hessian.H * d) + hessian.b.dot(d) + hessian.c;
}

template <typename Scalar>
void MargPrior<Scalar>::linearize(const VecX<Scalar>& d, MatX<Scalar>* H, VecX<Scalar>* b) const {
  if (sqrtStorage(storage)) {
    *H = sqrt.J.transpose() * sqrt.J;
    *b = sqrt.J.transpose() * (sqrt.r + sqrt.J * d);
  } else if (scaled()) {
    *H = scaling.unscaled(hessian.H);
    *b = scaling.unscaledGradient(hessian.b + hessian.H * scaling.toScaled(d));
  } else {
    *H = hessian.H;
    *b = hessian.b + hessian.H * d;
  }
}

template <typename Scalar>
void MargPrior<Scalar>::sqrtRows(const VecX<Scalar>& d, MatX<Scalar>* J, VecX<Scalar>* r) const {
  *J = sqrt.J;
  *r = sqrt.r + sqrt.J * d;
}

template <typename Scalar>
Scalar MargPrior<Scalar>::costChange(const VecX<Scalar>& d, const VecX<Scalar>& step) const {
  if (empty()) return Scalar(0);
  if (sqrtStorage(storage)) {
    const VecX<Scalar> r0 = sqrt.r + sqrt.J * d;
    const VecX<Scalar> J_step = sqrt.J * step;
    return r0.dot(J_step) + Scalar(0.5) * J_step.squaredNorm();
  }
  if (scaled()) {
    const VecX<Scalar> y = scaling.toScaled(d), t = scaling.toScaled(step);
    return (hessian.b + hessian.H * y).dot(t) + Scalar(0.5) * t.dot(hessian.H * t);
  }
  return (hessian.b + hessian.H * d).dot(step) + Scalar(0.5) * step.dot(hessian.H * step);
}

template <typename Scalar>
void MargPrior<Scalar>::gaugeLayout(PriorLayout* layout, GaugeState* state) const {
  for (const Block& block : blocks) {
    const int64_t id = block.var.frame_id;
    const int o = block.offset;
    if (block.var.block == StateBlock::kPose) {
      layout->push_back({PriorVariableKind::kPose, id, o});
      state->T_w_i[id] = block.T0.template cast<double>();
    } else if (block.var.block == StateBlock::kSpeedBias) {
      layout->push_back({PriorVariableKind::kVelocity, id, o});
      layout->push_back({PriorVariableKind::kGyroBias, id, o + 3});
      layout->push_back({PriorVariableKind::kAccelBias, id, o + 6});
      state->v_w[id] = block.sb0.template head<3>().template cast<double>();
    } else if (block.var.block == StateBlock::kStereoOffset) {
      layout->push_back({PriorVariableKind::kCalibration, id, o});
    } else {
      layout->push_back({PriorVariableKind::kPoint, id, o});
      state->p_w[id] = block.p0.template cast<double>();
    }
  }
}

#define MARGLAB_INST(S) template struct MargPrior<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
