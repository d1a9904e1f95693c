// Nonlinear factor recovery (core/sparsify/nfr.h) against independent computations: the factor
// Jacobians against central differences (rotations at 0, tiny, near π and π); the closed form
// against priors that are sums of the topology's factors (KLD 0, the factors' information
// recovered) and against generic dense priors (gradient of eq. 17 zero, every feasible
// perturbation raises the KLD, the gradient equal to central differences of the KLD); a gauge-free
// prior with the 4-dof VIO gauge; the square-root form; bad input as a Status.
//
// Tolerances. Rounding in Λ_t (ε relative) moves Σ̃_t, and so C_i, Λ_r^(i) and every log det
// term of the KLD, by at most about m ε κ relative (m columns, κ the condition number of Λ̃_t, or
// of Λ̃_s where that is the matrix inverted); the tests allow 100 m ε κ. A KLD increase on one
// problem is resolved much more finely (kldDifferenceTolerance).

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>
#include <vector>

#include "core/sparsify/nfr.h"
#include "geometry/geometry_test_utils.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::randomGaussian;

template <typename S>
double eps() {
  return static_cast<double>(NumericTraits<S>::kEpsilon);
}

// Q diag(cond^(k/(d−1))) Qᵀ with Q a random orthogonal matrix: SPD with condition number cond.
MatXd randomSpd(std::mt19937_64& rng, int d, double cond) {
  const MatXd Q = Eigen::HouseholderQR<MatXd>(randomGaussian(rng, d, d)).householderQ();
  VecXd lambda(d);
  for (int k = 0; k < d; ++k) lambda[k] = d > 1 ? std::pow(cond, double(k) / (d - 1)) : 1.0;
  return Q * lambda.asDiagonal() * Q.transpose();
}

double conditionNumber(const MatXd& A) {
  const VecXd lambda = Eigen::SelfAdjointEigenSolver<MatXd>(A).eigenvalues();
  return lambda.maxCoeff() / lambda.minCoeff();
}

double relError(const MatXd& a, const MatXd& b) { return (a - b).norm() / b.norm(); }

// Eq. 16 returned every A_i of a prior Λ_t = Σ H_iᵀ A_i H_i, so Λ_s = Λ_t and D = 0 (to tol).
template <typename S>
void expectExactRecovery(const Sparsification<S>& sp, const std::vector<MatXd>& A,
                         const MatXd& Lambda_t, double tol) {
  ASSERT_EQ(sp.factors.size(), A.size());
  for (size_t i = 0; i < A.size(); ++i) {
    EXPECT_LE(relError(sp.factors[i].information.template cast<double>(), A[i]), tol)
        << "factor " << i;
  }
  EXPECT_LE(relError(sp.Lambda_s.template cast<double>(), Lambda_t), tol);
  EXPECT_LE(std::abs(double(sp.kld)), tol);
}

// One IMU state — pose at columns 0..5, velocity 6..8, bias 9..14 — and n_landmarks world points
// 2–6 m from it at 15 + 3j.
Blanket<double> imuStateWithLandmarks(std::mt19937_64& rng, const Eigen::Vector3d& phi,
                                      int n_landmarks) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> range(2.0, 6.0);
  Blanket<double> x;
  BlanketVariable<double> pose;
  pose.kind = BlanketKind::kPose;
  pose.T_w_i = SE3d(expSO3<double>(phi), Eigen::Vector3d(1.0, -2.0, 0.5));
  x.push_back(pose);
  BlanketVariable<double> velocity;
  velocity.kind = BlanketKind::kVelocity;
  velocity.offset = 6;
  velocity.value = Eigen::Vector3d(0.8, -0.3, 0.1);
  x.push_back(velocity);
  BlanketVariable<double> bias;
  bias.kind = BlanketKind::kBias;
  bias.offset = 9;
  bias.value = 0.01 * randomGaussian(rng, 6, 1);
  x.push_back(bias);
  for (int j = 0; j < n_landmarks; ++j) {
    BlanketVariable<double> landmark;
    landmark.kind = BlanketKind::kLandmark;
    landmark.offset = 15 + 3 * j;
    landmark.value = pose.T_w_i.translation() + range(rng) * randomGaussian(rng, 3, 1).normalized();
    x.push_back(landmark);
  }
  return x;
}

int blanketDim(const Blanket<double>& x) {
  int n = 0;
  for (const auto& v : x) n += blanketKindDim(v.kind);
  return n;
}

// The columns 0..n-1 not in the gauge reference: the subspace S the recovery works on.
std::vector<int> columnsOutside(int n, const std::vector<int>& reference) {
  std::vector<int> kept;
  for (int c = 0; c < n; ++c) {
    if (std::find(reference.begin(), reference.end(), c) == reference.end()) kept.push_back(c);
  }
  return kept;
}

template <typename S>
Blanket<S> castBlanket(const Blanket<double>& x) {
  Blanket<S> out;
  for (const auto& v : x) {
    BlanketVariable<S> w;
    w.kind = v.kind;
    w.offset = v.offset;
    w.T_w_i = v.T_w_i.cast<S>();
    w.value = v.value.cast<S>();
    out.push_back(w);
  }
  return out;
}

// Rows of H_s of every factor over all n columns at x, from the residual Jacobians of nfr.h;
// unary factors keep only the rows not in `reference` (columns of Λ_t).
std::vector<MatXd> factorJacobians(const Blanket<double>& x, const NfrTopology& topology,
                                   const std::vector<int>& reference = {}) {
  const int n = blanketDim(x);
  std::vector<MatXd> out;
  for (const NfrFactorSpec& spec : topology) {
    const BlanketVariable<double>& var = x[spec.var];
    if (spec.kind == NfrFactorKind::kRelativePose) {
      const BlanketVariable<double>& pose_b = x[spec.pose_b];
      Mat<double, 6, 6> J_a, J_b;
      relativePoseResidual<double>(var.T_w_i, pose_b.T_w_i, var.T_w_i.inverse() * pose_b.T_w_i,
                                   &J_a, &J_b);
      MatXd J = MatXd::Zero(6, n);
      J.middleCols(var.offset, 6) = J_a;
      J.middleCols(pose_b.offset, 6) = J_b;
      out.push_back(J);
    } else if (spec.kind == NfrFactorKind::kPoseLandmark) {
      Mat<double, 3, 6> J_pose;
      Eigen::Matrix3d J_landmark;
      poseLandmarkResidual<double>(var.T_w_i, x[spec.landmark].value, Eigen::Vector3d::Zero(),
                                   &J_pose, &J_landmark);
      MatXd J = MatXd::Zero(3, n);
      J.middleCols(var.offset, 6) = J_pose;
      J.middleCols(x[spec.landmark].offset, 3) = J_landmark;
      out.push_back(J);
    } else {
      const int d = blanketKindDim(var.kind);
      MatXd J(0, n);
      for (int k = 0; k < d; ++k) {
        if (std::find(reference.begin(), reference.end(), var.offset + k) != reference.end()) {
          continue;
        }
        J.conservativeResize(J.rows() + 1, n);
        J.row(J.rows() - 1) = Eigen::RowVectorXd::Unit(n, var.offset + k);
      }
      out.push_back(J);
    }
  }
  return out;
}

