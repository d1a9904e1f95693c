#include "core/estimator/vo_estimator.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

#include "core/common/scalar.h"
#include "core/geometry/stereographic.h"
#include "core/linalg/flat_qr.h"
#include "core/linalg/landmark_block.h"
#include "core/linalg/rcs_solve.h"
#include "core/linalg/schur.h"

namespace marglab {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The landmark eliminations of one LM iteration, in the variant's flavour.
template <typename Scalar>
struct ReducedSystem {
  std::vector<LandmarkBlockNs<Scalar>> ns;
  std::vector<LandmarkBlockSc<Scalar>> sc;
  MatX<Scalar> H_prior;
  VecX<Scalar> b_prior;
  MatX<Scalar> H;
  VecX<Scalar> b;
};

// Adds the prior's Hessian and gradient at δ to a system whose pose columns are column_of.
template <typename Scalar>
void addPrior(const MargPrior<Scalar>& prior, const VecX<Scalar>& delta,
              const std::map<int64_t, int>& column_of, MatX<Scalar>& H, VecX<Scalar>& b) {
  constexpr int kPoseDim = MargPrior<Scalar>::kPoseDim;
  MatX<Scalar> Hp;
  VecX<Scalar> bp;
  prior.linearize(delta, &Hp, &bp);
  for (size_t i = 0; i < prior.frame_ids.size(); ++i) {
    const int ci = column_of.at(prior.frame_ids[i]);
    b.template segment<kPoseDim>(ci) += bp.template segment<kPoseDim>(kPoseDim * i);
    for (size_t j = 0; j < prior.frame_ids.size(); ++j) {
      H.template block<kPoseDim, kPoseDim>(ci, column_of.at(prior.frame_ids[j])) +=
          Hp.template block<kPoseDim, kPoseDim>(kPoseDim * i, kPoseDim * j);
    }
  }
}

}  // namespace

template <typename Scalar>
VoEstimator<Scalar>::VoEstimator(const EstimatorConfig& config, const Variant& variant,
                                 const StereoRig<double>& rig, const SE3<double>& T_w_c0_initial)
    : config_(config),
      variant_(variant),
      rig_(rig.template cast<Scalar>()),
      T_c0_c1_(rig.T_c0_c1().template cast<Scalar>()),
      last_pose_(T_w_c0_initial),
      lambda_(static_cast<Scalar>(config.lambda_init)) {
  prior_.storage = variant.storage;
  shadow_prior_.storage = variant.storage;
  if (config_.min_frames_after_kf < 1) config_.min_frames_after_kf = 1;
}

template <typename Scalar>
int VoEstimator<Scalar>::numKeyframes() const {
  return static_cast<int>(std::count_if(frames_.begin(), frames_.end(),
                                        [](const auto& f) { return f.second.is_keyframe; }));
}

template <typename Scalar>
typename VoEstimator<Scalar>::SE3S VoEstimator<Scalar>::jacobianPoseOf(int64_t frame_id) const {
  const Frame& frame = frames_.at(frame_id);
  return frame.linearized ? frame.T_w_c_lin : frame.T_w_c;
}

// Huber cost of a reprojection error e (pixels), divided by σ²: ½e² inside, k·e − ½k² outside.
template <typename Scalar>
static Scalar huberCost(Scalar e, Scalar k, Scalar sigma) {
  const Scalar c = e <= k ? Scalar(0.5) * e * e : k * e - Scalar(0.5) * k * k;
  return c / (sigma * sigma);
}

template <typename Scalar>
Scalar VoEstimator<Scalar>::landmarkCost(const Landmark& lm) const {
  const Scalar k = static_cast<Scalar>(config_.huber_px);
  const Scalar sigma = static_cast<Scalar>(config_.obs_std_px);
  const SE3S& T_w_h = frames_.at(lm.host).T_w_c;
  Scalar cost = 0;
  for (const auto& [frame_id, obs] : lm.obs) {
    const SE3S& T_w_t = frames_.at(frame_id).T_w_c;
    for (int cam = 0; cam < (obs.has_right ? 2 : 1); ++cam) {
      const SE3S T_i_ct = cam == 0 ? SE3S() : T_c0_c1_;
      const SE3S T_ct_h = frame_id == lm.host ? T_i_ct.inverse()
                                              : relativePose<Scalar>(T_w_h, SE3S(), T_w_t, T_i_ct);
      const Vec3S q = transformLandmark<Scalar>(T_ct_h, lm.param);
      Vec2S uv;
      if (!(cam == 0 ? rig_.cam0 : rig_.cam1).project(q, &uv)) continue;
      cost += huberCost<Scalar>((uv - (cam == 0 ? obs.uv0 : obs.uv1)).norm(), k, sigma);
    }
  }
  return cost;
}

