// The control stage's cooperative part: groups of robots driven by one CooperativeController
// (Simulation::add_cooperative), each seeing its members' states, sensors and grips.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "coopsim/simulation.hpp"
#include "stages.hpp"

namespace coopsim {

int Simulation::add_cooperative(std::shared_ptr<CooperativeController> controller, std::vector<int> robots) {
  const Entry driving = enter_();  // one driver at a time
  if (!controller) throw std::invalid_argument("controller must not be None");
  for (size_t k = 0; k < data_.cooperatives.size(); ++k)
    if (data_.cooperatives[k] == controller && model_->cooperatives[k].active)
      throw std::invalid_argument("this cooperative controller already drives a group: give each group its own");
  if (robots.empty()) throw std::invalid_argument("robots must name at least one robot");
  std::vector<const Robot*> rs;
  for (size_t a = 0; a < robots.size(); ++a) {
    const int i = robots[a];
    check_(i);
    for (size_t b = 0; b < a; ++b)
      if (robots[b] == i) throw std::invalid_argument("robots names robot " + std::to_string(i) + " twice");
    if (model_->robots[i].coop >= 0)
      throw std::invalid_argument("robot " + std::to_string(i) + " is already driven by cooperative group " +
                                  std::to_string(model_->robots[i].coop));
    rs.push_back(&model_->robots[i].robot);
  }
  controller->check(rs);
  if (data_.started) controller->reset(rs, model_->options.dt * model_->options.control_every);
  SimulationModel& m = edit_();
  const int k = static_cast<int>(m.cooperatives.size());
  m.cooperatives.push_back(CooperativeModel{controller, robots, true});
  for (int i : robots) m.robots[i].coop = k;
  data_.cooperatives.push_back(std::move(controller));
  return k;
}

void Simulation::remove_cooperative(int k) {
  const Entry driving = enter_();  // one driver at a time
  if (k < 0 || k >= cooperative_count())
    throw std::out_of_range("cooperative group " + std::to_string(k) + " out of range");
  if (!model_->cooperatives[k].active) return;
  SimulationModel& m = edit_();
  CooperativeModel& g = m.cooperatives[k];
  g.active = false;
  for (int i : g.robots) {
    m.robots[i].coop = -1;
    if (data_.started) data_.robots[i].control.controller->reset(m.robots[i].robot, m.options.dt * m.options.control_every);
  }
}

const std::shared_ptr<CooperativeController>& Simulation::cooperative(int k) const {
  if (k < 0 || k >= cooperative_count())
    throw std::out_of_range("cooperative group " + std::to_string(k) + " out of range");
  return data_.cooperatives[k];
}
const std::vector<int>& Simulation::cooperative_robots(int k) const {
  cooperative(k);
  return model_->cooperatives[k].robots;
}
bool Simulation::cooperative_active(int k) const {
  cooperative(k);
  return model_->cooperatives[k].active;
}

namespace stages {

// Each active group not yet updated at t_k: its members' references, sensors and grips, then its
// controller's torques, saturated and held like a robot's own controller's.
void cooperate(const Model& m, Data& d) {
  const double t = d.time(m);
  for (size_t k = 0; k < m.cooperatives.size(); ++k) {
    const CooperativeModel& g = m.cooperatives[k];
    if (!g.active || d.robots[g.robots[0]].control.updated_at == d.k) continue;
    d.members.resize(g.robots.size());
    d.coop_tau.resize(g.robots.size());
    d.coop_out.resize(g.robots.size());
    std::vector<double*>& out = d.coop_out;
    for (size_t a = 0; a < g.robots.size(); ++a) {
      const int i = g.robots[a];
      RobotData& s = d.robots[i];
      RobotData::Control& c = s.control;
      const Robot& r = m.robots[i].robot;
      m.robots[i].reference->evaluate(t, c.q_ref.data(), c.qd_ref.data(), c.qdd_ref.data());
      r.kinematics(s.state.q.data(), s.ws, false);  // the frames, for the sensor, the grip and the controller
      sense_robot(m, d, i, true, true);
      CoopMember& mb = d.members[a];
      mb.robot = i;
      mb.in = ControlInput{r.dof(), t, s.state.q.data(), s.state.qd.data(), c.q_ref.data(), c.qd_ref.data(),
                           c.qdd_ref.data(), s.sensor.world.data(), &s.ws, r.kinematics_id()};
      mb.held = s.grasp.held;
      if (mb.held >= 0) {
        mb.grip = r.tool_pose(s.ws).inverse() * (r.frame(s.ws, r.clamp().fixed_link) * s.grasp.weld_X);
      } else {
        mb.grip.setIdentity();
      }
      d.coop_tau[a].setZero(r.dof());
      out[a] = d.coop_tau[a].data();
    }
    d.cooperatives[k]->compute(t, d.members, out);
    for (size_t a = 0; a < g.robots.size(); ++a) {
      const int i = g.robots[a];
      RobotData& s = d.robots[i];
      VecN& u = d.coop_tau[a];
      if (!u.allFinite()) torque_diverged(m, d, i, u);
      saturate(m.robots[i].robot.dof(), m.robots[i].tau_max.data(), u.data());
      s.control.tau = u;
      s.state.k1_valid = false;
    }
  }
}

}  // namespace stages

}  // namespace coopsim