// Σ_i J_iᵀ A_i J_i with random SPD A_i (condition 10): a prior the topology represents exactly.
MatXd sumOfFactors(std::mt19937_64& rng, const std::vector<MatXd>& J, std::vector<MatXd>* A) {
  MatXd Lambda = MatXd::Zero(J.front().cols(), J.front().cols());
  for (const MatXd& J_i : J) {
    A->push_back(randomSpd(rng, static_cast<int>(J_i.rows()), 10.0));
    Lambda += J_i.transpose() * A->back() * J_i;
  }
  return Lambda;
}

// A blanket of keyframe poses (rotation vectors phis, columns 6k), the velocity and bias of the
// newest one, and n_landmarks world points 2–6 m from it: the layout of the estimator's blankets.
Blanket<double> posesWithLandmarks(std::mt19937_64& rng, const std::vector<Eigen::Vector3d>& phis,
                                   int n_landmarks) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> range(2.0, 6.0);
  Blanket<double> x;
  int offset = 0;
  for (size_t k = 0; k < phis.size(); ++k) {
    BlanketVariable<double> pose;
    pose.kind = BlanketKind::kPose;
    pose.offset = offset;
    pose.T_w_i = SE3d(expSO3<double>(phis[k]), Eigen::Vector3d(0.7 * double(k), -0.3, 0.2) +
                                                   0.1 * randomGaussian(rng, 3, 1));
    x.push_back(pose);
    offset += 6;
  }
  BlanketVariable<double> velocity;
  velocity.kind = BlanketKind::kVelocity;
  velocity.offset = offset;
  velocity.value = Eigen::Vector3d(0.8, -0.3, 0.1);
  x.push_back(velocity);
  BlanketVariable<double> bias;
  bias.kind = BlanketKind::kBias;
  bias.offset = offset + 3;
  bias.value = 0.01 * randomGaussian(rng, 6, 1);
  x.push_back(bias);
  offset += 9;
  const Eigen::Vector3d t_newest = x[phis.size() - 1].T_w_i.translation();
  for (int j = 0; j < n_landmarks; ++j) {
    BlanketVariable<double> landmark;
    landmark.kind = BlanketKind::kLandmark;
    landmark.offset = offset + 3 * j;
    landmark.value = t_newest + range(rng) * randomGaussian(rng, 3, 1).normalized();
    x.push_back(landmark);
  }
  return x;
}

// The relative-pose topology over posesWithLandmarks: the chain in blanket order, the anchor the
// newest pose.
NfrTopology chainTopology(const Blanket<double>& x, int n_poses) {
  std::vector<int> chain(static_cast<size_t>(n_poses));
  for (int k = 0; k < n_poses; ++k) chain[static_cast<size_t>(k)] = k;
  return relativePoseTopology(x, chain, n_poses - 1);
}

// Rotations of the chain tests: at 0, near π and π, and generic.
std::vector<Eigen::Vector3d> chainRotations() {
  return {Eigen::Vector3d::Zero(), (M_PI - 1e-3) * Eigen::Vector3d(1, 2, -1).normalized(),
          M_PI * Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.3, -0.2, 1.1)};
}

// A gauge-free prior over posesWithLandmarks: relative-pose factors between every pair of poses,
// pose–landmark factors from every pose, gravity-direction factors Rᵀg, the newest pose's
// body-frame velocity Rᵀv and its bias — all invariant under translations and yaw, so the
// nullspace is the VIO gauge; the topology cannot represent it (landmarks seen from every pose,
// the velocity in the body frame, every pair of poses linked).
MatXd gaugeFreeChainPrior(std::mt19937_64& rng, const Blanket<double>& x, int n_poses) {
  const int n = blanketDim(x);
  MatXd H = MatXd::Zero(n, n);
  const auto add = [&](const MatXd& J) {
    H += J.transpose() * randomSpd(rng, static_cast<int>(J.rows()), 10.0) * J;
  };
  for (int a = 0; a < n_poses; ++a) {
    for (int b = a + 1; b < n_poses; ++b) {
      add(factorJacobians(x, {{NfrFactorKind::kRelativePose, a, -1, b}})[0]);
    }
    for (int v = 0; v < static_cast<int>(x.size()); ++v) {
      if (x[v].kind == BlanketKind::kLandmark) {
        add(factorJacobians(x, {{NfrFactorKind::kPoseLandmark, a, v, -1}})[0]);
      }
    }
    MatXd J = MatXd::Zero(3, n);
    J.middleCols(x[a].offset + 3, 3) =
        x[a].T_w_i.rotationMatrix().transpose() * hat<double>(Eigen::Vector3d(0, 0, -1));
    add(J);
  }
  const BlanketVariable<double>& newest = x[n_poses - 1];
  const Eigen::Matrix3d R_i_w = newest.T_w_i.rotationMatrix().transpose();
  MatXd J_v = MatXd::Zero(3, n);
  J_v.middleCols(newest.offset + 3, 3) = R_i_w * hat<double>(x[n_poses].value);
  J_v.middleCols(x[n_poses].offset, 3) = R_i_w;
  add(J_v);
  MatXd J_b = MatXd::Zero(6, n);
  J_b.middleCols(x[n_poses + 1].offset, 6).setIdentity();
  add(J_b);
  return H;
}

