// The engine's schedule (schedule.hpp), run with the GIL released: coopsim.Simulation.run_schedule
// hands its steps over as plain tuples (coopsim/schedule.py builds them) and gets a dict back.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <exception>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "convert.hpp"
#include "coopsim/schedule.hpp"
#include "generated/docstrings.hpp"
#include "struct_binding.hpp"
#include "coopsim/world.hpp"
#include "nogil.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;
using namespace coopsim::docs;
using coopsim::py_struct::Struct;

py::object exception_object(const std::exception_ptr& p);                        // bind_simulation.cpp
const World& world_of(const Simulation& s);                                        // bind_simulation.cpp
int body_id(const Simulation& s, const std::string& name);                         // bind_simulation.cpp
std::shared_ptr<const Reference> reference_arg(const py::object& ref, int n);     // bind_simulation.cpp

namespace {

// (robot, body name or None) pairs
std::vector<ScheduleCondition> conditions(const Simulation& sim, const py::handle& list, const std::string& where) {
  std::vector<ScheduleCondition> out;
  for (const py::handle& item : py::reinterpret_borrow<py::sequence>(list)) {
    const auto t = py::reinterpret_borrow<py::tuple>(item);
    ScheduleCondition c;
    c.robot = t[0].cast<int>();
    if (!t[1].is_none()) {
      try {
        c.body = body_id(sim, t[1].cast<std::string>());
      } catch (const std::exception& e) {
        throw py::value_error(where + ": " + e.what());
      }
    }
    out.push_back(c);
  }
  return out;
}

// An action's tuple (kind, arguments...) read for `sim`, throwing what the arguments' conversions throw.
ScheduleAction parse_action(const Simulation& sim, const py::tuple& t, const std::string& kind) {
  ScheduleAction a;
  auto robot = [&](const py::handle& h) {  // checked here: set_reference reads the robot's dof
    const int i = h.cast<int>();
    if (i < 0 || i >= sim.robot_count())
      throw py::value_error("robot " + std::to_string(i) + " out of range (0 .. " +
                            std::to_string(sim.robot_count() - 1) + ")");
    return i;
  };
  if (kind == "set_controller") {
    a.kind = ScheduleAction::kSetController;
    a.robot = robot(t[1]);
    a.controller = t[2].cast<std::shared_ptr<Controller>>();
  } else if (kind == "set_reference") {
    a.kind = ScheduleAction::kSetReference;
    a.robot = robot(t[1]);
    a.reference = reference_arg(py::reinterpret_borrow<py::object>(t[2]), sim.robot(a.robot).dof());
  } else if (kind == "add_cooperative") {
    a.kind = ScheduleAction::kAddCooperative;
    a.cooperative = t[1].cast<std::shared_ptr<CooperativeController>>();
    a.robots = t[2].cast<std::vector<int>>();
  } else if (kind == "remove_cooperative") {
    a.kind = ScheduleAction::kRemoveCooperative;
    a.group = t[1].is_none() ? -1 : t[1].cast<int>();
  } else if (kind == "set_body_wrench") {
    a.kind = ScheduleAction::kSetBodyWrench;
    a.body = body_id(sim, t[1].cast<std::string>());
    a.wrench = vector_arg<Vec6>(t[2], 6, "wrench");
  } else if (kind == "release") {
    a.kind = ScheduleAction::kRelease;
    a.robot = robot(t[1]);
  } else {
    throw py::value_error("unknown action '" + kind + "'");
  }
  return a;
}

// An action's tuple as the engine's action, its controller, reference or law kept alive by the simulation
// (as set_controller's keep_alive does); ValueError naming the step and the action for a bad argument.
ScheduleAction action(const py::object& sim_obj, const Simulation& sim, const py::handle& item,
                      const std::string& where) {
  const auto t = py::reinterpret_borrow<py::tuple>(item);
  const std::string kind = t[0].cast<std::string>();
  const std::string at = where + " (" + kind + "): ";
  ScheduleAction a;
  try {
    a = parse_action(sim, t, kind);
  } catch (const py::cast_error&) {
    throw py::value_error(at + "an argument of the wrong type in " + std::string(py::repr(item)));
  } catch (const std::exception& e) {  // ValueErrors of the conversions, the world's unknown body
    throw py::value_error(at + e.what());
  }
  if (a.controller || a.reference) py::detail::keep_alive_impl(sim_obj, t[2]);
  if (a.cooperative) py::detail::keep_alive_impl(sim_obj, t[1]);
  return a;
}

}  // namespace

