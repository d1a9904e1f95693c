// ATE (core/diagnostics/ate.h): association with interpolation and gap skipping, rigid alignment
// with the reflection fix (checked against Eigen::umeyama without scaling), TUM export.

#include "core/diagnostics/ate.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/geometry/so3.h"

namespace marglab {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A helix sampled at 20 Hz from t0: positions of magnitude ~5 m.
Trajectory helix(int samples, std::int64_t t0 = 1'403'636'579'763'555'584) {
  Trajectory gt;
  for (int i = 0; i < samples; ++i) {
    const double s = 0.05 * i;
    gt.push_back(t0 + static_cast<std::int64_t>(i) * 50'000'000,
                 Eigen::Vector3d(3.0 * std::cos(s), 2.0 * std::sin(s), 0.3 * s),
                 Eigen::Quaterniond(Eigen::AngleAxisd(s, Eigen::Vector3d::UnitZ())));
  }
  return gt;
}

TEST(Ate, NoiseFreeTransformedTrajectoryAlignsExactlyAndRecoversTheTransform) {
  const Trajectory gt = helix(120);
  const Eigen::Matrix3d R = expSO3<double>(Eigen::Vector3d(0.4, -1.1, 2.0));
  const Eigen::Vector3d t(10.0, -4.0, 2.5);
  // Estimate in its own frame: p_est = R⁻¹ (p_gt − t), so that p_gt = R p_est + t.
  std::vector<Eigen::Vector3d> p_est;
  for (const auto& p : gt.p_w_b) p_est.push_back(R.transpose() * (p - t));
  const AteResult ate = computeAte(gt.t_ns, p_est, gt);
  ASSERT_TRUE(ate.alignment.valid);
  EXPECT_EQ(ate.n_pairs, gt.size());
  // Rounding of the rotation of |p| ~ 12 m coordinates and of the SVD: a few ε·|p|.
  const double tol = 100 * kEps * 15.0;
  EXPECT_LT(ate.rmse, tol);
  EXPECT_LT((ate.alignment.R_gt_est - R).norm(), 100 * kEps);
  EXPECT_LT((ate.alignment.t_gt_est - t).norm(), tol);
  for (double e : ate.error) EXPECT_LT(e, tol);
}

TEST(Ate, MatchesEigenUmeyamaOnNoisyData) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  std::vector<Eigen::Vector3d> src, dst;
  const Eigen::Matrix3d R = expSO3<double>(Eigen::Vector3d(-0.3, 0.2, 0.9));
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d p(normal(rng) * 4, normal(rng) * 2, normal(rng));
    src.push_back(p);
    dst.push_back(R * p + Eigen::Vector3d(1, 2, 3) +
                  0.05 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
  }
  Eigen::Matrix3Xd S(3, 50), D(3, 50);
  for (int i = 0; i < 50; ++i) {
    S.col(i) = src[i];
    D.col(i) = dst[i];
  }
  const Eigen::Matrix4d T_ref = Eigen::umeyama(S, D, false);
  const RigidAlignment a = alignRigid(src, dst);
  EXPECT_LT((a.R_gt_est - T_ref.topLeftCorner<3, 3>()).norm(), 1e-12);
  EXPECT_LT((a.t_gt_est - T_ref.topRightCorner<3, 1>()).norm(), 1e-12);
  double sum = 0;
  for (int i = 0; i < 50; ++i)
    sum += (D.col(i) - (T_ref.topLeftCorner<3, 3>() * S.col(i) + T_ref.topRightCorner<3, 1>()))
               .squaredNorm();
  EXPECT_NEAR(computeAte(src, dst).rmse, std::sqrt(sum / 50), 1e-12);
}

