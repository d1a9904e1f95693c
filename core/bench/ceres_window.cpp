#include "core/bench/ceres_window.h"

#include <ceres/ceres.h>

#include <map>
#include <memory>

#include "core/common/error.h"
#include "core/geometry/stereographic.h"
#include "core/imu/preintegration.h"

namespace marglab {
namespace {

using Vec9d = Vec<double, 9>;

SE3<double> poseFrom(const double* x) {
  Eigen::Quaterniond q(x[3], x[0], x[1], x[2]);
  return SE3<double>(q, Eigen::Vector3d(x[4], x[5], x[6]));
}

void poseTo(const SE3<double>& T, double* x) {
  const Eigen::Quaterniond& q = T.unitQuaternion();
  x[0] = q.x();
  x[1] = q.y();
  x[2] = q.z();
  x[3] = q.w();
  for (int i = 0; i < 3; ++i) x[4 + i] = T.translation()[i];
}

// The estimator's pose manifold; PlusJacobian [I₆; 0] lets the cost functions hand Ceres the
// tangent Jacobian directly (first six ambient columns).
class PoseManifold : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 7; }
  int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    poseTo(boxPlus<double>(poseFrom(x), Eigen::Map<const Vec<double, 6>>(delta)), x_plus_delta);
    return true;
  }
  bool PlusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.topRows<6>().setIdentity();
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    Eigen::Map<Vec<double, 6>>{y_minus_x} = boxMinus<double>(poseFrom(y), poseFrom(x));
    return true;
  }
  bool MinusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.leftCols<6>().setIdentity();
    return true;
  }
};

// A tangent Jacobian (rows × 6) written into a row-major rows × 7 ambient Jacobian.
template <int Rows>
void writePoseJacobian(const Mat<double, Rows, 6>& J_tangent, double* out) {
  Eigen::Map<Eigen::Matrix<double, Rows, 7, Eigen::RowMajor>> J(out);
  J.template leftCols<6>() = J_tangent;
  J.col(6).setZero();
}

struct FrameLin {
  const SE3<double>* T_lin = nullptr;  // first estimate, or null: the current value
  const Vec9d* sb_lin = nullptr;
};

// Reprojection of a landmark hosted in another frame.
class ReprojectionCost : public ceres::SizedCostFunction<2, 7, 7, 3> {
 public:
  ReprojectionCost(const PinholeCamera<double>& cam, const SE3<double>& T_i_c0,
                   const SE3<double>& T_i_c, const Eigen::Vector2d& z, double sigma, FrameLin host,
                   FrameLin target)
      : cam_(cam),
        T_i_c0_(T_i_c0),
        T_i_c_(T_i_c),
        z_(z),
        sigma_(sigma),
        host_(host),
        target_(target) {}
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const SE3<double> T_h = poseFrom(p[0]), T_t = poseFrom(p[1]);
    const Eigen::Vector3d l(p[2][0], p[2][1], p[2][2]);
    Eigen::Vector2d uv;
    if (!cam_.project(transformLandmark<double>(relativePose(T_h, T_i_c0_, T_t, T_i_c_), l), &uv)) {
      return false;
    }
    Eigen::Map<Eigen::Vector2d>{residuals} = (uv - z_) / sigma_;
    if (jacobians == nullptr) return true;
    Mat<double, 6, 6> D_h, D_t;
    const SE3<double> T_jac =
        relativePose(host_.T_lin ? *host_.T_lin : T_h, T_i_c0_,
                     target_.T_lin ? *target_.T_lin : T_t, T_i_c_, &D_h, &D_t);
    Mat3<double> D_q_l;
    Mat<double, 3, 6> D_q_T;
    const Eigen::Vector3d q = transformLandmark<double>(T_jac, l, &D_q_l, &D_q_T);
    Mat<double, 2, 3> D_uv_q;
    if (!cam_.project(q, &uv, &D_uv_q)) return false;
    const Mat<double, 2, 6> D_r_T = D_uv_q * D_q_T / sigma_;
    if (jacobians[0]) writePoseJacobian<2>(D_r_T * D_h, jacobians[0]);
    if (jacobians[1]) writePoseJacobian<2>(D_r_T * D_t, jacobians[1]);
    if (jacobians[2]) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>>{jacobians[2]} =
          D_uv_q * D_q_l / sigma_;
    }
    return true;
  }

 private:
  PinholeCamera<double> cam_;
  SE3<double> T_i_c0_, T_i_c_;
  Eigen::Vector2d z_;
  double sigma_;
  FrameLin host_, target_;
};