template <typename Scalar>
Scalar VoEstimator<Scalar>::totalCost() const {
  Scalar cost = 0;
  for (const auto& [id, lm] : landmarks_) cost += landmarkCost(lm);
  if (!prior_.empty()) {
    cost += prior_.cost(prior_.delta([this](int64_t f) { return poseOf(f); }));
  }
  return cost;
}

template <typename Scalar>
bool VoEstimator<Scalar>::linearizeLandmark(int64_t track_id, const Landmark& lm,
                                            const std::set<int64_t>& system_frames,
                                            Linearized* out) const {
  const Scalar k = static_cast<Scalar>(config_.huber_px);
  const Scalar sigma = static_cast<Scalar>(config_.obs_std_px);
  struct Row2 {
    int64_t target;  // −1: no pose Jacobian (observation in the host frame)
    Mat<Scalar, 2, 6> J_h, J_t;
    Mat<Scalar, 2, 3> J_l;
    Vec2S r;
  };
  std::vector<Row2> rows;
  out->cost = 0;
  const SE3S& T_w_h = frames_.at(lm.host).T_w_c;
  const SE3S T_w_h_jac = jacobianPoseOf(lm.host);
  const bool host_linearized = frames_.at(lm.host).linearized;
  for (const auto& [frame_id, obs] : lm.obs) {
    if (system_frames.count(frame_id) == 0) continue;
    const bool in_host = frame_id == lm.host;
    for (int cam = 0; cam < (obs.has_right ? 2 : 1); ++cam) {
      const PinholeCamera<Scalar>& camera = cam == 0 ? rig_.cam0 : rig_.cam1;
      const SE3S T_i_ct = cam == 0 ? SE3S() : T_c0_c1_;
      Mat<Scalar, 6, 6> D_rel_h, D_rel_t;
      SE3S T_ct_h, T_ct_h_jac;
      if (in_host) {
        T_ct_h = T_i_ct.inverse();
        T_ct_h_jac = T_ct_h;
      } else {
        const Frame& target = frames_.at(frame_id);
        T_ct_h_jac = relativePose<Scalar>(T_w_h_jac, SE3S(), jacobianPoseOf(frame_id), T_i_ct,
                                          &D_rel_h, &D_rel_t);
        // The residual needs its own relative pose only when a first estimate differs from the
        // current one.
        T_ct_h = host_linearized || target.linearized
                     ? relativePose<Scalar>(T_w_h, SE3S(), target.T_w_c, T_i_ct)
                     : T_ct_h_jac;
      }
      Mat<Scalar, 3, 3> D_q_l;
      Mat<Scalar, 3, 6> D_q_T;
      const Vec3S q_jac = transformLandmark<Scalar>(T_ct_h_jac, lm.param, &D_q_l, &D_q_T);
      Vec2S uv_jac, uv;
      Mat<Scalar, 2, 3> D_uv_q;
      if (!camera.project(q_jac, &uv_jac, &D_uv_q)) continue;
      if (!camera.project(transformLandmark<Scalar>(T_ct_h, lm.param), &uv)) continue;
      Row2 row;
      row.r = uv - (cam == 0 ? obs.uv0 : obs.uv1);
      const Scalar e = row.r.norm();
      out->cost += huberCost<Scalar>(e, k, sigma);
      // IRLS weight of the Huber norm, applied as √w/σ to both rows.
      const Scalar scale = std::sqrt(e <= k ? Scalar(1) : k / e) / sigma;
      row.r *= scale;
      row.J_l = scale * D_uv_q * D_q_l;
      row.target = in_host ? -1 : frame_id;
      if (!in_host) {
        const Mat<Scalar, 2, 6> D_r_T = scale * D_uv_q * D_q_T;
        row.J_h = D_r_T * D_rel_h;
        row.J_t = D_r_T * D_rel_t;
      }
      rows.push_back(row);
    }
  }
  const int m = 2 * static_cast<int>(rows.size());
  if (m < 3) return false;
  std::set<int64_t> frames;
  for (const Row2& row : rows) {
    if (row.target >= 0) {
      frames.insert(row.target);
      frames.insert(lm.host);
    }
  }
  out->track_id = track_id;
  out->frames.assign(frames.begin(), frames.end());
  std::map<int64_t, int> local;
  for (size_t j = 0; j < out->frames.size(); ++j) local[out->frames[j]] = kPoseDim * j;
  out->J_p.setZero(m, kPoseDim * out->frames.size());
  out->J_l.resize(m, 3);
  out->r.resize(m);
  for (size_t i = 0; i < rows.size(); ++i) {
    out->J_l.template middleRows<2>(2 * i) = rows[i].J_l;
    out->r.template segment<2>(2 * i) = rows[i].r;
    if (rows[i].target >= 0) {
      out->J_p.template block<2, kPoseDim>(2 * i, local[lm.host]) += rows[i].J_h;
      out->J_p.template block<2, kPoseDim>(2 * i, local[rows[i].target]) += rows[i].J_t;
    }
  }
  return true;
}