// Independent optimum of a tree topology (H_s square): in the measurement coordinates y = H_s δx
// the target has covariance Σ_y = H_s Σ_t H_sᵀ, the factors make the blocks of y independent, so
// Λ_r^(i) = (Σ_y^(ii))⁻¹ and D is the total correlation ½ (Σ_i log det Σ_y^(ii) − log det Σ_y).
// Dense inverse and LU determinants in double over the non-reference columns; the unary rows of a
// reference coordinate are dropped as in nfr.h.
struct TreeOptimum {
  std::vector<MatXd> information;
  double kld = 0;
};
TreeOptimum treeOptimum(const MatXd& Lambda_t, const Blanket<double>& x,
                        const NfrTopology& topology, const std::vector<int>& reference) {
  const std::vector<int> kept = columnsOutside(blanketDim(x), reference);
  const std::vector<MatXd> J = factorJacobians(x, topology, reference);
  MatXd H(0, static_cast<Eigen::Index>(kept.size()));
  for (const MatXd& J_i : J) {
    H.conservativeResize(H.rows() + J_i.rows(), Eigen::NoChange);
    H.bottomRows(J_i.rows()) = J_i(Eigen::all, kept);
  }
  const MatXd Sigma_y = H * MatXd(Lambda_t(kept, kept)).inverse() * H.transpose();
  TreeOptimum out;
  out.kld = -0.5 * std::log(Sigma_y.determinant());
  Eigen::Index row = 0;
  for (const MatXd& J_i : J) {
    const MatXd block = Sigma_y.block(row, row, J_i.rows(), J_i.rows());
    out.information.push_back(block.inverse());
    out.kld += 0.5 * std::log(block.determinant());
    row += J_i.rows();
  }
  return out;
}

// A gauge-free dense prior over the blanket of imuStateWithLandmarks: pose–landmark factors from
// the blanket's pose and from a second pose P0, gravity-direction factors h = Rᵀg on both poses, a
// body-frame velocity factor h = Rᵀv, a bias factor, then P0 marginalized (Schur complement).
// Every residual is invariant under translations and rotations about z (the gravity axis), so the
// prior's nullspace is the VIO gauge x, y, z, yaw.
MatXd gaugeFreePrior(std::mt19937_64& rng, const Blanket<double>& x) {
  const int n = blanketDim(x);
  const int n_all = n + 6;  // P0 at columns n .. n + 5
  const SE3d T_0(expSO3<double>(Eigen::Vector3d(0.1, -0.2, 0.3)), Eigen::Vector3d(0.5, -1.0, 0.2));
  const SE3d& T_1 = x[0].T_w_i;
  const Eigen::Vector3d g(0, 0, -1);  // the direction: unit weight keeps Λ_t well conditioned
  MatXd H = MatXd::Zero(n_all, n_all);
  const auto add = [&](const MatXd& J) {
    H += J.transpose() * randomSpd(rng, static_cast<int>(J.rows()), 10.0) * J;
  };
  for (const auto& v : x) {
    if (v.kind != BlanketKind::kLandmark) continue;
    for (const auto& [T, offset] : {std::make_pair(T_1, 0), std::make_pair(T_0, n)}) {
      Mat<double, 3, 6> J_pose;
      Eigen::Matrix3d J_landmark;
      poseLandmarkResidual<double>(T, v.value, Eigen::Vector3d::Zero(), &J_pose, &J_landmark);
      MatXd J = MatXd::Zero(3, n_all);
      J.middleCols(offset, 6) = J_pose;
      J.middleCols(v.offset, 3) = J_landmark;
      add(J);
    }
  }
  for (const auto& [T, offset] : {std::make_pair(T_1, 0), std::make_pair(T_0, n)}) {
    MatXd J = MatXd::Zero(3, n_all);
    J.middleCols(offset + 3, 3) = T.rotationMatrix().transpose() * hat<double>(g);
    add(J);
  }
  MatXd J_v = MatXd::Zero(3, n_all);
  J_v.middleCols(3, 3) = T_1.rotationMatrix().transpose() * hat<double>(x[1].value);
  J_v.middleCols(6, 3) = T_1.rotationMatrix().transpose();
  add(J_v);
  MatXd J_b = MatXd::Zero(6, n_all);
  J_b.middleCols(9, 6).setIdentity();
  add(J_b);
  const MatXd H_mm_inv = H.bottomRightCorner(6, 6).inverse();
  return H.topLeftCorner(n, n) - H.topRightCorner(n, 6) * H_mm_inv * H.bottomLeftCorner(6, n);
}

// The VIO gauge directions at x (gauge.h): translation e_x, e_y, e_z (poses and landmarks shift),
// and yaw about the origin (δφ = e_z, δt = e_z × t, δp = e_z × p, δv = e_z × v).
MatXd gaugeBasis(const Blanket<double>& x) {
  MatXd N = MatXd::Zero(blanketDim(x), 4);
  const Eigen::Vector3d e_z = Eigen::Vector3d::UnitZ();
  for (const auto& v : x) {
    if (v.kind == BlanketKind::kPose) {
      N.block<3, 3>(v.offset, 0).setIdentity();
      N.block<3, 1>(v.offset, 3) = e_z.cross(v.T_w_i.translation());
      N(v.offset + 5, 3) = 1.0;
    } else if (v.kind == BlanketKind::kVelocity) {
      N.block<3, 1>(v.offset, 3) = e_z.cross(Eigen::Vector3d(v.value));
    } else if (v.kind == BlanketKind::kLandmark) {
      N.block<3, 3>(v.offset, 0).setIdentity();
      N.block<3, 1>(v.offset, 3) = e_z.cross(Eigen::Vector3d(v.value));
    }
  }
  return N;
}

template <typename S>
std::vector<MatX<S>> informationBlocks(const Sparsification<S>& sp) {
  std::vector<MatX<S>> out;
  for (const auto& f : sp.factors) out.push_back(f.information);
  return out;
}

// Λ' = M Λ Mᵀ with M = I + t G / ‖G‖₂, G random: positive definite for t < 1.
template <typename S>
MatX<S> congruence(std::mt19937_64& rng, const MatX<S>& Lambda, double t) {
  const int d = static_cast<int>(Lambda.rows());
  const MatXd G = randomGaussian(rng, d, d);
  const MatXd M = MatXd::Identity(d, d) + t * G / Eigen::JacobiSVD<MatXd>(G).singularValues()[0];
  return (M * Lambda.template cast<double>() * M.transpose()).template cast<S>();
}

// Rounding of D(Λ') − D(Λ_r) on one problem: log det Λ̃_t, log|det H̃_s| and the C_i are shared,
// only ⟨Λ^(i), C_i⟩ (≈ its size near the minimum) and log det Λ^(i) are rounded anew.
template <typename S>
double kldDifferenceTolerance(const std::vector<MatX<S>>& Lambda_r) {
  double scale = 0;
  for (const MatX<S>& block : Lambda_r) {
    scale += double(block.rows()) + std::abs(std::log(block.template cast<double>().determinant()));
  }
  return 100 * eps<S>() * scale;
}

template <typename S>
class NfrTest : public ::testing::Test {};
TYPED_TEST_SUITE(NfrTest, test::ScalarTypes, test::ScalarNames);

