// The simulation's lifecycle and options (construction, robots, references, applied inputs,
// reset), its model shared by other runs, the step's stages in order (stages::run, advance), and
// the two stages that are the simulation's own: control (references and controllers) and
// integrate. The other stages live beside it, as free functions over the model and the data
// (stages.hpp): the world's side and the contacts in contact_coupling.cpp, the grasp in grasp.cpp,
// the log in log.cpp; divergence checks in divergence.cpp.
#include "coopsim/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "simulation_internal.hpp"
#include "stages.hpp"

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

void check_options(const SimulationOptions& o) {
  check_step_size(o.dt);
  if (o.world_every < 1) throw std::invalid_argument("world_every must be >= 1, got " + std::to_string(o.world_every));
  if (!(o.contact_frequency_dt > 0 && o.contact_frequency_dt <= 1))
    throw std::invalid_argument("contact_frequency_dt must be in (0, 1]");
  check_grasp_options(o.grasp);
  if (o.control_every < 1)
    throw std::invalid_argument("control_every must be >= 1, got " + std::to_string(o.control_every));
  if (o.log_every < 0)
    throw std::invalid_argument("log_every must be >= 0 (0: no log), got " + std::to_string(o.log_every));
  if (!(o.max_speed > 0)) throw std::invalid_argument("max_speed must be > 0, got " + std::to_string(o.max_speed));
  if (!(o.max_position > 0))
    throw std::invalid_argument("max_position must be > 0, got " + std::to_string(o.max_position));
}

}  // namespace

// ---- the run's data (stages.hpp) ----

namespace stages {

void add_robot_data(const Model& m, Data& d, int i) {
  const RobotModel& rm = m.robots[i];
  const int n = rm.robot.dof();
  d.robots.emplace_back(n);
  RobotData& s = d.robots.back();
  s.state.q = rm.q0;
  s.state.qd = rm.qd0;
  s.control.tau = VecN::Zero(n);
  s.control.q_ref = s.control.qd_ref = s.control.qdd_ref = s.state.k1 = s.state.q_prev = s.state.qd_prev = VecN::Zero(n);
  s.external.forces = s.external.tau = s.contact.tau = VecN::Zero(n);
  s.record.metrics.sum_sq_error = s.record.metrics.max_abs_error = s.record.metrics.max_abs_tau = VecN::Zero(n);
  for (LogColumn& c : s.record.log.columns) c = LogColumn(n);
  s.record.log.grasp = LogColumn(7);
  s.record.log.ft = LogColumn(12);
  reset_sensor(rm, s);
  for (int a = 0; a < i; ++a) {
    d.pairs.emplace_back();
    d.pairs.back().a = a;
    d.pairs.back().b = i;
  }
}

void init(const Model& m, Data& d, std::shared_ptr<World> world, bool own) {
  d.world = std::move(world);
  for (int i = 0; i < m.robot_count(); ++i) {
    add_robot_data(m, d, i);
    const RobotModel& rm = m.robots[i];
    std::shared_ptr<Controller> c = own ? rm.controller : rm.controller->clone();
    if (!c)
      throw std::invalid_argument("the controller of robot " + std::to_string(i) + " ('" + rm.robot.name() +
                                  "') cannot be copied for another run of its model: give that run its own");
    d.robots.back().control.controller = std::move(c);
  }
  for (size_t k = 0; k < m.cooperatives.size(); ++k) {
    const CooperativeModel& g = m.cooperatives[k];
    std::shared_ptr<CooperativeController> c = own ? g.controller : g.controller->clone();
    if (!c)
      throw std::invalid_argument("the cooperative law of group " + std::to_string(k) +
                                  " cannot be copied for another run of its model: give that run its own");
    d.cooperatives.push_back(std::move(c));
  }
}

void reset(const Model& m, Data& d) {
  if (d.world) d.world->reset();
  for (LogColumn& c : d.body_log) c.clear();
  d.contact_log.clear();
  d.grasp_events.clear();
  d.body_wrenches.clear();
  d.world_at = -1;
  d.profile = StepProfile();
  d.k = 0;
  d.logged_at = -1;
  d.started = false;
  d.diverged = false;
  d.divergence.clear();
  d.log_t.clear();
  for (PairData& p : d.pairs) {
    p.log.clear();
    p.attached = false;
  }
  for (size_t i = 0; i < d.robots.size(); ++i) {
    const RobotModel& rm = m.robots[i];
    RobotData& s = d.robots[i];
    const int n = rm.robot.dof();
    s.state.q = rm.q0;
    s.state.qd = rm.qd0;
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
    reset_sensor(rm, s);
    s.record.metrics.steps = 0;
    s.record.metrics.sum_sq_error.setZero(n);
    s.record.metrics.max_abs_error.setZero(n);
    s.record.metrics.max_abs_tau.setZero(n);
  }
}

void start(const Model& m, Data& d) {
  if (d.world) {
    // robot labels: names, made unique with _<index> when repeated (as the log's)
    World& w = *d.world;
    w.clear_robots();
    for (size_t i = 0; i < d.robots.size(); ++i) {
      RobotData& s = d.robots[i];
      const Robot& r = m.robots[i].robot;
      int same = 0;
      for (const RobotModel& o : m.robots) same += o.robot.name() == r.name();
      const std::string label = same > 1 ? r.name() + "_" + std::to_string(i) : r.name();
      const std::vector<Eigen::Isometry3d> poses = box_poses_at(r, s.state.q, s.ws);
      std::vector<std::string> names;
      std::vector<int> links;
      std::vector<Shape> shapes;
      for (const LinkBox& b : r.boxes()) {
        names.push_back(b.name.empty() ? "box" + std::to_string(names.size()) : b.name);
        links.push_back(b.link);
        shapes.push_back(b);
      }
      s.contact.first_body = w.body_count();
      w.add_robot(static_cast<int>(i), label, names, links, shapes, poses, Simulation::excluded_pairs(r), 1.0);
    }
    d.free_ids = w.free_bodies();
    d.body_now.assign(d.free_ids.size(), BodyState());
    if (d.body_log.size() != d.free_ids.size()) d.body_log.assign(d.free_ids.size(), LogColumn(13));
  }
  const double period = m.options.dt * m.options.control_every;
  for (size_t k = 0; k < m.cooperatives.size(); ++k) {
    const CooperativeModel& g = m.cooperatives[k];
    if (!g.active) continue;
    std::vector<const Robot*> rs;
    for (int i : g.robots) rs.push_back(&m.robots[i].robot);
    d.cooperatives[k]->reset(rs, period);
  }
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    s.control.controller->reset(m.robots[i].robot, period);
    s.control.updated_at = -1;
    s.state.k1_valid = false;
  }
  d.started = true;
}

