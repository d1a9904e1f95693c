// Landmark elimination: nullspace projection and Schur complement give the same reduced camera
// system and the same LM step, which equals the step of the damped full system solved densely.

#include <Eigen/Dense>

#include "core/linalg/landmark_block.h"
#include "core/linalg/rcs_solve.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::eps;
using test::relError;

constexpr int kPoseDim = 6;
constexpr int kNumPoses = 5;
constexpr int kRcsSize = kPoseDim * kNumPoses;

struct LandmarkData {
  PoseBlockMap map;
  MatXd J_p;
  Mat<double, Eigen::Dynamic, 3> J_l;
  VecXd r;
};

// Each landmark is observed in 2–4 poses with 2 rows per observation; rows are non-zero only in
// the observing pose's block, as for reprojection residuals.
std::vector<LandmarkData> makeLandmarks(std::mt19937_64& rng, int n_landmarks) {
  std::vector<LandmarkData> landmarks;
  std::uniform_int_distribution<int> n_obs_dist(2, 4);
  for (int l = 0; l < n_landmarks; ++l) {
    const int n_obs = n_obs_dist(rng);
    std::vector<int> poses(kNumPoses);
    std::iota(poses.begin(), poses.end(), 0);
    std::shuffle(poses.begin(), poses.end(), rng);
    poses.resize(n_obs);
    std::sort(poses.begin(), poses.end());
    LandmarkData data;
    data.map.pose_dim = kPoseDim;
    for (int p : poses) data.map.rcs_offset.push_back(p * kPoseDim);
    const int m = 2 * n_obs;
    data.J_p = MatXd::Zero(m, kPoseDim * n_obs);
    for (int o = 0; o < n_obs; ++o) {
      data.J_p.block(2 * o, kPoseDim * o, 2, kPoseDim) = test::randomGaussian(rng, 2, kPoseDim);
    }
    data.J_l = test::randomGaussian(rng, m, 3);
    data.r = test::randomGaussian(rng, m, 1);
    landmarks.push_back(std::move(data));
  }
  return landmarks;
}

template <typename Scalar>
class LandmarkBlockTest : public ::testing::Test {};
TYPED_TEST_SUITE(LandmarkBlockTest, test::Scalars, test::ScalarName);

template <typename Scalar>
struct Reduced {
  MatX<Scalar> H = MatX<Scalar>::Zero(kRcsSize, kRcsSize);
  VecX<Scalar> b = VecX<Scalar>::Zero(kRcsSize);
};

// Independent: the full system [poses | landmarks] damped with the same diagonal (d_l on the
// landmarks, lmDamping of the reduced system's diagonal on the poses), solved densely in double;
// and κ of the damped reduced system, which amplifies the reduced system's error into the step.
struct DenseStep {
  VecXd delta;
  double kappa_reduced = 0;
};

template <typename Scalar>
DenseStep denseFullStep(const std::vector<LandmarkData>& landmarks,
                        const std::vector<Vec3<Scalar>>& d_l, const MatXd& H_red, double lambda) {
  const int n_full = kRcsSize + 3 * static_cast<int>(landmarks.size());
  MatXd H_full = MatXd::Zero(n_full, n_full);
  VecXd b_full = VecXd::Zero(n_full);
  for (size_t l = 0; l < landmarks.size(); ++l) {
    const auto& lm = landmarks[l];
    MatXd J_row = MatXd::Zero(lm.r.size(), n_full);
    for (size_t j = 0; j < lm.map.rcs_offset.size(); ++j) {
      J_row.block(0, lm.map.rcs_offset[j], lm.r.size(), kPoseDim) =
          lm.J_p.block(0, j * kPoseDim, lm.r.size(), kPoseDim);
    }
    J_row.block(0, kRcsSize + 3 * l, lm.r.size(), 3) = lm.J_l;
    H_full += J_row.transpose() * J_row;
    b_full += J_row.transpose() * lm.r;
    H_full.diagonal().segment(kRcsSize + 3 * l, 3) += d_l[l].template cast<double>();
  }
  MatXd H_red_damped = H_red;
  for (int i = 0; i < kRcsSize; ++i) {
    const double d = lmDamping(H_red(i, i), lambda, 1e-7);
    H_full(i, i) += d;
    H_red_damped(i, i) += d;
  }
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<MatXd>(H_red_damped).eigenvalues();
  return {-H_full.ldlt().solve(b_full), ev.maxCoeff() / ev.minCoeff()};
}

