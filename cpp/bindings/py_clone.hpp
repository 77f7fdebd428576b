// A Python subclass of an engine interface (Controller, TaskController, CooperativeController)
// copied for another run of one model (SimulationModel): copy.deepcopy of its Python object, kept
// alive by the returned pointer (released under the GIL), so that its overrides stay reachable.
#pragma once

#include <pybind11/pybind11.h>

#include <memory>

namespace coopsim::py_convert {

template <class Base>
std::shared_ptr<Base> python_clone(const Base* self) {
  namespace py = pybind11;
  py::gil_scoped_acquire gil;
  py::object copy = py::module_::import("copy").attr("deepcopy")(py::cast(self));
  Base* raw = copy.cast<Base*>();
  auto keep = std::make_shared<py::object>(std::move(copy));
  return std::shared_ptr<Base>(raw, [keep](Base*) mutable {
    py::gil_scoped_acquire release_gil;
    keep.reset();
  });
}

}  // namespace coopsim::py_convert
