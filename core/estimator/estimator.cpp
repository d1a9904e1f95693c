#include "core/estimator/estimator.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/common/error.h"
#include "core/common/scalar.h"
#include "core/geometry/stereographic.h"
#include "core/imu/preintegration.h"
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
  MatX<Scalar> H_fixed;  // IMU terms and prior: independent of the landmark damping
  VecX<Scalar> b_fixed;
  MatX<Scalar> H;
  VecX<Scalar> b;
};

// Adds H_blocks / b_blocks, laid out as `vars` at `offsets`, to a system with columns column_of.
template <typename Scalar>
void scatterBlocks(const std::vector<std::pair<VarKey, int>>& vars, const MatX<Scalar>& H_blocks,
                   const VecX<Scalar>& b_blocks, const std::map<VarKey, int>& column_of,
                   MatX<Scalar>& H, VecX<Scalar>& b) {
  for (const auto& [var_i, off_i] : vars) {
    const int ci = column_of.at(var_i);
    const int ni = stateBlockDim(var_i.block);
    b.segment(ci, ni) += b_blocks.segment(off_i, ni);
    for (const auto& [var_j, off_j] : vars) {
      const int nj = stateBlockDim(var_j.block);
      H.block(ci, column_of.at(var_j), ni, nj) += H_blocks.block(off_i, off_j, ni, nj);
    }
  }
}

template <typename Scalar>
std::vector<std::pair<VarKey, int>> priorVars(const MargPrior<Scalar>& prior) {
  std::vector<std::pair<VarKey, int>> vars;
  for (const auto& block : prior.blocks) vars.emplace_back(block.var, block.offset);
  return vars;
}

// The four blocks of an IMU factor's 30 columns.
std::vector<std::pair<VarKey, int>> linkVars(int64_t from, int64_t to) {
  return {{{from, StateBlock::kPose}, 0},
          {{from, StateBlock::kSpeedBias}, kPoseDim},
          {{to, StateBlock::kPose}, 15},
          {{to, StateBlock::kSpeedBias}, 15 + kPoseDim}};
}

// Adds the prior's Hessian and gradient at δ to a system with columns column_of.
template <typename Scalar>
void addPrior(const MargPrior<Scalar>& prior, const VecX<Scalar>& delta,
              const std::map<VarKey, int>& column_of, MatX<Scalar>& H, VecX<Scalar>& b) {
  MatX<Scalar> Hp;
  VecX<Scalar> bp;
  prior.linearize(delta, &Hp, &bp);
  scatterBlocks(priorVars(prior), Hp, bp, column_of, H, b);
}

// Gathers the entries of a system vector for a layout of blocks.
template <typename Scalar>
VecX<Scalar> gatherBlocks(const std::vector<std::pair<VarKey, int>>& vars, int size,
                          const VecX<Scalar>& x, const std::map<VarKey, int>& column_of) {
  VecX<Scalar> out(size);
  for (const auto& [var, offset] : vars) {
    const int n = stateBlockDim(var.block);
    out.segment(offset, n) = x.segment(column_of.at(var), n);
  }
  return out;
}

// Adds JᵀJ, Jᵀr of a RowBlock (estimator.h) to a system with columns column_of.
template <typename Scalar, typename Rows>
void addRowBlock(const Rows& rows, const std::map<VarKey, int>& column_of, MatX<Scalar>& H,
                 VecX<Scalar>& b) {
  const MatX<Scalar> H_rows = rows.J.transpose() * rows.J;
  const VecX<Scalar> b_rows = rows.J.transpose() * rows.r;
  scatterBlocks(rows.vars, H_rows, b_rows, column_of, H, b);
}

// Change of ½‖r + J δ‖² along a step of the whole system.
template <typename Scalar, typename Rows>
Scalar rowBlockModelChange(const Rows& rows, const VecX<Scalar>& step,
                           const std::map<VarKey, int>& column_of) {
  const VecX<Scalar> J_step =
      rows.J * gatherBlocks<Scalar>(rows.vars, static_cast<int>(rows.J.cols()), step, column_of);
  return rows.r.dot(J_step) + Scalar(0.5) * J_step.squaredNorm();
}

// Huber cost of a reprojection error e (pixels), divided by σ²: ½e² inside, k·e − ½k² outside.
template <typename Scalar>
Scalar huberCost(Scalar e, Scalar k, Scalar sigma) {
  const Scalar c = e <= k ? Scalar(0.5) * e * e : k * e - Scalar(0.5) * k * k;
  return c / (sigma * sigma);
}

}  // namespace

int MargEvent::numPoses() const {
  return static_cast<int>(std::count_if(layout.begin(), layout.end(), [](const PriorVariable& v) {
    return v.kind == PriorVariableKind::kPose;
  }));
}

template <typename Scalar>
SlidingWindowEstimator<Scalar>::SlidingWindowEstimator(const EstimatorConfig& config,
                                                       const Variant& variant,
                                                       const StereoRig<double>& rig,
                                                       const SE3<double>& T_w_i_initial,
                                                       std::optional<ImuSetup> imu)
    : config_(config),
      variant_(variant),
      rig_input_(rig),
      rig_(rig.template cast<Scalar>()),
      imu_(std::move(imu)),
      last_pose_(imu_ ? imu_->initial.T_w_i : T_w_i_initial),
      lambda_(static_cast<Scalar>(config.lambda_init)),
      pool_(std::make_shared<ThreadPool>(std::max(config.lm_threads, 1))) {
  if (imu_) {
    T_i_c_ = {rig.T_i_c0.template cast<Scalar>(), rig.T_i_c1.template cast<Scalar>()};
    g_w_ = imu_->g_w.template cast<Scalar>();
  } else {
    T_i_c_ = {SE3S(), rig.T_c0_c1().template cast<Scalar>()};
  }
  for (int cam = 0; cam < 2; ++cam) {
    T_c_i_[cam] = T_i_c_[cam].inverse();
    T_c_h_host_[cam] = T_c_i_[cam] * T_i_c_[0];
  }
  prior_.storage = variant.storage;
  shadow_prior_.storage = variant.storage;
  if (config_.min_frames_after_kf < 1) config_.min_frames_after_kf = 1;
  if (config_.max_states < 2) config_.max_states = 2;
}

template <typename Scalar>
int SlidingWindowEstimator<Scalar>::numKeyframes() const {
  return static_cast<int>(std::count_if(frames_.begin(), frames_.end(),
                                        [](const auto& f) { return f.second.is_keyframe; }));
}

template <typename Scalar>
typename SlidingWindowEstimator<Scalar>::SE3S SlidingWindowEstimator<Scalar>::jacobianPoseOf(
    int64_t frame_id) const {
  const Frame& frame = frames_.at(frame_id);
  return frame.linearized ? frame.T_w_i_lin : frame.T_w_i;
}

template <typename Scalar>
ImuState<Scalar> SlidingWindowEstimator<Scalar>::stateOf(int64_t frame_id,
                                                         bool at_linearization_point) const {
  const Frame& frame = frames_.at(frame_id);
  ImuState<Scalar> s;
  s.t_ns = frame.t_ns;
  s.T_w_i = at_linearization_point ? jacobianPoseOf(frame_id) : frame.T_w_i;
  const Vec9S& sb = at_linearization_point && frame.speed_bias_linearized ? frame.speed_bias_lin
                                                                          : frame.speed_bias;
  s.v_w = sb.template head<3>();
  s.b_g = sb.template segment<3>(3);
  s.b_a = sb.template tail<3>();
  return s;
}

template <typename Scalar>
size_t SlidingWindowEstimator<Scalar>::RelativePoses::index(int64_t host, int64_t target,
                                                            int cam) const {
  const size_t n = ids.size();
  const size_t h = std::lower_bound(ids.begin(), ids.end(), host) - ids.begin();
  const size_t t = std::lower_bound(ids.begin(), ids.end(), target) - ids.begin();
  return (h * n + t) * 2 + static_cast<size_t>(cam);
}

template <typename Scalar>
typename SlidingWindowEstimator<Scalar>::RelativePoses
SlidingWindowEstimator<Scalar>::relativePoses(bool with_jacobians) const {
  RelativePoses rel;
  for (const auto& [id, frame] : frames_) rel.ids.push_back(id);
  const size_t size = rel.ids.size() * rel.ids.size() * 2;
  rel.T_ct_h.resize(size);
  if (with_jacobians) {
    rel.T_ct_h_jac.resize(size);
    rel.D_rel_h.resize(size);
    rel.D_rel_t.resize(size);
  }
  for (const auto& [h, host] : frames_) {
    for (const auto& [t, target] : frames_) {
      for (int cam = 0; cam < 2; ++cam) {
        const size_t k = rel.index(h, t, cam);
        if (h == t) {
          rel.T_ct_h[k] = T_c_h_host_[cam];
          if (with_jacobians) rel.T_ct_h_jac[k] = T_c_h_host_[cam];
          continue;
        }
        if (!with_jacobians) {
          rel.T_ct_h[k] = relativePose<Scalar>(host.T_w_i, T_i_c_[0], target.T_w_i, T_i_c_[cam]);
          continue;
        }
        rel.T_ct_h_jac[k] = relativePose<Scalar>(jacobianPoseOf(h), T_i_c_[0], jacobianPoseOf(t),
                                                 T_i_c_[cam], &rel.D_rel_h[k], &rel.D_rel_t[k]);
        // The residual needs its own relative pose only when a first estimate differs from the
        // current one.
        rel.T_ct_h[k] = host.linearized || target.linearized
                            ? relativePose<Scalar>(host.T_w_i, T_i_c_[0], target.T_w_i, T_i_c_[cam])
                            : rel.T_ct_h_jac[k];
      }
    }
  }
  return rel;
}

