#include "coopsim/simulation.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <new>
#include <sstream>
#include <random>
#include <thread>

#include <unistd.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace coopsim {

namespace {

std::string vec_str(const VecN& v) {
  std::ostringstream s;
  s.precision(6);
  s << "[";
  for (int i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v[i];
  s << "]";
  return s.str();
}

// The poses of robot's collision boxes at q (computed in ws), in its boxes' order.
std::vector<Eigen::Isometry3d> box_poses_at(const Robot& robot, const VecN& q, Workspace& ws) {
  robot.kinematics(q.data(), ws);
  std::vector<Eigen::Isometry3d> poses;
  robot.box_poses(ws, poses);
  return poses;
}

}  // namespace

const std::array<LogQuantityInfo, kLogQuantities>& log_schema() {
  static const std::array<LogQuantityInfo, kLogQuantities> schema = {{
      {"q", "joint positions at t (rad or m)"},
      {"qd", "joint velocities at t (rad/s or m/s)"},
      {"qdd", "joint accelerations at t under the held torques (rad/s^2 or m/s^2)"},
      {"tau", "torque applied over [t, t + dt), held and saturated (N m or N)"},
      {"tau_ext", "joint torque of the applied forces and wrenches over [t, t + dt), held (N m or N)"},
      {"q_ref", "reference positions at t (rad or m)"},
      {"qd_ref", "reference velocities at t (rad/s or m/s)"},
  }};
  return schema;
}

VecN TrackingMetrics::rms_error() const {
  if (steps == 0) return VecN::Zero(sum_sq_error.size());
  return (sum_sq_error / static_cast<double>(steps)).cwiseSqrt();
}

Simulation::Simulation(SimulationOptions options, std::shared_ptr<World> world) : opt_(options) {
  check_step_size(opt_.dt);
  if (opt_.world_every < 1)
    throw std::invalid_argument("world_every must be >= 1, got " + std::to_string(opt_.world_every));
  if (!(opt_.contact_frequency_dt > 0 && opt_.contact_frequency_dt <= 1))
    throw std::invalid_argument("contact_frequency_dt must be in (0, 1]");
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
  if (started_ || k_ != 0) throw std::invalid_argument("robots can only be added before the first step (call reset())");
  if (!controller) throw std::invalid_argument("controller must not be None");
  if (!reference) throw std::invalid_argument("reference must not be None");
  const int n = robot.dof();
  if (reference->dof() != n)
    throw std::invalid_argument("reference has " + std::to_string(reference->dof()) + " joints but robot '" +
                                robot.name() + "' has " + std::to_string(n));
  for (const Slot& s : slots_)
    if (s.controller == controller)
      throw std::invalid_argument("controller is already driving another robot: give each robot its own instance");
  controller->check(robot);
  Slot s(robot);
  s.controller = std::move(controller);
  s.reference = std::move(reference);
  s.q0 = VecN::Zero(n);
  s.qd0 = VecN::Zero(n);
  s.reference->evaluate(0.0, s.q0.data(), s.qd0.data(), nullptr);
  if (q0) s.q0 = Eigen::Map<const VecN>(q0, n);
  if (qd0) s.qd0 = Eigen::Map<const VecN>(qd0, n);
  if (!s.q0.allFinite()) throw std::invalid_argument("q0 must be finite");
  if (!s.qd0.allFinite()) throw std::invalid_argument("qd0 must be finite");
  if (world_) {  // its boxes at q0 where a world can hold them: refused here rather than at the first step
    const std::vector<Eigen::Isometry3d> poses = box_poses_at(robot, s.q0, s.ws);
    for (size_t k = 0; k < poses.size(); ++k) {
      const std::string& box = robot.boxes()[k].name;
      World::check_pose(poses[k], "the start of robot '" + robot.name() + "' (q0, or its reference at t = 0) puts its box '" +
                                      (box.empty() ? std::to_string(k) : box) + "'");
    }
  }
  s.q = s.q0;
  s.qd = s.qd0;
  s.tau = VecN::Zero(n);
  s.tau_max = robot.tau_max();
  s.q_ref = s.qd_ref = s.qdd_ref = s.k1 = s.q_prev = s.qd_prev = VecN::Zero(n);
  s.applied_forces = s.tau_ext = s.tau_contact = VecN::Zero(n);
  if (world_ && (robot.gravity_acceleration() - world_->options().gravity).norm() > 1e-12)
    throw std::invalid_argument("robot '" + robot.name() + "' has another gravity than the world's");
  s.metrics.sum_sq_error = s.metrics.max_abs_error = s.metrics.max_abs_tau = VecN::Zero(n);
  for (LogColumn& c : s.log.columns) c = LogColumn(n);
  s.log.grasp = LogColumn(7);
  slots_.push_back(std::move(s));
  return robot_count() - 1;
}

void Simulation::reset() {
  if (world_) world_->reset();
  for (LogColumn& c : body_log_) c.clear();
  contact_log_.clear();
  grasp_events_.clear();
  world_at_ = -1;
  profile_ = StepProfile();
  k_ = 0;
  logged_at_ = -1;
  started_ = false;
  diverged_ = false;
  divergence_.clear();
  log_t_.clear();
  for (Slot& s : slots_) {
    const int n = s.robot.dof();
    s.q = s.q0;
    s.qd = s.qd0;
    s.tau.setZero(n);
    s.applied_forces.setZero(n);
    s.tau_ext.setZero(n);
    s.tau_contact.setZero(n);
    s.applied_wrenches.clear();
    s.contact_wrenches.clear();
    s.has_applied = s.has_contact = false;
    s.held = s.candidate = -1;
    s.candidate_since = -1;
    s.weld.setZero();
    s.fade = 1.0;
    s.releasing = false;
    s.k1_valid = false;
    s.updated_at = -1;
    for (LogColumn& c : s.log.columns) c.clear();
    s.log.grasp.clear();
    s.metrics.steps = 0;
    s.metrics.sum_sq_error.setZero(n);
    s.metrics.max_abs_error.setZero(n);
    s.metrics.max_abs_tau.setZero(n);
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

namespace {

// Log blocks freed lately, kept for the next logs: writing fresh memory costs
// a page fault per page (dear under virtualisation), reusing it does not.
// Bounded; leaked on purpose so that blocks freed at exit find it alive.
class BlockPool {
 public:
  static BlockPool& get() {
    static BlockPool* pool = new BlockPool;
    return *pool;
  }
  // A block of at least n doubles (its size in *size), reused when one of
  // at most 2 n is free.
  std::shared_ptr<double[]> take(size_t n, size_t* size) {
    double* p = nullptr;
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto it = free_.lower_bound(n);
      if (it != free_.end() && it->first <= 2 * n) {
        p = it->second;
        *size = it->first;
        bytes_ -= it->first * sizeof(double);
        free_.erase(it);
      }
    }
    if (!p) {
      p = new double[n];  // uninitialised: pages are touched when rows are written
      *size = n;
    }
    const size_t sz = *size;
    return std::shared_ptr<double[]>(p, [sz](double* q) { BlockPool::get().give(q, sz); });
  }
  void give(double* p, size_t n) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (bytes_ + n * sizeof(double) <= kMaxBytes) {
        free_.emplace(n, p);
        bytes_ += n * sizeof(double);
        return;
      }
    }
    delete[] p;
  }

 private:
  static constexpr size_t kMaxBytes = size_t(64) << 20;
  std::mutex mu_;
  std::multimap<size_t, double*> free_;
  size_t bytes_ = 0;
};

// The machine's memory, bytes (physical pages; 1 TiB where the system does not say).
size_t memory_bytes() {
  static const size_t bytes = [] {
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    return pages > 0 && page > 0 ? static_cast<size_t>(pages) * static_cast<size_t>(page) : size_t(1) << 40;
  }();
  return bytes;
}

}  // namespace