template <typename Scalar>
PoseBlockMap VoEstimator<Scalar>::blockMap(const Linearized& lin,
                                           const std::map<int64_t, int>& column_of) const {
  PoseBlockMap map;
  map.pose_dim = kPoseDim;
  for (int64_t f : lin.frames) map.rcs_offset.push_back(column_of.at(f));
  return map;
}

template <typename Scalar>
std::vector<int64_t> VoEstimator<Scalar>::keyframeIds() const {
  std::vector<int64_t> ids;
  for (const auto& [id, frame] : frames_) {
    if (frame.is_keyframe) ids.push_back(id);
  }
  return ids;
}

template <typename Scalar>
Status VoEstimator<Scalar>::computeStep(OptElimination elimination, Scalar lambda,
                                        VecX<Scalar>* delta_poses) const {
  std::set<int64_t> system;
  std::map<int64_t, int> column_of;
  for (const auto& [id, frame] : frames_) {
    column_of[id] = kPoseDim * static_cast<int>(system.size());
    system.insert(id);
  }
  const int n = kPoseDim * static_cast<int>(system.size());
  MatX<Scalar> H = MatX<Scalar>::Zero(n, n);
  VecX<Scalar> b = VecX<Scalar>::Zero(n);
  const Scalar lambda_min = static_cast<Scalar>(config_.lambda_min);
  for (const auto& [id, lm] : landmarks_) {
    Linearized lin;
    if (!linearizeLandmark(id, lm, system, &lin)) continue;
    Vec3<Scalar> d;
    if (elimination == OptElimination::kNullspace) {
      LandmarkBlockNs<Scalar> block;
      Status s = block.setFromJacobians(lin.J_p, lin.J_l, lin.r, blockMap(lin, column_of));
      if (!s.ok()) return s;
      for (int i = 0; i < 3; ++i)
        d[i] = lmDamping(block.landmarkHessianDiagonal()[i], lambda, lambda_min);
      block.setLandmarkDamping(d);
      block.addToReducedSystem(H, b);
    } else {
      LandmarkBlockSc<Scalar> block;
      Status s = block.setFromJacobians(lin.J_p, lin.J_l, lin.r, blockMap(lin, column_of));
      if (!s.ok()) return s;
      for (int i = 0; i < 3; ++i)
        d[i] = lmDamping(block.landmarkHessianDiagonal()[i], lambda, lambda_min);
      block.setLandmarkDamping(d);
      s = block.addToReducedSystem(H, b);
      if (!s.ok()) return s;
    }
  }
  if (!prior_.empty()) {
    addPrior(prior_, prior_.delta([this](int64_t f) { return poseOf(f); }), column_of, H, b);
  }
  const DampedSolve<Scalar> solve = solveDampedLdlt<Scalar>(H, b, lambda, lambda_min);
  *delta_poses = solve.delta;
  return solve.status;
}

