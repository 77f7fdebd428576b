// The serial robot (robot.hpp), its construction and checks: DH rows and link tables read and checked,
// the precomputed per-link constants, copies with another base, gravity, geometry, names or dynamics
// backend, generated dynamics attached and checked against the tables. Kinematics in
// robot_kinematics.cpp, dynamics in robot_dynamics.cpp.
#include "coopsim/robot.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <atomic>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "coopsim/generated.hpp"
#include "internal.hpp"

namespace coopsim {

namespace {

std::string link_name(size_t k) {
  std::ostringstream s;
  s << "link " << (k + 1);
  return s.str();
}

using detail::require;

bool finite_dh(const DHParams& p) {
  return std::isfinite(p.theta) && std::isfinite(p.d) && std::isfinite(p.a) && std::isfinite(p.alpha);
}

}  // namespace

Eigen::Isometry3d dh_transform(double theta, double d, double a, double alpha) {
  const double ct = std::cos(theta), st = std::sin(theta), ca = std::cos(alpha), sa = std::sin(alpha);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0, sa, ca;
  T.translation() << a * ct, a * st, d;
  return T;
}

Eigen::Matrix3d box_inertia(double mass, double lx, double ly, double lz) {
  // a link's rule (build_): a box without mass (a frame that carries nothing) has no inertia
  require(std::isfinite(mass) && mass >= 0, "box_inertia: mass must be finite and >= 0 kg, got " + detail::num(mass));
  require(std::isfinite(lx) && std::isfinite(ly) && std::isfinite(lz) && lx >= 0 && ly >= 0 && lz >= 0,
          "box_inertia: edge lengths must be finite and >= 0");
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  I(0, 0) = mass * (ly * ly + lz * lz) / 12.0;
  I(1, 1) = mass * (lx * lx + lz * lz) / 12.0;
  I(2, 2) = mass * (lx * lx + ly * ly) / 12.0;
  return I;
}

void com_row_from_vector(JointType type, const DHParams& dh, const Eigen::Vector3d& r, const Eigen::Matrix3d& I,
                         DHParams& com, Eigen::Matrix3d& I_com, double scale) {
  // the CoM seen from frame i-1 turned back by theta: Tz(d) Tx(a) Rx(alpha) r
  // (for a prismatic joint q adds to d on both sides, so the same holds)
  const double ca = std::cos(dh.alpha), sa = std::sin(dh.alpha);
  const Eigen::Vector3d p(dh.a + r.x(), ca * r.y() - sa * r.z(), dh.d + sa * r.y() + ca * r.z());
  // an offset from the axis at the level of rounding is none: the CoM is on the axis (an angle of
  // that noise would be no angle at all, and would cost generated code its structure)
  const double noise = 16 * std::numeric_limits<double>::epsilon() * std::max(std::abs(dh.a) + r.norm(), scale);
  double rho = std::hypot(p.x(), p.y());
  double delta = 0.0;
  if (rho > noise) delta = std::atan2(p.y(), p.x());
  else rho = 0.0;
  com = DHParams{dh.theta + delta, p.z(), rho, 0.0};
  // CoM frame axes in frame i: Rx(alpha)^T Rz(delta)
  Eigen::Matrix3d Rx, Rz;
  Rx << 1, 0, 0, 0, ca, -sa, 0, sa, ca;
  const double cd = std::cos(delta), sd = std::sin(delta);
  Rz << cd, -sd, 0, sd, cd, 0, 0, 0, 1;
  const Eigen::Matrix3d R = Rx.transpose() * Rz;
  I_com = R.transpose() * I * R;
  I_com = 0.5 * (I_com + I_com.transpose());
}

namespace {

JointType joint_type(char c, size_t k) {
  if (c == 'R' || c == 'r') return JointType::Revolute;
  if (c == 'P' || c == 'p') return JointType::Prismatic;
  if (static_cast<unsigned char>(c) >= 128)
    throw std::invalid_argument("joint_types must be letters 'R' or 'P' only (a non-ASCII character at byte " +
                                std::to_string(k) + ")");
  throw std::invalid_argument("joint_types[" + std::to_string(k) + "] must be 'R' or 'P', got '" +
                              std::string(1, c) + "'");
}

DHParams dh_row(const double* r) { return DHParams{r[0], r[1], r[2], r[3]}; }

// a table of one row per joint, checked
const Array& rows(const Array& a, std::initializer_list<std::ptrdiff_t> shape, const char* name, bool finite = true) {
  check_shape(a, shape, name);
  if (finite) check_finite(a, name);
  return a;
}

}  // namespace

Robot Robot::from_tables(const RobotTables& t, std::vector<std::string>* warnings) {
  const std::string& policy = t.inertia_check;
  require(policy == "warn" || policy == "error" || policy == "ignore",
          "inertia_check must be 'warn', 'error' or 'ignore', got '" + policy + "'");
  const std::vector<double>& D = rows(t.dh, {-1, 4}, "dh").values;
  const int n = static_cast<int>(t.dh.shape[0]);
  require(n >= 1 && n <= kMaxDof, "dh must have 1 to " + std::to_string(kMaxDof) + " rows, got " + std::to_string(n));
  for (size_t k = 0; k < t.joint_types.size(); ++k) joint_type(t.joint_types[k], k);  // the letters first
  require(static_cast<int>(t.joint_types.size()) == n, "joint_types must have one letter per DH row: expected " +
                                                           std::to_string(n) + ", got " +
                                                           std::to_string(t.joint_types.size()));
  const bool com_vectors = t.com.ndim() == 2 && t.com.shape[0] == n && t.com.shape[1] == 3;
  const std::vector<double>& C = rows(t.com, {n, com_vectors ? 3 : 4}, "com").values;
  const std::vector<double>& M = rows(t.masses, {n}, "masses").values;
  const Array& I = t.inertias;
  const bool six = I.ndim() == 2 && I.shape[0] == n && I.shape[1] == 6;
  if (!six && !(I.ndim() == 3 && I.shape[0] == n && I.shape[1] == 3 && I.shape[2] == 3))
    throw std::invalid_argument("wrong shape for inertias: expected (" + std::to_string(n) + ", 3, 3) or (" +
                                std::to_string(n) + ", 6) [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], got " +
                                shape_string(I.shape.data(), I.ndim()));
  check_finite(I, "inertias");
  std::vector<Link> links(n);
  if (t.friction) rows(*t.friction, {n}, "friction");
  if (t.q_limits) rows(*t.q_limits, {n, 2}, "q_limits", false);
  if (t.tau_limits) rows(*t.tau_limits, {n}, "tau_limits", false);
  const std::vector<double> Ia = t.armature ? per_joint(*t.armature, n, "armature") : std::vector<double>(),
                            Fc = t.coulomb ? per_joint(*t.coulomb, n, "coulomb") : std::vector<double>(),
                            Vc = t.coulomb_width ? per_joint(*t.coulomb_width, n, "coulomb_width") : std::vector<double>();
  // CoM vectors: the robot's size sets what rounding noise is
  double scale = 0.0;
  for (int j = 0; com_vectors && j < n; ++j)
    scale += std::abs(D[4 * j + 1]) + std::abs(D[4 * j + 2]) + Eigen::Map<const Eigen::Vector3d>(&C[3 * j]).norm();
  for (int k = 0; k < n; ++k) {
    Link& L = links[k];
    L.type = joint_type(t.joint_types[k], k);
    L.dh = dh_row(&D[4 * k]);
    L.mass = M[k];
    const double* v = &I.values[(six ? 6 : 9) * k];
    if (six) L.inertia << v[0], v[3], v[4], v[3], v[1], v[5], v[4], v[5], v[2];
    else L.inertia = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(v);
    if (com_vectors) {
      const Eigen::Matrix3d I_link = L.inertia;  // in DH frame i's axes: to the CoM row and CoM frame
      com_row_from_vector(L.type, L.dh, Eigen::Map<const Eigen::Vector3d>(&C[3 * k]), I_link, L.com, L.inertia,
                          scale);
    } else {
      L.com = dh_row(&C[4 * k]);
    }
    if (t.armature) L.armature = Ia[k];
    if (t.coulomb) L.coulomb = Fc[k];
    if (t.coulomb_width) L.coulomb_width = Vc[k];
    if (t.friction) L.friction = t.friction->values[k];
    if (t.q_limits) L.q_min = t.q_limits->values[2 * k], L.q_max = t.q_limits->values[2 * k + 1];
    if (t.tau_limits) L.tau_max = t.tau_limits->values[k];
  }
  const Eigen::Vector3d g = Eigen::Map<const Eigen::Vector3d>(rows(t.gravity, {3}, "gravity").values.data());
  const Eigen::Vector3d p =
      Eigen::Map<const Eigen::Vector3d>(rows(t.base_position, {3}, "base_position").values.data());
  check_finite(t.base_yaw, "base_yaw");
  Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity();
  if (t.base_orientation)
    R0 = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
        rows(*t.base_orientation, {3, 3}, "base_orientation").values.data());
  Robot r(std::move(links), g, p, t.base_yaw, t.tool, t.name, t.end_stop, R0);
  if (!r.inertia_warnings().empty() && policy == "error")
    throw std::invalid_argument(r.inertia_warnings().front() + " (inertia_check='error')");
  if (warnings && policy == "warn")
    for (const std::string& w : r.inertia_warnings())
      warnings->push_back(w + " (allowed; inertia_check='error' refuses it)");
  if (t.boxes || t.clamp.present()) r = r.with_geometry(t.boxes.value_or(std::vector<LinkBox>()), t.clamp);
  if (!t.dimensions.empty()) r = r.with_dimensions(t.dimensions);
  return r;
}