void LogColumn::reserve(long rows) {
  if (rows <= cap_) return;
  // a log larger than the machine's memory is refused as new[] refuses what it cannot give
  // (std::bad_alloc), before asking: the size in bytes could overflow, and an allocator may
  // abort rather than throw (AddressSanitizer's does on requests beyond its limit)
  const long limit = static_cast<long>(memory_bytes() / sizeof(double) / static_cast<size_t>(width_));
  if (rows > limit) throw std::bad_alloc();
  const long want = std::min(std::max(rows, 2 * cap_), limit);
  size_t size = 0;
  std::shared_ptr<double[]> b = BlockPool::get().take(static_cast<size_t>(want) * width_, &size);
  if (rows_) std::copy(block_.get(), block_.get() + rows_ * width_, b.get());
  block_ = std::move(b);
  cap_ = static_cast<long>(size / width_);
}

void Simulation::reserve(long steps) {
  if (opt_.log_every == 0 || steps <= 0) return;
  const long rows = log_t_.rows() + steps / opt_.log_every + 2;
  log_t_.reserve(rows);
  for (Slot& s : slots_) {
    for (LogColumn& c : s.log.columns) c.reserve(rows);
    s.log.grasp.reserve(rows);
  }
  for (LogColumn& c : body_log_) c.reserve(rows);
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
      const std::vector<Eigen::Isometry3d> poses = box_poses_at(r, s.q, s.ws);
      std::vector<std::string> names;
      std::vector<int> links;
      std::vector<Eigen::Vector3d> half;
      for (const LinkBox& b : r.boxes()) {
        names.push_back(b.name.empty() ? "box" + std::to_string(names.size()) : b.name);
        links.push_back(b.link);
        half.push_back(b.half_extents);
      }
      s.first_body = w.body_count();
      w.add_robot(static_cast<int>(i), label, names, links, half, poses, excluded_pairs(r), 1.0);
    }
    free_ids_ = w.free_bodies();
    body_now_.assign(free_ids_.size(), BodyState());
    if (body_log_.size() != free_ids_.size()) body_log_.assign(free_ids_.size(), LogColumn(13));
  }
  const double period = opt_.dt * opt_.control_every;
  for (Slot& s : slots_) {
    s.controller->reset(s.robot, period);
    s.updated_at = -1;
    s.k1_valid = false;
  }
  started_ = true;
}

void Simulation::qdd_(Slot& s, VecN& out) {
  s.robot.forward_dynamics(s.q.data(), s.qd.data(), s.tau.data(), has_ext_(s) ? s.tau_ext.data() : nullptr, s.ws,
                           out, opt_.end_stops);
}

void Simulation::set_reference(int i, std::shared_ptr<const Reference> reference) {
  Slot& s = slot_(i);
  if (!reference) throw std::invalid_argument("reference must not be None");
  if (reference->dof() != s.robot.dof())
    throw std::invalid_argument("reference has " + std::to_string(reference->dof()) + " joints but robot '" +
                                s.robot.name() + "' has " + std::to_string(s.robot.dof()));
  s.reference = std::move(reference);
}

