// Task-space controllers: TaskState, Payload, the abstract TaskController (subclassable from
// Python), Impedance and HybridForce.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <vector>

#include "nogil.hpp"
#include "convert.hpp"
#include "py_clone.hpp"
#include "coopsim/task.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

// A Python law: compute_task(state) -> tau (n,); an optional reset(robot, period) runs after the
// engine's own reset (the task axes and directions are set up first).
class PyTaskController : public TaskController {
 public:
  std::shared_ptr<Controller> clone() const override { return python_clone<Controller>(this); }
  using TaskController::TaskController;
  void reset(const Robot& robot, double period) override {
    TaskController::reset(robot, period);
    coopsim::py_nogil::GilAgain gil;
    py::function f = py::get_override(static_cast<const TaskController*>(this), "reset");
    if (f) f(robot, period);
  }
  void compute_task(const TaskState& s, double* tau) override {
    coopsim::py_nogil::GilAgain gil;
    py::function f = py::get_override(static_cast<const TaskController*>(this), "compute_task");
    if (!f) throw py::type_error("TaskController subclass must define compute_task(state) -> tau");
    py::object out = f(s);  // a copy: the state stays valid after the call
    // non-finite values pass through: the simulation reports them with context
    Arr a = array(out, {s.n}, "tau returned by compute_task", false);
    std::copy(a.data(), a.data() + s.n, tau);
  }
};

std::vector<std::string> names_arg(const py::object& obj, const char* name) {
  if (obj.is_none()) return {};
  if (py::isinstance<py::str>(obj)) return {obj.cast<std::string>()};
  std::vector<std::string> out;
  for (py::handle h : obj) {
    if (!py::isinstance<py::str>(h))
      throw py::type_error(std::string(name) + " must be direction names (str), got " + std::string(py::repr(h)));
    out.push_back(h.cast<std::string>());
  }
  return out;
}

Eigen::VectorXd values(const py::handle& obj, const char* name) { return coopsim::gains(table(obj, name), name); }

Payload payload_arg(const py::object& obj) {
  if (obj.is_none()) return Payload();
  if (!py::isinstance<Payload>(obj)) throw py::type_error("payload must be a coopsim.Payload or None");
  return obj.cast<Payload>();
}

py::object payload_out(const Payload& p) { return p.mass > 0 ? py::cast(p) : py::none(); }

py::tuple axis_names(const std::array<bool, kTaskAxes>& mask) {
  py::list out;
  for (int a = 0; a < kTaskAxes; ++a)
    if (mask[a]) out.append(task_axis_name(a));
  return py::tuple(out);
}

py::object names_out(const std::vector<std::string>& v) {
  if (v.empty()) return py::none();
  return py::cast(v);
}

py::array_t<double> torques_py(TaskController& c, const TaskState& s, const py::object& accel,
                               const py::object& wrench) {
  const Vec6 a = vector_arg<Vec6>(accel, 6, "accel");
  const Vec6 w = wrench.is_none() ? Vec6(Vec6::Zero()) : vector_arg<Vec6>(wrench, 6, "wrench");
  VecN tau(s.n);
  c.torques(s, a, w, tau.data());
  return to_numpy(tau);
}

template <class C>
py::dict common_kwargs(const C& c) {
  return py::dict(py::arg("jaw_kp") = c.jaw_kp(), py::arg("jaw_kd") = c.jaw_kd(), py::arg("null_kp") = c.null_kp(),
                  py::arg("null_kd") = c.null_kd(), py::arg("payload") = payload_out(c.payload()),
                  py::arg("model") = model_out(c.model()));
}

}  // namespace