void qdd(const Model& m, Data& d, int i, VecN& out) {
  RobotData& s = d.robots[i];
  m.robots[i].robot.forward_dynamics(s.state.q.data(), s.state.qd.data(), s.control.tau.data(),
                                     has_ext(s) ? s.external.tau.data() : nullptr, s.ws, out, m.options.end_stops);
}

void applied_changed(const Model& m, Data& d, int i) {
  RobotData& s = d.robots[i];
  // the new inputs hold from now on, over the next step
  external(m.robots[i], s);
  s.state.k1_valid = false;
  if (s.sensor.at == d.k) sense_robot(m, d, i);  // the reading at this time sees them too
  // a row already logged at this time shows the inputs before the change:
  // the next advance logs a second row at this time with the new ones
  if (d.logged_at == d.k) d.logged_at = -1;
}

void external(const RobotModel& r, RobotData& s) {
  s.external.tau = s.contact.tau;
  if (!s.external.applied) return;
  s.external.tau += s.external.forces;
  if (!s.external.wrenches.empty()) {
    VecN t;
    r.robot.kinematics(s.state.q.data(), s.ws);
    r.robot.external_torques(s.external.wrenches, s.ws, t);
    s.external.tau += t;
  }
}

// ---- the step ----

// The stages at t_k, in order. What they hold (torques, contacts, welds) acts over [t_k, t_k+1);
// integrate() then takes every robot there. A stage already done at t_k is not done again.
void run(const Model& m, Data& d) {
  const bool fresh = control(m, d);  // control: references and controllers (zero-order hold)
  if (world_due(m, d)) {
    const double h = m.options.dt * m.options.world_every;
    {
      Stopwatch world(d.profiling, d.profile.world);  // the grasp included
      links_to_world(m, d);   // world: the links' poses and twists, the free bodies at t_k
      grasp(m, d, h);         // grasp: the clamp rule, the welds' wrenches on the bodies
      world_advance(m, d, h); // the world's step (Bullet): free bodies, contacts
    }
    {
      Stopwatch contacts(d.profiling, d.profile.contacts);
      contacts_to_robots(m, d, h);  // contact and weld wrenches as joint torques, held over the world step
    }
    d.world_at = d.k;
    if (d.profiling) ++d.profile.world_steps;
  }
  if (fresh) hold_external(m, d);  // applied inputs and contacts: the external torque over the step
  sense(m, d);                     // sense: the force/torque sensors at t_k
  log(m, d);                       // log: the row at t_k
}

