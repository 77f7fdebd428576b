// Task-space control (task.hpp): the task axes, the state a law sees, the common part of the laws
// (task acceleration and wrench to joint torques), impedance and hybrid position/force control.
#include "coopsim/task.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "internal.hpp"

namespace coopsim {

namespace {

const char* const kAxisNames[kTaskAxes] = {"x", "y", "z", "roll", "pitch", "yaw"};

std::string names_of(const std::array<bool, kTaskAxes>& mask) {
  std::string out;
  for (int a = 0; a < kTaskAxes; ++a)
    if (mask[a]) out += (out.empty() ? "" : ", ") + std::string(kAxisNames[a]);
  return out.empty() ? "none" : out;
}

std::vector<int> axes_of(const std::vector<std::string>& names, const char* what) {
  std::vector<int> out;
  for (const std::string& n : names) {
    const int a = task_axis(n, what);
    for (int b : out)
      if (b == a) throw std::invalid_argument(std::string(what) + " names '" + n + "' twice");
    out.push_back(a);
  }
  return out;
}

void check_values(const Eigen::VectorXd& v, const char* name, bool positive, bool signed_ok = false) {
  if (v.size() == 0) throw std::invalid_argument(std::string(name) + " must have at least one value");
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) throw std::invalid_argument(std::string(name) + " must be finite (got NaN or inf)");
    if (signed_ok) continue;
    if (positive ? !(v[i] > 0) : v[i] < 0)
      throw std::invalid_argument(std::string(name) + " must be " + (positive ? "> 0" : ">= 0") + ", got " +
                                  detail::num(v[i]) + " at entry " + std::to_string(i + 1));
  }
}

// v (1 value, or one per axis of `axes`) spread over the six axes
Vec6 spread(const Eigen::VectorXd& v, const std::vector<int>& axes, const char* name) {
  if (v.size() != 1 && v.size() != static_cast<Eigen::Index>(axes.size())) {
    std::string list;
    for (int a : axes) list += (list.empty() ? "" : ", ") + std::string(kAxisNames[a]);
    throw std::invalid_argument("wrong size for " + std::string(name) + ": expected 1 or " +
                                std::to_string(axes.size()) + " values (" + list + "), got " +
                                std::to_string(v.size()));
  }
  Vec6 out = Vec6::Zero();
  for (std::size_t k = 0; k < axes.size(); ++k) out[axes[k]] = v.size() == 1 ? v[0] : v[k];
  return out;
}

int jaw_of(const Robot& r) { return r.clamp().present() ? r.clamp().moving_joint - 1 : -1; }

using Mat66 = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kTaskAxes, kTaskAxes>;
using Vec6d = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kTaskAxes, 1>;

// x = A^-1 b by LU with partial pivoting, fixed-size (unrolled) for the sizes the arms have; false
// when A is singular: its smallest pivot below 1e-9 of its largest (a cheap bound, no condition estimate)
template <int N>
bool solve_fixed(const Mat66& A, const Vec6d& b, Vec6d& x) {
  const Eigen::PartialPivLU<Eigen::Matrix<double, N, N>> lu(A.template topLeftCorner<N, N>());
  const auto d = lu.matrixLU().diagonal().cwiseAbs();
  if (!(d.minCoeff() > 1e-9 * d.maxCoeff())) return false;
  x = lu.solve(b.template head<N>());
  return true;
}

bool solve_square(const Mat66& A, const Vec6d& b, Vec6d& x) {
  switch (A.rows()) {
    case 1: return solve_fixed<1>(A, b, x);
    case 2: return solve_fixed<2>(A, b, x);
    case 3: return solve_fixed<3>(A, b, x);
    case 4: return solve_fixed<4>(A, b, x);
    case 5: return solve_fixed<5>(A, b, x);
    default: return solve_fixed<6>(A, b, x);
  }
}

}  // namespace

const char* task_axis_name(int axis) {
  if (axis < 0 || axis >= kTaskAxes) throw std::out_of_range("task axis out of range");
  return kAxisNames[axis];
}