template <typename Scalar>
Status VoEstimator<Scalar>::optimize(FrameResult* result) {
  std::set<int64_t> system;
  std::map<int64_t, int> column_of;
  for (const auto& [id, frame] : frames_) {
    column_of[id] = kPoseDim * static_cast<int>(system.size());
    system.insert(id);
  }
  const int n = kPoseDim * static_cast<int>(system.size());
  const Scalar lambda_min = static_cast<Scalar>(config_.lambda_min);
  const Scalar lambda_max = static_cast<Scalar>(config_.lambda_max);
  auto pose_of = [this](int64_t f) { return poseOf(f); };

  // λ restarts at its initial value for every frame (as Basalt's optimize does).
  lambda_ = static_cast<Scalar>(config_.lambda_init);
  nu_ = Scalar(2);
  Scalar cost = totalCost();
  result->cost_initial = static_cast<double>(cost);
  if (!std::isfinite(cost)) {
    return Status::Error(Status::Code::kNotFinite, "the cost of the window is not finite");
  }
  for (int it = 0; it < config_.lm_max_iterations; ++it) {
    std::vector<Linearized> lins;
    for (const auto& [id, lm] : landmarks_) {
      Linearized lin;
      if (linearizeLandmark(id, lm, system, &lin)) lins.push_back(std::move(lin));
    }
    ReducedSystem<Scalar> rs;
    rs.H_prior = MatX<Scalar>::Zero(n, n);
    rs.b_prior = VecX<Scalar>::Zero(n);
    VecX<Scalar> prior_delta;
    if (!prior_.empty()) {
      prior_delta = prior_.delta(pose_of);
      addPrior(prior_, prior_delta, column_of, rs.H_prior, rs.b_prior);
    }
    for (const Linearized& lin : lins) {
      if (variant_.opt == OptElimination::kNullspace) {
        rs.ns.emplace_back();
        Status s = rs.ns.back().setFromJacobians(lin.J_p, lin.J_l, lin.r, blockMap(lin, column_of));
        if (!s.ok()) return s;
      } else {
        rs.sc.emplace_back();
        Status s = rs.sc.back().setFromJacobians(lin.J_p, lin.J_l, lin.r, blockMap(lin, column_of));
        if (!s.ok()) return s;
      }
    }

    bool stop = false;
    while (true) {
      // Assemble the damped reduced camera system for the current λ.
      rs.H = rs.H_prior;
      rs.b = rs.b_prior;
      Status status = Status::Ok();
      for (size_t l = 0; l < lins.size(); ++l) {
        Vec3<Scalar> d;
        if (variant_.opt == OptElimination::kNullspace) {
          for (int i = 0; i < 3; ++i) {
            d[i] = lmDamping(rs.ns[l].landmarkHessianDiagonal()[i], lambda_, lambda_min);
          }
          rs.ns[l].setLandmarkDamping(d);
          rs.ns[l].addToReducedSystem(rs.H, rs.b);
        } else {
          for (int i = 0; i < 3; ++i) {
            d[i] = lmDamping(rs.sc[l].landmarkHessianDiagonal()[i], lambda_, lambda_min);
          }
          rs.sc[l].setLandmarkDamping(d);
          if (status.ok()) status = rs.sc[l].addToReducedSystem(rs.H, rs.b);
        }
      }
      DampedSolve<Scalar> solve;
      if (status.ok()) {
        solve = solveDampedLdlt<Scalar>(rs.H, rs.b, lambda_, lambda_min);
        status = solve.status;
      }
      std::vector<Vec3<Scalar>> delta_l(lins.size());
      for (size_t l = 0; l < lins.size() && status.ok(); ++l) {
        status = variant_.opt == OptElimination::kNullspace
                     ? rs.ns[l].backSubstitute(solve.delta, &delta_l[l])
                     : rs.sc[l].backSubstitute(solve.delta, &delta_l[l]);
      }
      if (!status.ok()) {
        if (++failed_solves_ >= config_.max_failed_solves) {
          return Status::Error(status.code(),
                               fmt::format("linear solve failed {} times in a row: {}",
                                           failed_solves_, status.message()));
        }
        lambda_ = std::min(lambda_ * nu_, lambda_max);
        nu_ *= Scalar(2);
        continue;
      }
      failed_solves_ = 0;

      // Model decrease of the undamped linearized energy.
      Scalar model_change = 0;
      for (size_t l = 0; l < lins.size(); ++l) {
        model_change += variant_.opt == OptElimination::kNullspace
                            ? rs.ns[l].linearizedCostChange(solve.delta, delta_l[l])
                            : rs.sc[l].linearizedCostChange(solve.delta, delta_l[l]);
      }
      if (!prior_.empty()) {
        VecX<Scalar> step(prior_.cols());
        for (size_t i = 0; i < prior_.frame_ids.size(); ++i) {
          step.template segment<kPoseDim>(kPoseDim * i) =
              solve.delta.template segment<kPoseDim>(column_of.at(prior_.frame_ids[i]));
        }
        model_change += prior_.costChange(prior_delta, step);
      }

      // Apply the step on a backup.
      std::map<int64_t, SE3S> pose_backup;
      for (auto& [id, frame] : frames_) {
        pose_backup[id] = frame.T_w_c;
        frame.T_w_c =
            boxPlus<Scalar>(frame.T_w_c, solve.delta.template segment<kPoseDim>(column_of.at(id)));
      }
      std::vector<Vec3S> param_backup(lins.size());
      Scalar max_step = solve.delta.size() ? solve.delta.cwiseAbs().maxCoeff() : Scalar(0);
      for (size_t l = 0; l < lins.size(); ++l) {
        Landmark& lm = landmarks_.at(lins[l].track_id);
        param_backup[l] = lm.param;
        lm.param += delta_l[l];
        lm.param.z() = std::max(lm.param.z(), Scalar(0));
        max_step = std::max(max_step, delta_l[l].cwiseAbs().maxCoeff());
      }
      const Scalar new_cost = totalCost();
      if (std::isfinite(new_cost) && new_cost < cost) {
        const Scalar rho = model_change < 0 ? (cost - new_cost) / -model_change : Scalar(1);
        const Scalar f = Scalar(2) * rho - Scalar(1);
        lambda_ *= std::max(Scalar(1) / Scalar(3), Scalar(1) - f * f * f);
        lambda_ = std::clamp(lambda_, lambda_min, lambda_max);
        nu_ = Scalar(2);
        const Scalar relative_decrease = (cost - new_cost) / cost;
        cost = new_cost;
        stop = relative_decrease < static_cast<Scalar>(config_.stop_relative_cost) ||
               max_step < static_cast<Scalar>(config_.stop_max_step);
        break;
      }
      for (auto& [id, frame] : frames_) frame.T_w_c = pose_backup[id];
      for (size_t l = 0; l < lins.size(); ++l)
        landmarks_.at(lins[l].track_id).param = param_backup[l];
      if (lambda_ >= lambda_max) {
        stop = true;  // no decrease even with maximal damping: converged as far as LM can tell
        break;
      }
      lambda_ = std::min(lambda_ * nu_, lambda_max);
      nu_ *= Scalar(2);
    }
    ++result->lm_iterations;
    if (stop) break;
  }
  result->cost_final = static_cast<double>(cost);
  for (const auto& [id, frame] : frames_) {
    if (!frame.T_w_c.translation().allFinite() ||
        !frame.T_w_c.unitQuaternion().coeffs().allFinite()) {
      return Status::Error(Status::Code::kNotFinite, "a pose turned non-finite");
    }
  }
  return Status::Ok();
}