template <typename Scalar>
Scalar SlidingWindowEstimator<Scalar>::landmarkCost(const Landmark& lm,
                                                    const RelativePoses& rel) const {
  const Scalar k = static_cast<Scalar>(config_.huber_px);
  const Scalar sigma = static_cast<Scalar>(config_.obs_std_px);
  Scalar cost = 0;
  for (const auto& [frame_id, obs] : lm.obs) {
    const Vec3S p_i = lm.world() ? poseOf(frame_id).inverse() * lm.param : Vec3S::Zero();
    for (int cam = 0; cam < (obs.has_right ? 2 : 1); ++cam) {
      const Vec3S q = lm.world() ? T_c_i_[cam] * p_i
                                 : transformLandmark<Scalar>(
                                       rel.T_ct_h[rel.index(lm.host, frame_id, cam)], lm.param);
      Vec2S uv;
      if (!(cam == 0 ? rig_.cam0 : rig_.cam1).project(q, &uv)) continue;
      cost += huberCost<Scalar>((uv - (cam == 0 ? obs.uv0 : obs.uv1)).norm(), k, sigma);
    }
  }
  for (const NfrFactor& f : lm.nfr) cost += nfrCost(f, &lm);
  return cost;
}

template <typename Scalar>
Blanket<Scalar> SlidingWindowEstimator<Scalar>::nfrBlanket(const NfrFactor& f, const Landmark* lm,
                                                           bool at_first_estimates) const {
  Blanket<Scalar> x(1);
  x[0].kind = f.kind;
  if (f.kind == BlanketKind::kPose) {
    x[0].T_w_i = at_first_estimates ? jacobianPoseOf(f.frame) : poseOf(f.frame);
  } else {
    const Frame& frame = frames_.at(f.frame);
    const Vec9S sb =
        at_first_estimates && frame.speed_bias_linearized ? frame.speed_bias_lin : frame.speed_bias;
    x[0].value = f.kind == BlanketKind::kVelocity ? VecX<Scalar>(sb.template head<3>())
                                                  : VecX<Scalar>(sb.template tail<6>());
  }
  if (lm != nullptr) {
    x.push_back({BlanketKind::kLandmark, kPoseDim, SE3S(),
                 at_first_estimates ? jacobianPointOf(*lm) : lm->param});
  }
  return x;
}

