// Helpers the engine's sources share; internal (not installed, not part of the API).
#pragma once

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

namespace coopsim::detail {

// Throws std::invalid_argument(msg) (Python's ValueError) unless ok.
inline void require(bool ok, const std::string& msg) {
  if (!ok) throw std::invalid_argument(msg);
}

// x as a message shows it: six significant digits.
inline std::string num(double x) {
  std::ostringstream s;
  s.precision(6);
  s << x;
  return s.str();
}

// Throws std::invalid_argument naming `name` unless x is finite and >= 0.
inline void require_nonnegative(double x, const char* name) {
  if (!std::isfinite(x) || x < 0)
    throw std::invalid_argument(std::string(name) + " must be finite and >= 0, got " + num(x));
}

// S(v), the cross-product matrix: S(v) x = v x x.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

// The rotation vector (axis times angle, rad) of a rotation matrix.
inline Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

}  // namespace coopsim::detail
