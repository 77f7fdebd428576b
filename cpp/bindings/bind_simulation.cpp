// The simulation loop. Stepping runs with the GIL released; Python
// controllers and references take it back for their own calls only.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>

#include "convert.hpp"
#include "coopsim/simulation.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

PyObject* divergence_type = nullptr;  // coopsim.DivergenceError, lives as long as the interpreter

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

py::dict metrics_dict(const Simulation& s, int i) {
  const TrackingMetrics& m = s.metrics(i);
  py::dict d;
  d["steps"] = m.steps;
  d["rms_error"] = to_numpy(m.rms_error());
  d["max_abs_error"] = to_numpy(m.max_abs_error);
  d["max_abs_tau"] = to_numpy(m.max_abs_tau);
  return d;
}

}  // namespace

void bind_simulation(py::module_& m) {
  divergence_type = PyErr_NewExceptionWithDoc(
      "coopsim._core.DivergenceError",
      "The simulation diverged (non-finite or runaway state, or a non-finite torque). Attributes: step, time "
      "(s), robot (index), q, qd (the rejected state). The simulation keeps its log up to the last good step.",
      PyExc_RuntimeError, nullptr);
  m.attr("DivergenceError") = py::reinterpret_borrow<py::object>(divergence_type);
  py::register_local_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const DivergenceError& e) {
      py::object inst = divergence_object(e);
      PyErr_SetObject(divergence_type, inst.ptr());
    }
  });

  py::class_<Simulation>(m, "SimulationCore", R"doc(
The C++ simulation loop behind coopsim.Simulation (use that class): robots
with controllers and references, RK4 at a fixed dt, zero-order hold of the
torques between controller updates, the log and tracking metrics.)doc")
      .def(py::init([](double dt, int control_every, int log_every, bool end_stops, double max_speed,
                       double max_position, const std::string& integrator) {
             SimulationOptions o;
             o.dt = dt;
             o.control_every = control_every;
             o.log_every = log_every;
             o.end_stops = end_stops;
             o.max_speed = max_speed;
             o.max_position = max_position;
             o.integrator = method_from_name(integrator, "integrator");
             return Simulation(o);
           }),
           py::arg("dt") = 2e-4, py::arg("control_every") = 1, py::arg("log_every") = 1, py::arg("end_stops") = true,
           py::arg("max_speed") = 1e4, py::arg("max_position") = 1e6, py::arg("integrator") = "rk4")
      .def("add_robot", [](Simulation& s, const Robot& robot, std::shared_ptr<Controller> controller,
                           const py::object& reference, const py::object& q0, const py::object& qd0) {
             const int n = robot.dof();
             VecN q0v, qd0v;
             if (!q0.is_none()) q0v = vec(q0, n, "q0");
             if (!qd0.is_none()) qd0v = vec(qd0, n, "qd0");
             auto ref = reference_arg(reference, n);
             return s.add_robot(robot, std::move(controller), std::move(ref), q0.is_none() ? nullptr : q0v.data(),
                                qd0.is_none() ? nullptr : qd0v.data());
           },
           py::arg("robot"), py::arg("controller"), py::arg("reference"), py::arg("q0") = py::none(),
           py::arg("qd0") = py::none(), py::keep_alive<1, 3>(), py::keep_alive<1, 4>(),
           "Adds a robot (copied); returns its index.")
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

  m.def("log_schema", []() {
    py::list out;
    for (const LogQuantityInfo& q : log_schema()) out.append(py::make_tuple(q.name, q.doc));
    return out;
  }, "The quantities a simulation logs per robot, in column order: [(name, description)], one column per joint.");

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