void advance(const Model& m, Data& d, long n) {
  if (n < 0) throw std::invalid_argument("n must be >= 0, got " + std::to_string(n));
  if (d.robots.empty() && !d.world)
    throw std::invalid_argument("the simulation has no robot: add one with add_robot()");
  if (d.diverged) throw std::runtime_error("the simulation has diverged (" + d.divergence + "); call reset()");
  if (!d.started) start(m, d);
  reserve(m, d, n);
  run(m, d);
  for (long i = 0; i < n; ++i) {
    integrate(m, d);  // integrate: t_k -> t_k+1
    run(m, d);
  }
}

// The control stage: every robot not yet updated at t_k samples its reference; at the control
// steps its controller computes the torque, saturated and held until the next update. The
// tracking metrics count every step. Returns whether any robot was updated.
bool control(const Model& m, Data& d) {
  Stopwatch watch(d.profiling, d.profile.controllers);
  const double t = d.time(m);
  const bool control = d.k % m.options.control_every == 0;
  if (control && !m.cooperatives.empty()) cooperate(m, d);
  ControlInput in;
  in.t = t;
  bool fresh = false;
  for (size_t i = 0; i < d.robots.size(); ++i) {
    const RobotModel& rm = m.robots[i];
    RobotData& s = d.robots[i];
    RobotData::Control& c = s.control;
    if (c.updated_at == d.k) continue;
    fresh = true;
    const int n = rm.robot.dof();
    rm.reference->evaluate(t, c.q_ref.data(), c.qd_ref.data(), c.qdd_ref.data());
    if (control && rm.coop < 0) {
      in.n = n;
      in.q = s.state.q.data();
      in.qd = s.state.qd.data();
      in.q_ref = c.q_ref.data();
      in.qd_ref = c.qd_ref.data();
      in.qdd_ref = c.qdd_ref.data();
      in.wrench = nullptr;
      in.workspace = &s.ws;  // the robot's kinematics at q: computed once for the controller and the step
      in.robot = rm.robot.kinematics_id();
      if (c.controller->senses()) {  // the sensor at t_k: the contact and weld wrenches of the last world step
        rm.robot.kinematics(s.state.q.data(), s.ws, false);  // the frames, for the sensor
        sense_robot(m, d, static_cast<int>(i), true, true);
        in.wrench = s.sensor.world.data();
      }
      VecN u(n);
      c.controller->compute(in, u.data());
      if (!u.allFinite()) torque_diverged(m, d, static_cast<int>(i), u);
      // actuator limits bind whatever the controller did
      saturate(n, rm.tau_max.data(), u.data());
      c.tau = u;
      s.state.k1_valid = false;
    }
    TrackingMetrics& mt = s.record.metrics;
    for (int j = 0; j < n; ++j) {
      const double e = c.q_ref[j] - s.state.q[j];
      mt.sum_sq_error[j] += e * e;
      mt.max_abs_error[j] = std::max(mt.max_abs_error[j], std::abs(e));
      mt.max_abs_tau[j] = std::max(mt.max_abs_tau[j], std::abs(c.tau[j]));
    }
    ++mt.steps;
    c.updated_at = d.k;
  }
  return fresh;
}

// The external torque of each robot at t_k: the applied wrenches' J^T changes with q, contacts
// may have come or gone.
void hold_external(const Model& m, Data& d) {
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    if (s.external.applied || s.contact.any || s.external.held) {
      external(m.robots[i], s);
      s.state.k1_valid = false;
      s.external.held = s.external.applied || s.contact.any;
    }
  }
}