void bind_task(py::module_& m) {
  m.attr("TASK_AXES") = py::make_tuple("x", "y", "z", "roll", "pitch", "yaw");
  m.def("task_axes", [](const py::object& tool) { return to_numpy(Eigen::Matrix3d(task_axes(pose(tool, "tool")))); },
        py::arg("tool"),
        "The task axes' basis (3, 3), columns roll, pitch, yaw axes in the world, for a tool pose (4, 4): yaw "
        "about the world's z, pitch about the tool's y axis laid into the horizontal plane, roll across both. "
        "ValueError-like domain error when the tool's y axis is vertical.");
  m.def("commandable_directions",
        [](const Robot& r, const py::object& q0) {
          VecN q;
          if (!q0.is_none()) q = vec(q0, r.dof(), "q0");
          return axis_names(commandable_directions(r, q0.is_none() ? nullptr : q.data()));
        },
        py::arg("robot"), py::arg("q0") = py::none(),
        "The task directions (names, in the order x, y, z, roll, pitch, yaw) `robot`'s arm joints (the jaw "
        "excluded) can move its tool centre point along: a Jacobian row nonzero at q0 or at one of 32 seeded "
        "random configurations within the joint limits.");

  py::class_<Payload>(m, "Payload", R"doc(A rigid load the task-space controller knows (e.g. the held body).

mass kg >= 0; com (3,) m, its centre of mass in the tool frame; inertia (3, 3) kg m^2 about the
centre of mass in the tool frame (symmetric). Its weight and inertia are taken out of the sensed
wrench (with the acceleration commanded at the previous update).)doc")
      .def(py::init([](double mass, const py::object& com, const py::object& inertia) {
             Payload p;
             p.mass = mass;
             p.com = vector_arg<Eigen::Vector3d>(com, 3, "com");
             Arr I = array(inertia, {3, 3}, "inertia");
             for (int i = 0; i < 3; ++i)
               for (int j = 0; j < 3; ++j) p.inertia(i, j) = I.data()[3 * i + j];
             // checked as the controllers check it
             TaskController::check_payload(p);
             return p;
           }),
           py::arg("mass"), py::arg("com") = py::make_tuple(0.0, 0.0, 0.0),
           py::arg("inertia") = py::array_t<double>(std::vector<py::ssize_t>{3, 3}, std::vector<double>(9, 0.0).data()))
      .def_property_readonly("mass", [](const Payload& p) { return p.mass; }, "kg.")
      .def_property_readonly("com", [](const Payload& p) { return to_numpy(p.com); }, "(3,) m, tool frame.")
      .def_property_readonly("inertia", [](const Payload& p) { return to_numpy(p.inertia); },
                             "(3, 3) kg m^2 about the com, tool frame.")
      .def("__repr__", [](const Payload& p) { return "<coopsim.Payload mass=" + std::to_string(p.mass) + " kg>"; })
      .def(pickle_by_call<Payload>([](const Payload& p) {
        return py::make_tuple(py::make_tuple(p.mass, to_numpy(p.com), to_numpy(p.inertia)), py::dict());
      }));

  py::class_<TaskState>(m, "TaskState", R"doc(What a task-space law sees at one update (a copy).

Task axes (see TaskController): vectors of 6 are [x, y, z, roll, pitch, yaw] (m or rad; N or N m
for wrenches). error and error_rate are reference minus measured.)doc")
      .def_property_readonly("t", [](const TaskState& s) { return s.t; }, "Time, s.")
      .def_property_readonly("q", [](const TaskState& s) { return to_numpy(s.q); }, "(n,) measured joints.")
      .def_property_readonly("qd", [](const TaskState& s) { return to_numpy(s.qd); }, "(n,).")
      .def_property_readonly("q_ref", [](const TaskState& s) { return to_numpy(s.q_ref); }, "(n,) joint reference.")
      .def_property_readonly("qd_ref", [](const TaskState& s) { return to_numpy(s.qd_ref); }, "(n,).")
      .def_property_readonly("qdd_ref", [](const TaskState& s) { return to_numpy(s.qdd_ref); }, "(n,).")
      .def_property_readonly("jaw", [](const TaskState& s) -> py::object {
         return s.jaw >= 0 ? py::object(py::int_(s.jaw)) : py::none();
       }, "The jaw's joint index (0-based), or None.")
      .def_property_readonly("pose", [](const TaskState& s) { return to_numpy(s.pose); }, "(4, 4) the TCP, world.")
      .def_property_readonly("pose_ref", [](const TaskState& s) { return to_numpy(s.pose_ref); },
                             "(4, 4) the TCP at the joint reference.")
      .def_property_readonly("axes", [](const TaskState& s) { return to_numpy(s.axes); },
                             "(3, 3) roll, pitch, yaw axes (columns, world).")
      .def_property_readonly("error", [](const TaskState& s) { return to_numpy(s.error); }, "(6,) m, rad.")
      .def_property_readonly("error_rate", [](const TaskState& s) { return to_numpy(s.error_rate); },
                             "(6,) m/s, rad/s.")
      .def_property_readonly("velocity", [](const TaskState& s) { return to_numpy(s.velocity); }, "(6,).")
      .def_property_readonly("velocity_ref", [](const TaskState& s) { return to_numpy(s.velocity_ref); }, "(6,).")
      .def_property_readonly("accel_ref", [](const TaskState& s) { return to_numpy(s.accel_ref); },
                             "(6,) m/s^2, rad/s^2.")
      .def_property_readonly("wrench", [](const TaskState& s) { return to_numpy(s.wrench); },
                             "(6,) the sensor: what the clamp applies to its environment, N and N m.")
      .def_property_readonly("external", [](const TaskState& s) { return to_numpy(s.external); },
                             "(6,) the environment's wrench on the clamp: -wrench less the payload's.")
      .def_property_readonly("sensed", [](const TaskState& s) { return s.sensed; }, "A sensor reading was given.")
      .def_property_readonly("jacobian", [](const TaskState& s) { return to_numpy(Eigen::MatrixXd(s.J)); },
                             "(6, n) task Jacobian.")
      .def_property_readonly("bias", [](const TaskState& s) { return to_numpy(s.bias); }, "(6,) Jd qd.")
      .def_property_readonly("commanded", [](const TaskState& s) { return axis_names(s.commanded); },
                             "The commanded directions' names.");

  py::class_<TaskController, Controller, PyTaskController, std::shared_ptr<TaskController>>(m, "TaskController",
                                                                                              R"doc(
Abstract task-space controller: a law on the tool centre point (TCP) that sees the force/torque
sensor.

Subclass it in Python: call super().__init__(directions, ...), define compute_task(state) -> tau
(n,) from a TaskState, usually as self.torques(state, accel, wrench): the task acceleration
accel (6,) for the commanded directions and a wrench (6,) to apply. Optionally reset(robot,
period), called after the engine's own set-up.

Task axes: x, y, z the TCP's position (world); yaw about the world's vertical, pitch about the
tool's y axis laid horizontal (the SCARA clamp's pitch joint), roll across both. directions:
names to command (default: every direction the arm can command; SCARA #1: x, y, z, pitch, yaw;
SCARA #2: x, y, z, yaw). The others are reported in the state, never commanded.

torques(): jaw position-controlled (jaw_kp, jaw_kd, 1/s^2, 1/s); the arm's accelerations solve
J_c qdd = accel - Jd qd exactly, or, for a redundant arm (SCARA #2), with the pseudo-inverse
plus qdd_ref + null_kd (qd_ref - qd) + null_kp (q_ref - q) in J_c's null space (the redundancy
follows the joint reference: at rest the deviation from it has no null-space part); then tau = M qdd + C + G + K qd of `model`
(default: the robot) + J^T wrench. The reference is the joint reference mapped by the robot's
kinematics (plan_cartesian gives one). The sensor is read at the start of each step (the contact
and weld wrenches of the last world step). payload: a Payload whose weight and inertia are taken
out of the sensed wrench, or None.)doc")
      .def(py::init([](const py::object& directions, double jaw_kp, double jaw_kd, double null_kp,
                             double null_kd, const py::object& payload, const py::object& model) {
             return std::make_shared<PyTaskController>(names_arg(directions, "directions"), jaw_kp, jaw_kd, null_kp,
                                                       null_kd, payload_arg(payload), model_arg(model));
           }),
           py::arg("directions") = py::none(), py::kw_only(), py::arg("jaw_kp") = TaskDefaults::jaw_kp,
           py::arg("jaw_kd") = TaskDefaults::jaw_kd, py::arg("null_kp") = TaskDefaults::null_kp,
           py::arg("null_kd") = TaskDefaults::null_kd, py::arg("payload") = py::none(), py::arg("model") = py::none())
      .def("torques", &torques_py, py::arg("state"), py::arg("accel"), py::arg("wrench") = py::none(),
           "Joint torques (n,) for the task acceleration accel (6,; m/s^2, rad/s^2; commanded entries used) and "
           "the wrench (6,; N, N m; task axes; default zero) the clamp is to apply, at `state`.")
      .def_property_readonly("directions", [](const TaskController& c) { return names_out(c.directions()); },
                             "The directions given (None: every commandable one).")
      .def_property_readonly("commanded", [](const TaskController& c) { return axis_names(c.commanded()); },
                             "The directions this run commands (after reset).")
      .def_property_readonly("uncommanded", [](const TaskController& c) {
         std::array<bool, kTaskAxes> o{};
         for (int a = 0; a < kTaskAxes; ++a) o[a] = !c.commanded()[a];
         return axis_names(o);
       }, "The directions this run reports but does not command (after reset).")
      .def_property_readonly("state", [](const TaskController& c) { return c.state(); },
                             "The TaskState of the last update (a copy).")
      .def_property_readonly("jaw_kp", &TaskController::jaw_kp)
      .def_property_readonly("jaw_kd", &TaskController::jaw_kd)
      .def_property_readonly("null_kp", &TaskController::null_kp)
      .def_property_readonly("null_kd", &TaskController::null_kd)
      .def_property_readonly("payload", [](const TaskController& c) { return payload_out(c.payload()); })
      .def_property_readonly("model", [](const TaskController& c) { return model_out(c.model()); });

  py::class_<Impedance, TaskController, std::shared_ptr<Impedance>>(m, "Impedance", Impedance::kDoc)
      .def(py::init([](const py::object& k, const py::object& d, const py::object& mass, const py::object& directions,
                       bool feedback, double jaw_kp, double jaw_kd, double null_kp, double null_kd,
                       const py::object& payload, const py::object& model) {
             return std::make_shared<Impedance>(values(k, "stiffness"), values(d, "damping"), values(mass, "mass"),
                                                names_arg(directions, "directions"), feedback, jaw_kp, jaw_kd,
                                                null_kp, null_kd, payload_arg(payload), model_arg(model));
           }),
           py::arg("stiffness"), py::arg("damping"), py::arg("mass"), py::arg("directions") = py::none(),
           py::kw_only(), py::arg("force_feedback") = true, py::arg("jaw_kp") = TaskDefaults::jaw_kp,
           py::arg("jaw_kd") = TaskDefaults::jaw_kd, py::arg("null_kp") = TaskDefaults::null_kp,
           py::arg("null_kd") = TaskDefaults::null_kd, py::arg("payload") = py::none(), py::arg("model") = py::none())
      .def_property_readonly("stiffness", [](const Impedance& c) { return to_numpy(c.stiffness()); })
      .def_property_readonly("damping", [](const Impedance& c) { return to_numpy(c.damping()); })
      .def_property_readonly("mass", [](const Impedance& c) { return to_numpy(c.mass()); })
      .def_property_readonly("force_feedback", &Impedance::force_feedback)
      .def("__repr__", [](const Impedance& c) {
         return std::string("<coopsim.Impedance force_feedback=") + (c.force_feedback() ? "True" : "False") + ">";
       })
      .def(pickle_by_call<Impedance>([](const Impedance& c) {
        py::dict kw = common_kwargs(c);
        kw["directions"] = names_out(c.directions());
        kw["force_feedback"] = c.force_feedback();
        return py::make_tuple(py::make_tuple(to_numpy(c.stiffness()), to_numpy(c.damping()), to_numpy(c.mass())), kw);
      }));

  py::class_<HybridForce, TaskController, std::shared_ptr<HybridForce>>(m, "HybridForce", HybridForce::kDoc)
      .def(py::init([](const py::object& fdirs, const py::object& force, const py::object& kpf, const py::object& kif,
                       const py::object& kv, const py::object& kp, const py::object& kd, const py::object& directions,
                       bool feedback, double ilim, double jaw_kp, double jaw_kd, double null_kp, double null_kd,
                       const py::object& payload, const py::object& model) {
             return std::make_shared<HybridForce>(
                 names_arg(fdirs, "force_directions"), values(force, "force"), values(kpf, "kp_force"),
                 values(kif, "ki_force"), values(kv, "kv"), values(kp, "kp"), values(kd, "kd"),
                 names_arg(directions, "directions"), feedback, ilim, jaw_kp, jaw_kd, null_kp, null_kd,
                 payload_arg(payload), model_arg(model));
           }),
           py::arg("force_directions"), py::arg("force"), py::kw_only(), py::arg("kp_force") = TaskDefaults::kp_force,
           py::arg("ki_force") = TaskDefaults::ki_force, py::arg("kv") = TaskDefaults::kv,
           py::arg("kp") = TaskDefaults::kp, py::arg("kd") = TaskDefaults::kd, py::arg("directions") = py::none(),
           py::arg("force_feedback") = true, py::arg("integral_limit") = TaskDefaults::integral_limit,
           py::arg("jaw_kp") = TaskDefaults::jaw_kp, py::arg("jaw_kd") = TaskDefaults::jaw_kd,
           py::arg("null_kp") = TaskDefaults::null_kp, py::arg("null_kd") = TaskDefaults::null_kd,
           py::arg("payload") = py::none(), py::arg("model") = py::none())
      .def_property_readonly("force_directions", [](const HybridForce& c) { return c.force_directions(); })
      .def_property_readonly("force", [](const HybridForce& c) { return to_numpy(c.force()); })
      .def_property_readonly("kp_force", [](const HybridForce& c) { return to_numpy(c.kp_force()); })
      .def_property_readonly("ki_force", [](const HybridForce& c) { return to_numpy(c.ki_force()); })
      .def_property_readonly("kv", [](const HybridForce& c) { return to_numpy(c.kv()); })
      .def_property_readonly("kp", [](const HybridForce& c) { return to_numpy(c.kp()); })
      .def_property_readonly("kd", [](const HybridForce& c) { return to_numpy(c.kd()); })
      .def_property_readonly("force_feedback", &HybridForce::force_feedback)
      .def_property_readonly("integral_limit", &HybridForce::integral_limit)
      .def_property_readonly("integral", [](const HybridForce& c) { return to_numpy(c.integral()); },
                             "(6,) the force error's integral, N s (task axes).")
      .def("__repr__", [](const HybridForce& c) {
         std::string f;
         for (const auto& n : c.force_directions()) f += (f.empty() ? "" : ", ") + n;
         return "<coopsim.HybridForce force along " + f + ">";
       })
      .def(pickle_by_call<HybridForce>([](const HybridForce& c) {
        py::dict kw = common_kwargs(c);
        kw["kp_force"] = to_numpy(c.kp_force());
        kw["ki_force"] = to_numpy(c.ki_force());
        kw["kv"] = to_numpy(c.kv());
        kw["kp"] = to_numpy(c.kp());
        kw["kd"] = to_numpy(c.kd());
        kw["directions"] = names_out(c.directions());
        kw["force_feedback"] = c.force_feedback();
        kw["integral_limit"] = c.integral_limit();
        return py::make_tuple(py::make_tuple(py::cast(c.force_directions()), to_numpy(c.force())), kw);
      }));
}