RobotTables Robot::tables() const {
  RobotTables t;
  const std::ptrdiff_t n = n_;
  auto table = [&](std::vector<std::ptrdiff_t> shape, auto&& row) {
    Array a{{}, std::move(shape)};
    for (const Link& L : links_) row(L, a.values);
    return a;
  };
  auto dh = [](const DHParams& p, std::vector<double>& v) { v.insert(v.end(), {p.theta, p.d, p.a, p.alpha}); };
  t.dh = table({n, 4}, [&](const Link& L, auto& v) { dh(L.dh, v); });
  t.com = table({n, 4}, [&](const Link& L, auto& v) { dh(L.com, v); });
  t.masses = table({n}, [](const Link& L, auto& v) { v.push_back(L.mass); });
  t.inertias = table({n, 3, 3}, [](const Link& L, auto& v) {
    for (int i = 0; i < 3; ++i) v.insert(v.end(), {L.inertia(i, 0), L.inertia(i, 1), L.inertia(i, 2)});
  });
  t.joint_types = joint_types();
  t.friction = table({n}, [](const Link& L, auto& v) { v.push_back(L.friction); });
  t.q_limits = table({n, 2}, [](const Link& L, auto& v) { v.insert(v.end(), {L.q_min, L.q_max}); });
  t.tau_limits = table({n}, [](const Link& L, auto& v) { v.push_back(L.tau_max); });
  t.armature = table({n}, [](const Link& L, auto& v) { v.push_back(L.armature); });
  t.coulomb = table({n}, [](const Link& L, auto& v) { v.push_back(L.coulomb); });
  t.coulomb_width = table({n}, [](const Link& L, auto& v) { v.push_back(L.coulomb_width); });
  t.gravity.values.assign(gravity_.data(), gravity_.data() + 3);
  t.base_position.values.assign(base_p_.data(), base_p_.data() + 3);
  t.base_yaw = base_yaw_;
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> R0 = base_R_;
  t.base_orientation = Array{{R0.data(), R0.data() + 9}, {3, 3}};
  t.tool = tool_;
  t.name = name_;
  t.end_stop = end_stop_;
  if (!default_boxes_) t.boxes = boxes_;  // the default boxes are re-made from the tables
  t.clamp = clamp_;
  t.dimensions = dimensions_;
  t.inertia_check = "ignore";  // the robot exists: it was allowed
  return t;
}

