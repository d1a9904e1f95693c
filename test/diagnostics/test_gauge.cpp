// Gauge directions and ΔE_m (core/diagnostics/gauge.h) on synthetic VO / VIO windows whose
// residuals are invariant under rigid motions of the world (VO) or under translations and yaw
// (VIO, gravity along z). The prior is the Schur complement of the first frame and all landmarks,
// built in double from analytic Jacobians that are checked against central differences.

#include "core/diagnostics/gauge.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "core/diagnostics/diagnostics.h"
#include "core/geometry/so3.h"

namespace marglab {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
const Eigen::Vector3d kGravity(0.0, 0.0, -9.81);
constexpr double kDt = 0.1;

struct Window {
  bool vio = false;
  std::vector<SE3d> T_w_i;
  std::vector<Eigen::Vector3d> v_w, b_g, b_a;
  std::vector<Eigen::Vector3d> landmarks;
  std::vector<std::pair<int, int>> observations;  // (frame, landmark)
  std::vector<Eigen::Vector3d> z_obs;             // measured points in the frame, noisy

  int frameDim() const { return vio ? 15 : 6; }
  int frames() const { return static_cast<int>(T_w_i.size()); }
  int dim() const { return frames() * frameDim() + 3 * static_cast<int>(landmarks.size()); }
  int poseCol(int i) const { return i * frameDim(); }
  int velCol(int i) const { return i * frameDim() + 6; }
  int bgCol(int i) const { return i * frameDim() + 9; }
  int baCol(int i) const { return i * frameDim() + 12; }
  int lmCol(int k) const { return frames() * frameDim() + 3 * k; }

  // x ⊞ δ over the full state (poses by se3.h's boxPlus, the rest additive).
  Window plus(const VecXd& delta) const {
    Window w = *this;
    for (int i = 0; i < frames(); ++i) {
      w.T_w_i[i] = boxPlus<double>(T_w_i[i], delta.segment<6>(poseCol(i)));
      if (vio) {
        w.v_w[i] += delta.segment<3>(velCol(i));
        w.b_g[i] += delta.segment<3>(bgCol(i));
        w.b_a[i] += delta.segment<3>(baCol(i));
      }
    }
    for (std::size_t k = 0; k < landmarks.size(); ++k) {
      w.landmarks[k] += delta.segment<3>(lmCol(static_cast<int>(k)));
    }
    return w;
  }