// The integrate stage: every robot from t_k to t_k+1 under its held torques (RK4 or Euler),
// then the divergence check of its new state.
void integrate(const Model& m, Data& d) {
  Stopwatch watch(d.profiling, d.profile.robots);
  const SimulationOptions& opt = m.options;
  for (RobotData& s : d.robots) {
    s.state.q_prev = s.state.q;
    s.state.qd_prev = s.state.qd;
  }
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    try {
      // the first stage was computed for the log row at this state and torque
      step(m.robots[i].robot, s.ws, opt.integrator, s.state.q, s.state.qd, s.control.tau.data(),
           has_ext(s) ? s.external.tau.data() : nullptr, opt.dt, opt.end_stops,
           s.state.k1_valid ? &s.state.k1 : nullptr);
    } catch (const StageError& e) {
      diverge(m, d, static_cast<int>(i),
              stage_failure_reason(e, opt.integrator, DivergenceLimits{opt.max_speed, opt.max_position}), true, false);
    } catch (const std::exception& e) {
      diverge(m, d, static_cast<int>(i),
              std::string("the dynamics failed in a ") + method_name(opt.integrator) + " stage (" + e.what() + ")",
              true, false);
    }
    s.state.k1_valid = false;
    // the common case without a call: every joint finite and within the limits
    bool fine = true;
    for (int j = 0; j < s.state.q.size(); ++j)
      fine = fine && std::abs(s.state.qd[j]) <= opt.max_speed && std::abs(s.state.q[j]) <= opt.max_position;
    if (!fine) state_diverged(m, d, static_cast<int>(i));
  }
  ++d.k;
  if (d.profiling) ++d.profile.steps;
}

}  // namespace stages

// ---- the simulation: one model, one data ----

Simulation::Simulation(SimulationOptions options, std::shared_ptr<World> world)
    : driver_(make_driver_()), model_(std::make_shared<SimulationModel>()) {
  check_options(options);
  model_->options = options;
  if (world) {
    world->attach();
    data_.world = std::move(world);
  }
}

Simulation::Simulation(std::shared_ptr<const SimulationModel> model) : driver_(make_driver_()) {
  if (!model) throw std::invalid_argument("model must not be None");
  // shared as it is: this run changes a copy (edit_)
  model_ = std::const_pointer_cast<SimulationModel>(std::move(model));
  std::shared_ptr<World> world;
  if (model_->world) {
    world = std::make_shared<World>(model_->world->options);
    for (const BodySpec& b : model_->world->bodies) world->add_body(b);
    world->attach();
  }
  stages::init(*model_, data_, std::move(world), false);
}

Simulation::~Simulation() {
  if (data_.world) data_.world->detach();
}

std::shared_ptr<const SimulationModel> Simulation::model() {
  const Entry driving = enter_();  // one driver at a time (the world's description is written)
  if (data_.world) {
    std::optional<WorldDescription> w = WorldDescription{data_.world->options(), data_.world->own_bodies()};
    if (model_.use_count() > 1) {
      // already shared: the description it was shared with stays unless the world changed since
      const std::optional<WorldDescription>& was = model_->world;
      if (!was || was->bodies.size() != w->bodies.size()) edit_().world = std::move(w);
    } else {
      model_->world = std::move(w);
    }
  }
  return model_;
}

SimulationModel& Simulation::edit_() {
  if (model_.use_count() > 1) model_ = std::make_shared<SimulationModel>(*model_);
  return *model_;
}

int Simulation::check_(int i) const {
  if (i < 0 || i >= robot_count())
    throw std::out_of_range("robot index " + std::to_string(i) + " out of range (" + std::to_string(robot_count()) +
                            " robots)");
  return i;
}