// The reduced systems of both eliminations, the LM step on them, and the landmark increments;
// compared against a dense solve of the full damped system in double.
template <typename Scalar>
void checkEliminationEquivalence(double lambda) {
  std::mt19937_64 rng(31);
  const auto landmarks = makeLandmarks(rng, 40);
  const Scalar lambda_s = static_cast<Scalar>(lambda);
  const Scalar lambda_min = Scalar(1e-7);

  std::vector<LandmarkBlockNs<Scalar>> ns(landmarks.size());
  std::vector<LandmarkBlockSc<Scalar>> sc(landmarks.size());
  Reduced<Scalar> red_ns, red_sc;
  std::vector<Vec3<Scalar>> d_l(landmarks.size());
  // Tolerance of the reduced systems: the SC route inverts H_ll, so its error grows with
  // κ(H_ll) = κ(J_l)²; the rows per landmark bound the accumulation.
  double tol_reduced = 0;
  for (size_t l = 0; l < landmarks.size(); ++l) {
    const auto& lm = landmarks[l];
    const Eigen::Vector3d s = Eigen::JacobiSVD<MatXd>(lm.J_l).singularValues();
    tol_reduced =
        std::max(tol_reduced, 10.0 * lm.r.size() * eps<Scalar>() * (s[0] * s[0]) / (s[2] * s[2]));
    ASSERT_TRUE(ns[l]
                    .setFromJacobians(lm.J_p.cast<Scalar>(), lm.J_l.cast<Scalar>(),
                                      lm.r.cast<Scalar>(), lm.map)
                    .ok());
    ASSERT_TRUE(sc[l]
                    .setFromJacobians(lm.J_p.cast<Scalar>(), lm.J_l.cast<Scalar>(),
                                      lm.r.cast<Scalar>(), lm.map)
                    .ok());
    EXPECT_LE(relError(ns[l].landmarkHessianDiagonal(), sc[l].landmarkHessianDiagonal()),
              10 * eps<Scalar>());
    for (int i = 0; i < 3; ++i) {
      d_l[l][i] = lambda > 0 ? lmDamping(sc[l].landmarkHessianDiagonal()[i], lambda_s, lambda_min)
                             : Scalar(0);
    }
    ns[l].setLandmarkDamping(d_l[l]);
    sc[l].setLandmarkDamping(d_l[l]);
    ASSERT_TRUE(ns[l].addToReducedSystem(red_ns.H, red_ns.b).ok());
    ASSERT_TRUE(sc[l].addToReducedSystem(red_sc.H, red_sc.b).ok());
  }
  EXPECT_LE(relError(red_ns.H, red_sc.H), tol_reduced);
  EXPECT_LE(relError(red_ns.b, red_sc.b), tol_reduced);

  const auto step_ns = solveDampedLdlt<Scalar>(red_ns.H, red_ns.b, lambda_s, lambda_min);
  const auto step_sc = solveDampedLdlt<Scalar>(red_sc.H, red_sc.b, lambda_s, lambda_min);
  ASSERT_TRUE(step_ns.status.ok()) << step_ns.status.toString();
  ASSERT_TRUE(step_sc.status.ok()) << step_sc.status.toString();

  const DenseStep full = denseFullStep(landmarks, d_l, red_sc.H.template cast<double>(), lambda);
  const VecXd& delta_full = full.delta;
  const double tol_step = tol_reduced * full.kappa_reduced;
  EXPECT_LE(relError(step_ns.delta, step_sc.delta), tol_step);
  EXPECT_LE(relError(step_ns.delta, delta_full.head(kRcsSize)), tol_step);

  for (size_t l = 0; l < landmarks.size(); ++l) {
    Vec3<Scalar> dl_ns, dl_sc;
    ASSERT_TRUE(ns[l].backSubstitute(step_ns.delta, &dl_ns).ok());
    ASSERT_TRUE(sc[l].backSubstitute(step_sc.delta, &dl_sc).ok());
    const Eigen::Vector3d expected = delta_full.segment<3>(kRcsSize + 3 * l);
    EXPECT_LE(relError(dl_ns, expected), tol_step) << "landmark " << l;
    EXPECT_LE(relError(dl_sc, expected), tol_step) << "landmark " << l;
  }
}