void Simulation::set_applied_forces(int i, const VecN& forces) {
  Slot& s = slot_(i);
  const int n = s.robot.dof();
  if (forces.size() != n)
    throw std::invalid_argument("wrong size for applied joint forces: expected " + std::to_string(n) + ", got " +
                                std::to_string(forces.size()));
  if (!forces.allFinite()) throw std::invalid_argument("applied joint forces must be finite");
  s.applied_forces = forces;
  s.has_applied = !s.applied_wrenches.empty() || (forces.array() != 0.0).any();
  applied_changed_(s);
}

void Simulation::set_applied_wrenches(int i, std::vector<ExternalWrench> wrenches) {
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
  s.applied_wrenches = std::move(wrenches);
  s.has_applied = !s.applied_wrenches.empty() || (s.applied_forces.array() != 0.0).any();
  applied_changed_(s);
}

void Simulation::applied_changed_(Slot& s) {
  // the new inputs hold from now on, over the next step
  external_(s);
  s.k1_valid = false;
  // a row already logged at this time shows the inputs before the change:
  // the next advance logs a second row at this time with the new ones
  if (logged_at_ == k_) logged_at_ = -1;
}

void Simulation::external_(Slot& s) {
  s.tau_ext = s.tau_contact;
  if (!s.has_applied) return;
  s.tau_ext += s.applied_forces;
  if (!s.applied_wrenches.empty()) {
    VecN t;
    s.robot.kinematics(s.q.data(), s.ws);
    s.robot.external_torques(s.applied_wrenches, s.ws, t);
    s.tau_ext += t;
  }
}

void Simulation::update_() {
  using clock = std::chrono::steady_clock;
  const auto t0 = profiling_ ? clock::now() : clock::time_point();
  const double t = time();
  const bool control = k_ % opt_.control_every == 0;
  ControlInput in;
  in.t = t;
  bool fresh = false;
  for (Slot& s : slots_) {
    if (s.updated_at == k_) continue;
    fresh = true;
    const int n = s.robot.dof();
    s.reference->evaluate(t, s.q_ref.data(), s.qd_ref.data(), s.qdd_ref.data());
    if (control) {
      in.n = n;
      in.q = s.q.data();
      in.qd = s.qd.data();
      in.q_ref = s.q_ref.data();
      in.qd_ref = s.qd_ref.data();
      in.qdd_ref = s.qdd_ref.data();
      VecN u(n);
      s.controller->compute(in, u.data());
      if (!u.allFinite()) {
        std::ostringstream msg;
        msg << "controller of robot " << (&s - slots_.data()) << " '" << s.robot.name()
            << "' returned a non-finite torque at step " << k_ << " (t = " << t << " s): tau = " << vec_str(u)
            << ", q = " << vec_str(s.q) << ", qd = " << vec_str(s.qd);
        diverged_ = true;
        divergence_ = msg.str();
        throw DivergenceError(divergence_, k_, t, static_cast<int>(&s - slots_.data()), s.q, s.qd);
      }
      // actuator limits bind whatever the controller did
      saturate(n, s.tau_max.data(), u.data());
      s.tau = u;
      s.k1_valid = false;
    }
    TrackingMetrics& m = s.metrics;
    for (int i = 0; i < n; ++i) {
      const double e = s.q_ref[i] - s.q[i];
      m.sum_sq_error[i] += e * e;
      m.max_abs_error[i] = std::max(m.max_abs_error[i], std::abs(e));
      m.max_abs_tau[i] = std::max(m.max_abs_tau[i], std::abs(s.tau[i]));
    }
    ++m.steps;
    s.updated_at = k_;
  }
  if (profiling_) profile_.controllers += std::chrono::duration<double>(clock::now() - t0).count();
  if (world_ && world_at_ != k_ && k_ % opt_.world_every == 0) world_step_();
  if (fresh) {
    for (Slot& s : slots_) {
      // the applied wrenches' J^T changes with q; contacts may have come or gone
      if (s.has_applied || s.has_contact || s.ext_held) {
        external_(s);
        s.k1_valid = false;
        s.ext_held = s.has_applied || s.has_contact;
      }
    }
  }
  if (opt_.log_every == 0 || k_ % opt_.log_every != 0 || logged_at_ == k_) return;
  for (size_t i = 0; i < slots_.size(); ++i) {
    Slot& s = slots_[i];
    try {
      qdd_(s, s.k1);
    } catch (const std::exception& e) {
      diverge_(static_cast<int>(i), e.what(), false, true);
    }
    s.k1_valid = true;
  }
  const double now = time();
  log_t_.push(&now);
  for (Slot& s : slots_) {
    auto& c = s.log.columns;
    c[kLogQ].push(s.q.data());
    c[kLogQd].push(s.qd.data());
    c[kLogQdd].push(s.k1.data());
    c[kLogTau].push(s.tau.data());
    c[kLogTauExt].push(s.tau_ext.data());
    c[kLogQRef].push(s.q_ref.data());
    c[kLogQdRef].push(s.qd_ref.data());
    double g[7] = {static_cast<double>(s.held), s.weld[0], s.weld[1], s.weld[2], s.weld[3], s.weld[4], s.weld[5]};
    s.log.grasp.push(g);
  }
  for (size_t b = 0; b < body_log_.size(); ++b) {
    const BodyState& st = body_now_[b];
    const Eigen::Quaterniond quat(st.pose.linear());
    double row[13];
    Eigen::Map<Eigen::Vector3d>(row + 0) = st.pose.translation();
    row[3] = quat.w();
    row[4] = quat.x();
    row[5] = quat.y();
    row[6] = quat.z();
    Eigen::Map<Eigen::Vector3d>(row + 7) = st.velocity;
    Eigen::Map<Eigen::Vector3d>(row + 10) = st.angular_velocity;
    body_log_[b].push(row);
  }
  logged_at_ = k_;
}

