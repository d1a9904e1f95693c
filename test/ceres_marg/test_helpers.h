#pragma once
// Shared fixtures of the ceres_marg tests: linear factors and random linear-Gaussian graphs.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <random>
#include <vector>

namespace marglab::ceres_marg::test {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// r = Σ_k A_k x_k − z.
class LinearFactor final : public ceres::CostFunction {
 public:
  LinearFactor(std::vector<Eigen::MatrixXd> A, Eigen::VectorXd z)
      : A_(std::move(A)), z_(std::move(z)) {
    set_num_residuals(static_cast<int>(z_.size()));
    for (const auto& A_k : A_)
      mutable_parameter_block_sizes()->push_back(static_cast<int>(A_k.cols()));
  }
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::Map<Eigen::VectorXd> r(residuals, z_.size());
    r = -z_;
    for (std::size_t k = 0; k < A_.size(); ++k) {
      r += A_[k] * Eigen::Map<const Eigen::VectorXd>(x[k], A_[k].cols());
      if (jacobians != nullptr && jacobians[k] != nullptr) {
        Eigen::Map<RowMatrix> J(jacobians[k], A_[k].rows(), A_[k].cols());
        J = A_[k];
      }
    }
    return true;
  }

 private:
  std::vector<Eigen::MatrixXd> A_;
  Eigen::VectorXd z_;
};

// A random connected linear-Gaussian factor graph on Euclidean blocks: a unary factor on block 0
// (fixes the gauge), a chain of pairwise factors plus random extra pairs. Values live in x.
struct LinearGraph {
  std::vector<int> sizes;
  std::vector<std::vector<double>> x;  // storage of the blocks (stable addresses)
  struct Factor {
    std::vector<int> blocks;
    std::vector<Eigen::MatrixXd> A;
    Eigen::VectorXd z;
  };
  std::vector<Factor> factors;

  static LinearGraph random(int num_blocks, int extra_pairs, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    const auto randn = [&](int r, int c) {
      Eigen::MatrixXd M(r, c);
      for (int i = 0; i < r; ++i) {
        for (int j = 0; j < c; ++j) M(i, j) = normal(rng);
      }
      return M;
    };
    LinearGraph g;
    for (int b = 0; b < num_blocks; ++b) {
      const int size = 2 + b % 2;
      g.sizes.push_back(size);
      const Eigen::VectorXd v = randn(size, 1);
      g.x.emplace_back(v.data(), v.data() + size);
    }
    const auto addFactor = [&](std::vector<int> blocks) {
      const int rows = 3;
      Factor f;
      f.blocks = blocks;
      for (int b : blocks)
        f.A.push_back(randn(rows, g.sizes[b]) + Eigen::MatrixXd::Identity(rows, g.sizes[b]));
      f.z = randn(rows, 1);
      g.factors.push_back(f);
    };
    addFactor({0});
    for (int b = 0; b + 1 < num_blocks; ++b) addFactor({b, b + 1});
    std::uniform_int_distribution<int> pick(0, num_blocks - 1);
    for (int e = 0; e < extra_pairs; ++e) {
      const int a = pick(rng), b = pick(rng);
      if (a != b) addFactor({a, b});
    }
    return g;
  }

  void addTo(ceres::Problem* problem) {
    for (std::size_t b = 0; b < x.size(); ++b) problem->AddParameterBlock(x[b].data(), sizes[b]);
    for (const Factor& f : factors) {
      std::vector<double*> blocks;
      for (int b : f.blocks) blocks.push_back(x[b].data());
      problem->AddResidualBlock(new LinearFactor(f.A, f.z), nullptr, blocks);
    }
  }

  // Offsets of each block in the stacked state.
  std::vector<int> offsets() const {
    std::vector<int> o{0};
    for (int s : sizes) o.push_back(o.back() + s);
    return o;
  }

  // Dense J and f (r = J x − f_0 form: returns J and the constant so that r(x) = J x + c).
  void dense(Eigen::MatrixXd* J, Eigen::VectorXd* c) const {
    const std::vector<int> o = offsets();
    int rows = 0;
    for (const Factor& f : factors) rows += static_cast<int>(f.z.size());
    J->setZero(rows, o.back());
    c->resize(rows);
    int row = 0;
    for (const Factor& f : factors) {
      for (std::size_t k = 0; k < f.blocks.size(); ++k) {
        J->block(row, o[f.blocks[k]], f.z.size(), sizes[f.blocks[k]]) = f.A[k];
      }
      c->segment(row, f.z.size()) = -f.z;
      row += static_cast<int>(f.z.size());
    }
  }
};

}  // namespace marglab::ceres_marg::test