template <typename Scalar>
void VoEstimator<Scalar>::addNewLandmarks(int64_t frame_id, const TrackFrame& frame) {
  TriangulationOptions<Scalar> options;
  options.min_baseline = static_cast<Scalar>(config_.min_baseline_m);
  for (const StereoObservation& obs : frame.observations) {
    if (!obs.has_right || landmarks_.count(obs.track_id) != 0) continue;
    const Vec2S uv0 = obs.uv0.template cast<Scalar>();
    const Vec2S uv1 = obs.uv1.template cast<Scalar>();
    Vec3S p_c0;
    if (!rig_.triangulate(uv0, uv1, &p_c0, options)) continue;
    Landmark lm;
    lm.host = frame_id;
    lm.param = landmarkFromPoint<Scalar>(p_c0);
    lm.obs[frame_id] = Observation{uv0, true, uv1};
    landmarks_.emplace(obs.track_id, std::move(lm));
  }
}

template <typename Scalar>
std::optional<int64_t> VoEstimator<Scalar>::selectKeyframeToMarginalize(int64_t current) const {
  std::vector<int64_t> kfs;
  for (const auto& [id, frame] : frames_) {
    if (frame.is_keyframe) kfs.push_back(id);
  }
  if (static_cast<int>(kfs.size()) <= config_.max_kfs) return std::nullopt;
  const std::vector<int64_t> candidates(kfs.begin(), kfs.end() - 2);
  for (int64_t c : candidates) {
    int hosted = 0, connected = 0;
    for (const auto& [id, lm] : landmarks_) {
      if (lm.host != c) continue;
      ++hosted;
      connected += lm.obs.count(current) != 0 ? 1 : 0;
    }
    if (hosted == 0 || connected < config_.marg_connected_share * hosted) return c;
  }
  // DSO's distance score: prefer frames far from the newest keyframe but close to the others.
  const Vec3S t_last = frames_.at(kfs.back()).T_w_c.translation();
  int64_t best = candidates.front();
  Scalar best_score = -1;
  for (int64_t c : candidates) {
    const Vec3S t_c = frames_.at(c).T_w_c.translation();
    Scalar sum = 0;
    for (int64_t j : kfs) {
      if (j != c)
        sum += Scalar(1) / ((t_c - frames_.at(j).T_w_c.translation()).norm() + Scalar(1e-5));
    }
    const Scalar score = std::sqrt((t_c - t_last).norm()) * sum;
    if (score > best_score) {
      best_score = score;
      best = c;
    }
  }
  return best;
}

