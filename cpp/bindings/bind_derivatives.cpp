// The dynamics' derivatives (robot_derivatives.cpp): Robot.forward_dynamics_derivatives,
// Robot.inverse_dynamics_derivatives and the batch forward_dynamics_derivatives_batch (GIL released).
//
// The single calls are made to be called in loops (iLQR, MPC): a float64 C-contiguous argument of the
// right shape is read in place (any other goes through convert.hpp's conversion and its one-line errors),
// the results are written straight into new numpy arrays, or into the caller's own (`out=`), with no
// intermediate copies or containers.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "nogil.hpp"
#include "convert.hpp"
#include "coopsim/linearize.hpp"
#include "coopsim/robot.hpp"
#include "generated/docstrings.hpp"
#include "struct_binding.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

std::vector<ExternalWrench> wrenches_or_none(const py::object& f_ext) {
  return f_ext.is_none() ? std::vector<ExternalWrench>{} : wrenches_arg(f_ext, "f_ext");
}

VecN optional_vec(const py::object& obj, int n, const char* name) {
  return obj.is_none() ? VecN() : vec(obj, n, name);
}

const double* ptr(const VecN& v) { return v.size() ? v.data() : nullptr; }

// The data of `obj` when it is a float64 (native byte order), aligned, C-contiguous numpy array of the
// given shape (1 to 3 extents), writeable if asked; null otherwise.
double* direct(const py::handle& obj, std::initializer_list<py::ssize_t> shape, bool writeable) {
  static const auto& api = py::detail::npy_api::get();
  if (!api.PyArray_Check_(obj.ptr())) return nullptr;
  const auto* a = py::detail::array_proxy(obj.ptr());
  const auto* d = py::detail::array_descriptor_proxy(a->descr);
  int need = py::detail::npy_api::NPY_ARRAY_C_CONTIGUOUS_ | py::detail::npy_api::NPY_ARRAY_ALIGNED_;
  if (writeable) need |= py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  if (d->type_num != py::detail::npy_api::NPY_DOUBLE_ || d->byteorder != '=' || (a->flags & need) != need ||
      a->nd != static_cast<int>(shape.size()))
    return nullptr;
  int k = 0;
  for (const py::ssize_t extent : shape)
    if (a->dimensions[k++] != extent) return nullptr;
  return reinterpret_cast<double*>(a->data);
}

// An (n,) argument: read in place when it is a float64 C-contiguous array of n numbers (its values
// checked finite), else converted and checked by vec().
class VecArg {
 public:
  VecArg(const py::handle& obj, int n, const char* name) {
    if (const double* d = direct(obj, {n}, false)) {
      check_finite(d, static_cast<size_t>(n), name);
      p_ = d;
    } else {
      copy_ = vec(obj, n, name);
      p_ = copy_.data();
    }
  }
  const double* data() const { return p_; }

 private:
  VecN copy_;
  const double* p_;
};

// the three matrices (column-major) into numpy's row-major (n, n) layout, one after the other at p
void write_rows(const MatN& a, const MatN& b, const MatN& c, double* p) {
  const Eigen::Index n = a.rows();
  for (const MatN* m : {&a, &b, &c})
    for (Eigen::Index k = 0; k < n * n; ++k) *p++ = (*m)(k / n, k % n);
}

// A new (n, n) float64 array of the row-major values at src, made by numpy's own constructor.
PyObject* new_matrix(const double* src, Py_intptr_t n) {
  static const auto& api = py::detail::npy_api::get();
  Py_intptr_t dims[2] = {n, n};
  PyObject* descr = api.PyArray_DescrFromType_(py::detail::npy_api::NPY_DOUBLE_);
  PyObject* arr = descr ? api.PyArray_NewFromDescr_(api.PyArray_Type_, descr, 2, dims, nullptr, nullptr, 0, nullptr)
                        : nullptr;
  if (!arr) throw py::error_already_set();
  std::memcpy(py::detail::array_proxy(arr)->data, src, sizeof(double) * n * n);
  return arr;
}