int task_axis(const std::string& name, const char* what) {
  for (int a = 0; a < kTaskAxes; ++a)
    if (name == kAxisNames[a]) return a;
  throw std::invalid_argument(std::string(what) + ": unknown direction '" + name +
                              "' (expected x, y, z, roll, pitch or yaw)");
}

Eigen::Matrix3d task_axes(const Eigen::Isometry3d& tool) {
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d y = tool.linear().col(1);
  Eigen::Vector3d p = y - y.dot(z) * z;
  const double norm = p.norm();
  if (!(norm > 1e-6)) {
    std::ostringstream m;
    m << "task axes undefined: the tool's y axis is vertical (y_tool = " << y.transpose() << ")";
    throw std::domain_error(m.str());
  }
  p /= norm;
  Eigen::Matrix3d B;
  B.col(0) = p.cross(z);
  B.col(1) = p;
  B.col(2) = z;
  return B;
}

std::array<bool, kTaskAxes> commandable_directions(const Robot& robot, const double* q0, int samples) {
  std::array<bool, kTaskAxes> out{};
  const int n = robot.dof(), jaw = jaw_of(robot);
  const VecN lo = robot.q_min(), hi = robot.q_max();
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Workspace ws;
  Mat6N J;
  VecN q(n);
  for (int k = -1; k < samples; ++k) {
    if (k < 0 && !q0) continue;
    for (int i = 0; i < n; ++i) {
      if (k < 0) {
        q[i] = q0[i];
        continue;
      }
      const double a = std::isfinite(lo[i]) ? lo[i] : -3.0, b = std::isfinite(hi[i]) ? hi[i] : 3.0;
      q[i] = a + (b - a) * u(rng);
    }
    robot.kinematics(q.data(), ws, false);
    const Eigen::Isometry3d T = robot.tool_pose(ws);
    Eigen::Matrix3d B;
    try {
      B = task_axes(T);
    } catch (const std::domain_error&) {
      continue;
    }
    robot.tool_jacobian(ws, J);
    for (int j = 0; j < n; ++j) {
      if (j == jaw) continue;
      const Eigen::Vector3d w = B.transpose() * J.col(j).tail<3>();
      for (int a = 0; a < 3; ++a) {
        if (std::abs(J(a, j)) > 1e-9) out[a] = true;
        if (std::abs(w[a]) > 1e-9) out[3 + a] = true;
      }
    }
  }
  return out;
}

// ---- the common part ----

TaskController::TaskController(std::vector<std::string> directions, double jaw_kp, double jaw_kd, double null_kp,
                               double null_kd, Payload payload, std::shared_ptr<const Robot> model)
    : names_(std::move(directions)), jaw_kp_(jaw_kp), jaw_kd_(jaw_kd), null_kp_(null_kp), null_kd_(null_kd),
      payload_(std::move(payload)), model_(std::move(model)) {
  axes_of(names_, "directions");
  detail::require_nonnegative(jaw_kp_, "jaw_kp");
  detail::require_nonnegative(jaw_kd_, "jaw_kd");
  detail::require_nonnegative(null_kp_, "null_kp");
  detail::require_nonnegative(null_kd_, "null_kd");
  check_payload(payload_);
}

void TaskController::check_payload(const Payload& p) {
  detail::require_nonnegative(p.mass, "payload mass");
  if (!p.com.allFinite()) throw std::invalid_argument("payload com must be finite");
  check_inertia(p.inertia, "payload inertia");
}