Robot::Robot(std::vector<Link> links, Eigen::Vector3d gravity, Eigen::Vector3d base_position,
             double base_yaw, Tool tool, std::string name, EndStop end_stop, Eigen::Matrix3d base_orientation)
    : links_(std::move(links)),
      gravity_(gravity),
      base_p_(base_position),
      base_yaw_(base_yaw),
      base_R_(base_orientation),
      tool_(tool),
      name_(std::move(name)),
      end_stop_(end_stop) {
  build_();
}

void Robot::build_() {
  static std::atomic<std::uint64_t> next_id{1};
  kinematics_id_ = next_id.fetch_add(1, std::memory_order_relaxed);  // what a Workspace held is not ours
  n_ = static_cast<int>(links_.size());
  {
    std::ostringstream s;
    s << "a robot needs 1 to " << kMaxDof << " joints, got " << n_;
    require(n_ >= 1 && n_ <= kMaxDof, s.str());
  }
  inertia_warnings_.clear();
  for (size_t k = 0; k < links_.size(); ++k) {
    const Link& L = links_[k];
    const std::string who = link_name(k);
    require(L.type == JointType::Revolute || L.type == JointType::Prismatic,
            who + ": joint type must be 'R' or 'P'");
    require(finite_dh(L.dh), who + ": DH parameters must be finite");
    require(finite_dh(L.com), who + ": centre-of-mass parameters must be finite");
    require(std::isfinite(L.mass) && L.mass >= 0, who + ": mass must be finite and >= 0 kg");
    check_inertia(L.inertia, who + ": inertia tensor");
    const double tol = 1e-9 * std::max(L.inertia.cwiseAbs().maxCoeff(), 1e-300);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(L.inertia, Eigen::EigenvaluesOnly);
    const Eigen::Vector3d ev = es.eigenvalues();  // ascending
    if (ev(0) + ev(1) < ev(2) - tol) {
      std::ostringstream w;
      w << who << ": inertia tensor breaks the triangle inequality of its principal moments (I1 + I2 >= I3): "
        << ev(0) << " + " << ev(1) << " < " << ev(2) << " kg m^2 (no rigid body has it)";
      inertia_warnings_.push_back(w.str());
    }
    require(std::isfinite(L.friction) && L.friction >= 0, who + ": friction K must be finite and >= 0");
    require(std::isfinite(L.armature) && L.armature >= 0, who + ": armature must be finite and >= 0");
    require(std::isfinite(L.coulomb) && L.coulomb >= 0, who + ": Coulomb friction must be finite and >= 0");
    require(std::isfinite(L.coulomb_width) && L.coulomb_width > 0,
            who + ": Coulomb friction width must be finite and > 0");
    require(!std::isnan(L.q_min) && !std::isnan(L.q_max) && L.q_min < L.q_max,
            who + ": joint limits must satisfy q_min < q_max");
    require(!std::isnan(L.tau_max) && L.tau_max > 0, who + ": actuator limit tau_max must be > 0");
  }
  require(gravity_.allFinite(), "gravity must be finite");
  require(base_p_.allFinite() && std::isfinite(base_yaw_), "base position and yaw must be finite");
  check_rotation(base_R_, "base_orientation");
  require(std::isfinite(end_stop_.frequency) && end_stop_.frequency >= 0 &&
              std::isfinite(end_stop_.damping_ratio) && end_stop_.damping_ratio >= 0,
          "end stop frequency and damping ratio must be finite and >= 0");
  tool_.link = link_index_(tool_.link, "tool link");
  tool_.second_link = link_index_(tool_.second_link, "tool second_link");
  require(tool_.link >= 1 && tool_.second_link >= 1, "tool links must be 1..n (not the base)");
  require(tool_.second_point.allFinite(), "tool second_point must be finite");
  check_rigid(tool_.offset.matrix(), "tool offset");

  base_ = Eigen::Isometry3d::Identity();
  base_.linear() = Eigen::AngleAxisd(base_yaw_, Eigen::Vector3d::UnitZ()).toRotationMatrix() * base_R_;
  base_.translation() = base_p_;

  pre_.resize(n_);
  params_.assign(kParamsPerLink * n_ + 3, 0.0);
  for (int k = 0; k < n_; ++k) {
    const Link& L = links_[k];
    Pre& P = pre_[k];
    P.ct = std::cos(L.dh.theta);
    P.st = std::sin(L.dh.theta);
    P.ca = std::cos(L.dh.alpha);
    P.sa = std::sin(L.dh.alpha);
    // transform from DH frame i to the CoM frame; constant because q enters
    // the same slot of both rows and Rz, Tz commute
    const Eigen::Isometry3d A = dh_transform(L.dh.theta, L.dh.d, L.dh.a, L.dh.alpha);
    const Eigen::Isometry3d C = dh_transform(L.com.theta, L.com.d, L.com.a, L.com.alpha);
    const Eigen::Isometry3d X = A.inverse() * C;
    P.R_com = X.linear();
    P.p_com = X.translation();
    P.I_local = P.R_com * L.inertia * P.R_com.transpose();
    double* b = &params_[kParamsPerLink * k];
    b[kDhTheta] = L.dh.theta; b[kDhD] = L.dh.d; b[kDhA] = L.dh.a; b[kDhAlpha] = L.dh.alpha;
    b[kComTheta] = L.com.theta; b[kComD] = L.com.d; b[kComA] = L.com.a; b[kComAlpha] = L.com.alpha;
    b[kMass] = L.mass;
    b[kIxx] = L.inertia(0, 0); b[kIyy] = L.inertia(1, 1); b[kIzz] = L.inertia(2, 2);
    b[kIxy] = L.inertia(0, 1); b[kIxz] = L.inertia(0, 2); b[kIyz] = L.inertia(1, 2);
    b[kFriction] = L.friction;
    b[kArmature] = L.armature;
    b[kCoulomb] = L.coulomb;
    b[kCoulombWidth] = L.coulomb_width;
  }
  const Eigen::Vector3d g0 = base_.linear().transpose() * gravity_;
  params_[kParamsPerLink * n_ + 0] = g0.x();
  params_[kParamsPerLink * n_ + 1] = g0.y();
  params_[kParamsPerLink * n_ + 2] = g0.z();
  refresh_generated_params_();
  build_geometry_();
}