// What an out= given is, in one line: "a tuple of 3: float64 (6, 6), float32 (6, 6) read-only, ..."
std::string describe_out(const py::object& out) {
  auto item = [](const py::handle& h) -> std::string {
    if (!py::isinstance<py::array>(h)) return Py_TYPE(h.ptr())->tp_name;
    const auto a = py::reinterpret_borrow<py::array>(h);
    std::string s = std::string(py::str(a.dtype())) + " " + std::string(py::str(py::tuple(a.attr("shape"))));
    if (!a.writeable()) s += " read-only";
    if (!(a.flags() & py::array::c_style)) s += " not C-contiguous";
    return s;
  };
  if (!PyTuple_Check(out.ptr()) && !PyList_Check(out.ptr())) return item(out);
  std::string s = std::string("a ") + Py_TYPE(out.ptr())->tp_name + " of " + std::to_string(py::len(out));
  const char* sep = ": ";
  for (const py::handle h : out) {
    s += sep + item(h);
    sep = ", ";
  }
  return s;
}

// out=: three distinct writeable float64 C-contiguous arrays of `shape` (a tuple or a list), their data
// into d; a ValueError saying what was given otherwise.
void out_arrays(const py::object& out, std::initializer_list<py::ssize_t> shape, double* d[3]) {
  PyObject* o = out.ptr();
  const bool three = (PyTuple_Check(o) && PyTuple_GET_SIZE(o) == 3) || (PyList_Check(o) && PyList_GET_SIZE(o) == 3);
  bool ok = three;
  for (int i = 0; ok && i < 3; ++i) {
    d[i] = direct(PyTuple_Check(o) ? PyTuple_GET_ITEM(o, i) : PyList_GET_ITEM(o, i), shape, true);
    ok = d[i] != nullptr;
  }
  py::ssize_t size = 1;
  std::string dims, example;
  for (const py::ssize_t extent : shape) {
    size *= extent;
    dims += (dims.empty() ? "" : ", ") + std::to_string(extent);
  }
  if (ok && size > 0) ok = d[0] != d[1] && d[1] != d[2] && d[0] != d[2];
  if (!ok)
    throw py::value_error("out must be None or three distinct writeable float64 C-contiguous arrays of shape (" +
                          dims + ") (e.g. tuple(np.empty((3, " + dims + ")))), got " + describe_out(out));
}

bool finite(const double* p, int n) { return coopsim::all_finite(p, static_cast<std::size_t>(n)); }

// The three results (row-major (n, n) each, one after the other at rows) as new arrays, or copied into
// `out` (three float64 C-contiguous writeable (n, n) arrays, returned as a tuple); refused, with nothing
// written, when a result is not finite.
py::object results(const double* rows, py::ssize_t n, const py::object& out, const char* what) {
  const py::ssize_t nn = n * n;
  if (!finite(rows, static_cast<int>(3 * nn)))
    throw py::value_error(std::string(what) + ": result is not finite for this input (values out of range?)");
  if (out.is_none()) {
    py::tuple t(3);
    for (int i = 0; i < 3; ++i) PyTuple_SET_ITEM(t.ptr(), i, new_matrix(rows + i * nn, n));
    return std::move(t);
  }
  double* d[3];
  out_arrays(out, {n, n}, d);
  for (int i = 0; i < 3; ++i) std::memcpy(d[i], rows + i * nn, sizeof(double) * nn);
  return PyTuple_Check(out.ptr()) ? out : py::object(py::tuple(out));
}

// MatN results in numpy's layout, then as results()
py::object results(const MatN& a, const MatN& b, const MatN& c, const py::object& out, const char* what) {
  double rows[3 * kMaxDof * kMaxDof];
  write_rows(a, b, c, rows);
  return results(rows, a.rows(), out, what);
}

// Robot.forward_dynamics_derivatives(q, qd, tau[, out=]) of three float64 (n,) arrays by CPython's fast
// call (METH_FASTCALL): the call of iLQR's and MPC's loops without pybind11's dispatcher (about a fifth
// of it). Any other call (f_ext, other arguments) and any failure go to the pybind11 overload
// (g_forward_slow), which does the same or raises its one-line error.
PyObject* g_forward_slow = nullptr;
PyObject* forward_fast(PyObject* self, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  const bool with_out = kwnames && PyTuple_GET_SIZE(kwnames) == 1 &&
                        PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, 0), "out") == 0;
  if (nargs == 3 && (!kwnames || with_out)) {
    try {
      // self is a Robot (the method's descriptor checked it): its C++ object without pybind11's type lookup
      static const py::detail::type_info* robot_type = py::detail::get_type_info(typeid(Robot));
      const auto vh = reinterpret_cast<py::detail::instance*>(self)->get_value_and_holder(robot_type, false);
      if (!vh || !vh.value_ptr()) throw std::invalid_argument("not a constructed Robot");
      const Robot& r = *static_cast<const Robot*>(vh.value_ptr());
      const int n = r.dof();
      const double *q = direct(args[0], {n}, false), *qd = direct(args[1], {n}, false),
                   *tau = direct(args[2], {n}, false);
      if (q && qd && tau && finite(q, n) && finite(qd, n) && finite(tau, n)) {
        double rows[3 * kMaxDof * kMaxDof];
        r.forward_dynamics_derivatives_rows(q, qd, tau, rows, rows + n * n, rows + 2 * n * n);
        const py::object out = with_out ? py::reinterpret_borrow<py::object>(args[3]) : py::none();
        return results(rows, n, out, "forward_dynamics_derivatives").release().ptr();
      }
    } catch (...) {
    }
  }
  const Py_ssize_t total = nargs + (kwnames ? PyTuple_GET_SIZE(kwnames) : 0);
  std::vector<PyObject*> all(1 + total);
  all[0] = self;
  std::copy(args, args + total, all.begin() + 1);
  return PyObject_Vectorcall(g_forward_slow, all.data(), nargs + 1, kwnames);
}

}  // namespace