void bind_schedule(py::module_& m) {
  Struct<ScheduleRecord>(m, "ScheduleRecord", doc_ScheduleRecord)
      .member("step", &ScheduleRecord::step, doc_ScheduleRecord_step)
      .member("condition", &ScheduleRecord::condition, doc_ScheduleRecord_condition)
      .member("t", &ScheduleRecord::t, doc_ScheduleRecord_t)
      .member("q", &ScheduleRecord::q, doc_ScheduleRecord_q)
      .member("pose", &ScheduleRecord::pose, doc_ScheduleRecord_pose)
      .finish();
  Struct<ScheduleOutcome>(m, "ScheduleOutcome", doc_ScheduleOutcome)
      .member("times", &ScheduleOutcome::times, doc_ScheduleOutcome_times)
      .member("groups", &ScheduleOutcome::groups, doc_ScheduleOutcome_groups)
      .member("records", &ScheduleOutcome::records, doc_ScheduleOutcome_records)
      .member("contacts_seen", &ScheduleOutcome::contacts_seen, doc_ScheduleOutcome_contacts_seen)
      .member("failed_step", &ScheduleOutcome::failed_step, doc_ScheduleOutcome_failed_step)
      .member("kind", &ScheduleOutcome::kind, doc_ScheduleOutcome_kind)
      .member("condition", &ScheduleOutcome::condition, doc_ScheduleOutcome_condition)
      .member("t", &ScheduleOutcome::t, doc_ScheduleOutcome_t)
      .member("bodies", &ScheduleOutcome::bodies, doc_ScheduleOutcome_bodies)
      .member("reason", &ScheduleOutcome::reason, doc_ScheduleOutcome_reason)
      .field("error", [](const ScheduleOutcome& o) { return o.error ? exception_object(o.error) : py::none(); },
             doc_ScheduleOutcome_error)
      .finish();
  m.def("run_schedule", [](py::object sim_obj, const py::list& steps, bool check_contacts, const py::list& allowed,
                           long contacts_seen) {
    Simulation& sim = sim_obj.cast<Simulation&>();
    Schedule s;
    s.check_contacts = check_contacts;
    for (size_t k = 0; k < steps.size(); ++k) {
      const auto t = steps[k].cast<py::tuple>();
      ScheduleStep st;
      st.name = t[0].cast<std::string>();
      const std::string where = "schedule step " + std::to_string(k + 1) + " ('" + st.name + "')";
      st.until = t[1].cast<double>();
      st.every = t[2].cast<double>();
      const auto acts = py::reinterpret_borrow<py::sequence>(t[3]);
      for (size_t j = 0; j < acts.size(); ++j)
        st.actions.push_back(action(sim_obj, sim, acts[j], where + ", action " + std::to_string(j + 1)));
      st.hold = conditions(sim, t[4], where + ", hold");
      st.wait = conditions(sim, t[5], where + ", wait");
      st.at_end = conditions(sim, t[6], where + ", at_end");
      st.record = conditions(sim, t[7], where + ", record");
      s.steps.push_back(std::move(st));
    }
    for (const py::handle& item : allowed) {
      const auto t = py::reinterpret_borrow<py::tuple>(item);
      ContactRule r;
      r.a = t[0].cast<std::string>();
      r.b = t[1].cast<std::string>();
      r.from = t[2].cast<double>();
      r.to = t[3].cast<double>();
      s.allowed.push_back(std::move(r));
    }
    ScheduleOutcome o;
    {
      // between pieces on the main thread: Ctrl-C stops the run, the state and log consistent
      std::function<void()> between;
      if (coopsim::py_nogil::on_main_thread())
        between = []() {
          coopsim::py_nogil::GilAgain gil;
          if (PyErr_CheckSignals() != 0) throw py::error_already_set();
        };
      coopsim::py_nogil::NoGil nogil;
      o = run_schedule(sim, s, contacts_seen, between);
    }
    return o;
  }, py::arg("sim"), py::arg("steps"), py::arg("check_contacts"), py::arg("allowed"), py::arg("contacts_seen"),
     "The engine's schedule (coopsim.Simulation.run_schedule builds its arguments): steps as tuples (name, until, "
     "every, actions, hold, wait, at_end, record), the allowed contacts as (a, b, from, to). Returns a ScheduleOutcome.");
}
