// Generated dynamics in shared libraries built by coopsim.codegen.compile:
// loading one by path, and finding one by name in the build cache, so that a
// pickled robot gets its code back in another process.
#include <dlfcn.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "coopsim/generated.hpp"
#include "coopsim/robot.hpp"

namespace coopsim {

namespace {

template <class F>
F library_symbol(void* handle, const std::string& path, const char* name) {
  void* s = dlsym(handle, name);
  if (!s) throw std::invalid_argument(path + " lacks the symbol " + name + " (not built by coopsim.codegen?)");
  return reinterpret_cast<F>(s);
}

// Loading a library runs its code: only a file that this user (or root) owns and that no one else may
// write, in a folder no one else may write to (or a sticky one, like /tmp), is loaded. A library another
// user could have placed or changed is refused before dlopen.
void check_trusted(const std::string& path) {
  struct stat f, d;
  if (stat(path.c_str(), &f) != 0 || !S_ISREG(f.st_mode))
    throw std::invalid_argument("cannot load " + path + ": not a regular file");
  const uid_t me = geteuid();
  if (f.st_uid != me && f.st_uid != 0)
    throw std::invalid_argument("refusing to load " + path + ": it belongs to another user");
  if (f.st_mode & (S_IWGRP | S_IWOTH))
    throw std::invalid_argument("refusing to load " + path + ": other users may write to it");
  const size_t slash = path.find_last_of('/');
  const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  if (stat(dir.c_str(), &d) != 0) throw std::invalid_argument("cannot load " + path + ": no folder " + dir);
  if ((d.st_mode & S_IWOTH) && !(d.st_mode & S_ISVTX))
    throw std::invalid_argument("refusing to load " + path + ": its folder " + dir +
                                " may be written to by other users (and is not sticky)");
}

bool is_file(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

}  // namespace

std::string generated_cache_dir() {
  if (const char* d = std::getenv("COOPSIM_CACHE_DIR"); d && *d) return d;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d) return std::string(d) + "/coopsim";
  if (const char* d = std::getenv("HOME"); d && *d) return std::string(d) + "/.cache/coopsim";
  return "";
}

std::shared_ptr<const GeneratedDynamics> load_generated_library(const std::string& path) {
  check_trusted(path);
  // kept open for the process lifetime: robots may hold its functions
  void* h = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!h) {
    const char* err = dlerror();
    throw std::invalid_argument("cannot load " + path + ": " + (err ? err : "unknown error"));
  }
  auto g = std::make_shared<GeneratedDynamics>();
  g->name = library_symbol<const char* (*)()>(h, path, "coopsim_gen_name")();
  g->dof = library_symbol<int (*)()>(h, path, "coopsim_gen_dof")();
  g->joint_types = library_symbol<const char* (*)()>(h, path, "coopsim_gen_joint_types")();
  if (g->dof < 1 || g->dof > kMaxDof || static_cast<int>(g->joint_types.size()) != g->dof)
    throw std::invalid_argument(path + " describes a malformed structure");
  // the parameter layout it reads (libraries of older generators lack the symbol: rebuilt)
  if (library_symbol<int (*)()>(h, path, "coopsim_gen_params_per_link")() != kParamsPerLink)
    throw std::invalid_argument(path + " reads another parameter layout (built by another coopsim.codegen)");
  const double* angles = library_symbol<const double* (*)()>(h, path, "coopsim_gen_angles")();
  g->angles.assign(angles, angles + 4 * g->dof);
  g->generator_version = library_symbol<const char* (*)()>(h, path, "coopsim_gen_version")();
  g->operation_count = library_symbol<long (*)()>(h, path, "coopsim_gen_operation_count")();
  g->constant_count = library_symbol<int (*)()>(h, path, "coopsim_gen_constant_count")();
  if (g->constant_count < 0 || g->constant_count > 100000)
    throw std::invalid_argument(path + " describes a malformed structure");
  g->constants = library_symbol<decltype(g->constants)>(h, path, "coopsim_gen_constants");
  g->mass_matrix = library_symbol<decltype(g->mass_matrix)>(h, path, "coopsim_gen_mass_matrix");
  g->coriolis = library_symbol<decltype(g->coriolis)>(h, path, "coopsim_gen_coriolis");
  g->coriolis_matrix = library_symbol<decltype(g->coriolis_matrix)>(h, path, "coopsim_gen_coriolis_matrix");
  g->gravity = library_symbol<decltype(g->gravity)>(h, path, "coopsim_gen_gravity");
  g->dynamics = library_symbol<decltype(g->dynamics)>(h, path, "coopsim_gen_dynamics");
  g->solve = library_symbol<decltype(g->solve)>(h, path, "coopsim_gen_solve");
  // optional: emitted where the derivatives are tractable (the collected form)
  g->derivatives = reinterpret_cast<decltype(g->derivatives)>(dlsym(h, "coopsim_gen_derivatives"));
  // its results row-major from generator 1.6.0 on (column-major before: left to the general path)
  int major = 0, minor = 0;
  if (std::sscanf(g->generator_version.c_str(), "%d.%d", &major, &minor) == 2 && (major > 1 || minor >= 6))
    g->forward_derivatives =
        reinterpret_cast<decltype(g->forward_derivatives)>(dlsym(h, "coopsim_gen_forward_derivatives"));
  g->forward_derivatives4 =
      reinterpret_cast<decltype(g->forward_derivatives4)>(dlsym(h, "coopsim_gen_forward_derivatives4"));
  return g;
}

std::string register_generated_library(const std::string& path) {
  std::shared_ptr<const GeneratedDynamics> g;
  try {
    g = load_generated_library(path);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("path: ") + e.what());
  }
  if (!find_generated(g->name)) register_generated(g);
  return g->name;
}

std::shared_ptr<const GeneratedDynamics> find_cached_generated(const std::string& name) {
  // names of run-time builds are gen_<key>, their libraries coopsim_gen_<key>.so
  if (name.rfind("gen_", 0) != 0 || name.find('/') != std::string::npos) return nullptr;
  const std::string dir = generated_cache_dir();
  if (dir.empty()) return nullptr;
  const std::string path = dir + "/coopsim_" + name + ".so";
  if (!is_file(path)) return nullptr;
  try {
    auto g = load_generated_library(path);
    return g->name == name ? g : nullptr;
  } catch (const std::invalid_argument&) {
    return nullptr;
  }
}

}  // namespace coopsim