int Robot::link_index_(int link, const char* what) const {
  const int l = link < 0 ? n_ + 1 + link : link;
  if (l < 0 || l > n_) {
    std::ostringstream s;
    s << what << " must be in [-" << n_ << ", " << n_ << "], got " << link;
    throw std::invalid_argument(s.str());
  }
  return l;
}

std::string Robot::joint_types() const {
  std::string s;
  for (const Link& L : links_) s.push_back(static_cast<char>(L.type));
  return s;
}

VecN Robot::q_min() const {
  VecN v(n_);
  for (int k = 0; k < n_; ++k) v[k] = links_[k].q_min;
  return v;
}
VecN Robot::q_max() const {
  VecN v(n_);
  for (int k = 0; k < n_; ++k) v[k] = links_[k].q_max;
  return v;
}
VecN Robot::tau_max() const {
  VecN v(n_);
  for (int k = 0; k < n_; ++k) v[k] = links_[k].tau_max;
  return v;
}
VecN Robot::friction_coefficients() const {
  VecN v(n_);
  for (int k = 0; k < n_; ++k) v[k] = links_[k].friction;
  return v;
}

void Robot::friction_torques(const double* qd, VecN& tau) const {
  tau.resize(n_);
  for (int k = 0; k < n_; ++k) {
    const Link& L = links_[k];
    tau[k] = L.friction * qd[k] + (L.coulomb > 0 ? L.coulomb * std::tanh(qd[k] / L.coulomb_width) : 0.0);
  }
}