void TaskController::check(const Robot& robot) const {
  if (model_ && model_->dof() != robot.dof())
    throw std::invalid_argument("model has " + std::to_string(model_->dof()) + " joints but robot '" + robot.name() +
                                "' has " + std::to_string(robot.dof()));
  const std::array<bool, kTaskAxes> can = commandable_directions(robot);
  int count = 0;
  for (int a : axes_of(names_, "directions")) {
    if (!can[a])
      throw std::invalid_argument("directions: robot '" + robot.name() + "' cannot command '" + kAxisNames[a] +
                                  "' (it commands " + names_of(can) + ")");
    ++count;
  }
  if (names_.empty())
    for (bool c : can) count += c;
  const int arm = robot.dof() - (jaw_of(robot) >= 0 ? 1 : 0);
  if (count > arm)
    throw std::invalid_argument("directions: " + std::to_string(count) + " task directions but robot '" +
                                robot.name() + "' has " + std::to_string(arm) + " arm joints");
  if (count == 0) throw std::invalid_argument("robot '" + robot.name() + "' commands no task direction");
}

void TaskController::reset(const Robot& robot, double period) {
  check(robot);
  if (!(period > 0) || !std::isfinite(period)) throw std::invalid_argument("period must be finite and > 0 s");
  robot_ = std::make_shared<const Robot>(robot);
  run_model_ = model_ ? model_ : robot_;
  n_ = robot.dof();
  commandable_ = commandable_directions(robot);
  order_ = axes_of(names_, "directions");
  if (order_.empty())
    for (int a = 0; a < kTaskAxes; ++a)
      if (commandable_[a]) order_.push_back(a);
  commanded_ = {};
  for (int a : order_) commanded_[a] = true;
  prev_accel_.setZero();
  ref_valid_ = false;
  s_ = TaskState();
  s_.n = n_;
  s_.jaw = jaw_of(robot);
  s_.commanded = commanded_;
  out_ = VecN::Zero(n_);
  qdd_ = VecN::Zero(n_);
  jaw_inertia_ = 0.0;
  if (s_.jaw >= 0) {  // the jaw's own inertia: as the last joint (prismatic) M_jj is the same at every q
    MatN M;
    const VecN q0 = VecN::Zero(n_);
    run_model_->mass_matrix(q0.data(), ws_, M);
    jaw_inertia_ = M(s_.jaw, s_.jaw);
  }
}

Vec6 TaskController::per_axis(const Eigen::VectorXd& v, const char* name) const { return spread(v, order_, name); }

void TaskController::compute(const ControlInput& in, double* tau) { compute_task(observe(in), tau); }

