#include "core/diagnostics/gauge.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <utility>

#include "core/geometry/so3.h"

namespace marglab {

int variableDimension(PriorVariableKind kind) {
  if (kind == PriorVariableKind::kCalibration) return 1;
  return kind == PriorVariableKind::kPose ? 6 : 3;
}

const char* variableKindName(PriorVariableKind kind) {
  switch (kind) {
    case PriorVariableKind::kPose:
      return "pose";
    case PriorVariableKind::kVelocity:
      return "velocity";
    case PriorVariableKind::kGyroBias:
      return "bias_gyro";
    case PriorVariableKind::kAccelBias:
      return "bias_accel";
    case PriorVariableKind::kPoint:
      return "point";
    case PriorVariableKind::kCalibration:
      return "calibration";
  }
  return "unknown";
}

int layoutDimension(const PriorLayout& layout) {
  std::vector<std::pair<int, int>> ranges;
  for (const PriorVariable& v : layout) {
    if (v.offset < 0) throw std::invalid_argument("prior layout: negative offset");
    ranges.emplace_back(v.offset, v.offset + variableDimension(v.kind));
  }
  std::sort(ranges.begin(), ranges.end());
  int n = 0;
  for (const auto& [begin, end] : ranges) {
    if (begin < n) throw std::invalid_argument("prior layout: overlapping blocks");
    n = end;
  }
  return n;
}

VecXd randomUnitVector(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  // Uniform in (0, 1]: 53 random bits, shifted by one ulp so that log(u) is finite.
  auto uniform = [&rng] { return (static_cast<double>(rng() >> 11) + 1.0) * 0x1.0p-53; };
  constexpr double kTwoPi = 6.283185307179586476925;
  VecXd x(n);
  for (int i = 0; i < n; i += 2) {
    const double radius = std::sqrt(-2.0 * std::log(uniform()));
    const double angle = kTwoPi * uniform();
    x(i) = radius * std::cos(angle);
    if (i + 1 < n) x(i + 1) = radius * std::sin(angle);
  }
  const double norm = x.norm();
  if (norm > 0.0) x /= norm;
  return x;
}

GaugeDirections gaugeDirections(const PriorLayout& layout, int n, const GaugeState& state,
                                std::uint64_t seed) {
  if (n < layoutDimension(layout)) throw std::invalid_argument("gaugeDirections: n < layout size");
  auto poseOf = [&state](std::int64_t id) -> const SE3d& {
    const auto it = state.T_w_i.find(id);
    if (it == state.T_w_i.end()) throw std::invalid_argument("gaugeDirections: no pose for frame");
    return it->second;
  };

  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  if (state.center) {
    c = *state.center;
  } else {
    int poses = 0;
    for (const PriorVariable& v : layout) {
      if (v.kind != PriorVariableKind::kPose) continue;
      c += poseOf(v.frame_id).translation();
      ++poses;
    }
    if (poses > 0) c /= poses;
  }

  GaugeDirections E = GaugeDirections::Zero(n, kNumGaugeDirections);
  for (const PriorVariable& v : layout) {
    if (v.kind == PriorVariableKind::kPose) {
      const Eigen::Vector3d t_minus_c = poseOf(v.frame_id).translation() - c;
      const Eigen::Matrix3d minus_hat_t = -hat(t_minus_c);
      for (int a = 0; a < 3; ++a) {
        E(v.offset + a, kGaugeX + a) = 1.0;
        E.block<3, 1>(v.offset, kGaugeRoll + a) = minus_hat_t.col(a);
        E(v.offset + 3 + a, kGaugeRoll + a) = 1.0;
      }
    } else if (v.kind == PriorVariableKind::kVelocity) {
      const auto it = state.v_w.find(v.frame_id);
      if (it == state.v_w.end()) throw std::invalid_argument("gaugeDirections: no velocity");
      const Eigen::Matrix3d minus_hat_v = -hat(it->second);
      for (int a = 0; a < 3; ++a) E.block<3, 1>(v.offset, kGaugeRoll + a) = minus_hat_v.col(a);
    } else if (v.kind == PriorVariableKind::kPoint) {
      const auto it = state.p_w.find(v.frame_id);
      if (it == state.p_w.end()) throw std::invalid_argument("gaugeDirections: no point");
      const Eigen::Matrix3d minus_hat_p = -hat(Eigen::Vector3d(it->second - c));
      for (int a = 0; a < 3; ++a) {
        E(v.offset + a, kGaugeX + a) = 1.0;
        E.block<3, 1>(v.offset, kGaugeRoll + a) = minus_hat_p.col(a);
      }
    }
  }
  for (int k = 0; k < kGaugeRandom; ++k) {
    const double norm = E.col(k).norm();
    if (norm > 0.0) E.col(k) /= norm;
  }
  E.col(kGaugeRandom) = randomUnitVector(n, seed);
  return E;
}

Vec7d priorCostChange(const MatXd& H_m, const VecXd& b_m, const GaugeDirections& directions) {
  if (H_m.rows() != directions.rows() || H_m.cols() != directions.rows() ||
      b_m.size() != directions.rows()) {
    throw std::invalid_argument("priorCostChange: dimension mismatch");
  }
  Vec7d dE;
  for (int k = 0; k < kNumGaugeDirections; ++k) {
    const auto eps = directions.col(k);
    dE(k) = eps.squaredNorm() == 0.0 ? std::numeric_limits<double>::quiet_NaN()
                                     : 0.5 * eps.dot(H_m * eps) + eps.dot(b_m);
  }
  return dE;
}

Vec7d directionInformation(const MatXd& Lambda, const GaugeDirections& directions) {
  if (Lambda.rows() != directions.rows() || Lambda.cols() != directions.rows()) {
    throw std::invalid_argument("directionInformation: dimension mismatch");
  }
  Vec7d info;
  for (int k = 0; k < kNumGaugeDirections; ++k) {
    const auto eps = directions.col(k);
    info(k) =
        eps.squaredNorm() == 0.0 ? std::numeric_limits<double>::quiet_NaN() : eps.dot(Lambda * eps);
  }
  return info;
}

}  // namespace marglab