Eigen::Vector3d Simulation::point_velocity(const Slot& s, int link, const Eigen::Vector3d& p) {
  return s.frame_v[link] + s.frame_w[link].cross(p - s.ws.o[link]);
}

// J_v^T n (n,) for the world point p fixed on `link` of a slot's robot (kinematics in its ws).
static VecN normal_jacobian(const Robot& r, const Workspace& ws, int link, const Eigen::Vector3d& p,
                            const Eigen::Vector3d& n) {
  Mat6N J;
  r.jacobian(ws, link, ws.R[link].transpose() * (p - ws.o[link]), J);
  return J.topRows<3>().transpose() * n;
}

// u^T M^-1 u for the slot's robot at its q (M factored once per world step).
void Simulation::factor_mass_(Slot& s) {
  if (s.M_valid) return;
  MatN M;
  s.robot.mass_matrix(s.q.data(), s.ws, M);
  s.M_llt.compute(M);
  if (s.M_llt.info() != Eigen::Success)
    throw std::runtime_error("the mass matrix of robot '" + s.robot.name() + "' is not positive definite at q = " +
                             vec_str(s.q));
  s.M_valid = true;
}

double Simulation::inverse_mass_along(Slot& s, const VecN& u) {
  factor_mass_(s);
  // u^T M^-1 u = |L^-1 u|^2
  return s.M_llt.matrixL().solve(u).squaredNorm();
}

void Simulation::contact_wrenches_(double h) {
  for (Slot& s : slots_) s.contact_wrenches.clear();
  if (opt_.contact_forces) link_contacts_(h);
  // a held body pulls on its holder's clamp link: the weld's wrench, opposite, at the body's centre
  for (Slot& s : slots_) {
    if (s.held < 0) continue;
    ExternalWrench wr;
    wr.link = s.robot.clamp().fixed_link;
    wr.point = s.anchor_link;
    wr.wrench = -s.weld;
    s.contact_wrenches.push_back(wr);
  }
  for (Slot& s : slots_) {
    s.has_contact = !s.contact_wrenches.empty();
    if (s.has_contact) s.robot.external_torques(s.contact_wrenches, s.ws, s.tau_contact);
    else s.tau_contact.setZero();
    if (s.held >= 0) {
      // the moving jaw meets the held body as a stop at its width (as the joints' end stops)
      const int j = s.robot.clamp().moving_joint - 1;
      const double pen = s.held_width - s.q[j];
      if (pen > 0) {
        MatN M;
        s.robot.mass_matrix(s.q.data(), s.ws, M);
        const double w = s.robot.end_stop().frequency, z = s.robot.end_stop().damping_ratio;
        s.tau_contact[j] += std::max(0.0, M(j, j) * (w * w * pen - 2.0 * z * w * s.qd[j]));
        s.has_contact = true;
      }
    }
  }
}

void Simulation::link_contacts_(double h) {
  World& w = *world_;
  std::vector<ContactPoint>& contacts = w.contacts();
  // a penalty force where Bullet's solver gives none (link against scenery or
  // another link): pushing only, critically damped, stiffness from the
  // effective mass along the normal so that omega * h stays at contact_frequency_dt
  const double omega = opt_.contact_frequency_dt / h;
  for (ContactPoint& c : contacts) {
    if (c.solver || c.depth <= 0) continue;
    const BodySpec& A = w.body(c.a);
    const BodySpec& B = w.body(c.b);
    if (A.kind != BodyKind::Link && B.kind != BodyKind::Link) continue;
    double inv_mass = 0.0;
    Eigen::Vector3d va = Eigen::Vector3d::Zero(), vb = Eigen::Vector3d::Zero();
    if (A.kind == BodyKind::Link) va = point_velocity(slots_[A.robot], A.link, c.point_a);
    if (B.kind == BodyKind::Link) vb = point_velocity(slots_[B.robot], B.link, c.point_b);
    if (A.kind == BodyKind::Link && B.kind == BodyKind::Link && A.robot == B.robot) {
      Slot& s = slots_[A.robot];
      const VecN u = normal_jacobian(s.robot, s.ws, A.link, c.point_a, c.normal) -
                     normal_jacobian(s.robot, s.ws, B.link, c.point_b, c.normal);
      inv_mass = inverse_mass_along(s, u);
    } else {
      if (A.kind == BodyKind::Link) {
        Slot& s = slots_[A.robot];
        inv_mass += inverse_mass_along(s, normal_jacobian(s.robot, s.ws, A.link, c.point_a, c.normal));
      }
      if (B.kind == BodyKind::Link) {
        Slot& s = slots_[B.robot];
        inv_mass += inverse_mass_along(s, normal_jacobian(s.robot, s.ws, B.link, c.point_b, c.normal));
      }
    }
    if (!(inv_mass > 1e-12)) continue;  // neither side can move along the normal
    const double m = 1.0 / inv_mass;
    const double closing = -(va - vb).dot(c.normal);  // > 0: approaching
    const double f = m * omega * omega * c.depth + 2.0 * m * omega * closing;
    c.force = std::max(f, 0.0) * c.normal;
  }
  // every force on a link, as a wrench at its point
  for (const ContactPoint& c : contacts) {
    if (c.force.squaredNorm() == 0.0) continue;
    for (int side = 0; side < 2; ++side) {
      const BodySpec& body = w.body(side == 0 ? c.a : c.b);
      if (body.kind != BodyKind::Link || body.link == 0) continue;
      Slot& s = slots_[body.robot];
      const Eigen::Vector3d& p = side == 0 ? c.point_a : c.point_b;
      ExternalWrench wr;
      wr.link = body.link;
      wr.point = s.ws.R[body.link].transpose() * (p - s.ws.o[body.link]);
      wr.wrench.head<3>() = side == 0 ? c.force : Eigen::Vector3d(-c.force);
      s.contact_wrenches.push_back(wr);
    }
  }
}

