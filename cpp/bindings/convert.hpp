// Conversions between numpy arrays and the engine's Eigen types, with the
// argument checks of the Python API: every failure is a ValueError that names
// the argument and says what was wrong.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <optional>
#include <string>
#include <vector>

#include "coopsim/checks.hpp"
#include "coopsim/robot.hpp"

namespace coopsim::py_convert {

namespace py = pybind11;
using Arr = py::array_t<double, py::array::c_style | py::array::forcecast>;

inline Arr as_array(const py::handle& obj, const char* name) {
  if (obj.is_none()) throw py::value_error(std::string(name) + " must be an array of numbers, got None");
  // real numbers only: forcecast would drop imaginary parts (with a mere
  // warning) and call float() on arbitrary objects. ensure() returns a null
  // handle (with a Python error set) when numpy cannot make an array of obj
  py::array raw = py::array::ensure(obj);
  const char kind = raw.ptr() ? raw.dtype().kind() : 'O';
  if (!raw.ptr()) PyErr_Clear();
  if (kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b') {
    std::string got = kind == 'c' ? "complex" : raw.ptr() ? std::string(py::str(raw.dtype())) : "not an array";
    throw py::value_error(std::string(name) + " must be an array of real numbers, got " + got);
  }
  Arr a = Arr::ensure(raw);
  if (!a.ptr()) {
    PyErr_Clear();
    throw py::value_error(std::string(name) + " must be an array of real numbers");
  }
  return a;
}

// One finite real number (a Python or numpy scalar, or a 0-d array).
inline double scalar_arg(const py::handle& obj, const char* name) {
  if (obj.is_none() || py::isinstance<py::str>(obj))
    throw py::value_error(std::string(name) + " must be a real number");
  py::array raw = py::array::ensure(obj);
  if (!raw.ptr()) PyErr_Clear();
  if (!raw.ptr() || raw.ndim() != 0) throw py::value_error(std::string(name) + " must be a real number");
  const char kind = raw.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b')
    throw py::value_error(std::string(name) + " must be a real number, got " + std::string(py::str(raw.dtype())));
  const double v = Arr::ensure(raw).data()[0];
  check_finite(v, name);
  return v;
}

// An integer (Python int or numpy integer) in [lo, hi].
inline long index_arg(const py::handle& obj, const char* name, long lo, long hi) {
  const std::string range = " in " + std::to_string(lo) + " .. " + std::to_string(hi);
  if (PyBool_Check(obj.ptr()) || !PyIndex_Check(obj.ptr()))
    throw py::value_error(std::string(name) + " must be an integer" + range);
  int overflow = 0;
  py::object idx = py::reinterpret_steal<py::object>(PyNumber_Index(obj.ptr()));
  if (!idx) {
    // e.g. an array that cannot be one integer: a bad value, like the others here
    PyErr_Clear();
    throw py::value_error(std::string(name) + " must be an integer" + range + ", got " + std::string(py::repr(obj)));
  }
  const long v = PyLong_AsLongAndOverflow(idx.ptr(), &overflow);
  if (overflow || v < lo || v > hi)
    throw py::value_error(std::string(name) + " must be an integer" + range + ", got " + std::string(py::repr(obj)));
  return v;
}

inline std::string shape_str(const Arr& a) { return shape_string(a.shape(), static_cast<int>(a.ndim())); }

// A C-contiguous array of the given shape (-1: any extent) of finite numbers.
inline Arr array(const py::handle& obj, std::initializer_list<std::ptrdiff_t> shape, const char* name,
                 bool finite = true) {
  Arr a = as_array(obj, name);
  check_shape(a.shape(), static_cast<int>(a.ndim()), shape, name);
  if (finite) coopsim::check_finite(a.data(), static_cast<size_t>(a.size()), name);
  return a;
}

// A 1-D array of exactly n finite numbers, as Eigen vector type V.
template <class V>
V vector_arg(const py::handle& obj, py::ssize_t n, const char* name) {
  return Eigen::Map<const V>(array(obj, {n}, name).data(), n);
}

inline VecN vec(const py::handle& obj, int n, const char* name) { return vector_arg<VecN>(obj, n, name); }

inline Eigen::VectorXd vecx(const py::handle& obj, py::ssize_t n, const char* name) {
  return vector_arg<Eigen::VectorXd>(obj, n, name);
}

// The numbers of obj, copied as the engine takes a table (its checks are the engine's).
inline Array table(const py::handle& obj, const char* name) {
  Arr a = as_array(obj, name);
  return Array{{a.data(), a.data() + a.size()}, {a.shape(), a.shape() + a.ndim()}};
}

// The numbers of obj read in place (a copy only where numpy must convert it): `keep` holds the array,
// and must outlive the view.
inline ArrayView table_view(const py::handle& obj, const char* name, Arr& keep) {
  keep = as_array(obj, name);
  return ArrayView{keep.data(), {keep.shape(), keep.shape() + keep.ndim()}};
}

inline std::optional<Array> optional_table(const py::handle& obj, const char* name) {
  if (obj.is_none()) return std::nullopt;
  return table(obj, name);
}

// A rigid transform from 16 numbers, row-major (`name` names it in errors).
inline Eigen::Isometry3d pose_from(const double* data, const std::string& name) { return rigid_pose(data, name); }

inline Eigen::Isometry3d pose(const py::handle& obj, const char* name) {
  return rigid_pose(array(obj, {4, 4}, name, false).data(), name);
}

// Wrenches on a robot (`name`: the argument): a Wrench, a list or tuple of
// them (may be empty), or a (6,) wrench [f; m] at the tool centre point.
inline std::vector<ExternalWrench> wrenches_arg(const py::object& obj, const char* name) {
  if (py::isinstance<ExternalWrench>(obj)) return {obj.cast<ExternalWrench>()};
  if (py::isinstance<py::list>(obj) || py::isinstance<py::tuple>(obj)) {
    std::vector<ExternalWrench> out;
    for (py::handle h : obj) {
      if (!py::isinstance<ExternalWrench>(h)) break;
      out.push_back(h.cast<ExternalWrench>());
    }
    if (out.size() == py::len(obj)) return out;
  }
  ExternalWrench w;
  w.at_tool = true;
  Arr a = array(obj, {6}, name);
  w.wrench = Eigen::Map<const Vec6>(a.data());
  return {w};
}

// Issues a RuntimeWarning with `message` unless it is empty (an error if
// warnings are errors).
inline void warn_if(const std::string& message) {
  if (message.empty()) return;
  if (PyErr_WarnEx(PyExc_RuntimeWarning, message.c_str(), 1) != 0) throw py::error_already_set();
}

// Pickling by a call: `get` gives (arguments, keywords) of T's constructor (or
// of its static method `factory`), which unpickling calls again, so that a
// pickled object is checked as when it was made.
template <class T, class Get>
auto pickle_by_call(Get get, const char* factory = nullptr) {
  return py::pickle(get, [factory](const py::tuple& s) {
    py::object f = py::type::of<T>();
    if (factory) f = f.attr(factory);
    return f(*s[0], **s[1]).template cast<T>();
  });
}

inline py::array_t<double> to_numpy(const Eigen::Isometry3d& T);

template <class Derived>
py::array_t<double> to_numpy(const Eigen::MatrixBase<Derived>& m) {
  // vectors by type give 1-D arrays; matrices stay 2-D even with one column
  if constexpr (Derived::ColsAtCompileTime == 1) {
    py::array_t<double> out(m.rows());
    double* p = out.mutable_data();
    for (Eigen::Index i = 0; i < m.rows(); ++i) p[i] = m(i, 0);
    return out;
  }
  py::array_t<double> out({m.rows(), m.cols()});
  double* p = out.mutable_data();
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) p[i * m.cols() + j] = m(i, j);
  return out;
}