// r = Rᵀ(p − t) − z: |r| ≲ 8 and its third derivatives ≲ |p − t| ≈ 5 for these inputs.
TYPED_TEST(NfrTest, PoseLandmarkJacobiansMatchCentralDifferences) {
  using S = TypeParam;
  const Vec3<S> t(S(1), S(-2), S(0.5)), p(S(3), S(1), S(-2)), z(S(0.3), S(-0.1), S(2));
  for (const Vec3<S>& phi : test::hardRotationVectors<S>()) {
    const SE3<S> T(expSO3<S>(phi), t);
    Mat<S, 3, 6> J_pose;
    Mat3<S> J_landmark;
    poseLandmarkResidual<S>(T, p, z, &J_pose, &J_landmark);
    const auto f = [&](const Vec<S, 9>& d) -> Vec3<S> {
      return poseLandmarkResidual<S>(boxPlus(T, Vec<S, 6>(d.template head<6>())),
                                     Vec3<S>(p + d.template tail<3>()), z);
    };
    Mat<S, 3, 9> J;
    J << J_pose, J_landmark;
    const Mat<S, 3, 9> J_fd = test::fdJacobian<S, 3, 9>(f, Vec<S, 9>::Zero().eval());
    EXPECT_TRUE(test::matricesNear(J, J_fd, test::fdTolerance<S>(S(8), S(5))))
        << "θ = " << phi.norm();
  }
}

// r = T ⊟ z, with T at every hard rotation (z 0.4 rad away), and with the residual rotation itself
// at 0 … π − 0.1 (closer to π the log's branch cut lies within a difference step). |r| ≤ 4, and
// the third derivatives of log(exp(δ) E) stay O(1) away from θ = 2π.
TYPED_TEST(NfrTest, PosePriorJacobianMatchesCentralDifferences) {
  using S = TypeParam;
  const Vec3<S> t(S(1), S(-2), S(0.5));
  std::vector<std::pair<SE3<S>, SE3<S>>> cases;  // (T, z)
  Vec<S, 6> offset;
  offset << S(0.1), S(-0.2), S(0.05), S(0.2), S(-0.1), S(0.3);
  for (const Vec3<S>& phi : test::hardRotationVectors<S>()) {
    const SE3<S> T(expSO3<S>(phi), t);
    cases.emplace_back(T, boxPlus(T, offset));
  }
  const Vec3<S> axis = Vec3<S>(S(0.3), S(-0.5), S(0.8)).normalized();
  const SE3<S> z(expSO3<S>(Vec3<S>(S(0.4), S(1.0), S(-0.2))), t);
  for (double theta : {0.0, double(test::tinyAngle<S>()), 1e-3, 0.5, 1.0, 2.0, 3.0, M_PI - 0.1}) {
    const SE3<S> T(expSO3<S>(Vec3<S>(S(theta) * axis)) * z.rotationMatrix(), t);
    cases.emplace_back(T, z);
  }
  for (const auto& c : cases) {
    const SE3<S>& T = c.first;
    const SE3<S>& z_i = c.second;
    Mat<S, 6, 6> J;
    posePriorResidual<S>(T, z_i, &J);
    const auto f = [&](const Vec<S, 6>& d) -> Vec<S, 6> {
      return posePriorResidual<S>(boxPlus(T, d), z_i);
    };
    const Mat<S, 6, 6> J_fd = test::fdJacobian<S, 6, 6>(f, Vec<S, 6>::Zero().eval());
    EXPECT_TRUE(test::matricesNear(J, J_fd, test::fdTolerance<S>(S(4), S(4))))
        << "|r_φ| = " << boxMinus(T, z_i).template tail<3>().norm();
  }
}

// Λ_t = Σ H_iᵀ A_i H_i over the paper's topology: eq. 16 returns every A_i, Λ_s = Λ_t and the KLD
// is 0 — with the anchor at the identity and near π.
TYPED_TEST(NfrTest, RecoversAPriorThatIsASumOfTopologyFactors) {
  using S = TypeParam;
  std::mt19937_64 rng(11);
  for (const Eigen::Vector3d& phi :
       {Eigen::Vector3d::Zero().eval(),
        ((M_PI - 1e-3) * Eigen::Vector3d(1, 2, -1).normalized()).eval()}) {
    const Blanket<double> x = imuStateWithLandmarks(rng, phi, 5);
    const NfrTopology topology = paperTopology(x, 0);
    std::vector<MatXd> A;
    const MatXd Lambda_t = sumOfFactors(rng, factorJacobians(x, topology), &A);
    const NfrProblem<S> problem(Lambda_t.cast<S>(), castBlanket<S>(x), topology);
    ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
    const Sparsification<S> sp = problem.recover();
    ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
    const int m = problem.reducedDim();
    const double tol = 100 * m * eps<S>() * conditionNumber(Lambda_t);
    expectExactRecovery(sp, A, Lambda_t, tol);
  }
}

// A generic dense prior (condition 100) the topology cannot represent: D > 0 at the closed form,
// the gradient of eq. 17 (formed with Λ̃_s⁻¹, not with the closed form) vanishes there, and every
// feasible perturbation of Λ_r — congruences M Λ_r Mᵀ and additive ones within the positive
// definite cone — raises D by more than its rounding.
TYPED_TEST(NfrTest, ClosedFormIsTheMinimumOfTheKld) {
  using S = TypeParam;
  std::mt19937_64 rng(12);
  const Blanket<double> x = imuStateWithLandmarks(rng, Eigen::Vector3d(0.3, -0.2, 1.1), 5);
  const int n = blanketDim(x);
  const MatXd Lambda_t = randomSpd(rng, n, 100.0);
  const NfrProblem<S> problem(Lambda_t.cast<S>(), castBlanket<S>(x), paperTopology(x, 0));
  ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
  const Sparsification<S> sp = problem.recover();
  ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
  const double kappa =
      std::max(conditionNumber(Lambda_t), conditionNumber(sp.Lambda_s.template cast<double>()));
  const double tol = 100 * n * eps<S>() * kappa;
  EXPECT_GT(double(sp.kld), tol);

  const std::vector<MatX<S>> Lambda_r = informationBlocks(sp);
  std::vector<MatX<S>> G;
  ASSERT_TRUE(problem.kldGradient(Lambda_r, &G).ok());
  for (size_t i = 0; i < G.size(); ++i) {
    const double scale = (Lambda_r[i].inverse()).template cast<double>().norm();
    EXPECT_LE(G[i].template cast<double>().norm(), tol * scale) << "factor " << i;
  }

  const double tol_increase = kldDifferenceTolerance(Lambda_r);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<MatX<S>> perturbed = Lambda_r;
    std::uniform_int_distribution<size_t> pick(0, perturbed.size() - 1);
    const size_t i = pick(rng);
    if (trial % 2 == 0) {
      perturbed[i] = congruence<S>(rng, perturbed[i], trial < 10 ? 0.1 : 0.5);
    } else {
      // Λ + s E with ‖s E‖₂ = ½ λ_min(Λ): stays positive definite.
      const int d = static_cast<int>(perturbed[i].rows());
      const MatXd E0 = randomGaussian(rng, d, d);
      const MatXd E = 0.5 * (E0 + E0.transpose());
      const MatXd L = perturbed[i].template cast<double>();
      const double lambda_min = Eigen::SelfAdjointEigenSolver<MatXd>(L).eigenvalues()[0];
      const double e_norm =
          Eigen::SelfAdjointEigenSolver<MatXd>(E).eigenvalues().cwiseAbs().maxCoeff();
      perturbed[i] = (L + 0.5 * lambda_min / e_norm * E).cast<S>();
    }
    const double increase = double(problem.kld(perturbed)) - double(sp.kld);
    EXPECT_GT(increase, tol_increase) << "trial " << trial << ", factor " << i;
  }
}