const TaskState& TaskController::observe(const ControlInput& in, const TaskReference* ref) {
  if (n_ == 0 || in.n != n_) throw std::logic_error("TaskController.compute called before reset() for this robot");
  const int n = n_;
  TaskState& s = s_;
  s.t = in.t;
  s.q = Eigen::Map<const VecN>(in.q, n);
  s.qd = Eigen::Map<const VecN>(in.qd, n);
  s.q_ref = Eigen::Map<const VecN>(in.q_ref, n);
  s.qd_ref = Eigen::Map<const VecN>(in.qd_ref, n);
  s.qdd_ref = Eigen::Map<const VecN>(in.qdd_ref, n);
  // measured: pose, axes, Jacobian, bias
  const Robot& r = *robot_;
  Mat6N Jg, Jr;
  Vec6 bg, br;
  Vec6 twist_ref, accel_ref;
  if (ref) {
    s.pose_ref = ref->pose;
    twist_ref = ref->twist;
    accel_ref = ref->accel;
  } else {
    if (!(ref_valid_ && s.q_ref == ref_q_ && s.qd_ref == ref_qd_ && s.qdd_ref == ref_qdd_)) {
      r.kinematics(in.q_ref, wsr_, false);
      ref_pose_ = r.tool_pose(wsr_);
      r.tool_jacobian(wsr_, Jr);
      r.tool_bias(wsr_, in.qd_ref, br);
      ref_twist_ = Jr * s.qd_ref;
      ref_accel_ = Jr * s.qdd_ref + br;
      ref_jaw_ = s.jaw >= 0 ? Eigen::Vector3d(Jr.col(s.jaw).head<3>()) : Eigen::Vector3d::Zero();
      ref_q_ = s.q_ref;
      ref_qd_ = s.qd_ref;
      ref_qdd_ = s.qdd_ref;
      ref_valid_ = true;  // a set point's image is reused while it stays
    }
    s.pose_ref = ref_pose_;
    twist_ref = ref_twist_;
    accel_ref = ref_accel_;
    if (s.jaw >= 0) {
      // the TCP, midway between the jaws, referred to the jaw's measured opening and speed (a jaw squeezing
      // a body stops short of its reference): it slides by u d along the jaw's axis, u = J's jaw column
      // (half the axis, turning with the clamp at w), d = q_jaw - q_jaw,ref; the jaw's planned acceleration
      const double d = s.q[s.jaw] - s.q_ref[s.jaw], dd = s.qd[s.jaw] - s.qd_ref[s.jaw];
      const Eigen::Vector3d& u = ref_jaw_;
      const Eigen::Vector3d w = ref_twist_.tail<3>(), al = ref_accel_.tail<3>(), wu = w.cross(u);
      s.pose_ref.translation() += d * u;
      twist_ref.head<3>() += dd * u + d * wu;
      accel_ref.head<3>() += 2.0 * dd * wu + d * (al.cross(u) + w.cross(wu));
    }
  }
  shared_.workspace = in.workspace;
  shared_.robot = in.robot;
  Workspace& wk = workspace(in, r, ws_);  // the simulation's, whose frames at q one of its stages may have
  r.kinematics(in.q, wk, false);
  s.pose = r.tool_pose(wk);
  s.axes = task_axes(s.pose);
  r.tool_jacobian(wk, Jg);
  r.tool_bias(wk, in.qd, bg);
  const Eigen::Matrix3d Bt = s.axes.transpose();
  auto to_task = [&](const Vec6& w) {
    Vec6 o;
    o.head<3>() = w.head<3>();
    o.tail<3>() = Bt * w.tail<3>();
    return o;
  };
  s.J.resize(6, n);
  s.J.topRows<3>() = Jg.topRows<3>();
  s.J.bottomRows<3>() = Bt * Jg.bottomRows<3>();
  s.bias = to_task(bg);
  const Vec6 twist = Jg * s.qd;
  s.velocity = to_task(twist);
  s.velocity_ref = to_task(twist_ref);
  s.accel_ref = to_task(accel_ref);
  s.error.head<3>() = s.pose_ref.translation() - s.pose.translation();
  s.error.tail<3>() = Bt * detail::rotation_vector(s.pose_ref.linear() * s.pose.linear().transpose());
  s.error_rate = s.velocity_ref - s.velocity;
  // the sensor, less the payload's weight and inertia (acceleration commanded at the last update)
  s.sensed = in.wrench != nullptr;
  if (s.sensed) {
    const Vec6 w = Eigen::Map<const Vec6>(in.wrench);
    Vec6 h = -w;
    if (payload_.mass > 0) {
      const Eigen::Matrix3d& R = s.pose.linear();
      const Eigen::Vector3d rc = R * payload_.com, om = twist.tail<3>();
      const Eigen::Matrix3d Iw = R * payload_.inertia * R.transpose();
      const Eigen::Vector3d alpha = prev_accel_.tail<3>();
      const Eigen::Vector3d ac = prev_accel_.head<3>() + alpha.cross(rc) + om.cross(om.cross(rc));
      const Eigen::Vector3d f = payload_.mass * (r.gravity_acceleration() - ac);  // the payload's force on the clamp
      h.head<3>() -= f;
      h.tail<3>() -= rc.cross(f) - Iw * alpha - om.cross(Iw * om);
    }
    s.wrench = to_task(w);
    s.external = to_task(h);
  } else {
    s.wrench.setZero();
    s.external.setZero();
  }
  return s;
}