// Reprojection in the host frame itself (cam0 or cam1): the landmark only.
class HostReprojectionCost : public ceres::SizedCostFunction<2, 3> {
 public:
  HostReprojectionCost(const PinholeCamera<double>& cam, const SE3<double>& T_c_h,
                       const Eigen::Vector2d& z, double sigma)
      : cam_(cam), T_c_h_(T_c_h), z_(z), sigma_(sigma) {}
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const Eigen::Vector3d l(p[0][0], p[0][1], p[0][2]);
    Mat3<double> D_q_l;
    const Eigen::Vector3d q = transformLandmark<double>(T_c_h_, l, &D_q_l);
    Eigen::Vector2d uv;
    Mat<double, 2, 3> D_uv_q;
    if (!cam_.project(q, &uv, &D_uv_q)) return false;
    Eigen::Map<Eigen::Vector2d>{residuals} = (uv - z_) / sigma_;
    if (jacobians && jacobians[0]) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>>{jacobians[0]} =
          D_uv_q * D_q_l / sigma_;
    }
    return true;
  }

 private:
  PinholeCamera<double> cam_;
  SE3<double> T_c_h_;
  Eigen::Vector2d z_;
  double sigma_;
};

ImuState<double> imuState(int64_t t_ns, const SE3<double>& T, const Vec9d& sb) {
  ImuState<double> s;
  s.t_ns = t_ns;
  s.T_w_i = T;
  s.v_w = sb.head<3>();
  s.b_g = sb.segment<3>(3);
  s.b_a = sb.tail<3>();
  return s;
}

// IMU preintegration and bias random walk between consecutive states.
class ImuCost : public ceres::SizedCostFunction<15, 7, 9, 7, 9> {
 public:
  ImuCost(ImuFactor<double> factor, double dt_s, const ImuNoise& noise, int64_t t_i, int64_t t_j,
          FrameLin lin_i, FrameLin lin_j)
      : factor_(std::move(factor)),
        dt_s_(dt_s),
        noise_(noise),
        t_i_(t_i),
        t_j_(t_j),
        lin_i_(lin_i),
        lin_j_(lin_j) {}
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const SE3<double> T_i = poseFrom(p[0]), T_j = poseFrom(p[2]);
    const Vec9d sb_i = Eigen::Map<const Vec9d>(p[1]), sb_j = Eigen::Map<const Vec9d>(p[3]);
    const ImuState<double> s_i = imuState(t_i_, T_i, sb_i), s_j = imuState(t_j_, T_j, sb_j);
    Eigen::Map<Vec<double, 15>> r(residuals);
    r.head<9>() = factor_.whitenedResidual(s_i, s_j);
    r.tail<6>() = biasRandomWalkResidual<double>(s_i, s_j, dt_s_, noise_);
    if (jacobians == nullptr) return true;
    const ImuState<double> s_i_jac =
        imuState(t_i_, lin_i_.T_lin ? *lin_i_.T_lin : T_i, lin_i_.sb_lin ? *lin_i_.sb_lin : sb_i);
    const ImuState<double> s_j_jac =
        imuState(t_j_, lin_j_.T_lin ? *lin_j_.T_lin : T_j, lin_j_.sb_lin ? *lin_j_.sb_lin : sb_j);
    typename ImuFactor<double>::Jacobian J_imu;
    Mat<double, 6, 30> J_rw;
    factor_.whitenedResidual(s_i_jac, s_j_jac, &J_imu);
    biasRandomWalkResidual<double>(s_i_jac, s_j_jac, dt_s_, noise_, &J_rw);
    Mat<double, 15, 30> J;
    J.topRows<9>() = J_imu;
    J.bottomRows<6>() = J_rw;
    if (jacobians[0]) writePoseJacobian<15>(J.middleCols<6>(0), jacobians[0]);
    if (jacobians[1]) {
      Eigen::Map<Eigen::Matrix<double, 15, 9, Eigen::RowMajor>>{jacobians[1]} = J.middleCols<9>(6);
    }
    if (jacobians[2]) writePoseJacobian<15>(J.middleCols<6>(15), jacobians[2]);
    if (jacobians[3]) {
      Eigen::Map<Eigen::Matrix<double, 15, 9, Eigen::RowMajor>>{jacobians[3]} = J.middleCols<9>(21);
    }
    return true;
  }

 private:
  ImuFactor<double> factor_;
  double dt_s_;
  ImuNoise noise_;
  int64_t t_i_, t_j_;
  FrameLin lin_i_, lin_j_;
};