// Planar points: Σ has a zero singular value and the unconstrained Kabsch solution U Vᵀ may be
// a reflection; the fix makes it a rotation with the same (zero) residual. A mirrored point set
// (dst = diag(1,1,−1) src) must also come back as a proper rotation, never a mirror.
TEST(Ate, ReflectionFixAlwaysReturnsARotation) {
  std::vector<Eigen::Vector3d> planar, rotated, mirrored;
  const Eigen::Matrix3d R = expSO3<double>(Eigen::Vector3d(0.1, 0.2, 0.3));
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-5, 5);
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), 0.0);
    planar.push_back(p);
    rotated.push_back(R * p + Eigen::Vector3d(0, 0, 1));
    const Eigen::Vector3d q(u(rng), u(rng), u(rng));
    mirrored.push_back(Eigen::Vector3d(q.x(), q.y(), -q.z()));
  }
  const RigidAlignment a = alignRigid(planar, rotated);
  EXPECT_NEAR(a.R_gt_est.determinant(), 1.0, 1e-12);
  EXPECT_LT((a.R_gt_est.transpose() * a.R_gt_est - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT(computeAte(planar, rotated).rmse, 1e-12);
  // Same plane, reflected within it: the best rotation flips out of the plane.
  std::vector<Eigen::Vector3d> flipped;
  for (const auto& p : planar) flipped.push_back(Eigen::Vector3d(p.x(), -p.y(), 0.0));
  const RigidAlignment f = alignRigid(planar, flipped);
  EXPECT_NEAR(f.R_gt_est.determinant(), 1.0, 1e-12);
  EXPECT_LT(computeAte(planar, flipped).rmse, 1e-12);  // a rotation by π about x does it

  std::vector<Eigen::Vector3d> original;
  for (const auto& q : mirrored) original.push_back(Eigen::Vector3d(q.x(), q.y(), -q.z()));
  const RigidAlignment m = alignRigid(original, mirrored);
  EXPECT_NEAR(m.R_gt_est.determinant(), 1.0, 1e-12);
  EXPECT_GT(computeAte(original, mirrored).rmse, 0.1);  // a true mirror cannot be undone
}

TEST(Ate, InterpolatesLinearlyAndSkipsGapsAndOutsideSpan) {
  Trajectory gt;
  const Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  gt.push_back(1'000'000'000, Eigen::Vector3d(0, 0, 0), q);
  gt.push_back(1'100'000'000, Eigen::Vector3d(1, 2, 3), q);  // gap 0.10 s: ok
  gt.push_back(1'210'000'000, Eigen::Vector3d(2, 2, 3), q);  // gap 0.11 s: ok (not exceeding)
  gt.push_back(1'400'000'000, Eigen::Vector3d(3, 2, 3), q);  // gap 0.19 s: skipped inside

  auto at = [&](std::int64_t t) { return interpolatePosition(gt, t); };
  ASSERT_TRUE(at(1'025'000'000));
  EXPECT_LT((*at(1'025'000'000) - Eigen::Vector3d(0.25, 0.5, 0.75)).norm(), 4 * kEps);
  ASSERT_TRUE(at(1'155'000'000));
  EXPECT_LT((*at(1'155'000'000) - Eigen::Vector3d(1.5, 2, 3)).norm(), 8 * kEps);
  ASSERT_TRUE(at(1'100'000'000));
  EXPECT_EQ(*at(1'100'000'000), Eigen::Vector3d(1, 2, 3));
  EXPECT_TRUE(at(1'400'000'000));   // exact stamp at the end of a long gap
  EXPECT_FALSE(at(1'300'000'000));  // inside the 0.19 s gap
  EXPECT_FALSE(at(999'999'999));    // before the span
  EXPECT_FALSE(at(1'400'000'001));  // after the span
  EXPECT_TRUE(interpolatePosition(gt, 1'300'000'000, 200'000'000));  // a wider max gap

  // computeAte marks unassociated frames NaN and aligns the rest.
  const std::vector<std::int64_t> t = {900'000'000, 1'025'000'000, 1'155'000'000, 1'300'000'000,
                                       1'400'000'000};
  std::vector<Eigen::Vector3d> p_est = {Eigen::Vector3d::Zero(), Eigen::Vector3d(0.25, 0.5, 0.75),
                                        Eigen::Vector3d(1.5, 2, 3), Eigen::Vector3d::Zero(),
                                        Eigen::Vector3d(3, 2, 3)};
  const AteResult ate = computeAte(t, p_est, gt);
  EXPECT_EQ(ate.n_pairs, 3u);
  EXPECT_TRUE(std::isnan(ate.error[0]));
  EXPECT_TRUE(std::isnan(ate.error[3]));
  EXPECT_LT(ate.rmse, 1e-12);
}

TEST(Ate, NoPairsGivesNaNAndNonFiniteRowsAreSkipped) {
  const AteResult none = computeAte({Eigen::Vector3d::Zero()}, {Eigen::Vector3d::Constant(kNaN)});
  EXPECT_EQ(none.n_pairs, 0u);
  EXPECT_TRUE(std::isnan(none.rmse));
  EXPECT_FALSE(none.alignment.valid);
  const AteResult one = computeAte({Eigen::Vector3d(1, 2, 3), Eigen::Vector3d::Constant(kNaN)},
                                   {Eigen::Vector3d(4, 5, 6), Eigen::Vector3d(0, 0, 0)});
  EXPECT_EQ(one.n_pairs, 1u);
  EXPECT_LT(one.rmse, 1e-15);
  EXPECT_TRUE(std::isnan(one.error[1]));
}

TEST(Ate, TumExportIsExactInTimeAndAtomic) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("marglab_ate_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / "traj.txt").string();
  const std::vector<std::int64_t> t = {1'403'636'579'763'555'584, 5, -1'500'000'000};
  const std::vector<Eigen::Vector3d> p = {Eigen::Vector3d(1, -2, 3.25), Eigen::Vector3d::Zero(),
                                          Eigen::Vector3d(0.1, 0.2, 0.3)};
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()));
  writeTumTrajectory(path, t, p, {q, Eigen::Quaterniond::Identity(), q});
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(in, line)) lines.push_back(line);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[1],
            "0.000000005 0.000000000 0.000000000 0.000000000 0.000000000 0.000000000 "
            "0.000000000 1.000000000");
  EXPECT_EQ(lines[2].substr(0, 13), "-1.500000000 ");
  std::istringstream first(lines[0]);
  std::string stamp;
  double x, y, z, qx, qy, qz, qw;
  first >> stamp >> x >> y >> z >> qx >> qy >> qz >> qw;
  EXPECT_EQ(stamp, "1403636579.763555584");
  EXPECT_EQ(Eigen::Vector3d(x, y, z), p[0]);
  EXPECT_NEAR(qy, q.y(), 1e-9);
  EXPECT_NEAR(qw, q.w(), 1e-9);
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) entries += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(entries, 1);  // no temporary left behind
  EXPECT_THROW(writeTumTrajectory((dir / "missing" / "t.txt").string(), t, p, {q, q, q}),
               InputError);
  EXPECT_THROW(writeTumTrajectory(path, t, p, {q}), std::invalid_argument);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace marglab