// ∂D along symmetric directions E_i = L_i S_i L_iᵀ (Λ_r^(i) = L_i L_iᵀ, ‖S_i‖₂ = 1) against central
// differences of D, away from the minimum. |d³D/dh³| ≤ Σ_i tr|(Λ_i⁻¹E_i)³| ≤ m; D is evaluated
// from terms of size ≤ Σ|log λ(Λ̃_t)| + 2m, which bounds its rounding.
TYPED_TEST(NfrTest, KldGradientMatchesCentralDifferences) {
  using S = TypeParam;
  std::mt19937_64 rng(13);
  const Blanket<double> x = imuStateWithLandmarks(rng, Eigen::Vector3d(-0.4, 0.2, 2.0), 4);
  const int n = blanketDim(x);
  const MatXd Lambda_t = randomSpd(rng, n, 30.0);
  const NfrProblem<S> problem(Lambda_t.cast<S>(), castBlanket<S>(x), paperTopology(x, 0));
  ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
  std::vector<MatX<S>> Lambda_r = informationBlocks(problem.recover());
  for (auto& block : Lambda_r) block = congruence<S>(rng, block, 0.5);
  std::vector<MatX<S>> G;
  ASSERT_TRUE(problem.kldGradient(Lambda_r, &G).ok());

  std::vector<MatX<S>> E;
  double directional = 0;
  for (size_t i = 0; i < Lambda_r.size(); ++i) {
    const int d = static_cast<int>(Lambda_r[i].rows());
    const MatXd L = Eigen::LLT<MatXd>(Lambda_r[i].template cast<double>()).matrixL();
    const MatXd S0 = randomGaussian(rng, d, d);
    MatXd Si = 0.5 * (S0 + S0.transpose());
    Si /= Eigen::SelfAdjointEigenSolver<MatXd>(Si).eigenvalues().cwiseAbs().maxCoeff();
    E.push_back((L * Si * L.transpose()).cast<S>());
    directional +=
        0.5 * G[i].template cast<double>().cwiseProduct(E[i].template cast<double>()).sum();
  }
  const S h = test::fdStep<S>();
  std::vector<MatX<S>> plus = Lambda_r, minus = Lambda_r;
  for (size_t i = 0; i < Lambda_r.size(); ++i) {
    plus[i] += h * E[i];
    minus[i] -= h * E[i];
  }
  const double fd = (double(problem.kld(plus)) - double(problem.kld(minus))) / (2 * double(h));
  const VecXd lambda = Eigen::SelfAdjointEigenSolver<MatXd>(Lambda_t).eigenvalues();
  const double f_scale = lambda.array().log().abs().sum() + 2 * n;
  EXPECT_NEAR(fd, directional, double(test::fdTolerance<S>(S(f_scale), S(n))));
}

// D ≥ 0 for random dense priors and random feasible Λ_r; +∞ off the positive definite cone; NaN
// for blocks that do not fit the topology.
TYPED_TEST(NfrTest, KldIsNonNegative) {
  using S = TypeParam;
  std::mt19937_64 rng(14);
  for (int trial = 0; trial < 8; ++trial) {
    const Blanket<double> x =
        imuStateWithLandmarks(rng, Eigen::Vector3d(0.1 * trial, 0.5, -0.3), 3);
    const int n = blanketDim(x);
    const double cond = trial % 2 == 0 ? 10.0 : 100.0;
    const MatXd Lambda_t = randomSpd(rng, n, cond);
    const NfrProblem<S> problem(Lambda_t.cast<S>(), castBlanket<S>(x), paperTopology(x, 0));
    ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
    const Sparsification<S> sp = problem.recover();
    ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
    const double tol = 100 * n * eps<S>() * cond;
    EXPECT_GE(double(sp.kld), -tol);
    std::vector<MatX<S>> random_blocks;
    for (const auto& f : sp.factors) {
      const int d = static_cast<int>(f.rows.size());
      const double scale = std::exp(randomGaussian(rng, 1, 1)(0, 0));
      random_blocks.push_back((scale * randomSpd(rng, d, 50.0)).cast<S>());
    }
    EXPECT_GE(double(problem.kld(random_blocks)), double(sp.kld) - tol) << "trial " << trial;
    random_blocks[0](0, 0) = -random_blocks[0](0, 0);
    EXPECT_EQ(problem.kld(random_blocks), std::numeric_limits<S>::infinity());
    random_blocks.pop_back();
    EXPECT_TRUE(std::isnan(problem.kld(random_blocks)));
  }
}