// The grasp rule's first condition: the jaw commanded closing or closed.
static bool jaw_closing(double q_ref, double q, double qd_ref) { return q_ref <= q + 1e-9 || qd_ref < 0; }

GraspCheck Simulation::grasp_check_(const Slot& s, const BodyState& st, int id) const {
  const GraspOptions& g = opt_.grasp;
  const Robot& r = s.robot;
  const Clamp& c = r.clamp();
  const int j = c.moving_joint - 1, l = c.fixed_link;
  const double opening = s.q[j];
  GraspCheck out;
  // the jaw commanded closing or closed
  out.closing = jaw_closing(s.q_ref[j], opening, s.qd_ref[j]);
  const BodySpec& b = world_->body(id);
  const Eigen::Isometry3d link = s.robot.frame(s.ws, l);
  const Eigen::Isometry3d F = link * c.fixed_face;  // x along the jaw, z the jaw axis, origin the pad centre
  const Eigen::Matrix3d A = F.linear().transpose() * st.pose.linear();  // the body's axes in F
  const Eigen::Vector3d p = F.inverse() * st.pose.translation();
  const Eigen::Vector3d& he = b.half_extents;
  // a face of the body normal to the jaw axis
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(A(2, i)) > std::abs(A(2, k))) k = i;
  out.angle = std::acos(std::min(1.0, std::abs(A(2, k))));
  out.aligned = out.angle <= g.angle;
  out.width = 2.0 * he[k];
  // both jaws touch it
  const double ez = (A.row(2).cwiseAbs().transpose().array() * he.array()).sum();
  out.gap_fixed = p.z() - ez;
  out.gap_moving = opening - (p.z() + ez);
  out.touching = out.gap_fixed <= g.gap && out.gap_fixed >= -g.penetration && out.gap_moving <= g.gap &&
                 out.gap_moving >= -g.penetration;
  // between the pads: its centre within them along the jaw (x, towards the tips; a body may stand out
  // beyond the tips, as a bar on the floor gripped above it does), not into the palm, and across their
  // centre line
  const double ex = (A.row(0).cwiseAbs().transpose().array() * he.array()).sum();
  const double ey = (A.row(1).cwiseAbs().transpose().array() * he.array()).sum();
  out.in_pads = std::abs(p.x()) <= c.jaw_length / 2 + 1e-9 && p.x() - ex >= -c.jaw_length / 2 - 1e-9 &&
                std::abs(p.y()) <= ey;
  // moving with the clamp
  out.speed = (st.velocity - point_velocity(s, l, st.pose.translation())).norm();
  out.angular_speed = (st.angular_velocity - s.frame_w[l]).norm();
  out.slow = out.speed <= g.speed && out.angular_speed <= g.angular_speed;
  return out;
}

GraspCheck Simulation::grasp_check(int i, int body) {
  Slot& s = slot_(i);
  if (!world_) throw std::invalid_argument("the simulation has no world");
  if (!s.robot.clamp().present()) throw std::invalid_argument("robot '" + s.robot.name() + "' has no clamp");
  if (world_->body(body).kind != BodyKind::Free) throw std::invalid_argument("only free bodies can be grasped");
  if (s.updated_at != k_) {
    if (!started_) start_();
    update_();
  }
  s.robot.kinematics(s.q.data(), s.ws);
  s.robot.frame_velocities(s.ws, s.qd.data(), s.frame_w.data(), s.frame_v.data());
  return grasp_check_(s, world_->state(body), body);
}

