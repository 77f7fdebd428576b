// Cooperative control laws (cooperative_laws.hpp): object-level (symmetric) control with a commanded
// load share and squeeze (or an impedance to a push), and leader-follower. The groups they drive in a
// simulation: cooperative_stage.cpp.
#include "coopsim/cooperative_laws.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "internal.hpp"
#include "least_norm.hpp"

namespace coopsim {

namespace {

// A law-less task controller: the cooperative laws use its observe() and torques().
class Arm : public TaskController {
 public:
  using TaskController::TaskController;
  void compute_task(const TaskState&, double*) override {
    throw std::logic_error("a cooperative arm is driven by its cooperative controller");
  }
};

// world [v; w] <-> task axes of a state
Vec6 to_world(const TaskState& s, const Vec6& v) {
  Vec6 o;
  o.head<3>() = v.head<3>();
  o.tail<3>() = s.axes * v.tail<3>();
  return o;
}
Vec6 to_task(const TaskState& s, const Vec6& v) {
  Vec6 o;
  o.head<3>() = v.head<3>();
  o.tail<3>() = s.axes.transpose() * v.tail<3>();
  return o;
}

// A point r away of a rigid body with twist (v, w) and acceleration (a, alpha): its twist and acceleration.
void carry(const Vec6& twist, const Vec6& acc, const Eigen::Vector3d& r, Vec6& t_out, Vec6& a_out) {
  const Eigen::Vector3d w = twist.tail<3>(), al = acc.tail<3>();
  t_out.head<3>() = twist.head<3>() + w.cross(r);
  t_out.tail<3>() = w;
  a_out.head<3>() = acc.head<3>() + al.cross(r) + w.cross(w.cross(r));
  a_out.tail<3>() = al;
}

void require_two(const std::vector<const Robot*>& robots, const char* what) {
  if (robots.size() != 2)
    throw std::invalid_argument(std::string(what) + " drives two robots holding one object, got " +
                                std::to_string(robots.size()));
}

void require_holding(const std::vector<CoopMember>& m) {
  if (m[0].held < 0 || m[1].held < 0 || m[0].held != m[1].held)
    throw std::invalid_argument("the cooperative controller's robots " + std::to_string(m[0].robot) + " and " +
                                std::to_string(m[1].robot) + " do not hold the same body" +
                                (m[0].held < 0 || m[1].held < 0 ? " (one holds nothing)" : ""));
}

Vec6 checked_vec6(const Vec6& v, const char* name, bool positive) {
  for (int i = 0; i < 6; ++i)
    if (!std::isfinite(v[i]) || (positive ? !(v[i] > 0) : v[i] < 0))
      throw std::invalid_argument(std::string(name) + " must be finite and " + (positive ? "> 0" : ">= 0") +
                                  ", got " + detail::num(v[i]) + " at entry " + std::to_string(i + 1));
  return v;
}

}  // namespace

// ---- object-level control ----

ObjectControl::ObjectControl(double mass, const Eigen::Matrix3d& inertia, Gains gains, double load_share,
                             double squeeze, bool impedance, Vec6 stiffness, Vec6 damping, Vec6 imp_mass,
                             double accel_filter)
    : mass_(mass), inertia_(inertia), gains_(gains), impedance_(impedance), K_(stiffness), D_(damping),
      Md_(imp_mass), accel_filter_(accel_filter) {
  checked_vec6(K_, "stiffness", false);
  checked_vec6(D_, "damping", false);
  checked_vec6(Md_, "impedance mass", true);
  detail::require_nonnegative(accel_filter_, "accel_filter");
  if (!std::isfinite(mass_) || !(mass_ > 0))
    throw std::invalid_argument("mass (the object's, in the controller's model) must be finite and > 0 kg, got " +
                                detail::num(mass_));
  check_inertia(inertia_, "inertia (the object's, in the controller's model)");
  checked_vec6(gains_.kp, "kp", false);
  checked_vec6(gains_.kd, "kd", false);
  detail::require_nonnegative(gains_.kp_force, "kp_force");
  detail::require_nonnegative(gains_.ki_force, "ki_force");
  detail::require_nonnegative(gains_.integral_limit, "integral_limit");
  set_load_share(load_share);
  set_squeeze(squeeze);
}

void ObjectControl::set_load_share(double load_share) {
  if (!std::isfinite(load_share) || load_share < 0 || load_share > 1)
    throw std::invalid_argument("load_share must be in [0, 1], got " + detail::num(load_share));
  share_ = load_share;
}

void ObjectControl::set_squeeze(double squeeze) {
  if (!std::isfinite(squeeze)) throw std::invalid_argument("squeeze must be finite, got " + detail::num(squeeze));
  squeeze_ = squeeze;
}

void ObjectControl::set_offset(const Eigen::Vector3d& offset) {
  check_finite(offset.data(), 3, "offset");
  offset_ = offset;
}

void ObjectControl::set_offset_ramp(double seconds) {
  detail::require_nonnegative(seconds, "offset_ramp");
  ramp_ = seconds;
}

void ObjectControl::check(const std::vector<const Robot*>& robots) const {
  require_two(robots, "ObjectControl");
  for (const Robot* r : robots)
    if (!r->clamp().present()) throw std::invalid_argument("robot '" + r->name() + "' has no clamp");
}

void ObjectControl::reset(const std::vector<const Robot*>& robots, double period) {
  check(robots);
  arms_.clear();
  for (const Robot* r : robots) {
    arms_.push_back(std::make_shared<Arm>());
    arms_.back()->reset(*r, period);
  }
  g_ = robots[0]->gravity_acceleration();
  I_.assign(robots.size(), Vec6::Zero());
  cmd_.assign(robots.size(), Vec6::Zero());
  h_ = period;
  xc_.setZero();
  vc_.setZero();
  ac_.setZero();
  acc_f_.setZero();
  push_.setZero();
  off_now_ = ramp_from_ = ramp_to_ = offset_;  // a run starts at the commanded offset
  ramp_t0_ = -std::numeric_limits<double>::infinity();
  has_prev_ = false;
  acc_alpha_ = accel_filter_ > 0 ? -std::expm1(-period / accel_filter_) : 1.0;
}

void ObjectControl::compute(double t, const std::vector<CoopMember>& m, const std::vector<double*>& tau) {
  if (arms_.size() != 2 || m.size() != 2) throw std::logic_error("ObjectControl.compute called before reset()");
  require_holding(m);
  const TaskState& s0 = arms_[0]->observe(m[0].in);
  // the object: pose, twist and their references from member 0's TCP and grip
  const Eigen::Isometry3d To = s0.pose * m[0].grip, Tr = s0.pose_ref * m[0].grip;
  const Eigen::Vector3d c = To.translation();
  Vec6 tw, tw_ref, acc_ref, unused;
  carry(to_world(s0, s0.velocity), Vec6::Zero(), c - s0.pose.translation(), tw, unused);
  carry(to_world(s0, s0.velocity_ref), to_world(s0, s0.accel_ref), Tr.translation() - s0.pose_ref.translation(),
        tw_ref, acc_ref);
  // member 1's reference is the object's reference carried to its TCP (its own joint reference's image,
  // which the law does not use, is not computed)
  TaskController::TaskReference ref1;
  ref1.pose = Tr * m[1].grip.inverse();
  carry(tw_ref, acc_ref, ref1.pose.translation() - Tr.translation(), ref1.twist, ref1.accel);
  const TaskState& s1 = arms_[1]->observe(m[1].in, &ref1);
  const TaskState* s[2] = {&s0, &s1};
  // the reference's offset: a new one ramps from the offset of the last update at a constant rate
  if (offset_ != ramp_to_) {
    ramp_from_ = off_now_;
    ramp_to_ = offset_;
    ramp_t0_ = t;
  }
  Eigen::Vector3d off_rate = Eigen::Vector3d::Zero();
  const double along = ramp_ > 0 ? (t - ramp_t0_) / ramp_ : 1.0;
  if (along < 1.0 - 1e-9) {
    off_now_ = ramp_from_ + along * (ramp_to_ - ramp_from_);
    off_rate = (ramp_to_ - ramp_from_) / ramp_;
  } else {
    off_now_ = ramp_to_;
  }
  err_.head<3>() = Tr.translation() + off_now_ - c;
  err_.tail<3>() = detail::rotation_vector(Tr.linear() * To.linear().transpose());
  Vec6 rate = tw_ref - tw;
  rate.head<3>() += off_rate;
  const Eigen::Matrix3d Iw = To.linear() * inertia_ * To.linear().transpose();
  const Eigen::Vector3d w = tw.tail<3>();
  if (impedance_) {
    // the push: the object's Newton-Euler with its measured acceleration (the twist's difference,
    // low-pass filtered) less the clamps' sensed wrenches and its weight
    if (has_prev_) acc_f_ += acc_alpha_ * ((tw - tw_prev_) / h_ - acc_f_);
    tw_prev_ = tw;
    has_prev_ = true;
    Vec6 hs[2];
    for (int k = 0; k < 2; ++k) hs[k] = s[k]->sensed ? to_world(*s[k], s[k]->wrench) : Vec6(Vec6::Zero());
    const Eigen::Vector3d up = g_.norm() > 0 ? Eigen::Vector3d(-g_) : Eigen::Vector3d::UnitZ();
    const Cooperation sensed = cooperation(c, s0.pose.translation(), hs[0], s1.pose.translation(), hs[1], up);
    push_.head<3>() = mass_ * (acc_f_.head<3>() - g_) - sensed.external.head<3>();
    push_.tail<3>() = Iw * acc_f_.tail<3>() + w.cross(Iw * w) - sensed.external.tail<3>();
    // the admittance: the compliant offset from the reference, M xc'' + D xc' + K xc = push (semi-implicit Euler)
    for (int i = 0; i < 6; ++i) {
      ac_[i] = (push_[i] - D_[i] * vc_[i] - K_[i] * xc_[i]) / Md_[i];
      vc_[i] += ac_[i] * h_;
      xc_[i] += vc_[i] * h_;
    }
    // the motion loop tracks the reference moved by the offset
    err_ += xc_;
    rate += vc_;
    acc_ref += ac_;
  }
  // the object's acceleration and the wrench it takes
  Vec6 a;
  for (int i = 0; i < 6; ++i) a[i] = acc_ref[i] + gains_.kd[i] * rate[i] + gains_.kp[i] * err_[i];
  hd_.head<3>() = mass_ * (a.head<3>() - g_);
  hd_.tail<3>() = Iw * a.tail<3>() + w.cross(Iw * w);
  if (impedance_) hd_ -= push_;  // the clamps take the push: the motion loop follows x_c without an error
  // distribution: columns per clamp: fx, fy, fz and one moment per commanded rotation axis
  // (fixed-size storage: the update does not allocate)
  Eigen::Vector3d axes[2][3];
  int n_axes[2] = {0, 0};
  for (int k = 0; k < 2; ++k)
    for (int r = 0; r < 3; ++r)
      if (s[k]->commanded[3 + r]) axes[k][n_axes[k]++] = s[k]->axes.col(r);
  const int cols = 6 + n_axes[0] + n_axes[1];
  using Dist = Eigen::Matrix<double, 8, Eigen::Dynamic, 0, 8, 12>;
  Dist A = Dist::Zero(8, cols);
  Eigen::Matrix<double, 8, 1> b;
  const Eigen::Vector3d p[2] = {s0.pose.translation(), s1.pose.translation()};
  const Eigen::Vector3d e = (p[1] - p[0]).normalized();
  int col = 0, first[2];
  for (int k = 0; k < 2; ++k) {
    first[k] = col;
    const Eigen::Vector3d r = p[k] - c;
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d u = Eigen::Vector3d::Unit(j);
      A.block<3, 1>(0, col) = u;
      A.block<3, 1>(3, col) = r.cross(u);
      A(7, col) = (k == 0 ? 0.5 : -0.5) * e[j];
      ++col;
    }
    for (int j = 0; j < n_axes[k]; ++j) A.block<3, 1>(3, col++) = axes[k][j];
  }
  A(6, first[0] + 2) = 1.0 - share_;  // (1 - share) f0z - share f1z = 0
  A(6, first[1] + 2) = -share_;
  b.head<6>() = hd_;
  b[6] = 0.0;
  b[7] = squeeze_;
  // least norm, the directions the clamps can barely produce (a moment about the line through their
  // points, from forces whose lever is the TCPs' millimetres off it) left to the structure: singular
  // values below 1e-3 of the largest count as zero
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 12, 1> x(cols);
  // arms commanding all six directions: the distribution loses a direction only with the bar along the
  // vertical (the share's and the squeeze's rows then meet); the Gram's test proves the rest
  if (!(n_axes[0] == 3 && n_axes[1] == 3 && least_norm::well_conditioned(A, b, x))) least_norm::cod(A, b, 1e-3, x);
  // each arm: its TCP moves with the object; it applies its wrench, closed on its sensor
  for (int k = 0; k < 2; ++k) {
    Vec6 hk = Vec6::Zero();
    hk.head<3>() = x.segment<3>(first[k]);
    for (int j = 0; j < n_axes[k]; ++j) hk.tail<3>() += x[first[k] + 3 + j] * axes[k][j];
    cmd_[k] = hk;
    Vec6 tk, ak;
    carry(tw, a, p[k] - c, tk, ak);
    const Vec6 want = to_task(*s[k], hk), got = s[k]->wrench;
    Vec6 apply = Vec6::Zero();
    for (int i = 0; i < 6; ++i) {
      if (!s[k]->commanded[i]) continue;
      const double ei = want[i] - got[i];
      double I = I_[k][i] + ei * h_;
      if (gains_.ki_force > 0) {
        const double imax = gains_.integral_limit / gains_.ki_force;
        I = std::max(-imax, std::min(imax, I));
      }
      I_[k][i] = I;
      apply[i] = want[i] + gains_.kp_force * ei + gains_.ki_force * I;
    }
    arms_[k]->torques(*s[k], to_task(*s[k], ak), apply, tau[k]);
  }
}