template <typename Scalar>
Status VoEstimator<Scalar>::marginalizeInto(MargPrior<Scalar>& prior, MargMethod method,
                                            PriorStorage storage,
                                            const std::set<int64_t>& marg_frames,
                                            const std::vector<int64_t>& marg_landmarks,
                                            int* qr_rank) const {
  std::set<int64_t> all_frames;
  for (const auto& [id, frame] : frames_) all_frames.insert(id);
  std::vector<Linearized> lins;
  std::set<int64_t> keep;
  for (int64_t id : marg_landmarks) {
    Linearized lin;
    if (!linearizeLandmark(id, landmarks_.at(id), all_frames, &lin)) continue;
    // Rows beyond the three the landmark consumes carry pose information.
    if (lin.r.size() <= 3 || lin.frames.empty()) continue;
    keep.insert(lin.frames.begin(), lin.frames.end());
    lins.push_back(std::move(lin));
  }
  keep.insert(prior.frame_ids.begin(), prior.frame_ids.end());
  for (int64_t f : marg_frames) keep.erase(f);

  std::map<int64_t, int> column_of;
  int col = 0;
  for (int64_t f : marg_frames) {
    column_of[f] = col;
    col += kPoseDim;
  }
  const int n_marg = col;
  for (int64_t f : keep) {
    column_of[f] = col;
    col += kPoseDim;
  }
  const int n = col;
  const VecX<Scalar> old_delta = prior.delta([this](int64_t f) { return poseOf(f); });

  MargPrior<Scalar> next;
  next.storage = storage;
  next.frame_ids.assign(keep.begin(), keep.end());
  VecX<Scalar> new_delta(kPoseDim * next.frame_ids.size());
  for (size_t i = 0; i < next.frame_ids.size(); ++i) {
    next.x0.push_back(jacobianPoseOf(next.frame_ids[i]));
    new_delta.template segment<kPoseDim>(kPoseDim * i) =
        boxMinus(poseOf(next.frame_ids[i]), next.x0.back());
  }

  if (method == MargMethod::kQr) {
    int rows = prior.empty() ? 0 : prior.rows();
    std::vector<LandmarkBlockNs<Scalar>> blocks(lins.size());
    for (size_t l = 0; l < lins.size(); ++l) {
      Status s = blocks[l].setFromJacobians(lins[l].J_p, lins[l].J_l, lins[l].r,
                                            blockMap(lins[l], column_of));
      if (!s.ok()) return s;
      rows += blocks[l].numReducedRows();
    }
    MatX<Scalar> A = MatX<Scalar>::Zero(rows, n + 1);
    int row = 0;
    for (const auto& block : blocks) {
      block.copyReducedRows(A, row);
      row += block.numReducedRows();
    }
    if (!prior.empty()) {
      MatX<Scalar> J;
      VecX<Scalar> r;
      prior.sqrtRows(old_delta, &J, &r);
      for (size_t i = 0; i < prior.frame_ids.size(); ++i) {
        A.block(row, column_of.at(prior.frame_ids[i]), J.rows(), kPoseDim) =
            J.middleCols(kPoseDim * i, kPoseDim);
      }
      A.col(n).segment(row, r.size()) = r;
    }
    FlatQrOptions<Scalar> options;
    options.mode = config_.qr_threshold_mode;
    if (config_.qr_threshold >= 0) options.threshold = static_cast<Scalar>(config_.qr_threshold);
    FlatQrMarginalization<Scalar> qr = flatQrMarginalize<Scalar>(std::move(A), n_marg, options);
    if (!qr.status.ok()) return qr.status;
    if (qr_rank != nullptr) *qr_rank = qr.total_rank;
    next.sqrt.J = std::move(qr.prior.J);
    next.sqrt.r = qr.prior.r - next.sqrt.J * new_delta;
  } else {
    MatX<Scalar> H = MatX<Scalar>::Zero(n, n);
    VecX<Scalar> b = VecX<Scalar>::Zero(n);
    for (const Linearized& lin : lins) {
      LandmarkBlockSc<Scalar> block;
      Status s = block.setFromJacobians(lin.J_p, lin.J_l, lin.r, blockMap(lin, column_of));
      if (!s.ok()) return s;
      // A landmark whose H_ll is singular carries no usable pose information: skip it.
      block.addToReducedSystem(H, b);
    }
    if (!prior.empty()) addPrior(prior, old_delta, column_of, H, b);
    SchurMarginalization<Scalar> sc = schurMarginalize<Scalar>(H, b, n_marg);
    if (!sc.status.ok()) return sc.status;
    const VecX<Scalar> b_m = sc.prior.b - sc.prior.H * new_delta;
    if (storage == PriorStorage::kHessian) {
      next.hessian.H = std::move(sc.prior.H);
      next.hessian.b = b_m;
    } else {
      LdltSqrt<Scalar> ldlt = hessianToSqrtLdlt<Scalar>(sc.prior.H, b_m);
      if (!ldlt.status.ok()) return ldlt.status;
      next.sqrt = std::move(ldlt.prior);
    }
  }
  prior = std::move(next);
  return Status::Ok();
}

