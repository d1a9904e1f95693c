#include "core/frontend/camera_model.h"

#include <fmt/core.h>

#include <cmath>

#include "core/common/error.h"
#include "core/common/scalar.h"

namespace marglab {

const char* distortionModelName(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadTan:
      return "radtan";
    case DistortionModel::kEquidistant:
      return "equidistant";
  }
  return "?";
}

namespace {

constexpr int kMaxIterations = 20;
// Equidistant rays beyond ~80° from the axis map far outside any pinhole image.
constexpr double kMaxThetaRad = 1.4;

// Converged when the residual is a few rounding errors of x_d (relative to its size, ≥ 1).
template <typename Scalar>
Scalar solveTolerance(Scalar scale) {
  return Scalar(64) * NumericTraits<Scalar>::kEpsilon * std::max(Scalar(1), scale);
}

template <typename Scalar>
Eigen::Matrix<Scalar, 2, 1> radtan(const std::array<Scalar, 4>& k,
                                   const Eigen::Matrix<Scalar, 2, 1>& p,
                                   Eigen::Matrix<Scalar, 2, 2>* J) {
  const Scalar x = p.x(), y = p.y();
  const Scalar r2 = x * x + y * y;
  const Scalar rho = Scalar(1) + r2 * (k[0] + k[1] * r2);
  const Scalar k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
  if (J != nullptr) {
    const Scalar drho = k1 + Scalar(2) * k2 * r2;  // ∂ρ/∂(r²)
    (*J)(0, 0) = rho + Scalar(2) * x * drho * x + Scalar(2) * p1 * y + Scalar(6) * p2 * x;
    (*J)(0, 1) = Scalar(2) * y * drho * x + Scalar(2) * p1 * x + Scalar(2) * p2 * y;
    (*J)(1, 0) = Scalar(2) * x * drho * y + Scalar(2) * p1 * x + Scalar(2) * p2 * y;
    (*J)(1, 1) = rho + Scalar(2) * y * drho * y + Scalar(6) * p1 * y + Scalar(2) * p2 * x;
  }
  return {rho * x + Scalar(2) * p1 * x * y + p2 * (r2 + Scalar(2) * x * x),
          rho * y + p1 * (r2 + Scalar(2) * y * y) + Scalar(2) * p2 * x * y};
}

// θ_d(θ) and its derivative for the Kannala–Brandt polynomial.
template <typename Scalar>
Scalar kbTheta(const std::array<Scalar, 4>& k, Scalar theta, Scalar* dtheta_d) {
  const Scalar t2 = theta * theta;
  const Scalar poly = Scalar(1) + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])));
  if (dtheta_d != nullptr) {
    *dtheta_d = Scalar(1) +
                t2 * (Scalar(3) * k[0] +
                      t2 * (Scalar(5) * k[1] + t2 * (Scalar(7) * k[2] + t2 * Scalar(9) * k[3])));
  }
  return theta * poly;
}

template <typename Scalar>
Eigen::Matrix<Scalar, 2, 1> equidistant(const std::array<Scalar, 4>& k,
                                        const Eigen::Matrix<Scalar, 2, 1>& p,
                                        Eigen::Matrix<Scalar, 2, 2>* J) {
  const Scalar r = p.norm();
  // Below √ε the series θ_d/r = 1 + O(r²) is exact to rounding: the identity.
  if (r < NumericTraits<Scalar>::sqrtEpsilon()) {
    if (J != nullptr) J->setIdentity();
    return p;
  }
  const Scalar theta = std::atan(r);
  Scalar dtd_dtheta = 0;
  const Scalar theta_d = kbTheta(k, theta, &dtd_dtheta);
  const Scalar s = theta_d / r;
  if (J != nullptr) {
    const Scalar ds_dr = (dtd_dtheta / (Scalar(1) + r * r) * r - theta_d) / (r * r);
    *J = s * Eigen::Matrix<Scalar, 2, 2>::Identity() + (ds_dr / r) * p * p.transpose();
  }
  return s * p;
}

template <typename Scalar>
bool undistortRadTan(const CameraModel<Scalar>& cam, const Eigen::Matrix<Scalar, 2, 1>& x_d,
                     Eigen::Matrix<Scalar, 2, 1>* x) {
  Eigen::Matrix<Scalar, 2, 1> p = x_d;
  const Scalar tol = solveTolerance(x_d.norm());
  for (int it = 0; it < kMaxIterations; ++it) {
    Eigen::Matrix<Scalar, 2, 2> J;
    const Eigen::Matrix<Scalar, 2, 1> r = radtan(cam.k, p, &J) - x_d;
    if (!r.allFinite()) return false;
    if (r.norm() <= tol) {
      *x = p;
      return true;
    }
    p -= J.partialPivLu().solve(r);
  }
  // Accept the last iterate only if it converged in its final step.
  if ((radtan(cam.k, p, static_cast<Eigen::Matrix<Scalar, 2, 2>*>(nullptr)) - x_d).norm() > tol)
    return false;
  *x = p;
  return true;
}

