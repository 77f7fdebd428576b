// Linear models of the joint dynamics (linearize.hpp): the continuous (A, B), the exact Jacobians of a step
// by the chain rule through its stages, and the loop closed by a controller's own linearisation.
#include "coopsim/linearize.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "internal.hpp"

namespace coopsim {

namespace {

using detail::num;
using MatX = Eigen::MatrixXd;
using VecX = Eigen::VectorXd;

// the continuous model's Jacobians at x = (q, qd): F = [[0, 1], [dqdd/dq, dqdd/dqd]] (2n, 2n),
// G = [[0], [M^-1]] (2n, n), and qdd there
struct Stage {
  MatX F, G;
  VecN qdd;
};

void stage_jacobians(const Robot& robot, const VecN& q, const VecN& qd, const double* tau, const double* tau_ext,
                     const std::vector<ExternalWrench>& wrenches, Workspace& ws, Stage& s) {
  const int n = robot.dof();
  MatN dq, dqd, Minv;
  robot.forward_dynamics_derivatives(q.data(), qd.data(), tau, wrenches, ws, dq, dqd, Minv, &s.qdd, tau_ext);
  s.F = MatX::Zero(2 * n, 2 * n);
  s.F.topRightCorner(n, n).setIdentity();
  s.F.bottomLeftCorner(n, n) = dq;
  s.F.bottomRightCorner(n, n) = dqd;
  s.G = MatX::Zero(2 * n, n);
  s.G.bottomRows(n) = Minv;
}

void check_within_limits(const Robot& robot, const VecN& q, const char* where) {
  for (int j = 0; j < robot.dof(); ++j) {
    const Link& L = robot.links()[j];
    if (q[j] > L.q_max || q[j] < L.q_min)
      throw std::invalid_argument(std::string("linearize: at ") + where + " joint " + std::to_string(j + 1) +
                                  " is at " + num(q[j]) + ", beyond its limits [" + num(L.q_min) + ", " +
                                  num(L.q_max) + "], where the end stops act and their derivative is not "
                                  "modelled: linearise within the limits, or pass end_stops=False");
  }
}

std::vector<std::string> joint_states(int n) {
  std::vector<std::string> s;
  for (int i = 0; i < n; ++i) s.push_back("q" + std::to_string(i));
  for (int i = 0; i < n; ++i) s.push_back("qd" + std::to_string(i));
  return s;
}

// one step's Jacobians (A, B) from x = (q, qd), and the state after it into (q, qd)
void step_jacobians(const Robot& robot, VecN& q, VecN& qd, const double* tau, const double* tau_ext,
                    const std::vector<ExternalWrench>& wrenches, double dt, Method method, bool end_stops,
                    Workspace& ws, MatX& A, MatX& B) {
  const int n = robot.dof(), s2 = 2 * n;
  const MatX I = MatX::Identity(s2, s2);
  Stage st;
  if (end_stops) check_within_limits(robot, q, "the step's start");
  stage_jacobians(robot, q, qd, tau, tau_ext, wrenches, ws, st);
  if (method == Method::SemiImplicitEuler) {
    // qd+ = qd + dt qdd(q, qd); q+ = q + dt qd+
    MatX dv = MatX::Zero(n, s2);
    dv.rightCols(n).setIdentity();
    dv += dt * st.F.bottomRows(n);
    A.resize(s2, s2);
    A.topRows(n) = I.topRows(n) + dt * dv;
    A.bottomRows(n) = dv;
    B.resize(s2, n);
    B.bottomRows(n) = dt * st.G.bottomRows(n);
    B.topRows(n) = dt * B.bottomRows(n);
    if (!wrenches.empty()) {  // the step under the wrenches (the integrator holds joint torques only)
      qd += dt * st.qdd;
      q += dt * qd;
      return;
    }
  } else {
    // classic RK4 on x = [q; qd], the stages differentiated (linearize.hpp)
    const double c[4] = {0.0, 0.5 * dt, 0.5 * dt, dt}, w[4] = {1.0, 2.0, 2.0, 1.0};
    VecN kq = qd, kv = st.qdd;  // k_1
    VecN sq = kq, sv = kv;      // the weighted sums of the stages' derivatives
    MatX dkx = st.F, dku = st.G;
    A = I + (dt / 6.0) * dkx;
    B = (dt / 6.0) * dku;
    for (int i = 1; i < 4; ++i) {
      const VecN qs = q + c[i] * kq, vs = qd + c[i] * kv;
      if (end_stops) check_within_limits(robot, qs, ("RK4 stage " + std::to_string(i + 1)).c_str());
      stage_jacobians(robot, qs, vs, tau, tau_ext, wrenches, ws, st);
      const MatX nx = st.F * (I + c[i] * dkx), nu = st.F * (c[i] * dku) + st.G;
      dkx = nx;
      dku = nu;
      kq = vs;
      kv = st.qdd;
      sq += w[i] * kq;
      sv += w[i] * kv;
      A += (w[i] * dt / 6.0) * dkx;
      B += (w[i] * dt / 6.0) * dku;
    }
    if (!wrenches.empty()) {  // the step under the wrenches (the integrator holds joint torques only)
      q += (dt / 6.0) * sq;
      qd += (dt / 6.0) * sv;
      return;
    }
  }
  // the state after the step: the integrator's own arithmetic
  step(robot, ws, method, q, qd, tau, tau_ext, dt, end_stops);
}

void check_steps(double dt, int steps) {
  check_step_size(dt);
  if (steps < 1) throw std::invalid_argument("steps must be >= 1, got " + std::to_string(steps));
}

}  // namespace

LinearModel linearize_continuous(const Robot& robot, const double* q, const double* qd, const double* tau,
                                 const double* tau_ext, const std::vector<ExternalWrench>& wrenches) {
  const int n = robot.dof();
  Workspace ws;
  Stage st;
  const VecN qv = Eigen::Map<const VecN>(q, n), qdv = Eigen::Map<const VecN>(qd, n);
  stage_jacobians(robot, qv, qdv, tau, tau_ext, wrenches, ws, st);
  LinearModel m;
  m.A = st.F;
  m.B = st.G;
  m.x0.resize(2 * n);
  m.x0 << qv, qdv;
  m.tau0 = Eigen::Map<const VecN>(tau, n);
  m.x_next.resize(2 * n);
  m.x_next << qdv, st.qdd;
  m.dt = 0.0;
  m.method = "continuous";
  m.states = joint_states(n);
  return m;
}

LinearModel linearize_step(const Robot& robot, const double* q, const double* qd, const double* tau,
                           const double* tau_ext, const std::vector<ExternalWrench>& wrenches, double dt, int steps,
                           Method method, bool end_stops) {
  check_steps(dt, steps);
  const int n = robot.dof();
  Workspace ws;
  VecN qv = Eigen::Map<const VecN>(q, n), qdv = Eigen::Map<const VecN>(qd, n);
  LinearModel m;
  m.x0.resize(2 * n);
  m.x0 << qv, qdv;
  m.tau0 = Eigen::Map<const VecN>(tau, n);
  MatX A, B;
  for (int k = 0; k < steps; ++k) {
    step_jacobians(robot, qv, qdv, tau, tau_ext, wrenches, dt, method, end_stops, ws, A, B);
    if (k == 0) {
      m.A = A;
      m.B = B;
    } else {  // Phi_k = A Phi_{k-1}, Gamma_k = A Gamma_{k-1} + B
      m.A = A * m.A;
      m.B = A * m.B + B;
    }
  }
  m.x_next.resize(2 * n);
  m.x_next << qv, qdv;
  m.dt = dt;
  m.steps = steps;
  m.method = method_name(method);
  m.states = joint_states(n);
  return m;
}

LinearModel linearize_closed_loop(const Robot& robot, const Controller& controller, const double* q,
                                  const double* qd, const double* q_ref, const double* qd_ref,
                                  const double* qdd_ref, const double* tau_ext,
                                  const std::vector<ExternalWrench>& wrenches, double dt, int steps, Method method,
                                  bool end_stops) {
  const int n = robot.dof();
  const bool continuous = dt == 0.0;
  if (!continuous) check_steps(dt, steps);
  ControllerJacobians J;
  const ControlInput in{n, 0.0, q, qd, q_ref, qd_ref, qdd_ref, nullptr, nullptr};
  if (controller.senses())
    throw std::invalid_argument("linearize: the controller reads the force/torque sensor, which the joint model "
                                "does not have");
  if (!controller.linearize(robot, continuous ? 0.0 : dt * steps, in, J))
    throw std::invalid_argument("linearize: this controller gives no linearisation (Controller.linearize): close "
                                "the loop by hand with its gain, A + B K");
  const int mc = static_cast<int>(J.c.size()), s = 2 * n + mc;
  if (continuous && mc > 0)
    throw std::invalid_argument("linearize: the controller has an internal state updated once per period (" +
                                std::to_string(mc) + " values): give dt (s) for the discrete closed loop");
  LinearModel open = continuous ? linearize_continuous(robot, q, qd, J.tau.data(), tau_ext, wrenches)
                                : linearize_step(robot, q, qd, J.tau.data(), tau_ext, wrenches, dt, steps, method,
                                                 end_stops);
  LinearModel m = open;
  // tau = g(x, c): A = [[Phi_x + Phi_tau g_x, Phi_tau g_c], [h_x, h_c]], B = [[Phi_tau], [0]]
  MatX gx(n, 2 * n);
  gx << J.dtau_dq, J.dtau_dqd;
  m.A = MatX::Zero(s, s);
  m.A.topLeftCorner(2 * n, 2 * n) = open.A + open.B * gx;
  m.A.topRightCorner(2 * n, mc) = open.B * J.dtau_dc;
  m.A.bottomLeftCorner(mc, n) = J.dc_dq;
  m.A.block(2 * n, n, mc, n) = J.dc_dqd;
  m.A.bottomRightCorner(mc, mc) = J.dc_dc;
  m.B = MatX::Zero(s, n);
  m.B.topRows(2 * n) = open.B;
  m.x0.conservativeResize(s);
  m.x0.tail(mc) = J.c;
  if (!continuous) {
    m.x_next.conservativeResize(s);  // and the controller's state after its update
    m.x_next.tail(mc) = J.c_next;
  }
  for (const std::string& name : J.states) m.states.push_back(name);
  return m;
}

}  // namespace coopsim
