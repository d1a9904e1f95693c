#pragma once
// The phases of one Levenberg–Marquardt iteration of the estimator on a captured window (for the
// benchmark suite and `marglab bench`), run by the estimator's own Linearization object
// (core/estimator/linearization.h) — the code a run executes:
//   linearize()  relative poses, per-landmark reprojection Jacobians (J_p, J_l, r), IMU factors,
//                the fixed part of the reduced system (IMU, direct rows, prior);
//   eliminate()  landmark elimination of the variant (ns: in-place Householder QR of [J_p J_l r]
//                and the Q2ᵀ rows into the reduced camera system; sc: Schur complement);
//   solve()      damped LDLT of the reduced system, back-substitution of the landmarks and the
//                model cost change.
// iteration() is the three in a row; optimizeOnce() is the estimator's optimizer itself
// (LevenbergMarquardt::optimize) with one LM iteration (including the cost evaluations and λ
// trials). marginalize() is one marginalization event as the policy plans it (the oldest keyframe
// with its landmarks; for VIO also the oldest state's speed-bias) by the variant's Marginalizer
// (flat QR or Schur complement), on a copy of the prior.

#include <memory>
#include <vector>

#include "core/estimator/levenberg_marquardt.h"
#include "core/estimator/window_snapshot.h"
#include "core/linalg/landmark_block.h"

namespace marglab {

// The Householder-QR kernel's flop count for an m × n block [J_p J_l r] with 3 landmark columns:
// for reflector k: its norm 2(m−k), and its application to the n−k−1 columns on its right
// 4(m−k) each (dot product and rank-1 update).
double landmarkQrFlops(int m, int n);

template <typename Scalar>
class WindowKernels {
 public:
  WindowKernels(const WindowSnapshot& window, const Variant& variant);
  ~WindowKernels();

  void linearize();
  Status eliminate();
  Status solve();
  Status iteration();
  // LevenbergMarquardt::optimize with lm_max_iterations = 1 on a copy of the window.
  Status optimizeOnce();
  // LevenbergMarquardt::optimize to convergence on a copy; iterations in *iterations.
  Status optimizeFull(int* iterations, double* cost_final = nullptr);
  Status marginalize(MargMethod method);

  // After linearize(): the landmark blocks, as the QR kernel's inputs.
  int numLandmarkBlocks() const;
  const MatX<Scalar>& blockJp(int i) const;
  const Mat<Scalar, Eigen::Dynamic, 3>& blockJl(int i) const;
  const VecX<Scalar>& blockR(int i) const;
  PoseBlockMap blockMap(int i) const;
  const std::vector<LandmarkJacobians<Scalar>>& landmarkJacobians() const;
  int numColumns() const;
  const VecX<Scalar>& step() const;  // after solve()

 private:
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace marglab