Robot Robot::with_base(const Eigen::Vector3d& position, double yaw) const {
  check_finite(yaw, "yaw");
  Robot r = *this;
  r.base_p_ = position;
  r.base_yaw_ = yaw;
  r.build_();
  return r;
}

Robot Robot::with_base_orientation(const Eigen::Matrix3d& R) const {
  Robot r = *this;
  r.base_R_ = R;
  r.build_();
  return r;
}

Robot Robot::with_gravity(const Eigen::Vector3d& gravity) const {
  Robot r = *this;
  r.gravity_ = gravity;
  r.build_();
  return r;
}

void Robot::attach_generated_(std::shared_ptr<const GeneratedDynamics> gen) {
  require(static_cast<bool>(gen), "attach_generated: no generated dynamics given");
  require(gen->dof == n_, "generated dynamics '" + gen->name + "' has " + std::to_string(gen->dof) +
                              " joints, robot has " + std::to_string(n_));
  require(gen->joint_types == joint_types(), "generated dynamics '" + gen->name + "' is for joint types " +
                                                 gen->joint_types + ", robot has " + joint_types());
  require(static_cast<int>(gen->angles.size()) == 4 * n_,
          "generated dynamics '" + gen->name + "' carries a malformed angle table");
  for (int k = 0; k < n_; ++k) {
    const Link& L = links_[k];
    const double mine[4] = {L.dh.theta, L.dh.alpha, L.com.theta, L.com.alpha};
    const char* what[4] = {"DH theta", "DH alpha", "CoM theta", "CoM alpha"};
    for (int j = 0; j < 4; ++j) {
      if (std::abs(mine[j] - gen->angles[4 * k + j]) > 1e-12) {
        std::ostringstream s;
        s << "generated dynamics '" << gen->name << "' was generated for " << what[j] << " = "
          << gen->angles[4 * k + j] << " on " << link_name(k) << ", robot has " << mine[j]
          << " (angles are structural: regenerate)";
        throw std::invalid_argument(s.str());
      }
    }
  }
  require(gen->mass_matrix && gen->coriolis && gen->coriolis_matrix && gen->gravity,
          "generated dynamics '" + gen->name + "' lacks a function");
  require(gen->constant_count >= 0 && (gen->constants || gen->constant_count == 0),
          "generated dynamics '" + gen->name + "' lacks its constants function");
  generated_ = std::move(gen);
  use_generated_ = true;
  refresh_generated_params_();
}

