// Linear models of a robot's joint dynamics (linearize.cpp): the continuous model's (A, B) at a point,
// the exact Jacobians of one integration step (RK4's four stages, or semi-implicit Euler, differentiated
// through the chain rule with the dynamics' analytic derivatives: no finite differences), and the loop
// closed by a controller that gives its own linearisation (Controller::linearize).
//
// State x = [q; qd] (2n): joint positions (rad or m) and velocities. Continuous: xdot = [qd; qdd(q, qd, tau)],
//   A = [[0, 1], [dqdd/dq, dqdd/dqd]],  B = [[0], [M^-1]].
// Discrete: x+ = Phi(x, tau), tau held over `steps` steps of dt (zero-order hold), A = dPhi/dx, B = dPhi/dtau;
// for one RK4 step with k_i = f(x_i), x_1 = x, x_2 = x + dt/2 k_1, x_3 = x + dt/2 k_2, x_4 = x + dt k_3:
//   dk_i/dx = F_i (1 + c_i dt dk_{i-1}/dx),  dk_i/dtau = F_i c_i dt dk_{i-1}/dtau + G_i   (F_i, G_i: A, B at x_i)
//   A = 1 + dt/6 (dk_1 + 2 dk_2 + 2 dk_3 + dk_4)/dx, and B alike.
// Closed loop (a controller with internal state c, m values, updated once per period of `steps` steps):
// z = [q; qd; c], tau = g(x, c), c+ = h(x, c), z+ = [Phi(x, g(x, c) + u); h(x, c)]:
//   A = [[Phi_x + Phi_tau g_x, Phi_tau g_c], [h_x, h_c]],  B = [[Phi_tau], [0]]  (u: a torque added to the output).
#pragma once

#include <string>
#include <vector>

#include "coopsim/controller.hpp"
#include "coopsim/integrator.hpp"
#include "coopsim/robot.hpp"

namespace coopsim {

// documentation of coopsim.linearize (Python)
inline constexpr char kLinearizeDoc[] = R"doc(A linear model of the robot's joint dynamics at (q, qd, tau): a LinearModel.

dt None: the continuous model, xdot = [qd; qdd(q, qd, tau)], x = [q; qd] (2n):
    A = [[0, 1], [dqdd/dq, dqdd/dqd]] (2n, 2n),  B = [[0], [M^-1]] (2n, n),
from the dynamics' analytic derivatives (Robot.forward_dynamics_derivatives).
dt (s): the exact Jacobians of `steps` integration steps of dt (method "rk4", as
rk4_step and the simulation integrate, or "euler") with tau held: RK4's four
stages differentiated by the chain rule (not finite differences), so that
x+ = x_next + A (x - x0) + B (tau - tau0) to first order; x_next equals
rk4_step's result.
controller (PID or ComputedTorque; tau must then be None): the loop closed
by it, updated once per `steps` dt with the reference (q_ref, qd_ref,
qdd_ref) (default: (q, qd, 0), regulation at the point); the state is then
[q; qd; c] with c the controller's own state (the PID's integral, velocity
estimate and last q: see PID.linearize), B the input of a torque added to
the controller's output. A controller that has run linearises at its state.
dt None with a controller: its continuous closed loop (controllers without
state only).
tau_ext (n,): joint torques held (no derivative); f_ext: a (6,) wrench at
the tool or Wrench(s) on links, fixed in the world (their points move with
the links). With end_stops (as rk4_step), a stage beyond a joint limit is a
ValueError: the end stops' derivative is not modelled.)doc";

// A linear model of the joint dynamics at one point: x+ = x_next + A (x - x0) + B (tau - tau0) for a step
// (dt > 0), xdot = xdot0 + A (x - x0) + B (tau - tau0) for the continuous model (dt = 0).
struct LinearModel {
  Eigen::MatrixXd A;  // (s, s), s = 2n (+ m, the controller's state, when closed): d(x+)/dx, or d(xdot)/dx
  Eigen::MatrixXd B;  // (s, n): d(x+)/dtau, or d(xdot)/dtau (1/(kg m^2) ...)
  Eigen::VectorXd x0;      // (s,) the point: [q; qd] (rad, rad/s or m, m/s) [; the controller's state]
  Eigen::VectorXd tau0;    // (n,) the joint torques there (N m or N): given, or the controller's output
  Eigen::VectorXd x_next;  // (s,) x+ at the point (a step), or xdot (continuous)
  double dt = 0.0;  // s, the step (0: continuous)
  int steps = 1;    // integration steps per model step (the controller's period: steps dt)
  std::string method;  // "continuous", "rk4" or "euler"
  std::vector<std::string> states;  // (s,) the names of the state's entries: q0 .. qd0 .. then the controller's
};

// The continuous model at (q, qd, tau) under tau_ext (n, may be null, held) and wrenches (as in
// Robot::forward_dynamics_derivatives). Throws std::domain_error where M is not positive definite.
LinearModel linearize_continuous(const Robot& robot, const double* q, const double* qd, const double* tau,
                                 const double* tau_ext, const std::vector<ExternalWrench>& wrenches);

// The exact Jacobians of `steps` steps of `method` of dt (s) from (q, qd) under tau held (the stages
// differentiated; x_next is rk4_step's / euler_step's own result, or with wrenches, which the integrator
// does not take, the stages' sum). With end_stops, a stage's
// state beyond a joint limit (where the end stops act and their derivative is not modelled) throws
// std::invalid_argument naming the joint and the stage.
LinearModel linearize_step(const Robot& robot, const double* q, const double* qd, const double* tau,
                           const double* tau_ext, const std::vector<ExternalWrench>& wrenches, double dt, int steps,
                           Method method, bool end_stops);

// The loop closed by `controller` (Controller::linearize: a controller that has run linearises at its
// state, a new one at a new run's), at (q, qd) with the reference (q_ref, qd_ref, qdd_ref): the controller's
// output held over the period. dt = 0: the continuous closed loop (controllers without internal state
// only). Throws std::invalid_argument when the controller gives no linearisation (Controller::linearize).
LinearModel linearize_closed_loop(const Robot& robot, const Controller& controller, const double* q,
                                  const double* qd, const double* q_ref, const double* qd_ref,
                                  const double* qdd_ref, const double* tau_ext,
                                  const std::vector<ExternalWrench>& wrenches, double dt, int steps, Method method,
                                  bool end_stops);

}  // namespace coopsim