// The gauge-free prior (nullspace x, y, z, yaw): refused without a gauge reference and with one
// that does not fix the nullspace; with the anchor's position and δφ_z held, the closed form is
// the minimum on S, D ≥ 0, the pose factor measures roll and pitch only, and Λ_s keeps the
// translation gauge in its nullspace.
TYPED_TEST(NfrTest, GaugeFreePriorIsSparsifiedGivenAReference) {
  using S = TypeParam;
  std::mt19937_64 rng(15);
  const Blanket<double> x = imuStateWithLandmarks(rng, Eigen::Vector3d(0.2, -0.1, 0.7), 5);
  const int n = blanketDim(x);
  const MatXd Lambda_t = gaugeFreePrior(rng, x);
  const MatXd N = gaugeBasis(x);
  ASSERT_LE((Lambda_t * N).norm(), 1e-12 * Lambda_t.norm() * N.norm());  // the construction
  const NfrTopology topology = paperTopology(x, 0);
  const Blanket<S> x_s = castBlanket<S>(x);

  const NfrProblem<S> no_reference(Lambda_t.cast<S>(), x_s, topology);
  EXPECT_EQ(no_reference.status().code(), Status::Code::kRankDeficient);
  EXPECT_NE(no_reference.status().message().find("gauge reference"), std::string::npos)
      << no_reference.status().message();
  EXPECT_TRUE(std::isnan(no_reference.kld({})));
  // Roll, pitch and two velocity components do not move under a translation.
  const NfrProblem<S> wrong_reference(Lambda_t.cast<S>(), x_s, topology, {3, 4, 6, 7});
  EXPECT_EQ(wrong_reference.status().code(), Status::Code::kRankDeficient);

  const std::vector<int> reference = vioGaugeReference(x[0].offset);
  const NfrProblem<S> problem(Lambda_t.cast<S>(), x_s, topology, reference);
  ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
  EXPECT_EQ(problem.reducedDim(), n - 4);
  const Sparsification<S> sp = problem.recover();
  ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
  const std::vector<int> kept = columnsOutside(n, reference);
  const MatXd Lambda_red = Lambda_t(kept, kept);
  const MatXd Lambda_s = sp.Lambda_s.template cast<double>();
  const MatXd Lambda_s_red = Lambda_s(kept, kept);
  const int m = problem.reducedDim();
  const double tol =
      100 * m * eps<S>() * std::max(conditionNumber(Lambda_red), conditionNumber(Lambda_s_red));
  EXPECT_GE(double(sp.kld), -tol);

  const std::vector<MatX<S>> Lambda_r = informationBlocks(sp);
  std::vector<MatX<S>> G;
  ASSERT_TRUE(problem.kldGradient(Lambda_r, &G).ok());
  for (size_t i = 0; i < G.size(); ++i) {
    const double scale = (Lambda_r[i].inverse()).template cast<double>().norm();
    EXPECT_LE(G[i].template cast<double>().norm(), tol * scale) << "factor " << i;
  }
  const double tol_increase = kldDifferenceTolerance(Lambda_r);
  for (int trial = 0; trial < 10; ++trial) {
    std::vector<MatX<S>> perturbed = Lambda_r;
    const size_t i = static_cast<size_t>(trial) % perturbed.size();
    perturbed[i] = congruence<S>(rng, perturbed[i], 0.3);
    EXPECT_GT(double(problem.kld(perturbed)) - double(sp.kld), tol_increase) << "factor " << i;
  }

  ASSERT_EQ(sp.factors[0].spec.var, 0);
  EXPECT_EQ(sp.factors[0].rows, (std::vector<int>{3, 4}));
  for (int c : {0, 1, 2, 5}) EXPECT_TRUE(sp.factors[0].sqrt_information.col(c).isZero());
  EXPECT_LE((Lambda_s * N.leftCols(3)).norm(), tol * Lambda_s.norm() * N.leftCols(3).norm());
}

// A prior that is a sum of the reference-reduced topology's factors (the pose factor on roll and
// pitch only; rank n − 3) is recovered exactly on S: the factors' information and D = 0.
TYPED_TEST(NfrTest, RecoversAReducedTopologyPriorGivenAReference) {
  using S = TypeParam;
  std::mt19937_64 rng(16);
  const Blanket<double> x = imuStateWithLandmarks(rng, Eigen::Vector3d(0.5, 0.3, -2.5), 4);
  const NfrTopology topology = paperTopology(x, 0);
  const std::vector<int> reference = vioGaugeReference(x[0].offset);
  std::vector<MatXd> A;
  const MatXd Lambda_t = sumOfFactors(rng, factorJacobians(x, topology, reference), &A);
  const NfrProblem<S> problem(Lambda_t.cast<S>(), castBlanket<S>(x), topology, reference);
  ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
  const Sparsification<S> sp = problem.recover();
  ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
  const std::vector<int> kept = columnsOutside(blanketDim(x), reference);
  const int m = problem.reducedDim();
  const double tol = 100 * m * eps<S>() * conditionNumber(Lambda_t(kept, kept));
  expectExactRecovery(sp, A, Lambda_t, tol);
}

// The square-root factors of sp: zero residuals at x̄ whose Jacobians give Λ_s = Σ J_iᵀ J_i, and
// Jacobians of W S (h(x) ⊟ z) equal to central differences at a state 0.1–0.2 away from x̄.
template <typename S>
void expectSquareRootFactors(std::mt19937_64& rng, const Blanket<double>& x,
                             const Sparsification<S>& sp) {
  ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
  const int n = blanketDim(x);
  const Blanket<S> x_s = castBlanket<S>(x);
  Blanket<S> x_moved = x_s;
  for (auto& v : x_moved) {
    const Vec<S, 6> d = (0.1 * randomGaussian(rng, 6, 1)).cast<S>();
    if (v.kind == BlanketKind::kPose) {
      v.T_w_i = boxPlus(v.T_w_i, d);
    } else {
      v.value += d.head(v.value.size());
    }
  }
  MatXd Lambda_from_sqrt = MatXd::Zero(n, n);
  for (const RecoveredFactor<S>& f : sp.factors) {
    std::vector<int> cols;
    for (int v : {f.spec.var, f.spec.landmark, f.spec.pose_b}) {
      if (v < 0) continue;
      for (int k = 0; k < blanketKindDim(x[v].kind); ++k) cols.push_back(x[v].offset + k);
    }
    MatX<S> J;
    EXPECT_TRUE(f.whitenedResidual(x_s, &J).isZero());
    Lambda_from_sqrt(cols, cols) += (J.transpose() * J).template cast<double>();

    f.whitenedResidual(x_moved, &J);
    const int d = static_cast<int>(cols.size());
    const auto residual_at = [&](const VecX<S>& delta) {
      Blanket<S> x_d = x_moved;
      int k = 0;
      for (int v : {f.spec.var, f.spec.landmark, f.spec.pose_b}) {
        if (v < 0) continue;
        const int dim = blanketKindDim(x[v].kind);
        if (x[v].kind == BlanketKind::kPose) {
          x_d[v].T_w_i = boxPlus(x_d[v].T_w_i, Vec<S, 6>(delta.segment(k, 6)));
        } else {
          x_d[v].value += delta.segment(k, dim);
        }
        k += dim;
      }
      return f.whitenedResidual(x_d);
    };
    MatX<S> J_fd(J.rows(), d);
    const S h = test::fdStep<S>();
    for (int k = 0; k < d; ++k) {
      VecX<S> delta = VecX<S>::Zero(d);
      delta[k] = h;
      const VecX<S> r_plus = residual_at(delta);
      delta[k] = -h;
      J_fd.col(k) = (r_plus - residual_at(delta)) / (2 * h);
    }
    // The whitened residual is W times one of the residuals above: scale by ‖W‖.
    const S w = S(f.sqrt_information.template cast<double>().norm());
    EXPECT_TRUE(test::matricesNear(J, J_fd, double(w * test::fdTolerance<S>(S(8), S(5)))));
  }
  const MatXd Lambda_s = sp.Lambda_s.template cast<double>();
  EXPECT_LE(relError(Lambda_from_sqrt, Lambda_s), 100 * n * eps<S>());
}