void Simulation::grasp_rule_(double h) {
  World& w = *world_;
  const GraspOptions& g = opt_.grasp;
  bool changed = false;
  for (size_t i = 0; i < slots_.size(); ++i) {
    Slot& s = slots_[i];
    const Clamp& c = s.robot.clamp();
    if (!c.present()) continue;
    const int l = c.fixed_link;
    if (s.held >= 0) {
      const Eigen::Isometry3d link = s.robot.frame(s.ws, l);
      const Eigen::Vector3d target = link * s.anchor_link;
      BodyState st = w.state(s.held);
      if (s.releasing) {
        // letting go by opening: the weld fades out, then the body is free (it moves on its own already)
        s.release_progress = std::min(1.0, s.release_progress + (g.release_time > 0 ? h / g.release_time : 1.0));
        const double p = s.release_progress;
        s.fade = 1.0 - p * p * (3.0 - 2.0 * p);  // smooth at both ends: the load moves over without a jump
        if (p >= 1.0 - 1e-12) {
          release_(s, "opened", false);
          changed = true;
        }
      } else if (s.qd_ref[c.moving_joint - 1] >= 0.0 && s.q_ref[c.moving_joint - 1] > s.held_width + g.open_margin) {
        // opening: the jaw's reference above the body's width and not closing (a grasp made while the
        // reference still closes towards the body is kept)
        s.releasing = true;
        s.fade = 1.0;
        s.release_progress = 0.0;
      } else if ((target - st.pose * s.anchor_body).norm() > g.slip) {
        release_(s, "slipped");
        changed = true;
      }
      continue;
    }
    int found = -1;
    double width = 0.0;
    const int j = c.moving_joint - 1;
    if (!jaw_closing(s.q_ref[j], s.q[j], s.qd_ref[j])) {  // nothing to check while the jaw opens
      s.candidate = -1;
      continue;
    }
    for (size_t b = 0; b < free_ids_.size(); ++b) {
      const GraspCheck c = grasp_check_(s, body_now_[b], free_ids_[b]);
      if (c.ok()) {
        found = free_ids_[b];
        width = c.width;
        break;
      }
    }
    if (found < 0) {
      s.candidate = -1;
      continue;
    }
    if (s.candidate != found) {
      s.candidate = found;
      s.candidate_since = k_;
    }
    if ((k_ - s.candidate_since) * opt_.dt < g.hold_time - 1e-12) continue;
    // attach where the body is now: no snapping
    const Eigen::Isometry3d link = s.robot.frame(s.ws, l);
    s.held = found;
    s.held_width = width;
    const Eigen::Isometry3d body = w.state(found).pose;
    s.weld_X = link.inverse() * body;
    // anchored midway between the pads' centres, where the clamp holds it
    const Eigen::Isometry3d face = link * c.fixed_face;
    const Eigen::Vector3d anchor = face * Eigen::Vector3d(0, 0, 0.5 * s.q[c.moving_joint - 1]);
    s.anchor_link = link.inverse() * anchor;
    s.anchor_body = body.inverse() * anchor;
    s.candidate = -1;
    grasp_events_.push_back(GraspEvent{time(), static_cast<int>(i), found, true, "grasp"});
    changed = true;
  }
  if (changed) ignore_held_();
  (void)h;
}

void Simulation::ignore_held_() {
  // a held body does not collide with its holder's clamp
  std::vector<std::pair<int, int>> pairs;
  for (const Slot& s : slots_) {
    if (s.held < 0) continue;
    const std::vector<LinkBox>& boxes = s.robot.boxes();
    for (size_t b = 0; b < boxes.size(); ++b)
      if (boxes[b].link >= s.robot.clamp().fixed_link) pairs.emplace_back(s.held, s.first_body + static_cast<int>(b));
  }
  world_->set_ignored(std::move(pairs));
}

void Simulation::release_(Slot& s, const std::string& why, bool set_twist) {
  if (s.held < 0) return;
  const int l = s.robot.clamp().fixed_link;
  s.robot.kinematics(s.q.data(), s.ws);
  s.robot.frame_velocities(s.ws, s.qd.data(), s.frame_w.data(), s.frame_v.data());
  const BodyState st = world_->state(s.held);
  // the body leaves with the clamp's rigid twist at its centre of mass
  if (set_twist) world_->set_velocity(s.held, point_velocity(s, l, st.pose.translation()), s.frame_w[l]);
  s.releasing = false;
  s.fade = 1.0;
  grasp_events_.push_back(GraspEvent{time(), static_cast<int>(&s - slots_.data()), s.held, false, why});
  s.held = -1;
  s.weld.setZero();
}

void Simulation::release(int i) {
  Slot& s = slot_(i);
  if (s.held < 0) return;
  release_(s, "released");
  ignore_held_();
  // its body's state now is the released one; the robots feel the weld no more from the next step
  for (size_t k = 0; k < free_ids_.size(); ++k) body_now_[k] = world_->state(free_ids_[k]);
  for (Slot& o : slots_) {
    o.robot.kinematics(o.q.data(), o.ws);
    o.robot.frame_velocities(o.ws, o.qd.data(), o.frame_w.data(), o.frame_v.data());
    o.M_valid = false;
  }
  contact_wrenches_(opt_.dt * opt_.world_every);
  for (Slot& o : slots_) {
    external_(o);
    o.k1_valid = false;
    o.ext_held = o.has_applied || o.has_contact;
  }
  if (logged_at_ == k_) logged_at_ = -1;
}

void Simulation::welds_(double h) {
  World& w = *world_;
  const double omega = opt_.grasp.weld_omega_dt / h;
  for (Slot& s : slots_) {
    if (s.held < 0) continue;
    const int l = s.robot.clamp().fixed_link;
    // the damping is shared among the welds on the body, a fading one counting as much as it holds
    double holders = 0.0;
    for (const Slot& o : slots_)
      if (o.held == s.held) holders += o.fade;
    const BodySpec& b = w.body(s.held);
    const BodyState st = w.state(s.held);
    const Eigen::Isometry3d link = s.robot.frame(s.ws, l);
    const Eigen::Isometry3d target = link * s.weld_X;
    const Eigen::Vector3d p_target = link * s.anchor_link, p_body = st.pose * s.anchor_body;
    const Eigen::Vector3d r = p_body - st.pose.translation();  // from the body's centre to the weld's point
    // the reduced mass and inertia matrices between body and robot at the weld's point (operational
    // space): every mode of the weld then rings at omega, critically damped
    Mat6N J;
    s.robot.jacobian(s.ws, l, s.anchor_link, J);
    factor_mass_(s);  // once this world step
    // J M^-1 J^T = Y^T Y with Y = L^-1 J^T (one triangular solve for the six columns)
    Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kMaxDof, 6> Y = J.transpose();
    s.M_llt.matrixL().solveInPlace(Y);
    const Eigen::Matrix<double, 6, 6> A_robot = Y.transpose() * Y;
    const Eigen::Matrix3d I_inv = w.inertia(s.held).inverse();
    Eigen::Matrix3d rx;
    rx << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
    const Eigen::Matrix3d A_lin = Eigen::Matrix3d::Identity() / b.mass - rx * I_inv * rx + A_robot.topLeftCorner<3, 3>();
    const Eigen::Matrix3d A_rot = I_inv + A_robot.bottomRightCorner<3, 3>();
    const Eigen::Matrix3d m = A_lin.inverse(), i = A_rot.inverse();
    const Eigen::Vector3d e_p = p_target - p_body;
    const Eigen::AngleAxisd e_r(target.linear() * st.pose.linear().transpose());
    const Eigen::Vector3d e_v = point_velocity(s, l, p_target) - (st.velocity + st.angular_velocity.cross(r));
    const Eigen::Vector3d e_w = s.frame_w[l] - st.angular_velocity;
    s.weld.head<3>() = s.fade * (m * (omega * omega * e_p + 2.0 * omega / holders * e_v));
    s.weld.tail<3>() = s.fade * (i * (omega * omega * e_r.angle() * e_r.axis() + 2.0 * omega / holders * e_w));
    if (!opt_.grasp.weld_moment) s.weld.tail<3>().setZero();
    // the force acts at the weld's point: about the body's centre it also turns it
    w.apply_wrench(s.held, s.weld.head<3>(), s.weld.tail<3>() + r.cross(Eigen::Vector3d(s.weld.head<3>())));
  }
}