// ½‖r_m + J_m (x ⊟ x⁰)‖² over the prior's blocks, Jacobian J_m (first estimates).
class PriorCost : public ceres::CostFunction {
 public:
  explicit PriorCost(MargPrior<double> prior) : prior_(std::move(prior)) {
    set_num_residuals(static_cast<int>(prior_.sqrt.J.rows()));
    for (const auto& b : prior_.blocks) {
      mutable_parameter_block_sizes()->push_back(b.var.block == StateBlock::kPose ? 7 : 9);
    }
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    std::map<int64_t, const double*> poses, sbs;
    for (size_t k = 0; k < prior_.blocks.size(); ++k) {
      (prior_.blocks[k].var.block == StateBlock::kPose ? poses
                                                       : sbs)[prior_.blocks[k].var.frame_id] = p[k];
    }
    const VecXd delta =
        prior_.delta([&](int64_t f) { return poseFrom(poses.at(f)); },
                     [&](int64_t f) { return Vec9d(Eigen::Map<const Vec9d>(sbs.at(f))); });
    const Eigen::Index m = prior_.sqrt.J.rows();
    Eigen::Map<VecXd>{residuals, m} = prior_.sqrt.r + prior_.sqrt.J * delta;
    if (jacobians == nullptr) return true;
    for (size_t k = 0; k < prior_.blocks.size(); ++k) {
      if (jacobians[k] == nullptr) continue;
      const auto& b = prior_.blocks[k];
      if (b.var.block == StateBlock::kPose) {
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 7, Eigen::RowMajor>> J(jacobians[k], m, 7);
        J.leftCols<6>() = prior_.sqrt.J.middleCols(b.offset, 6);
        J.col(6).setZero();
      } else {
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 9, Eigen::RowMajor>> J(jacobians[k], m, 9);
        J = prior_.sqrt.J.middleCols(b.offset, 9);
      }
    }
    return true;
  }

 private:
  MargPrior<double> prior_;
};

// The window as a Ceres problem: the parameter storage (stable addresses) and the problem that
// points into it, with the Schur elimination groups (landmarks first).
struct CeresWindowProblem {
  std::map<int64_t, std::array<double, 7>> poses;
  std::map<int64_t, std::array<double, 9>> sbs;
  std::map<int64_t, std::array<double, 3>> landmarks;
  std::map<int64_t, FrameLin> lin;
  std::map<int64_t, const WindowSnapshot::FrameState*> frame_of;
  std::unique_ptr<ceres::Problem> problem;
  std::shared_ptr<ceres::ParameterBlockOrdering> ordering =
      std::make_shared<ceres::ParameterBlockOrdering>();
  int residual_blocks = 0;
};

void addStates(const WindowSnapshot& w, CeresWindowProblem& p) {
  for (const auto& f : w.frames) {
    poseTo(f.T_w_i, p.poses[f.id].data());
    p.frame_of[f.id] = &f;
    FrameLin fl;
    if (f.linearized) fl.T_lin = &f.T_w_i_lin;
    if (f.has_speed_bias) {
      std::copy(f.speed_bias.data(), f.speed_bias.data() + 9, p.sbs[f.id].data());
      if (f.speed_bias_linearized) fl.sb_lin = &f.speed_bias_lin;
    }
    p.lin[f.id] = fl;
  }
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::TAKE_OWNERSHIP;
  p.problem = std::make_unique<ceres::Problem>(problem_options);
  for (auto& [id, x] : p.poses) {
    p.problem->AddParameterBlock(x.data(), 7, new PoseManifold);
    p.ordering->AddElementToGroup(x.data(), 1);
  }
  for (auto& [id, x] : p.sbs) {
    p.problem->AddParameterBlock(x.data(), 9);
    p.ordering->AddElementToGroup(x.data(), 1);
  }
}