  // Residuals r(x) and analytic Jacobian J = ∂r/∂δ. Rows:
  //   point:        R_iᵀ(l − t_i) − z              (VO and VIO)
  //   VIO gravity:  R_iᵀ g − z_g                    (fixes roll and pitch)
  //   VIO motion:   R_iᵀ(t_j − t_i − v_i Δt − ½ g Δt²) − z_m,  j = i + 1
  //   VIO velocity: R_iᵀ v_i − z_v
  //   VIO biases:   b_j − b_i (gyro, accel)
  // With R ← exp(δφ) R: ∂(R_iᵀ a)/∂δφ = R_iᵀ [a]×.
  void linearize(VecXd& r, MatXd& J) const {
    std::vector<Eigen::Vector3d> rows;
    std::vector<std::vector<std::pair<int, Eigen::Matrix3d>>> blocks;
    for (std::size_t o = 0; o < observations.size(); ++o) {
      const auto [i, k] = observations[o];
      const Eigen::Matrix3d Rt = T_w_i[i].rotationMatrix().transpose();
      const Eigen::Vector3d a = landmarks[k] - T_w_i[i].translation();
      rows.push_back(Rt * a - z_obs[o]);
      blocks.push_back({{poseCol(i), -Rt}, {poseCol(i) + 3, Rt * hat(a)}, {lmCol(k), Rt}});
    }
    if (vio) {
      for (int i = 0; i < frames(); ++i) {
        const Eigen::Matrix3d Rt = T_w_i[i].rotationMatrix().transpose();
        rows.push_back(Rt * kGravity - Eigen::Vector3d(0.01, -0.02, 0.03));
        blocks.push_back({{poseCol(i) + 3, Rt * hat(kGravity)}});
        rows.push_back(Rt * v_w[i] - Eigen::Vector3d(0.02, 0.01, -0.01));
        blocks.push_back({{velCol(i), Rt}, {poseCol(i) + 3, Rt * hat(v_w[i])}});
        if (i + 1 == frames()) continue;
        const int j = i + 1;
        const Eigen::Vector3d d = T_w_i[j].translation() - T_w_i[i].translation() - v_w[i] * kDt -
                                  0.5 * kGravity * kDt * kDt;
        rows.push_back(Rt * d - Eigen::Vector3d(-0.01, 0.02, 0.01));
        blocks.push_back({{poseCol(i), -Rt},
                          {poseCol(j), Rt},
                          {velCol(i), -kDt * Rt},
                          {poseCol(i) + 3, Rt * hat(d)}});
        const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
        rows.push_back(b_g[j] - b_g[i]);
        blocks.push_back({{bgCol(i), -I}, {bgCol(j), I}});
        rows.push_back(b_a[j] - b_a[i]);
        blocks.push_back({{baCol(i), -I}, {baCol(j), I}});
      }
    }
    const int m = 3 * static_cast<int>(rows.size());
    r.resize(m);
    J = MatXd::Zero(m, dim());
    for (std::size_t q = 0; q < rows.size(); ++q) {
      const int row = 3 * static_cast<int>(q);
      r.segment<3>(row) = rows[q];
      for (const auto& [col, block] : blocks[q]) J.block<3, 3>(row, col) += block;
    }
  }
};

Window makeWindow(bool vio, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  auto randn3 = [&] { return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)); };
  Window w;
  w.vio = vio;
  const int frames = 5, landmarks = 24;
  for (int i = 0; i < frames; ++i) {
    const Eigen::Vector3d t(0.4 * i + 3.0, 0.1 * i * i - 1.0, 1.5 + 0.05 * normal(rng));
    w.T_w_i.emplace_back(expSO3Quaternion<double>(0.3 * randn3()), t);
    if (vio) {
      w.v_w.push_back(Eigen::Vector3d(4.0, 2.0 * i, 0.0) + 0.1 * randn3());
      w.b_g.push_back(0.01 * randn3());
      w.b_a.push_back(0.1 * randn3());
    }
  }
  for (int k = 0; k < landmarks; ++k)
    w.landmarks.push_back(Eigen::Vector3d(4.0, 0.0, 1.5) + 3.0 * randn3());
  for (int i = 0; i < frames; ++i) {
    for (int k = 0; k < landmarks; ++k) {
      if ((i + k) % 3 == 0 && !(i == 0 && k % 2 == 1)) continue;  // partial visibility
      w.observations.emplace_back(i, k);
      const Eigen::Vector3d p = w.T_w_i[i].inverse() * w.landmarks[k];
      w.z_obs.push_back(p + 0.01 * randn3());  // noisy: b_m ≠ 0
    }
  }
  return w;
}

// The prior on frames 1..N−1 after marginalizing frame 0 and all landmarks (Schur complement,
// eq. 3), plus the scale that bounds its rounding error: ‖H_kk‖ + ‖H_km‖² ‖H_mm⁻¹‖, and the
// analogous scale of b_m.
struct Prior {
  MatXd H_m;
  VecXd b_m;
  PriorLayout layout;
  GaugeState state;
  double H_scale = 0.0;
  double b_scale = 0.0;
};