void bind_derivatives(py::module_& m) {
  auto robot = py::reinterpret_borrow<py::class_<Robot>>(m.attr("Robot"));
  robot.def("inverse_dynamics_derivatives", [](const Robot& r, const py::object& q, const py::object& qd,
                                                const py::object& qdd, const py::object& f_ext,
                                                const py::object& out) {
         const int n = r.dof();
         const VecArg qv(q, n, "q"), qdv(qd, n, "qd"), qddv(qdd, n, "qdd");
         const std::vector<ExternalWrench> w = wrenches_or_none(f_ext);
         Workspace ws;
         MatN dq, dqd, M;
         r.inverse_dynamics_derivatives(qv.data(), qdv.data(), qddv.data(), w, ws, dq, dqd, M);
         return results(dq, dqd, M, out, "inverse_dynamics_derivatives");
       }, py::arg("q"), py::arg("qd"), py::arg("qdd"), py::arg("f_ext") = py::none(), py::kw_only(),
       py::arg("out") = py::none(), docs::doc_Robot_inverse_dynamics_derivatives);
  // the pybind11 overload, kept out of the class: the method is the fast call, which hands it the rest
  py::cpp_function slow([](const Robot& r, const py::object& q, const py::object& qd, const py::object& tau,
                           const py::object& f_ext, const py::object& out) {
         const int n = r.dof();
         const VecArg qv(q, n, "q"), qdv(qd, n, "qd"), tv(tau, n, "tau");
         const std::vector<ExternalWrench> w = wrenches_or_none(f_ext);
         Workspace ws;
         MatN dq, dqd, Minv;
         r.forward_dynamics_derivatives(qv.data(), qdv.data(), tv.data(), w, ws, dq, dqd, Minv);
         return results(dq, dqd, Minv, out, "forward_dynamics_derivatives");
       }, py::name("forward_dynamics_derivatives"), py::is_method(robot), py::arg("q"), py::arg("qd"), py::arg("tau"),
       py::arg("f_ext") = py::none(), py::kw_only(), py::arg("out") = py::none(),
       docs::doc_Robot_forward_dynamics_derivatives);
  static const std::string doc = py::str(slow.attr("__doc__"));  // pybind11's signature line and the text
  g_forward_slow = slow.release().ptr();
  static PyMethodDef fast = {"forward_dynamics_derivatives", reinterpret_cast<PyCFunction>(
                                 reinterpret_cast<void (*)()>(forward_fast)), METH_FASTCALL | METH_KEYWORDS, doc.c_str()};
  robot.attr("forward_dynamics_derivatives") = py::reinterpret_steal<py::object>(
      PyDescr_NewMethod(reinterpret_cast<PyTypeObject*>(robot.ptr()), &fast));
  m.def("forward_dynamics_derivatives_batch", [](const Robot& r, const py::object& Q, const py::object& QD,
                                                 const py::object& TAU, const py::object& threads_obj,
                                                 const py::object& out) {
         const int threads = static_cast<int>(index_arg(threads_obj, "threads", 0, 4096));
         const int n = r.dof();
         Arr q = array(Q, {-1, n}, "q");
         const py::ssize_t N = q.shape(0);
         Arr qd = array(QD, {N, n}, "qd");
         Arr tau = array(TAU, {N, n}, "tau");
         const py::ssize_t nn = n;
         py::tuple res(3);
         double* d[3] = {nullptr, nullptr, nullptr};
         if (out.is_none()) {
           for (int i = 0; i < 3; ++i) {
             py::array_t<double> a({N, nn, nn});
             d[i] = a.mutable_data();
             res[i] = a;
           }
         } else {
           out_arrays(out, {N, nn, nn}, d);
         }
         {
           coopsim::py_nogil::NoGil nogil;
           forward_dynamics_derivatives_batch(r, q.data(), qd.data(), tau.data(), static_cast<int>(N), d[0], d[1],
                                              d[2], threads);
         }
         if (out.is_none()) return py::object(res);
         return PyTuple_Check(out.ptr()) ? out : py::object(py::tuple(out));  // as given, or the list's tuple
       }, py::arg("robot"), py::arg("q"), py::arg("qd"), py::arg("tau"), py::arg("threads") = 0, py::kw_only(),
       py::arg("out") = py::none(), docs::doc_forward_dynamics_derivatives_batch);

  py_struct::Struct<LinearModel>(m, "LinearModel", docs::doc_LinearModel)
      .member("A", &LinearModel::A, docs::doc_LinearModel_A)
      .member("B", &LinearModel::B, docs::doc_LinearModel_B)
      .member("x0", &LinearModel::x0, docs::doc_LinearModel_x0)
      .member("tau0", &LinearModel::tau0, docs::doc_LinearModel_tau0)
      .member("x_next", &LinearModel::x_next, docs::doc_LinearModel_x_next)
      .member("dt", &LinearModel::dt, docs::doc_LinearModel_dt)
      .member("steps", &LinearModel::steps, docs::doc_LinearModel_steps)
      .member("method", &LinearModel::method, docs::doc_LinearModel_method)
      .member("states", &LinearModel::states, docs::doc_LinearModel_states)
      .finish();
  m.def("linearize", [](const Robot& r, const py::object& q, const py::object& qd, const py::object& tau,
                        const py::object& dt, int steps, const std::string& method,
                        const std::shared_ptr<Controller>& controller, const py::object& q_ref,
                        const py::object& qd_ref, const py::object& qdd_ref, const py::object& tau_ext,
                        const py::object& f_ext, bool end_stops) {
         const int n = r.dof();
         const VecN qv = vec(q, n, "q"), qdv = vec(qd, n, "qd"), te = optional_vec(tau_ext, n, "tau_ext");
         const std::vector<ExternalWrench> w = wrenches_or_none(f_ext);
         const Method meth = method_from_name(method);
         const double h = dt.is_none() ? 0.0 : scalar_arg(dt, "dt");
         if (!dt.is_none()) check_step_size(h);
         if (controller) {
           if (!tau.is_none()) throw py::value_error("tau must be None with a controller (it gives the torques)");
           const VecN qr = q_ref.is_none() ? qv : vec(q_ref, n, "q_ref");
           const VecN qdr = qd_ref.is_none() ? qdv : vec(qd_ref, n, "qd_ref");
           const VecN qddr = qdd_ref.is_none() ? VecN(VecN::Zero(n)) : vec(qdd_ref, n, "qdd_ref");
           return linearize_closed_loop(r, *controller, qv.data(), qdv.data(), qr.data(), qdr.data(), qddr.data(),
                                        ptr(te), w, h, steps, meth, end_stops);
         }
         if (tau.is_none()) throw py::value_error("tau must be given (n,) without a controller, got None");
         for (const py::object* o : {&q_ref, &qd_ref, &qdd_ref})
           if (!o->is_none()) throw py::value_error("q_ref, qd_ref and qdd_ref apply with a controller only");
         const VecN tv = vec(tau, n, "tau");
         if (dt.is_none()) return linearize_continuous(r, qv.data(), qdv.data(), tv.data(), ptr(te), w);
         return linearize_step(r, qv.data(), qdv.data(), tv.data(), ptr(te), w, h, steps, meth, end_stops);
       }, py::arg("robot"), py::arg("q"), py::arg("qd"), py::arg("tau") = py::none(), py::arg("dt") = py::none(),
       py::kw_only(), py::arg("steps") = 1, py::arg("method") = "rk4", py::arg("controller") = nullptr,
       py::arg("q_ref") = py::none(), py::arg("qd_ref") = py::none(), py::arg("qdd_ref") = py::none(),
       py::arg("tau_ext") = py::none(), py::arg("f_ext") = py::none(), py::arg("end_stops") = true, kLinearizeDoc);
}
