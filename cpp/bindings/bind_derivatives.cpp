// The dynamics' derivatives (robot_derivatives.cpp): Robot.forward_dynamics_derivatives,
// Robot.inverse_dynamics_derivatives and the batch forward_dynamics_derivatives_batch (GIL released).
#include <pybind11/pybind11.h>

#include "convert.hpp"
#include "coopsim/robot.hpp"
#include "generated/docstrings.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

std::vector<ExternalWrench> wrenches_or_none(const py::object& f_ext) {
  return f_ext.is_none() ? std::vector<ExternalWrench>{} : wrenches_arg(f_ext, "f_ext");
}

py::tuple three(const MatN& a, const MatN& b, const MatN& c, const char* what) {
  return py::make_tuple(checked(a, what), checked(b, what), checked(c, what));
}

}  // namespace

void bind_derivatives(py::module_& m) {
  auto robot = py::reinterpret_borrow<py::class_<Robot>>(m.attr("Robot"));
  robot.def("inverse_dynamics_derivatives", [](const Robot& r, const py::object& q, const py::object& qd,
                                                const py::object& qdd, const py::object& f_ext) {
         const int n = r.dof();
         const VecN qv = vec(q, n, "q"), qdv = vec(qd, n, "qd"), qddv = vec(qdd, n, "qdd");
         const std::vector<ExternalWrench> w = wrenches_or_none(f_ext);
         Workspace ws;
         MatN dq, dqd, M;
         r.inverse_dynamics_derivatives(qv.data(), qdv.data(), qddv.data(), w, ws, dq, dqd, M);
         return three(dq, dqd, M, "inverse_dynamics_derivatives");
       }, py::arg("q"), py::arg("qd"), py::arg("qdd"), py::arg("f_ext") = py::none(),
       docs::doc_Robot_inverse_dynamics_derivatives);
  robot.def("forward_dynamics_derivatives", [](const Robot& r, const py::object& q, const py::object& qd,
                                                const py::object& tau, const py::object& f_ext) {
         const int n = r.dof();
         const VecN qv = vec(q, n, "q"), qdv = vec(qd, n, "qd"), tv = vec(tau, n, "tau");
         const std::vector<ExternalWrench> w = wrenches_or_none(f_ext);
         Workspace ws;
         MatN dq, dqd, Minv;
         r.forward_dynamics_derivatives(qv.data(), qdv.data(), tv.data(), w, ws, dq, dqd, Minv);
         return three(dq, dqd, Minv, "forward_dynamics_derivatives");
       }, py::arg("q"), py::arg("qd"), py::arg("tau"), py::arg("f_ext") = py::none(),
       docs::doc_Robot_forward_dynamics_derivatives);
  m.def("forward_dynamics_derivatives_batch", [](const Robot& r, const py::object& Q, const py::object& QD,
                                                 const py::object& TAU, const py::object& threads_obj) {
         const int threads = static_cast<int>(index_arg(threads_obj, "threads", 0, 4096));
         const int n = r.dof();
         Arr q = array(Q, {-1, n}, "q");
         const py::ssize_t N = q.shape(0);
         Arr qd = array(QD, {N, n}, "qd");
         Arr tau = array(TAU, {N, n}, "tau");
         const py::ssize_t nn = n;
         py::array_t<double> dq({N, nn, nn}), dqd({N, nn, nn}), dtau({N, nn, nn});
         double *a = dq.mutable_data(), *b = dqd.mutable_data(), *c = dtau.mutable_data();
         {
           py::gil_scoped_release nogil;
           forward_dynamics_derivatives_batch(r, q.data(), qd.data(), tau.data(), static_cast<int>(N), a, b, c,
                                              threads);
         }
         return py::make_tuple(dq, dqd, dtau);
       }, py::arg("robot"), py::arg("q"), py::arg("qd"), py::arg("tau"), py::arg("threads") = 0,
       docs::doc_forward_dynamics_derivatives_batch);
}
