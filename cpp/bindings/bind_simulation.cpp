// The simulation loop. Stepping runs with the GIL released; Python
// controllers and references take it back for their own calls only.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include "convert.hpp"
#include "coopsim/batch.hpp"
#include "coopsim/held_body.hpp"
#include "coopsim/grasp.hpp"
#include "coopsim/integrator.hpp"
#include "coopsim/simulation.hpp"
#include "coopsim/world.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

PyObject* divergence_type = nullptr;  // coopsim.DivergenceError, lives as long as the interpreter
PyObject* busy_type = nullptr;        // coopsim.SimulationBusyError, likewise

// A thread id as Python's threading.get_ident() gives it (an int), or its text where it is not a number.
py::object thread_object(const std::string& text) {
  try {
    size_t used = 0;
    const unsigned long long id = std::stoull(text, &used);
    if (used == text.size()) return py::int_(id);
  } catch (const std::exception&) {
  }
  return py::str(text);
}

py::object busy_object(const SimulationBusyError& e) {
  py::object inst = py::reinterpret_borrow<py::object>(busy_type)(e.what());
  inst.attr("holder") = e.holder();
  inst.attr("thread") = thread_object(e.thread());
  return inst;
}

py::object divergence_object(const DivergenceError& e) {
  py::object inst = py::reinterpret_borrow<py::object>(divergence_type)(e.what());
  inst.attr("step") = e.step;
  inst.attr("time") = e.time;
  inst.attr("robot") = e.robot;
  inst.attr("q") = to_numpy(e.q);
  inst.attr("qd") = to_numpy(e.qd);
  return inst;
}

// The exception a failed batch member raised, as a Python exception object.
py::object exception_object(const std::exception_ptr& p) {
  try {
    std::rethrow_exception(p);
  } catch (py::error_already_set& e) {
    return e.value();
  } catch (const DivergenceError& e) {
    return divergence_object(e);
  } catch (const SimulationBusyError& e) {
    return busy_object(e);
  } catch (const std::invalid_argument& e) {
    return py::reinterpret_borrow<py::object>(PyExc_ValueError)(e.what());
  } catch (const std::exception& e) {
    return py::reinterpret_borrow<py::object>(PyExc_RuntimeError)(e.what());
  }
}

// A Reference (C++ or Python subclass), or a set-point array held at all times.
std::shared_ptr<const Reference> reference_arg(const py::object& ref, int n) {
  if (py::isinstance<Reference>(ref)) return ref.cast<std::shared_ptr<Reference>>();
  if (ref.is_none())
    throw py::value_error("reference must be a coopsim.Reference (e.g. CubicTrajectory) or a set-point (n,)");
  return std::make_shared<ConstantReference>(vec(ref, n, "reference"));
}

