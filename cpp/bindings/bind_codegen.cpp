// Generated dynamics from Python: loading libraries built by
// coopsim.codegen.compile and describing what a robot has attached.
#include <dlfcn.h>

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "coopsim/generated.hpp"
#include "coopsim/robot.hpp"

namespace py = pybind11;
using namespace coopsim;

namespace {

template <class F>
F symbol(void* handle, const std::string& path, const char* name) {
  void* s = dlsym(handle, name);
  if (!s) throw py::value_error("path: " + path + " lacks the symbol " + name + " (not built by coopsim.codegen?)");
  return reinterpret_cast<F>(s);
}

// Opens the library (kept open for the process lifetime: robots may hold its
// functions) and registers its functions under `name`.
void load_library(const std::string& path, const std::string& name, int dof, const std::string& joint_types,
                  const std::vector<double>& angles, const std::string& generator_version,
                  long operation_count) {
  if (name.empty()) throw py::value_error("name must not be empty");
  if (dof < 1 || dof > kMaxDof) throw py::value_error("dof must be 1.." + std::to_string(kMaxDof));
  if (static_cast<int>(joint_types.size()) != dof)
    throw py::value_error("joint_types must have dof letters, got '" + joint_types + "'");
  if (static_cast<int>(angles.size()) != 4 * dof) throw py::value_error("angles must have 4 * dof entries");
  void* h = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!h) {
    const char* err = dlerror();
    throw py::value_error("path: cannot load " + path + ": " + (err ? err : "unknown error"));
  }
  auto dof_fn = symbol<int (*)()>(h, path, "coopsim_gen_dof");
  if (dof_fn() != dof)
    throw py::value_error("path: " + path + " was generated for " + std::to_string(dof_fn()) + " joints, not " +
                          std::to_string(dof));
  auto g = std::make_shared<GeneratedDynamics>();
  g->name = name;
  g->dof = dof;
  g->joint_types = joint_types;
  g->angles = angles;
  g->generator_version = generator_version;
  g->operation_count = operation_count;
  g->mass_matrix = symbol<decltype(g->mass_matrix)>(h, path, "coopsim_gen_mass_matrix");
  g->coriolis = symbol<decltype(g->coriolis)>(h, path, "coopsim_gen_coriolis");
  g->coriolis_matrix = symbol<decltype(g->coriolis_matrix)>(h, path, "coopsim_gen_coriolis_matrix");
  g->gravity = symbol<decltype(g->gravity)>(h, path, "coopsim_gen_gravity");
  g->dynamics = symbol<decltype(g->dynamics)>(h, path, "coopsim_gen_dynamics");
  g->solve = symbol<decltype(g->solve)>(h, path, "coopsim_gen_solve");
  register_generated(std::move(g));
}

}  // namespace

void bind_codegen(py::module_& m) {
  m.def("load_generated_library", &load_library, py::arg("path"), py::arg("name"), py::arg("dof"),
        py::arg("joint_types"), py::arg("angles"), py::arg("generator_version"), py::arg("operation_count"),
        "Loads a shared library built by coopsim.codegen.compile and registers its generated dynamics as "
        "`name` (attach with attach_builtin_generated). angles: 4 * dof structural angles (rad), per link "
        "dh theta, dh alpha, com theta, com alpha.");
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
    return d;
  }, py::arg("robot"),
  "The generated dynamics attached to `robot` as a dict (name, dof, joint_types, angles, generator_version, "
  "operation_count, in_use), or None.");
}
