// Integrators and batch evaluation; long loops release the GIL.
#include <pybind11/pybind11.h>

#include "nogil.hpp"
#include "convert.hpp"
#include "coopsim/integrator.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

py::tuple step(const Robot& r, const py::object& q, const py::object& qd, const py::object& tau, double dt,
               const py::object& f_ext, bool end_stops, Method method) {
  const int n = r.dof();
  VecN qv = vec(q, n, "q"), qdv = vec(qd, n, "qd");
  const VecN tv = vec(tau, n, "tau");
  check_step_size(dt);
  if (end_stops) warn_if(end_stop_step_warning(r, dt));
  VecN te;
  const double* tep = nullptr;
  if (!f_ext.is_none()) {
    te = vec(f_ext, n, "f_ext");
    tep = te.data();
  }
  Workspace ws;
  if (method == Method::RK4) rk4_step(r, ws, qv, qdv, tv.data(), tep, dt, end_stops);
  else euler_step(r, ws, qv, qdv, tv.data(), tep, dt, end_stops);
  const char* what = method == Method::RK4 ? "rk4_step" : "euler_step";
  return py::make_tuple(checked(qv, what), checked(qdv, what));
}

}  // namespace

void bind_integrator(py::module_& m) {
  m.def("rk4_step", [](const Robot& r, const py::object& q, const py::object& qd, const py::object& tau,
                       double dt, const py::object& tau_ext, bool end_stops) {
         return step(r, q, qd, tau, dt, tau_ext, end_stops, Method::RK4);
       }, py::arg("robot"), py::arg("q"), py::arg("qd"), py::arg("tau"), py::arg("dt") = 2e-4,
       py::arg("tau_ext") = py::none(), py::arg("end_stops") = true,
       "One classic RK4 step of dt seconds (default 0.2 ms) under joint torques tau (n,) held constant, "
       "plus optional external joint torques tau_ext (n,). Returns (q, qd), each (n,).");
  m.def("euler_step", [](const Robot& r, const py::object& q, const py::object& qd, const py::object& tau,
                         double dt, const py::object& tau_ext, bool end_stops) {
         return step(r, q, qd, tau, dt, tau_ext, end_stops, Method::SemiImplicitEuler);
       }, py::arg("robot"), py::arg("q"), py::arg("qd"), py::arg("tau"), py::arg("dt") = 2e-4,
       py::arg("tau_ext") = py::none(), py::arg("end_stops") = true,
       "One semi-implicit Euler step (qd first, then q with the new qd). Returns (q, qd).");
  m.def("integrate", [](const Robot& r, const py::object& q0, const py::object& qd0, const py::object& tau,
                        double dt, long steps, const std::string& method, bool end_stops, long record_every) {
         const int n = r.dof();
         const VecN qv = vec(q0, n, "q0"), qdv = vec(qd0, n, "qd0");
         if (steps < 0 || steps > 2000000000L) throw py::value_error("steps must be in [0, 2e9]");
         Arr T = as_array(tau, "tau");
         int rows = 1;
         if (T.ndim() == 1) {
           T = array(tau, {n}, "tau");
         } else {
           T = array(tau, {steps, n}, "tau");
           rows = static_cast<int>(steps);
         }
         const Method meth = method_from_name(method);
         check_step_size(dt);
         if (end_stops) warn_if(end_stop_step_warning(r, dt));
         IntegrationResult res;
         {
           coopsim::py_nogil::NoGil nogil;
           res = integrate(r, qv.data(), qdv.data(), T.data(), rows, dt, static_cast<int>(steps), meth, end_stops,
                           static_cast<int>(record_every));
         }
         py::array_t<double> t(res.rows), Q({res.rows, n}), QD({res.rows, n});
         std::copy(res.t.begin(), res.t.end(), t.mutable_data());
         std::copy(res.q.begin(), res.q.end(), Q.mutable_data());
         std::copy(res.qd.begin(), res.qd.end(), QD.mutable_data());
         return py::make_tuple(t, Q, QD);
       }, py::arg("robot"), py::arg("q0"), py::arg("qd0"), py::arg("tau"), py::arg("dt") = 2e-4,
       py::arg("steps") = 1, py::arg("method") = "rk4", py::arg("end_stops") = true, py::arg("record_every") = 1,
       R"doc(Integrates `steps` fixed steps of dt seconds in C++ (GIL released).

tau: (n,) held throughout, or (steps, n), one row per step (zero-order hold),
N m or N, applied as given: integrate does not saturate it at the robot's
tau_limits (a Simulation's control stage does; np.clip(tau, -robot.tau_limits,
robot.tau_limits) first to model saturated drives).
method: 'rk4' (default) or 'euler' (semi-implicit).
Returns (t (m,), q (m, n), qd (m, n)) with every record_every-th state, the
first and the last included. Raises DivergenceError (a RuntimeError) naming the
step if the state stops being finite, or if the dynamics fail in a stage: a
runaway (a stage's state not finite, or beyond 1e4 rad/s or 1e6 rad) names that
state and the bound; a mass matrix not positive definite at a sane state names
q (links without mass or inertia).)doc");
  m.def("forward_dynamics_batch", [](const Robot& r, const py::object& Q, const py::object& QD,
                                     const py::object& TAU, const py::object& threads_obj) {
         const int threads = static_cast<int>(index_arg(threads_obj, "threads", 0, 4096));
         const int n = r.dof();
         Arr q = array(Q, {-1, n}, "q");
         const py::ssize_t N = q.shape(0);
         Arr qd = array(QD, {N, n}, "qd");
         Arr tau = array(TAU, {N, n}, "tau");
         py::array_t<double> out({N, static_cast<py::ssize_t>(n)});
         double* o = out.mutable_data();
         {
           coopsim::py_nogil::NoGil nogil;
           forward_dynamics_batch(r, q.data(), qd.data(), tau.data(), static_cast<int>(N), o, threads);
         }
         return out;
       }, py::arg("robot"), py::arg("q"), py::arg("qd"), py::arg("tau"), py::arg("threads") = 0,
       "Forward dynamics of N states in one call: q, qd, tau (N, n) -> qdd (N, n), rad/s^2 or m/s^2; GIL "
       "released, on `threads` threads (0: all cores), each taking chunks of 256 states as it becomes idle. A "
       "state whose dynamics fail (its forces overflow, its mass matrix is not positive definite) is a "
       "ValueError naming its row, the first such row of the batch.");
}
