// The control stage's cooperative part: groups of robots driven by one CooperativeController
// (Simulation::add_cooperative), each seeing its members' states, sensors and grips.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "coopsim/simulation.hpp"

namespace coopsim {

int Simulation::add_cooperative(std::shared_ptr<CooperativeController> controller, std::vector<int> robots) {
  const Entry driving = enter_();  // one driver at a time
  if (!controller) throw std::invalid_argument("controller must not be None");
  for (const Coop& g : coops_)
    if (g.controller == controller && g.active)
      throw std::invalid_argument("this cooperative controller already drives a group: give each group its own");
  if (robots.empty()) throw std::invalid_argument("robots must name at least one robot");
  std::vector<const Robot*> rs;
  for (size_t a = 0; a < robots.size(); ++a) {
    const int i = robots[a];
    slot_(i);  // the index's check
    for (size_t b = 0; b < a; ++b)
      if (robots[b] == i) throw std::invalid_argument("robots names robot " + std::to_string(i) + " twice");
    if (slots_[i].control.coop >= 0)
      throw std::invalid_argument("robot " + std::to_string(i) + " is already driven by cooperative group " +
                                  std::to_string(slots_[i].control.coop));
    rs.push_back(&slots_[i].robot);
  }
  controller->check(rs);
  if (started_) controller->reset(rs, opt_.dt * opt_.control_every);
  const int k = static_cast<int>(coops_.size());
  coops_.push_back(Coop{std::move(controller), robots, true});
  for (int i : robots) slots_[i].control.coop = k;
  return k;
}

void Simulation::remove_cooperative(int k) {
  const Entry driving = enter_();  // one driver at a time
  if (k < 0 || k >= cooperative_count())
    throw std::out_of_range("cooperative group " + std::to_string(k) + " out of range");
  Coop& g = coops_[k];
  if (!g.active) return;
  g.active = false;
  for (int i : g.robots) {
    Slot& s = slots_[i];
    s.control.coop = -1;
    if (started_) s.control.controller->reset(s.robot, opt_.dt * opt_.control_every);
  }
}

const std::shared_ptr<CooperativeController>& Simulation::cooperative(int k) const {
  if (k < 0 || k >= cooperative_count())
    throw std::out_of_range("cooperative group " + std::to_string(k) + " out of range");
  return coops_[k].controller;
}
const std::vector<int>& Simulation::cooperative_robots(int k) const {
  cooperative(k);
  return coops_[k].robots;
}
bool Simulation::cooperative_active(int k) const {
  cooperative(k);
  return coops_[k].active;
}

// Each active group not yet updated at t_k: its members' references, sensors and grips, then its
// controller's torques, saturated and held like a robot's own controller's.
void Simulation::cooperate_() {
  const double t = time();
  for (Coop& g : coops_) {
    if (!g.active || slots_[g.robots[0]].control.updated_at == k_) continue;
    members_.resize(g.robots.size());
    coop_tau_.resize(g.robots.size());
    coop_out_.resize(g.robots.size());
    std::vector<double*>& out = coop_out_;
    for (size_t a = 0; a < g.robots.size(); ++a) {
      Slot& s = slots_[g.robots[a]];
      Slot::Control& c = s.control;
      const Robot& r = s.robot;
      c.reference->evaluate(t, c.q_ref.data(), c.qd_ref.data(), c.qdd_ref.data());
      r.kinematics(s.state.q.data(), s.ws, false);  // the frames, for the sensor, the grip and the controller
      sense_(s, true, true);
      CoopMember& m = members_[a];
      m.robot = g.robots[a];
      m.in = ControlInput{r.dof(), t, s.state.q.data(), s.state.qd.data(), c.q_ref.data(), c.qd_ref.data(),
                          c.qdd_ref.data(), s.sensor.world.data(), &s.ws};
      m.held = s.grasp.held;
      if (m.held >= 0) {
        m.grip = r.tool_pose(s.ws).inverse() * (r.frame(s.ws, r.clamp().fixed_link) * s.grasp.weld_X);
      } else {
        m.grip.setIdentity();
      }
      coop_tau_[a].setZero(r.dof());
      out[a] = coop_tau_[a].data();
    }
    g.controller->compute(t, members_, out);
    for (size_t a = 0; a < g.robots.size(); ++a) {
      Slot& s = slots_[g.robots[a]];
      VecN& u = coop_tau_[a];
      if (!u.allFinite()) torque_diverged_(s, u);
      saturate(s.robot.dof(), s.control.tau_max.data(), u.data());
      s.control.tau = u;
      s.state.k1_valid = false;
    }
  }
}

}  // namespace coopsim
