#include "coopsim/integrator.hpp"
#include "batch_rows.hpp"
#include "internal.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

namespace coopsim {

Method method_from_name(const std::string& name, const char* what) {
  if (name == "rk4") return Method::RK4;
  if (name == "euler") return Method::SemiImplicitEuler;
  throw std::invalid_argument(std::string(what) + " must be 'rk4' or 'euler', got '" + name + "'");
}

const char* method_name(Method m) { return m == Method::RK4 ? "rk4" : "euler"; }

void check_step_size(double dt) {
  if (!(dt > 0) || !(dt <= 1.0)) {
    std::ostringstream s;
    s << "dt must be > 0 and at most 1 s, got " << dt;
    throw std::invalid_argument(s.str());
  }
}

std::string end_stop_step_warning(const Robot& robot, double dt) {
  bool limited = false;
  for (const Link& L : robot.links()) limited = limited || std::isfinite(L.q_min) || std::isfinite(L.q_max);
  const double w = robot.end_stop().frequency;
  if (!limited || !(w * dt > kEndStopOmegaDtLimit)) return std::string();
  std::ostringstream s;
  s << "the end stops of robot '" << robot.name() << "' have omega * dt = " << w * dt << " at dt = " << dt
    << " s, above " << kEndStopOmegaDtLimit << ": they will be inaccurate or unstable (energy grows); use dt <= "
    << kEndStopOmegaDtLimit / w << " s, or end_stops=False";
  return s.str();
}

namespace {

// forward dynamics of one stage; a failure becomes StageError with the stage and its state
void stage_dynamics(const Robot& robot, int stage, const VecN& q, const VecN& qd, const double* tau,
                    const double* tau_ext, Workspace& ws, VecN& qdd, bool end_stops) {
  try {
    robot.forward_dynamics(q.data(), qd.data(), tau, tau_ext, ws, qdd, end_stops);
  } catch (const std::domain_error& e) {
    throw StageError(e.what(), stage, q, qd);
  }
}

// RK4's stages 2 to 4 and the update, on x = [q; qd], the robot's dof N known at compile time (N > 0, the loops
// unroll) or not (N = 0: n). Element by element the same operations in the same order as the vector
// expressions q + (dt / 2) qd, ..., q + (dt / 6) (qd + 2 k2q + 2 k3q + k4q): the same results to the bit.
// Nothing is allocated; q and qd change only once every stage succeeded.
template <int N>
void rk4_stages(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau, const double* tau_ext,
                double dt, bool end_stops, const VecN& k1v, int n_any) {
  const int n = N > 0 ? N : n_any;
  VecN k2v, k3v, k4v, qs(n), vs(n);
  double k2q[kMaxDof], k3q[kMaxDof], k4q[kMaxDof];
  const double* x = q.data();
  const double* v = qd.data();
  double* xs = qs.data();
  double* ys = vs.data();
  const double h2 = 0.5 * dt;
  const double* k1 = k1v.data();
  for (int j = 0; j < n; ++j) {
    xs[j] = x[j] + h2 * v[j];
    ys[j] = v[j] + h2 * k1[j];
    k2q[j] = ys[j];
  }
  stage_dynamics(robot, 2, qs, vs, tau, tau_ext, ws, k2v, end_stops);
  const double* k2 = k2v.data();
  for (int j = 0; j < n; ++j) {
    xs[j] = x[j] + h2 * k2q[j];
    ys[j] = v[j] + h2 * k2[j];
    k3q[j] = ys[j];
  }
  stage_dynamics(robot, 3, qs, vs, tau, tau_ext, ws, k3v, end_stops);
  const double* k3 = k3v.data();
  for (int j = 0; j < n; ++j) {
    xs[j] = x[j] + dt * k3q[j];
    ys[j] = v[j] + dt * k3[j];
    k4q[j] = ys[j];
  }
  stage_dynamics(robot, 4, qs, vs, tau, tau_ext, ws, k4v, end_stops);
  const double* k4 = k4v.data();
  const double h6 = dt / 6.0;
  double* xo = q.data();
  double* vo = qd.data();
  for (int j = 0; j < n; ++j) {
    const double dq = h6 * (((v[j] + 2.0 * k2q[j]) + 2.0 * k3q[j]) + k4q[j]);
    const double dv = h6 * (((k1[j] + 2.0 * k2[j]) + 2.0 * k3[j]) + k4[j]);
    xo[j] += dq;
    vo[j] += dv;
  }
}

}  // namespace

void step(const Robot& robot, Workspace& ws, Method method, VecN& q, VecN& qd, const double* tau,
          const double* tau_ext, double dt, bool end_stops, const VecN* qdd0) {
  VecN k1v;
  if (qdd0) k1v = *qdd0;
  else stage_dynamics(robot, 1, q, qd, tau, tau_ext, ws, k1v, end_stops);
  if (method == Method::SemiImplicitEuler) {
    qd += dt * k1v;
    q += dt * qd;
    return;
  }
  // classic RK4; the common sizes with their loops unrolled
  const int n = robot.dof();
  switch (n) {
    case 2: rk4_stages<2>(robot, ws, q, qd, tau, tau_ext, dt, end_stops, k1v, n); break;
    case 3: rk4_stages<3>(robot, ws, q, qd, tau, tau_ext, dt, end_stops, k1v, n); break;
    case 6: rk4_stages<6>(robot, ws, q, qd, tau, tau_ext, dt, end_stops, k1v, n); break;
    case 7: rk4_stages<7>(robot, ws, q, qd, tau, tau_ext, dt, end_stops, k1v, n); break;
    default: rk4_stages<0>(robot, ws, q, qd, tau, tau_ext, dt, end_stops, k1v, n); break;
  }
}

void rk4_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau, const double* tau_ext,
              double dt, bool end_stops) {
  step(robot, ws, Method::RK4, q, qd, tau, tau_ext, dt, end_stops);
}