void TaskController::torques(const TaskState& s, const Vec6& accel, const Vec6& wrench, double* tau) {
  if (n_ == 0 || s.n != n_) throw std::logic_error("TaskController.torques called before reset() for this robot");
  if (!accel.allFinite()) throw std::invalid_argument("task acceleration must be finite");
  if (!wrench.allFinite()) throw std::invalid_argument("wrench must be finite");
  const int n = n_, jaw = s.jaw;
  // the jaw: position control
  if (jaw >= 0)
    qdd_[jaw] = s.qdd_ref[jaw] + jaw_kd_ * (s.qd_ref[jaw] - s.qd[jaw]) + jaw_kp_ * (s.q_ref[jaw] - s.q[jaw]);
  // the arm: the commanded rows
  int arm[kMaxDof], na = 0;
  for (int j = 0; j < n; ++j)
    if (j != jaw) arm[na++] = j;
  int rows[kTaskAxes], m = 0;
  for (int a = 0; a < kTaskAxes; ++a)
    if (commanded_[a]) rows[m++] = a;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kTaskAxes, kMaxDof> Jc(m, na);
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kTaskAxes, 1> rhs(m);
  for (int i = 0; i < m; ++i) {
    // the jaw's planned acceleration moves the TCP (midway between the jaws); its correction is left
    // out: a jaw closed on a body cannot follow it, and the arm must not answer a motion that is not there
    rhs[i] = accel[rows[i]] - s.bias[rows[i]] - (jaw >= 0 ? s.J(rows[i], jaw) * s.qdd_ref[jaw] : 0.0);
    for (int k = 0; k < na; ++k) Jc(i, k) = s.J(rows[i], arm[k]);
  }
  VecN qa(na);
  Vec6d x(m);
  const auto singular = [&]() {
    std::ostringstream msg;
    msg << "task Jacobian singular at q = [" << s.q.transpose() << "] (commanded " << names_of(commanded_) << ")";
    return std::domain_error(msg.str());
  };
  if (m == na) {
    if (!solve_square(Mat66(Jc), Vec6d(rhs), x)) throw singular();
    qa = x;
  } else {
    VecN q0(na);
    for (int k = 0; k < na; ++k) {
      const int j = arm[k];
      q0[k] = s.qdd_ref[j] + null_kd_ * (s.qd_ref[j] - s.qd[j]) + null_kp_ * (s.q_ref[j] - s.q[j]);
    }
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDof, kTaskAxes> X = Jc.transpose();
    // the pseudo-inverse J^T (J J^T)^-1: the null space is J's orthogonal one
    const Mat66 A = Jc * X;
    if (!solve_square(A, Vec6d(rhs - Jc * q0), x)) throw singular();
    qa = q0 + X * x;
  }
  for (int k = 0; k < na; ++k) qdd_[arm[k]] = qa[k];
  // M qdd + C + G + K qd (+ friction) of the model, plus J^T w in the world
  // with the jaw's planned acceleration: the arm does not answer the jaw's correction (a jaw squeezing a
  // body does not move); the jaw's own torque takes its correction times its own inertia
  double correction = 0.0;
  if (jaw >= 0) {
    correction = qdd_[jaw] - s.qdd_ref[jaw];
    qdd_[jaw] = s.qdd_ref[jaw];
  }
  Workspace& w = workspace(shared_, *run_model_, ws_);  // observe()'s caller's, for this update only
  shared_ = ControlInput();
  run_model_->rnea(s.q.data(), s.qd.data(), qdd_.data(), w, out_, 1.0, true);
  if (jaw >= 0) {
    if (jaw != n - 1) {  // links beyond the jaw: its inertia depends on q
      MatN M;
      run_model_->mass_matrix(s.q.data(), w, M);
      jaw_inertia_ = M(jaw, jaw);
    }
    out_[jaw] += jaw_inertia_ * correction;
    qdd_[jaw] += correction;
  }
  Vec6 ww;
  ww.head<3>() = wrench.head<3>();
  ww.tail<3>() = s.axes * wrench.tail<3>();
  // the geometric Jacobian back from the task one: angular rows B (B^T Jw)
  for (int j = 0; j < n; ++j) {
    const Eigen::Vector3d jv = s.J.col(j).head<3>(), jw = s.axes * s.J.col(j).tail<3>();
    tau[j] = out_[j] + jv.dot(ww.head<3>()) + jw.dot(ww.tail<3>());
  }
  // the TCP's acceleration this commands (world), for the payload at the next update: the jaw's
  // planned acceleration, as in the arm's equation (not its correction)
  Vec6 acc = s.J * qdd_ + s.bias;
  if (jaw >= 0) acc -= s.J.col(jaw) * (qdd_[jaw] - s.qdd_ref[jaw]);
  prev_accel_.head<3>() = acc.head<3>();
  prev_accel_.tail<3>() = s.axes * acc.tail<3>();
}

