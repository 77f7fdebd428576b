// Divergence: the reason a state after a step is rejected, and the errors that stop a run (a
// diverged robot, a non-finite torque, a diverged free body of the world). Each one marks the
// simulation diverged, keeps its log up to the last good step and throws DivergenceError naming
// the step, the time, the robot and the state.
#include <cmath>
#include <sstream>

#include "coopsim/simulation.hpp"
#include "simulation_internal.hpp"
#include "stages.hpp"

namespace coopsim {

namespace stages {

using detail::vec_str;

void state_diverged(const Model& m, Data& d, int i) {
  const RobotData& s = d.robots[i];
  const std::string why =
      divergence_reason(s.state.q, s.state.qd, DivergenceLimits{m.options.max_speed, m.options.max_position});
  if (!why.empty()) diverge(m, d, i, why, true, true);
}

void diverge(const Model& m, Data& d, int i, const std::string& why, bool in_step, bool state_is_result) {
  const SimulationOptions& opt = m.options;
  RobotData& bad = d.robots[i];
  const Robot& robot = m.robots[i].robot;
  const VecN q_bad = bad.state.q, qd_bad = bad.state.qd;
  const long step = in_step ? d.k + 1 : d.k;
  // a rejected step goes back to the last good state
  for (RobotData& s : d.robots) {
    if (in_step) {
      s.state.q = s.state.q_prev;
      s.state.qd = s.state.qd_prev;
    }
    s.state.k1_valid = false;
  }
  d.diverged = true;
  std::ostringstream msg;
  msg << "simulation diverged at step " << step << " (t = " << step * opt.dt << " s, dt = " << opt.dt
      << " s): robot " << i << " '" << robot.name() << "': " << why << "; "
      << (state_is_result ? "state reached" : "state at the start of the step") << ": q = " << vec_str(q_bad)
      << ", qd = " << vec_str(qd_bad) << ", torque held = " << vec_str(bad.control.tau) << "; the log ends at t = "
      << (d.log_t.rows() ? d.log_t.back() : 0.0) << " s";
  if (opt.end_stops) {
    const std::string hint = end_stop_step_warning(robot, opt.dt);
    if (!hint.empty()) msg << "; " << hint;
  }
  d.divergence = msg.str();
  throw DivergenceError(d.divergence, step, step * opt.dt, i, q_bad, qd_bad);
}

void torque_diverged(const Model& m, Data& d, int i, const VecN& u) {
  const RobotData& s = d.robots[i];
  const double t = d.time(m);
  std::ostringstream msg;
  msg << "controller of robot " << i << " '" << m.robots[i].robot.name() << "' returned a non-finite torque at step "
      << d.k << " (t = " << t << " s): tau = " << vec_str(u) << ", q = " << vec_str(s.state.q)
      << ", qd = " << vec_str(s.state.qd);
  d.diverged = true;
  d.divergence = msg.str();
  throw DivergenceError(d.divergence, d.k, t, i, s.state.q, s.state.qd);
}

void world_diverged(const Model& m, Data& d, const WorldDivergence& e, double h) {
  d.diverged = true;
  std::ostringstream msg;
  msg << "simulation diverged at step " << d.k + 1 << ": " << e.what() << "; the log ends at t = "
      << (d.log_t.rows() ? d.log_t.back() : 0.0) << " s";
  d.divergence = msg.str();
  throw DivergenceError(d.divergence, d.k + 1, d.time(m) + h, -1, VecN(), VecN());
}

}  // namespace stages

}  // namespace coopsim