void Robot::refresh_generated_params_() {
  gen_params_ = params_;
  if (!generated_ || !generated_->constants) return;
  gen_params_.resize(params_.size() + generated_->constant_count);
  generated_->constants(params_.data(), gen_params_.data() + params_.size());
}

Robot Robot::with_generated(std::shared_ptr<const GeneratedDynamics> gen) const {
  Robot r = *this;
  r.attach_generated_(std::move(gen));
  return r;
}

Robot Robot::with_generated(const std::string& name) const {
  const GeneratedDynamics* g = find_generated(name);
  require(g, "no generated dynamics named '" + name + "' in this build or the build cache");
  return with_generated(std::shared_ptr<const GeneratedDynamics>(g, [](const GeneratedDynamics*) {}));  // kept for good
}

Robot Robot::with_backend(const std::string& backend) const {
  Robot r = *this;
  if (backend == "numeric") {
    r.use_generated_ = false;
  } else if (backend == "generated") {
    require(static_cast<bool>(generated_),
            "backend 'generated' is not available for robot '" + name_ + "': no generated code attached");
    r.use_generated_ = true;
  } else {
    throw std::invalid_argument("backend must be 'generated' or 'numeric', got '" + backend + "'");
  }
  return r;
}

Robot Robot::with_geometry(std::vector<LinkBox> boxes, Clamp clamp) const {
  Robot r = *this;
  r.default_boxes_ = boxes.empty();
  r.boxes_ = std::move(boxes);
  r.clamp_ = clamp;
  r.build_geometry_();
  return r;
}

Robot Robot::with_dimensions(std::map<std::string, double> dimensions) const {
  for (const auto& [key, value] : dimensions)
    require(std::isfinite(value), "dimension '" + key + "' must be finite");
  Robot r = *this;
  r.dimensions_ = std::move(dimensions);
  return r;
}

namespace {
std::vector<std::string> default_names(const char* prefix, int n) {
  std::vector<std::string> out;
  for (int i = 1; i <= n; ++i) out.push_back(prefix + std::to_string(i));
  return out;
}

void check_names(const std::vector<std::string>& names, int n, const char* what) {
  require(static_cast<int>(names.size()) == n,
          std::string(what) + " must hold " + std::to_string(n) + " names, got " + std::to_string(names.size()));
  for (std::size_t i = 0; i < names.size(); ++i) {
    require(!names[i].empty(), std::string(what) + "[" + std::to_string(i) + "] must not be empty");
    for (std::size_t j = 0; j < i; ++j)
      require(names[i] != names[j], std::string(what) + " must be unique: '" + names[i] + "' appears twice");
  }
}
}  // namespace

std::vector<std::string> Robot::joint_names() const {
  return joint_names_.empty() ? default_names("joint", n_) : joint_names_;
}

std::vector<std::string> Robot::link_names() const {
  return link_names_.empty() ? default_names("link", n_) : link_names_;
}

Robot Robot::with_names(std::vector<std::string> joint_names, std::vector<std::string> link_names) const {
  check_names(joint_names, n_, "joint_names");
  check_names(link_names, n_, "link_names");
  Robot r = *this;
  r.joint_names_ = std::move(joint_names);
  r.link_names_ = std::move(link_names);
  return r;
}

}  // namespace coopsim
