// Fixed-step integration of the joint dynamics.
//
// State layout: q (n) joint positions and qd (n) joint velocities, kept as two
// vectors; RK4 integrates x = [q; qd] with xdot = [qd; qdd(q, qd, tau)].
// The torque tau (and any external joint torque) is held constant over a step
// (zero-order hold). With end_stops on, a joint beyond its limit feels the
// robot's spring-damper end stop (Robot::end_stop_torques) inside every stage,
// so limits are soft but stiff, and penetration is bounded and damped.
#pragma once

#include <vector>

#include "coopsim/robot.hpp"

namespace coopsim {

enum class Method { RK4, SemiImplicitEuler };

// One classic fourth-order Runge-Kutta step of size dt (s), in place.
void rk4_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau,
              const double* tau_ext, double dt, bool end_stops);
// One semi-implicit (symplectic) Euler step: qd += dt qdd(q, qd); q += dt qd.
void euler_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau,
                const double* tau_ext, double dt, bool end_stops);

// Integrates `steps` steps from (q0, qd0) under joint torques `tau`, given as
// one row (held throughout) or one row per step (row-major, steps x n).
// Records every `record_every`-th state including the first and the last into
// t_out (m), q_out and qd_out (m x n row-major), m = steps / record_every + 1
// (plus one when steps is not a multiple). Throws std::runtime_error when the
// state stops being finite, naming the step.
struct IntegrationResult {
  std::vector<double> t, q, qd;
  int rows = 0;
};
IntegrationResult integrate(const Robot& robot, const double* q0, const double* qd0, const double* tau,
                            int tau_rows, double dt, int steps, Method method, bool end_stops,
                            int record_every);

// Forward dynamics of N independent states (row-major N x n arrays), split
// over `threads` threads (0: hardware concurrency).
void forward_dynamics_batch(const Robot& robot, const double* Q, const double* QD, const double* TAU, int N,
                            double* QDD, int threads);

}  // namespace coopsim
