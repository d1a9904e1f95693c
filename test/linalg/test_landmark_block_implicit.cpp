// The implicit nullspace projection (core/linalg/landmark_block_implicit.h) against an independent
// computation: the projector onto the left nullspace of the damped [J_l; diag(√d)] from its SVD,
// applied in double, and the Schur complement's back-substitution in double; against the explicit
// reduced rows of LandmarkBlockNs; in both precisions, well-conditioned, near-singular and
// rank-deficient landmarks.

#include <Eigen/Dense>

#include "core/linalg/landmark_block.h"
#include "core/linalg/landmark_block_implicit.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::eps;

constexpr int kDim = 9;  // a BAL camera
constexpr int kCameras = 6;
constexpr int kRcs = kDim * kCameras;

struct Landmark {
  PoseBlockMap map;
  Mat<double, Eigen::Dynamic, kDim> J_obs;  // rows 2j, 2j+1: observation j's camera block
  Mat<double, Eigen::Dynamic, 3> J_l;
  VecXd r;
  Eigen::Vector3d d = Eigen::Vector3d::Zero();  // landmark damping
};

// n observations in distinct cameras; J_l = A · diag(1, 1, shrink) · B with orthogonal B, so
// κ(J_l) ≈ 1 / shrink (shrink = 0: rank 2).
Landmark makeLandmark(std::mt19937_64& rng, int n, double shrink, double damping) {
  Landmark lm;
  lm.map.pose_dim = kDim;
  std::vector<int> cameras(kCameras);
  std::iota(cameras.begin(), cameras.end(), 0);
  std::shuffle(cameras.begin(), cameras.end(), rng);
  for (int j = 0; j < n; ++j) lm.map.rcs_offset.push_back(kDim * cameras[j]);
  lm.J_obs = test::randomGaussian(rng, 2 * n, kDim);
  const Eigen::Matrix3d B =
      Eigen::HouseholderQR<Eigen::Matrix3d>(test::randomGaussian(rng, 3, 3)).householderQ();
  lm.J_l = test::randomGaussian(rng, 2 * n, 3) * Eigen::Vector3d(1, 1, shrink).asDiagonal() * B;
  lm.r = test::randomGaussian(rng, 2 * n, 1);
  lm.d.setConstant(damping);
  return lm;
}

// The landmark's rows over the whole reduced camera system, the damping rows below (zero there).
MatXd fullJp(const Landmark& lm) {
  const Eigen::Index m = lm.J_l.rows();
  MatXd J = MatXd::Zero(m + 3, kRcs);
  for (size_t j = 0; j < lm.map.rcs_offset.size(); ++j) {
    J.block(2 * j, lm.map.rcs_offset[j], 2, kDim) = lm.J_obs.middleRows<2>(2 * j);
  }
  return J;
}

// I − Q1Q1ᵀ for the damped [J_l; diag(√d)], Q1 from the SVD (an algorithm independent of the
// Householder QR under test), and κ of that matrix.
MatXd nullspaceProjector(const Landmark& lm, double* kappa) {
  const Eigen::Index m = lm.J_l.rows();
  MatXd A(m + 3, 3);
  A << lm.J_l, lm.d.cwiseSqrt().asDiagonal().toDenseMatrix();
  const Eigen::JacobiSVD<MatXd> svd(A, Eigen::ComputeThinU);
  *kappa = svd.singularValues()(0) / svd.singularValues()(2);
  return MatXd::Identity(m + 3, m + 3) - svd.matrixU() * svd.matrixU().transpose();
}

template <typename Scalar>
LandmarkBlockNsImplicit<Scalar, kDim> makeBlock(const Landmark& lm) {
  LandmarkBlockNsImplicit<Scalar, kDim> block;
  EXPECT_TRUE(block
                  .setFromJacobians(lm.J_obs.cast<Scalar>(), lm.J_l.cast<Scalar>(),
                                    lm.r.cast<Scalar>(), lm.map)
                  .ok());
  block.setLandmarkDamping(lm.d.cast<Scalar>());
  return block;
}

template <typename Scalar>
class LandmarkBlockImplicitTest : public ::testing::Test {};
TYPED_TEST_SUITE(LandmarkBlockImplicitTest, test::Scalars, test::ScalarName);

