// The engine's checks of the numbers it is given, each written once: the
// shape and finiteness of arrays, rotations and rigid poses. Every failure
// throws std::invalid_argument (Python's ValueError) with a message that
// names the argument and says what is wrong.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

namespace coopsim {

// Numbers as the engine takes a table: the values in row-major order and the
// shape (empty: one number).
struct Array {
  std::vector<double> values;
  std::vector<std::ptrdiff_t> shape;
  int ndim() const { return static_cast<int>(shape.size()); }
};

// A table of numbers read in place (row-major), which the caller keeps alive and unchanged during the
// call: how the bindings hand the engine large inputs without a copy.
struct ArrayView {
  const double* values = nullptr;
  std::vector<std::ptrdiff_t> shape;
  int ndim() const { return static_cast<int>(shape.size()); }
  std::size_t size() const {
    std::size_t n = 1;
    for (std::ptrdiff_t e : shape) n *= static_cast<std::size_t>(e);
    return n;
  }
};

// A shape as Python prints it: "(3, 4)", "(3,)", "()".
std::string shape_string(const std::ptrdiff_t* shape, int ndim);
// Unless `shape` (ndim extents) is `expected` (-1: any extent, printed N):
// "wrong shape for NAME: expected (N, 4), got (3, 5)".
void check_shape(const std::ptrdiff_t* shape, int ndim, std::initializer_list<std::ptrdiff_t> expected,
                 const char* name);
inline void check_shape(const Array& a, std::initializer_list<std::ptrdiff_t> expected, const char* name) {
  check_shape(a.shape.data(), a.ndim(), expected, name);
}
// Whether the count values at p are all finite (no NaN, no inf).
bool all_finite(const double* p, std::size_t count);
// Unless the `count` values at p are finite: "NAME must be finite (got NaN or inf)".
void check_finite(const double* p, std::size_t count, const char* name);
inline void check_finite(double x, const char* name) { check_finite(&x, 1, name); }
inline void check_finite(const Array& a, const char* name) { check_finite(a.values.data(), a.values.size(), name); }
inline void check_shape(const ArrayView& a, std::initializer_list<std::ptrdiff_t> expected, const char* name) {
  check_shape(a.shape.data(), a.ndim(), expected, name);
}
inline void check_finite(const ArrayView& a, const char* name) { check_finite(a.values, a.size(), name); }
// The n finite values of a (n,) table: "wrong shape for NAME: ...", "NAME must be finite ...".
Eigen::VectorXd vector_of(const Array& a, std::ptrdiff_t n, const char* name);
// One value per joint: `a` is one number (every joint) or (n,), finite; out gets n values.
std::vector<double> per_joint(const Array& a, int n, const char* name);

// R is a rotation: finite, orthonormal to 1e-9, determinant +1.
bool is_rotation(const Eigen::Matrix3d& R);
// Unless R is a rotation: "NAME must be a rotation matrix (orthonormal, determinant +1)".
void check_rotation(const Eigen::Matrix3d& R, const std::string& name);
// Unless T is a finite rigid transform (a rotation and a translation, last
// row 0 0 0 1): "NAME must be a homogeneous transform (last row 0 0 0 1)",
// "NAME must be a rigid transform (orthonormal rotation)".
void check_rigid(const Eigen::Matrix4d& T, const std::string& name);
// What keeps T from being such a transform (check_rigid's message without the name), or nullptr.
const char* rigid_problem(const Eigen::Matrix4d& T);
// The rigid transform of 16 row-major numbers (checked by check_rigid).
Eigen::Isometry3d rigid_pose(const double* row_major, const std::string& name);
// The same, the name made only for the message (a table's "NAME[k]" costs nothing when T is rigid).
Eigen::Isometry3d rigid_pose(const double* row_major, const std::function<std::string()>& name);
// The rigid transforms of a (N, 4, 4) table of finite numbers, the k-th named "NAME[k]".
std::vector<Eigen::Isometry3d> rigid_poses(const Array& a, const char* name);
// The rigid transform of a (4, 4) table.
Eigen::Isometry3d rigid_pose(const Array& a, const char* name);
// Unless I (kg m^2) is a rigid body's inertia tensor: "NAME must be finite", "NAME must be symmetric",
// "NAME must be positive semi-definite (principal moments >= 0 kg m^2), got principal moments [a, b, c]"
// (symmetry and the moments to 1e-9 of its largest entry).
void check_inertia(const Eigen::Matrix3d& I, const std::string& name);

}  // namespace coopsim