template <typename Scalar>
Scalar SlidingWindowEstimator<Scalar>::nfrCost(const NfrFactor& f, const Landmark* lm) const {
  return Scalar(0.5) * f.factor.whitenedResidual(nfrBlanket(f, lm, false)).squaredNorm();
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::linearizeNfr(const NfrFactor& f, int64_t track_id,
                                                  const Landmark* lm,
                                                  std::vector<std::pair<VarKey, int>>* vars,
                                                  MatX<Scalar>* J, VecX<Scalar>* r) const {
  // Residual at the current state, Jacobian at the first estimates, as every other residual.
  MatX<Scalar> J_f;
  f.factor.whitenedResidual(nfrBlanket(f, lm, true), &J_f);
  *r = f.factor.whitenedResidual(nfrBlanket(f, lm, false));
  vars->clear();
  vars->push_back({f.var(), 0});
  if (f.kind == BlanketKind::kPose) {
    if (lm != nullptr) vars->push_back({{track_id, StateBlock::kLandmark}, kPoseDim});
    *J = J_f;
    return;
  }
  // A velocity or bias factor: its columns within the speed-bias block [v; b_g; b_a].
  J->setZero(J_f.rows(), kSpeedBiasDim);
  J->middleCols(f.kind == BlanketKind::kVelocity ? 0 : 3, J_f.cols()) = J_f;
}

template <typename Scalar>
Scalar SlidingWindowEstimator<Scalar>::linkCost(int64_t from, const ImuLink& link) const {
  const ImuState<Scalar> s_i = stateOf(from, false);
  const ImuState<Scalar> s_j = stateOf(link.to, false);
  return Scalar(0.5) *
         (link.factor.whitenedResidual(s_i, s_j).squaredNorm() +
          biasRandomWalkResidual<Scalar>(s_i, s_j, link.dt_s, imu_->noise).squaredNorm());
}

template <typename Scalar>
VecX<Scalar> SlidingWindowEstimator<Scalar>::priorDelta(const MargPrior<Scalar>& prior) const {
  return prior.delta([this](int64_t f) { return poseOf(f); },
                     [this](int64_t f) { return speedBiasOf(f); },
                     [this](int64_t track) { return landmarks_.at(track).param; });
}

template <typename Scalar>
std::set<int64_t> SlidingWindowEstimator<Scalar>::priorLandmarks() const {
  std::set<int64_t> tracks;
  for (const auto& block : prior_.blocks) {
    if (block.var.block == StateBlock::kLandmark) tracks.insert(block.var.frame_id);
  }
  return tracks;
}

template <typename Scalar>
Scalar SlidingWindowEstimator<Scalar>::totalCost() const {
  const RelativePoses rel = relativePoses(false);
  std::vector<const Landmark*> lms;
  lms.reserve(landmarks_.size());
  for (const auto& [id, lm] : landmarks_) lms.push_back(&lm);
  std::vector<Scalar> chunk_cost(static_cast<size_t>(pool_->threads()), Scalar(0));
  pool_->forChunks(lms.size(), [&](size_t begin, size_t end, int chunk) {
    Scalar sum = 0;
    for (size_t i = begin; i < end; ++i) sum += landmarkCost(*lms[i], rel);
    chunk_cost[static_cast<size_t>(chunk)] = sum;
  });
  Scalar cost = 0;
  for (const Scalar c : chunk_cost) cost += c;
  for (const auto& [from, link] : imu_links_) cost += linkCost(from, link);
  for (const NfrFactor& f : nfr_unary_) cost += nfrCost(f, nullptr);
  if (!prior_.empty()) cost += prior_.cost(priorDelta(prior_));
  return cost;
}

template <typename Scalar>
bool SlidingWindowEstimator<Scalar>::linearizeLandmark(int64_t track_id, const Landmark& lm,
                                                       const std::set<int64_t>& system_frames,
                                                       const RelativePoses& rel, Linearized* out,
                                                       bool with_nfr, int min_rows) const {
  const Scalar k = static_cast<Scalar>(config_.huber_px);
  const Scalar sigma = static_cast<Scalar>(config_.obs_std_px);
  struct Row2 {
    int64_t target;  // −1: no pose Jacobian (observation in the host frame)
    Mat<Scalar, 2, 6> J_h, J_t;
    Mat<Scalar, 2, 3> J_l;
    Vec2S r;
  };
  // Scratch reused across calls (no allocation per landmark once warm); one per thread.
  thread_local std::vector<Row2> rows;
  rows.clear();
  out->cost = 0;
  const Vec3S p_w_jac = lm.world() ? jacobianPointOf(lm) : Vec3S::Zero();
  for (const auto& [frame_id, obs] : lm.obs) {
    if (system_frames.count(frame_id) == 0) continue;
    const bool in_host = frame_id == lm.host;
    // A world point in the body frame, p_i = Rᵀ(p_w − t) — the pose–landmark map of
    // core/sparsify — at the first estimates with its Jacobians, and at the current state.
    Mat<Scalar, 3, 6> D_p_T;
    Mat3<Scalar> D_p_l;
    Vec3S p_i_jac = Vec3S::Zero(), p_i = Vec3S::Zero();
    if (lm.world()) {
      p_i_jac = poseLandmarkResidual<Scalar>(jacobianPoseOf(frame_id), p_w_jac, Vec3S::Zero(),
                                             &D_p_T, &D_p_l);
      p_i = poseOf(frame_id).inverse() * lm.param;
    }
    for (int cam = 0; cam < (obs.has_right ? 2 : 1); ++cam) {
      const PinholeCamera<Scalar>& camera = cam == 0 ? rig_.cam0 : rig_.cam1;
      Mat<Scalar, 3, 3> D_q_l;
      Mat<Scalar, 3, 6> D_q_T;
      Vec3S q_jac, q;
      size_t k_rel = 0;
      if (lm.world()) {
        const Mat3<Scalar> R_c_i = T_c_i_[cam].rotationMatrix();
        q_jac = T_c_i_[cam] * p_i_jac;
        D_q_T = R_c_i * D_p_T;
        D_q_l = R_c_i * D_p_l;
        q = T_c_i_[cam] * p_i;
      } else {
        k_rel = rel.index(lm.host, frame_id, cam);
        q_jac = transformLandmark<Scalar>(rel.T_ct_h_jac[k_rel], lm.param, &D_q_l, &D_q_T);
        q = transformLandmark<Scalar>(rel.T_ct_h[k_rel], lm.param);
      }
      Vec2S uv_jac, uv;
      Mat<Scalar, 2, 3> D_uv_q;
      if (!camera.project(q_jac, &uv_jac, &D_uv_q)) continue;
      if (!camera.project(q, &uv)) continue;
      Row2 row;
      row.r = uv - (cam == 0 ? obs.uv0 : obs.uv1);
      const Scalar e = row.r.norm();
      out->cost += huberCost<Scalar>(e, k, sigma);
      // IRLS weight of the Huber norm, applied as √w/σ to both rows.
      const Scalar scale = std::sqrt(e <= k ? Scalar(1) : k / e) / sigma;
      row.r *= scale;
      row.J_l = scale * D_uv_q * D_q_l;
      row.target = in_host ? -1 : frame_id;
      if (lm.world()) {
        row.J_t = scale * D_uv_q * D_q_T;
      } else if (!in_host) {
        const Mat<Scalar, 2, 6> D_r_T = scale * D_uv_q * D_q_T;
        row.J_h = D_r_T * rel.D_rel_h[k_rel];
        row.J_t = D_r_T * rel.D_rel_t[k_rel];
      }
      rows.push_back(row);
    }
  }
  // Pose–landmark factors: rows over [anchor pose | landmark].
  thread_local std::vector<RowBlock> nfr_rows;
  nfr_rows.clear();
  int m_nfr = 0;
  for (const NfrFactor& f : lm.nfr) {
    if (!with_nfr || system_frames.count(f.frame) == 0) continue;
    RowBlock rows;
    linearizeNfr(f, track_id, &lm, &rows.vars, &rows.J, &rows.r);
    out->cost += Scalar(0.5) * rows.r.squaredNorm();
    m_nfr += static_cast<int>(rows.r.size());
    nfr_rows.push_back(std::move(rows));
  }
  const int m_obs = 2 * static_cast<int>(rows.size());
  const int m = m_obs + m_nfr;
  if (m < min_rows) return false;
  // The pose blocks: the host and every target with a pose Jacobian (and the anchor of the
  // pose–landmark factor), in id order (a small sorted vector).
  std::vector<int64_t>& frames = out->frames;
  frames.clear();
  auto insert = [&frames](int64_t f) {
    const auto it = std::lower_bound(frames.begin(), frames.end(), f);
    if (it == frames.end() || *it != f) frames.insert(it, f);
  };
  for (const Row2& row : rows) {
    if (row.target < 0) continue;
    if (!lm.world()) insert(lm.host);
    insert(row.target);
  }
  for (const RowBlock& rows : nfr_rows) insert(rows.vars.front().first.frame_id);
  auto local = [&frames](int64_t f) {
    return kPoseDim *
           static_cast<int>(std::lower_bound(frames.begin(), frames.end(), f) - frames.begin());
  };
  out->track_id = track_id;
  out->J_p.setZero(m, kPoseDim * static_cast<Eigen::Index>(frames.size()));
  out->J_l.resize(m, 3);
  out->r.resize(m);
  const int host_col = frames.empty() || lm.world() ? 0 : local(lm.host);
  for (size_t i = 0; i < rows.size(); ++i) {
    out->J_l.template middleRows<2>(2 * i) = rows[i].J_l;
    out->r.template segment<2>(2 * i) = rows[i].r;
    if (rows[i].target < 0) continue;
    if (!lm.world()) out->J_p.template block<2, kPoseDim>(2 * i, host_col) += rows[i].J_h;
    out->J_p.template block<2, kPoseDim>(2 * i, local(rows[i].target)) += rows[i].J_t;
  }
  Eigen::Index row = m_obs;
  for (const RowBlock& rows : nfr_rows) {
    const Eigen::Index n_r = rows.r.size();
    out->J_p.block(row, local(rows.vars.front().first.frame_id), n_r, kPoseDim) =
        rows.J.leftCols(kPoseDim);
    out->J_l.middleRows(row, n_r) = rows.J.rightCols(kPointDim);
    out->r.segment(row, n_r) = rows.r;
    row += n_r;
  }
  return true;
}

template <typename Scalar>
bool SlidingWindowEstimator<Scalar>::landmarkRows(int64_t track_id,
                                                  const std::set<int64_t>& system_frames,
                                                  const RelativePoses& rel, bool with_nfr,
                                                  RowBlock* out) const {
  Linearized lin;
  if (!linearizeLandmark(track_id, landmarks_.at(track_id), system_frames, rel, &lin, with_nfr,
                         1)) {
    return false;
  }
  out->vars.clear();
  for (size_t i = 0; i < lin.frames.size(); ++i) {
    out->vars.push_back({{lin.frames[i], StateBlock::kPose}, kPoseDim * static_cast<int>(i)});
  }
  const Eigen::Index n_p = lin.J_p.cols();
  out->vars.push_back({{track_id, StateBlock::kLandmark}, static_cast<int>(n_p)});
  out->J.resize(lin.r.size(), n_p + kPointDim);
  out->J << lin.J_p, lin.J_l;
  out->r = std::move(lin.r);
  return true;
}

template <typename Scalar>
std::vector<typename SlidingWindowEstimator<Scalar>::RowBlock>
SlidingWindowEstimator<Scalar>::directRows(const std::set<int64_t>& system_frames,
                                           const RelativePoses& rel) const {
  std::vector<RowBlock> out;
  for (int64_t track : priorLandmarks()) {
    RowBlock rows;
    if (landmarkRows(track, system_frames, rel, true, &rows)) out.push_back(std::move(rows));
  }
  for (const NfrFactor& f : nfr_unary_) {
    RowBlock rows;
    linearizeNfr(f, -1, nullptr, &rows.vars, &rows.J, &rows.r);
    out.push_back(std::move(rows));
  }
  return out;
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::linearizeLink(int64_t from, const ImuLink& link,
                                                   LinkLinearized* out) const {
  out->from = from;
  out->to = link.to;
  const ImuState<Scalar> s_i = stateOf(from, false), s_j = stateOf(link.to, false);
  const ImuState<Scalar> s_i_jac = stateOf(from, true), s_j_jac = stateOf(link.to, true);
  typename ImuFactor<Scalar>::Jacobian J_imu;
  Mat<Scalar, 6, 30> J_rw;
  link.factor.whitenedResidual(s_i_jac, s_j_jac, &J_imu);
  biasRandomWalkResidual<Scalar>(s_i_jac, s_j_jac, link.dt_s, imu_->noise, &J_rw);
  out->J.template topRows<9>() = J_imu;
  out->J.template bottomRows<6>() = J_rw;
  out->r.template head<9>() = link.factor.whitenedResidual(s_i, s_j);
  out->r.template tail<6>() = biasRandomWalkResidual<Scalar>(s_i, s_j, link.dt_s, imu_->noise);
}

template <typename Scalar>
PoseBlockMap SlidingWindowEstimator<Scalar>::blockMap(const Linearized& lin,
                                                      const ColumnMap& column_of) const {
  PoseBlockMap map;
  map.pose_dim = kPoseDim;
  for (int64_t f : lin.frames) map.rcs_offset.push_back(column_of.at({f, StateBlock::kPose}));
  return map;
}

template <typename Scalar>
int SlidingWindowEstimator<Scalar>::windowColumns(ColumnMap* column_of) const {
  int col = 0;
  for (const auto& [id, frame] : frames_) {
    (*column_of)[{id, StateBlock::kPose}] = col;
    col += kPoseDim;
    if (frame.has_speed_bias) {
      (*column_of)[{id, StateBlock::kSpeedBias}] = col;
      col += kSpeedBiasDim;
    }
  }
  for (int64_t track : priorLandmarks()) {
    (*column_of)[{track, StateBlock::kLandmark}] = col;
    col += kPointDim;
  }
  return col;
}

template <typename Scalar>
std::vector<int64_t> SlidingWindowEstimator<Scalar>::keyframeIds() const {
  std::vector<int64_t> ids;
  for (const auto& [id, frame] : frames_) {
    if (frame.is_keyframe) ids.push_back(id);
  }
  return ids;
}

template <typename Scalar>
std::vector<int64_t> SlidingWindowEstimator<Scalar>::stateIds() const {
  std::vector<int64_t> ids;
  for (const auto& [id, frame] : frames_) {
    if (frame.has_speed_bias) ids.push_back(id);
  }
  return ids;
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::computeStep(OptElimination elimination, Scalar lambda,
                                                   VecX<Scalar>* delta) const {
  std::set<int64_t> system;
  for (const auto& [id, frame] : frames_) system.insert(id);
  ColumnMap column_of;
  const int n = windowColumns(&column_of);
  MatX<Scalar> H = MatX<Scalar>::Zero(n, n);
  VecX<Scalar> b = VecX<Scalar>::Zero(n);
  const Scalar lambda_min = static_cast<Scalar>(config_.lambda_min);
  const RelativePoses rel = relativePoses(true);
  const std::set<int64_t> reduced = priorLandmarks();
  for (const RowBlock& rows : directRows(system, rel)) addRowBlock<Scalar>(rows, column_of, H, b);
  for (const auto& [id, lm] : landmarks_) {
    Linearized lin;
    if (reduced.count(id) != 0 || !linearizeLandmark(id, lm, system, rel, &lin)) continue;
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
  for (const auto& [from, link] : imu_links_) {
    LinkLinearized lin;
    linearizeLink(from, link, &lin);
    const MatX<Scalar> H_link = lin.J.transpose() * lin.J;
    const VecX<Scalar> b_link = lin.J.transpose() * lin.r;
    scatterBlocks(linkVars(from, link.to), H_link, b_link, column_of, H, b);
  }
  if (!prior_.empty()) addPrior(prior_, priorDelta(prior_), column_of, H, b);
  const DampedSolve<Scalar> solve = solveDampedLdlt<Scalar>(H, b, lambda, lambda_min);
  *delta = solve.delta;
  return solve.status;
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::optimize(FrameResult* result) {
  std::set<int64_t> system;
  for (const auto& [id, frame] : frames_) system.insert(id);
  ColumnMap column_of;
  const int n = windowColumns(&column_of);
  const Scalar lambda_min = static_cast<Scalar>(config_.lambda_min);
  const Scalar lambda_max = static_cast<Scalar>(config_.lambda_max);
  const bool ns = variant_.opt == OptElimination::kNullspace;

  // λ restarts at its initial value for every frame (as Basalt's optimize does).
  lambda_ = static_cast<Scalar>(config_.lambda_init);
  nu_ = Scalar(2);
  Scalar cost = totalCost();
  result->cost_initial = static_cast<double>(cost);
  if (!std::isfinite(cost)) {
    return Status::Error(Status::Code::kNotFinite, "the cost of the window is not finite");
  }
  // Reused across iterations: the landmarks' Jacobians and elimination blocks keep their storage
  // (same sizes from one linearization to the next), so the loop does not allocate per landmark.
  std::vector<Linearized> lins;
  ReducedSystem<Scalar> rs;
  // The landmark loops run in the pool's chunks; per-chunk results are combined in chunk order.
  const size_t n_chunks = static_cast<size_t>(pool_->threads());
  std::vector<std::pair<int64_t, const Landmark*>> lms;
  std::vector<char> linearized;
  std::vector<Status> chunk_status(n_chunks);
  std::vector<Scalar> chunk_change(n_chunks);
  std::vector<MatX<Scalar>> chunk_H(n_chunks - 1);
  std::vector<VecX<Scalar>> chunk_b(n_chunks - 1);
  auto firstError = [&chunk_status]() {
    for (const Status& s : chunk_status) {
      if (!s.ok()) return s;
    }
    return Status::Ok();
  };
  const std::set<int64_t> reduced = priorLandmarks();
  for (int it = 0; it < config_.lm_max_iterations; ++it) {
    const RelativePoses rel = relativePoses(true);
    lms.clear();
    for (const auto& [id, lm] : landmarks_) {
      if (reduced.count(id) == 0) lms.emplace_back(id, &lm);
    }
    lins.resize(lms.size());
    linearized.assign(lms.size(), 0);
    pool_->forChunks(lms.size(), [&](size_t begin, size_t end, int) {
      for (size_t i = begin; i < end; ++i) {
        linearized[i] = linearizeLandmark(lms[i].first, *lms[i].second, system, rel, &lins[i]);
      }
    });
    size_t n_lins = 0;
    for (size_t i = 0; i < lins.size(); ++i) {
      if (!linearized[i]) continue;
      if (i != n_lins) std::swap(lins[n_lins], lins[i]);
      ++n_lins;
    }
    lins.resize(n_lins);
    rs.H_fixed = MatX<Scalar>::Zero(n, n);
    rs.b_fixed = VecX<Scalar>::Zero(n);
    std::vector<LinkLinearized> links(imu_links_.size());
    size_t link_index = 0;
    for (const auto& [from, link] : imu_links_) {
      LinkLinearized& lin = links[link_index++];
      linearizeLink(from, link, &lin);
      const MatX<Scalar> H_link = lin.J.transpose() * lin.J;
      const VecX<Scalar> b_link = lin.J.transpose() * lin.r;
      scatterBlocks(linkVars(from, link.to), H_link, b_link, column_of, rs.H_fixed, rs.b_fixed);
    }
    const std::vector<RowBlock> direct = directRows(system, rel);
    for (const RowBlock& rows : direct)
      addRowBlock<Scalar>(rows, column_of, rs.H_fixed, rs.b_fixed);
    VecX<Scalar> prior_delta;
    if (!prior_.empty()) {
      prior_delta = priorDelta(prior_);
      addPrior(prior_, prior_delta, column_of, rs.H_fixed, rs.b_fixed);
    }
    if (ns) {
      rs.ns.resize(std::max(rs.ns.size(), lins.size()));
    } else {
      rs.sc.resize(std::max(rs.sc.size(), lins.size()));
    }
    std::fill(chunk_status.begin(), chunk_status.end(), Status::Ok());
    pool_->forChunks(lins.size(), [&](size_t begin, size_t end, int chunk) {
      for (size_t l = begin; l < end; ++l) {
        const Linearized& lin = lins[l];
        const PoseBlockMap blocks = blockMap(lin, column_of);
        Status s = ns ? rs.ns[l].setFromJacobians(lin.J_p, lin.J_l, lin.r, blocks)
                      : rs.sc[l].setFromJacobians(lin.J_p, lin.J_l, lin.r, blocks);
        if (!s.ok()) {
          chunk_status[static_cast<size_t>(chunk)] = s;
          return;
        }
      }
    });
    if (Status s = firstError(); !s.ok()) return s;

    // Without landmark damping (the paper's setting, §5) the reduced system does not depend on λ:
    // it is formed once per linearization and only the pose diagonal is damped per trial.
    // Landmarks that cannot be eliminated (singular R1 / H_ll) then stay fixed in this iteration.
    const bool damp_landmarks = config_.lm_landmark_damping;
    std::vector<char> active(lins.size(), 1);
    if (!damp_landmarks) {
      // Chunk 0 adds into the system itself, the others into their own, summed in chunk order.
      for (size_t c = 1; c < n_chunks; ++c) {
        chunk_H[c - 1].setZero(n, n);
        chunk_b[c - 1].setZero(n);
      }
      pool_->forChunks(lins.size(), [&](size_t begin, size_t end, int chunk) {
        MatX<Scalar>& H = chunk == 0 ? rs.H_fixed : chunk_H[static_cast<size_t>(chunk) - 1];
        VecX<Scalar>& b = chunk == 0 ? rs.b_fixed : chunk_b[static_cast<size_t>(chunk) - 1];
        for (size_t l = begin; l < end; ++l) {
          if (ns) {
            active[l] = rs.ns[l].landmarkSolvable();
            if (active[l]) rs.ns[l].addToReducedSystem(H, b);
          } else {
            active[l] = rs.sc[l].addToReducedSystem(H, b).ok();
          }
        }
      });
      for (size_t c = 1; c < n_chunks; ++c) {
        rs.H_fixed += chunk_H[c - 1];
        rs.b_fixed += chunk_b[c - 1];
      }
    }

    bool stop = false;
    while (true) {
      // Assemble the damped reduced system for the current λ.
      rs.H = rs.H_fixed;
      rs.b = rs.b_fixed;
      Status status = Status::Ok();
      for (size_t l = 0; l < lins.size() && damp_landmarks; ++l) {
        Vec3<Scalar> d;
        if (ns) {
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
      // Back-substitution and the landmarks' share of the model decrease, per chunk.
      std::vector<Vec3<Scalar>> delta_l(lins.size(), Vec3<Scalar>::Zero());
      std::fill(chunk_change.begin(), chunk_change.end(), Scalar(0));
      if (status.ok()) {
        std::fill(chunk_status.begin(), chunk_status.end(), Status::Ok());
        pool_->forChunks(lins.size(), [&](size_t begin, size_t end, int chunk) {
          const size_t c = static_cast<size_t>(chunk);
          for (size_t l = begin; l < end; ++l) {
            if (!active[l]) continue;
            Status s = ns ? rs.ns[l].backSubstitute(solve.delta, &delta_l[l])
                          : rs.sc[l].backSubstitute(solve.delta, &delta_l[l]);
            if (!s.ok()) {
              chunk_status[c] = s;
              return;
            }
            chunk_change[c] += ns ? rs.ns[l].linearizedCostChange(solve.delta, delta_l[l])
                                  : rs.sc[l].linearizedCostChange(solve.delta, delta_l[l]);
          }
        });
        status = firstError();
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
      for (const Scalar change : chunk_change) model_change += change;
      for (const LinkLinearized& lin : links) {
        const Vec<Scalar, 15> J_step =
            lin.J * gatherBlocks<Scalar>(linkVars(lin.from, lin.to), 30, solve.delta, column_of);
        model_change += lin.r.dot(J_step) + Scalar(0.5) * J_step.squaredNorm();
      }
      for (const RowBlock& rows : direct) {
        model_change += rowBlockModelChange<Scalar>(rows, solve.delta, column_of);
      }
      if (!prior_.empty()) {
        model_change += prior_.costChange(
            prior_delta,
            gatherBlocks<Scalar>(priorVars(prior_), prior_.cols(), solve.delta, column_of));
      }

      // Apply the step on a backup.
      std::map<int64_t, Frame> frame_backup = frames_;
      for (auto& [id, frame] : frames_) {
        frame.T_w_i = boxPlus<Scalar>(frame.T_w_i, solve.delta.template segment<kPoseDim>(
                                                       column_of.at({id, StateBlock::kPose})));
        if (frame.has_speed_bias) {
          frame.speed_bias += solve.delta.template segment<kSpeedBiasDim>(
              column_of.at({id, StateBlock::kSpeedBias}));
        }
      }
      std::vector<Vec3S> param_backup(lins.size());
      Scalar max_step = solve.delta.size() ? solve.delta.cwiseAbs().maxCoeff() : Scalar(0);
      for (size_t l = 0; l < lins.size(); ++l) {
        Landmark& lm = landmarks_.at(lins[l].track_id);
        param_backup[l] = lm.param;
        lm.param += delta_l[l];
        if (!lm.world()) lm.param.z() = std::max(lm.param.z(), Scalar(0));
        max_step = std::max(max_step, delta_l[l].cwiseAbs().maxCoeff());
      }
      std::map<int64_t, Vec3S> reduced_backup;
      for (int64_t track : reduced) {
        Vec3S& p_w = landmarks_.at(track).param;
        reduced_backup[track] = p_w;
        p_w +=
            solve.delta.template segment<kPointDim>(column_of.at({track, StateBlock::kLandmark}));
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
      frames_ = std::move(frame_backup);
      for (size_t l = 0; l < lins.size(); ++l)
        landmarks_.at(lins[l].track_id).param = param_backup[l];
      for (const auto& [track, p_w] : reduced_backup) landmarks_.at(track).param = p_w;
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
    if (!frame.T_w_i.translation().allFinite() ||
        !frame.T_w_i.unitQuaternion().coeffs().allFinite() || !frame.speed_bias.allFinite()) {
      return Status::Error(Status::Code::kNotFinite, "a state turned non-finite");
    }
  }
  return Status::Ok();
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::addNewLandmarks(int64_t frame_id, const TrackFrame& frame) {
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
std::optional<int64_t> SlidingWindowEstimator<Scalar>::selectKeyframeToMarginalize(
    int64_t current, const std::set<VarKey>& marg_vars) const {
  const std::vector<int64_t> kfs = keyframeIds();
  if (static_cast<int>(kfs.size()) <= config_.max_kfs) return std::nullopt;
  // Only pose-only keyframes (VIO: older than the states, or losing their speed-bias now).
  std::vector<int64_t> candidates;
  for (auto it = kfs.begin(); it != kfs.end() - 2; ++it) {
    if (!frames_.at(*it).has_speed_bias || marg_vars.count({*it, StateBlock::kSpeedBias}) != 0) {
      candidates.push_back(*it);
    }
  }
  if (candidates.empty()) return std::nullopt;
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
  const Vec3S t_last = frames_.at(kfs.back()).T_w_i.translation();
  int64_t best = candidates.front();
  Scalar best_score = -1;
  for (int64_t c : candidates) {
    const Vec3S t_c = frames_.at(c).T_w_i.translation();
    Scalar sum = 0;
    for (int64_t j : kfs) {
      if (j != c)
        sum += Scalar(1) / ((t_c - frames_.at(j).T_w_i.translation()).norm() + Scalar(1e-5));
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
Status SlidingWindowEstimator<Scalar>::marginalizeInto(MargPrior<Scalar>& prior, MargMethod method,
                                                       PriorStorage storage, const MargPlan& plan,
                                                       int* qr_rank) const {
  std::set<int64_t> system_frames;
  for (const auto& [id, frame] : frames_) {
    if (plan.drop_obs_frames.count(id) == 0) system_frames.insert(id);
  }
  std::vector<Linearized> lins;
  std::set<VarKey> keep;
  const RelativePoses rel = relativePoses(true);
  for (int64_t id : plan.landmarks) {
    Linearized lin;
    if (!linearizeLandmark(id, landmarks_.at(id), system_frames, rel, &lin)) continue;
    // Rows beyond the three the landmark consumes carry pose information.
    if (lin.r.size() <= 3 || lin.frames.empty()) continue;
    for (int64_t f : lin.frames) keep.insert({f, StateBlock::kPose});
    lins.push_back(std::move(lin));
  }
  // Rows stacked as they are: IMU factors, observations whose landmark stays, landmarks of the
  // prior that go, recovered factors on marginalized variables.
  std::vector<RowBlock> direct;
  for (int64_t from : plan.imu_links) {
    LinkLinearized lin;
    linearizeLink(from, imu_links_.at(from), &lin);
    direct.push_back({linkVars(lin.from, lin.to), lin.J, lin.r});
  }
  for (const auto& [track, frame] : plan.kept_landmark_obs) {
    RowBlock rows;
    if (landmarkRows(track, {frame}, rel, false, &rows)) direct.push_back(std::move(rows));
  }
  for (const VarKey& var : plan.vars) {
    RowBlock rows;
    if (var.block == StateBlock::kLandmark &&
        landmarkRows(var.frame_id, system_frames, rel, true, &rows)) {
      direct.push_back(std::move(rows));
    }
  }
  for (const NfrFactor& f : nfr_unary_) {
    if (plan.vars.count(f.var()) == 0) continue;
    RowBlock rows;
    linearizeNfr(f, -1, nullptr, &rows.vars, &rows.J, &rows.r);
    direct.push_back(std::move(rows));
  }
  const std::set<int64_t> eliminated(plan.landmarks.begin(), plan.landmarks.end());
  for (const auto& [id, lm] : landmarks_) {
    if (eliminated.count(id) != 0 || plan.vars.count({id, StateBlock::kLandmark}) != 0) continue;
    for (const NfrFactor& f : lm.nfr) {
      if (plan.vars.count(f.var()) == 0) continue;
      RowBlock rows;
      linearizeNfr(f, id, &lm, &rows.vars, &rows.J, &rows.r);
      direct.push_back(std::move(rows));
    }
  }
  for (const RowBlock& rows : direct) {
    for (const auto& [var, offset] : rows.vars) keep.insert(var);
  }
  for (const auto& block : prior.blocks) keep.insert(block.var);
  for (const VarKey& var : plan.vars) keep.erase(var);

  ColumnMap column_of;
  int col = 0;
  for (const VarKey& var : plan.vars) {
    column_of[var] = col;
    col += stateBlockDim(var.block);
  }
  const int n_marg = col;
  MargPrior<Scalar> next;
  next.storage = storage;
  for (const VarKey& var : keep) {
    column_of[var] = col;
    col += stateBlockDim(var.block);
    if (var.block == StateBlock::kLandmark) {
      next.addBlock(var, SE3S(), Vec9S::Zero(), jacobianPointOf(landmarks_.at(var.frame_id)));
      continue;
    }
    const Frame& frame = frames_.at(var.frame_id);
    next.addBlock(var, jacobianPoseOf(var.frame_id),
                  frame.speed_bias_linearized ? frame.speed_bias_lin : frame.speed_bias);
  }
  const int n = col;
  const VecX<Scalar> old_delta = priorDelta(prior);
  const VecX<Scalar> new_delta = priorDelta(next);

  if (method == MargMethod::kQr) {
    int rows = prior.empty() ? 0 : prior.rows();
    std::vector<LandmarkBlockNs<Scalar>> blocks(lins.size());
    for (size_t l = 0; l < lins.size(); ++l) {
      Status s = blocks[l].setFromJacobians(lins[l].J_p, lins[l].J_l, lins[l].r,
                                            blockMap(lins[l], column_of));
      if (!s.ok()) return s;
      rows += blocks[l].numReducedRows();
    }
    for (const RowBlock& d : direct) rows += static_cast<int>(d.r.size());
    MatX<Scalar> A = MatX<Scalar>::Zero(rows, n + 1);
    int row = 0;
    for (const auto& block : blocks) {
      block.copyReducedRows(A, row);
      row += block.numReducedRows();
    }
    for (const RowBlock& d : direct) {
      const int m = static_cast<int>(d.r.size());
      for (const auto& [var, offset] : d.vars) {
        const int dim = stateBlockDim(var.block);
        A.block(row, column_of.at(var), m, dim) = d.J.middleCols(offset, dim);
      }
      A.col(n).segment(row, m) = d.r;
      row += m;
    }
    if (!prior.empty()) {
      MatX<Scalar> J;
      VecX<Scalar> r;
      prior.sqrtRows(old_delta, &J, &r);
      for (const auto& block : prior.blocks) {
        const int dim = stateBlockDim(block.var.block);
        A.block(row, column_of.at(block.var), J.rows(), dim) = J.middleCols(block.offset, dim);
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
      block.addToReducedSystem(H, b).ok();
    }
    for (const RowBlock& d : direct) addRowBlock<Scalar>(d, column_of, H, b);
    if (!prior.empty()) addPrior(prior, old_delta, column_of, H, b);
    SchurMarginalization<Scalar> sc = schurMarginalize<Scalar>(H, b, n_marg);
    if (!sc.status.ok()) return sc.status;
    const VecX<Scalar> b_m = sc.prior.b - sc.prior.H * new_delta;
    // The square root ½‖r + Jδ‖² of the prior (anchored at x⁰); a Hessian prior keeps its value
    // at δ = 0 as its constant c = ½ b_mᵀ H⁺ b_m, so that both storages are the same function
    // and the flat QR's (rows without Jacobian carry no constant either). The energy of the
    // marginalized residuals themselves would grow with every marginalization and loosen the
    // relative-decrease stopping rule for the Hessian storage alone.
    LdltSqrt<Scalar> ldlt = hessianToSqrtLdlt<Scalar>(sc.prior.H, b_m);
    if (!ldlt.status.ok()) {
      return storage == PriorStorage::kHessian
                 ? Status::Error(ldlt.status.code(),
                                 "the constant of the Hessian prior: " + ldlt.status.message())
                 : ldlt.status;
    }
    if (storage == PriorStorage::kHessian) {
      next.hessian.c = Scalar(0.5) * ldlt.prior.r.squaredNorm();
      next.hessian.H = std::move(sc.prior.H);
      next.hessian.b = b_m;
    } else {
      next.sqrt = std::move(ldlt.prior);
    }
  }
  prior = std::move(next);
  return Status::Ok();
}

template <typename Scalar>
std::optional<MargPlan> SlidingWindowEstimator<Scalar>::planStateMarginalization(bool force) const {
  const std::vector<int64_t> states = stateIds();
  if (!imu_ || states.size() < 2 ||
      (!force && static_cast<int>(states.size()) <= config_.max_states)) {
    return std::nullopt;
  }
  const int64_t oldest = states.front();
  MargPlan plan;
  plan.vars.insert({oldest, StateBlock::kSpeedBias});
  if (!frames_.at(oldest).is_keyframe) {
    plan.vars.insert({oldest, StateBlock::kPose});
    plan.drop_obs_frames.insert(oldest);
  }
  if (imu_links_.count(oldest) != 0) plan.imu_links.push_back(oldest);
  return plan;
}

template <typename Scalar>
MargPlan SlidingWindowEstimator<Scalar>::planKeyframeMarginalization(int64_t frame_id) const {
  MargPlan plan;
  plan.vars.insert({frame_id, StateBlock::kPose});
  for (const auto& [id, lm] : landmarks_) {
    if (lm.host == frame_id) plan.landmarks.push_back(id);
  }
  return plan;
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::trialMarginalization(const MargPlan& plan, MargMethod method,
                                                            MatXd* H_m) const {
  MargPrior<Scalar> prior = shadow_prior_;
  const PriorStorage storage =
      method == MargMethod::kQr ? PriorStorage::kSqrt : PriorStorage::kHessian;
  if (method == MargMethod::kQr && prior.storage != PriorStorage::kSqrt && !prior.empty()) {
    return Status::Error(Status::Code::kInvalidArgument,
                         "qr marginalization needs a square-root shadow prior");
  }
  Status s = marginalizeInto(prior, method, storage, plan, nullptr);
  if (!s.ok()) return s;
  if (storage == PriorStorage::kSqrt) {
    const MatXd J = prior.sqrt.J.template cast<double>();
    *H_m = J.transpose() * J;
  } else {
    *H_m = prior.hessian.H.template cast<double>();
  }
  return Status::Ok();
}

template <typename Scalar>
MargEvent SlidingWindowEstimator<Scalar>::shadowEvent() const {
  MargEvent event;
  for (const auto& block : shadow_prior_.blocks) {
    const int64_t f = block.var.frame_id;
    if (block.var.block == StateBlock::kPose) {
      event.layout.push_back({PriorVariableKind::kPose, f, block.offset});
      event.state.T_w_i[f] = block.T0.template cast<double>();
    } else {
      event.layout.push_back({PriorVariableKind::kVelocity, f, block.offset});
      event.layout.push_back({PriorVariableKind::kGyroBias, f, block.offset + 3});
      event.layout.push_back({PriorVariableKind::kAccelBias, f, block.offset + 6});
      event.state.v_w[f] = block.sb0.template head<3>().template cast<double>();
    }
  }
  // Gauge directions at the linearization points: the prior's nullspace lies there (FEJ).
  const VecX<Scalar> delta = priorDelta(shadow_prior_);
  if (shadow_prior_.storage == PriorStorage::kSqrt) {
    event.J_m = shadow_prior_.sqrt.J.template cast<double>();
    event.r_m = (shadow_prior_.sqrt.r + shadow_prior_.sqrt.J * delta).template cast<double>();
    event.H_m = event.J_m.transpose() * event.J_m;
    event.b_m = event.J_m.transpose() * event.r_m;
  } else {
    event.H_m = shadow_prior_.hessian.H.template cast<double>();
    event.b_m = (shadow_prior_.hessian.b + shadow_prior_.hessian.H * delta).template cast<double>();
  }
  event.prior_rows = shadow_prior_.rows();
  return event;
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::marginalize(int64_t current, FrameResult* result) {
  const bool current_is_kf = frames_.at(current).is_keyframe;
  MargPlan plan;
  std::set<int64_t> marg_landmarks;
  const bool keep_landmarks = keepsLandmarks();
  for (const auto& [id, lm] : landmarks_) {
    if (lm.obs.count(current) == 0) marg_landmarks.insert(id);  // track lost
  }
  if (!imu_ && !current_is_kf) plan.drop_obs_frames.insert(current);
  if (const auto state_plan = planStateMarginalization()) {
    plan.vars = state_plan->vars;
    plan.imu_links = state_plan->imu_links;
    plan.drop_obs_frames.insert(state_plan->drop_obs_frames.begin(),
                                state_plan->drop_obs_frames.end());
  }
  for (int64_t f : plan.drop_obs_frames) {
    for (auto& [id, lm] : landmarks_) lm.obs.erase(f);
  }
  int n_marg_frames = 0;
  const std::optional<int64_t> kf = selectKeyframeToMarginalize(current, plan.vars);
  if (kf) {
    plan.vars.insert({*kf, StateBlock::kPose});
    if (keep_landmarks) {
      planKeptLandmarks(*kf, &marg_landmarks, &plan);
    } else {
      for (auto& [id, lm] : landmarks_) {
        if (lm.host == *kf) {
          marg_landmarks.insert(id);
        } else if (marg_landmarks.count(id) == 0) {
          lm.obs.erase(*kf);  // keeps the prior sparse (paper §3.2.2)
        }
      }
    }
  }
  // Landmarks of a dense prior are variables of the prior: they go as such.
  for (int64_t track : priorLandmarks()) {
    if (marg_landmarks.erase(track) != 0) plan.vars.insert({track, StateBlock::kLandmark});
  }
  for (const VarKey& var : plan.vars) n_marg_frames += var.block == StateBlock::kPose ? 1 : 0;
  plan.landmarks.assign(marg_landmarks.begin(), marg_landmarks.end());
  if (!plan.empty()) {
    const auto t0 = Clock::now();
    int qr_rank = -1;
    Status status = marginalizeInto(prior_, variant_.marg, variant_.storage, plan, &qr_rank);
    result->t_marg_s = secondsSince(t0);
    if (!status.ok()) return status;
    for (const auto& [track, frame] : plan.kept_landmark_obs) landmarks_.at(track).obs.erase(frame);
    // Recovered factors on marginalized variables are in the prior now.
    nfr_unary_.erase(
        std::remove_if(nfr_unary_.begin(), nfr_unary_.end(),
                       [&plan](const NfrFactor& f) { return plan.vars.count(f.var()) != 0; }),
        nfr_unary_.end());
    for (auto& [id, lm] : landmarks_) {
      lm.nfr.erase(
          std::remove_if(lm.nfr.begin(), lm.nfr.end(),
                         [&plan](const NfrFactor& f) { return plan.vars.count(f.var()) != 0; }),
          lm.nfr.end());
    }
    for (const auto& block : prior_.blocks) {
      if (block.var.block == StateBlock::kLandmark) {
        Landmark& lm = landmarks_.at(block.var.frame_id);
        if (!lm.linearized) {
          lm.linearized = true;
          lm.param_lin = lm.param;
        }
        continue;
      }
      Frame& frame = frames_.at(block.var.frame_id);
      if (block.var.block == StateBlock::kPose && !frame.linearized) {
        frame.linearized = true;
        frame.T_w_i_lin = frame.T_w_i;
      } else if (block.var.block == StateBlock::kSpeedBias && !frame.speed_bias_linearized) {
        frame.speed_bias_linearized = true;
        frame.speed_bias_lin = frame.speed_bias;
      }
    }
    if (kf && keep_landmarks) {
      SparsifyEvent event;
      event.t_schur_s = result->t_marg_s;
      if (config_.marg_strategy == MargStrategy::kNfr) {
        sparsifyPrior(&event);
        result->t_marg_s += event.t_recovery_s + event.t_insert_s;
      } else {
        describeBlanket(&event);
      }
      result->sparsify_event = std::move(event);
    }
    // The gauge diagnostics analyse a prior over frame states (the shadow prior of discard).
    if (config_.diagnostics && !keep_landmarks) {
      const auto t1 = Clock::now();
      int shadow_rank = -1;
      status = marginalizeInto(shadow_prior_, variant_.marg, variant_.storage, plan, &shadow_rank);
      if (!status.ok()) return status;
      MargEvent event = shadowEvent();
      event.qr_rank = shadow_rank;
      event.n_marg_frames = n_marg_frames;
      event.n_marg_landmarks = static_cast<int>(plan.landmarks.size());
      event.t_shadow_s = secondsSince(t1);
      result->marg_event = std::move(event);
    }
    for (int64_t id : plan.landmarks) landmarks_.erase(id);
    for (int64_t from : plan.imu_links) imu_links_.erase(from);
    for (const VarKey& var : plan.vars) {
      if (var.block == StateBlock::kLandmark) {
        landmarks_.erase(var.frame_id);
      } else if (var.block == StateBlock::kPose) {
        frames_.erase(var.frame_id);
      } else if (auto it = frames_.find(var.frame_id); it != frames_.end()) {
        it->second.has_speed_bias = false;
        it->second.speed_bias_linearized = false;
      }
    }
  }
  if (!imu_ && !current_is_kf) frames_.erase(current);
  return Status::Ok();
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::planKeptLandmarks(int64_t kf,
                                                       std::set<int64_t>* marg_landmarks,
                                                       MargPlan* plan) {
  // Below this inverse distance (1 km) a landmark is as good as at infinity: no world point.
  const Scalar min_rho = Scalar(1e-3);
  for (auto& [id, lm] : landmarks_) {
    if (marg_landmarks->count(id) != 0) continue;
    const bool seen_in_kf = lm.obs.count(kf) != 0;
    if (!seen_in_kf && lm.host != kf) continue;
    const bool seen_elsewhere = std::any_of(lm.obs.begin(), lm.obs.end(),
                                            [kf](const auto& entry) { return entry.first != kf; });
    if (!seen_elsewhere || (!lm.world() && lm.param.z() < min_rho)) {
      marg_landmarks->insert(id);
      continue;
    }
    // Re-parametrized as a world point before it joins the prior: a free variable, so no change
    // of variables of any prior is needed, and its host may leave the window later.
    if (!lm.world()) {
      lm.param = poseOf(lm.host) * (T_i_c_[0] * landmarkToPoint<Scalar>(lm.param));
      lm.host = -1;
    }
    if (!seen_in_kf) continue;
    // nfr needs a positive definite Λ_t: a monocular observation alone gives the landmark a
    // rank-2 prior (no depth), so it is dropped unless a factor anchored at kf fixes the depth.
    const bool anchored_at_kf = std::any_of(lm.nfr.begin(), lm.nfr.end(),
                                            [kf](const NfrFactor& f) { return f.frame == kf; });
    if (config_.marg_strategy == MargStrategy::kNfr && !lm.obs.at(kf).has_right &&
        !anchored_at_kf) {
      lm.obs.erase(kf);
      continue;
    }
    plan->kept_landmark_obs.emplace_back(id, kf);
  }
}

template <typename Scalar>
MatX<Scalar> SlidingWindowEstimator<Scalar>::describeBlanket(SparsifyEvent* event) const {
  MatX<Scalar> Lambda_t = prior_.storage == PriorStorage::kSqrt
                              ? MatX<Scalar>(prior_.sqrt.J.transpose() * prior_.sqrt.J)
                              : prior_.hessian.H;
  event->blanket_cols = prior_.cols();
  event->n_blanket_poses = 0;
  event->n_blanket_landmarks = 0;
  for (const auto& block : prior_.blocks) {
    event->n_blanket_poses += block.var.block == StateBlock::kPose ? 1 : 0;
    event->n_blanket_landmarks += block.var.block == StateBlock::kLandmark ? 1 : 0;
  }
  event->nnz_dense = (Lambda_t.array() != Scalar(0)).count();
  event->nnz_sparse = event->nnz_dense;
  return Lambda_t;
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::sparsifyPrior(SparsifyEvent* event) {
  // Our blanket is only positive semi-definite in general — a keyframe pose that enters it
  // through landmark eliminations alone carries relative information — while the closed form
  // needs Σ_t. It is recovered for Λ_t + εI, ε = 10 n ε_mach tr Λ_t (tr Λ_t ≥ λ_max): just above
  // the rank threshold of core/sparsify (n ε_mach λ_max), so that Σ_t exists; the recovered
  // factors carry information of order ε along the directions Λ_t leaves free.
  MatX<Scalar> Lambda_t = describeBlanket(event);
  const Scalar regularization =
      Scalar(10) * NumericTraits<Scalar>::pinvRelativeTolerance(static_cast<int>(Lambda_t.rows())) *
      Lambda_t.trace();
  Lambda_t.diagonal().array() += regularization;
  const auto t0 = Clock::now();
  auto fallback = [event, t0](const std::string& reason) {
    event->t_recovery_s = secondsSince(t0);
    event->fallback_reason = reason;
  };
  // The factors measure h at the prior's linearization point x⁰ (the paper's choice: z = h(μ_t)
  // with μ_t the linearization point); the dense prior's gradient there is not carried over.
  // Taking them at the dense prior's minimizer x⁰ ⊞ δ*, (Λ_t + εI) δ* = −b, instead was far
  // worse (MH_02, 600 frames: ATE 0.023 m against 0.004 m) — presumably because δ* is ill
  // determined along the directions Λ_t leaves (nearly) free.
  Blanket<Scalar> x;
  std::vector<VarKey> var_of;  // blanket index → window variable
  int anchor = -1;
  int64_t anchor_frame = -1;
  bool anchor_is_kf = false;
  for (const auto& block : prior_.blocks) {
    const int off = block.offset;
    if (block.var.block == StateBlock::kPose) {
      const bool is_kf = frames_.at(block.var.frame_id).is_keyframe;
      // The newest keyframe pose anchors the landmarks (keyframes leave the window last).
      if (is_kf >= anchor_is_kf && (is_kf > anchor_is_kf || block.var.frame_id > anchor_frame)) {
        anchor = static_cast<int>(x.size());
        anchor_frame = block.var.frame_id;
        anchor_is_kf = is_kf;
      }
      x.push_back({BlanketKind::kPose, off, block.T0, {}});
      var_of.push_back(block.var);
    } else if (block.var.block == StateBlock::kSpeedBias) {
      x.push_back({BlanketKind::kVelocity, off, SE3S(), block.sb0.template head<3>()});
      x.push_back({BlanketKind::kBias, off + 3, SE3S(), block.sb0.template tail<6>()});
      var_of.insert(var_of.end(), 2, block.var);
    } else {
      x.push_back({BlanketKind::kLandmark, off, SE3S(), block.p0});
      var_of.push_back(block.var);
    }
  }
  if (anchor < 0) return fallback("no pose in the blanket");
  const Sparsification<Scalar> sp = sparsify<Scalar>(Lambda_t, x, paperTopology(x, anchor));
  if (!sp.status.ok()) return fallback(sp.status.toString());
  Scalar kld = sp.kld;
  MatX<Scalar> Lambda_s = sp.Lambda_s;
  // joint-states: one factor over all state blocks instead of the unary ones. Its closed form
  // (eq. 16) is the inverse of Σ_t's state block, i.e. Λ_t marginalized onto the states; H_s is
  // the same matrix (the unary Jacobians at x⁰ are identities), so the KLD changes only by the
  // log-determinants of the state factors.
  const bool joint = config_.nfr_topology == SparsifyTopology::kJointStates;
  std::vector<int> state_cols, landmark_cols;
  for (const auto& block : prior_.blocks) {
    std::vector<int>& cols = block.var.block == StateBlock::kLandmark ? landmark_cols : state_cols;
    for (int c = 0; c < stateBlockDim(block.var.block); ++c) cols.push_back(block.offset + c);
  }
  Eigen::LLT<MatX<Scalar>> joint_llt;
  VecX<Scalar> b_states;
  if (joint) {
    // The dense prior ½ δᵀ Λ_t δ + bᵀ δ marginalized onto the states, gradient included: the
    // joint factor carries the correlations between states the IMU chain makes tight, and dropping
    // its gradient (measurement at x⁰, as the unary factors do) would pull them to first estimates
    // taken at different times (MH_02, 600 frames: ATE 0.27 m).
    const VecX<Scalar> b0 = prior_.storage == PriorStorage::kSqrt
                                ? VecX<Scalar>(prior_.sqrt.J.transpose() * prior_.sqrt.r)
                                : prior_.hessian.b;
    MatX<Scalar> Lambda_states = Lambda_t(state_cols, state_cols);
    b_states = b0(state_cols);
    if (!landmark_cols.empty()) {
      const MatX<Scalar> Lambda_sl = Lambda_t(state_cols, landmark_cols);
      const Eigen::LDLT<MatX<Scalar>> ldlt_ll(Lambda_t(landmark_cols, landmark_cols));
      Lambda_states -= Lambda_sl * ldlt_ll.solve(Lambda_sl.transpose());
      b_states -= Lambda_sl * ldlt_ll.solve(VecX<Scalar>(b0(landmark_cols)));
    }
    joint_llt.compute(Lambda_states);
    if (joint_llt.info() != Eigen::Success) {
      return fallback("the joint state factor's information is not positive definite");
    }
    const Scalar log_det_joint = Scalar(2) * joint_llt.matrixLLT().diagonal().array().log().sum();
    Scalar log_det_unary = 0;
    for (const RecoveredFactor<Scalar>& f : sp.factors) {
      if (f.spec.kind != NfrFactorKind::kUnary) continue;
      log_det_unary +=
          Scalar(2) *
          Eigen::LLT<MatX<Scalar>>(f.information).matrixLLT().diagonal().array().log().sum();
      const int off = x[static_cast<size_t>(f.spec.var)].offset;
      const Eigen::Index dim = f.information.rows();
      Lambda_s.block(off, off, dim, dim) -= f.information;
    }
    kld -= Scalar(0.5) * (log_det_joint - log_det_unary);
    Lambda_s(state_cols, state_cols) += Lambda_states;
  }
  event->t_recovery_s = secondsSince(t0);

  const auto t1 = Clock::now();
  for (const RecoveredFactor<Scalar>& recovered : sp.factors) {
    NfrFactor f;
    f.factor = recovered;
    f.factor.spec.var = 0;
    f.kind = x[static_cast<size_t>(recovered.spec.var)].kind;
    f.frame = var_of[static_cast<size_t>(recovered.spec.var)].frame_id;
    if (recovered.spec.kind == NfrFactorKind::kPoseLandmark) {
      f.factor.spec.landmark = 1;
      landmarks_.at(var_of[static_cast<size_t>(recovered.spec.landmark)].frame_id)
          .nfr.push_back(std::move(f));
    } else if (!joint) {
      nfr_unary_.push_back(std::move(f));
    }
  }
  // The factors replace the prior. paper: no variable is in a linear prior any more, so
  // first-estimate Jacobians end (the factors are relinearized like every other residual).
  // joint-states: the joint factor is kept as the linear prior over the states (δ = x ⊟ x⁰, the
  // unary residuals to first order), its states keep their first estimates.
  MargPrior<Scalar> states;
  states.storage = prior_.storage;
  if (joint) {
    for (const auto& block : prior_.blocks) {
      if (block.var.block != StateBlock::kLandmark) states.addBlock(block.var, block.T0, block.sb0);
    }
    // ½‖r + Uδ‖² with UᵀU = Λ, Uᵀr = b; the Hessian storage keeps c = ½‖r‖² (its convention).
    states.sqrt.J = joint_llt.matrixU();
    states.sqrt.r = joint_llt.matrixL().solve(b_states);
    states.hessian.H = joint_llt.reconstructedMatrix();
    states.hessian.b = b_states;
    states.hessian.c = Scalar(0.5) * states.sqrt.r.squaredNorm();
  }
  prior_ = std::move(states);
  for (auto& [id, frame] : frames_) {
    frame.linearized = frame.linearized && prior_.indexOf({id, StateBlock::kPose}) >= 0;
    frame.speed_bias_linearized =
        frame.speed_bias_linearized && prior_.indexOf({id, StateBlock::kSpeedBias}) >= 0;
  }
  for (auto& [id, lm] : landmarks_) lm.linearized = false;
  event->t_insert_s = secondsSince(t1);
  event->recovered = true;
  event->kld = static_cast<double>(kld);
  event->nnz_sparse = (Lambda_s.array() != Scalar(0)).count();
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::initializeGaugePrior(int64_t frame_id) {
  // Weights on the first state's increment: VO all 6 pose dof; VIO position, yaw (δφ_z, the
  // rotation about gravity) and the biases.
  const Frame& first = frames_.at(frame_id);
  VecXd weights = VecXd::Zero(first.has_speed_bias ? 15 : 6);
  if (first.has_speed_bias) {
    weights.head<3>().setConstant(config_.gauge_prior_weight);
    weights[5] = config_.gauge_prior_weight;
    weights.segment<3>(kPoseDim + 3).setConstant(config_.gauge_prior_bias_gyro);
    weights.segment<3>(kPoseDim + 6).setConstant(config_.gauge_prior_bias_accel);
  } else {
    weights.setConstant(config_.gauge_prior_weight);
  }
  const int n = static_cast<int>(weights.size());
  const int m = static_cast<int>((weights.array() > 0).count());
  prior_.blocks.clear();
  prior_.addBlock({frame_id, StateBlock::kPose}, first.T_w_i, first.speed_bias);
  if (first.has_speed_bias) {
    prior_.addBlock({frame_id, StateBlock::kSpeedBias}, first.T_w_i, first.speed_bias);
  }
  prior_.sqrt.J = MatX<Scalar>::Zero(m, n);
  prior_.sqrt.r = VecX<Scalar>::Zero(m);
  prior_.hessian.H = MatX<Scalar>::Zero(n, n);
  prior_.hessian.b = VecX<Scalar>::Zero(n);
  for (int c = 0, row = 0; c < n; ++c) {
    if (weights[c] <= 0) continue;
    const Scalar w = static_cast<Scalar>(weights[c]);
    prior_.sqrt.J(row++, c) = std::sqrt(w);
    prior_.hessian.H(c, c) = w;
  }
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::addImuLink(int64_t from, int64_t to) {
  // Preintegrated in double (measurement preprocessing, like the pixel measurements), then used in
  // the estimator's precision.
  const ImuState<Scalar> s_i = stateOf(from, false);
  ImuLink link =
      makeImuLink(from, to, s_i.b_g.template cast<double>(), s_i.b_a.template cast<double>());
  imu_links_.erase(from);
  imu_links_.emplace(from, std::move(link));
}

template <typename Scalar>
typename SlidingWindowEstimator<Scalar>::ImuLink SlidingWindowEstimator<Scalar>::makeImuLink(
    int64_t from, int64_t to, const Eigen::Vector3d& b_g, const Eigen::Vector3d& b_a) const {
  const ImuPreintegration<double> pre = preintegrate<double>(
      imu_->imu, frames_.at(from).t_ns, frames_.at(to).t_ns, b_g, b_a,
      ImuSampleNoise<double>::fromDensities(imu_->noise, imu_->sample_period_s));
  return ImuLink{to, ImuFactor<Scalar>(pre.template cast<Scalar>(), g_w_),
                 static_cast<Scalar>(pre.durationSeconds())};
}

template <typename Scalar>
FrameResult SlidingWindowEstimator<Scalar>::processFrame(const TrackFrame& track_frame) {
  FrameResult result;
  result.t_ns = track_frame.t_ns;
  const int64_t id = next_frame_index_++;
  Frame frame;
  frame.t_ns = track_frame.t_ns;
  frame.has_speed_bias = isVio();
  if (imu_ && id == 0) {
    const ImuState<Scalar> s = imu_->initial.template cast<Scalar>();
    frame.T_w_i = s.T_w_i;
    frame.speed_bias << s.v_w, s.b_g, s.b_a;
  } else if (!imu_) {
    SE3<double> T_init = last_pose_;
    if (has_previous_pose_) {
      // Constant-velocity prediction: T_k = (T_{k−1} T_{k−2}⁻¹) T_{k−1}.
      T_init = (last_pose_ * previous_pose_.inverse()) * last_pose_;
    }
    frame.T_w_i = T_init.template cast<Scalar>();
  }
  frame.T_w_i_lin = frame.T_w_i;
  if (imu_ && id > 0) {
    // Predicted from the previous state through the new IMU factor.
    const int64_t previous = frames_.rbegin()->first;
    frames_[id] = frame;
    addImuLink(previous, id);
    const ImuState<Scalar> s_j = predictState<Scalar>(
        stateOf(previous, false), imu_links_.at(previous).factor.preintegration(), g_w_);
    Frame& added = frames_.at(id);
    added.T_w_i = s_j.T_w_i;
    added.T_w_i_lin = s_j.T_w_i;
    added.speed_bias << s_j.v_w, s_j.b_g, s_j.b_a;
  } else {
    frames_[id] = frame;
  }

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
    first.speed_bias_linearized = first.has_speed_bias;
    first.speed_bias_lin = first.speed_bias;
    last_keyframe_ = id;
    initializeGaugePrior(id);  // the shadow prior has none
    addNewLandmarks(id, track_frame);
  }

  if (capture_next_) captured_ = snapshot();
  const auto t0 = Clock::now();
  result.status = optimize(&result);
  result.t_opt_s = secondsSince(t0);
  if (capture_next_) {
    recordStep(result, &*captured_);
    capture_next_ = false;
  }
  const Frame& optimized = frames_.at(id);
  result.T_w_i = optimized.T_w_i.template cast<double>();
  if (optimized.has_speed_bias) {
    result.v_w = optimized.speed_bias.template head<3>().template cast<double>();
  }
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
  last_pose_ = result.T_w_i;
  has_previous_pose_ = id > 0;
  return result;
}

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

}  // namespace

template <typename Scalar>
WindowSnapshot SlidingWindowEstimator<Scalar>::snapshot() const {
  // Exact widening of a Scalar pose (no renormalization).
  auto widen = [](const SE3S& T) {
    SE3<double> out(T.unitQuaternion().template cast<double>(),
                    T.translation().template cast<double>());
    const_cast<Eigen::Quaterniond&>(out.unitQuaternion()) =
        T.unitQuaternion().template cast<double>();
    return out;
  };
  WindowSnapshot w;
  w.variant = variant_.name();
  w.config = config_;
  w.rig = rig_input_;
  w.vio = isVio();
  w.failed_solves = failed_solves_;
  for (const auto& [id, f] : frames_) {
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
  for (const auto& [id, lm] : landmarks_) {
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
  if (imu_) {
    w.imu_noise = imu_->noise;
    w.imu_sample_period_s = imu_->sample_period_s;
    w.g_w = imu_->g_w;
    int64_t t_min = std::numeric_limits<int64_t>::max(),
            t_max = std::numeric_limits<int64_t>::min();
    for (const auto& [from, link] : imu_links_) {
      const ImuPreintegration<Scalar>& pre = link.factor.preintegration();
      w.imu_links.push_back({from, link.to, pre.biasGyroLin().template cast<double>(),
                             pre.biasAccelLin().template cast<double>()});
      t_min = std::min(t_min, frames_.at(from).t_ns);
      t_max = std::max(t_max, frames_.at(link.to).t_ns);
    }
    // The samples preintegration reads: from the one in force at the first link's start (with a
    // margin) to the first one at or after the last link's end.
    const std::vector<int64_t>& t = imu_->imu.t_ns;
    if (!imu_links_.empty() && !t.empty()) {
      const auto lo_it = std::upper_bound(t.begin(), t.end(), t_min);
      const auto hi_it = std::upper_bound(t.begin(), t.end(), t_max);
      const size_t lo = static_cast<size_t>(std::max<std::ptrdiff_t>(0, lo_it - t.begin() - 2));
      const size_t hi = std::min(t.size() - 1, static_cast<size_t>(hi_it - t.begin()) + 1);
      for (size_t k = lo; k <= hi; ++k) {
        w.imu.t_ns.push_back(t[k]);
        w.imu.gyro.push_back(imu_->imu.gyro[k]);
        w.imu.accel.push_back(imu_->imu.accel[k]);
      }
    }
  }
  w.prior_storage = prior_.storage;
  for (const auto& block : prior_.blocks) {
    w.prior_blocks.push_back(
        {block.var, block.offset, widen(block.T0), block.sb0.template cast<double>()});
  }
  w.prior_J = prior_.sqrt.J.template cast<double>();
  w.prior_r = prior_.sqrt.r.template cast<double>();
  w.prior_H = prior_.hessian.H.template cast<double>();
  w.prior_b = prior_.hessian.b.template cast<double>();
  w.prior_c = static_cast<double>(prior_.hessian.c);
  return w;
}

template <typename Scalar>
std::optional<WindowSnapshot> SlidingWindowEstimator<Scalar>::takeCapturedWindow() {
  std::optional<WindowSnapshot> out = std::move(captured_);
  captured_.reset();
  return out;
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::recordStep(const FrameResult& result,
                                                WindowSnapshot* window) const {
  const WindowSnapshot now = snapshot();
  WindowSnapshot::Step& step = window->after;
  step.present = true;
  step.lm_iterations = result.lm_iterations;
  step.cost_initial = result.cost_initial;
  step.cost_final = result.cost_final;
  step.frames = now.frames;
  step.landmarks = now.landmarks;
  for (auto& lm : step.landmarks) lm.obs.clear();
}

template <typename Scalar>
SlidingWindowEstimator<Scalar> SlidingWindowEstimator<Scalar>::fromSnapshot(
    const WindowSnapshot& w, const Variant& variant, const std::optional<EstimatorConfig>& config) {
  if (w.frames.empty()) throw InputError("", 0, "window: no frames");
  EstimatorConfig cfg = config ? *config : w.config;
  cfg.diagnostics = false;  // a restored window has no shadow prior
  std::optional<ImuSetup> imu;
  if (w.vio) {
    ImuSetup setup;
    setup.imu = w.imu;
    setup.noise = w.imu_noise;
    setup.sample_period_s = w.imu_sample_period_s;
    setup.g_w = w.g_w;
    setup.initial.T_w_i = w.frames.front().T_w_i;
    imu = std::move(setup);
  }
  SlidingWindowEstimator est(cfg, variant, w.rig, w.frames.front().T_w_i, std::move(imu));
  for (const auto& fs : w.frames) {
    Frame f;
    f.t_ns = fs.t_ns;
    f.T_w_i = exactPose<Scalar>(fs.T_w_i);
    f.T_w_i_lin = exactPose<Scalar>(fs.T_w_i_lin);
    f.linearized = fs.linearized;
    f.is_keyframe = fs.is_keyframe;
    f.has_speed_bias = fs.has_speed_bias;
    f.speed_bias = fs.speed_bias.template cast<Scalar>();
    f.speed_bias_lin = fs.speed_bias_lin.template cast<Scalar>();
    f.speed_bias_linearized = fs.speed_bias_linearized;
    est.frames_[fs.id] = f;
    if (fs.is_keyframe) est.last_keyframe_ = std::max(est.last_keyframe_, fs.id);
    est.next_frame_index_ = std::max(est.next_frame_index_, fs.id + 1);
  }
  for (const auto& ls : w.landmarks) {
    if (est.frames_.count(ls.host) == 0) throw InputError("", 0, "window: landmark host missing");
    Landmark lm;
    lm.host = ls.host;
    lm.param = ls.param.template cast<Scalar>();
    for (const auto& o : ls.obs) {
      if (est.frames_.count(o.frame) == 0)
        throw InputError("", 0, "window: observing frame missing");
      lm.obs[o.frame] =
          Observation{o.uv0.template cast<Scalar>(), o.has_right, o.uv1.template cast<Scalar>()};
    }
    est.landmarks_.emplace(ls.id, std::move(lm));
  }
  for (const auto& link : w.imu_links) {
    if (!w.vio || est.frames_.count(link.from) == 0 || est.frames_.count(link.to) == 0) {
      throw InputError("", 0, "window: IMU factor between missing frames");
    }
    est.imu_links_.emplace(
        link.from, est.makeImuLink(link.from, link.to, link.bias_gyro_lin, link.bias_accel_lin));
  }
  MargPrior<Scalar>& prior = est.prior_;
  for (const auto& b : w.prior_blocks) {
    typename MargPrior<Scalar>::Block block;
    block.var = b.var;
    block.offset = b.offset;
    block.T0 = exactPose<Scalar>(b.T0);
    block.sb0 = b.sb0.template cast<Scalar>();
    prior.blocks.push_back(block);
  }
  if (w.prior_storage == variant.storage) {
    prior.sqrt.J = w.prior_J.template cast<Scalar>();
    prior.sqrt.r = w.prior_r.template cast<Scalar>();
    prior.hessian.H = w.prior_H.template cast<Scalar>();
    prior.hessian.b = w.prior_b.template cast<Scalar>();
    prior.hessian.c = static_cast<Scalar>(w.prior_c);
  } else if (w.prior_storage == PriorStorage::kSqrt) {
    // E_m = ½‖r + Jδ‖² = ½δᵀ(JᵀJ)δ + (Jᵀr)ᵀδ + ½‖r‖², formed in double.
    prior.hessian.H = (w.prior_J.transpose() * w.prior_J).template cast<Scalar>();
    prior.hessian.b = (w.prior_J.transpose() * w.prior_r).template cast<Scalar>();
    prior.hessian.c = static_cast<Scalar>(0.5 * w.prior_r.squaredNorm());
  } else {
    throw InputError("", 0, "window: a Hessian prior cannot be replayed with square-root storage");
  }
  const int cols = prior.empty() ? 0 : prior.cols();
  const bool sqrt_storage = variant.storage == PriorStorage::kSqrt;
  if (!prior.empty() &&
      (sqrt_storage ? prior.sqrt.J.cols() != cols || prior.sqrt.r.size() != prior.sqrt.J.rows()
                    : prior.hessian.H.cols() != cols || prior.hessian.b.size() != cols)) {
    throw InputError("", 0, "window: prior size does not match its layout");
  }
  est.failed_solves_ = w.failed_solves;
  return est;
}

#define MARGLAB_INST(S) template class SlidingWindowEstimator<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