// One Huber-robustified residual per observation the estimator would use (projectable now);
// a landmark without any is left out of the problem.
void addReprojections(const WindowSnapshot& w, CeresWindowProblem& p) {
  const EstimatorSettings& cfg = w.config;
  const double sigma = cfg.obs_std_px;
  std::array<SE3<double>, 2> T_i_c;
  if (w.vio) {
    T_i_c = {w.rig.T_i_c0, w.rig.T_i_c1};
  } else {
    T_i_c = {SE3<double>(), w.rig.T_c0_c1()};
  }
  const std::array<PinholeCamera<double>, 2> cams = {w.rig.cam0, w.rig.cam1};
  const double huber_a = cfg.huber_px / sigma;
  for (const auto& lm : w.landmarks) {
    auto& x = p.landmarks[lm.id];
    for (int i = 0; i < 3; ++i) x[i] = lm.param[i];
    bool added = false;
    for (const auto& o : lm.obs) {
      for (int cam = 0; cam < (o.has_right ? 2 : 1); ++cam) {
        const Eigen::Vector2d& z = cam == 0 ? o.uv0 : o.uv1;
        std::unique_ptr<ceres::CostFunction> cost;
        std::vector<double*> blocks;
        if (o.frame == lm.host) {
          cost = std::make_unique<HostReprojectionCost>(cams[cam], T_i_c[cam].inverse() * T_i_c[0],
                                                        z, sigma);
          blocks = {x.data()};
        } else {
          cost = std::make_unique<ReprojectionCost>(cams[cam], T_i_c[0], T_i_c[cam], z, sigma,
                                                    p.lin.at(lm.host), p.lin.at(o.frame));
          blocks = {p.poses.at(lm.host).data(), p.poses.at(o.frame).data(), x.data()};
        }
        double r[2];
        if (!cost->Evaluate(blocks.data(), r, nullptr)) continue;
        p.problem->AddResidualBlock(cost.release(), new ceres::HuberLoss(huber_a), blocks);
        ++p.residual_blocks;
        added = true;
      }
    }
    if (added) {
      p.ordering->AddElementToGroup(x.data(), 0);
      p.problem->SetParameterLowerBound(x.data(), 2, 0.0);
    } else {
      p.landmarks.erase(lm.id);
    }
  }
}

void addImuAndPrior(const WindowSnapshot& w, CeresWindowProblem& p) {
  for (const auto& link : w.imu_links) {
    const auto& fi = *p.frame_of.at(link.from);
    const auto& fj = *p.frame_of.at(link.to);
    const ImuPreintegration<double> pre = preintegrate<double>(
        w.imu, fi.t_ns, fj.t_ns, link.bias_gyro_lin, link.bias_accel_lin,
        ImuSampleNoise<double>::fromDensities(w.imu_noise, w.imu_sample_period_s));
    p.problem->AddResidualBlock(
        new ImuCost(ImuFactor<double>(pre, w.g_w), pre.durationSeconds(), w.imu_noise, fi.t_ns,
                    fj.t_ns, p.lin.at(link.from), p.lin.at(link.to)),
        nullptr,
        {p.poses.at(link.from).data(), p.sbs.at(link.from).data(), p.poses.at(link.to).data(),
         p.sbs.at(link.to).data()});
    ++p.residual_blocks;
  }
  if (w.prior_blocks.empty()) return;
  MargPrior<double> prior;
  prior.storage = PriorStorage{};
  std::vector<double*> blocks;
  for (const auto& b : w.prior_blocks) {
    prior.blocks.push_back({b.var, b.offset, b.T0, b.sb0});
    blocks.push_back(b.var.block == StateBlock::kPose ? p.poses.at(b.var.frame_id).data()
                                                      : p.sbs.at(b.var.frame_id).data());
  }
  prior.sqrt.J = w.prior_J;
  prior.sqrt.r = w.prior_r;
  p.problem->AddResidualBlock(new PriorCost(std::move(prior)), nullptr, blocks);
  ++p.residual_blocks;
}