TYPED_TEST(LandmarkBlockTest, EliminationsAgreeWithoutLandmarkDamping) {
  checkEliminationEquivalence<TypeParam>(0.0);
}

TYPED_TEST(LandmarkBlockTest, EliminationsAgreeWithLandmarkDamping) {
  checkEliminationEquivalence<TypeParam>(1e-2);
  checkEliminationEquivalence<TypeParam>(10.0);
}

TEST(LandmarkBlockDouble, StepAgreesToRelative1e10) {
  std::mt19937_64 rng(33);
  const auto landmarks = makeLandmarks(rng, 20);
  Reduced<double> red_ns, red_sc;
  for (const auto& lm : landmarks) {
    LandmarkBlockNs<double> ns;
    LandmarkBlockSc<double> sc;
    ASSERT_TRUE(ns.setFromJacobians(lm.J_p, lm.J_l, lm.r, lm.map).ok());
    ASSERT_TRUE(sc.setFromJacobians(lm.J_p, lm.J_l, lm.r, lm.map).ok());
    ASSERT_TRUE(ns.addToReducedSystem(red_ns.H, red_ns.b).ok());
    ASSERT_TRUE(sc.addToReducedSystem(red_sc.H, red_sc.b).ok());
  }
  const auto step_ns = solveDampedLdlt<double>(red_ns.H, red_ns.b, 1e-4, 1e-7);
  const auto step_sc = solveDampedLdlt<double>(red_sc.H, red_sc.b, 1e-4, 1e-7);
  EXPECT_LE(relError(step_ns.delta, step_sc.delta), 1e-10);
}

// The Q2ᵀ rows are the projection onto the left nullspace of J_l:
// (Q2ᵀJ_p)ᵀ(Q2ᵀJ_p) = J_pᵀ(I − J_l(J_lᵀJ_l)⁻¹J_lᵀ)J_p, and stacked rows give the same H.
TYPED_TEST(LandmarkBlockTest, ReducedRowsAreNullspaceProjection) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(34);
  const auto lm = makeLandmarks(rng, 1).front();
  LandmarkBlockNs<Scalar> ns;
  ASSERT_TRUE(
      ns.setFromJacobians(lm.J_p.cast<Scalar>(), lm.J_l.cast<Scalar>(), lm.r.cast<Scalar>(), lm.map)
          .ok());
  EXPECT_EQ(ns.numReducedRows(), lm.r.size() - 3);
  const MatXd P = MatXd::Identity(lm.r.size(), lm.r.size()) -
                  lm.J_l * (lm.J_l.transpose() * lm.J_l).inverse() * lm.J_l.transpose();
  const MatXd Jr = ns.reducedJp().template cast<double>();
  EXPECT_LE(relError(Jr.transpose() * Jr, lm.J_p.transpose() * P * lm.J_p), 1e3 * eps<Scalar>());

  MatX<Scalar> stacked = MatX<Scalar>::Zero(ns.numReducedRows(), kRcsSize + 1);
  ns.copyReducedRows(stacked, 0);
  Reduced<Scalar> red;
  ASSERT_TRUE(ns.addToReducedSystem(red.H, red.b).ok());
  const MatX<Scalar> Js = stacked.leftCols(kRcsSize);
  EXPECT_LE(relError(MatX<Scalar>(Js.transpose() * Js), red.H), 10 * eps<Scalar>());
  EXPECT_LE(relError(VecX<Scalar>(Js.transpose() * stacked.col(kRcsSize)), red.b),
            10 * eps<Scalar>());
}

