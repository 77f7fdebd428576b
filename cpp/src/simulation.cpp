// The simulation's lifecycle and options (construction, robots, references, applied inputs,
// reset), the step's stages in order (stages_, advance), and the two stages that are the
// simulation's own: control (references and controllers) and integrate. The other stages live
// beside it: the world's side and the contacts in contact_coupling.cpp, the grasp in grasp.cpp,
// the log in log.cpp; divergence checks in divergence.cpp.
#include "coopsim/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "simulation_internal.hpp"

namespace coopsim {

using detail::Stopwatch;

namespace {

// The poses of robot's collision boxes at q (computed in ws), in its boxes' order.
std::vector<Eigen::Isometry3d> box_poses_at(const Robot& robot, const VecN& q, Workspace& ws) {
  robot.kinematics(q.data(), ws);
  std::vector<Eigen::Isometry3d> poses;
  robot.box_poses(ws, poses);
  return poses;
}

}  // namespace

Simulation::Simulation(SimulationOptions options, std::shared_ptr<World> world)
    : driver_(make_driver_()), opt_(options) {
  check_step_size(opt_.dt);
  if (opt_.world_every < 1)
    throw std::invalid_argument("world_every must be >= 1, got " + std::to_string(opt_.world_every));
  if (!(opt_.contact_frequency_dt > 0 && opt_.contact_frequency_dt <= 1))
    throw std::invalid_argument("contact_frequency_dt must be in (0, 1]");
  check_grasp_options(opt_.grasp);
  if (opt_.control_every < 1)
    throw std::invalid_argument("control_every must be >= 1, got " + std::to_string(opt_.control_every));
  if (opt_.log_every < 0)
    throw std::invalid_argument("log_every must be >= 0 (0: no log), got " + std::to_string(opt_.log_every));
  if (!(opt_.max_speed > 0))
    throw std::invalid_argument("max_speed must be > 0, got " + std::to_string(opt_.max_speed));
  if (!(opt_.max_position > 0))
    throw std::invalid_argument("max_position must be > 0, got " + std::to_string(opt_.max_position));
  if (world) {
    world->attach();
    world_ = std::move(world);
  }
}

Simulation::~Simulation() {
  if (world_) world_->detach();
}

Simulation::Slot& Simulation::slot_(int i) {
  if (i < 0 || i >= robot_count())
    throw std::out_of_range("robot index " + std::to_string(i) + " out of range (" + std::to_string(robot_count()) +
                            " robots)");
  return slots_[i];
}

const Simulation::Slot& Simulation::slot_(int i) const {
  return const_cast<Simulation*>(this)->slot_(i);
}

int Simulation::add_robot(const Robot& robot, std::shared_ptr<Controller> controller,
                          std::shared_ptr<const Reference> reference, const double* q0, const double* qd0) {
  const Entry driving = enter_();  // one driver at a time
  if (started_ || k_ != 0) throw std::invalid_argument("robots can only be added before the first step (call reset())");
  if (!controller) throw std::invalid_argument("controller must not be None");
  if (!reference) throw std::invalid_argument("reference must not be None");
  const int n = robot.dof();
  if (reference->dof() != n)
    throw std::invalid_argument("reference has " + std::to_string(reference->dof()) + " joints but robot '" +
                                robot.name() + "' has " + std::to_string(n));
  for (const Slot& s : slots_)
    if (s.control.controller == controller)
      throw std::invalid_argument("controller is already driving another robot: give each robot its own instance");
  controller->check(robot);
  Slot s(robot);
  s.control.controller = std::move(controller);
  s.control.reference = std::move(reference);
  s.state.q0 = VecN::Zero(n);
  s.state.qd0 = VecN::Zero(n);
  s.control.reference->evaluate(0.0, s.state.q0.data(), s.state.qd0.data(), nullptr);
  if (q0) s.state.q0 = Eigen::Map<const VecN>(q0, n);
  if (qd0) s.state.qd0 = Eigen::Map<const VecN>(qd0, n);
  if (!s.state.q0.allFinite()) throw std::invalid_argument("q0 must be finite");
  if (!s.state.qd0.allFinite()) throw std::invalid_argument("qd0 must be finite");
  if (world_) {  // its boxes at q0 where a world can hold them: refused here rather than at the first step
    const std::vector<Eigen::Isometry3d> poses = box_poses_at(robot, s.state.q0, s.ws);
    for (size_t k = 0; k < poses.size(); ++k) {
      const std::string& box = robot.boxes()[k].name;
      World::check_pose(poses[k], "the start of robot '" + robot.name() + "' (q0, or its reference at t = 0) puts its box '" +
                                      (box.empty() ? std::to_string(k) : box) + "'");
    }
  }
  s.state.q = s.state.q0;
  s.state.qd = s.state.qd0;
  s.control.tau = VecN::Zero(n);
  s.control.tau_max = robot.tau_max();
  s.control.q_ref = s.control.qd_ref = s.control.qdd_ref = s.state.k1 = s.state.q_prev = s.state.qd_prev = VecN::Zero(n);
  s.external.forces = s.external.tau = s.contact.tau = VecN::Zero(n);
  if (world_ && (robot.gravity_acceleration() - world_->options().gravity).norm() > 1e-12)
    throw std::invalid_argument("robot '" + robot.name() + "' has another gravity than the world's");
  s.record.metrics.sum_sq_error = s.record.metrics.max_abs_error = s.record.metrics.max_abs_tau = VecN::Zero(n);
  for (LogColumn& c : s.record.log.columns) c = LogColumn(n);
  s.record.log.grasp = LogColumn(7);
  s.record.log.ft = LogColumn(12);
  slots_.push_back(std::move(s));
  for (int a = 0; a + 1 < robot_count(); ++a) {
    pairs_.emplace_back();
    pairs_.back().a = a;
    pairs_.back().b = robot_count() - 1;
  }
  return robot_count() - 1;
}

void Simulation::reset() {
  const Entry driving = enter_();  // one driver at a time
  if (world_) world_->reset();
  for (LogColumn& c : body_log_) c.clear();
  contact_log_.clear();
  grasp_events_.clear();
  body_wrenches_.clear();
  world_at_ = -1;
  profile_ = StepProfile();
  k_ = 0;
  logged_at_ = -1;
  started_ = false;
  diverged_ = false;
  divergence_.clear();
  log_t_.clear();
  for (Pair& p : pairs_) {
    p.log.clear();
    p.attached = false;
  }
  for (Slot& s : slots_) {
    const int n = s.robot.dof();
    s.state.q = s.state.q0;
    s.state.qd = s.state.qd0;
    s.control.tau.setZero(n);
    s.external.forces.setZero(n);
    s.external.tau.setZero(n);
    s.contact.tau.setZero(n);
    s.external.wrenches.clear();
    s.contact.wrenches.clear();
    s.external.applied = s.contact.any = false;
    s.grasp.held = s.grasp.candidate = -1;
    s.grasp.candidate_since = -1;
    s.grasp.weld.setZero();
    s.grasp.fade = 1.0;
    s.grasp.releasing = false;
    s.state.k1_valid = false;
    s.control.updated_at = -1;
    for (LogColumn& c : s.record.log.columns) c.clear();
    s.record.log.grasp.clear();
    s.record.log.ft.clear();
    reset_sensor_(s);
    s.record.metrics.steps = 0;
    s.record.metrics.sum_sq_error.setZero(n);
    s.record.metrics.max_abs_error.setZero(n);
    s.record.metrics.max_abs_tau.setZero(n);
  }
}

long Simulation::steps_until(double t_end) const {
  if (!std::isfinite(t_end)) throw std::invalid_argument("t_end must be finite");
  const double span = (t_end - time()) / opt_.dt;
  if (span < -1e-9)
    throw std::invalid_argument("t_end = " + std::to_string(t_end) + " s is before the current time " +
                                std::to_string(time()) + " s");
  if (span > 4e18) throw std::invalid_argument("t_end is too far ahead for dt");
  return std::max(0L, static_cast<long>(std::floor(span + 1e-9)));
}

void Simulation::start_() {
  if (world_) {
    // robot labels: names, made unique with _<index> when repeated (as the log's)
    World& w = *world_;
    w.clear_robots();
    for (size_t i = 0; i < slots_.size(); ++i) {
      Slot& s = slots_[i];
      const Robot& r = s.robot;
      int same = 0;
      for (const Slot& o : slots_) same += o.robot.name() == r.name();
      const std::string label = same > 1 ? r.name() + "_" + std::to_string(i) : r.name();
      const std::vector<Eigen::Isometry3d> poses = box_poses_at(r, s.state.q, s.ws);
      std::vector<std::string> names;
      std::vector<int> links;
      std::vector<Eigen::Vector3d> half;
      for (const LinkBox& b : r.boxes()) {
        names.push_back(b.name.empty() ? "box" + std::to_string(names.size()) : b.name);
        links.push_back(b.link);
        half.push_back(b.half_extents);
      }
      s.contact.first_body = w.body_count();
      w.add_robot(static_cast<int>(i), label, names, links, half, poses, excluded_pairs(r), 1.0);
    }
    free_ids_ = w.free_bodies();
    body_now_.assign(free_ids_.size(), BodyState());
    if (body_log_.size() != free_ids_.size()) body_log_.assign(free_ids_.size(), LogColumn(13));
  }
  const double period = opt_.dt * opt_.control_every;
  for (Coop& g : coops_) {
    if (!g.active) continue;
    std::vector<const Robot*> rs;
    for (int i : g.robots) rs.push_back(&slots_[i].robot);
    g.controller->reset(rs, period);
  }
  for (Slot& s : slots_) {
    s.control.controller->reset(s.robot, period);
    s.control.updated_at = -1;
    s.state.k1_valid = false;
  }
  started_ = true;
}

void Simulation::qdd_(Slot& s, VecN& out) {
  s.robot.forward_dynamics(s.state.q.data(), s.state.qd.data(), s.control.tau.data(),
                           has_ext_(s) ? s.external.tau.data() : nullptr, s.ws, out, opt_.end_stops);
}

void Simulation::set_reference(int i, std::shared_ptr<const Reference> reference) {
  const Entry driving = enter_();  // one driver at a time
  Slot& s = slot_(i);
  if (!reference) throw std::invalid_argument("reference must not be None");
  if (reference->dof() != s.robot.dof())
    throw std::invalid_argument("reference has " + std::to_string(reference->dof()) + " joints but robot '" +
                                s.robot.name() + "' has " + std::to_string(s.robot.dof()));
  s.control.reference = std::move(reference);
}

void Simulation::set_applied_forces(int i, const VecN& forces) {
  const Entry driving = enter_();  // one driver at a time
  Slot& s = slot_(i);
  const int n = s.robot.dof();
  if (forces.size() != n)
    throw std::invalid_argument("wrong size for applied joint forces: expected " + std::to_string(n) + ", got " +
                                std::to_string(forces.size()));
  if (!forces.allFinite()) throw std::invalid_argument("applied joint forces must be finite");
  s.external.forces = forces;
  s.external.applied = !s.external.wrenches.empty() || (forces.array() != 0.0).any();
  applied_changed_(s);
}

void Simulation::set_applied_wrenches(int i, std::vector<ExternalWrench> wrenches) {
  const Entry driving = enter_();  // one driver at a time
  Slot& s = slot_(i);
  const int n = s.robot.dof();
  for (size_t k = 0; k < wrenches.size(); ++k) {
    const ExternalWrench& w = wrenches[k];
    if (!w.at_tool && (w.link < -n || w.link > n || w.link == 0))
      throw std::invalid_argument("wrenches[" + std::to_string(k) + "]: link must be 1.." + std::to_string(n) +
                                  " (or negative from the last), got " + std::to_string(w.link));
    if (!w.point.allFinite() || !w.wrench.allFinite())
      throw std::invalid_argument("wrenches[" + std::to_string(k) + "]: point and wrench must be finite");
  }
  s.external.wrenches = std::move(wrenches);
  s.external.applied = !s.external.wrenches.empty() || (s.external.forces.array() != 0.0).any();
  applied_changed_(s);
}

void Simulation::applied_changed_(Slot& s) {
  // the new inputs hold from now on, over the next step
  external_(s);
  s.state.k1_valid = false;
  if (s.sensor.at == k_) sense_(s);  // the reading at this time sees them too
  // a row already logged at this time shows the inputs before the change:
  // the next advance logs a second row at this time with the new ones
  if (logged_at_ == k_) logged_at_ = -1;
}

void Simulation::external_(Slot& s) {
  s.external.tau = s.contact.tau;
  if (!s.external.applied) return;
  s.external.tau += s.external.forces;
  if (!s.external.wrenches.empty()) {
    VecN t;
    s.robot.kinematics(s.state.q.data(), s.ws);
    s.robot.external_torques(s.external.wrenches, s.ws, t);
    s.external.tau += t;
  }
}

int Simulation::link_body(int i, int box) const {
  const Slot& s = slot_(i);
  if (s.contact.first_body < 0) return -1;
  if (box < 0 || box >= static_cast<int>(s.robot.boxes().size()))
    throw std::out_of_range("box index " + std::to_string(box) + " out of range");
  return s.contact.first_body + box;
}

BodyState Simulation::body_state(int id) const {
  if (!world_) throw std::invalid_argument("the simulation has no world");
  const BodySpec& b = world_->body(id);
  if (b.kind == BodyKind::Link) throw std::invalid_argument("body '" + b.name + "' is a robot's link: see the robot's state");
  if (b.kind == BodyKind::Free && world_at_ >= 0) {
    for (size_t k = 0; k < free_ids_.size(); ++k)
      if (free_ids_[k] == id) return body_now_[k];
  }
  return world_->state(id);
}

// ---- the step ----

// The stages at t_k, in order. What they hold (torques, contacts, welds) acts over [t_k, t_k+1);
// integrate_() then takes every robot there. A stage already done at t_k is not done again.
void Simulation::stages_() {
  const bool fresh = control_();  // control: references and controllers (zero-order hold)
  if (world_due_()) {
    const double h = opt_.dt * opt_.world_every;
    {
      Stopwatch world(profiling_, profile_.world);  // the grasp included
      links_to_world_();   // world: the links' poses and twists, the free bodies at t_k
      grasp_(h);           // grasp: the clamp rule, the welds' wrenches on the bodies
      world_advance_(h);   // the world's step (Bullet): free bodies, contacts
    }
    {
      Stopwatch contacts(profiling_, profile_.contacts);
      contacts_to_robots_(h);  // contact and weld wrenches as joint torques, held over the world step
    }
    world_at_ = k_;
    if (profiling_) ++profile_.world_steps;
  }
  if (fresh) hold_external_();  // applied inputs and contacts: the external torque over the step
  sense_();                     // sense: the force/torque sensors at t_k
  log_();                       // log: the row at t_k
}

void Simulation::advance(long n) {
  const Entry driving = enter_();  // one driver at a time
  if (n < 0) throw std::invalid_argument("n must be >= 0, got " + std::to_string(n));
  if (slots_.empty() && !world_)
    throw std::invalid_argument("the simulation has no robot: add one with add_robot()");
  if (diverged_) throw std::runtime_error("the simulation has diverged (" + divergence_ + "); call reset()");
  if (!started_) start_();
  reserve(n);
  stages_();
  for (long i = 0; i < n; ++i) {
    integrate_();  // integrate: t_k -> t_k+1
    stages_();
  }
}

// The control stage: every robot not yet updated at t_k samples its reference; at the control
// steps its controller computes the torque, saturated and held until the next update. The
// tracking metrics count every step. Returns whether any robot was updated.
bool Simulation::control_() {
  Stopwatch watch(profiling_, profile_.controllers);
  const double t = time();
  const bool control = k_ % opt_.control_every == 0;
  if (control && !coops_.empty()) cooperate_();
  ControlInput in;
  in.t = t;
  bool fresh = false;
  for (Slot& s : slots_) {
    Slot::Control& c = s.control;
    if (c.updated_at == k_) continue;
    fresh = true;
    const int n = s.robot.dof();
    c.reference->evaluate(t, c.q_ref.data(), c.qd_ref.data(), c.qdd_ref.data());
    if (control && c.coop < 0) {
      in.n = n;
      in.q = s.state.q.data();
      in.qd = s.state.qd.data();
      in.q_ref = c.q_ref.data();
      in.qd_ref = c.qd_ref.data();
      in.qdd_ref = c.qdd_ref.data();
      in.wrench = nullptr;
      in.frames = nullptr;
      if (c.controller->senses()) {  // the sensor at t_k: the contact and weld wrenches of the last world step
        s.robot.kinematics(s.state.q.data(), s.ws, false);  // the frames, for the sensor and the controller
        sense_(s, true, true);
        in.wrench = s.sensor.world.data();
        in.frames = &s.ws;
      }
      VecN u(n);
      c.controller->compute(in, u.data());
      if (!u.allFinite()) torque_diverged_(s, u);
      // actuator limits bind whatever the controller did
      saturate(n, c.tau_max.data(), u.data());
      c.tau = u;
      s.state.k1_valid = false;
    }
    TrackingMetrics& m = s.record.metrics;
    for (int i = 0; i < n; ++i) {
      const double e = c.q_ref[i] - s.state.q[i];
      m.sum_sq_error[i] += e * e;
      m.max_abs_error[i] = std::max(m.max_abs_error[i], std::abs(e));
      m.max_abs_tau[i] = std::max(m.max_abs_tau[i], std::abs(c.tau[i]));
    }
    ++m.steps;
    c.updated_at = k_;
  }
  return fresh;
}

// The external torque of each robot at t_k: the applied wrenches' J^T changes with q, contacts
// may have come or gone.
void Simulation::hold_external_() {
  for (Slot& s : slots_) {
    if (s.external.applied || s.contact.any || s.external.held) {
      external_(s);
      s.state.k1_valid = false;
      s.external.held = s.external.applied || s.contact.any;
    }
  }
}

// The integrate stage: every robot from t_k to t_k+1 under its held torques (RK4 or Euler),
// then the divergence check of its new state.
void Simulation::integrate_() {
  Stopwatch watch(profiling_, profile_.robots);
  for (Slot& s : slots_) {
    s.state.q_prev = s.state.q;
    s.state.qd_prev = s.state.qd;
  }
  for (size_t i = 0; i < slots_.size(); ++i) {
    Slot& s = slots_[i];
    try {
      // the first stage was computed for the log row at this state and torque
      step(s.robot, s.ws, opt_.integrator, s.state.q, s.state.qd, s.control.tau.data(),
           has_ext_(s) ? s.external.tau.data() : nullptr, opt_.dt, opt_.end_stops,
           s.state.k1_valid ? &s.state.k1 : nullptr);
    } catch (const StageError& e) {
      diverge_(static_cast<int>(i),
               stage_failure_reason(e, opt_.integrator, DivergenceLimits{opt_.max_speed, opt_.max_position}), true,
               false);
    } catch (const std::exception& e) {
      diverge_(static_cast<int>(i),
               std::string("the dynamics failed in a ") + method_name(opt_.integrator) + " stage (" + e.what() + ")",
               true, false);
    }
    s.state.k1_valid = false;
    // the common case without a call: every joint finite and within the limits
    bool fine = true;
    for (int j = 0; j < s.state.q.size(); ++j)
      fine = fine && std::abs(s.state.qd[j]) <= opt_.max_speed && std::abs(s.state.q[j]) <= opt_.max_position;
    if (!fine) state_diverged_(static_cast<int>(i));
  }
  ++k_;
  if (profiling_) ++profile_.steps;
}

long Simulation::run(double t_end, long chunk, const std::function<bool(long, long)>& progress) {
  const Entry driving = enter_();  // one driver at a time
  if (chunk < 1) throw std::invalid_argument("chunk must be >= 1, got " + std::to_string(chunk));
  const long total = steps_until(t_end);
  reserve(total);
  long done = 0;
  do {
    const long c = std::min(chunk, total - done);
    advance(c);
    done += c;
    if (progress && !progress(done, total)) break;
  } while (done < total);
  return done;
}

// ---- replacing a robot's controller in a run ----

void Simulation::set_controller(int i, std::shared_ptr<Controller> controller) {
  const Entry driving = enter_();  // one driver at a time
  Slot& s = slot_(i);
  if (!controller) throw std::invalid_argument("controller must not be None");
  for (size_t k = 0; k < slots_.size(); ++k)
    if (static_cast<int>(k) != i && slots_[k].control.controller == controller)
      throw std::invalid_argument("controller is already driving robot " + std::to_string(k) +
                                  ": give each robot its own instance");
  controller->check(s.robot);
  // a run under way: the new controller starts now (start_ resets it otherwise)
  if (started_) controller->reset(s.robot, opt_.dt * opt_.control_every);
  s.control.controller = std::move(controller);
}


// ---- replacing a robot in a run ----

void Simulation::set_robot(int i, const Robot& robot) {
  const Entry driving = enter_();  // one driver at a time
  Slot& s = slot_(i);
  const Robot& old = s.robot;
  const int n = old.dof();
  if (robot.dof() != n || robot.joint_types() != old.joint_types())
    throw std::invalid_argument("robot must have the joints of robot '" + old.name() + "' (" + old.joint_types() +
                                "), got '" + robot.name() + "' (" + robot.joint_types() + ")");
  const std::vector<LinkBox>& nb = robot.boxes();
  bool same_boxes = nb.size() == old.boxes().size();
  for (size_t b = 0; same_boxes && b < nb.size(); ++b) same_boxes = nb[b].link == old.boxes()[b].link;
  if (!same_boxes)
    throw std::invalid_argument("robot must have as many boxes as robot '" + old.name() + "' (" +
                                std::to_string(old.boxes().size()) + "), on the same links; got " +
                                std::to_string(nb.size()));
  if (s.grasp.held >= 0)
    throw std::invalid_argument("robot " + std::to_string(i) + " holds a body: release it before replacing the robot");
  if (world_ && (robot.gravity_acceleration() - world_->options().gravity).norm() > 1e-12)
    throw std::invalid_argument("robot '" + robot.name() + "' has another gravity than the world's");
  s.control.controller->check(robot);
  // every check before any change: the boxes at q where the world can hold them
  Workspace ws;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<Eigen::Vector3d> half;
  std::vector<std::pair<int, int>> excluded;
  const bool in_world = world_ && started_ && s.contact.first_body >= 0;  // its bodies in the world now
  if (world_) {
    poses = box_poses_at(robot, s.state.q, ws);
    for (size_t k = 0; k < poses.size(); ++k)
      World::check_pose(poses[k], "robot '" + robot.name() + "' at the present q puts its box '" +
                                      (nb[k].name.empty() ? std::to_string(k) : nb[k].name) + "'");
    for (const LinkBox& b : nb) half.push_back(b.half_extents);
    if (in_world) excluded = excluded_pairs(robot);
  }
  s.robot = robot;
  s.ws = ws;
  s.control.tau_max = s.robot.tau_max();
  saturate(n, s.control.tau_max.data(), s.control.tau.data());
  s.state.k1_valid = false;  // the dynamics changed: the next step's first stage anew
  s.contact.M_valid = false;
  if (started_) s.control.controller->reset(s.robot, opt_.dt * opt_.control_every);
  if (in_world) world_->replace_robot_boxes(s.contact.first_body, half, poses, excluded);
}

}  // namespace coopsim