template <typename Scalar>
Status VoEstimator<Scalar>::trialMarginalization(int64_t frame_id, MargMethod method,
                                                 MatXd* H_m) const {
  std::vector<int64_t> hosted;
  for (const auto& [id, lm] : landmarks_) {
    if (lm.host == frame_id) hosted.push_back(id);
  }
  MargPrior<Scalar> prior = prior_;
  Status s = marginalizeInto(prior, method, PriorStorage::kSqrt, {frame_id}, hosted, nullptr);
  if (!s.ok()) return s;
  const MatXd J = prior.sqrt.J.template cast<double>();
  *H_m = J.transpose() * J;
  return Status::Ok();
}

template <typename Scalar>
Status VoEstimator<Scalar>::marginalize(int64_t current, FrameResult* result) {
  const bool current_is_kf = frames_.at(current).is_keyframe;
  std::set<int64_t> marg_frames;
  std::set<int64_t> marg_landmarks;
  for (const auto& [id, lm] : landmarks_) {
    if (lm.obs.count(current) == 0) marg_landmarks.insert(id);  // track lost
  }
  if (!current_is_kf) {
    for (auto& [id, lm] : landmarks_) lm.obs.erase(current);
  }
  if (const auto kf = selectKeyframeToMarginalize(current)) {
    marg_frames.insert(*kf);
    for (auto& [id, lm] : landmarks_) {
      if (lm.host == *kf) {
        marg_landmarks.insert(id);
      } else if (marg_landmarks.count(id) == 0) {
        lm.obs.erase(*kf);  // keeps the prior sparse (paper §3.2.2)
      }
    }
  }
  if (!marg_frames.empty() || !marg_landmarks.empty()) {
    const std::vector<int64_t> landmarks(marg_landmarks.begin(), marg_landmarks.end());
    const auto t0 = Clock::now();
    int qr_rank = -1;
    Status status =
        marginalizeInto(prior_, variant_.marg, variant_.storage, marg_frames, landmarks, &qr_rank);
    result->t_marg_s = secondsSince(t0);
    if (!status.ok()) return status;
    for (int64_t f : prior_.frame_ids) {
      Frame& frame = frames_.at(f);
      if (!frame.linearized) {
        frame.linearized = true;
        frame.T_w_c_lin = frame.T_w_c;
      }
    }
    if (config_.diagnostics) {
      const auto t1 = Clock::now();
      MargEvent event;
      status = marginalizeInto(shadow_prior_, variant_.marg, variant_.storage, marg_frames,
                               landmarks, &event.qr_rank);
      if (!status.ok()) return status;
      event.frame_ids = shadow_prior_.frame_ids;
      // Gauge directions at the linearization points: the prior's nullspace lies there (FEJ).
      for (const SE3S& T : shadow_prior_.x0) event.T_w_c.push_back(T.template cast<double>());
      const VecX<Scalar> delta = shadow_prior_.delta([this](int64_t f) { return poseOf(f); });
      if (shadow_prior_.storage == PriorStorage::kSqrt) {
        event.J_m = shadow_prior_.sqrt.J.template cast<double>();
        event.r_m = (shadow_prior_.sqrt.r + shadow_prior_.sqrt.J * delta).template cast<double>();
        event.H_m = event.J_m.transpose() * event.J_m;
        event.b_m = event.J_m.transpose() * event.r_m;
      } else {
        event.H_m = shadow_prior_.hessian.H.template cast<double>();
        event.b_m =
            (shadow_prior_.hessian.b + shadow_prior_.hessian.H * delta).template cast<double>();
      }
      event.prior_rows = shadow_prior_.rows();
      event.n_marg_frames = static_cast<int>(marg_frames.size());
      event.n_marg_landmarks = static_cast<int>(landmarks.size());
      event.t_shadow_s = secondsSince(t1);
      result->marg_event = std::move(event);
    }
    for (int64_t id : marg_landmarks) landmarks_.erase(id);
    for (int64_t f : marg_frames) frames_.erase(f);
  }
  if (!current_is_kf) frames_.erase(current);
  return Status::Ok();
}