// addToReducedSystem against the product of the reduced rows copied into a stacked system
// (computed here in double): the 6-column pose blocks (the pose-pair kernel) and another pose size
// (the rank-update path), undamped and damped, for a landmark seen from non-adjacent poses.
TYPED_TEST(LandmarkBlockTest, ReducedSystemIsTheProductOfTheReducedRowsForEveryPoseSize) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(38);
  for (const int pd : {6, 4}) {
    const PoseBlockMap map{pd, {0, 2 * pd, 3 * pd, 5 * pd}};
    const int n_rcs = 6 * pd, m = 9;
    const MatXd J_p = test::randomGaussian(rng, m, map.localCols());
    const MatXd J_l = test::randomGaussian(rng, m, 3), r = test::randomGaussian(rng, m, 1);
    for (const double d : {0.0, 2.0}) {
      SCOPED_TRACE(testing::Message() << "pose_dim " << pd << " damping " << d);
      LandmarkBlockNs<Scalar> ns;
      ASSERT_TRUE(ns.setFromJacobians(J_p.cast<Scalar>(), J_l.cast<Scalar>(),
                                      VecX<Scalar>(r.cast<Scalar>()), map)
                      .ok());
      ns.setLandmarkDamping(Vec3<Scalar>::Constant(static_cast<Scalar>(d)));
      MatX<Scalar> stacked = MatX<Scalar>::Zero(ns.numReducedRows(), n_rcs + 1);
      ns.copyReducedRows(stacked, 0);
      const MatXd Js = stacked.leftCols(n_rcs).template cast<double>();
      const VecXd rs = stacked.col(n_rcs).template cast<double>();
      MatX<Scalar> H = MatX<Scalar>::Zero(n_rcs, n_rcs);
      VecX<Scalar> b = VecX<Scalar>::Zero(n_rcs);
      ASSERT_TRUE(ns.addToReducedSystem(H, b).ok());
      // Sums of R = numReducedRows() products of the same Scalar rows: entrywise error ≤ R ε
      // times the sum of absolute products.
      const double g = (ns.numReducedRows() + 1) * eps<Scalar>();
      const MatXd Ja = Js.cwiseAbs();
      EXPECT_LE(relError(H, MatXd(Js.transpose() * Js)),
                g * (Ja.transpose() * Ja).norm() / (Js.transpose() * Js).norm());
      EXPECT_LE(relError(b, VecXd(Js.transpose() * rs)),
                g * (Ja.transpose() * rs.cwiseAbs()).norm() / (Js.transpose() * rs).norm());
      EXPECT_TRUE(H == H.transpose()) << "not symmetric";
    }
  }
}

// Mixed precision (variant ...-mixed): a float elimination accumulated into a double reduced
// system agrees with the double elimination to float accuracy (same bound as the reduced rows
// above), and is not the double result (the elimination did run in float).
TEST(LandmarkBlockMixed, FloatBlocksIntoDoubleSystem) {
  std::mt19937_64 rng(37);
  Reduced<double> mixed, reference;
  for (const LandmarkData& lm : makeLandmarks(rng, 20)) {
    LandmarkBlockNs<float> f;
    LandmarkBlockNs<double> d;
    ASSERT_TRUE(
        f.setFromJacobians(lm.J_p.cast<float>(), lm.J_l.cast<float>(), lm.r.cast<float>(), lm.map)
            .ok());
    ASSERT_TRUE(d.setFromJacobians(lm.J_p, lm.J_l, lm.r, lm.map).ok());
    ASSERT_TRUE(f.addToReducedSystem(mixed.H, mixed.b).ok());
    ASSERT_TRUE(d.addToReducedSystem(reference.H, reference.b).ok());
  }
  EXPECT_LE(relError(mixed.H, reference.H), 1e3 * eps<float>());
  EXPECT_LE(relError(mixed.b, reference.b), 1e3 * eps<float>());
  EXPECT_GT(relError(mixed.H, reference.H), 10 * eps<double>());
}