// A read-only numpy view of the first `rows` rows of a log column, keeping
// its memory block alive: rows once written never change in a block.
py::array_t<double> view(const LogColumn& c, long rows, bool matrix) {
  const py::ssize_t w = c.width();
  if (!c.data() || rows == 0)
    return matrix ? py::array_t<double>(std::vector<py::ssize_t>{0, w}) : py::array_t<double>(py::ssize_t(0));
  auto* keep = new std::shared_ptr<double[]>(c.block());
  py::capsule owner(keep, [](void* p) { delete static_cast<std::shared_ptr<double[]>*>(p); });
  const py::ssize_t r = rows, sz = static_cast<py::ssize_t>(sizeof(double));
  py::array_t<double> a = matrix ? py::array_t<double>({r, w}, {w * sz, sz}, c.data(), owner)
                                 : py::array_t<double>({r}, {sz}, c.data(), owner);
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

py::dict log_dict(const Simulation& s, int i) {
  const RobotLog& L = s.log(i);
  const long rows = s.log_rows();
  py::dict d;
  for (int k = 0; k < kLogQuantities; ++k) d[log_schema()[k].name] = view(L[k], rows, true);
  return d;
}

// Robot i's grasp log: (rows, 7) [held body id or -1, weld force (3), weld moment (3)].
py::array_t<double> grasp_log(const Simulation& s, int i) {
  return view(s.log(i).grasp, s.log_rows(), true);
}

// Two holders' quantities (held_body.hpp) by the names of cooperation_schema(), body and holding aside.
py::dict cooperation_dict(const Cooperation& c) {
  py::dict d;
  d["centre"] = to_numpy(c.centre);
  d["point_a"] = to_numpy(c.point_a);
  d["point_b"] = to_numpy(c.point_b);
  d["external"] = to_numpy(c.external);
  d["internal"] = to_numpy(c.internal);
  d["squeeze"] = c.squeeze;
  d["twist"] = c.twist;
  d["bending"] = to_numpy(c.bending);
  d["shear"] = c.shear;
  d["load_share"] = to_numpy(c.load_share);
  d["relative_pose_error"] = to_numpy(c.relative_pose_error);
  return d;
}

py::dict metrics_dict(const Simulation& s, int i) {
  const TrackingMetrics& m = s.metrics(i);
  py::dict d;
  d["steps"] = m.steps;
  d["rms_error"] = to_numpy(m.rms_error());
  d["max_abs_error"] = to_numpy(m.max_abs_error);
  d["max_abs_tau"] = to_numpy(m.max_abs_tau);
  return d;
}

py::dict contact_dict(const World& w, const ContactPoint& c) {
  const BodySpec& a = w.body(c.a);
  const BodySpec& b = w.body(c.b);
  py::dict d;
  d["a"] = a.name;
  d["b"] = b.name;
  d["kind"] = contact_kind(a, b);
  d["point_a"] = to_numpy(c.point_a);
  d["point_b"] = to_numpy(c.point_b);
  d["normal"] = to_numpy(c.normal);
  d["depth"] = c.depth;
  d["force"] = to_numpy(c.force);
  return d;
}

const World& world_of(const Simulation& s) {
  if (!s.world()) throw py::value_error("the simulation has no world (give one: Simulation(world=...))");
  return *s.world();
}

int body_id(const Simulation& s, const std::string& name) { return world_of(s).id(name); }

// Columns of a table of n rows, as a dict of arrays: one per field.
template <class T, class F>
py::array_t<double> column(const std::vector<T>& rows, F field) {
  py::array_t<double> out(static_cast<py::ssize_t>(rows.size()));
  for (size_t i = 0; i < rows.size(); ++i) out.mutable_data()[i] = field(rows[i]);
  return out;
}

template <class T, class F>
py::list names(const World& w, const std::vector<T>& rows, F field) {
  py::list out;
  for (const T& r : rows) out.append(w.body(field(r)).name);
  return out;
}

// The options a default-constructed SimulationOptions holds: the one source of the defaults.
const SimulationOptions kDefaults{};
const SensorOptions kSensorDefaults{};

py::dict sensor_options_dict(const SensorOptions& o) {
  py::dict d;
  d["noise_force"] = o.noise_force;
  d["noise_moment"] = o.noise_moment;
  d["time_constant"] = o.time_constant;
  d["seed"] = o.seed;
  return d;
}

// Sets grasp option `name` (engine's table; weld_moment a flag) from a Python value.
void set_grasp_option(GraspOptions& g, const std::string& name, const py::handle& value) {
  if (name == "weld_moment") g.weld_moment = value.cast<bool>();
  else grasp_option(g, name) = scalar_arg(value, name.c_str());
}

py::dict grasp_options_dict(const GraspOptions& g) {
  py::dict d;
  for (const GraspOptionField& f : grasp_option_fields()) d[f.name] = g.*f.field;
  d["weld_moment"] = g.weld_moment;
  return d;
}

}  // namespace

py::dict body_state_dict(const BodyState& s);  // bind_world.cpp