// The square-root form of the paper topology (a gauge-free prior, with a reference) and of the
// relative-pose topology (its pose chain at rotations up to π).
TYPED_TEST(NfrTest, SquareRootFactorsReproduceTheSparseInformation) {
  using S = TypeParam;
  std::mt19937_64 rng(17);
  const Blanket<double> x = imuStateWithLandmarks(rng, Eigen::Vector3d(2.0, -1.0, 0.5), 3);
  const MatXd Lambda_t = gaugeFreePrior(rng, x);
  expectSquareRootFactors<S>(rng, x,
                             sparsify<S>(Lambda_t.cast<S>(), castBlanket<S>(x), paperTopology(x, 0),
                                         vioGaugeReference(0)));
  const Blanket<double> chain = posesWithLandmarks(rng, chainRotations(), 3);
  const MatXd Lambda_chain = gaugeFreeChainPrior(rng, chain, 4);
  expectSquareRootFactors<S>(
      rng, chain,
      sparsify<S>(Lambda_chain.cast<S>(), castBlanket<S>(chain), chainTopology(chain, 4),
                  vioGaugeReference(chain[3].offset)));
}

TYPED_TEST(NfrTest, BadInputIsAStatus) {
  using S = TypeParam;
  std::mt19937_64 rng(18);
  const Blanket<double> x = imuStateWithLandmarks(rng, Eigen::Vector3d(0.1, 0.2, 0.3), 2);
  const int n = blanketDim(x);
  const Blanket<S> x_s = castBlanket<S>(x);
  const MatX<S> Lambda_t = randomSpd(rng, n, 10.0).cast<S>();
  const NfrTopology topology = paperTopology(x, 0);
  const auto code = [&](const MatX<S>& L, const Blanket<S>& b, const NfrTopology& t,
                        const std::vector<int>& ref = {}) {
    return NfrProblem<S>(L, b, t, ref).status().code();
  };
  using Code = Status::Code;
  EXPECT_EQ(code(Lambda_t, x_s, topology), Code::kOk);
  EXPECT_EQ(code(Lambda_t.leftCols(n - 1), x_s, topology), Code::kInvalidArgument);
  MatX<S> with_nan = Lambda_t;
  with_nan(3, 2) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_EQ(code(with_nan, x_s, topology), Code::kNotFinite);
  Blanket<S> overlapping = x_s;
  overlapping[1].offset = 4;
  EXPECT_EQ(code(Lambda_t, overlapping, topology), Code::kInvalidArgument);
  Blanket<S> short_value = x_s;
  short_value[2].value.resize(3);
  EXPECT_EQ(code(Lambda_t, short_value, topology), Code::kInvalidArgument);
  NfrTopology missing = topology;
  missing.pop_back();
  EXPECT_EQ(code(Lambda_t, x_s, missing), Code::kInvalidArgument);
  NfrTopology landmark_unary = topology;
  landmark_unary.back() = {NfrFactorKind::kUnary, 3, -1};
  EXPECT_EQ(code(Lambda_t, x_s, landmark_unary), Code::kInvalidArgument);
  EXPECT_EQ(code(Lambda_t, x_s, topology, {15}), Code::kInvalidArgument);  // a landmark column
  EXPECT_EQ(code(Lambda_t, x_s, topology, {0, 0}), Code::kInvalidArgument);
  // Square but singular: the pose is measured by nothing but the landmarks are measured twice.
  const NfrTopology singular = {
      {NfrFactorKind::kUnary, 1, -1},       {NfrFactorKind::kUnary, 2, -1},
      {NfrFactorKind::kPoseLandmark, 0, 3}, {NfrFactorKind::kPoseLandmark, 0, 3},
      {NfrFactorKind::kPoseLandmark, 0, 4}, {NfrFactorKind::kPoseLandmark, 0, 4}};
  EXPECT_EQ(code(Lambda_t, x_s, singular), Code::kRankDeficient);
  // A relative-pose factor needs two different poses.
  const NfrTopology relative_to_itself = {{NfrFactorKind::kRelativePose, 0, -1, 0}};
  EXPECT_EQ(code(Lambda_t, x_s, relative_to_itself), Code::kInvalidArgument);
  const NfrTopology relative_to_landmark = {{NfrFactorKind::kRelativePose, 0, -1, 3}};
  EXPECT_EQ(code(Lambda_t, x_s, relative_to_landmark), Code::kInvalidArgument);
  const Sparsification<S> failed = sparsify<S>(Lambda_t, x_s, missing);
  EXPECT_FALSE(failed.status.ok());
  EXPECT_TRUE(failed.factors.empty());
  EXPECT_TRUE(std::isnan(failed.kld));
}

// r = [R_aᵀ(t_b − t_a) − t_z; log(R_aᵀ R_b R_zᵀ)] at every pair of hard rotations (z 0.4 rad
// away), and with the residual rotation itself at 0 … π − 0.1. |r| ≤ 8 and the third derivatives
// ≲ |t_b − t_a| + 1 ≈ 5 for these inputs.
TYPED_TEST(NfrTest, RelativePoseJacobiansMatchCentralDifferences) {
  using S = TypeParam;
  const Vec3<S> t_a(S(1), S(-2), S(0.5)), t_b(S(3), S(1), S(-1));
  Vec<S, 6> offset;
  offset << S(0.1), S(-0.2), S(0.05), S(0.2), S(-0.1), S(0.3);
  std::vector<std::tuple<SE3<S>, SE3<S>, SE3<S>>> cases;  // (T_a, T_b, z)
  const std::vector<Vec3<S>> phis = test::hardRotationVectors<S>();
  for (size_t i = 0; i < phis.size(); ++i) {
    const SE3<S> T_a(expSO3<S>(phis[i]), t_a);
    const SE3<S> T_b(expSO3<S>(phis[phis.size() - 1 - i]), t_b);
    cases.emplace_back(T_a, T_b, boxPlus(SE3<S>(T_a.inverse() * T_b), offset));
  }
  const Vec3<S> axis = Vec3<S>(S(0.3), S(-0.5), S(0.8)).normalized();
  const SE3<S> T_a(expSO3<S>(Vec3<S>(S(0.4), S(1.0), S(-0.2))), t_a);
  const SE3<S> T_b(expSO3<S>(Vec3<S>(S(-2.0), S(0.5), S(1.0))), t_b);
  for (double theta : {0.0, double(test::tinyAngle<S>()), 1e-3, 0.5, 1.0, 2.0, 3.0, M_PI - 0.1}) {
    // log(R_aᵀ R_b R_zᵀ) = θ axis.
    const Mat3<S> R_z = expSO3<S>(Vec3<S>(S(theta) * axis)).transpose() *
                        T_a.rotationMatrix().transpose() * T_b.rotationMatrix();
    cases.emplace_back(T_a, T_b, SE3<S>(R_z, Vec3<S>(S(0.2), S(0.1), S(-0.3))));
  }
  for (const auto& [T_a_i, T_b_i, z] : cases) {
    Mat<S, 6, 6> J_a, J_b;
    relativePoseResidual<S>(T_a_i, T_b_i, z, &J_a, &J_b);
    const auto f = [&](const Vec<S, 12>& d) -> Vec<S, 6> {
      return relativePoseResidual<S>(boxPlus(T_a_i, Vec<S, 6>(d.template head<6>())),
                                     boxPlus(T_b_i, Vec<S, 6>(d.template tail<6>())), z);
    };
    Mat<S, 6, 12> J;
    J << J_a, J_b;
    const Mat<S, 6, 12> J_fd = test::fdJacobian<S, 6, 12>(f, Vec<S, 12>::Zero().eval());
    EXPECT_TRUE(test::matricesNear(J, J_fd, test::fdTolerance<S>(S(8), S(5))))
        << "θ_a = " << logSO3<S>(T_a_i.unitQuaternion()).norm()
        << ", |r_φ| = " << relativePoseResidual<S>(T_a_i, T_b_i, z).template tail<3>().norm();
  }
}