// S_l = J_pᵀ P J_p, g_l = J_pᵀ P r, their camera blocks and products. The QR's Q1 is orthonormal
// to about m ε and moves by ε κ under rounding of the input, so every quantity is within
// c · m · ε · κ · ‖J‖² of the projector's (‖J‖ including r); c = 10 covers the accumulation.
template <typename Scalar>
void checkAgainstTheProjector(double shrink, double damping) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Landmark lm = makeLandmark(rng, 2 + trial % 4, shrink, damping);
    double kappa = 0;
    const MatXd P = nullspaceProjector(lm, &kappa);
    const MatXd J = fullJp(lm);
    VecXd r_full = VecXd::Zero(J.rows());
    r_full.head(lm.r.size()) = lm.r;
    const MatXd S_ref = J.transpose() * P * J;
    const VecXd g_ref = J.transpose() * P * r_full;
    const auto block = makeBlock<Scalar>(lm);
    const double scale = J.squaredNorm() + r_full.squaredNorm();
    const double tol = 10.0 * lm.r.size() * eps<Scalar>() * kappa * scale;

    MatXd S = MatXd::Zero(kRcs, kRcs);
    VecXd g = VecXd::Zero(kRcs);
    MatX<Scalar> S_s = MatX<Scalar>::Zero(kRcs, kRcs);
    VecX<Scalar> g_s = VecX<Scalar>::Zero(kRcs);
    ASSERT_TRUE(block.addToReducedSystem(S_s, g_s).ok());
    S = S_s.template cast<double>();
    g = g_s.template cast<double>();
    EXPECT_LE((S - S_ref).norm(), tol) << "trial " << trial << " κ " << kappa;
    EXPECT_LE((g - g_ref).norm(), tol) << "trial " << trial;

    const VecXd x = test::randomGaussian(rng, kRcs, 1);
    const int n = static_cast<int>(lm.map.rcs_offset.size());
    VecX<Scalar> t(2 * n), y(kDim * n);
    block.reducedProduct(x.cast<Scalar>(), t.data(), y.data());
    VecX<Scalar> y_g(kDim * n);
    block.reducedGradient(y_g.data());
    const VecXd Sx = S_ref * x;
    for (int j = 0; j < n; ++j) {
      const int o = lm.map.rcs_offset[j];
      EXPECT_LE(
          (y.template segment<kDim>(kDim * j).template cast<double>() - Sx.segment<kDim>(o)).norm(),
          tol * x.norm());
      EXPECT_LE(
          (y_g.template segment<kDim>(kDim * j).template cast<double>() - g_ref.segment<kDim>(o))
              .norm(),
          tol);
      EXPECT_LE(
          (block.reducedCameraBlock(j).template cast<double>() - S_ref.block(o, o, kDim, kDim))
              .norm(),
          tol);
    }
  }
}

TYPED_TEST(LandmarkBlockImplicitTest, ReducedSystemIsTheSvdProjectorsWellConditioned) {
  checkAgainstTheProjector<TypeParam>(0.5, 0.0);
  checkAgainstTheProjector<TypeParam>(0.5, 0.3);
}

// κ(J_l) ≈ 1e3 (float) / 1e6 (double): the bound grows with κ and still holds.
TYPED_TEST(LandmarkBlockImplicitTest, ReducedSystemIsTheSvdProjectorsNearSingular) {
  const double shrink = std::is_same_v<TypeParam, float> ? 1e-3 : 1e-6;
  checkAgainstTheProjector<TypeParam>(shrink, 0.0);
}

// J_l of rank 2: the damping makes the landmark eliminable, with κ ≈ ‖J_l‖ / √d.
TYPED_TEST(LandmarkBlockImplicitTest, RankDeficientLandmarkWithDamping) {
  checkAgainstTheProjector<TypeParam>(0.0, 1e-2);
}

// The same reduced system as the explicit rows Q2ᵀJ_p of LandmarkBlockNs, within the sum of both
// storages' bounds.
TYPED_TEST(LandmarkBlockImplicitTest, AgreesWithTheExplicitReducedRows) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    const Landmark lm = makeLandmark(rng, 2 + trial % 4, 0.3, trial % 2 ? 0.1 : 0.0);
    double kappa = 0;
    nullspaceProjector(lm, &kappa);
    const int n = static_cast<int>(lm.map.rcs_offset.size());
    MatXd J_dense = MatXd::Zero(2 * n, kDim * n);
    for (int j = 0; j < n; ++j)
      J_dense.block<2, kDim>(2 * j, kDim * j) = lm.J_obs.middleRows<2>(2 * j);
    LandmarkBlockNs<Scalar> explicit_block;
    ASSERT_TRUE(explicit_block
                    .setFromJacobians(J_dense.cast<Scalar>(), lm.J_l.cast<Scalar>(),
                                      lm.r.cast<Scalar>(), lm.map)
                    .ok());
    explicit_block.setLandmarkDamping(lm.d.cast<Scalar>());
    const auto implicit_block = makeBlock<Scalar>(lm);
    MatX<Scalar> S_e = MatX<Scalar>::Zero(kRcs, kRcs), S_i = S_e;
    VecX<Scalar> g_e = VecX<Scalar>::Zero(kRcs), g_i = g_e;
    ASSERT_TRUE(explicit_block.addToReducedSystem(S_e, g_e).ok());
    ASSERT_TRUE(implicit_block.addToReducedSystem(S_i, g_i).ok());
    const double scale = fullJp(lm).squaredNorm() + lm.r.squaredNorm();
    const double tol = 20.0 * 2 * n * eps<Scalar>() * kappa * scale;
    EXPECT_LE((S_e - S_i).template cast<double>().norm(), tol) << "trial " << trial;
    EXPECT_LE((g_e - g_i).template cast<double>().norm(), tol) << "trial " << trial;
  }
}

