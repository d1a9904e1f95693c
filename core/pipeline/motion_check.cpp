#include "core/pipeline/motion_check.h"
#include "core/common/statistics.h"

#include <fmt/core.h>

#include <algorithm>

namespace marglab {

double MotionCheck::recentStep() const { return median(steps_); }

std::string MotionCheck::update(int frame_index, std::int64_t t_ns, const Eigen::Vector3d& p_est) {
  std::string failure;
  if (max_jump_ > 0 && p_.size() == 2 && t_ns_[1] > t_ns_[0] && !steps_.empty()) {
    const double ratio =
        static_cast<double>(t_ns - t_ns_[1]) / static_cast<double>(t_ns_[1] - t_ns_[0]);
    const Eigen::Vector3d predicted = p_[1] + (p_[1] - p_[0]) * ratio;
    const double off = (p_est - predicted).norm();
    const double scale = std::max(recentStep(), floor_m_);
    if (off > max_jump_ * scale) {
      failure = fmt::format(
          "motion inconsistent at frame {}: the estimate lies {:.3g} m from the constant-velocity "
          "prediction, {:.1f} times the recent motion of {:.3g} m per frame "
          "(failure.max_motion_jump "
          "= {:g}): frames out of order, or an estimate that jumped",
          frame_index, off, off / scale, scale, max_jump_);
    }
  }
  if (!p_.empty()) {
    steps_.push_back((p_est - p_.back()).norm());
    if (steps_.size() > static_cast<std::size_t>(kRecentSteps)) steps_.erase(steps_.begin());
  }
  p_.push_back(p_est);
  t_ns_.push_back(t_ns);
  if (p_.size() > 2) {
    p_.erase(p_.begin());
    t_ns_.erase(t_ns_.begin());
  }
  return failure;
}

}  // namespace marglab
