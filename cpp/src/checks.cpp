#include "coopsim/checks.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace coopsim {

std::string shape_string(const std::ptrdiff_t* shape, int ndim) {
  std::ostringstream s;
  s << "(";
  for (int i = 0; i < ndim; ++i) s << (i ? ", " : "") << shape[i];
  s << (ndim == 1 ? ",)" : ")");
  return s.str();
}

void check_shape(const std::ptrdiff_t* shape, int ndim, std::initializer_list<std::ptrdiff_t> expected,
                 const char* name) {
  bool ok = ndim == static_cast<int>(expected.size());
  int i = 0;
  for (auto it = expected.begin(); ok && it != expected.end(); ++it, ++i) ok = *it < 0 || shape[i] == *it;
  if (ok) return;
  std::ostringstream s;
  s << "wrong shape for " << name << ": expected (";
  i = 0;
  for (std::ptrdiff_t e : expected) {
    s << (i++ ? ", " : "");
    if (e < 0) s << "N"; else s << e;
  }
  s << (expected.size() == 1 ? ",)" : ")") << ", got " << shape_string(shape, ndim);
  throw std::invalid_argument(s.str());
}

bool all_finite(const double* p, std::size_t count) {
  // x - x is 0 for a finite x and NaN otherwise: summed in four lanes (vectorised), no branch per value
  double acc[4] = {0.0, 0.0, 0.0, 0.0};
  std::size_t i = 0;
  for (; i + 4 <= count; i += 4)
    for (int j = 0; j < 4; ++j) acc[j] += p[i + j] - p[i + j];
  for (; i < count; ++i) acc[0] += p[i] - p[i];
  return acc[0] + acc[1] + acc[2] + acc[3] == 0.0;
}

void check_finite(const double* p, std::size_t count, const char* name) {
  if (!all_finite(p, count)) throw std::invalid_argument(std::string(name) + " must be finite (got NaN or inf)");
}

std::vector<double> per_joint(const Array& a, int n, const char* name) {
  if (a.ndim() == 0 && a.values.size() == 1) {
    check_finite(a, name);
    return std::vector<double>(n, a.values[0]);
  }
  check_shape(a, {n}, name);
  check_finite(a, name);
  return a.values;
}

Eigen::VectorXd vector_of(const Array& a, std::ptrdiff_t n, const char* name) {
  check_shape(a, {n}, name);
  check_finite(a, name);
  return Eigen::Map<const Eigen::VectorXd>(a.values.data(), n);
}

bool is_rotation(const Eigen::Matrix3d& R) {
  return R.allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-9 &&
         R.determinant() > 0;
}

void check_rotation(const Eigen::Matrix3d& R, const std::string& name) {
  if (!is_rotation(R)) throw std::invalid_argument(name + " must be a rotation matrix (orthonormal, determinant +1)");
}

const char* rigid_problem(const Eigen::Matrix4d& T) {
  if (!T.allFinite()) return "must be finite (got NaN or inf)";
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-12)
    return "must be a homogeneous transform (last row 0 0 0 1)";
  if (!is_rotation(T.topLeftCorner<3, 3>())) return "must be a rigid transform (orthonormal rotation)";
  return nullptr;
}

void check_rigid(const Eigen::Matrix4d& T, const std::string& name) {
  if (const char* problem = rigid_problem(T)) throw std::invalid_argument(name + " " + problem);
}

Eigen::Isometry3d rigid_pose(const double* row_major, const std::string& name) {
  return rigid_pose(row_major, [&name] { return name; });
}

Eigen::Isometry3d rigid_pose(const double* row_major, const std::function<std::string()>& name) {
  Eigen::Isometry3d T;
  T.matrix() = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(row_major);
  if (const char* problem = rigid_problem(T.matrix())) throw std::invalid_argument(name() + " " + problem);
  return T;
}

std::vector<Eigen::Isometry3d> rigid_poses(const Array& a, const char* name) {
  check_shape(a, {-1, 4, 4}, name);
  check_finite(a, name);
  std::vector<Eigen::Isometry3d> out;
  out.reserve(static_cast<size_t>(a.shape[0]));
  for (std::ptrdiff_t k = 0; k < a.shape[0]; ++k)
    out.push_back(rigid_pose(a.values.data() + 16 * k, [&] { return std::string(name) + "[" + std::to_string(k) + "]"; }));
  return out;
}

Eigen::Isometry3d rigid_pose(const Array& a, const char* name) {
  check_shape(a, {4, 4}, name);
  return rigid_pose(a.values.data(), name);
}

void check_inertia(const Eigen::Matrix3d& I, const std::string& name) {
  if (!I.allFinite()) throw std::invalid_argument(name + " must be finite");
  const double tol = 1e-9 * std::max(I.cwiseAbs().maxCoeff(), 1e-300);
  if ((I - I.transpose()).cwiseAbs().maxCoeff() > tol) throw std::invalid_argument(name + " must be symmetric");
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(I, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d ev = es.eigenvalues();  // ascending
  if (ev(0) < -tol) {
    std::ostringstream s;
    s.precision(6);
    s << name << " must be positive semi-definite (principal moments >= 0 kg m^2), got principal moments [" << ev(0)
      << ", " << ev(1) << ", " << ev(2) << "]";
    throw std::invalid_argument(s.str());
  }
}

}  // namespace coopsim