std::vector<std::pair<int, int>> Simulation::excluded_pairs(const Robot& r, int samples) {
  const std::vector<LinkBox>& boxes = r.boxes();
  const int k = static_cast<int>(boxes.size()), n = r.dof();
  std::vector<std::pair<int, int>> out, candidates;
  for (int i = 0; i < k; ++i)
    for (int j = i + 1; j < k; ++j) {
      if (std::abs(boxes[i].link - boxes[j].link) <= 1) out.emplace_back(i, j);
      else candidates.emplace_back(i, j);
    }
  // the others that touch at every sampled pose (MoveIt's way), from a fixed seed
  std::mt19937 rng(12345);
  std::vector<char> always(candidates.size(), 1);
  Workspace ws;
  std::vector<Eigen::Isometry3d> poses;
  VecN q(n);
  for (int s = 0; s < samples; ++s) {
    for (int j = 0; j < n; ++j) {
      const Link& L = r.links()[j];
      const double span = L.type == JointType::Revolute ? M_PI : 0.5;
      const double lo = std::isfinite(L.q_min) ? L.q_min : -span, hi = std::isfinite(L.q_max) ? L.q_max : span;
      q[j] = std::uniform_real_distribution<double>(lo, hi)(rng);
    }
    r.kinematics(q.data(), ws);
    r.box_poses(ws, poses);
    for (size_t c = 0; c < candidates.size(); ++c) {
      const auto [i, j] = candidates[c];
      if (always[c] && box_penetration(poses[i], boxes[i].half_extents, poses[j], boxes[j].half_extents) <= -1e-9)
        always[c] = 0;
    }
  }
  for (size_t c = 0; c < candidates.size(); ++c)
    if (always[c]) out.push_back(candidates[c]);
  return out;
}