template <typename Scalar>
FrameResult VoEstimator<Scalar>::processFrame(const TrackFrame& track_frame) {
  FrameResult result;
  result.t_ns = track_frame.t_ns;
  const int64_t id = next_frame_index_++;
  SE3<double> T_init = last_pose_;
  if (has_previous_pose_) {
    // Constant-velocity prediction: T_k = (T_{k−1} T_{k−2}⁻¹) T_{k−1}.
    T_init = (last_pose_ * previous_pose_.inverse()) * last_pose_;
  }
  Frame frame;
  frame.t_ns = track_frame.t_ns;
  frame.T_w_c = T_init.template cast<Scalar>();
  frame.T_w_c_lin = frame.T_w_c;
  frames_[id] = frame;

  int connected = 0;
  for (const StereoObservation& obs : track_frame.observations) {
    auto it = landmarks_.find(obs.track_id);
    if (it == landmarks_.end()) continue;
    ++connected;
    it->second.obs[id] = Observation{obs.uv0.template cast<Scalar>(), obs.has_right,
                                     obs.uv1.template cast<Scalar>()};
  }
  if (id == 0) {
    Frame& first = frames_.at(id);
    first.is_keyframe = true;
    first.linearized = true;
    last_keyframe_ = id;
    // Gauge prior on all 6 dof of the first pose (the shadow prior has none).
    const Scalar w = static_cast<Scalar>(config_.gauge_prior_weight);
    prior_.frame_ids = {id};
    prior_.x0 = {first.T_w_c};
    prior_.sqrt.J = std::sqrt(w) * MatX<Scalar>::Identity(kPoseDim, kPoseDim);
    prior_.sqrt.r = VecX<Scalar>::Zero(kPoseDim);
    prior_.hessian.H = w * MatX<Scalar>::Identity(kPoseDim, kPoseDim);
    prior_.hessian.b = VecX<Scalar>::Zero(kPoseDim);
    addNewLandmarks(id, track_frame);
  }

  const auto t0 = Clock::now();
  result.status = optimize(&result);
  result.t_opt_s = secondsSince(t0);
  result.T_w_c = frames_.at(id).T_w_c.template cast<double>();
  if (!result.status.ok()) return result;

  const double observed = static_cast<double>(track_frame.observations.size());
  if (id > 0 && (observed == 0 || connected < config_.kf_connected_ratio * observed) &&
      id - last_keyframe_ >= config_.min_frames_after_kf) {
    frames_.at(id).is_keyframe = true;
    last_keyframe_ = id;
    addNewLandmarks(id, track_frame);
  }
  result.is_keyframe = frames_.at(id).is_keyframe;
  result.n_landmarks = numLandmarks();
  for (const auto& [lid, lm] : landmarks_) {
    for (const auto& [f, obs] : lm.obs) result.n_observations += obs.has_right ? 2 : 1;
  }
  result.status = marginalize(id, &result);

  previous_pose_ = last_pose_;
  last_pose_ = result.T_w_c;
  has_previous_pose_ = id > 0;
  return result;
}

#define MARGLAB_INST(S) template class VoEstimator<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