// ---- leader-follower ----

LeaderFollower::LeaderFollower(double kp, double kd, Eigen::VectorXd stiffness, Eigen::VectorXd damping,
                               Eigen::VectorXd mass, double object_mass, double follower_share)
    : kp_(kp), kd_(kd), k_(std::move(stiffness)), d_(std::move(damping)), m_(std::move(mass)),
      object_mass_(object_mass), share_(follower_share) {
  detail::require_nonnegative(kp_, "kp");
  detail::require_nonnegative(kd_, "kd");
  detail::require_nonnegative(object_mass_, "object_mass");
  if (!std::isfinite(share_) || share_ < 0 || share_ > 1)
    throw std::invalid_argument("follower_share must be in [0, 1], got " + detail::num(share_));
  // the values' checks are the impedance's
  Impedance(k_, d_, m_);
}

void LeaderFollower::check(const std::vector<const Robot*>& robots) const {
  require_two(robots, "LeaderFollower");
  for (const Robot* r : robots)
    if (!r->clamp().present()) throw std::invalid_argument("robot '" + r->name() + "' has no clamp");
  Impedance(k_, d_, m_).check(*robots[1]);
}

void LeaderFollower::reset(const std::vector<const Robot*>& robots, double period) {
  check(robots);
  arms_.clear();
  // both arms command the directions both can (the SCARAs: x, y, z, yaw): a leader holding a rotation
  // the follower yields to would bend the object between them; the rest follows the joint reference
  const auto a = commandable_directions(*robots[0]), b = commandable_directions(*robots[1]);
  std::vector<std::string> common;
  for (int i = 0; i < kTaskAxes; ++i)
    if (a[i] && b[i]) common.push_back(task_axis_name(i));
  for (const Robot* r : robots) {
    arms_.push_back(std::make_shared<Arm>(common));
    arms_.back()->reset(*r, period);
  }
  Impedance imp(k_, d_, m_);
  imp.reset(*robots[1], period);
  // the follower's parameters by axis, as the impedance spreads them
  K_ = Md_ = D_ = Vec6::Zero();
  std::vector<int> order;
  for (int a = 0; a < kTaskAxes; ++a)
    if (arms_[1]->commanded()[a]) order.push_back(a);
  for (size_t j = 0; j < order.size(); ++j) {
    const auto pick = [&](const Eigen::VectorXd& v) { return v.size() == 1 ? v[0] : v[static_cast<Eigen::Index>(j)]; };
    K_[order[j]] = pick(k_);
    D_[order[j]] = pick(d_);
    Md_[order[j]] = pick(m_);
  }
  g_ = robots[0]->gravity_acceleration();
  lead_acc_.setZero();
  rel_.setZero();
}