void bind_simulation(py::module_& m) {
  divergence_type = PyErr_NewExceptionWithDoc(
      "coopsim._core.DivergenceError",
      "The simulation diverged (non-finite or runaway state, or a non-finite torque). Attributes: step, time "
      "(s), robot (index; -1 when a free body of the world diverged, named in the message), q, qd (the rejected "
      "state; empty for a free body). The simulation keeps its log up to the last good step.",
      PyExc_RuntimeError, nullptr);
  m.attr("DivergenceError") = py::reinterpret_borrow<py::object>(divergence_type);
  busy_type = PyErr_NewExceptionWithDoc(
      "coopsim._core.SimulationBusyError",
      "Another thread is running this simulation: a call that advances or changes it (advance, run, reset, "
      "set_*, ...) was made from a thread other than its holder's. One driver at a time: pause or close the "
      "other driver (e.g. the live view) first. Attributes: holder (str, the holder's label; 'another thread' "
      "for a call holding it for its own duration), thread (int, the holder's threading.get_ident()).",
      PyExc_RuntimeError, nullptr);
  m.attr("SimulationBusyError") = py::reinterpret_borrow<py::object>(busy_type);
  py::register_local_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const DivergenceError& e) {
      py::object inst = divergence_object(e);
      PyErr_SetObject(divergence_type, inst.ptr());
    } catch (const SimulationBusyError& e) {
      py::object inst = busy_object(e);
      PyErr_SetObject(busy_type, inst.ptr());
    }
  });

  py::class_<Simulation::Hold>(m, "SimulationHold", R"doc(
A hold on a SimulationCore's run (SimulationCore.hold; use coopsim.Simulation.driving): while it is held,
only the thread that took it may advance or change the simulation. release() gives it back; it must be
called on that thread.)doc")
      .def("release", &Simulation::Hold::release,
           "Gives the run back (nothing if already given back); RuntimeError from another thread than the "
           "one that took it.")
      .def_property_readonly("held", &Simulation::Hold::held, "Whether this hold still holds the run.");

  py::class_<Simulation>(m, "SimulationCore", R"doc(
The C++ simulation loop behind coopsim.Simulation (use that class): robots
with controllers and references, RK4 at a fixed dt, zero-order hold of the
torques between controller updates, the log and tracking metrics.)doc")
      .def(py::init([](double dt, int control_every, int log_every, bool end_stops, double max_speed,
                       double max_position, const std::string& integrator, std::shared_ptr<World> world,
                       int world_every, bool contact_forces, bool log_contacts, bool grasp, const py::dict& grasp_options) {
             SimulationOptions o;
             o.dt = dt;
             o.control_every = control_every;
             o.log_every = log_every;
             o.end_stops = end_stops;
             o.max_speed = max_speed;
             o.max_position = max_position;
             o.integrator = method_from_name(integrator, "integrator");
             o.world_every = world_every;
             o.contact_forces = contact_forces;
             o.log_contacts = log_contacts;
             o.grasp.enabled = grasp;
             for (auto item : grasp_options) set_grasp_option(o.grasp, item.first.cast<std::string>(), item.second);
             return Simulation(o, std::move(world));  // checks every option
           }),
           py::arg("dt") = kDefaults.dt, py::arg("control_every") = kDefaults.control_every,
           py::arg("log_every") = kDefaults.log_every, py::arg("end_stops") = kDefaults.end_stops,
           py::arg("max_speed") = kDefaults.max_speed, py::arg("max_position") = kDefaults.max_position,
           py::arg("integrator") = method_name(kDefaults.integrator), py::arg("world") = py::none(),
           py::arg("world_every") = kDefaults.world_every, py::arg("contact_forces") = kDefaults.contact_forces,
           py::arg("log_contacts") = kDefaults.log_contacts, py::arg("grasp") = kDefaults.grasp.enabled,
           py::arg("grasp_options") = py::dict())
      .def("add_robot", [](Simulation& s, const Robot& robot, std::shared_ptr<Controller> controller,
                           const py::object& reference, const py::object& q0, const py::object& qd0) {
             const int n = robot.dof();
             VecN q0v, qd0v;
             if (!q0.is_none()) q0v = vec(q0, n, "q0");
             if (!qd0.is_none()) qd0v = vec(qd0, n, "qd0");
             auto ref = reference_arg(reference, n);
             if (s.options().end_stops) warn_if(end_stop_step_warning(robot, s.options().dt));
             return s.add_robot(robot, std::move(controller), std::move(ref), q0.is_none() ? nullptr : q0v.data(),
                                qd0.is_none() ? nullptr : qd0v.data());
           },
           py::arg("robot"), py::arg("controller"), py::arg("reference"), py::arg("q0") = py::none(),
           py::arg("qd0") = py::none(), py::keep_alive<1, 3>(), py::keep_alive<1, 4>(),
           "Adds a robot (copied); returns its index.")
      .def("set_reference", [](Simulation& s, int i, const py::object& reference) {
             s.set_reference(i, reference_arg(reference, s.robot(i).dof()));
           }, py::arg("i"), py::arg("reference"), py::keep_alive<1, 3>(),
           "Replaces robot i's reference (a Reference or a set-point (n,)); it acts from the next controller "
           "update.")
      .def("set_robot", &Simulation::set_robot, py::arg("i"), py::arg("robot"),
           "Replaces robot i by a robot of the same joints and boxes (copied); q and qd stay, the controller "
           "is reset, with a world the robot's link bodies and exclusions follow.")
      .def("add_cooperative", &Simulation::add_cooperative, py::arg("controller"), py::arg("robots"),
           py::keep_alive<1, 2>())
      .def("remove_cooperative", &Simulation::remove_cooperative, py::arg("k"))
      .def("set_controller", &Simulation::set_controller, py::arg("i"), py::arg("controller"),
           py::keep_alive<1, 3>(),
           "Replaces robot i's controller (checked as add_robot's); the state stays, the new controller "
           "is reset now and acts from the next controller update.")
      .def("hold", [](Simulation& s, const py::object& label) {
             // a py::object, checked here: pybind11's own message for a wrong type here crashes (3.1.0)
             if (!py::isinstance<py::str>(label))
               throw py::type_error("SimulationCore.hold(): label must be a str, got " +
                                    std::string(py::str(py::type::of(label).attr("__name__"))));
             return s.hold(label.cast<std::string>());
           }, py::arg("label"), py::keep_alive<0, 1>(),
           "Takes the run for the calling thread until the returned SimulationHold is released: another "
           "thread's advance, run, reset, set_* ... then raises SimulationBusyError naming `label` (non-empty "
           "str). Re-entrant on the holding thread. SimulationBusyError when another thread holds it.")
      .def_property_readonly("holder", [](const Simulation& s) -> py::object {
             std::thread::id id;
             const std::string label = s.holder(&id);
             if (id == std::thread::id() || label.empty()) return py::none();
             std::ostringstream text;
             text << id;
             return py::make_tuple(label, thread_object(text.str()));
           },
           "(label, thread) of the thread holding the run now (thread: its threading.get_ident()), or None. "
           "A snapshot: it may change at once.")
      .def("advance", [](Simulation& s, long n) {
             py::gil_scoped_release nogil;
             s.advance(n);
           }, py::arg("n"), "Advances n steps with the GIL released.")
      .def("run", [](Simulation& s, double t_end, const py::object& callback, long chunk) {
             long total = 0;
             try {
               total = s.steps_until(t_end);
               s.reserve(total);
             } catch (const std::bad_alloc&) {
               const long rows = s.options().log_every > 0 ? total / s.options().log_every : 0;
               PyErr_SetString(PyExc_MemoryError,
                               ("no memory for a log of " + std::to_string(rows) + " rows (" +
                                std::to_string(total) + " steps); log fewer rows with log_every")
                                   .c_str());
               throw py::error_already_set();
             }
             // between chunks: Ctrl-C stops the run with the log kept, then the progress callback
             auto between = [&callback](long done, long all) {
               py::gil_scoped_acquire gil;
               if (PyErr_CheckSignals() != 0) throw py::error_already_set();
               if (!callback.is_none()) callback(done, all);
               return true;
             };
             py::gil_scoped_release nogil;
             return s.run(t_end, chunk, between);
           },
           py::arg("t_end"), py::arg("callback") = py::none(), py::arg("chunk") = 4096,
           "Advances to time t_end (s) in chunks of `chunk` steps with the GIL released, calling "
           "callback(done, total) after each chunk. Returns the number of steps.")
      .def("steps_until", &Simulation::steps_until, py::arg("t_end"),
           "Steps from now to t_end (s), rounded down.")
      .def("reset", &Simulation::reset, "Back to t = 0 and the initial states; clears log and metrics.")
      .def_property_readonly("time", &Simulation::time, "Simulated time, s.")
      .def_property_readonly("steps", &Simulation::step_count, "Steps taken since the start.")
      .def_property_readonly("dt", [](const Simulation& s) { return s.options().dt; }, "Step size, s.")
      .def_property_readonly("control_every", [](const Simulation& s) { return s.options().control_every; })
      .def_property_readonly("log_every", [](const Simulation& s) { return s.options().log_every; })
      .def_property_readonly("end_stops", [](const Simulation& s) { return s.options().end_stops; })
      .def_property_readonly("max_speed", [](const Simulation& s) { return s.options().max_speed; })
      .def_property_readonly("max_position", [](const Simulation& s) { return s.options().max_position; })
      .def_property_readonly("robot_count", &Simulation::robot_count)
      .def_property_readonly("started", &Simulation::started)
      .def_property_readonly("diverged", &Simulation::diverged)
      .def_property_readonly("integrator", [](const Simulation& s) { return method_name(s.options().integrator); })
      .def_property_readonly("world", [](const Simulation& s) { return s.world(); })
      .def_property_readonly("world_every", [](const Simulation& s) { return s.options().world_every; })
      .def_property_readonly("contact_forces", [](const Simulation& s) { return s.options().contact_forces; })
      .def_property_readonly("log_contacts", [](const Simulation& s) { return s.options().log_contacts; })
      .def("contacts", [](const Simulation& s) {
             const World& w = world_of(s);
             py::list out;
             for (const ContactPoint& c : w.contacts()) out.append(contact_dict(w, c));
             return out;
           }, "Contact points of the last world step: dicts with a, b (names), kind, point_a, point_b (3,) m, "
              "normal (3,) from b to a, depth m (>= 0 touching), force (3,) N on a (b feels -force).")
      .def("set_body_wrench", [](Simulation& s, const std::string& name, const py::object& w) {
             s.set_body_wrench(body_id(s, name), vector_arg<Vec6>(w, 6, "wrench"));
           }, py::arg("name"), py::arg("wrench"))
      .def("body_wrench", [](const Simulation& s, const std::string& name) {
             return to_numpy(s.body_wrench(body_id(s, name)));
           }, py::arg("name"))
      .def("body_state", [](const Simulation& s, const std::string& name) {
             return body_state_dict(s.body_state(body_id(s, name)));
           }, py::arg("name"), "A free or static body's state now: pose (4, 4), position (3,), quaternion (4,) "
                               "[w, x, y, z], velocity (3,) m/s, angular_velocity (3,) rad/s.")
      .def("holding", [](const Simulation& s, int i) -> py::object {
             const int id = s.holding(i);
             if (id < 0) return py::none();
             return py::str(world_of(s).body(id).name);
           }, py::arg("i"), "The name of the free body robot i holds, or None.")
      .def("release", &Simulation::release, py::arg("i"), "Releases what robot i holds, now.")
      .def("weld_wrench", [](const Simulation& s, int i) { return to_numpy(s.weld_wrench(i)); }, py::arg("i"),
           "The weld's force (N) and moment (N m) on the body robot i holds over the last world step, (6,).")
      .def("grasp_check", [](Simulation& s, int i, const std::string& body) {
             const GraspCheck c = s.grasp_check(i, body_id(s, body));
             py::dict d;
             d["closing"] = c.closing; d["aligned"] = c.aligned; d["touching"] = c.touching;
             d["in_pads"] = c.in_pads; d["slow"] = c.slow; d["ok"] = c.ok();
             d["angle"] = c.angle; d["gap_fixed"] = c.gap_fixed; d["gap_moving"] = c.gap_moving;
             d["speed"] = c.speed; d["angular_speed"] = c.angular_speed; d["width"] = c.width;
             return d;
           }, py::arg("i"), py::arg("body"),
           "The clamp rule's conditions for robot i and a free body now: closing, aligned, touching, in_pads, "
           "slow, ok (all of them), with angle (rad), gap_fixed, gap_moving (m, < 0 penetrating), speed (m/s), "
           "angular_speed (rad/s) and width (m).")
      .def("grasp_options", [](const Simulation& s) { return grasp_options_dict(s.options().grasp); },
           "The clamp rule's options of this simulation: {name: value} (see simulation_defaults()).")
      .def_property_readonly("grasp", [](const Simulation& s) { return s.options().grasp.enabled; })
      .def("grasp_events", [](const Simulation& s) {
             py::dict d;
             py::list t, robot, body, event, reason;
             for (const GraspEvent& e : s.grasp_events()) {
               t.append(e.t);
               robot.append(e.robot);
               body.append(world_of(s).body(e.body).name);
               event.append(e.grasp ? "grasp" : "release");
               reason.append(e.reason);
             }
             d["t"] = t; d["robot"] = robot; d["body"] = body; d["event"] = event; d["reason"] = reason;
             return d;
           }, "Grasps and releases as columns: t (s), robot (index), body (name), event ('grasp' or 'release'), "
              "reason ('grasp', 'opened', 'slipped', 'released').")
      .def("link_body_state", [](const Simulation& s, int i, int box) {
             const int id = s.link_body(i, box);
             if (id < 0) throw py::value_error("the robots' link bodies join the world at the first step");
             return body_state_dict(world_of(s).state(id));
           }, py::arg("i"), py::arg("box"),
           "The pose and twist the world holds for robot i's box (as set at the last world step).")
      .def("free_body_names", [](const Simulation& s) {
             return s.world() ? s.world()->names(s.world()->free_bodies()) : std::vector<std::string>();
           })
      .def("body_log", [](const Simulation& s) {
             py::list out;
             for (const LogColumn& c : s.body_log()) out.append(view(c, s.log_rows(), true));
             return out;
           }, "Free bodies' logs (free_body_names order), each (rows, 13): position (3), quaternion w x y z (4), "
              "velocity (3), angular velocity (3).")
      .def("contact_events", [](const Simulation& s) {
             py::dict d;
             if (!s.world()) return d;
             const World& w = *s.world();
             const auto& ev = w.events();
             d["a"] = names(w, ev, [](const ContactEvent& e) { return e.a; });
             d["b"] = names(w, ev, [](const ContactEvent& e) { return e.b; });
             py::list kinds;
             for (const ContactEvent& e : ev) kinds.append(contact_kind(w.body(e.a), w.body(e.b)));
             d["kind"] = kinds;
             d["begin"] = column(ev, [](const ContactEvent& e) { return e.begin; });
             d["end"] = column(ev, [](const ContactEvent& e) { return e.end; });
             d["peak_force"] = column(ev, [](const ContactEvent& e) { return e.peak_force; });
             d["max_depth"] = column(ev, [](const ContactEvent& e) { return e.max_depth; });
             d["steps"] = column(ev, [](const ContactEvent& e) { return static_cast<double>(e.steps); });
             return d;
           }, "Contact events of the run as columns: a, b, kind, begin, end (s; NaN while ongoing), peak_force "
              "(N), max_depth (m), steps.")
      .def("set_sensor", [](Simulation& s, int i, double noise_force, double noise_moment, double time_constant,
                            std::int64_t seed) {
             SensorOptions o;
             o.noise_force = noise_force;
             o.noise_moment = noise_moment;
             o.time_constant = time_constant;
             o.seed = seed;
             s.set_sensor(i, o);  // checks every option
           },
           py::arg("i"), py::arg("noise_force") = kSensorDefaults.noise_force,
           py::arg("noise_moment") = kSensorDefaults.noise_moment,
           py::arg("time_constant") = kSensorDefaults.time_constant, py::arg("seed") = kSensorDefaults.seed,
           "Configures robot i's force/torque sensor: noise_force (N) and noise_moment (N m), the standard "
           "deviations of the Gaussian noise per component in the sensor frame; time_constant (s) of the "
           "first-order low-pass filter (0: none); seed (>= 0) of the noise generator, which restarts from it.")
      .def("sensor_options", [](const Simulation& s, int i) { return sensor_options_dict(s.sensor_options(i)); },
           py::arg("i"), "Robot i's sensor options: noise_force, noise_moment, time_constant, seed.")
      .def("sensor", [](Simulation& s, int i) {
             py::dict d;
             d["ft_world"] = to_numpy(s.ft_world(i));
             d["ft_clamp"] = to_numpy(s.ft_clamp(i));
             d["ft_true_world"] = to_numpy(s.ft_true_world(i));
             d["ft_true_clamp"] = to_numpy(s.ft_true_clamp(i));
             d["pose"] = to_numpy(s.sensor_pose(i));
             d["tau"] = to_numpy(s.tau(i));
             d["tau_ext"] = to_numpy(s.tau_ext(i));
             return d;
           }, py::arg("i"),
           "Robot i's sensors now: ft_world, ft_clamp (6,) the force/torque reading [N; N m about the tool "
           "centre point] in world axes and in the sensor frame, ft_true_world, ft_true_clamp (6,) the same "
           "without noise or filter, pose (4, 4) the sensor frame (the TCP) in the world, tau (n,) the motors' "
           "held torque, tau_ext (n,) the environment's joint torque held over the step.")
      .def("sensor_log", [](const Simulation& s, int i) { return view(s.log(i).ft, s.log_rows(), true); },
           py::arg("i"), "Robot i's force/torque reading per log row, (rows, 12): world axes (6), sensor frame (6).")
      .def("cooperation", [](Simulation& s, int a, int b) {
             bool holding = false;
             py::dict d = cooperation_dict(s.cooperation(a, b, &holding));
             d["holding"] = holding;
             return d;
           }, py::arg("a"), py::arg("b"),
           "Robots a < b holding one body now: holding (bool) and the quantities of cooperation_schema() (zeros "
           "when not holding).")
      .def("cooperation_log", [](Simulation& s, int a, int b) {
             return view(s.cooperation_log(a, b), s.log_rows(), true);
           }, py::arg("a"), py::arg("b"),
           "Robots a < b: one row of cooperation_schema() per log row, (rows, width).")
      .def("grasp_log", &grasp_log, py::arg("i"),
           "Robot i's grasp per log row, (rows, 7): the world id of the body held (-1: none), the weld's force "
           "(3) N and moment (3) N m on it.")
      .def("contact_log", [](const Simulation& s) {
             py::dict d;
             if (!s.world()) return d;
             const World& w = *s.world();
             const auto& rows = s.contact_log();
             d["t"] = column(rows, [](const LoggedContact& c) { return c.t; });
             d["a"] = names(w, rows, [](const LoggedContact& c) { return c.contact.a; });
             d["b"] = names(w, rows, [](const LoggedContact& c) { return c.contact.b; });
             for (int k = 0; k < 3; ++k) {
               const char* axis[3] = {"x", "y", "z"};
               d[py::str(std::string("point_") + axis[k])] = column(rows, [k](const LoggedContact& c) { return c.contact.point_a[k]; });
               d[py::str(std::string("normal_") + axis[k])] = column(rows, [k](const LoggedContact& c) { return c.contact.normal[k]; });
               d[py::str(std::string("force_") + axis[k])] = column(rows, [k](const LoggedContact& c) { return c.contact.force[k]; });
             }
             d["depth"] = column(rows, [](const LoggedContact& c) { return c.contact.depth; });
             return d;
           }, "Every contact point of every world step (with log_contacts=True) as columns: t, a, b, point_x.. "
              "(on a), normal_x.., force_x.. (on a), depth.")
      .def_static("excluded_pairs", [](const Robot& r, int samples) { return Simulation::excluded_pairs(r, samples); },
                  py::arg("robot"), py::arg("samples") = 200,
                  "Box index pairs of a robot that never collide: same or adjacent links, and pairs touching at "
                  "every one of `samples` random poses.")
      .def("set_profiling", &Simulation::set_profiling, py::arg("on"))
      .def("profile", [](const Simulation& s) {
             const StepProfile& p = s.profile();
             py::dict d;
             d["controllers"] = p.controllers;
             d["world"] = p.world;
             d["contacts"] = p.contacts;
             d["robots"] = p.robots;
             d["grasp"] = p.grasp;
             d["world_steps"] = p.world_steps;
             return d;
           }, "Seconds spent in the controllers, the world's step (grasp included), the grasp rule and welds, the "
              "contact mapping and the robots' integration since profiling was switched on (set_profiling).")
      .def("robot", [](const Simulation& s, int i) { return s.robot(i); }, py::arg("i"),
           "Robot i as simulated (robots are immutable: this equals the robot added).")
      .def("controller", [](const Simulation& s, int i) { return s.controller(i); }, py::arg("i"))
      .def("reference", [](const Simulation& s, int i) { return std::const_pointer_cast<Reference>(s.reference(i)); },
           py::arg("i"))
      .def("set_applied", [](Simulation& s, int i, const py::object& forces, const py::object& wrenches) {
             const int n = s.robot(i).dof();
             if (!forces.is_none()) s.set_applied_forces(i, vec(forces, n, "forces"));
             if (!wrenches.is_none()) s.set_applied_wrenches(i, wrenches_arg(wrenches, "wrenches"));
           }, py::arg("i"), py::arg("forces") = py::none(), py::arg("wrenches") = py::none(),
           "Sets robot i's applied joint forces (n,) and/or wrenches (a Wrench, a list of them, or a (6,) wrench "
           "at the tool centre point); None keeps that input as it is.")
      .def("applied", [](const Simulation& s, int i) {
             return py::make_tuple(to_numpy(s.applied_forces(i)), s.applied_wrenches(i));
           }, py::arg("i"), "(forces (n,), wrenches [Wrench]) applied to robot i now.")
      .def("tau_ext", [](const Simulation& s, int i) { return to_numpy(s.tau_ext(i)); }, py::arg("i"),
           "The external joint torque of robot i's applied inputs, held over the next step, (n,).")
      .def("state", [](const Simulation& s, int i) { return py::make_tuple(to_numpy(s.q(i)), to_numpy(s.qd(i))); },
           py::arg("i"), "(q, qd) of robot i now, each (n,).")
      .def("torque", [](const Simulation& s, int i) { return to_numpy(s.tau(i)); }, py::arg("i"),
           "The torque held on robot i now (saturated), (n,).")
      .def("initial_state", [](const Simulation& s, int i) {
             return py::make_tuple(to_numpy(s.initial_q(i)), to_numpy(s.initial_qd(i)));
           }, py::arg("i"))
      .def_property_readonly("log_rows", &Simulation::log_rows)
      .def("log_t", [](const Simulation& s) { return view(s.log_t(), s.log_rows(), false); },
           "Logged times (rows,), s: a read-only view that later steps do not change.")
      .def("log", &log_dict, py::arg("i"),
           "Robot i's log as a dict of (rows, n) arrays, one per quantity of log_schema(): read-only views "
           "of the rows so far, which later steps and reset() do not change.")
      .def("metrics", &metrics_dict, py::arg("i"),
           "Tracking metrics of robot i over every step: steps, rms_error, max_abs_error (n,), max_abs_tau (n,).");

  m.def("simulation_defaults", []() {
    using namespace py::literals;
    const SimulationOptions& o = kDefaults;
    return py::dict("dt"_a = o.dt, "control_every"_a = o.control_every, "log_every"_a = o.log_every,
                    "end_stops"_a = o.end_stops, "max_speed"_a = o.max_speed, "max_position"_a = o.max_position,
                    "integrator"_a = method_name(o.integrator), "world_every"_a = o.world_every,
                    "contact_forces"_a = o.contact_forces, "log_contacts"_a = o.log_contacts,
                    "grasp"_a = o.grasp.enabled, "grasp_options"_a = grasp_options_dict(o.grasp));
  }, "The engine's defaults of SimulationCore's options, the only place they are written: a dict with dt "
     "(s), control_every, log_every, end_stops, max_speed (rad/s or m/s), max_position (rad or m), integrator, "
     "world_every, contact_forces, log_contacts, grasp, and grasp_options (a dict: hold_time s, gap m, "
     "penetration m, angle rad, speed m/s, angular_speed rad/s, open_margin m, slip m, weld_omega_dt, "
     "release_time s, weld_moment).");

  m.def("sensor_defaults", []() { return sensor_options_dict(kSensorDefaults); },
        "The engine's defaults of a robot's force/torque sensor (SimulationCore.set_sensor), the only place they "
        "are written: noise_force (N), noise_moment (N m), time_constant (s), seed.");

  m.def("log_schema", []() {
    py::list out;
    for (const LogQuantityInfo& q : log_schema()) out.append(py::make_tuple(q.name, q.doc));
    return out;
  }, "The quantities a simulation logs per robot, in column order: [(name, description)], one column per joint.");

  m.def("cooperation_schema", []() {
    py::list out;
    for (const CooperationColumn& c : cooperation_schema()) out.append(py::make_tuple(c.name, c.width, c.doc));
    return out;
  }, "The log's columns of a pair of robots holding one body, in row order: [(name, width, description)].");

  m.def("cooperation_wrenches", [](const py::object& centre, const py::object& point_a, const py::object& wrench_a,
                                   const py::object& point_b, const py::object& wrench_b, const py::object& up) {
    using V3 = Eigen::Vector3d;
    return cooperation_dict(cooperation(vector_arg<V3>(centre, 3, "centre"), vector_arg<V3>(point_a, 3, "point_a"),
                                        vector_arg<Vec6>(wrench_a, 6, "wrench_a"), vector_arg<V3>(point_b, 3, "point_b"),
                                        vector_arg<Vec6>(wrench_b, 6, "wrench_b"), vector_arg<V3>(up, 3, "up")));
  }, py::arg("centre"), py::arg("point_a"), py::arg("wrench_a"), py::arg("point_b"), py::arg("wrench_b"),
     py::arg("up") = std::vector<double>{0.0, 0.0, 1.0},
     "Two holders' wrenches [f; mu] (6,) (N, N m about their points) at point_a, point_b (3,) m on a body "
     "whose centre of mass is `centre` (3,) m: the engine's external, internal, squeeze, twist, bending, shear "
     "and load_share (up (3,): against gravity), as the log's cooperation columns (relative_pose_error zero).");

  m.def("run_batch", [](const py::list& sims, double t_end, int threads) {
         std::vector<Simulation*> ptrs;
         for (py::handle h : sims) ptrs.push_back(h.cast<Simulation*>());
         std::vector<std::exception_ptr> errs;
         std::vector<double> seconds;
         {
           py::gil_scoped_release nogil;
           errs = run_batch(ptrs, t_end, threads, &seconds);
         }
         py::list out;
         py::list secs;
         for (size_t i = 0; i < errs.size(); ++i) {
           out.append(errs[i] ? exception_object(errs[i]) : py::none());
           secs.append(seconds[i]);
         }
         return py::make_tuple(out, secs);
       }, py::arg("sims"), py::arg("t_end"), py::arg("threads") = 0,
       "Runs each SimulationCore up to t_end (s) on `threads` threads (0: all cores) with the GIL released. "
       "Returns (errors, seconds): per simulation None or the exception that stopped it, and the wall time "
       "(s) its run took.");
}
