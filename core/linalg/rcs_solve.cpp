#include "core/linalg/rcs_solve.h"

#include <fmt/core.h>
#include <Eigen/Cholesky>

#include "core/common/scalar.h"

namespace marglab {

template <typename Scalar>
DampedSolve<Scalar> solveDampedLdlt(MatX<Scalar> H, const VecX<Scalar>& b, Scalar lambda,
                                    Scalar lambda_min, Preconditioning preconditioning,
                                    bool solve_indefinite) {
  DampedSolve<Scalar> result;
  if (!H.allFinite() || !b.allFinite()) {
    result.status = Status::Error(Status::Code::kNotFinite,
                                  "reduced camera system: H or b has a non-finite entry");
    return result;
  }
  for (Eigen::Index i = 0; i < H.rows(); ++i) H(i, i) += lmDamping(H(i, i), lambda, lambda_min);
  const bool scaled = preconditioning != Preconditioning::kNone;
  BlockScaling<Scalar> P;
  if (scaled) {
    P = BlockScaling<Scalar>::fromHessian(H, preconditioning);
    H = P.scaled(H);
  }
  Eigen::LDLT<MatX<Scalar>> ldlt(H);
  const bool positive = (ldlt.vectorD().array() > Scalar(0)).all();
  if (ldlt.info() != Eigen::Success || (!positive && !solve_indefinite)) {
    result.status = Status::Error(
        Status::Code::kSolveFailed,
        fmt::format("reduced camera system: damped {}H ({}x{}) is not positive definite "
                    "(min LDLT pivot {:.3e})",
                    scaled ? "preconditioned " : "", H.rows(), H.cols(),
                    ldlt.vectorD().minCoeff()));
    return result;
  }
  result.delta = scaled ? VecX<Scalar>(-P.toDelta(ldlt.solve(P.scaledGradient(b))))
                        : VecX<Scalar>(-ldlt.solve(b));
  if (!result.delta.allFinite()) {
    result.status =
        Status::Error(Status::Code::kNotFinite, "reduced camera system: non-finite step");
  }
  return result;
}

#define MARGLAB_INST(S) \
  template DampedSolve<S> solveDampedLdlt<S>(MatX<S>, const VecX<S>&, S, S, Preconditioning, bool);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