TYPED_TEST(LandmarkBlockTest, DampingCanBeChangedAndRemoved) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(35);
  const auto lm = makeLandmarks(rng, 1).front();
  LandmarkBlockNs<Scalar> ns;
  ASSERT_TRUE(
      ns.setFromJacobians(lm.J_p.cast<Scalar>(), lm.J_l.cast<Scalar>(), lm.r.cast<Scalar>(), lm.map)
          .ok());
  Reduced<Scalar> before, after;
  ASSERT_TRUE(ns.addToReducedSystem(before.H, before.b).ok());
  ns.setLandmarkDamping(Vec3<Scalar>(1, 2, 3));
  EXPECT_EQ(ns.numReducedRows(), lm.r.size());
  ns.setLandmarkDamping(Vec3<Scalar>::Zero());
  ASSERT_TRUE(ns.addToReducedSystem(after.H, after.b).ok());
  EXPECT_EQ(relError(after.H, before.H), 0.0);
}

TYPED_TEST(LandmarkBlockTest, InvalidOrSingularInputIsAStatus) {
  using Scalar = TypeParam;
  PoseBlockMap map{kPoseDim, {0}};
  LandmarkBlockNs<Scalar> ns;
  LandmarkBlockSc<Scalar> sc;
  // Two rows cannot determine three landmark coordinates.
  EXPECT_EQ(
      ns.setFromJacobians(MatX<Scalar>::Ones(2, 6), Mat<Scalar, Eigen::Dynamic, 3>::Ones(2, 3),
                          VecX<Scalar>::Ones(2), map)
          .code(),
      Status::Code::kInvalidArgument);
  // A landmark Jacobian of rank 1 without damping: back-substitution must fail, not divide by 0.
  Mat<Scalar, Eigen::Dynamic, 3> J_l = Mat<Scalar, Eigen::Dynamic, 3>::Zero(4, 3);
  J_l.col(0).setOnes();
  ASSERT_TRUE(sc.setFromJacobians(MatX<Scalar>::Ones(4, 6), J_l, VecX<Scalar>::Ones(4), map).ok());
  MatX<Scalar> H = MatX<Scalar>::Zero(6, 6);
  VecX<Scalar> b = VecX<Scalar>::Zero(6);
  EXPECT_FALSE(sc.addToReducedSystem(H, b).ok());
  ASSERT_TRUE(ns.setFromJacobians(MatX<Scalar>::Ones(4, 6), J_l, VecX<Scalar>::Ones(4), map).ok());
  Vec3<Scalar> dl;
  EXPECT_FALSE(ns.backSubstitute(VecX<Scalar>::Zero(6), &dl).ok());
  // Neither elimination adds a landmark it cannot back-substitute.
  EXPECT_FALSE(ns.addToReducedSystem(H, b).ok());
  EXPECT_TRUE(H.isZero(0) && b.isZero(0));
  EXPECT_FALSE(ns.landmarkSolvable());
  // With damping both succeed.
  ns.setLandmarkDamping(Vec3<Scalar>::Constant(Scalar(1e-3)));
  EXPECT_TRUE(ns.backSubstitute(VecX<Scalar>::Zero(6), &dl).ok());
}

