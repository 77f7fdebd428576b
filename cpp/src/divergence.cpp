// Divergence: the reason a state after a step is rejected, and the errors that stop a run (a
// diverged robot, a non-finite torque, a diverged free body of the world). Each one marks the
// simulation diverged, keeps its log up to the last good step and throws DivergenceError naming
// the step, the time, the robot and the state.
#include <cmath>
#include <sstream>

#include "coopsim/simulation.hpp"
#include "simulation_internal.hpp"

namespace coopsim {

using detail::vec_str;

void Simulation::state_diverged_(int i) {
  const Slot& s = slots_[i];
  const std::string why =
      divergence_reason(s.state.q, s.state.qd, DivergenceLimits{opt_.max_speed, opt_.max_position});
  if (!why.empty()) diverge_(i, why, true, true);
}

void Simulation::diverge_(int i, const std::string& why, bool in_step, bool state_is_result) {
  Slot& bad = slots_[i];
  const VecN q_bad = bad.state.q, qd_bad = bad.state.qd;
  const long step = in_step ? k_ + 1 : k_;
  // a rejected step goes back to the last good state
  for (Slot& s : slots_) {
    if (in_step) {
      s.state.q = s.state.q_prev;
      s.state.qd = s.state.qd_prev;
    }
    s.state.k1_valid = false;
  }
  diverged_ = true;
  std::ostringstream msg;
  msg << "simulation diverged at step " << step << " (t = " << step * opt_.dt << " s, dt = " << opt_.dt
      << " s): robot " << i << " '" << bad.robot.name() << "': " << why << "; "
      << (state_is_result ? "state reached" : "state at the start of the step") << ": q = " << vec_str(q_bad)
      << ", qd = " << vec_str(qd_bad) << ", torque held = " << vec_str(bad.control.tau) << "; the log ends at t = "
      << (log_t_.rows() ? log_t_.back() : 0.0) << " s";
  if (opt_.end_stops) {
    const std::string hint = end_stop_step_warning(bad.robot, opt_.dt);
    if (!hint.empty()) msg << "; " << hint;
  }
  divergence_ = msg.str();
  throw DivergenceError(divergence_, step, step * opt_.dt, i, q_bad, qd_bad);
}

void Simulation::torque_diverged_(const Slot& s, const VecN& u) {
  const int i = static_cast<int>(&s - slots_.data());
  const double t = time();
  std::ostringstream msg;
  msg << "controller of robot " << i << " '" << s.robot.name() << "' returned a non-finite torque at step " << k_
      << " (t = " << t << " s): tau = " << vec_str(u) << ", q = " << vec_str(s.state.q)
      << ", qd = " << vec_str(s.state.qd);
  diverged_ = true;
  divergence_ = msg.str();
  throw DivergenceError(divergence_, k_, t, i, s.state.q, s.state.qd);
}

void Simulation::world_diverged_(const WorldDivergence& e, double h) {
  diverged_ = true;
  std::ostringstream msg;
  msg << "simulation diverged at step " << k_ + 1 << ": " << e.what() << "; the log ends at t = "
      << (log_t_.rows() ? log_t_.back() : 0.0) << " s";
  divergence_ = msg.str();
  throw DivergenceError(divergence_, k_ + 1, time() + h, -1, VecN(), VecN());
}

}  // namespace coopsim
