#include "core/ceres_marg/manifold_minus.h"

#include <ceres/product_manifold.h>
#include <fmt/core.h>

#include <Eigen/Core>
#include <typeinfo>
#include <utility>
#include <vector>

namespace marglab::ceres_marg {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Minus affine in y: δ = Minus(y, x̌) and ∂δ/∂y = MinusJacobian (constant).
class AffineDifference final : public BlockDifference {
 public:
  // manifold == nullptr: Euclidean of dimension size.
  AffineDifference(const ceres::Manifold* manifold, int size)
      : manifold_(manifold),
        ambient_(size),
        tangent_(manifold ? manifold->TangentSize() : size),
        D_(tangent_, ambient_) {
    if (manifold_ == nullptr) {
      D_.setIdentity();
    } else {
      const std::vector<double> x(static_cast<std::size_t>(ambient_), 0.0);
      ok_ = manifold_->MinusJacobian(x.data(), D_.data());
    }
  }
  int ambientSize() const override { return ambient_; }
  int tangentSize() const override { return tangent_; }
  bool evaluate(const double* y, const double* x_lin, double* delta, double* D_y) const override {
    if (!ok_) return false;
    if (manifold_ == nullptr) {
      for (int i = 0; i < ambient_; ++i) delta[i] = y[i] - x_lin[i];
    } else if (!manifold_->Minus(y, x_lin, delta)) {
      return false;
    }
    if (D_y != nullptr) Eigen::Map<RowMatrix>(D_y, tangent_, ambient_) = D_;
    return true;
  }

 private:
  const ceres::Manifold* manifold_;
  int ambient_;
  int tangent_;
  RowMatrix D_;
  bool ok_ = true;
};

template <bool kWFirst>
class QuaternionDifference final : public BlockDifference {
 public:
  int ambientSize() const override { return 4; }
  int tangentSize() const override { return 3; }
  bool evaluate(const double* y, const double* x_lin, double* delta, double* D_y) const override {
    if (D_y == nullptr) {
      quaternionMinus<kWFirst>(y, x_lin, delta);
      return true;
    }
    using Jet = ceres::Jet<double, 4>;
    Jet y_jet[4];
    for (int i = 0; i < 4; ++i) y_jet[i] = Jet(y[i], i);
    Jet delta_jet[3];
    quaternionMinus<kWFirst>(y_jet, x_lin, delta_jet);
    for (int r = 0; r < 3; ++r) {
      delta[r] = delta_jet[r].a;
      for (int c = 0; c < 4; ++c) D_y[r * 4 + c] = delta_jet[r].v[c];
    }
    return true;
  }
};

// A user manifold with DifferentiableMinus.
class ProvidedDifference final : public BlockDifference {
 public:
  ProvidedDifference(const ceres::Manifold* manifold, const DifferentiableMinus* minus)
      : manifold_(manifold), minus_(minus) {}
  int ambientSize() const override { return manifold_->AmbientSize(); }
  int tangentSize() const override { return manifold_->TangentSize(); }
  bool evaluate(const double* y, const double* x_lin, double* delta, double* D_y) const override {
    if (!manifold_->Minus(y, x_lin, delta)) return false;
    return D_y == nullptr || minus_->MinusJacobianWrtY(y, x_lin, D_y);
  }

 private:
  const ceres::Manifold* manifold_;
  const DifferentiableMinus* minus_;
};

// Block-diagonal composition of two differences (ProductManifold<A, B>).
class ProductDifference final : public BlockDifference {
 public:
  ProductDifference(std::unique_ptr<BlockDifference> a, std::unique_ptr<BlockDifference> b)
      : a_(std::move(a)), b_(std::move(b)) {}
  int ambientSize() const override { return a_->ambientSize() + b_->ambientSize(); }
  int tangentSize() const override { return a_->tangentSize() + b_->tangentSize(); }
  bool evaluate(const double* y, const double* x_lin, double* delta, double* D_y) const override {
    const int na = a_->ambientSize(), ta = a_->tangentSize();
    const int nb = b_->ambientSize(), tb = b_->tangentSize();
    RowMatrix D_a(ta, na), D_b(tb, nb);
    const bool want = D_y != nullptr;
    if (!a_->evaluate(y, x_lin, delta, want ? D_a.data() : nullptr)) return false;
    if (!b_->evaluate(y + na, x_lin + na, delta + ta, want ? D_b.data() : nullptr)) return false;
    if (want) {
      Eigen::Map<RowMatrix> D(D_y, ta + tb, na + nb);
      D.setZero();
      D.topLeftCorner(ta, na) = D_a;
      D.bottomRightCorner(tb, nb) = D_b;
    }
    return true;
  }

