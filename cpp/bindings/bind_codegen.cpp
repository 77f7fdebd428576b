// Generated dynamics from Python: loading libraries built by
// coopsim.codegen.compile and describing what a robot has attached.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "coopsim/generated.hpp"
#include "coopsim/robot.hpp"

namespace py = pybind11;
using namespace coopsim;

void bind_codegen(py::module_& m) {
  m.def("load_generated_library", &register_generated_library, py::arg("path"),
        "Loads a shared library built by coopsim.codegen.compile, registers its generated dynamics under the "
        "name it carries (attach with Robot.with_generated) and returns that name.");
  m.def("generated_cache_dir", &generated_cache_dir,
        "Folder where libraries of coopsim.codegen.compile are looked up by name (e.g. when unpickling): "
        "$COOPSIM_CACHE_DIR, else $XDG_CACHE_HOME/coopsim, else ~/.cache/coopsim.");
  m.def("generated_info", [](const Robot& r) -> py::object {
    if (!r.has_generated()) return py::none();
    const GeneratedDynamics& g = *r.generated();
    py::dict d;
    d["name"] = g.name;
    d["dof"] = g.dof;
    d["joint_types"] = g.joint_types;
    d["angles"] = g.angles;
    d["generator_version"] = g.generator_version;
    d["operation_count"] = g.operation_count;
    d["in_use"] = r.uses_generated();
    d["derivatives"] = g.derivatives != nullptr;
    return d;
  }, py::arg("robot"),
  "The generated dynamics attached to `robot` as a dict (name, dof, joint_types, angles, generator_version, "
  "operation_count, in_use, derivatives: whether it carries the dynamics' derivatives), or None.");
}
