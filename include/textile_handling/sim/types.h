// Numeric types shared by every ROS-free core of textile_handling.
//
// SI units everywhere (m, kg, s, N, J); z points up and gravity acts along -z.
// Keep this header light: it is included by every hot kernel.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace textile_handling {

using Real = double;
using Vec2 = Eigen::Matrix<Real, 2, 1>;
using Vec3 = Eigen::Matrix<Real, 3, 1>;
using Mat3 = Eigen::Matrix<Real, 3, 3>;
using VecX = Eigen::Matrix<Real, Eigen::Dynamic, 1>;
using Index = std::int32_t;

// Standard gravity [m/s^2].
constexpr Real kGravity = 9.80665;
// One gram-force in newton (KES data are given in gf).
constexpr Real kGramForce = 9.80665e-3;
constexpr Real kPi = 3.14159265358979323846;

// Map node i of a stacked DOF vector (3 DOFs per node) to a 3-vector view.
inline Eigen::Map<Vec3> node3(VecX& x, Index i) { return Eigen::Map<Vec3>(x.data() + 3 * i); }
inline Eigen::Map<const Vec3> node3(const VecX& x, Index i) { return Eigen::Map<const Vec3>(x.data() + 3 * i); }

}  // namespace textile_handling
