// The compiled core of coopsim. Each area binds itself in bind_<area>.cpp.
#include <pybind11/pybind11.h>

namespace py = pybind11;

void bind_robot(py::module_& m);
void bind_derivatives(py::module_& m);
void bind_integrator(py::module_& m);
void bind_codegen(py::module_& m);
void bind_trajectory(py::module_& m);
void bind_ik(py::module_& m);
void bind_control(py::module_& m);
void bind_task(py::module_& m);
void bind_cooperative(py::module_& m);
void bind_world(py::module_& m);
void bind_simulation(py::module_& m);
void bind_batch(py::module_& m);
void bind_schedule(py::module_& m);
void bind_model(py::module_& m);
void bind_build_info(py::module_& m);
void short_type_errors(py::module_& m);

PYBIND11_MODULE(_core, m) {
  m.doc() = "coopsim engine: robot models, dynamics, integration and collisions (C++, Eigen, Bullet)";
#ifdef COOPSIM_OPTIMISED
  m.attr("build_optimised") = true;
#else
  m.attr("build_optimised") = false;
#endif
  // the sanitizers this module and the engine were built with (CMake's COOPSIM_SANITIZE), "" for none
#ifdef COOPSIM_SANITIZERS
  m.attr("build_sanitizers") = COOPSIM_SANITIZERS;
#else
  m.attr("build_sanitizers") = "";
#endif
  bind_robot(m);
  bind_derivatives(m);
  bind_integrator(m);
  bind_codegen(m);
  bind_trajectory(m);
  bind_ik(m);
  bind_control(m);
  bind_task(m);
  bind_cooperative(m);
  bind_world(m);
  bind_simulation(m);
  bind_batch(m);
  bind_schedule(m);
  bind_model(m);
  bind_build_info(m);
  // last, once every function is bound: a wrong argument type is one short TypeError (short_errors.cpp)
  short_type_errors(m);
}
