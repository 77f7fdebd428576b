// The dynamics' derivatives (robot_derivatives.cpp): Robot.forward_dynamics_derivatives,
// Robot.inverse_dynamics_derivatives and the batch forward_dynamics_derivatives_batch (GIL released).
#include <pybind11/pybind11.h>

#include <pybind11/stl.h>

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
