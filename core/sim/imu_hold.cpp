#include "core/sim/imu_hold.h"

#include "core/imu/imu_factor.h"
#include "core/imu/preintegration.h"
#include "core/sim/imu_synth.h"

namespace marglab {

namespace {

ImuState<double> stateAt(const TrajectoryFunction& trajectory, int64_t t_ns) {
  const TrajectorySample s = trajectory.evaluate(t_ns);
  ImuState<double> x;
  x.t_ns = t_ns;
  x.T_w_i = SE3<double>(s.R_w_b, s.p_w_b);
  x.v_w = s.v_w;
  return x;
}

}  // namespace

std::vector<ImuHoldInterval> imuHoldErrors(const TrajectoryFunction& trajectory,
                                           const std::vector<int64_t>& frame_t_ns,
                                           const ImuNoise& noise, const Eigen::Vector3d& g_w,
                                           double rate_hz, double sample_shift_s) {
  ImuSynthOptions options = ImuSynthOptions::noiseFree();
  options.gravity_w = g_w;
  options.sample_shift_s = sample_shift_s;
  const ImuData imu = synthesizeImu(trajectory, noise, rate_hz, 0, options).imu;
  const auto sample_noise = ImuSampleNoise<double>::fromDensities(noise, 1.0 / rate_hz);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  std::vector<ImuHoldInterval> out;
  for (std::size_t k = 0; k + 1 < frame_t_ns.size(); ++k) {
    const int64_t t_i = frame_t_ns[k], t_j = frame_t_ns[k + 1];
    if (t_i < imu.t_ns.front() || t_j > trajectory.endTimeNs() || t_j <= t_i) continue;
    const ImuFactor<double> factor(preintegrate<double>(imu, t_i, t_j, zero, zero, sample_noise),
                                   g_w);
    const ImuState<double> s_i = stateAt(trajectory, t_i), s_j = stateAt(trajectory, t_j);
    const Vec<double, 9> r = factor.residual(s_i, s_j);
    ImuHoldInterval h;
    h.t_i_ns = t_i;
    h.t_j_ns = t_j;
    h.pos_m = r.segment<3>(PreintIndex::kPos).norm();
    h.rot_rad = r.segment<3>(PreintIndex::kRot).norm();
    h.vel_mps = r.segment<3>(PreintIndex::kVel).norm();
    h.chi2 = factor.whitenedResidual(s_i, s_j).squaredNorm();
    out.push_back(h);
  }
  return out;
}

}  // namespace marglab