TYPED_TEST(LandmarkBlockTest, DampedSolveFailsAsStatusOnIndefiniteSystem) {
  using Scalar = TypeParam;
  MatX<Scalar> H = MatX<Scalar>::Identity(3, 3);
  H(1, 1) = Scalar(-5);
  const auto step = solveDampedLdlt<Scalar>(H, VecX<Scalar>::Ones(3), Scalar(1e-4), Scalar(1e-7));
  EXPECT_EQ(step.status.code(), Status::Code::kSolveFailed);
  H(1, 1) = Scalar(0);  // singular, rescued by λ_min
  const auto rescued =
      solveDampedLdlt<Scalar>(H, VecX<Scalar>::Ones(3), Scalar(1e-4), Scalar(1e-2));
  ASSERT_TRUE(rescued.status.ok());
  EXPECT_NEAR(rescued.delta[1], Scalar(-100), Scalar(100) * 10 * eps<Scalar>());
}

}  // namespace
}  // namespace marglab

namespace marglab {
namespace {

// The LM model decrease: both eliminations against ½‖J_p δp + J_l δl + r‖² − ½‖r‖², damped or not.
TYPED_TEST(LandmarkBlockTest, LinearizedCostChangeIsTheUndampedModel) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(36);
  const auto lm = makeLandmarks(rng, 1).front();
  const VecXd delta_rcs = test::randomGaussian(rng, kRcsSize, 1);
  const Eigen::Vector3d delta_l = test::randomGaussian(rng, 3, 1);
  const VecXd dp = gatherLocal(lm.map, delta_rcs);
  const double expected =
      0.5 * ((lm.J_p * dp + lm.J_l * delta_l + lm.r).squaredNorm() - lm.r.squaredNorm());
  LandmarkBlockNs<Scalar> ns;
  LandmarkBlockSc<Scalar> sc;
  ASSERT_TRUE(
      ns.setFromJacobians(lm.J_p.cast<Scalar>(), lm.J_l.cast<Scalar>(), lm.r.cast<Scalar>(), lm.map)
          .ok());
  ASSERT_TRUE(
      sc.setFromJacobians(lm.J_p.cast<Scalar>(), lm.J_l.cast<Scalar>(), lm.r.cast<Scalar>(), lm.map)
          .ok());
  ns.setLandmarkDamping(Vec3<Scalar>::Constant(Scalar(2)));
  sc.setLandmarkDamping(Vec3<Scalar>::Constant(Scalar(2)));
  const double scale =
      0.5 * (lm.J_p * dp + lm.J_l * delta_l + lm.r).squaredNorm() + 0.5 * lm.r.squaredNorm();
  const double tol = 100 * lm.r.size() * eps<Scalar>() * scale;
  EXPECT_NEAR(ns.linearizedCostChange(delta_rcs.cast<Scalar>(), delta_l.cast<Scalar>()), expected,
              tol);
  EXPECT_NEAR(sc.linearizedCostChange(delta_rcs.cast<Scalar>(), delta_l.cast<Scalar>()), expected,
              tol);
}

// A trailing column every landmark shares (PoseBlockMap::extra_cols, the stereo cx offset of the
// estimator): both eliminations, the copied reduced rows and the back-substitution against the
// dense Schur complement of the full system [poses | extra | landmark] in double. The extra
// column sits at the end of the reduced system; its rows are nonzero in half of the landmark's
// observation rows (the right camera's u rows).
TYPED_TEST(LandmarkBlockTest, SharedExtraColumnIsEliminatedLikeAPoseColumn) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(39);
  const int n_rcs = kRcsSize + 1;
  for (LandmarkData lm : makeLandmarks(rng, 6)) {
    const int m = static_cast<int>(lm.r.size());
    lm.map.extra_cols = 1;
    lm.map.extra_rcs_offset = kRcsSize;
    MatXd J_p(m, lm.map.localCols());
    J_p << lm.J_p, VecXd::Zero(m);
    for (int i = 0; i < m; i += 4) J_p(i, lm.map.poseCols()) = 1.0 + 0.1 * i;
    // Independent: the full system and its Schur complement on the landmark, in double.
    MatXd J_full = MatXd::Zero(m, n_rcs + 3);
    for (size_t j = 0; j < lm.map.rcs_offset.size(); ++j) {
      J_full.block(0, lm.map.rcs_offset[j], m, kPoseDim) = J_p.block(0, j * kPoseDim, m, kPoseDim);
    }
    J_full.col(kRcsSize) = J_p.col(lm.map.poseCols());
    J_full.rightCols(3) = lm.J_l;
    const MatXd H = J_full.transpose() * J_full;
    const VecXd g = J_full.transpose() * lm.r;
    const Eigen::Matrix3d H_ll_inv = H.bottomRightCorner(3, 3).inverse();
    const MatXd H_red = H.topLeftCorner(n_rcs, n_rcs) -
                        H.topRightCorner(n_rcs, 3) * H_ll_inv * H.bottomLeftCorner(3, n_rcs);
    const VecXd b_red = g.head(n_rcs) - H.topRightCorner(n_rcs, 3) * H_ll_inv * g.tail(3);
    const Eigen::Vector3d s = Eigen::JacobiSVD<MatXd>(lm.J_l).singularValues();
    const double tol = 10.0 * m * eps<Scalar>() * (s[0] * s[0]) / (s[2] * s[2]) *
                       std::max(1.0, H.norm() / H_red.norm());
    LandmarkBlockNs<Scalar> ns;
    LandmarkBlockSc<Scalar> sc;
    const MatX<Scalar> J_s = J_p.cast<Scalar>();
    ASSERT_TRUE(ns.setFromJacobians(J_s, lm.J_l.cast<Scalar>(), lm.r.cast<Scalar>(), lm.map).ok());
    ASSERT_TRUE(sc.setFromJacobians(J_s, lm.J_l.cast<Scalar>(), lm.r.cast<Scalar>(), lm.map).ok());
    MatX<Scalar> H_ns = MatX<Scalar>::Zero(n_rcs, n_rcs), H_sc = H_ns;
    VecX<Scalar> b_ns = VecX<Scalar>::Zero(n_rcs), b_sc = b_ns;
    ASSERT_TRUE(ns.addToReducedSystem(H_ns, b_ns).ok());
    ASSERT_TRUE(sc.addToReducedSystem(H_sc, b_sc).ok());
    EXPECT_LE(relError(H_ns, H_red), tol);
    EXPECT_LE(relError(H_sc, H_red), tol);
    EXPECT_LE(relError(b_ns, b_red), tol);
    EXPECT_LE(relError(b_sc, b_red), tol);
    EXPECT_GT(std::abs(H_red(kRcsSize, kRcsSize)), 0.0);  // the column carries information
    MatX<Scalar> stacked = MatX<Scalar>::Zero(ns.numReducedRows(), n_rcs + 1);
    ns.copyReducedRows(stacked, 0);
    const MatXd Js = stacked.leftCols(n_rcs).template cast<double>();
    EXPECT_LE(relError(MatXd(Js.transpose() * Js), H_red), tol);
    // Back-substitution: δl = −H_ll⁻¹ (g_l + H_lp δp) for any δp, the extra column included.
    const VecXd delta = test::randomGaussian(rng, n_rcs, 1);
    const Eigen::Vector3d expected = -H_ll_inv * (g.tail(3) + H.bottomLeftCorner(3, n_rcs) * delta);
    Vec3<Scalar> dl_ns, dl_sc;
    ASSERT_TRUE(ns.backSubstitute(delta.cast<Scalar>(), &dl_ns).ok());
    ASSERT_TRUE(sc.backSubstitute(delta.cast<Scalar>(), &dl_sc).ok());
    EXPECT_LE(relError(dl_ns, expected), tol);
    EXPECT_LE(relError(dl_sc, expected), tol);
    EXPECT_EQ(gatherLocal(lm.map, delta)(lm.map.poseCols()), delta(kRcsSize));
  }
}

}  // namespace
}  // namespace marglab
