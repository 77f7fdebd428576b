// A simulation's model shared by runs (simulation_model.hpp): SimulationModel, and the
// SimulationCore's side of it (model(), from_model, its cooperative groups).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>

#include "coopsim/simulation.hpp"
#include "generated/docstrings.hpp"

namespace py = pybind11;
using namespace coopsim;

void bind_model(py::module_& m) {
  py::class_<SimulationModel, std::shared_ptr<SimulationModel>>(m, "SimulationModel", R"doc(
What a simulation is, apart from where it is (simulation_model.hpp): its options, its robots as
configured (controller, reference, initial state, sensor) and cooperative groups, and its world's
description. Given by coopsim.Simulation.model(); coopsim.Simulation.from_model(model) makes a run of it
with data of its own. Runs of one model share it; it does not change while shared.)doc")
      .def_property_readonly("robot_count", &SimulationModel::robot_count, "Number of robots.")
      .def_property_readonly("dt", [](const SimulationModel& mo) { return mo.options.dt; }, "Step size, s.")
      .def_property_readonly("has_world", [](const SimulationModel& mo) { return mo.world.has_value(); },
                             "Whether the model describes a world (its runs each build their own).")
      .def("robot", [](const SimulationModel& mo, int i) {
             if (i < 0 || i >= mo.robot_count())
               throw py::index_error("robot index " + std::to_string(i) + " out of range");
             return mo.robots[i].robot;
           }, py::arg("i"), "Robot i as configured (a copy).");

  auto core = py::reinterpret_borrow<py::class_<Simulation>>(m.attr("SimulationCore"));
  core.def_static("from_model", [](std::shared_ptr<SimulationModel> model) { return Simulation(std::move(model)); },
                  py::arg("model"), "A run of `model` at t = 0 with data of its own: controllers copied, a world of its own.")
      .def("model", [](Simulation& s) { return std::const_pointer_cast<SimulationModel>(s.model()); }, docs::doc_Simulation_model)
      .def_property_readonly("cooperative_count", &Simulation::cooperative_count,
                             "Number of cooperative groups added (removed ones included).")
      .def("cooperative_group", [](const Simulation& s, int k) {
             return py::make_tuple(s.cooperative(k), s.cooperative_robots(k), s.cooperative_active(k));
           }, py::arg("k"), "Group k: (its live CooperativeController, its robots' indices, whether it drives).");
}