// Λ_t = Σ H_iᵀ A_i H_i over the relative-pose topology (poses at 0, near π, π and generic): eq. 16
// returns every A_i, Λ_s = Λ_t and D = 0 — full rank, and rank-deficient with the gauge held by a
// reference (the anchor's unary factor on roll and pitch only: Λ_t has rank n − 4).
TYPED_TEST(NfrTest, RelativePoseTopologyRecoversASumOfItsFactors) {
  using S = TypeParam;
  std::mt19937_64 rng(19);
  const Blanket<double> x = posesWithLandmarks(rng, chainRotations(), 4);
  const NfrTopology topology = chainTopology(x, 4);
  for (const std::vector<int>& reference : {std::vector<int>{}, vioGaugeReference(x[3].offset)}) {
    std::vector<MatXd> A;
    const MatXd Lambda_t = sumOfFactors(rng, factorJacobians(x, topology, reference), &A);
    const NfrProblem<S> problem(Lambda_t.cast<S>(), castBlanket<S>(x), topology, reference);
    ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
    const Sparsification<S> sp = problem.recover();
    ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
    const std::vector<int> kept = columnsOutside(blanketDim(x), reference);
    const int m = problem.reducedDim();
    EXPECT_EQ(m, blanketDim(x) - static_cast<int>(reference.size()));
    const double tol = 100 * m * eps<S>() * conditionNumber(Lambda_t(kept, kept));
    expectExactRecovery(sp, A, Lambda_t, tol);
  }
}

// Priors the relative-pose topology cannot represent — a generic dense one and the gauge-free
// chain prior (nullspace x, y, z, yaw) with the anchor's position and yaw held — against the
// tree's optimum computed independently (treeOptimum: dense inverse, block marginals, LU
// determinants): the same Λ_r^(i) and D, D > 0, the gradient of eq. 17 zero. The gauge-free
// prior is refused without a reference, and Λ_s keeps the translation gauge in its nullspace
// (the relative-pose and pose–landmark factors are invariant under a rigid motion).
TYPED_TEST(NfrTest, RelativePoseTopologyIsTheTreeOptimum) {
  using S = TypeParam;
  std::mt19937_64 rng(20);
  const Blanket<double> x = posesWithLandmarks(rng, chainRotations(), 3);
  const int n = blanketDim(x);
  const NfrTopology topology = chainTopology(x, 4);
  const MatXd gauge_free = gaugeFreeChainPrior(rng, x, 4);
  const MatXd N = gaugeBasis(x);
  ASSERT_LE((gauge_free * N).norm(), 1e-12 * gauge_free.norm() * N.norm());  // the construction
  const NfrProblem<S> no_reference(gauge_free.cast<S>(), castBlanket<S>(x), topology);
  EXPECT_EQ(no_reference.status().code(), Status::Code::kRankDeficient);

  const std::vector<int> reference = vioGaugeReference(x[3].offset);
  for (const bool gauge : {false, true}) {
    const MatXd Lambda_t = gauge ? gauge_free : randomSpd(rng, n, 100.0);
    const std::vector<int> ref = gauge ? reference : std::vector<int>{};
    const NfrProblem<S> problem(Lambda_t.cast<S>(), castBlanket<S>(x), topology, ref);
    ASSERT_TRUE(problem.status().ok()) << problem.status().toString();
    const Sparsification<S> sp = problem.recover();
    ASSERT_TRUE(sp.status.ok()) << sp.status.toString();
    const std::vector<int> kept = columnsOutside(n, ref);
    const MatXd Lambda_s = sp.Lambda_s.template cast<double>();
    const int m = problem.reducedDim();
    const double tol = 100 * m * eps<S>() *
                       std::max(conditionNumber(Lambda_t(kept, kept)),
                                conditionNumber(MatXd(Lambda_s(kept, kept))));
    const TreeOptimum expected = treeOptimum(Lambda_t, x, topology, ref);
    ASSERT_EQ(sp.factors.size(), expected.information.size());
    for (size_t i = 0; i < sp.factors.size(); ++i) {
      EXPECT_LE(
          relError(sp.factors[i].information.template cast<double>(), expected.information[i]), tol)
          << "factor " << i << (gauge ? ", gauge-free" : "");
    }
    EXPECT_NEAR(double(sp.kld), expected.kld, tol) << (gauge ? "gauge-free" : "");
    EXPECT_GT(double(sp.kld), tol);

    const std::vector<MatX<S>> Lambda_r = informationBlocks(sp);
    std::vector<MatX<S>> G;
    ASSERT_TRUE(problem.kldGradient(Lambda_r, &G).ok());
    for (size_t i = 0; i < G.size(); ++i) {
      const double scale = (Lambda_r[i].inverse()).template cast<double>().norm();
      EXPECT_LE(G[i].template cast<double>().norm(), tol * scale) << "factor " << i;
    }
    if (gauge) {
      EXPECT_LE((Lambda_s * N.leftCols(3)).norm(), tol * Lambda_s.norm() * N.leftCols(3).norm());
    }
  }
}

}  // namespace
}  // namespace marglab