int Simulation::add_robot(const Robot& robot, std::shared_ptr<Controller> controller,
                          std::shared_ptr<const Reference> reference, const double* q0, const double* qd0) {
  const Entry driving = enter_();  // one driver at a time
  if (data_.started || data_.k != 0)
    throw std::invalid_argument("robots can only be added before the first step (call reset())");
  if (!controller) throw std::invalid_argument("controller must not be None");
  if (!reference) throw std::invalid_argument("reference must not be None");
  const int n = robot.dof();
  if (reference->dof() != n)
    throw std::invalid_argument("reference has " + std::to_string(reference->dof()) + " joints but robot '" +
                                robot.name() + "' has " + std::to_string(n));
  for (const RobotData& s : data_.robots)
    if (s.control.controller == controller)
      throw std::invalid_argument("controller is already driving another robot: give each robot its own instance");
  controller->check(robot);
  RobotModel rm{robot, controller, std::move(reference), VecN(), VecN(), VecN(), SensorOptions(), -1};
  rm.q0 = VecN::Zero(n);
  rm.qd0 = VecN::Zero(n);
  rm.reference->evaluate(0.0, rm.q0.data(), rm.qd0.data(), nullptr);
  if (q0) rm.q0 = Eigen::Map<const VecN>(q0, n);
  if (qd0) rm.qd0 = Eigen::Map<const VecN>(qd0, n);
  if (!rm.q0.allFinite()) throw std::invalid_argument("q0 must be finite");
  if (!rm.qd0.allFinite()) throw std::invalid_argument("qd0 must be finite");
  const std::shared_ptr<World>& world = data_.world;
  if (world) {  // its boxes at q0 where a world can hold them: refused here rather than at the first step
    Workspace ws;
    const std::vector<Eigen::Isometry3d> poses = box_poses_at(robot, rm.q0, ws);
    for (size_t k = 0; k < poses.size(); ++k) {
      const std::string& box = robot.boxes()[k].name;
      World::check_pose(poses[k], "the start of robot '" + robot.name() + "' (q0, or its reference at t = 0) puts its box '" +
                                      (box.empty() ? std::to_string(k) : box) + "'");
    }
    if ((robot.gravity_acceleration() - world->options().gravity).norm() > 1e-12)
      throw std::invalid_argument("robot '" + robot.name() + "' has another gravity than the world's");
  }
  rm.tau_max = robot.tau_max();
  SimulationModel& m = edit_();
  m.robots.push_back(std::move(rm));
  const int i = m.robot_count() - 1;
  stages::add_robot_data(m, data_, i);
  data_.robots.back().control.controller = std::move(controller);
  return i;
}

void Simulation::reset() {
  const Entry driving = enter_();  // one driver at a time
  stages::reset(*model_, data_);
}

long Simulation::steps_until(double t_end) const {
  if (!std::isfinite(t_end)) throw std::invalid_argument("t_end must be finite");
  const double span = (t_end - time()) / model_->options.dt;
  if (span < -1e-9)
    throw std::invalid_argument("t_end = " + std::to_string(t_end) + " s is before the current time " +
                                std::to_string(time()) + " s");
  if (span > 4e18) throw std::invalid_argument("t_end is too far ahead for dt");
  return std::max(0L, static_cast<long>(std::floor(span + 1e-9)));
}

void Simulation::set_reference(int i, std::shared_ptr<const Reference> reference) {
  const Entry driving = enter_();  // one driver at a time
  const Robot& r = robot(i);
  if (!reference) throw std::invalid_argument("reference must not be None");
  if (reference->dof() != r.dof())
    throw std::invalid_argument("reference has " + std::to_string(reference->dof()) + " joints but robot '" +
                                r.name() + "' has " + std::to_string(r.dof()));
  edit_().robots[i].reference = std::move(reference);
}

void Simulation::set_applied_forces(int i, const VecN& forces) {
  const Entry driving = enter_();  // one driver at a time
  RobotData& s = slot_(i);
  const int n = robot(i).dof();
  if (forces.size() != n)
    throw std::invalid_argument("wrong size for applied joint forces: expected " + std::to_string(n) + ", got " +
                                std::to_string(forces.size()));
  if (!forces.allFinite()) throw std::invalid_argument("applied joint forces must be finite");
  s.external.forces = forces;
  s.external.applied = !s.external.wrenches.empty() || (forces.array() != 0.0).any();
  stages::applied_changed(*model_, data_, i);
}

void Simulation::set_applied_wrenches(int i, std::vector<ExternalWrench> wrenches) {
  const Entry driving = enter_();  // one driver at a time
  RobotData& s = slot_(i);
  const int n = robot(i).dof();
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
  stages::applied_changed(*model_, data_, i);
}

int Simulation::link_body(int i, int box) const {
  const RobotData& s = slot_(i);
  if (s.contact.first_body < 0) return -1;
  if (box < 0 || box >= static_cast<int>(robot(i).boxes().size()))
    throw std::out_of_range("box index " + std::to_string(box) + " out of range");
  return s.contact.first_body + box;
}

BodyState Simulation::body_state(int id) const { return stages::body_state(*model_, data_, id); }