// δl = −(H_ll + diag(d))⁻¹ (b_l + H_lp δp) in double (the Schur complement's formula), and the
// undamped model change ½‖J_p δp + J_l δl + r‖² − ½‖r‖² evaluated directly in double.
TYPED_TEST(LandmarkBlockImplicitTest, BackSubstitutionAndModelChangeMatchTheSchurFormulas) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    const Landmark lm = makeLandmark(rng, 2 + trial % 4, 0.4, trial % 2 ? 0.2 : 0.0);
    double kappa = 0;
    nullspaceProjector(lm, &kappa);
    const auto block = makeBlock<Scalar>(lm);
    const VecXd delta_rcs = test::randomGaussian(rng, kRcs, 1);
    const MatXd J_p = fullJp(lm).topRows(lm.r.size());
    const Eigen::Matrix3d H_ll = lm.J_l.transpose() * lm.J_l + Eigen::Matrix3d(lm.d.asDiagonal());
    const Eigen::Vector3d expected =
        -H_ll.ldlt().solve(lm.J_l.transpose() * (lm.r + J_p * delta_rcs));
    Vec3<Scalar> delta_l;
    ASSERT_TRUE(block.backSubstitute(delta_rcs.cast<Scalar>(), &delta_l).ok());
    // The solve through R1ᵈ amplifies the rounding by κ, relative to the right-hand side's scale.
    const double rhs = (lm.r + J_p * delta_rcs).norm() * lm.J_l.norm();
    const double tol = 10.0 * lm.r.size() * eps<Scalar>() * kappa * kappa * rhs /
                       H_ll.eigenvalues().real().minCoeff();
    EXPECT_LE((delta_l.template cast<double>() - expected).norm(), tol) << "trial " << trial;

    const VecXd e = J_p * delta_rcs + lm.J_l * expected;
    const double change_expected = e.dot(lm.r) + 0.5 * e.squaredNorm();
    const double change =
        double(block.linearizedCostChange(delta_rcs.cast<Scalar>(), expected.cast<Scalar>()));
    EXPECT_NEAR(change, change_expected,
                10.0 * lm.r.size() * eps<Scalar>() * (e.norm() + lm.r.norm()) * e.norm());
  }
}

// A landmark column of zeros: R1 has an exact zero pivot. Undamped it cannot be eliminated (a
// status, not a crash); damped it can.
TYPED_TEST(LandmarkBlockImplicitTest, UnobservableLandmarkIsAStatus) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(3);
  Landmark lm = makeLandmark(rng, 3, 1.0, 0.0);
  lm.J_l.col(1).setZero();
  auto block = makeBlock<Scalar>(lm);
  EXPECT_FALSE(block.landmarkSolvable());
  MatX<Scalar> S = MatX<Scalar>::Zero(kRcs, kRcs);
  VecX<Scalar> g = VecX<Scalar>::Zero(kRcs);
  EXPECT_EQ(block.addToReducedSystem(S, g).code(), Status::Code::kRankDeficient);
  EXPECT_EQ(S.norm(), 0);
  Vec3<Scalar> delta_l;
  EXPECT_EQ(block.backSubstitute(VecX<Scalar>::Zero(kRcs), &delta_l).code(),
            Status::Code::kRankDeficient);
  block.setLandmarkDamping(Vec3<Scalar>::Constant(Scalar(0.1)));
  EXPECT_TRUE(block.landmarkSolvable());
  EXPECT_TRUE(block.backSubstitute(VecX<Scalar>::Zero(kRcs), &delta_l).ok());
}

TYPED_TEST(LandmarkBlockImplicitTest, InconsistentOrNonFiniteInputIsAStatus) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(9);
  const Landmark lm = makeLandmark(rng, 3, 1.0, 0.0);
  LandmarkBlockNsImplicit<Scalar, kDim> block;
  PoseBlockMap short_map = lm.map;
  short_map.rcs_offset.pop_back();  // two blocks for three observations' rows
  EXPECT_EQ(block
                .setFromJacobians(lm.J_obs.cast<Scalar>(), lm.J_l.cast<Scalar>(),
                                  lm.r.cast<Scalar>(), short_map)
                .code(),
            Status::Code::kInvalidArgument);
  VecX<Scalar> r = lm.r.cast<Scalar>();
  r[1] = std::numeric_limits<Scalar>::quiet_NaN();
  EXPECT_EQ(
      block.setFromJacobians(lm.J_obs.cast<Scalar>(), lm.J_l.cast<Scalar>(), r, lm.map).code(),
      Status::Code::kNotFinite);
}

}  // namespace
}  // namespace marglab
