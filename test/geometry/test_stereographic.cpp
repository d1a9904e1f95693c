// Stereographic bearing and inverse-distance landmark: round trips (near the forward axis and far
// from it, down to 1° from the singular pole (0, 0, −1)), Jacobians by central differences, and
// the target-camera point.

#include <gtest/gtest.h>

#include <cmath>

#include "core/geometry/stereographic.h"
#include "test/geometry/geometry_test_utils.h"

namespace marglab::test {
namespace {

// Unit bearings at the given angles (degrees) from the forward axis (0, 0, 1), each about a random
// azimuth, plus (0, 0, 1) itself and a bearing a tiny angle off it.
template <typename Scalar>
std::vector<Vec3<Scalar>> testBearings(std::initializer_list<double> angles_deg) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> azimuth(0.0, 2 * M_PI);
  std::vector<Vec3<Scalar>> out;
  out.push_back(Vec3<Scalar>::UnitZ());
  const double tiny = tinyAngle<Scalar>();
  out.push_back(Eigen::Vector3d(std::sin(tiny), -0.5 * std::sin(tiny), std::cos(tiny))
                    .normalized()
                    .cast<Scalar>());
  for (double deg : angles_deg) {
    const double a = deg * M_PI / 180.0;
    const double z = azimuth(rng);
    out.push_back(Eigen::Vector3d(std::sin(a) * std::cos(z), std::sin(a) * std::sin(z), std::cos(a))
                      .cast<Scalar>());
  }
  return out;
}

template <typename Scalar>
class StereographicTest : public ::testing::Test {};
TYPED_TEST_SUITE(StereographicTest, ScalarTypes, ScalarNames);

TYPED_TEST(StereographicTest, BearingRoundTrip) {
  using S = TypeParam;
  for (const Vec3<S>& b : testBearings<S>({1, 10, 30, 60, 89, 90, 120, 150, 170, 179})) {
    const Vec<S, 2> uv = stereographicProject(b);
    const Vec3<S> b2 = stereographicUnproject(uv);
    EXPECT_TRUE(matricesNear(b2, b, kEvalUlps * kEps<S>)) << "b " << b.transpose();
    EXPECT_NEAR(b2.norm(), S(1), kEvalUlps * kEps<S>);
    // u = x/(|b| + z) in long double ((|b| + z) = (x² + y²)/(|b| − z), the latter for z < 0 where
    // the former cancels; b is unit only to rounding, so 1 + z is not a valid reference there).
    const Eigen::Matrix<long double, 3, 1> b_l = b.template cast<long double>();
    const long double n_l = b_l.norm();
    const long double m_l =
        b_l.z() >= 0 ? n_l + b_l.z() : b_l.template head<2>().squaredNorm() / (n_l - b_l.z());
    const Eigen::Matrix<long double, 2, 1> uv_ref = b_l.template head<2>() / m_l;
    EXPECT_TRUE(matricesNear(uv, uv_ref, kEvalUlps * kEps<S> * uv.norm()));
    EXPECT_TRUE(matricesNear(stereographicProject(Vec3<S>(S(7.5) * b)), uv,
                             kEvalUlps * kEps<S> * uv.norm()));
  }
}

// project(unproject(uv)) = uv to relative accuracy O(ε), from |uv| = 1e-8 up to |uv| = 100.
TYPED_TEST(StereographicTest, UvRoundTrip) {
  using S = TypeParam;
  std::mt19937 rng(22);
  for (double r : {0.0, 1e-8, 1e-3, 0.3, 1.0, 2.0, 10.0, 100.0}) {
    const Vec<S, 2> uv = (randomUnit<double>(rng).head<2>().normalized() * r).cast<S>();
    EXPECT_TRUE(matricesNear(stereographicProject(stereographicUnproject(uv)), uv,
                             kEvalUlps * kEps<S> * uv.norm()))
        << "uv " << uv.transpose();
  }
}

TYPED_TEST(StereographicTest, JacobiansMatchCentralDifferences) {
  using S = TypeParam;
  for (const Vec3<S>& b : testBearings<S>({5, 30, 60, 90, 120})) {
    for (S scale : {S(0.5), S(1), S(3)}) {
      const Vec3<S> p = scale * b;
      Mat<S, 2, 3> d_uv_d_p;
      const Vec<S, 2> uv = stereographicProject(p, &d_uv_d_p);
      const auto fd =
          fdJacobian<S, 2, 3>([](const Vec3<S>& x) { return stereographicProject<S>(x); }, p);
      // |u| ≤ |uv|; the derivatives of x/(|p| + z) scale with 1/|p|^k (the FD step is
      // h·max(1,|p_i|)).
      const S f3 = (S(1) + uv.norm()) * S(6) / (scale * scale * scale);
      EXPECT_TRUE(matricesNear(d_uv_d_p, fd, fdTolerance<S>(S(1) + uv.norm(), f3)))
          << "p " << p.transpose();
      EXPECT_TRUE(matricesNear(d_uv_d_p * p, Vec<S, 2>::Zero(), kEvalUlps * kEps<S> * 10));
    }
  }
  std::mt19937 rng(23);
  for (double r : {0.0, 1e-3, 0.5, 1.0, 3.0}) {
    const Vec<S, 2> uv = (randomUnit<double>(rng).head<2>().normalized() * r).cast<S>();
    Mat<S, 3, 2> d_b_d_uv;
    stereographicUnproject(uv, &d_b_d_uv);
    const auto fd =
        fdJacobian<S, 3, 2>([](const Vec<S, 2>& x) { return stereographicUnproject<S>(x); }, uv);
    // |b| = 1 and |∂³(2u/(1+u²))| ≤ 12.
    EXPECT_TRUE(matricesNear(d_b_d_uv, fd, fdTolerance<S>(S(1), S(12)))) << "uv " << uv.transpose();
  }
}

TYPED_TEST(StereographicTest, LandmarkPointRoundTrip) {
  using S = TypeParam;
  for (const Vec3<S>& b : testBearings<S>({10, 45, 80})) {
    for (S dist : {S(0.3), S(2), S(50)}) {
      const Vec3<S> p_h = dist * b;
      const Vec3<S> l = landmarkFromPoint(p_h);
      EXPECT_NEAR(l.z(), S(1) / dist, kEvalUlps * kEps<S> / dist);
      EXPECT_TRUE(matricesNear(landmarkToPoint(l), p_h, kEvalUlps * kEps<S> * dist));
    }
  }
}

// q = R_t_h b + ρ t_t_h = ρ T_t_h p_h, and its Jacobians w.r.t. (u, v, ρ) and ⊞ of T_t_h.
TYPED_TEST(StereographicTest, TransformLandmarkValueAndJacobians) {
  using S = TypeParam;
  std::mt19937 rng(24);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::uniform_real_distribution<double> inv_dist(0.05, 2.0);
  for (int i = 0; i < 20; ++i) {
    const SE3<S> T_t_h(expSO3<S>(randomUnit<S>(rng) * S(0.5 + uni(rng) * 0.4)),
                       randomUnit<S>(rng) * S(0.6));
    const Vec3<S> l(S(uni(rng)), S(uni(rng)), S(inv_dist(rng)));
    Mat<S, 3, 3> d_q_d_l;
    Mat<S, 3, 6> d_q_d_T;
    const Vec3<S> q = transformLandmark(T_t_h, l, &d_q_d_l, &d_q_d_T);
    EXPECT_TRUE(matricesNear(q, l.z() * (T_t_h * landmarkToPoint(l)), kEvalUlps * kEps<S> * 4));
    EXPECT_TRUE(matricesNear(transformLandmark(T_t_h, l), q, 0.0));
    const auto fd_l =
        fdJacobian<S, 3, 3>([&](const Vec3<S>& x) { return transformLandmark<S>(T_t_h, x); }, l);
    const auto fd_T = fdJacobian<S, 3, 6>(
        [&](const Vec<S, 6>& d) { return transformLandmark<S>(boxPlus(T_t_h, d), l); },
        Vec<S, 6>::Zero());
    // |q| ≤ 1 + ρ|t| ≤ 2.2; third derivatives O(|b'''|) ≤ 12.
    EXPECT_TRUE(matricesNear(d_q_d_l, fd_l, fdTolerance<S>(S(2.2), S(12))));
    EXPECT_TRUE(matricesNear(d_q_d_T, fd_T, fdTolerance<S>(S(2.2), S(2.2))));
  }
}

TEST(StereographicFloatVsDouble, Agree) {
  for (const Vec3<float>& b : testBearings<float>({10, 60, 120, 170})) {
    Mat<float, 2, 3> J_f;
    Mat<double, 2, 3> J_d;
    const Vec<float, 2> uv_f = stereographicProject(b, &J_f);
    const Vec<double, 2> uv_d = stereographicProject(Vec3<double>(b.cast<double>()), &J_d);
    const double scale = 1 + uv_d.squaredNorm();
    EXPECT_TRUE(matricesNear(uv_f, uv_d, kEvalUlps * kEps<float> * scale));
    EXPECT_TRUE(matricesNear(J_f, J_d, kEvalUlps * kEps<float> * scale));
    Mat<float, 3, 2> Jb_f;
    Mat<double, 3, 2> Jb_d;
    EXPECT_TRUE(matricesNear(stereographicUnproject(uv_f, &Jb_f),
                             stereographicUnproject(Vec<double, 2>(uv_f.cast<double>()), &Jb_d),
                             kEvalUlps * kEps<float>));
    EXPECT_TRUE(matricesNear(Jb_f, Jb_d, kEvalUlps * kEps<float> * 4));
  }
}

}  // namespace
}  // namespace marglab::test
