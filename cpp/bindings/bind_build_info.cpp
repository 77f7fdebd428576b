// What the build of this module knows of itself: the compiler, its flags, the build type and the libraries
// compiled in (coopsim._core.build_toolchain). The values come from CMake (COOPSIM_BUILD_* definitions on
// this file alone, CMakeLists.txt) and from the compiler's and libraries' own macros.
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <string>

namespace py = pybind11;

#ifndef COOPSIM_BUILD_COMPILER
#define COOPSIM_BUILD_COMPILER ""
#endif
#ifndef COOPSIM_BUILD_FLAGS
#define COOPSIM_BUILD_FLAGS ""
#endif
#ifndef COOPSIM_BUILD_TYPE
#define COOPSIM_BUILD_TYPE ""
#endif

namespace {

#define COOPSIM_STR2(x) #x
#define COOPSIM_STR(x) COOPSIM_STR2(x)

std::string compiler_version() {
#if defined(__clang__)
  return std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  return std::string("GCC ") + __VERSION__;
#elif defined(_MSC_VER)
  return std::string("MSVC ") + COOPSIM_STR(_MSC_FULL_VER);
#else
  return "unknown";
#endif
}

}  // namespace

void bind_build_info(py::module_& m) {
  m.def("build_toolchain", []() {
    py::dict d;
    d["compiler"] = std::string(COOPSIM_BUILD_COMPILER);
    d["compiler_version"] = compiler_version();
    d["build_type"] = std::string(COOPSIM_BUILD_TYPE);
    d["flags"] = std::string(COOPSIM_BUILD_FLAGS);
    d["cxx_standard"] = static_cast<long>(__cplusplus);
    d["eigen"] = std::string(COOPSIM_STR(EIGEN_WORLD_VERSION) "." COOPSIM_STR(EIGEN_MAJOR_VERSION) "."
                             COOPSIM_STR(EIGEN_MINOR_VERSION));
    d["pybind11"] = std::string(COOPSIM_STR(PYBIND11_VERSION_MAJOR) "." COOPSIM_STR(PYBIND11_VERSION_MINOR) "."
                                COOPSIM_STR(PYBIND11_VERSION_PATCH));
    return d;
  },
  "How this module was built, as a dict of str (cxx_standard an int): compiler (CMake's compiler id and "
  "version), compiler_version (the compiler's own version string), build_type (CMake's, e.g. 'Release'), "
  "flags (the C++ flags of that build type and the sanitizers' flags; the engine adds -Wall -Wextra), "
  "cxx_standard (__cplusplus), eigen and pybind11 (the versions compiled in). Empty strings where the build "
  "did not say (a build outside CMake).");
}