// Converts a computed result, refusing to hand back NaN or inf: inputs that
// are finite but far out of range (e.g. a prismatic joint at 1e200 m) would
// otherwise yield a silently wrong answer.
template <class Derived>
py::array_t<double> checked(const Eigen::MatrixBase<Derived>& m, const char* what) {
  if (!m.allFinite())
    throw py::value_error(std::string(what) + ": result is not finite for this input (values out of range?)");
  return to_numpy(m);
}

inline py::array_t<double> to_numpy(const Array& a) {
  py::array_t<double> out(std::vector<py::ssize_t>(a.shape.begin(), a.shape.end()));
  std::copy(a.values.begin(), a.values.end(), out.mutable_data());
  return out;
}

inline py::object to_numpy(const std::optional<Array>& a) { return a ? py::object(to_numpy(*a)) : py::none(); }

inline py::array_t<double> to_numpy(const Eigen::Isometry3d& T) {
  py::array_t<double> out({4, 4});
  Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(out.mutable_data()) = T.matrix();
  return out;
}

// A controller's model argument: a Robot (copied) or None.
inline std::shared_ptr<const Robot> model_arg(const py::object& model) {
  if (model.is_none()) return nullptr;
  if (!py::isinstance<Robot>(model)) throw py::value_error("model must be a coopsim.Robot or None");
  return std::make_shared<const Robot>(model.cast<const Robot&>());
}

// A controller's model for Python: a copy (the controller's model stays immutable), or None.
inline py::object model_out(const std::shared_ptr<const Robot>& m) { return m ? py::cast(*m) : py::none(); }

}  // namespace coopsim::py_convert