void LeaderFollower::compute(double t, const std::vector<CoopMember>& m, const std::vector<double*>& tau) {
  if (arms_.size() != 2 || m.size() != 2) throw std::logic_error("LeaderFollower.compute called before reset()");
  require_holding(m);
  // the leader: task-space computed torque on its own reference, carrying what it feels
  const TaskState& sl = arms_[0]->observe(m[0].in);
  Vec6 al = Vec6::Zero();
  for (int i = 0; i < 6; ++i)
    if (sl.commanded[i]) al[i] = sl.accel_ref[i] + kd_ * sl.error_rate[i] + kp_ * sl.error[i];
  arms_[0]->torques(sl, al, sl.wrench, tau[0]);
  // the follower's reference: where the grips put it, given the leader's clamp position and its planned
  // orientation (the leader's own rotation errors, e.g. a wrist yielding, would swing the follower's
  // reference through the object's lever: the follower follows the leader's translation)
  const Eigen::Isometry3d G = m[0].grip * m[1].grip.inverse();  // follower TCP in the leader's TCP frame
  Eigen::Isometry3d lead = sl.pose_ref;
  lead.translation() = sl.pose.translation();
  TaskController::TaskReference ref;
  ref.pose = lead * G;
  Vec6 tw_l = to_world(sl, sl.velocity), acc_l = to_world(sl, al);
  const Vec6 tw_r = to_world(sl, sl.velocity_ref), acc_r = to_world(sl, sl.accel_ref);
  tw_l.tail<3>() = tw_r.tail<3>();
  acc_l.tail<3>() = acc_r.tail<3>();
  carry(tw_l, acc_l, ref.pose.translation() - lead.translation(), ref.twist, ref.accel);
  const TaskState& sf = arms_[1]->observe(m[1].in, &ref);
  rel_ = sf.error;
  // its impedance, driven by its sensed wrench less its share of the object's weight
  Vec6 weight = Vec6::Zero();
  weight.head<3>() = share_ * object_mass_ * g_;  // the share of the weight pulling on the follower's clamp
  const Vec6 ext = sf.external - to_task(sf, weight);
  Vec6 af = Vec6::Zero();
  for (int i = 0; i < 6; ++i)
    if (sf.commanded[i]) af[i] = sf.accel_ref[i] + (ext[i] + D_[i] * sf.error_rate[i] + K_[i] * sf.error[i]) / Md_[i];
  arms_[1]->torques(sf, af, sf.wrench, tau[1]);
  (void)t;
}

}  // namespace coopsim