Prior marginalizeFirstFrameAndLandmarks(const Window& w) {
  VecXd r;
  MatXd J;
  w.linearize(r, J);
  const MatXd H = J.transpose() * J;
  const VecXd b = J.transpose() * r;
  const int fd = w.frameDim(), n = w.dim();
  std::vector<int> marg, keep;
  for (int c = 0; c < n; ++c) ((c < fd || c >= w.lmCol(0)) ? marg : keep).push_back(c);
  auto sub = [&](const std::vector<int>& rs, const std::vector<int>& cs) {
    MatXd M(rs.size(), cs.size());
    for (std::size_t i = 0; i < rs.size(); ++i) {
      for (std::size_t j = 0; j < cs.size(); ++j) M(i, j) = H(rs[i], cs[j]);
    }
    return M;
  };
  auto subv = [&](const std::vector<int>& rs) {
    VecXd v(rs.size());
    for (std::size_t i = 0; i < rs.size(); ++i) v(i) = b(rs[i]);
    return v;
  };
  const MatXd H_mm = sub(marg, marg), H_km = sub(keep, marg), H_kk = sub(keep, keep);
  const VecXd b_mm = subv(marg), b_k = subv(keep);
  const MatXd H_mm_inv = H_mm.llt().solve(MatXd::Identity(H_mm.rows(), H_mm.cols()));
  Prior p;
  p.H_m = H_kk - H_km * H_mm_inv * H_km.transpose();
  p.b_m = b_k - H_km * H_mm_inv * b_mm;
  const double inv_norm = H_mm_inv.norm();
  p.H_scale = H_kk.norm() + H_km.squaredNorm() * inv_norm;
  p.b_scale = b_k.norm() + H_km.norm() * inv_norm * b_mm.norm();
  for (int i = 1; i < w.frames(); ++i) {
    const std::int64_t id = 1000 + i;
    const int base = (i - 1) * fd;
    p.layout.push_back({PriorVariableKind::kPose, id, base});
    p.state.T_w_i[id] = w.T_w_i[i];
    if (w.vio) {
      p.layout.push_back({PriorVariableKind::kVelocity, id, base + 6});
      p.layout.push_back({PriorVariableKind::kGyroBias, id, base + 9});
      p.layout.push_back({PriorVariableKind::kAccelBias, id, base + 12});
      p.state.v_w[id] = w.v_w[i];
    }
  }
  return p;
}

TEST(GaugeWindow, AnalyticJacobiansMatchCentralDifferences) {
  for (const bool vio : {false, true}) {
    const Window w = makeWindow(vio, 21);
    VecXd r;
    MatXd J;
    w.linearize(r, J);
    // Central differences: truncation h²/6 |r'''| plus rounding ε |r| / h; h = 1e-5 balances them
    // for |r| ~ 10 and curvature ~ 1 at ~1e-10.
    const double h = 1e-5;
    MatXd J_num(J.rows(), J.cols());
    for (int c = 0; c < w.dim(); ++c) {
      const VecXd e = VecXd::Unit(w.dim(), c) * h;
      VecXd r_plus, r_minus;
      MatXd unused;
      w.plus(e).linearize(r_plus, unused);
      w.plus(-e).linearize(r_minus, unused);
      J_num.col(c) = (r_plus - r_minus) / (2 * h);
    }
    EXPECT_LT((J - J_num).cwiseAbs().maxCoeff(), 1e-8) << (vio ? "VIO" : "VO");
  }
}

TEST(GaugeDirections, AreUnitLengthAndTranslationsOrthogonalToRotations) {
  const Prior p = marginalizeFirstFrameAndLandmarks(makeWindow(true, 22));
  const int n = static_cast<int>(p.H_m.rows());
  ASSERT_EQ(layoutDimension(p.layout), n);
  const GaugeDirections E = gaugeDirections(p.layout, n, p.state, 99);
  for (int k = 0; k < kNumGaugeDirections; ++k) EXPECT_NEAR(E.col(k).norm(), 1.0, 4 * kEps);
  // Σ_i δt_i of a rotation about the centroid is −[Σ(t_i − c)]× ω = 0, and velocities / biases
  // are 0 in translations: every translation is orthogonal to every rotation.
  for (int a = kGaugeX; a <= kGaugeZ; ++a) {
    for (int b = kGaugeX; b <= kGaugeZ; ++b) {
      EXPECT_NEAR(E.col(a).dot(E.col(b)), a == b ? 1.0 : 0.0, 4 * kEps);
    }
    for (int b = kGaugeRoll; b <= kGaugeYaw; ++b)
      EXPECT_NEAR(E.col(a).dot(E.col(b)), 0.0, 16 * kEps);
  }
  // Bias blocks are zero in every gauge direction.
  for (const PriorVariable& v : p.layout) {
    if (v.kind == PriorVariableKind::kGyroBias || v.kind == PriorVariableKind::kAccelBias) {
      EXPECT_EQ(E.block(v.offset, 0, 3, kGaugeRandom).norm(), 0.0);
    }
  }
  // The random direction is deterministic for a seed and changes with it.
  EXPECT_EQ(E.col(kGaugeRandom), gaugeDirections(p.layout, n, p.state, 99).col(kGaugeRandom));
  EXPECT_GT(
      (E.col(kGaugeRandom) - gaugeDirections(p.layout, n, p.state, 100).col(kGaugeRandom)).norm(),
      0.1);
}

