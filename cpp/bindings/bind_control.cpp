// Controllers: the abstract Controller (subclassable from Python), PID and
// ComputedTorque.
#include <pybind11/pybind11.h>

#include <memory>
#include <stdexcept>

#include "nogil.hpp"
#include "convert.hpp"
#include "py_clone.hpp"
#include "coopsim/controller.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

// Lets a Python class implement Controller: it defines
// compute(t, q, qd, q_ref, qd_ref, qdd_ref) -> tau and, optionally,
// reset(robot, period). Calls take the GIL, so a simulation with such a
// controller runs its steps in C++ but its updates in Python.
class PyController : public Controller {
 public:
  std::shared_ptr<Controller> clone() const override { return python_clone<Controller>(this); }
  void reset(const Robot& robot, double period) override {
    coopsim::py_nogil::GilAgain gil;
    py::function f = py::get_override(static_cast<const Controller*>(this), "reset");
    if (f) f(robot, period);
  }
  void compute(const ControlInput& in, double* tau) override {
    coopsim::py_nogil::GilAgain gil;
    py::function f = py::get_override(static_cast<const Controller*>(this), "compute");
    if (!f) throw py::type_error("Controller subclass must define compute(t, q, qd, q_ref, qd_ref, qdd_ref) -> tau");
    auto arr = [&](const double* p) {
      py::array_t<double> a(in.n);
      std::copy(p, p + in.n, a.mutable_data());
      return a;
    };
    py::object out = f(in.t, arr(in.q), arr(in.qd), arr(in.q_ref), arr(in.qd_ref), arr(in.qdd_ref));
    // non-finite values pass through: the simulation reports them with context
    Arr a = array(out, {in.n}, "tau returned by compute", false);
    std::copy(a.data(), a.data() + in.n, tau);
  }
};

Eigen::VectorXd gains(const py::handle& obj, const char* name) { return coopsim::gains(table(obj, name), name); }

py::array_t<double> np(const Eigen::VectorXd& v) { return to_numpy(v); }

py::array_t<double> compute_py(Controller& c, double t, const py::object& q, const py::object& qd,
                               const py::object& q_ref, const py::object& qd_ref, const py::object& qdd_ref,
                               const py::object& wrench) {
  Array w;
  if (!wrench.is_none()) w = table(wrench, "wrench");
  return to_numpy(compute(c, t, table(q, "q"), table(qd, "qd"), table(q_ref, "q_ref"), table(qd_ref, "qd_ref"),
                          table(qdd_ref, "qdd_ref"), wrench.is_none() ? nullptr : &w));
}

}  // namespace

