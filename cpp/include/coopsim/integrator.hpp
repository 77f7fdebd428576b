// Fixed-step integration of the joint dynamics: the one step function that
// rk4_step, euler_step, integrate and the simulation loop all use.
//
// State layout: q (n) joint positions and qd (n) joint velocities, kept as two
// vectors; RK4 integrates x = [q; qd] with xdot = [qd; qdd(q, qd, tau)].
// The torque tau and the external joint torque tau_ext are held constant over
// a step (zero-order hold). With end_stops on, a joint beyond its limit feels
// the robot's spring-damper end stop (Robot::end_stop_torques) inside every
// stage, so limits are soft but stiff, and penetration is bounded and damped.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "coopsim/robot.hpp"

namespace coopsim {

enum class Method { RK4, SemiImplicitEuler };

// "rk4" or "euler"; throws std::invalid_argument naming `what` otherwise.
Method method_from_name(const std::string& name, const char* what = "method");
const char* method_name(Method m);
// Throws std::invalid_argument unless dt (s) is finite and > 0.
void check_step_size(double dt);

// The largest omega * dt of the robot's end stops at which they stay accurate
// and stable under RK4 and Euler (RK4's stability ends near 2.8; energy grows
// visibly well before: 13 J became 47 J in a second at omega * dt = 2.5).
constexpr double kEndStopOmegaDtLimit = 1.0;
// A sentence saying the end stops are too stiff for dt (s), naming omega *
// dt and the largest step that keeps it at the limit; empty when they are
// fine (or the robot has no finite joint limit).
std::string end_stop_step_warning(const Robot& robot, double dt);

// One step of size dt (s) of `method`, in place, under tau (n) and tau_ext
// (n, may be null) held over the step. qdd0, when given, is qdd(q, qd) at the
// start of the step (RK4's first stage, or Euler's only one), already
// computed with the same tau and tau_ext; it is then not recomputed. Throws
// StageError (a std::domain_error) when the dynamics fail in a stage (e.g. an
// overflowing state, a mass matrix not positive definite); q and qd are then
// unchanged.
void step(const Robot& robot, Workspace& ws, Method method, VecN& q, VecN& qd, const double* tau,
          const double* tau_ext, double dt, bool end_stops, const VecN* qdd0 = nullptr);

// One classic fourth-order Runge-Kutta step: step(..., Method::RK4, ...).
void rk4_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau,
              const double* tau_ext, double dt, bool end_stops);
// One semi-implicit (symplectic) Euler step: qd += dt qdd(q, qd); q += dt qd.
void euler_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau,
                const double* tau_ext, double dt, bool end_stops);

// Bounds beyond which a state counts as diverged.
struct DivergenceLimits {
  double max_speed = kInf;     // rad/s or m/s
  double max_position = kInf;  // rad or m
};

// Why (q, qd) counts as diverged ("state is no longer finite", "a joint
// speed exceeds max_speed = ...", ...), or an empty string when it does not.
std::string divergence_reason(const VecN& q, const VecN& qd, const DivergenceLimits& limits);

// The dynamics failed in a stage of a step: the stage (1 .. 4 for RK4, 1 for
// Euler), the state (q, qd) it was evaluated at, and the dynamics' reason.
class StageError : public std::domain_error {
 public:
  StageError(const std::string& what, int stage, VecN q, VecN qd)
      : std::domain_error(what), stage(stage), q(std::move(q)), qd(std::move(qd)) {}
  int stage;
  VecN q, qd;
};

// Beyond these a state has run away whatever the limits (no robot turns a
// joint at 1e4 rad/s or sends it 1e6 rad or m away): they only decide how a
// failed stage is reported (stage_failure_reason), never reject a state.
constexpr double kRunawaySpeed = 1e4, kRunawayPosition = 1e6;

// Why a step failed in its dynamics, for DivergenceError: when the stage's
// state is not finite, leaves `limits` or exceeds kRunawaySpeed /
// kRunawayPosition, the runaway (that state and which bound it broke: the
// mass matrix there is lost to rounding or overflow, not to a robot without
// mass); otherwise the dynamics' own reason (a genuinely singular mass
// matrix names q and the links without mass).
std::string stage_failure_reason(const StageError& e, Method method, const DivergenceLimits& limits);

// A run stopped by a diverged state (or a non-finite torque): the step whose
// result was rejected, its time, the robot, and the rejected state.
class DivergenceError : public std::runtime_error {
 public:
  DivergenceError(const std::string& what, long step, double time, int robot, VecN q, VecN qd)
      : std::runtime_error(what), step(step), time(time), robot(robot), q(std::move(q)), qd(std::move(qd)) {}
  long step;    // the step whose result was rejected (1-based count of steps)
  double time;  // s, t at the end of that step
  int robot;    // index of the robot that diverged
  VecN q, qd;   // its rejected state
};

// Integrates `steps` steps from (q0, qd0) under joint torques `tau`, given as
// one row (held throughout) or one row per step (row-major, steps x n).
// Records every `record_every`-th state including the first and the last into
// t_out (m), q_out and qd_out (m x n row-major), m = steps / record_every + 1
// (plus one when steps is not a multiple). Throws DivergenceError when the
// state stops being finite or leaves `limits`, naming the step, with the
// state of the step before.
struct IntegrationResult {
  std::vector<double> t, q, qd;
  int rows = 0;
};
IntegrationResult integrate(const Robot& robot, const double* q0, const double* qd0, const double* tau,
                            int tau_rows, double dt, int steps, Method method, bool end_stops,
                            int record_every, const DivergenceLimits& limits = DivergenceLimits());

// Forward dynamics of N independent states (row-major N x n arrays) on
// `threads` threads (0: hardware concurrency), the calling thread one of them:
// each takes the next chunk of 256 states from an atomic counter when idle and
// writes its rows of QDD; nothing is allocated per state. A state whose
// dynamics throw stops the batch: the first failing row (as a serial loop
// would find it) is rethrown, a std::domain_error naming the row.
void forward_dynamics_batch(const Robot& robot, const double* Q, const double* QD, const double* TAU, int N,
                            double* QDD, int threads);

}  // namespace coopsim