// Centroid of the state's pose positions: gaugeDirections' default rotation centre.
Eigen::Vector3d poseCentroid(const GaugeState& state) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& [id, T] : state.T_w_i) c += T.translation();
  return c / static_cast<double>(state.T_w_i.size());
}

// x(θ) ⊟ x over the layout when the world is rotated by exp(θω) about c: poses
// (exp(θω) R_i, exp(θω)(t_i − c) + c), velocities exp(θω) v_i, points exp(θω)(p − c) + c.
VecXd rigidRotationDelta(const PriorLayout& layout, const GaugeState& state, int n,
                         const Eigen::Vector3d& c, const Eigen::Vector3d& omega, double theta) {
  const Eigen::Matrix3d R = expSO3<double>(theta * omega);
  VecXd d = VecXd::Zero(n);
  for (const PriorVariable& v : layout) {
    if (v.kind == PriorVariableKind::kPose) {
      const SE3d& T = state.T_w_i.at(v.frame_id);
      const SE3d T_rot(Eigen::Matrix3d(R * T.rotationMatrix()), R * (T.translation() - c) + c);
      d.segment<6>(v.offset) = boxMinus(T_rot, T);
    } else if (v.kind == PriorVariableKind::kVelocity) {
      const Eigen::Vector3d& vel = state.v_w.at(v.frame_id);
      d.segment<3>(v.offset) = R * vel - vel;
    } else if (v.kind == PriorVariableKind::kPoint) {
      const Eigen::Vector3d& x = state.p_w.at(v.frame_id);
      d.segment<3>(v.offset) = R * (x - c) + c - x;
    }
  }
  return d;
}

// The rotation directions are the derivative of the exact rigid rotation of the world about c:
// T_i(θ) = (exp(θω) R_i, exp(θω)(t_i − c) + c), v_i(θ) = exp(θω) v_i. Central difference of
// [T_i(θ) ⊟ T_i; v_i(θ) − v_i] at θ = ±h, normalized, against the direction (truncation O(h²)).
TEST(GaugeDirections, RotationMatchesCentralDifferenceOfRigidWorldRotation) {
  const Prior p = marginalizeFirstFrameAndLandmarks(makeWindow(true, 23));
  const int n = static_cast<int>(p.H_m.rows());
  const GaugeDirections E = gaugeDirections(p.layout, n, p.state, 1);
  const Eigen::Vector3d c = poseCentroid(p.state);
  const double h = 1e-5;
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d omega = Eigen::Vector3d::Unit(a);
    auto displaced = [&](double theta) {
      return rigidRotationDelta(p.layout, p.state, n, c, omega, theta);
    };
    const VecXd derivative = (displaced(h) - displaced(-h)) / (2 * h);
    const VecXd direction = derivative / derivative.norm();
    EXPECT_LT((direction - E.col(kGaugeRoll + a)).cwiseAbs().maxCoeff(), 1e-8) << "axis " << a;
    // To first order ⊞ along the direction reproduces the rotated poses: the gap is O(h²).
    const VecXd step = derivative.norm() * h * E.col(kGaugeRoll + a);
    const VecXd exact = displaced(h);
    for (const PriorVariable& v : p.layout) {
      if (v.kind != PriorVariableKind::kPose) continue;
      const SE3d& T = p.state.T_w_i.at(v.frame_id);
      const SE3d by_plus = boxPlus<double>(T, step.segment<6>(v.offset));
      const SE3d by_rotation = boxPlus<double>(T, exact.segment<6>(v.offset));
      EXPECT_LT(boxMinus(by_plus, by_rotation).norm(), 100 * h * h);
    }
  }
}