 private:
  std::unique_ptr<BlockDifference> a_;
  std::unique_ptr<BlockDifference> b_;
};

// Leaf manifolds a ProductManifold may be made of, default constructible.
template <typename M>
std::unique_ptr<BlockDifference> leafDifference() {
  if constexpr (std::is_same_v<M, ceres::QuaternionManifold>) {
    return std::make_unique<QuaternionDifference<true>>();
  } else if constexpr (std::is_same_v<M, ceres::EigenQuaternionManifold>) {
    return std::make_unique<QuaternionDifference<false>>();
  } else {
    static const M kEuclidean;  // EuclideanManifold<N>: stateless
    return std::make_unique<AffineDifference>(&kEuclidean, kEuclidean.AmbientSize());
  }
}

template <typename A, typename... Bs>
std::unique_ptr<BlockDifference> productWithFirst(const ceres::Manifold* manifold) {
  std::unique_ptr<BlockDifference> result;
  ((result == nullptr && dynamic_cast<const ceres::ProductManifold<A, Bs>*>(manifold) != nullptr
        ? (result = std::make_unique<ProductDifference>(leafDifference<A>(), leafDifference<Bs>()),
           0)
        : 0),
   ...);
  return result;
}

template <typename... Leaves>
std::unique_ptr<BlockDifference> productDifference(const ceres::Manifold* manifold) {
  std::unique_ptr<BlockDifference> result;
  ((result == nullptr ? (result = productWithFirst<Leaves, Leaves...>(manifold), 0) : 0), ...);
  return result;
}

template <int... Sizes>
bool isEuclidean(const ceres::Manifold* manifold, std::integer_sequence<int, Sizes...>) {
  return dynamic_cast<const ceres::EuclideanManifold<ceres::DYNAMIC>*>(manifold) != nullptr ||
         ((dynamic_cast<const ceres::EuclideanManifold<Sizes + 1>*>(manifold) != nullptr) || ...);
}

}  // namespace

std::unique_ptr<BlockDifference> makeBlockDifference(const ceres::Manifold* manifold, int size,
                                                     std::string* what) {
  if (manifold == nullptr) return std::make_unique<AffineDifference>(nullptr, size);
  if (const auto* provided = dynamic_cast<const DifferentiableMinus*>(manifold)) {
    return std::make_unique<ProvidedDifference>(manifold, provided);
  }
  if (dynamic_cast<const ceres::QuaternionManifold*>(manifold) != nullptr) {
    return std::make_unique<QuaternionDifference<true>>();
  }
  if (dynamic_cast<const ceres::EigenQuaternionManifold*>(manifold) != nullptr) {
    return std::make_unique<QuaternionDifference<false>>();
  }
  if (dynamic_cast<const ceres::SubsetManifold*>(manifold) != nullptr ||
      isEuclidean(manifold, std::make_integer_sequence<int, 16>{})) {
    return std::make_unique<AffineDifference>(manifold, size);
  }
  if (auto product = productDifference<ceres::QuaternionManifold, ceres::EigenQuaternionManifold,
                                       ceres::EuclideanManifold<1>, ceres::EuclideanManifold<2>,
                                       ceres::EuclideanManifold<3>>(manifold)) {
    return product;
  }
  if (what != nullptr) {
    const ceres::Manifold& m = *manifold;
    *what = fmt::format(
        "manifold {} (ambient {}, tangent {}) is not supported in a Markov blanket: derive it "
        "from marglab::ceres_marg::DifferentiableMinus (or use MarginalizableAutoDiffManifold)",
        typeid(m).name(), m.AmbientSize(), m.TangentSize());
  }
  return nullptr;
}

}  // namespace marglab::ceres_marg