void euler_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau, const double* tau_ext,
                double dt, bool end_stops) {
  step(robot, ws, Method::SemiImplicitEuler, q, qd, tau, tau_ext, dt, end_stops);
}

namespace {

using detail::num;

}  // namespace

std::string divergence_reason(const VecN& q, const VecN& qd, const DivergenceLimits& limits) {
  bool fast = false, far = false;
  for (int j = 0; j < q.size(); ++j) {
    if (!std::isfinite(q[j]) || !std::isfinite(qd[j])) return "state is no longer finite";
    if (std::abs(qd[j]) > limits.max_speed) fast = true;
    else if (std::abs(q[j]) > limits.max_position) far = true;
  }
  if (fast) return "a joint speed exceeds max_speed = " + num(limits.max_speed);
  if (far) return "a joint position exceeds max_position = " + num(limits.max_position);
  return std::string();
}

std::string stage_failure_reason(const StageError& e, Method method, const DivergenceLimits& limits) {
  std::string why = divergence_reason(e.q, e.qd, limits);
  if (why.empty() && !divergence_reason(e.q, e.qd, DivergenceLimits{kRunawaySpeed, kRunawayPosition}).empty())
    why = "a joint beyond " + num(kRunawaySpeed) + " rad/s or " + num(kRunawayPosition) + " rad (m/s, m)";
  const std::string stage = std::string(method_name(method)) + " stage " + std::to_string(e.stage);
  if (why.empty()) return "the dynamics failed in the " + stage + " (" + e.what() + ")";
  std::ostringstream s;
  s.precision(6);
  s << "the state ran away: the " << stage << " was evaluated at q = [" << e.q.transpose() << "], qd = ["
    << e.qd.transpose() << "] (" << why << "), where the dynamics lose the mass matrix to rounding or overflow "
    << "(a smaller dt, lower gains or smaller torques keep it bounded)";
  return s.str();
}

IntegrationResult integrate(const Robot& robot, const double* q0, const double* qd0, const double* tau,
                            int tau_rows, double dt, int steps, Method method, bool end_stops, int record_every,
                            const DivergenceLimits& limits) {
  const int n = robot.dof();
  check_step_size(dt);
  if (steps < 0 || steps > 2000000000)
    throw std::invalid_argument("steps must be in [0, 2e9], got " + std::to_string(steps));
  if (record_every < 1) throw std::invalid_argument("record_every must be >= 1");
  if (tau_rows != 1 && tau_rows != steps)
    throw std::invalid_argument("tau must have one row or one row per step");
  IntegrationResult out;
  const int m = steps / record_every + 1 + (steps % record_every ? 1 : 0);
  out.t.reserve(m);
  out.q.reserve(static_cast<size_t>(m) * n);
  out.qd.reserve(static_cast<size_t>(m) * n);
  Workspace ws;
  VecN q = Eigen::Map<const VecN>(q0, n), qd = Eigen::Map<const VecN>(qd0, n);
  auto record = [&](int k) {
    out.t.push_back(k * dt);
    out.q.insert(out.q.end(), q.data(), q.data() + n);
    out.qd.insert(out.qd.end(), qd.data(), qd.data() + n);
    ++out.rows;
  };
  record(0);
  for (int s = 0; s < steps; ++s) {
    const double* u = tau + (tau_rows == 1 ? 0 : static_cast<size_t>(s) * n);
    const VecN q_prev = q, qd_prev = qd;
    std::string why;
    try {
      step(robot, ws, method, q, qd, u, nullptr, dt, end_stops);
      why = divergence_reason(q, qd, limits);
    } catch (const StageError& e) {
      why = stage_failure_reason(e, method, limits);
    }
    if (!why.empty()) {
      const VecN q_bad = q, qd_bad = qd;
      q = q_prev;
      qd = qd_prev;
      std::ostringstream msg;
      msg << "integration diverged at step " << s + 1 << " (t = " << (s + 1) * dt << " s, dt = " << dt
          << " s): " << why << "; last good state q = [" << q.transpose() << "], qd = [" << qd.transpose() << "]";
      if (end_stops) {
        const std::string hint = end_stop_step_warning(robot, dt);
        if (!hint.empty()) msg << "; " << hint;
      }
      throw DivergenceError(msg.str(), s + 1, (s + 1) * dt, 0, q_bad, qd_bad);
    }
    if ((s + 1) % record_every == 0 || s + 1 == steps) record(s + 1);
  }
  return out;
}

void forward_dynamics_batch(const Robot& robot, const double* Q, const double* QD, const double* TAU, int N,
                            double* QDD, int threads) {
  const int n = robot.dof();
  // chunks of 256 states (batch_rows.hpp): each thread writes its chunks' rows of QDD, disjoint rows of
  // 256 * n * 8 bytes (a multiple of 64), so two threads share at most the cache line at a chunk's edge
  struct State {
    Workspace ws;
    VecN qdd;
  };
  detail::batch_rows(N, 256, threads, [] { return State(); }, [&](State& st, int i) {
    const size_t o = static_cast<size_t>(i) * n;
    robot.forward_dynamics(Q + o, QD + o, TAU + o, nullptr, st.ws, st.qdd, false);
    std::copy(st.qdd.data(), st.qdd.data() + n, QDD + o);
  });
}

}  // namespace coopsim