// World points (the landmarks of a dense keyframe prior) move with the world: δp = e_a in the
// translations, and the rotation directions are the derivative of p(θ) = exp(θω)(p − c) + c,
// checked by central differences together with the poses (truncation O(h²)).
TEST(GaugeDirections, PointsMoveRigidlyWithTheWorld) {
  const Prior p = marginalizeFirstFrameAndLandmarks(makeWindow(true, 24));
  PriorLayout layout = p.layout;
  GaugeState state = p.state;
  int n = static_cast<int>(p.H_m.rows());
  const std::vector<Eigen::Vector3d> points = {{1.0, -2.0, 3.0}, {-4.0, 0.5, 1.5}};
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto id = static_cast<std::int64_t>(900 + k);
    layout.push_back({PriorVariableKind::kPoint, id, n});
    state.p_w[id] = points[k];
    n += 3;
  }
  const GaugeDirections E = gaugeDirections(layout, n, state, 1);
  const Eigen::Vector3d c = poseCentroid(state);
  const double h = 1e-5;
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d omega = Eigen::Vector3d::Unit(a);
    const VecXd derivative = (rigidRotationDelta(layout, state, n, c, omega, h) -
                              rigidRotationDelta(layout, state, n, c, omega, -h)) /
                             (2 * h);
    EXPECT_LT((derivative / derivative.norm() - E.col(kGaugeRoll + a)).cwiseAbs().maxCoeff(), 1e-8)
        << "axis " << a;
    VecXd translation = VecXd::Zero(n);
    for (const PriorVariable& v : layout) {
      if (v.kind == PriorVariableKind::kPose || v.kind == PriorVariableKind::kPoint) {
        translation(v.offset + a) = 1.0;
      }
    }
    EXPECT_LT((translation.normalized() - E.col(kGaugeX + a)).cwiseAbs().maxCoeff(), 4 * kEps);
  }
  state.p_w.erase(901);
  EXPECT_THROW(gaugeDirections(layout, n, state, 1), std::invalid_argument);  // a point without p_w
}

// εᵀΛε against ‖Aᵀε‖² for Λ = AAᵀ (rank-deficient: A has fewer columns than rows), NaN for a
// zero direction, and a size mismatch throws.
TEST(GaugeInformation, IsTheQuadraticFormAlongEachDirection) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  const int n = 12;
  MatXd A(n, 7);
  for (int i = 0; i < A.size(); ++i) A.data()[i] = normal(rng);
  GaugeDirections E(n, kNumGaugeDirections);
  for (int i = 0; i < E.size(); ++i) E.data()[i] = normal(rng);
  E.col(kGaugeY).setZero();
  const Vec7d info = directionInformation(A * A.transpose(), E);
  for (int k = 0; k < kNumGaugeDirections; ++k) {
    if (k == kGaugeY) {
      EXPECT_TRUE(std::isnan(info(k)));
      continue;
    }
    const double expected = (A.transpose() * E.col(k)).squaredNorm();
    EXPECT_NEAR(info(k), expected, 8 * n * kEps * A.squaredNorm() * E.col(k).squaredNorm());
  }
  EXPECT_THROW(directionInformation(MatXd::Identity(n - 1, n - 1), E), std::invalid_argument);
}

// ΔE_m along gauge directions vanishes up to the rounding of forming the prior:
// |ΔE| ≤ n ε (‖H‖-scale + ‖b‖-scale), with the scales of the Schur complement above.
void expectGauge(bool vio, std::uint64_t seed) {
  const Prior p = marginalizeFirstFrameAndLandmarks(makeWindow(vio, seed));
  const int n = static_cast<int>(p.H_m.rows());
  const PriorDiagnostics d = diagnosePrior(p.H_m, p.b_m, p.layout, p.state, 5);
  const double tol = n * kEps * (p.H_scale + p.b_scale);
  const std::vector<int> gauge =
      vio ? std::vector<int>{kGaugeX, kGaugeY, kGaugeZ, kGaugeYaw}
          : std::vector<int>{kGaugeX, kGaugeY, kGaugeZ, kGaugeRoll, kGaugePitch, kGaugeYaw};
  for (int k = 0; k < kNumGaugeDirections; ++k) {
    const bool is_gauge = std::find(gauge.begin(), gauge.end(), k) != gauge.end();
    if (is_gauge) {
      EXPECT_LE(std::abs(d.dEm(k)), tol) << kGaugeDirectionNames[k];
    } else {
      EXPECT_GT(std::abs(d.dEm(k)), 1e6 * tol) << kGaugeDirectionNames[k];
    }
  }
  // The prior itself has exactly the gauge nullspace (VIO additionally the common bias offsets of
  // the random-walk-only biases: 6 more).
  EXPECT_EQ(d.spectrum.n_negative, 0);
  EXPECT_EQ(d.spectrum.rank, n - (vio ? 4 + 6 : 6));
}

