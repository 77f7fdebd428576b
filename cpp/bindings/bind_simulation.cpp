// The simulation loop. Stepping runs with the GIL released; Python
// controllers and references take it back for their own calls only.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include "nogil.hpp"
#include "convert.hpp"
#include "generated/docstrings.hpp"
#include "struct_binding.hpp"
#include "coopsim/held_body.hpp"
#include "coopsim/grasp.hpp"
#include "coopsim/integrator.hpp"
#include "coopsim/simulation.hpp"
#include "coopsim/world.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;
using namespace coopsim::docs;
using coopsim::py_struct::Struct;

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

// What the bindings return beside the engine's own structs: each one an engine struct with the names
// Python reads (the world's bodies by name, not id), bound once below.
struct Contact {  // a ContactPoint of the last world step, its bodies named
  ContactPoint point;
  std::string a, b, kind;
};
struct HeldCooperation {  // Simulation::cooperation's answer: the Cooperation, whether they hold, the body
  Cooperation values;
  bool holding = false;
  py::object body = py::none();
};
struct RobotMetrics {  // a robot's TrackingMetrics with its name
  std::string name;
  TrackingMetrics metrics;
};
struct SensorReading {  // a robot's force/torque sensor and joint torques now
  Vec6 ft_world, ft_clamp, ft_true_world, ft_true_clamp;
  Eigen::Isometry3d pose;
  VecN tau, tau_ext;
};

// The fields of a Cooperation (held_body.hpp) on a class whose `part` gives it.
#define COOPSIM_FIELD(n) .field(#n, [part](const auto& s) { return part(s).n; }, doc_Cooperation_##n)
template <class B, class Part>
void cooperation_fields(B& b, Part part) {
  b COOPSIM_FIELD(centre) COOPSIM_FIELD(point_a) COOPSIM_FIELD(point_b) COOPSIM_FIELD(external) COOPSIM_FIELD(internal)
      COOPSIM_FIELD(squeeze) COOPSIM_FIELD(twist) COOPSIM_FIELD(bending) COOPSIM_FIELD(shear) COOPSIM_FIELD(load_share)
      COOPSIM_FIELD(relative_pose_error);
}
#undef COOPSIM_FIELD

// A table's columns, one per field of its rows' struct, each written once: its name and its value in a
// row, a number (a float64 column) or a Python object (a list).
template <class Row>
struct ColumnField {
  const char* name;
  std::function<double(const Row&)> number;
  std::function<py::object(const Row&)> object;
};
template <class Row>
py::dict columns(const std::vector<Row>& rows, const std::vector<ColumnField<Row>>& fields, size_t first = 0) {
  py::dict d;
  for (const ColumnField<Row>& f : fields) {
    if (f.number) {
      py::array_t<double> col(static_cast<py::ssize_t>(rows.size() - first));
      for (size_t i = first; i < rows.size(); ++i) col.mutable_data()[i - first] = f.number(rows[i]);
      d[py::str(f.name)] = col;
    } else {
      py::list col;
      for (size_t i = first; i < rows.size(); ++i) col.append(f.object(rows[i]));
      d[py::str(f.name)] = col;
    }
  }
  return d;
}

// The options a default-constructed SimulationOptions holds: the one source of the defaults.
const SimulationOptions kDefaults{};
const SensorOptions kSensorDefaults{};

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

// (also bind_schedule.cpp's)
const World& world_of(const Simulation& s) {
  if (!s.world()) throw py::value_error("the simulation has no world (give one: Simulation(world=...))");
  return *s.world();
}

int body_id(const Simulation& s, const std::string& name) { return world_of(s).id(name); }