template <typename Scalar>
bool undistortEquidistant(const CameraModel<Scalar>& cam, const Eigen::Matrix<Scalar, 2, 1>& x_d,
                          Eigen::Matrix<Scalar, 2, 1>* x) {
  const Scalar r_d = x_d.norm();
  if (r_d < NumericTraits<Scalar>::sqrtEpsilon()) {
    *x = x_d;
    return true;
  }
  Scalar theta = r_d;  // θ_d ≈ θ: the polynomial is a small correction
  const Scalar tol = solveTolerance(r_d);
  for (int it = 0; it < kMaxIterations; ++it) {
    Scalar dtd = 0;
    const Scalar f = kbTheta(cam.k, theta, &dtd) - r_d;
    if (!std::isfinite(f) || !(dtd > Scalar(0))) return false;  // θ_d not monotone here
    if (std::abs(f) <= tol) break;
    theta -= f / dtd;
    if (it == kMaxIterations - 1) return false;
  }
  if (!(theta >= Scalar(0)) || theta >= Scalar(kMaxThetaRad)) return false;
  *x = (std::tan(theta) / r_d) * x_d;
  return true;
}

}  // namespace

template <typename Scalar>
typename CameraModel<Scalar>::Vec2 CameraModel<Scalar>::distortNormalized(const Vec2& x,
                                                                          Mat2* J) const {
  switch (model) {
    case DistortionModel::kRadTan:
      return radtan(k, x, J);
    case DistortionModel::kEquidistant:
      return equidistant(k, x, J);
    case DistortionModel::kNone:
      break;
  }
  if (J != nullptr) J->setIdentity();
  return x;
}

template <typename Scalar>
bool CameraModel<Scalar>::undistortNormalized(const Vec2& x_d, Vec2* x) const {
  if (!x_d.allFinite()) return false;
  switch (model) {
    case DistortionModel::kRadTan:
      return undistortRadTan(*this, x_d, x);
    case DistortionModel::kEquidistant:
      return undistortEquidistant(*this, x_d, x);
    case DistortionModel::kNone:
      break;
  }
  *x = x_d;
  return true;
}

template <typename Scalar>
typename CameraModel<Scalar>::Vec2 CameraModel<Scalar>::distortPixel(const Vec2& uv) const {
  const Vec2 x_d = distortNormalized(Vec2((uv.x() - cx) / fx, (uv.y() - cy) / fy));
  return {fx * x_d.x() + cx, fy * x_d.y() + cy};
}

template <typename Scalar>
bool CameraModel<Scalar>::undistortPixel(const Vec2& uv_d, Vec2* uv) const {
  Vec2 x;
  if (!undistortNormalized(Vec2((uv_d.x() - cx) / fx, (uv_d.y() - cy) / fy), &x)) return false;
  *uv = Vec2(fx * x.x() + cx, fy * x.y() + cy);
  return true;
}

template <typename Scalar>
CameraModel<Scalar> cameraModelFromCalib(const CameraCalib& calib, const std::string& source) {
  CameraModel<Scalar> cam;
  cam.fx = static_cast<Scalar>(calib.fx);
  cam.fy = static_cast<Scalar>(calib.fy);
  cam.cx = static_cast<Scalar>(calib.cx);
  cam.cy = static_cast<Scalar>(calib.cy);
  cam.width = calib.width;
  cam.height = calib.height;
  const std::string& name = calib.distortion_model;
  if (name == "none" || name.empty()) {
    cam.model = DistortionModel::kNone;
    return cam;
  }
  if (name == "radtan" || name == "radial-tangential") {
    cam.model = DistortionModel::kRadTan;
  } else if (name == "equidistant" || name == "kannala-brandt") {
    cam.model = DistortionModel::kEquidistant;
  } else {
    throw InputError(source, 0,
                     fmt::format("unknown distortion model '{}' (expected radtan, equidistant "
                                 "or none)",
                                 name));
  }
  // Kalibr's radtan may carry a fifth coefficient k3; EuRoC and TUM-VI have exactly four.
  if (calib.distortion.size() != 4) {
    throw InputError(source, 0,
                     fmt::format("expected 4 distortion coefficients for {}, found {}", name,
                                 calib.distortion.size()));
  }
  for (int i = 0; i < 4; ++i) cam.k[i] = static_cast<Scalar>(calib.distortion[i]);
  return cam;
}

#define MARGLAB_CAMERA_MODEL(S)   \
  template struct CameraModel<S>; \
  template CameraModel<S> cameraModelFromCalib<S>(const CameraCalib&, const std::string&);
MARGLAB_INSTANTIATE(MARGLAB_CAMERA_MODEL)
#undef MARGLAB_CAMERA_MODEL

}  // namespace marglab
