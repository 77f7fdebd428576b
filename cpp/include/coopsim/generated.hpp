// Interface between the engine and closed-form dynamics emitted by the
// symbolic generator (python/coopsim/codegen). Generated code reads every
// length, mass, inertia, armature, friction and gravity value from the robot's
// parameter vector p (see Robot::parameter_vector), so that changing a
// dimension or a mass at run time needs no regeneration. Joint types and the
// angle parameters (DH and CoM theta offsets and alpha) are structural: they
// were fixed at generation and are checked when the code is attached.
//
// The parameter polynomials of the closed forms (kappa: sums of products of
// masses, lengths and inertias) do not depend on the state: constants()
// computes them once from p, and every other function reads them right after
// the parameters, i.e. its p is the parameter vector followed by constants(p)
// (Robot keeps both in one vector and refreshes it when parameters change).
//
// Array layouts: q, qd: n; M, C: n x n column-major; c, g: n.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace coopsim {

struct GeneratedDynamics {
  std::string name;          // e.g. "scara1"
  int dof = 0;
  std::string joint_types;   // e.g. "RRPRRP"
  // structural angles per link: dh theta, dh alpha, com theta, com alpha
  // (theta of a revolute row is the offset added to q)
  std::vector<double> angles;
  std::string generator_version;
  long operation_count = 0;  // arithmetic operations of dynamics() after cse, sin/cos counted once
  int constant_count = 0;    // values constants() writes after the parameters
  // k[0..constant_count) <- the parameter polynomials of p (the plain parameter vector)
  void (*constants)(const double* p, double* k) = nullptr;
  void (*mass_matrix)(const double* p, const double* q, double* M) = nullptr;
  void (*coriolis)(const double* p, const double* q, const double* qd, double* c) = nullptr;
  void (*coriolis_matrix)(const double* p, const double* q, const double* qd, double* C) = nullptr;
  void (*gravity)(const double* p, const double* q, double* g) = nullptr;
  // optional: M and h = C(q, qd) qd + G(q) + K qd + F_c tanh(qd / v_c) in one
  // pass (shared sin/cos); M always includes the armature on its diagonal
  void (*dynamics)(const double* p, const double* q, const double* qd, double* M, double* h) = nullptr;
  // optional: the inverse dynamics' derivatives at (q, qd, qdd) from the symbolic model, with
  // tau = M(q) qdd + C(q, qd) qd + G(q) + K qd + F_c tanh(qd / v_c): dtau_dq = d tau / dq,
  // dtau_dqd = d tau / dqd (friction's slope on the diagonal), each n x n column-major with
  // [i + n k] = d tau_i / d x_k, and M (armature included) in the same pass; null where the
  // generator did not emit them (the engine's recursive algorithm is used then)
  void (*derivatives)(const double* p, const double* q, const double* qd, const double* qdd, double* dtau_dq,
                      double* dtau_dqd, double* M) = nullptr;
  // optional, with derivatives: the forward dynamics' derivatives at (q, qd, tau) in one straight-line
  // pass (M and h, M's LDL^T factor, qdd = M^-1 (tau - h), the derivatives above at qdd, the 3n
  // right-hand sides [-dtau_dq, -dtau_dqd, 1] solved with the same factor): dqdd_dq, dqdd_dqd, Minv
  // n x n row-major (numpy's layout; libraries of generators before 1.6.0 wrote them column-major and
  // are not given it), qdd (n) unless null; false where a pivot is not above 1e-13 of M's diagonal
  // entry (forward_dynamics' rule: results undefined). forward_derivatives4: four states at once, one
  // per lane of a vector, q, qd, tau (4, n) row-major and the results (4, n, n) row-major (numpy's)
  bool (*forward_derivatives)(const double* p, const double* q, const double* qd, const double* tau,
                              double* dqdd_dq, double* dqdd_dqd, double* Minv, double* qdd) = nullptr;
  bool (*forward_derivatives4)(const double* p, const double* q, const double* qd, const double* tau,
                               double* dqdd_dq, double* dqdd_dqd, double* Minv) = nullptr;
  // optional: x <- M^-1 x by an unrolled LDL^T that skips M's structural
  // zeros; false if M is not positive definite (x is then undefined)
  bool (*solve)(const double* M, double* x) = nullptr;
};

// Per link parameter block length and offsets into the parameter vector.
constexpr int kParamsPerLink = 19;
enum ParamOffset : int {
  kDhTheta = 0, kDhD = 1, kDhA = 2, kDhAlpha = 3,
  kComTheta = 4, kComD = 5, kComA = 6, kComAlpha = 7,
  kMass = 8, kIxx = 9, kIyy = 10, kIzz = 11, kIxy = 12, kIxz = 13, kIyz = 14,
  kFriction = 15, kArmature = 16, kCoulomb = 17, kCoulombWidth = 18
};
// Gravity (gx, gy, gz) in frame 0 follows the n link blocks.

// Generated code by name, null if none: compiled into the engine, registered
// at run time (register_generated), or a library of the build cache
// (find_cached_generated).
const GeneratedDynamics* find_generated(const std::string& name);
// The names of the generated code compiled into the engine.
std::vector<std::string> compiled_generated_names();
// Keeps `gen` for the process lifetime and makes it findable by name (code
// loaded from a shared library, e.g. by coopsim.codegen.compile).
void register_generated(std::shared_ptr<const GeneratedDynamics> gen);
// The list emitted by the generator in cpp/generated/registry.cpp.
std::vector<const GeneratedDynamics*> compiled_generated();

// Shared libraries built by coopsim.codegen.compile: the library describes
// its structure itself. Throws std::invalid_argument when it cannot be
// loaded. find_generated() also finds a library gen_<key> of the build
// cache ($COOPSIM_CACHE_DIR, else $XDG_CACHE_HOME/coopsim, else
// ~/.cache/coopsim) by name, so pickled robots find their code again.
std::shared_ptr<const GeneratedDynamics> load_generated_library(const std::string& path);
std::shared_ptr<const GeneratedDynamics> find_cached_generated(const std::string& name);
// Loads the library at `path` and registers its code under the name it
// carries, unless that name is registered already (its code then stays);
// returns the name. std::invalid_argument naming `path` when it cannot load.
std::string register_generated_library(const std::string& path);
std::string generated_cache_dir();

}  // namespace coopsim
