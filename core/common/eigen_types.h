#pragma once
// Eigen aliases templated on the scalar type, shared by every module.

#include <Eigen/Core>

namespace marglab {

template <typename S>
using MatX = Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic>;
template <typename S>
using VecX = Eigen::Matrix<S, Eigen::Dynamic, 1>;
template <typename S, int R, int C>
using Mat = Eigen::Matrix<S, R, C>;
template <typename S, int N>
using Vec = Eigen::Matrix<S, N, 1>;
template <typename S>
using Mat3 = Eigen::Matrix<S, 3, 3>;
template <typename S>
using Vec3 = Eigen::Matrix<S, 3, 1>;

using MatXd = MatX<double>;
using VecXd = VecX<double>;

}  // namespace marglab