TEST(GaugeCostChange, VoPriorHasSixDofGauge) { expectGauge(false, 31); }
TEST(GaugeCostChange, VioPriorHasFourDofGauge) { expectGauge(true, 32); }

TEST(GaugeCostChange, MatchesTheQuadraticModelAndSqrtForm) {
  const Prior p = marginalizeFirstFrameAndLandmarks(makeWindow(false, 33));
  const int n = static_cast<int>(p.H_m.rows());
  const GaugeDirections E = gaugeDirections(p.layout, n, p.state, 8);
  const Vec7d dE = priorCostChange(p.H_m, p.b_m, E);
  for (int k = 0; k < kNumGaugeDirections; ++k) {
    const VecXd e = E.col(k);
    const double expected = 0.5 * e.dot(p.H_m * e) + e.dot(p.b_m);
    EXPECT_NEAR(dE(k), expected, 4 * n * kEps * (p.H_scale + p.b_scale));
  }
  // Square-root form of the same prior: H = JᵀJ, b = Jᵀr with J = Lᵀ (H = L Lᵀ after a small
  // ridge making it definite), r = L⁻¹ b.
  const MatXd H_pd = p.H_m + 1e-3 * MatXd::Identity(n, n);
  const Eigen::LLT<MatXd> llt(H_pd);
  const MatXd J = llt.matrixU();
  const VecXd r = llt.matrixL().solve(p.b_m);
  const PriorDiagnostics sq = diagnosePrior(H_pd, p.b_m, p.layout, p.state, 8);
  const PriorDiagnostics rt = diagnoseSqrtPrior(J, r, p.layout, p.state, 8);
  for (int k = 0; k < kNumGaugeDirections; ++k) {
    EXPECT_NEAR(rt.dEm(k), sq.dEm(k), 64 * n * kEps * (p.H_scale + p.b_scale));
  }
}

TEST(GaugeDirections, ZeroDirectionsGiveNaNAndBadLayoutsThrow) {
  // Only bias blocks: every gauge direction is 0 on the layout → NaN, the random one is finite.
  const PriorLayout biases = {{PriorVariableKind::kGyroBias, 1, 0},
                              {PriorVariableKind::kAccelBias, 1, 3}};
  const GaugeDirections E = gaugeDirections(biases, 6, GaugeState{}, 3);
  const Vec7d dE = priorCostChange(MatXd::Identity(6, 6), VecXd::Zero(6), E);
  for (int k = 0; k < kGaugeRandom; ++k) EXPECT_TRUE(std::isnan(dE(k)));
  EXPECT_NEAR(dE(kGaugeRandom), 0.5, 4 * kEps);

  const PriorLayout overlap = {{PriorVariableKind::kPose, 1, 0},
                               {PriorVariableKind::kVelocity, 1, 4}};
  EXPECT_THROW(layoutDimension(overlap), std::invalid_argument);
  const PriorLayout pose = {{PriorVariableKind::kPose, 7, 0}};
  EXPECT_THROW(gaugeDirections(pose, 6, GaugeState{}, 1), std::invalid_argument);  // no T_w_i
  GaugeState state;
  state.T_w_i[7] = SE3d();
  EXPECT_THROW(gaugeDirections(pose, 5, state, 1), std::invalid_argument);  // n too small
}

TEST(GaugeDirections, RandomUnitVectorIsStandardNormalBeforeNormalization) {
  // 20000 Box–Muller samples, checked through scale-free moments: mean ≈ 0, kurtosis ≈ 3
  // (standard errors ≈ 0.007 and 0.035 for the normalized vector times √n).
  const int n = 20000;
  const VecXd x = randomUnitVector(n, 17) * std::sqrt(static_cast<double>(n));
  EXPECT_NEAR(x.norm() / std::sqrt(static_cast<double>(n)), 1.0, 1e-12);
  EXPECT_NEAR(x.mean(), 0.0, 0.03);
  EXPECT_NEAR(x.array().pow(4).mean(), 3.0, 0.15);
  EXPECT_EQ(randomUnitVector(5, 17), randomUnitVector(5, 17));
}

}  // namespace
}  // namespace marglab