// A Reference (C++ or Python subclass), or a set-point array held at all times.
std::shared_ptr<const Reference> reference_arg(const py::object& ref, int n) {
  if (py::isinstance<Reference>(ref)) return ref.cast<std::shared_ptr<Reference>>();
  if (ref.is_none())
    throw py::value_error("reference must be a coopsim.Reference (e.g. CubicTrajectory) or a set-point (n,)");
  return std::make_shared<ConstantReference>(vec(ref, n, "reference"));
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



void bind_simulation(py::module_& m) {
  divergence_type = PyErr_NewExceptionWithDoc(
      "coopsim._core.DivergenceError", doc_DivergenceError,
      PyExc_RuntimeError, nullptr);
  m.attr("DivergenceError") = py::reinterpret_borrow<py::object>(divergence_type);
  busy_type = PyErr_NewExceptionWithDoc(
      "coopsim._core.SimulationBusyError", doc_SimulationBusyError,
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

  // ---- the quantities a run exposes: engine structs, each bound once (struct_binding.hpp) ----
  Struct<Contact>(m, "Contact", doc_ContactPoint)
      .member("a", &Contact::a, "the name of body a")
      .member("b", &Contact::b, "the name of body b")
      .member("kind", &Contact::kind, doc_contact_kind)
      .field("point_a", [](const Contact& c) { return c.point.point_a; }, doc_ContactPoint_point_a)
      .field("point_b", [](const Contact& c) { return c.point.point_b; }, doc_ContactPoint_point_b)
      .field("normal", [](const Contact& c) { return c.point.normal; }, doc_ContactPoint_normal)
      .field("depth", [](const Contact& c) { return c.point.depth; }, doc_ContactPoint_depth)
      .field("force", [](const Contact& c) { return c.point.force; }, doc_ContactPoint_force)
      .finish();
  Struct<GraspCheck>(m, "GraspCheck", doc_GraspCheck)
      .member("closing", &GraspCheck::closing, doc_GraspCheck_closing)
      .member("aligned", &GraspCheck::aligned, doc_GraspCheck_aligned)
      .member("touching", &GraspCheck::touching, doc_GraspCheck_touching)
      .member("in_pads", &GraspCheck::in_pads, doc_GraspCheck_in_pads)
      .member("slow", &GraspCheck::slow, doc_GraspCheck_slow)
      .field("ok", [](const GraspCheck& c) { return c.ok(); }, doc_GraspCheck_ok)
      .member("angle", &GraspCheck::angle, doc_GraspCheck_angle)
      .member("gap_fixed", &GraspCheck::gap_fixed, doc_GraspCheck_gap_fixed)
      .member("gap_moving", &GraspCheck::gap_moving, doc_GraspCheck_gap_moving)
      .member("speed", &GraspCheck::speed, doc_GraspCheck_speed)
      .member("angular_speed", &GraspCheck::angular_speed, doc_GraspCheck_angular_speed)
      .member("width", &GraspCheck::width, doc_GraspCheck_width)
      .finish();
  {
    Struct<Cooperation> c(m, "Cooperation", doc_Cooperation);
    cooperation_fields(c, [](const Cooperation& x) -> const Cooperation& { return x; });
    c.finish();
    Struct<HeldCooperation> h(m, "HeldCooperation", doc_Simulation_cooperation);
    h.member("holding", &HeldCooperation::holding, "whether robots a and b hold one body now")
        .field("body", [](const HeldCooperation& x) { return x.body; }, "the name of the body they hold, or None");
    cooperation_fields(h, [](const HeldCooperation& x) -> const Cooperation& { return x.values; });
    h.finish();
  }
  Struct<RobotMetrics> metrics(m, "TrackingMetrics", doc_TrackingMetrics);
  metrics.cls().def(py::pickle(  // results of coopsim.simulate(output="metrics") cross processes
      [](const RobotMetrics& x) { const TrackingMetrics& t = x.metrics;
        return py::make_tuple(x.name, t.steps, to_numpy(t.sum_sq_error), to_numpy(t.max_abs_error), to_numpy(t.max_abs_tau)); },
      [](const py::tuple& t) { auto v = [&t](int k) { return vec(t[k], static_cast<int>(py::len(t[k])), "metrics"); };
        return RobotMetrics{t[0].cast<std::string>(), TrackingMetrics{t[1].cast<long>(), v(2), v(3), v(4)}}; }));
  metrics.member("name", &RobotMetrics::name, doc_Robot_name)
      .field("steps", [](const RobotMetrics& x) { return x.metrics.steps; }, doc_TrackingMetrics_steps)
      .field("rms_error", [](const RobotMetrics& x) { return x.metrics.rms_error(); }, doc_TrackingMetrics_rms_error)
      .field("max_abs_error", [](const RobotMetrics& x) { return x.metrics.max_abs_error; },
             doc_TrackingMetrics_max_abs_error)
      .field("max_abs_tau", [](const RobotMetrics& x) { return x.metrics.max_abs_tau; },
             doc_TrackingMetrics_max_abs_tau)
      .finish();
  {
    Struct<SensorOptions> o(m, "SensorOptions", doc_SensorOptions);
    o.member("noise_force", &SensorOptions::noise_force, doc_SensorOptions_noise_force)
        .member("noise_moment", &SensorOptions::noise_moment, doc_SensorOptions_noise_moment)
        .member("time_constant", &SensorOptions::time_constant, doc_SensorOptions_time_constant)
        .member("seed", &SensorOptions::seed, doc_SensorOptions_seed);
    o.cls().def(py::pickle(
        [](const SensorOptions& x) { return py::make_tuple(x.noise_force, x.noise_moment, x.time_constant, x.seed); },
        [](const py::tuple& t) {
          SensorOptions x;
          x.noise_force = t[0].cast<double>();
          x.noise_moment = t[1].cast<double>();
          x.time_constant = t[2].cast<double>();
          x.seed = t[3].cast<std::int64_t>();
          check_sensor_options(x);
          return x;
        }));
    o.finish();
  }
  Struct<SensorReading>(m, "SensorReading", doc_Simulation_ft_clamp)
      .member("ft_world", &SensorReading::ft_world, doc_Simulation_ft_clamp)
      .member("ft_clamp", &SensorReading::ft_clamp, doc_Simulation_ft_clamp)
      .member("ft_true_world", &SensorReading::ft_true_world, doc_Simulation_ft_clamp)
      .member("ft_true_clamp", &SensorReading::ft_true_clamp, doc_Simulation_ft_clamp)
      .member("pose", &SensorReading::pose, doc_Simulation_sensor_pose)
      .member("tau", &SensorReading::tau, doc_Simulation_tau)
      .member("tau_ext", &SensorReading::tau_ext, doc_Simulation_tau_ext)
      .finish();
  Struct<StepProfile>(m, "StepProfile", doc_StepProfile)
      .member("controllers", &StepProfile::controllers, doc_StepProfile)
      .member("world", &StepProfile::world, doc_StepProfile)
      .member("contacts", &StepProfile::contacts, doc_StepProfile)
      .member("robots", &StepProfile::robots, doc_StepProfile)
      .member("grasp", &StepProfile::grasp, doc_StepProfile_grasp)
      .member("world_steps", &StepProfile::world_steps, doc_StepProfile)
      .finish();

  py::class_<Simulation::Hold>(m, "SimulationHold", doc_Simulation_Hold)
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
           }, py::arg("i"), py::arg("reference"), py::keep_alive<1, 3>(), doc_Simulation_set_reference)
      .def("set_robot", &Simulation::set_robot, py::arg("i"), py::arg("robot"), doc_Simulation_set_robot)
      .def("add_cooperative", &Simulation::add_cooperative, py::arg("controller"), py::arg("robots"),
           py::keep_alive<1, 2>(), doc_Simulation_add_cooperative)
      .def("remove_cooperative", &Simulation::remove_cooperative, py::arg("k"), doc_Simulation_remove_cooperative)
      .def("set_controller", &Simulation::set_controller, py::arg("i"), py::arg("controller"),
           py::keep_alive<1, 3>(), doc_Simulation_set_controller)
      .def("hold", [](Simulation& s, const py::object& label) {
             // a py::object, checked here: pybind11's own message for a wrong type here crashes (3.1.0)
             if (!py::isinstance<py::str>(label))
               throw py::type_error("SimulationCore.hold(): label must be a str, got " +
                                    std::string(py::str(py::type::of(label).attr("__name__"))));
             return s.hold(label.cast<std::string>());
           }, py::arg("label"), py::keep_alive<0, 1>(), doc_Simulation_hold)
      .def_property_readonly("holder", [](const Simulation& s) -> py::object {
             std::thread::id id;
             const std::string label = s.holder(&id);
             if (id == std::thread::id() || label.empty()) return py::none();
             std::ostringstream text;
             text << id;
             return py::make_tuple(label, thread_object(text.str()));
           }, doc_Simulation_holder)
      .def("advance", [](Simulation& s, long n) {
             coopsim::py_nogil::NoGil nogil;
             s.advance(n);
           }, py::arg("n"), doc_Simulation_advance)
      .def("run", [](Simulation& s, double t_end, const py::object& callback, long chunk) {
             coopsim::py_nogil::NoGil nogil;  // the log's reserve copies its rows: without the GIL too
             long total = 0;
             try {
               total = s.steps_until(t_end);
               s.reserve(total);
             } catch (const std::bad_alloc&) {
               coopsim::py_nogil::GilAgain gil;
               const long rows = s.options().log_every > 0 ? total / s.options().log_every : 0;
               PyErr_SetString(PyExc_MemoryError,
                               ("no memory for a log of " + std::to_string(rows) + " rows (" +
                                std::to_string(total) + " steps); log fewer rows with log_every")
                                   .c_str());
               throw py::error_already_set();
             }
             // between chunks: Ctrl-C stops the run with the log kept, then the progress callback
             auto between = [&callback](long done, long all) {
               coopsim::py_nogil::GilAgain gil;
               if (PyErr_CheckSignals() != 0) throw py::error_already_set();
               if (!callback.is_none()) callback(done, all);
               return true;
             };
             return s.run(t_end, chunk, between);
           },
           py::arg("t_end"), py::arg("callback") = py::none(), py::arg("chunk") = 4096, doc_Simulation_run)
      .def("run_until", [](Simulation& s, double t_end, int until, double every, long chunk) {
             // every `chunk` steps on the main thread: Ctrl-C stops the run with the log kept
             std::function<bool(long, long)> between;
             if (coopsim::py_nogil::on_main_thread())
               between = [](long, long) {
                 coopsim::py_nogil::GilAgain gil;
                 if (PyErr_CheckSignals() != 0) throw py::error_already_set();
                 return true;
               };
             coopsim::py_nogil::NoGil nogil;
             return s.run_until(t_end, until, every, chunk, between);
           },
           py::arg("t_end"), py::arg("until"), py::arg("every"), py::arg("chunk") = 4096, doc_Simulation_run_until)
      .def("steps_until", &Simulation::steps_until, py::arg("t_end"), doc_Simulation_steps_until)
      .def("reset", &Simulation::reset, doc_Simulation_reset)
      .def_property_readonly("time", &Simulation::time, doc_Simulation_time)
      .def_property_readonly("steps", &Simulation::step_count, doc_Simulation_step_count)
      .def_property_readonly("dt", [](const Simulation& s) { return s.options().dt; }, doc_SimulationOptions_dt)
      .def_property_readonly("control_every", [](const Simulation& s) { return s.options().control_every; }, doc_SimulationOptions_control_every)
      .def_property_readonly("log_every", [](const Simulation& s) { return s.options().log_every; }, doc_SimulationOptions_log_every)
      .def_property_readonly("end_stops", [](const Simulation& s) { return s.options().end_stops; }, doc_SimulationOptions_end_stops)
      .def_property_readonly("max_speed", [](const Simulation& s) { return s.options().max_speed; }, doc_SimulationOptions_max_speed)
      .def_property_readonly("max_position", [](const Simulation& s) { return s.options().max_position; }, doc_SimulationOptions_max_position)
      .def_property_readonly("robot_count", &Simulation::robot_count, doc_Simulation_robot_count)
      .def_property_readonly("started", &Simulation::started, doc_Simulation_started)
      .def_property_readonly("diverged", &Simulation::diverged, doc_Simulation_diverged)
      .def_property_readonly("integrator", [](const Simulation& s) { return method_name(s.options().integrator); }, doc_SimulationOptions_integrator)
      .def_property_readonly("world", [](const Simulation& s) { return s.world(); }, doc_Simulation_world)
      .def_property_readonly("world_every", [](const Simulation& s) { return s.options().world_every; }, doc_SimulationOptions_world_every)
      .def_property_readonly("contact_forces", [](const Simulation& s) { return s.options().contact_forces; }, doc_SimulationOptions_contact_forces)
      .def_property_readonly("log_contacts", [](const Simulation& s) { return s.options().log_contacts; }, doc_SimulationOptions_log_contacts)
      .def("contacts", [](const Simulation& s) {
             const World& w = world_of(s);
             std::vector<Contact> out;
             for (const ContactPoint& c : w.contacts()) {
               const BodySpec& a = w.body(c.a);
               const BodySpec& b = w.body(c.b);
               out.push_back(Contact{c, a.name, b.name, contact_kind(a, b)});
             }
             return out;
           }, doc_World_contacts)
      .def("set_body_wrench", [](Simulation& s, const std::string& name, const py::object& w) {
             s.set_body_wrench(body_id(s, name), vector_arg<Vec6>(w, 6, "wrench"));
           }, py::arg("name"), py::arg("wrench"), doc_Simulation_set_body_wrench)
      .def("body_wrench", [](const Simulation& s, const std::string& name) {
             return to_numpy(s.body_wrench(body_id(s, name)));
           }, py::arg("name"))
      .def("body_state", [](const Simulation& s, const std::string& name) {
             return s.body_state(body_id(s, name));
           }, py::arg("name"), doc_Simulation_body_state)
      .def("holding", [](const Simulation& s, int i) -> py::object {
             const int id = s.holding(i);
             if (id < 0) return py::none();
             return py::str(world_of(s).body(id).name);
           }, py::arg("i"), doc_Simulation_holding)
      .def("release", &Simulation::release, py::arg("i"), doc_Simulation_release)
      .def("weld_wrench", [](const Simulation& s, int i) { return to_numpy(s.weld_wrench(i)); }, py::arg("i"),
           doc_Simulation_weld_wrench)
      .def("grasp_check", [](Simulation& s, int i, const std::string& body) {
             return s.grasp_check(i, body_id(s, body));
           }, py::arg("i"), py::arg("body"), doc_Simulation_grasp_check)
      .def("grasp_options", [](const Simulation& s) { return grasp_options_dict(s.options().grasp); },
           "The clamp rule's options of this simulation: {name: value} (see simulation_defaults()).")
      .def_property_readonly("grasp", [](const Simulation& s) { return s.options().grasp.enabled; })
      .def("grasp_events", [](const Simulation& s) {
             const World* w = s.world().get();
             auto name = [w](int id) -> py::object { return py::str(w->body(id).name); };
             return columns<GraspEvent>(s.grasp_events(), {
                 {"t", [](const GraspEvent& e) { return e.t; }, nullptr},
                 {"robot", nullptr, [](const GraspEvent& e) { return py::int_(e.robot); }},
                 {"body", nullptr, [name](const GraspEvent& e) { return name(e.body); }},
                 {"event", nullptr, [](const GraspEvent& e) { return py::str(e.grasp ? "grasp" : "release"); }},
                 {"reason", nullptr, [](const GraspEvent& e) { return py::str(e.reason); }}});
           }, doc_GraspEvent)
      .def("link_body_state", [](const Simulation& s, int i, int box) {
             const int id = s.link_body(i, box);
             if (id < 0) throw py::value_error("the robots' link bodies join the world at the first step");
             return world_of(s).state(id);
           }, py::arg("i"), py::arg("box"), doc_Simulation_link_body)
      .def("free_body_names", [](const Simulation& s) {
             return s.world() ? s.world()->names(s.world()->free_bodies()) : std::vector<std::string>();
           })
      .def("body_log", [](const Simulation& s) {
             py::list out;
             for (const LogColumn& c : s.body_log()) out.append(view(c, s.log_rows(), true));
             return out;
           }, doc_Simulation_body_log)
      .def("contact_events", [](const Simulation& s, std::int64_t first) {
             if (!s.world()) return py::dict();
             const World& w = *s.world();
             const auto count = static_cast<std::int64_t>(w.events().size());
             if (first < 0 || first > count)
               throw py::value_error("first must be 0 .. " + std::to_string(count) + " (the events so far), got " +
                                     std::to_string(first));
             return columns<ContactEvent>(w.events(), {
                 {"a", nullptr, [&w](const ContactEvent& e) { return py::str(w.body(e.a).name); }},
                 {"b", nullptr, [&w](const ContactEvent& e) { return py::str(w.body(e.b).name); }},
                 {"kind", nullptr, [&w](const ContactEvent& e) { return py::str(contact_kind(w.body(e.a), w.body(e.b))); }},
                 {"begin", [](const ContactEvent& e) { return e.begin; }, nullptr},
                 {"end", [](const ContactEvent& e) { return e.end; }, nullptr},
                 {"peak_force", [](const ContactEvent& e) { return e.peak_force; }, nullptr},
                 {"max_depth", [](const ContactEvent& e) { return e.max_depth; }, nullptr},
                 {"steps", [](const ContactEvent& e) { return static_cast<double>(e.steps); }, nullptr}},
                 static_cast<size_t>(first));
           }, py::arg("first") = 0,
           "The world's contact events, from the `first` on (0: every one; a caller that looks after each piece "
           "of a run passes the count it has seen and gets only the new ones), as columns: a, b (body names), "
           "kind, begin, end (s; NaN while the contact lasts), peak_force (N, the largest magnitude of the pair's "
           "total force), max_depth (m), steps (world steps in contact). An event is a contact between two bodies "
           "from the first world step where they touch to the first where they no longer do. {} without a world; "
           "ValueError for a `first` outside 0 .. the count so far.")
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
           doc_Simulation_set_sensor)
      .def("sensor_options", [](const Simulation& s, int i) { return s.sensor_options(i); },
           py::arg("i"), doc_SensorOptions)
      .def("sensor", [](Simulation& s, int i) {
             return SensorReading{s.ft_world(i), s.ft_clamp(i), s.ft_true_world(i), s.ft_true_clamp(i),
                                  s.sensor_pose(i), s.tau(i), s.tau_ext(i)};
           }, py::arg("i"), doc_Simulation_ft_clamp)
      .def("sensor_log", [](const Simulation& s, int i) { return view(s.log(i).ft, s.log_rows(), true); },
           py::arg("i"), "Robot i's force/torque reading per log row, (rows, 12): world axes (6), sensor frame (6).")
      .def("cooperation", [](Simulation& s, int a, int b) {
             HeldCooperation out;
             out.values = s.cooperation(a, b, &out.holding);
             if (out.holding && s.world() && s.holding(a) >= 0) out.body = py::str(s.world()->body(s.holding(a)).name);
             return out;
           }, py::arg("a"), py::arg("b"), doc_Simulation_cooperation)
      .def("cooperation_log", [](Simulation& s, int a, int b) {
             return view(s.cooperation_log(a, b), s.log_rows(), true);
           }, py::arg("a"), py::arg("b"), doc_Simulation_cooperation_log)
      .def("grasp_log", &grasp_log, py::arg("i"),
           "Robot i's grasp per log row, (rows, 7): the world id of the body held (-1: none), the weld's force "
           "(3) N and moment (3) N m on it.")
      .def("contact_log", [](const Simulation& s) {
             if (!s.world()) return py::dict();
             const World& w = *s.world();
             using L = LoggedContact;
             return columns<L>(s.contact_log(), {
                 {"t", [](const L& c) { return c.t; }, nullptr},
                 {"a", nullptr, [&w](const L& c) { return py::str(w.body(c.contact.a).name); }},
                 {"b", nullptr, [&w](const L& c) { return py::str(w.body(c.contact.b).name); }},
                 {"point_x", [](const L& c) { return c.contact.point_a.x(); }, nullptr},
                 {"normal_x", [](const L& c) { return c.contact.normal.x(); }, nullptr},
                 {"force_x", [](const L& c) { return c.contact.force.x(); }, nullptr},
                 {"point_y", [](const L& c) { return c.contact.point_a.y(); }, nullptr},
                 {"normal_y", [](const L& c) { return c.contact.normal.y(); }, nullptr},
                 {"force_y", [](const L& c) { return c.contact.force.y(); }, nullptr},
                 {"point_z", [](const L& c) { return c.contact.point_a.z(); }, nullptr},
                 {"normal_z", [](const L& c) { return c.contact.normal.z(); }, nullptr},
                 {"force_z", [](const L& c) { return c.contact.force.z(); }, nullptr},
                 {"depth", [](const L& c) { return c.contact.depth; }, nullptr}});
           }, doc_ContactPoint)
      .def_static("excluded_pairs", [](const Robot& r, int samples) { return Simulation::excluded_pairs(r, samples); },
                  py::arg("robot"), py::arg("samples") = Simulation::kExclusionSamples, doc_Simulation_excluded_pairs)
      .def("set_profiling", &Simulation::set_profiling, py::arg("on"))
      .def("profile", [](const Simulation& s) { return s.profile(); }, doc_StepProfile)
      .def("robot", [](const Simulation& s, int i) { return s.robot(i); }, py::arg("i"),
           "Robot i as simulated (robots are immutable: this equals the robot added).")
      .def("controller", [](const Simulation& s, int i) { return s.controller(i); }, py::arg("i"))
      .def("reference", [](const Simulation& s, int i) { return std::const_pointer_cast<Reference>(s.reference(i)); },
           py::arg("i"))
      .def("set_applied", [](Simulation& s, int i, const py::object& forces, const py::object& wrenches) {
             const int n = s.robot(i).dof();
             if (!forces.is_none()) s.set_applied_forces(i, vec(forces, n, "forces"));
             if (!wrenches.is_none()) s.set_applied_wrenches(i, wrenches_arg(wrenches, "wrenches"));
           }, py::arg("i"), py::arg("forces") = py::none(), py::arg("wrenches") = py::none(), doc_Simulation_set_applied_forces)
      .def("applied", [](const Simulation& s, int i) {
             return py::make_tuple(to_numpy(s.applied_forces(i)), s.applied_wrenches(i));
           }, py::arg("i"), "(forces (n,), wrenches [Wrench]) applied to robot i now.")
      .def("tau_ext", [](const Simulation& s, int i) { return to_numpy(s.tau_ext(i)); }, py::arg("i"),
           doc_Simulation_tau_ext)
      .def("state", [](const Simulation& s, int i) { return py::make_tuple(to_numpy(s.q(i)), to_numpy(s.qd(i))); },
           py::arg("i"), "(q, qd) of robot i now, each (n,).")
      .def("torque", [](const Simulation& s, int i) { return to_numpy(s.tau(i)); }, py::arg("i"),
           doc_Simulation_tau)
      .def("initial_state", [](const Simulation& s, int i) {
             return py::make_tuple(to_numpy(s.initial_q(i)), to_numpy(s.initial_qd(i)));
           }, py::arg("i"))
      .def_property_readonly("log_rows", &Simulation::log_rows, doc_Simulation_log_rows)
      .def("log_t", [](const Simulation& s) { return view(s.log_t(), s.log_rows(), false); },
           "Logged times (rows,), s: a read-only view that later steps do not change.")
      .def("log", &log_dict, py::arg("i"),
           "Robot i's log as a dict of (rows, n) arrays, one per quantity of log_schema(): read-only views "
           "of the rows so far, which later steps and reset() do not change.")
      .def("metrics", [](const Simulation& s, int i) { return RobotMetrics{s.robot(i).name(), s.metrics(i)}; },
           py::arg("i"), doc_TrackingMetrics);

  m.def("simulation_defaults", []() {
    using namespace py::literals;
    const SimulationOptions& o = kDefaults;
    return py::dict("dt"_a = o.dt, "control_every"_a = o.control_every, "log_every"_a = o.log_every,
                    "end_stops"_a = o.end_stops, "max_speed"_a = o.max_speed, "max_position"_a = o.max_position,
                    "integrator"_a = method_name(o.integrator), "world_every"_a = o.world_every,
                    "contact_forces"_a = o.contact_forces, "log_contacts"_a = o.log_contacts,
                    "grasp"_a = o.grasp.enabled, "grasp_options"_a = grasp_options_dict(o.grasp));
  }, doc_SimulationOptions);

  m.def("sensor_defaults", []() { return kSensorDefaults; }, doc_SensorOptions);

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
    return (cooperation(vector_arg<V3>(centre, 3, "centre"), vector_arg<V3>(point_a, 3, "point_a"),
                                        vector_arg<Vec6>(wrench_a, 6, "wrench_a"), vector_arg<V3>(point_b, 3, "point_b"),
                                        vector_arg<Vec6>(wrench_b, 6, "wrench_b"), vector_arg<V3>(up, 3, "up")));
  }, py::arg("centre"), py::arg("point_a"), py::arg("wrench_a"), py::arg("point_b"), py::arg("wrench_b"),
     py::arg("up") = std::vector<double>{0.0, 0.0, 1.0},
     doc_cooperation);

  m.def("pair_readout", [](const std::vector<Simulation*>& sims, int a, int b, const std::string& body) {
         Simulation::ReadoutRows rows;
         { coopsim::py_nogil::NoGil nogil; rows = Simulation::pair_readout(sims, a, b, body); }
         return to_numpy(rows);
       }, py::arg("sims"), py::arg("a"), py::arg("b"), py::arg("body"), doc_Simulation_pair_readout);
  m.def("gil_released_seconds", &coopsim::py_nogil::released_seconds,
        "Wall seconds the calling thread spent in the engine's calls with the GIL released (a running total; "
        "coopsim.gil_released_seconds).");
}