// The window's LM settings in Ceres' terms (trust radius = 1/λ).
ceres::Solver::Options solverOptions(
    const EstimatorSettings& cfg, const CeresWindowOptions& opt,
    const std::shared_ptr<ceres::ParameterBlockOrdering>& ordering) {
  ceres::Solver::Options o;
  o.minimizer_type = ceres::TRUST_REGION;
  o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  o.linear_solver_type = opt.linear_solver;
  o.preconditioner_type = opt.preconditioner;
  // The elimination groups concern the Schur solvers only; the others keep Ceres' default.
  if (opt.linear_solver == ceres::DENSE_SCHUR || opt.linear_solver == ceres::SPARSE_SCHUR ||
      opt.linear_solver == ceres::ITERATIVE_SCHUR) {
    o.linear_solver_ordering = ordering;
  }
  o.initial_trust_region_radius = 1.0 / cfg.lambda_init;
  o.max_trust_region_radius = 1.0 / cfg.lambda_min;
  o.min_trust_region_radius = 1.0 / cfg.lambda_max;
  o.max_num_iterations = opt.max_iterations > 0 ? opt.max_iterations : cfg.lm_max_iterations;
  o.function_tolerance =
      opt.function_tolerance >= 0 ? opt.function_tolerance : cfg.stop_relative_cost;
  // The estimator stops on max|δ| < stop_max_step (absolute); Ceres' parameter tolerance is
  // relative to ‖x‖, which on KITTI (positions of hundreds of metres) stops before the first step.
  // Not mapped: Ceres stops on the relative cost decrease and the iteration cap.
  o.parameter_tolerance = opt.parameter_tolerance >= 0 ? opt.parameter_tolerance : 1e-12;
  o.gradient_tolerance = opt.gradient_tolerance;
  o.jacobi_scaling = false;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  return o;
}

CeresWindowResult resultOf(const ceres::Solver::Summary& summary, const WindowSnapshot& w,
                           const CeresWindowProblem& p) {
  CeresWindowResult out;
  out.ok = summary.IsSolutionUsable();
  out.message = summary.message;
  out.iterations = static_cast<int>(summary.iterations.size()) - 1;
  out.successful_iterations = summary.num_successful_steps;
  out.seconds = summary.total_time_in_seconds;
  out.split.preprocessor_s = summary.preprocessor_time_in_seconds;
  out.split.minimizer_s = summary.minimizer_time_in_seconds;
  out.split.linear_solver_s = summary.linear_solver_time_in_seconds;
  out.split.residual_s = summary.residual_evaluation_time_in_seconds;
  out.split.jacobian_s = summary.jacobian_evaluation_time_in_seconds;
  out.split.postprocessor_s = summary.postprocessor_time_in_seconds;
  out.cost_initial = summary.initial_cost;
  out.cost_final = summary.final_cost;
  out.num_residual_blocks = p.residual_blocks;
  out.step.present = true;
  out.step.lm_iterations = out.iterations;
  out.step.cost_initial = out.cost_initial;
  out.step.cost_final = out.cost_final;
  for (const auto& f : w.frames) {
    WindowSnapshot::FrameState fs;
    fs.id = f.id;
    fs.T_w_i = poseFrom(p.poses.at(f.id).data());
    fs.has_speed_bias = f.has_speed_bias;
    fs.is_keyframe = f.is_keyframe;
    if (f.has_speed_bias) fs.speed_bias = Eigen::Map<const Vec9d>(p.sbs.at(f.id).data());
    out.step.frames.push_back(fs);
  }
  for (const auto& [id, x] : p.landmarks) {
    WindowSnapshot::LandmarkState ls;
    ls.id = id;
    ls.param = Eigen::Vector3d(x[0], x[1], x[2]);
    out.step.landmarks.push_back(ls);
  }
  return out;
}

}  // namespace

CeresWindowResult solveWindowWithCeres(const WindowSnapshot& w, const CeresWindowOptions& opt) {
  if (w.prior_representation != Representation::kSqrt && !w.prior_blocks.empty()) {
    throw InputError("", 0, "Ceres peer: the window's prior must be in square-root storage");
  }
  CeresWindowProblem p;
  addStates(w, p);
  addReprojections(w, p);
  addImuAndPrior(w, p);
  ceres::Solver::Summary summary;
  ceres::Solve(solverOptions(w.config, opt, p.ordering), p.problem.get(), &summary);
  return resultOf(summary, w, p);
}

}  // namespace marglab
