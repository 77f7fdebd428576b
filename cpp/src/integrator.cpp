#include "coopsim/integrator.hpp"

#include <algorithm>
#include <string>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace coopsim {

void rk4_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau, const double* tau_ext,
              double dt, bool end_stops) {
  const int n = robot.dof();
  VecN k1q = qd, k1v, k2q, k2v, k3q, k3v, k4q, k4v, qs(n), vs(n);
  robot.forward_dynamics(q.data(), qd.data(), tau, tau_ext, ws, k1v, end_stops);
  qs = q + 0.5 * dt * k1q;
  vs = qd + 0.5 * dt * k1v;
  k2q = vs;
  robot.forward_dynamics(qs.data(), vs.data(), tau, tau_ext, ws, k2v, end_stops);
  qs = q + 0.5 * dt * k2q;
  vs = qd + 0.5 * dt * k2v;
  k3q = vs;
  robot.forward_dynamics(qs.data(), vs.data(), tau, tau_ext, ws, k3v, end_stops);
  qs = q + dt * k3q;
  vs = qd + dt * k3v;
  k4q = vs;
  robot.forward_dynamics(qs.data(), vs.data(), tau, tau_ext, ws, k4v, end_stops);
  q += (dt / 6.0) * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
  qd += (dt / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
}

void euler_step(const Robot& robot, Workspace& ws, VecN& q, VecN& qd, const double* tau, const double* tau_ext,
                double dt, bool end_stops) {
  VecN qdd;
  robot.forward_dynamics(q.data(), qd.data(), tau, tau_ext, ws, qdd, end_stops);
  qd += dt * qdd;
  q += dt * qd;
}

IntegrationResult integrate(const Robot& robot, const double* q0, const double* qd0, const double* tau,
                            int tau_rows, double dt, int steps, Method method, bool end_stops,
                            int record_every) {
  const int n = robot.dof();
  if (!(dt > 0) || !std::isfinite(dt)) throw std::invalid_argument("dt must be finite and > 0 s");
  if (steps < 0) throw std::invalid_argument("steps must be >= 0");
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
  auto record = [&](int step) {
    out.t.push_back(step * dt);
    out.q.insert(out.q.end(), q.data(), q.data() + n);
    out.qd.insert(out.qd.end(), qd.data(), qd.data() + n);
    ++out.rows;
  };
  record(0);
  auto fail = [&](int step, const std::string& why) {
    std::ostringstream msg;
    msg << "integration diverged at step " << step << " (t = " << step * dt << " s): " << why
        << "; last finite state q = [" << q.transpose() << "], qd = [" << qd.transpose() << "]";
    throw std::runtime_error(msg.str());
  };
  for (int s = 0; s < steps; ++s) {
    const double* u = tau + (tau_rows == 1 ? 0 : static_cast<size_t>(s) * n);
    const VecN q_prev = q, qd_prev = qd;
    try {
      if (method == Method::RK4) rk4_step(robot, ws, q, qd, u, nullptr, dt, end_stops);
      else euler_step(robot, ws, q, qd, u, nullptr, dt, end_stops);
    } catch (const std::domain_error& e) {
      q = q_prev;
      qd = qd_prev;
      fail(s + 1, e.what());
    }
    if (!q.allFinite() || !qd.allFinite()) {
      q = q_prev;
      qd = qd_prev;
      fail(s + 1, "state is no longer finite");
    }
    if ((s + 1) % record_every == 0 || s + 1 == steps) record(s + 1);
  }
  return out;
}

void forward_dynamics_batch(const Robot& robot, const double* Q, const double* QD, const double* TAU, int N,
                            double* QDD, int threads) {
  const int n = robot.dof();
  if (threads <= 0) threads = std::max(1u, std::thread::hardware_concurrency());
  threads = std::max(1, std::min(threads, N / 256 + 1));
  auto work = [&](int begin, int end) {
    Workspace ws;
    VecN qdd;
    for (int i = begin; i < end; ++i) {
      const size_t o = static_cast<size_t>(i) * n;
      robot.forward_dynamics(Q + o, QD + o, TAU + o, nullptr, ws, qdd, false);
      std::copy(qdd.data(), qdd.data() + n, QDD + o);
    }
  };
  if (threads == 1) {
    work(0, N);
    return;
  }
  std::vector<std::thread> pool;
  const int chunk = (N + threads - 1) / threads;
  for (int t = 0; t < threads; ++t) {
    const int b = t * chunk, e = std::min(N, b + chunk);
    if (b < e) pool.emplace_back(work, b, e);
  }
  for (auto& th : pool) th.join();
}

}  // namespace coopsim