int Simulation::link_body(int i, int box) const {
  const Slot& s = slot_(i);
  if (s.first_body < 0) return -1;
  if (box < 0 || box >= static_cast<int>(s.robot.boxes().size()))
    throw std::out_of_range("box index " + std::to_string(box) + " out of range");
  return s.first_body + box;
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

void Simulation::world_step_() {
  using clock = std::chrono::steady_clock;
  const auto t0 = profiling_ ? clock::now() : clock::time_point();
  World& w = *world_;
  const double h = opt_.dt * opt_.world_every;
  // link bodies where the robots are now, with their exact twists
  std::vector<Eigen::Isometry3d>& poses = box_poses_;
  for (Slot& s : slots_) {
    const Robot& r = s.robot;
    r.kinematics(s.q.data(), s.ws, false);  // the frames (what follows reads no centre of mass or inertia)
    r.frame_velocities(s.ws, s.qd.data(), s.frame_w.data(), s.frame_v.data());
    r.box_poses(s.ws, poses);
    for (size_t b = 0; b < poses.size(); ++b) {
      const int l = r.boxes()[b].link;
      w.set_link(s.first_body + static_cast<int>(b), poses[b], point_velocity(s, l, poses[b].translation()),
                 s.frame_w[l]);
    }
    s.M_valid = false;
  }
  // free bodies as they are at t_k, for the log and body_state()
  for (size_t b = 0; b < free_ids_.size(); ++b) body_now_[b] = w.state(free_ids_[b]);
  const auto tg = profiling_ ? clock::now() : clock::time_point();
  if (opt_.grasp.enabled) {
    grasp_rule_(h);
    welds_(h);
  }
  if (profiling_) profile_.grasp += std::chrono::duration<double>(clock::now() - tg).count();
  try {
    w.step(h, time());
  } catch (const WorldDivergence& e) {
    diverged_ = true;
    std::ostringstream msg;
    msg << "simulation diverged at step " << k_ + 1 << ": " << e.what() << "; the log ends at t = "
        << (log_t_.rows() ? log_t_.back() : 0.0) << " s";
    divergence_ = msg.str();
    throw DivergenceError(divergence_, k_ + 1, time() + h, -1, VecN(), VecN());
  }
  const auto t1 = profiling_ ? clock::now() : clock::time_point();
  contact_wrenches_(h);
  w.record_events(time());
  if (opt_.log_contacts)
    for (const ContactPoint& c : w.contacts()) contact_log_.push_back(LoggedContact{time(), c});
  world_at_ = k_;
  if (profiling_) {
    const auto t2 = clock::now();
    profile_.world += std::chrono::duration<double>(t1 - t0).count();  // the grasp included
    profile_.contacts += std::chrono::duration<double>(t2 - t1).count();
    ++profile_.world_steps;
  }
}

void Simulation::diverge_(int i, const std::string& why, bool in_step, bool state_is_result) {
  Slot& bad = slots_[i];
  const VecN q_bad = bad.q, qd_bad = bad.qd;
  const long step = in_step ? k_ + 1 : k_;
  // a rejected step goes back to the last good state
  for (Slot& s : slots_) {
    if (in_step) {
      s.q = s.q_prev;
      s.qd = s.qd_prev;
    }
    s.k1_valid = false;
  }
  diverged_ = true;
  std::ostringstream msg;
  msg << "simulation diverged at step " << step << " (t = " << step * opt_.dt << " s, dt = " << opt_.dt
      << " s): robot " << i << " '" << bad.robot.name() << "': " << why << "; "
      << (state_is_result ? "state reached" : "state at the start of the step") << ": q = " << vec_str(q_bad)
      << ", qd = " << vec_str(qd_bad) << ", torque held = " << vec_str(bad.tau) << "; the log ends at t = "
      << (log_t_.rows() ? log_t_.back() : 0.0) << " s";
  if (opt_.end_stops) {
    const std::string hint = end_stop_step_warning(bad.robot, opt_.dt);
    if (!hint.empty()) msg << "; " << hint;
  }
  divergence_ = msg.str();
  throw DivergenceError(divergence_, step, step * opt_.dt, i, q_bad, qd_bad);
}

void Simulation::step_() {
  using clock = std::chrono::steady_clock;
  const auto t0 = profiling_ ? clock::now() : clock::time_point();
  for (Slot& s : slots_) {
    s.q_prev = s.q;
    s.qd_prev = s.qd;
  }
  for (size_t i = 0; i < slots_.size(); ++i) {
    Slot& s = slots_[i];
    try {
      // the first stage was computed for the log row at this state and torque
      step(s.robot, s.ws, opt_.integrator, s.q, s.qd, s.tau.data(), has_ext_(s) ? s.tau_ext.data() : nullptr,
           opt_.dt, opt_.end_stops, s.k1_valid ? &s.k1 : nullptr);
    } catch (const std::exception& e) {
      diverge_(static_cast<int>(i),
               std::string("the dynamics failed in a ") + method_name(opt_.integrator) + " stage (" + e.what() + ")",
               true, false);
    }
    s.k1_valid = false;
    // the common case without building a string: every joint finite and within the limits
    bool fine = true;
    for (int j = 0; j < s.q.size(); ++j)
      fine = fine && std::abs(s.qd[j]) <= opt_.max_speed && std::abs(s.q[j]) <= opt_.max_position;
    if (!fine) {
      const std::string why = divergence_reason(s.q, s.qd, DivergenceLimits{opt_.max_speed, opt_.max_position});
      if (!why.empty()) diverge_(static_cast<int>(i), why, true, true);
    }
  }
  ++k_;
  if (profiling_) {
    profile_.robots += std::chrono::duration<double>(clock::now() - t0).count();
    ++profile_.steps;
  }
}

void Simulation::advance(long n) {
  if (n < 0) throw std::invalid_argument("n must be >= 0, got " + std::to_string(n));
  if (slots_.empty() && !world_)
    throw std::invalid_argument("the simulation has no robot: add one with add_robot()");
  if (diverged_) throw std::runtime_error("the simulation has diverged (" + divergence_ + "); call reset()");
  if (!started_) start_();
  reserve(n);
  update_();
  for (long i = 0; i < n; ++i) {
    step_();
    update_();
  }
}

long Simulation::run(double t_end, long chunk, const std::function<bool(long, long)>& progress) {
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

std::vector<std::exception_ptr> run_batch(const std::vector<Simulation*>& sims, double t_end, int threads,
                                          std::vector<double>* seconds) {
  const int N = static_cast<int>(sims.size());
  for (int i = 0; i < N; ++i) {
    if (!sims[i]) throw std::invalid_argument("sims must not contain None");
    for (int j = 0; j < i; ++j) {
      if (sims[i] == sims[j])
        throw std::invalid_argument("sims[" + std::to_string(i) + "] is the same simulation as sims[" +
                                    std::to_string(j) + "]");
      for (int a = 0; a < sims[i]->robot_count(); ++a)
        for (int b = 0; b < sims[j]->robot_count(); ++b)
          if (sims[i]->controller(a) == sims[j]->controller(b))
            throw std::invalid_argument("sims[" + std::to_string(i) + "] and sims[" + std::to_string(j) +
                                        "] share a controller instance: give each its own");
    }
  }
  if (!std::isfinite(t_end)) throw std::invalid_argument("t_end must be finite");
  std::vector<std::exception_ptr> errors(N);
  if (seconds) seconds->assign(N, 0.0);
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::max(1, std::min(threads, N));
  std::atomic<int> next{0};
  auto work = [&]() {
    for (int i = next++; i < N; i = next++) {
      const auto start = std::chrono::steady_clock::now();
      try {
        sims[i]->advance(sims[i]->steps_until(t_end));
      } catch (...) {
        errors[i] = std::current_exception();
      }
      if (seconds) (*seconds)[i] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
  };
  if (threads == 1) {
    work();
  } else {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(work);
    for (auto& th : pool) th.join();
  }
  return errors;
}

}  // namespace coopsim
