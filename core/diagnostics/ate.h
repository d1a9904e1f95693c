#pragma once
// Absolute trajectory error (docs/design.md §4): association with ground truth, rigid alignment
// without scale, RMSE, and TUM-format export.
//
// Association. Each estimated position (t, p) is paired with the ground-truth position at t,
// linearly interpolated between the GT samples t_k ≤ t ≤ t_{k+1}:
//   p_gt(t) = p_k + (t − t_k)/(t_{k+1} − t_k) · (p_{k+1} − p_k).
// The pair is skipped when t is outside [t_0, t_N] or the bracketing GT gap t_{k+1} − t_k exceeds
// max_gap (default 0.11 s: EuRoC GT has dropouts; interpolating across them would invent ground
// truth). A t equal to a GT stamp uses that sample.
//
// Alignment (Umeyama 1991 without scale, i.e. Kabsch). For pairs (s_i = p_est, d_i = p_gt),
// find R ∈ SO(3), t minimizing Σ‖d_i − (R s_i + t)‖²:
//   μ_s, μ_d the means,  Σ = (1/N) Σ (d_i − μ_d)(s_i − μ_s)ᵀ = U D Vᵀ (SVD),
//   R = U S Vᵀ with S = diag(1, 1, det(U)det(V))  — the reflection fix: without S a planar or
//   noisy configuration can yield det(R) = −1, a mirror, not a rotation (Umeyama eq. 39–43),
//   t = μ_d − R μ_s.
// ATE RMSE = sqrt(1/N Σ ‖d_i − (R s_i + t)‖²); the per-frame error is ‖d_i − (R s_i + t)‖.
// Degenerate sets (collinear, N < 3) give a non-unique R but still the minimal RMSE.
//
// TUM format (what evo reads): one line per pose "t x y z qx qy qz qw", t in seconds with 9
// decimals (exact from the integer nanoseconds), space separated, no header.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/data/types.h"

namespace marglab {

inline constexpr std::int64_t kDefaultMaxGtGapNs = 110'000'000;  // 0.11 s

// GT position at t_ns (see header comment), or nullopt when t is outside the GT span or inside a
// gap longer than max_gap_ns. gt.t_ns must be strictly increasing.
std::optional<Eigen::Vector3d> interpolatePosition(const Trajectory& gt, std::int64_t t_ns,
                                                   std::int64_t max_gap_ns = kDefaultMaxGtGapNs);

// p_gt ≈ R p_est + t.
struct RigidAlignment {
  Eigen::Matrix3d R_gt_est = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_gt_est = Eigen::Vector3d::Zero();
  bool valid = false;  // false when there are no pairs
};

// Umeyama / Kabsch without scale, with the reflection fix (src → dst). Sizes must match.
RigidAlignment alignRigid(const std::vector<Eigen::Vector3d>& src,
                          const std::vector<Eigen::Vector3d>& dst);

struct AteResult {
  double rmse = 0.0;  // NaN when no pair
  std::size_t n_pairs = 0;
  RigidAlignment alignment;
  std::vector<double> error;  // per estimate, after alignment; NaN when not associated
};

// Pairs are the rows i where both p_est[i] and p_gt[i] are finite (p_gt NaN = no ground truth).
AteResult computeAte(const std::vector<Eigen::Vector3d>& p_est,
                     const std::vector<Eigen::Vector3d>& p_gt);
// Associates (t_ns[i], p_est[i]) with gt by interpolatePosition, then as above.
AteResult computeAte(const std::vector<std::int64_t>& t_ns,
                     const std::vector<Eigen::Vector3d>& p_est, const Trajectory& gt,
                     std::int64_t max_gap_ns = kDefaultMaxGtGapNs);

// Writes the TUM file atomically (temporary sibling + rename). Throws InputError on I/O errors
// and std::invalid_argument on size mismatch.
void writeTumTrajectory(const std::string& path, const std::vector<std::int64_t>& t_ns,
                        const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<Eigen::Quaterniond>& quaternions);

}  // namespace marglab