void bind_control(py::module_& m) {
  py::class_<Controller, PyController, std::shared_ptr<Controller>>(m, "Controller", R"doc(
Abstract joint-space controller (the paper's Controller).

Subclass it in Python: call super().__init__(), define
compute(t, q, qd, q_ref, qd_ref, qdd_ref) -> tau, all (n,) float64 arrays
(t in s; q in rad or m; tau in N m or N), and optionally
reset(robot, period), called once before a run with the simulated robot and
the time between updates (s). The simulation saturates tau at the robot's
actuator limits. Controllers keep state, so give each robot its own.)doc")
      .def(py::init<>())
      .def("reset", &Controller::reset, py::arg("robot"), py::arg("period"),
           "Prepares for a run on `robot` with updates every `period` s; clears the state.")
      .def("compute", &compute_py, py::arg("t"), py::arg("q"), py::arg("qd"), py::arg("q_ref"), py::arg("qd_ref"),
           py::arg("qdd_ref"), py::arg("wrench") = py::none(),
           "Torques (n,) in N m or N at time t (s) from the measured q, qd and the reference q_ref, qd_ref, "
           "qdd_ref, all (n,); wrench (6,) the force/torque sensor's reading for a task-space controller "
           "(world axes, [N; N m about the TCP], what the clamp applies to its environment), else None. "
           "Built-ins need reset() first.")
      .def(py::pickle(
          // Python subclasses: their attributes are their state
          [](py::object self) {
            if (!py::hasattr(self, "__dict__"))
              throw py::type_error("this controller cannot be pickled");
            return py::dict(self.attr("__dict__"));
          },
          [](py::dict d) {
            return std::make_pair(std::shared_ptr<Controller>(std::make_shared<PyController>()), d);
          }));

  py::class_<PID, Controller, std::shared_ptr<PID>>(m, "PID", PID::kDoc)
      .def(py::init([](const py::object& kp, const py::object& ki, const py::object& kd, bool gravity_compensation,
                       double derivative_filter, const py::object& integral_limit, const py::object& model) {
             Eigen::VectorXd il;
             if (!integral_limit.is_none()) il = gains(integral_limit, "integral_limit");
             return std::make_shared<PID>(gains(kp, "kp"), gains(ki, "ki"), gains(kd, "kd"), gravity_compensation,
                                          derivative_filter, il, model_arg(model));
           }),
           py::arg("kp"), py::arg("ki"), py::arg("kd"), py::kw_only(), py::arg("gravity_compensation") = true,
           py::arg("derivative_filter") = 0.0, py::arg("integral_limit") = py::none(), py::arg("model") = py::none())
      .def_property_readonly("kp", [](const PID& c) { return np(c.kp()); }, "Proportional gains, (n,) or (1,).")
      .def_property_readonly("ki", [](const PID& c) { return np(c.ki()); }, "Integral gains, (n,) or (1,).")
      .def_property_readonly("kd", [](const PID& c) { return np(c.kd()); }, "Derivative gains, (n,) or (1,).")
      .def_property_readonly("gravity_compensation", &PID::gravity_compensation)
      .def_property_readonly("derivative_filter", &PID::derivative_filter, "Filter time constant, s.")
      .def_property_readonly("integral_limit", [](const PID& c) -> py::object {
         if (c.integral_limit().size() == 0) return py::none();
         return np(c.integral_limit());
       }, "Bound on |ki I| (N m or N), or None for the actuator limits.")
      .def_property_readonly("model", [](const PID& c) { return model_out(c.model()); },
                             "Model for gravity compensation (a copy), or None for the simulated robot.")
      .def_property_readonly("integral", [](const PID& c) { return to_numpy(c.integral()); },
                             "Integral of the error after the last update, (n,).")
      .def_property_readonly("velocity_estimate", [](const PID& c) { return to_numpy(c.velocity_estimate()); },
                             "Filtered measured velocity after the last update, (n,).")
      .def("__repr__", [](const PID& c) {
         return std::string("<coopsim.PID gravity_compensation=") + (c.gravity_compensation() ? "True" : "False") +
                ">";
       })
      .def(pickle_by_call<PID>([](const PID& c) {
        return py::make_tuple(
            py::make_tuple(np(c.kp()), np(c.ki()), np(c.kd())),
            py::dict(py::arg("gravity_compensation") = c.gravity_compensation(),
                     py::arg("derivative_filter") = c.derivative_filter(),
                     py::arg("integral_limit") = c.integral_limit().size() ? py::object(np(c.integral_limit())) : py::none(),
                     py::arg("model") = model_out(c.model())));
      }));

  py::class_<ComputedTorque, Controller, std::shared_ptr<ComputedTorque>>(m, "ComputedTorque", ComputedTorque::kDoc)
      .def(py::init([](const py::object& kp, const py::object& kd, const py::object& model) {
             return std::make_shared<ComputedTorque>(gains(kp, "kp"), gains(kd, "kd"), model_arg(model));
           }),
           py::arg("kp"), py::arg("kd"), py::kw_only(), py::arg("model") = py::none())
      .def_property_readonly("kp", [](const ComputedTorque& c) { return np(c.kp()); }, "(n,) or (1,), 1/s^2.")
      .def_property_readonly("kd", [](const ComputedTorque& c) { return np(c.kd()); }, "(n,) or (1,), 1/s.")
      .def_property_readonly("model", [](const ComputedTorque& c) { return model_out(c.model()); },
                             "The controller's model (a copy), or None for the simulated robot.")
      .def("__repr__", [](const ComputedTorque& c) {
         return std::string("<coopsim.ComputedTorque model=") + (c.model() ? "'" + c.model()->name() + "'" : "own") +
                ">";
       })
      .def(pickle_by_call<ComputedTorque>([](const ComputedTorque& c) {
        return py::make_tuple(py::make_tuple(np(c.kp()), np(c.kd())), py::dict(py::arg("model") = model_out(c.model())));
      }));
  py::class_<StateFeedback, Controller, std::shared_ptr<StateFeedback>>(m, "StateFeedback", StateFeedback::kDoc)
      .def(py::init([](const py::object& K, const py::object& tau0, bool gravity, const py::object& model) {
             Arr k = array(K, {-1, -1}, "K");
             Eigen::MatrixXd Km(k.shape(0), k.shape(1));
             for (py::ssize_t i = 0; i < k.shape(0); ++i)
               for (py::ssize_t j = 0; j < k.shape(1); ++j) Km(i, j) = *k.data(i, j);
             Eigen::VectorXd t0;
             if (!tau0.is_none()) {
               Arr a = array(tau0, {-1}, "tau0");
               t0 = Eigen::Map<const Eigen::VectorXd>(a.data(), a.shape(0));
             }
             return std::make_shared<StateFeedback>(Km, t0, gravity, model_arg(model));
           }),
           py::arg("K"), py::arg("tau0") = py::none(), py::kw_only(), py::arg("gravity_compensation") = false,
           py::arg("model") = py::none())
      .def_property_readonly("K", [](const StateFeedback& c) { return to_numpy(c.K()); }, "(n, 2n), the gain on [q - q_ref; qd - qd_ref].")
      .def_property_readonly("tau0", [](const StateFeedback& c) { return np(c.tau0()); }, "(n,) or (0,), N m or N.")
      .def_property_readonly("gravity_compensation", &StateFeedback::gravity_compensation)
      .def_property_readonly("model", [](const StateFeedback& c) { return model_out(c.model()); },
                             "The controller's model for G(q) (a copy), or None for the simulated robot.")
      .def(pickle_by_call<StateFeedback>([](const StateFeedback& c) {
        return py::make_tuple(py::make_tuple(to_numpy(c.K()), np(c.tau0())),
                              py::dict(py::arg("gravity_compensation") = c.gravity_compensation(),
                                       py::arg("model") = model_out(c.model())));
      }));
}