// ---- impedance ----

Impedance::Impedance(Eigen::VectorXd stiffness, Eigen::VectorXd damping, Eigen::VectorXd mass,
                     std::vector<std::string> directions, bool force_feedback, double jaw_kp, double jaw_kd,
                     double null_kp, double null_kd, Payload payload, std::shared_ptr<const Robot> model)
    : TaskController(std::move(directions), jaw_kp, jaw_kd, null_kp, null_kd, std::move(payload), std::move(model)),
      k_(std::move(stiffness)), d_(std::move(damping)), m_(std::move(mass)), feedback_(force_feedback) {
  check_values(k_, "stiffness", false);
  check_values(d_, "damping", false);
  check_values(m_, "mass", true);
  if (!this->directions().empty()) {
    const std::vector<int> axes = axes_of(this->directions(), "directions");
    spread(k_, axes, "stiffness");
    spread(d_, axes, "damping");
    spread(m_, axes, "mass");
  }
}

void Impedance::check(const Robot& robot) const {
  TaskController::check(robot);
  std::vector<int> axes = axes_of(directions(), "directions");
  if (axes.empty()) {
    const auto can = commandable_directions(robot);
    for (int a = 0; a < kTaskAxes; ++a)
      if (can[a]) axes.push_back(a);
  }
  spread(k_, axes, "stiffness");
  spread(d_, axes, "damping");
  spread(m_, axes, "mass");
}

void Impedance::reset(const Robot& robot, double period) {
  TaskController::reset(robot, period);
  K_ = per_axis(k_, "stiffness");
  D_ = per_axis(d_, "damping");
  Md_ = per_axis(m_, "mass");
}

void Impedance::compute_task(const TaskState& s, double* tau) {
  Vec6 a = Vec6::Zero(), w = Vec6::Zero();
  for (int i = 0; i < kTaskAxes; ++i) {
    if (!commanded_[i]) continue;
    if (feedback_) {
      a[i] = s.accel_ref[i] + (s.external[i] + D_[i] * s.error_rate[i] + K_[i] * s.error[i]) / Md_[i];
    } else {
      a[i] = s.accel_ref[i];
      w[i] = D_[i] * s.error_rate[i] + K_[i] * s.error[i];
    }
  }
  if (feedback_) w = s.wrench;
  torques(s, a, w, tau);
}

// ---- hybrid position/force ----

HybridForce::HybridForce(std::vector<std::string> force_directions, Eigen::VectorXd force, Eigen::VectorXd kp_force,
                         Eigen::VectorXd ki_force, Eigen::VectorXd kv, Eigen::VectorXd kp, Eigen::VectorXd kd,
                         std::vector<std::string> directions, bool force_feedback, double integral_limit,
                         double jaw_kp, double jaw_kd, double null_kp, double null_kd, Payload payload,
                         std::shared_ptr<const Robot> model)
    : TaskController(std::move(directions), jaw_kp, jaw_kd, null_kp, null_kd, std::move(payload), std::move(model)),
      fnames_(std::move(force_directions)), f_(std::move(force)), kpf_(std::move(kp_force)), kif_(std::move(ki_force)),
      kv_(std::move(kv)), kp_(std::move(kp)), kd_(std::move(kd)), feedback_(force_feedback), ilim_(integral_limit) {
  forder_ = axes_of(fnames_, "force_directions");
  if (forder_.empty()) throw std::invalid_argument("force_directions must name at least one direction");
  check_values(f_, "force", false, true);
  check_values(kpf_, "kp_force", false);
  check_values(kif_, "ki_force", false);
  check_values(kv_, "kv", false);
  check_values(kp_, "kp", false);
  check_values(kd_, "kd", false);
  detail::require_nonnegative(ilim_, "integral_limit");
  spread(f_, forder_, "force");
  spread(kpf_, forder_, "kp_force");
  spread(kif_, forder_, "ki_force");
  spread(kv_, forder_, "kv");
  if (!this->directions().empty()) {
    const std::vector<int> axes = axes_of(this->directions(), "directions");
    for (int a : forder_) {
      bool in = false;
      for (int b : axes) in |= a == b;
      if (!in)
        throw std::invalid_argument(std::string("force_directions: '") + kAxisNames[a] +
                                    "' is not among the commanded directions");
    }
  }
}

