#include "core/estimator/marg_prior.h"

#include <algorithm>

#include "core/common/scalar.h"

namespace marglab {

template <typename Scalar>
int MargPrior<Scalar>::rows() const {
  if (empty()) return 0;
  return storage == PriorStorage::kSqrt ? static_cast<int>(sqrt.J.rows()) : cols();
}

template <typename Scalar>
int MargPrior<Scalar>::indexOf(int64_t frame_id) const {
  auto it = std::find(frame_ids.begin(), frame_ids.end(), frame_id);
  return it == frame_ids.end() ? -1 : static_cast<int>(it - frame_ids.begin());
}

template <typename Scalar>
VecX<Scalar> MargPrior<Scalar>::delta(const std::function<SE3<Scalar>(int64_t)>& pose_of) const {
  VecX<Scalar> d(cols());
  for (size_t i = 0; i < frame_ids.size(); ++i) {
    d.template segment<kPoseDim>(kPoseDim * i) = boxMinus(pose_of(frame_ids[i]), x0[i]);
  }
  return d;
}

template <typename Scalar>
Scalar MargPrior<Scalar>::cost(const VecX<Scalar>& d) const {
  if (empty()) return Scalar(0);
  if (storage == PriorStorage::kSqrt) return Scalar(0.5) * (sqrt.r + sqrt.J * d).squaredNorm();
  return Scalar(0.5) * d.dot(hessian.H * d) + hessian.b.dot(d);
}

template <typename Scalar>
void MargPrior<Scalar>::linearize(const VecX<Scalar>& d, MatX<Scalar>* H, VecX<Scalar>* b) const {
  if (storage == PriorStorage::kSqrt) {
    *H = sqrt.J.transpose() * sqrt.J;
    *b = sqrt.J.transpose() * (sqrt.r + sqrt.J * d);
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
  if (storage == PriorStorage::kSqrt) {
    const VecX<Scalar> r0 = sqrt.r + sqrt.J * d;
    const VecX<Scalar> J_step = sqrt.J * step;
    return r0.dot(J_step) + Scalar(0.5) * J_step.squaredNorm();
  }
  return (hessian.b + hessian.H * d).dot(step) + Scalar(0.5) * step.dot(hessian.H * step);
}

#define MARGLAB_INST(S) template struct MargPrior<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
