#include "core/estimator/window_snapshot.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "core/common/scalar.h"

namespace marglab {

int WindowSnapshot::numObservations() const {
  int n = 0;
  for (const LandmarkState& lm : landmarks) {
    for (const ObservationState& o : lm.obs) n += o.has_right ? 2 : 1;
  }
  return n;
}

namespace {

// SE3 normalizes its quaternion on construction, and normalizing a unit quaternion again changes
// its last bits for about a third of all rotations; a window restored in its own precision must
// hold the very same bits, so a quaternion that is unit to the precision of S is assigned after
// construction. A float quaternion restored in double (‖q‖² − 1 ~ 1e-7) is normalized in double.
template <typename S>
SE3<S> exactPose(const SE3<double>& T) {
  const Eigen::Quaternion<S> q = T.unitQuaternion().template cast<S>();
  SE3<S> out(q, T.translation().template cast<S>());
  if (std::abs(q.coeffs().squaredNorm() - S(1)) <= S(8) * std::numeric_limits<S>::epsilon()) {
    const_cast<Eigen::Quaternion<S>&>(out.unitQuaternion()) = q;
  }
  return out;
}

// The IMU part of a snapshot: noise, gravity, the links' linearization biases and the samples their
// preintegration reads.
template <typename Scalar>
void snapshotImu(const Window<Scalar>& w_in, const ImuSetup& imu, WindowSnapshot* out) {
  WindowSnapshot& w = *out;
  w.imu_noise = imu.noise;
  w.imu_sample_period_s = imu.sample_period_s;
  w.g_w = imu.g_w;
  int64_t t_min = std::numeric_limits<int64_t>::max(), t_max = std::numeric_limits<int64_t>::min();
  for (const auto& [from, link] : w_in.imu_links) {
    const ImuPreintegration<Scalar>& pre = link.factor.preintegration();
    w.imu_links.push_back({from, link.to, pre.biasGyroLin().template cast<double>(),
                           pre.biasAccelLin().template cast<double>()});
    t_min = std::min(t_min, w_in.frames.at(from).t_ns);
    t_max = std::max(t_max, w_in.frames.at(link.to).t_ns);
  }
  // The samples preintegration reads: from the one in force at the first link's start (with a
  // margin) to the first one at or after the last link's end.
  const std::vector<int64_t>& t = imu.imu.t_ns;
  if (!w_in.imu_links.empty() && !t.empty()) {
    const auto lo_it = std::upper_bound(t.begin(), t.end(), t_min);
    const auto hi_it = std::upper_bound(t.begin(), t.end(), t_max);
    const size_t lo = static_cast<size_t>(std::max<std::ptrdiff_t>(0, lo_it - t.begin() - 2));
    const size_t hi = std::min(t.size() - 1, static_cast<size_t>(hi_it - t.begin()) + 1);
    for (size_t k = lo; k <= hi; ++k) {
      w.imu.t_ns.push_back(t[k]);
      w.imu.gyro.push_back(imu.imu.gyro[k]);
      w.imu.accel.push_back(imu.imu.accel[k]);
    }
  }
}

}  // namespace

template <typename Scalar>
WindowSnapshot snapshotOf(const Window<Scalar>& w_in) {
  using SE3S = SE3<Scalar>;
  // Exact widening of a Scalar pose (no renormalization).
  auto widen = [](const SE3S& T) {
    SE3<double> out(T.unitQuaternion().template cast<double>(),
                    T.translation().template cast<double>());
    const_cast<Eigen::Quaterniond&>(out.unitQuaternion()) =
        T.unitQuaternion().template cast<double>();
    return out;
  };
  WindowSnapshot w;
  w.config = w_in.config();
  w.rig = w_in.rigInput();
  w.vio = w_in.isVio();
  for (const auto& [id, f] : w_in.frames) {
    WindowSnapshot::FrameState fs;
    fs.id = id;
    fs.t_ns = f.t_ns;
    fs.is_keyframe = f.is_keyframe;
    fs.linearized = f.linearized;
    fs.has_speed_bias = f.has_speed_bias;
    fs.speed_bias_linearized = f.speed_bias_linearized;
    fs.T_w_i = widen(f.T_w_i);
    fs.T_w_i_lin = widen(f.T_w_i_lin);
    fs.speed_bias = f.speed_bias.template cast<double>();
    fs.speed_bias_lin = f.speed_bias_lin.template cast<double>();
    w.frames.push_back(fs);
  }
  for (const auto& [id, lm] : w_in.landmarks) {
    WindowSnapshot::LandmarkState ls;
    ls.id = id;
    ls.host = lm.host;
    ls.param = lm.param.template cast<double>();
    for (const auto& [frame, o] : lm.obs) {
      ls.obs.push_back(
          {frame, o.uv0.template cast<double>(), o.uv1.template cast<double>(), o.has_right});
    }
    w.landmarks.push_back(std::move(ls));
  }
  if (const std::optional<ImuSetup>& imu = w_in.imu()) snapshotImu(w_in, *imu, &w);
  const MargPrior<Scalar>& prior = w_in.prior;
  // A preconditioned Hessian prior is captured unscaled, as a Hessian prior.
  w.prior_representation = prior.storage.representation;
  for (const auto& block : prior.blocks) {
    w.prior_blocks.push_back(
        {block.var, block.offset, widen(block.T0), block.sb0.template cast<double>()});
  }
  w.prior_J = prior.sqrt.J.template cast<double>();
  w.prior_r = prior.sqrt.r.template cast<double>();
  w.prior_H = (prior.scaled() ? prior.hessianAtAnchor() : prior.hessian.H).template cast<double>();
  w.prior_b = (prior.scaled() ? prior.gradientAtAnchor() : prior.hessian.b).template cast<double>();
  w.prior_c = static_cast<double>(prior.hessian.c);
  return w;
}

template <typename Scalar>
std::optional<ImuSetup> imuSetupOf(const WindowSnapshot& w) {
  if (!w.vio) return std::nullopt;
  ImuSetup setup;
  setup.imu = w.imu;
  setup.noise = w.imu_noise;
  setup.sample_period_s = w.imu_sample_period_s;
  setup.g_w = w.g_w;
  setup.initial.T_w_i = w.frames.front().T_w_i;
  return setup;
}

template <typename Scalar>
void restoreWindow(const WindowSnapshot& w, const PriorStorage& storage, Window<Scalar>* window) {
  Window<Scalar>& est = *window;
  for (const auto& fs : w.frames) {
    typename Window<Scalar>::Frame f;
    f.t_ns = fs.t_ns;
    f.T_w_i = exactPose<Scalar>(fs.T_w_i);
    f.T_w_i_lin = exactPose<Scalar>(fs.T_w_i_lin);
    f.linearized = fs.linearized;
    f.is_keyframe = fs.is_keyframe;
    f.has_speed_bias = fs.has_speed_bias;
    f.speed_bias = fs.speed_bias.template cast<Scalar>();
    f.speed_bias_lin = fs.speed_bias_lin.template cast<Scalar>();
    f.speed_bias_linearized = fs.speed_bias_linearized;
    est.frames[fs.id] = f;
  }
  for (const auto& ls : w.landmarks) {
    if (est.frames.count(ls.host) == 0) throw InputError("", 0, "window: landmark host missing");
    typename Window<Scalar>::Landmark lm;
    lm.host = ls.host;
    lm.param = ls.param.template cast<Scalar>();
    for (const auto& o : ls.obs) {
      if (est.frames.count(o.frame) == 0)
        throw InputError("", 0, "window: observing frame missing");
      lm.obs[o.frame] = typename Window<Scalar>::Observation{
          o.uv0.template cast<Scalar>(), o.has_right, o.uv1.template cast<Scalar>()};
    }
    est.landmarks.emplace(ls.id, std::move(lm));
  }
  for (const auto& link : w.imu_links) {
    if (!w.vio || est.frames.count(link.from) == 0 || est.frames.count(link.to) == 0) {
      throw InputError("", 0, "window: IMU factor between missing frames");
    }
    est.imu_links.emplace(
        link.from, est.makeImuLink(link.from, link.to, link.bias_gyro_lin, link.bias_accel_lin));
  }
  MargPrior<Scalar>& prior = est.prior;
  for (const auto& b : w.prior_blocks) {
    typename MargPrior<Scalar>::Block block;
    block.var = b.var;
    block.offset = b.offset;
    block.T0 = exactPose<Scalar>(b.T0);
    block.sb0 = b.sb0.template cast<Scalar>();
    prior.blocks.push_back(block);
  }
  if (w.prior_representation == storage.representation) {
    prior.sqrt.J = w.prior_J.template cast<Scalar>();
    prior.sqrt.r = w.prior_r.template cast<Scalar>();
    prior.hessian.H = w.prior_H.template cast<Scalar>();
    prior.hessian.b = w.prior_b.template cast<Scalar>();
    prior.hessian.c = static_cast<Scalar>(w.prior_c);
  } else if (w.prior_representation == Representation::kSqrt) {
    // E_m = ½‖r + Jδ‖² = ½δᵀ(JᵀJ)δ + (Jᵀr)ᵀδ + ½‖r‖², formed in double.
    prior.hessian.H = (w.prior_J.transpose() * w.prior_J).template cast<Scalar>();
    prior.hessian.b = (w.prior_J.transpose() * w.prior_r).template cast<Scalar>();
    prior.hessian.c = static_cast<Scalar>(0.5 * w.prior_r.squaredNorm());
  } else {
    throw InputError("", 0, "window: a Hessian prior cannot be replayed with square-root storage");
  }
  const int cols = prior.empty() ? 0 : prior.cols();
  const bool sqrt_storage = sqrtStorage(storage);
  if (!prior.empty() &&
      (sqrt_storage ? prior.sqrt.J.cols() != cols || prior.sqrt.r.size() != prior.sqrt.J.rows()
                    : prior.hessian.H.cols() != cols || prior.hessian.b.size() != cols)) {
    throw InputError("", 0, "window: prior size does not match its layout");
  }
  prior.precondition();
}

template <typename Scalar>
Window<Scalar> restoredWindow(const WindowSnapshot& w, const Variant& variant,
                              const EstimatorSettings& config) {
  if (w.frames.empty()) throw InputError("", 0, "window: no frames");
  Window<Scalar> window(config, w.rig, imuSetupOf<Scalar>(w));
  // restoreWindow preconditions the prior as its storage says.
  window.prior.storage = withPsdHessianPrior(variant.storage, config.psd_hessian_prior);
  restoreWindow(w, variant.storage, &window);
  return window;
}

template <typename Scalar>
WindowSnapshot::Step stepOf(const Window<Scalar>& window, int lm_iterations, double cost_initial,
                            double cost_final) {
  WindowSnapshot now = snapshotOf(window);
  WindowSnapshot::Step step;
  step.present = true;
  step.lm_iterations = lm_iterations;
  step.cost_initial = cost_initial;
  step.cost_final = cost_final;
  step.frames = std::move(now.frames);
  step.landmarks = std::move(now.landmarks);
  for (auto& lm : step.landmarks) lm.obs.clear();
  return step;
}

#define MARGLAB_INST(S)                                                                   \
  template WindowSnapshot snapshotOf<S>(const Window<S>&);                                \
  template std::optional<ImuSetup> imuSetupOf<S>(const WindowSnapshot&);                  \
  template void restoreWindow<S>(const WindowSnapshot&, const PriorStorage&, Window<S>*); \
  template Window<S> restoredWindow<S>(const WindowSnapshot&, const Variant&,             \
                                       const EstimatorSettings&);                         \
  template WindowSnapshot::Step stepOf<S>(const Window<S>&, int, double, double);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