void HybridForce::check(const Robot& robot) const {
  TaskController::check(robot);
  std::array<bool, kTaskAxes> commanded{};
  const std::vector<int> given = axes_of(directions(), "directions");
  if (given.empty()) {
    commanded = commandable_directions(robot);
  } else {
    for (int a : given) commanded[a] = true;
  }
  for (int a : forder_)
    if (!commanded[a])
      throw std::invalid_argument(std::string("force_directions: robot '") + robot.name() + "' cannot command '" +
                                  kAxisNames[a] + "' (it commands " + names_of(commandable_directions(robot)) + ")");
  std::vector<int> pos;
  for (int a = 0; a < kTaskAxes; ++a) {
    bool f = false;
    for (int b : forder_) f |= a == b;
    if (commanded[a] && !f) pos.push_back(a);
  }
  if (!given.empty()) {  // the order given
    pos.clear();
    for (int a : given) {
      bool f = false;
      for (int b : forder_) f |= a == b;
      if (!f) pos.push_back(a);
    }
  }
  if (!pos.empty()) {
    spread(kp_, pos, "kp");
    spread(kd_, pos, "kd");
  }
}

void HybridForce::reset(const Robot& robot, double period) {
  TaskController::reset(robot, period);
  h_ = period;
  is_force_ = {};
  for (int a : forder_) is_force_[a] = true;
  porder_.clear();
  for (int a : order())
    if (!is_force_[a]) porder_.push_back(a);
  F_ = spread(f_, forder_, "force");
  Kpf_ = spread(kpf_, forder_, "kp_force");
  Kif_ = spread(kif_, forder_, "ki_force");
  Kv_ = spread(kv_, forder_, "kv");
  Kp_ = porder_.empty() ? Vec6(Vec6::Zero()) : spread(kp_, porder_, "kp");
  Kd_ = porder_.empty() ? Vec6(Vec6::Zero()) : spread(kd_, porder_, "kd");
  I_.setZero();
}

void HybridForce::compute_task(const TaskState& s, double* tau) {
  Vec6 a = Vec6::Zero(), w = feedback_ ? s.wrench : Vec6(Vec6::Zero());
  for (int i = 0; i < kTaskAxes; ++i) {
    if (!commanded_[i]) continue;
    if (!is_force_[i]) {
      a[i] = s.accel_ref[i] + Kd_[i] * s.error_rate[i] + Kp_[i] * s.error[i];
      continue;
    }
    // the force the clamp (with its payload) applies to its environment along i
    const double f = -s.external[i];
    const double e = F_[i] - f;
    double I = I_[i] + e * h_;
    if (Kif_[i] > 0) {
      const double imax = ilim_ / Kif_[i];
      if (I > imax) I = imax;
      else if (I < -imax) I = -imax;
    }
    I_[i] = I;
    const double cmd = F_[i] + Kpf_[i] * e + Kif_[i] * I;
    a[i] = -Kv_[i] * s.velocity[i];
    w[i] = feedback_ ? s.wrench[i] + cmd - f : cmd;
  }
  torques(s, a, w, tau);
}

}  // namespace coopsim
