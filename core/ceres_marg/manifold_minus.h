#pragma once
// Tangent-space differences δ = Minus(y, x̌) of one parameter block and their exact Jacobian
// ∂δ/∂y at ANY y (Levine, "A Technical Primer on Marginalization ...", 2023, eqs. 13 and 56).
//
// The marginalization prior r = r̃ + R̃ · (x_b ⊟ x̌_b) is a function of x_b through ⊟ = Minus, so
// its Jacobian is R̃ · ∂Minus(y, x̌)/∂y. Ceres' Manifold::MinusJacobian(x) is that derivative only
// at y = x, i.e. at the linearization point; once the optimizer moves x_b away from x̌_b the two
// differ (for SO(3) by the inverse right Jacobian of the rotation between them). Here Minus is
// differentiated itself:
//
//   no manifold / EuclideanManifold<N> / SubsetManifold:  Minus is affine in y, ∂δ/∂y = the
//       constant selection matrix (MinusJacobian is exact everywhere);
//   QuaternionManifold (w,x,y,z) and EigenQuaternionManifold (x,y,z,w):  Ceres 2.1 defines
//       p = y ⊗ x̌*,  u = ‖p_v‖,  θ = atan2(u, p_w),  δ = (θ/u) p_v  (δ = 0 at u = 0);
//       differentiated by forward-mode automatic differentiation (ceres::Jet), with the series
//       θ/u = (1/p_w)(1 − u²/(3p_w²) + O(u⁴)) for u ≪ p_w so that the derivative at y = x̌ is
//       finite and exact (it equals MinusJacobian there);
//   ProductManifold<A, B> of the above (SE(3) as quaternion × R³ in either order, with either
//       quaternion order):  block-diagonal;
//   any other manifold that also derives from marglab::DifferentiableMinus (for instance
//       MarginalizableAutoDiffManifold below, from a functor with templated Plus/Minus):
//       its MinusJacobianWrtY.
// Any other manifold is rejected: the marginalization then fails and leaves the problem unchanged.
//
// Ceres is double precision only, so this module is not templated on the scalar type.

#include <ceres/autodiff_manifold.h>
#include <ceres/jet.h>
#include <ceres/manifold.h>

#include <memory>
#include <string>

namespace marglab::ceres_marg {

// Mixin for a user ceres::Manifold: ∂Minus(y, x)/∂y at any y, tangent × ambient, row-major.
class DifferentiableMinus {
 public:
  virtual ~DifferentiableMinus() = default;
  virtual bool MinusJacobianWrtY(const double* y, const double* x, double* jacobian) const = 0;
};

// A ceres::Manifold from a functor with templated Plus(x, δ, x⊞δ) and Minus(y, x, y⊟x) (the
// functor of ceres::AutoDiffManifold) that the marginalization supports in the Markov blanket:
// Plus/Minus and their Jacobians come from ceres::AutoDiffManifold, ∂Minus/∂y at any y from
// automatic differentiation of Functor::Minus in y.
template <typename Functor, int kAmbientSize, int kTangentSize>
class MarginalizableAutoDiffManifold final : public ceres::Manifold, public DifferentiableMinus {
 public:
  explicit MarginalizableAutoDiffManifold(Functor functor = Functor())
      : functor_(functor), manifold_(new Functor(functor)) {}
  int AmbientSize() const override { return kAmbientSize; }
  int TangentSize() const override { return kTangentSize; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    return manifold_.Plus(x, delta, x_plus_delta);
  }
  bool PlusJacobian(const double* x, double* jacobian) const override {
    return manifold_.PlusJacobian(x, jacobian);
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    return manifold_.Minus(y, x, y_minus_x);
  }
  bool MinusJacobian(const double* x, double* jacobian) const override {
    return manifold_.MinusJacobian(x, jacobian);
  }
  bool MinusJacobianWrtY(const double* y, const double* x, double* jacobian) const override {
    using Jet = ceres::Jet<double, kAmbientSize>;
    Jet y_jet[kAmbientSize];
    Jet x_jet[kAmbientSize];
    for (int i = 0; i < kAmbientSize; ++i) {
      y_jet[i] = Jet(y[i], i);
      x_jet[i] = Jet(x[i]);
    }
    Jet delta[kTangentSize];
    if (!functor_.Minus(y_jet, x_jet, delta)) return false;
    for (int r = 0; r < kTangentSize; ++r) {
      for (int c = 0; c < kAmbientSize; ++c) jacobian[r * kAmbientSize + c] = delta[r].v[c];
    }
    return true;
  }

 private:
  Functor functor_;
  ceres::AutoDiffManifold<Functor, kAmbientSize, kTangentSize> manifold_;
};

// δ = Minus(y, x̌) of one parameter block and ∂δ/∂y (tangent × ambient, row-major).
class BlockDifference {
 public:
  virtual ~BlockDifference() = default;
  virtual int ambientSize() const = 0;
  virtual int tangentSize() const = 0;
  // D_y may be null. Returns false if the manifold's Minus or its derivative fails.
  virtual bool evaluate(const double* y, const double* x_lin, double* delta, double* D_y) const = 0;
};

// The difference of a parameter block of ambient size `size` with the given manifold (nullptr:
// Euclidean). Null if the manifold is not supported; *what then names it.
std::unique_ptr<BlockDifference> makeBlockDifference(const ceres::Manifold* manifold, int size,
                                                     std::string* what);

// Ceres 2.1's quaternion Minus on any scalar type (double or ceres::Jet); Order is w-first
// (ceres) when kWFirst, else x,y,z,w (Eigen).
template <bool kWFirst, typename T>
void quaternionMinus(const T* y, const double* x, T* delta) {
  constexpr int w = kWFirst ? 0 : 3;
  constexpr int i = kWFirst ? 1 : 0;
  constexpr int j = kWFirst ? 2 : 1;
  constexpr int k = kWFirst ? 3 : 2;
  // p = y ⊗ conj(x).
  const T p_w = y[w] * x[w] + y[i] * x[i] + y[j] * x[j] + y[k] * x[k];
  const T p_x = -y[w] * x[i] + y[i] * x[w] - y[j] * x[k] + y[k] * x[j];
  const T p_y = -y[w] * x[j] + y[i] * x[k] + y[j] * x[w] - y[k] * x[i];
  const T p_z = -y[w] * x[k] - y[i] * x[j] + y[j] * x[i] + y[k] * x[w];
  const T u_sq = p_x * p_x + p_y * p_y + p_z * p_z;
  using std::atan2;
  using std::sqrt;
  T scale;
  // Below 1e-12 relative, the two-term series of atan(u/p_w)/u is exact to double precision and,
  // unlike atan2(√u², ·)/√u², differentiable at u = 0.
  if (p_w > T(0) && u_sq < T(1e-12) * p_w * p_w) {
    scale = (T(1) - u_sq / (T(3) * p_w * p_w)) / p_w;
  } else if (u_sq == T(0)) {
    scale = T(0);  // y = −x̌: Ceres' convention δ = 0
  } else {
    const T u = sqrt(u_sq);
    scale = atan2(u, p_w) / u;
  }
  delta[0] = scale * p_x;
  delta[1] = scale * p_y;
  delta[2] = scale * p_z;
}

}  // namespace marglab::ceres_marg
