#pragma once
// Shared helpers of the linalg tests: seeded random matrices and scalar-dependent tolerances.

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include <algorithm>
#include <numeric>
#include <random>
#include <string>

#include "core/common/eigen_types.h"
#include "core/common/scalar.h"

namespace marglab::test {

inline MatXd randomGaussian(std::mt19937_64& rng, int rows, int cols) {
  std::normal_distribution<double> normal(0.0, 1.0);
  MatXd M(rows, cols);
  for (int j = 0; j < cols; ++j) {
    for (int i = 0; i < rows; ++i) M(i, j) = normal(rng);
  }
  return M;
}

// Relative Frobenius error ‖a − b‖ / ‖b‖.
template <typename A, typename B>
double relError(const A& a, const B& b) {
  return (a.template cast<double>() - b.template cast<double>()).norm() /
         b.template cast<double>().norm();
}

using Scalars = ::testing::Types<float, double>;

struct ScalarName {
  template <typename T>
  static std::string GetName(int) {
    return std::string(NumericTraits<T>::name());
  }
};

template <typename Scalar>
double eps() {
  return static_cast<double>(NumericTraits<Scalar>::kEpsilon);
}

}  // namespace marglab::test