void Simulation::advance(long n) {
  const Entry driving = enter_();  // one driver at a time
  stages::advance(*model_, data_, n);
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

int Simulation::run_until(double t_end, int until, double every_s, long chunk,
                          const std::function<bool(long, long)>& progress) {
  const Entry driving = enter_();  // one driver at a time
  if (!(std::isfinite(every_s) && every_s > 0.0))
    throw std::invalid_argument("every must be a finite time > 0 s, got " + std::to_string(every_s));
  const long every = std::max(1L, static_cast<long>(std::floor(every_s / model_->options.dt + 1e-9)));
  if (chunk < 1) throw std::invalid_argument("chunk must be >= 1, got " + std::to_string(chunk));
  if (until <= 0 || (until & ~(kUntilGrasp | kUntilContact)) != 0)
    throw std::invalid_argument("until must be a combination of kUntilGrasp and kUntilContact, got " +
                                std::to_string(until));
  const long total = steps_until(t_end);
  reserve(total);
  const World* w = data_.world.get();
  const size_t grasps = data_.grasp_events.size(), contacts = w ? w->events().size() : 0;
  long done = 0, reported = 0;
  while (done < total) {
    const long c = std::min(every, total - done);
    advance(c);
    done += c;
    int found = 0;
    if ((until & kUntilGrasp) && data_.grasp_events.size() != grasps) found |= kUntilGrasp;
    if ((until & kUntilContact) && w && w->events().size() != contacts) found |= kUntilContact;
    if (progress && (found || done == total || done - reported >= chunk)) {
      reported = done;
      if (!progress(done, total)) return found;
    }
    if (found) return found;
  }
  return 0;
}

// ---- replacing a robot's controller in a run ----

void Simulation::set_controller(int i, std::shared_ptr<Controller> controller) {
  const Entry driving = enter_();  // one driver at a time
  RobotData& s = slot_(i);
  if (!controller) throw std::invalid_argument("controller must not be None");
  for (size_t k = 0; k < data_.robots.size(); ++k)
    if (static_cast<int>(k) != i && data_.robots[k].control.controller == controller)
      throw std::invalid_argument("controller is already driving robot " + std::to_string(k) +
                                  ": give each robot its own instance");
  const Robot& r = robot(i);
  controller->check(r);
  // a run under way: the new controller starts now (start resets it otherwise)
  if (data_.started) controller->reset(r, model_->options.dt * model_->options.control_every);
  edit_().robots[i].controller = controller;
  s.control.controller = std::move(controller);
}

// ---- replacing a robot in a run ----

void Simulation::set_robot(int i, const Robot& robot) {
  const Entry driving = enter_();  // one driver at a time
  RobotData& s = slot_(i);
  const Robot& old = this->robot(i);
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
  const std::shared_ptr<World>& world = data_.world;
  if (world && (robot.gravity_acceleration() - world->options().gravity).norm() > 1e-12)
    throw std::invalid_argument("robot '" + robot.name() + "' has another gravity than the world's");
  s.control.controller->check(robot);
  // every check before any change: the boxes at q where the world can hold them
  Workspace ws;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<Shape> shapes;
  std::vector<std::pair<int, int>> excluded;
  const bool in_world = world && data_.started && s.contact.first_body >= 0;  // its bodies in the world now
  if (world) {
    poses = box_poses_at(robot, s.state.q, ws);
    for (size_t k = 0; k < poses.size(); ++k)
      World::check_pose(poses[k], "robot '" + robot.name() + "' at the present q puts its box '" +
                                      (nb[k].name.empty() ? std::to_string(k) : nb[k].name) + "'");
    for (const LinkBox& b : nb) shapes.push_back(b);
    if (in_world) excluded = excluded_pairs(robot);
  }
  RobotModel& rm = edit_().robots[i];
  rm.robot = robot;
  rm.tau_max = robot.tau_max();
  s.ws = ws;
  saturate(n, rm.tau_max.data(), s.control.tau.data());
  s.state.k1_valid = false;  // the dynamics changed: the next step's first stage anew
  s.contact.M_valid = false;
  if (data_.started) s.control.controller->reset(rm.robot, model_->options.dt * model_->options.control_every);
  if (in_world) world->replace_robot_boxes(s.contact.first_body, shapes, poses, excluded);
}

}  // namespace coopsim
