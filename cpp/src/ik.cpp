#include "coopsim/ik.hpp"
#include "internal.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <complex>
#include <random>
#include <sstream>

namespace coopsim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;
constexpr double kStructTol = 1e-9;  // structural parameters equal "exactly"
constexpr double kLimitTol = 1e-12;  // round-off allowed at a joint limit

bool angle_is(double a, double v) { return std::abs(std::remainder(a - v, kTwoPi)) < kStructTol; }
bool zero_or_pi(double a) { return angle_is(a, 0.0) || angle_is(a, kPi); }

using detail::num;

std::string joint_name(const Robot& r, int i) {
  const bool rev = r.links()[i].type == JointType::Revolute;
  return "joint " + std::to_string(i + 1) + " (" + (rev ? "theta" : "d") + std::to_string(i + 1) + ")";
}

std::string limits_str(const Link& L) {
  const bool rev = L.type == JointType::Revolute;
  const double f = rev ? 180.0 / kPi : 1.0;
  return "[" + num(L.q_min * f) + ", " + num(L.q_max * f) + "]" + (rev ? " deg" : " m");
}

std::string value_str(const Link& L, double q) {
  if (L.type == JointType::Revolute) return num(q) + " rad (" + num(q * 180.0 / kPi) + " deg)";
  return num(q) + " m";
}

// Brings joint i's value into its limits: revolute angles are shifted by
// 2 pi k to the admissible copy nearest `near`; prismatic values may only be
// rounded onto a limit. Returns an empty string, or why it is impossible.
std::string fit_joint(const Robot& r, int i, double& q, double near) {
  const Link& L = r.links()[i];
  if (L.type == JointType::Revolute) {
    // admissible k: q_min <= q + 2 pi k <= q_max
    const double lo = std::isfinite(L.q_min) ? std::ceil((L.q_min - kLimitTol - q) / kTwoPi) : -kInf;
    const double hi = std::isfinite(L.q_max) ? std::floor((L.q_max + kLimitTol - q) / kTwoPi) : kInf;
    if (lo > hi) {
      const double w = std::remainder(q, kTwoPi);
      return joint_name(r, i) + " would need " + value_str(L, w) + " (mod 360 deg), outside its limits " +
             limits_str(L);
    }
    double k = std::round((near - q) / kTwoPi);
    k = std::clamp(k, lo, hi);
    q += kTwoPi * k;
    q = std::clamp(q, L.q_min, L.q_max);  // moves it by round-off at most
    return "";
  }
  if (q < L.q_min - kLimitTol || q > L.q_max + kLimitTol)
    return joint_name(r, i) + " would need " + value_str(L, q) + ", outside its limits " + limits_str(L);
  q = std::clamp(q, L.q_min, L.q_max);
  return "";
}

Eigen::Isometry3d link_transform(const Link& L, double q) {
  const bool rev = L.type == JointType::Revolute;
  return dh_transform(L.dh.theta + (rev ? q : 0.0), L.dh.d + (rev ? 0.0 : q), L.dh.a, L.dh.alpha);
}

// Rx(-alpha) [a, 0, d]: where frame i's origin sits relative to frame i-1's
// z axis, seen from frame i (for a revolute joint i)
Eigen::Vector3d back_offset(const Link& L) {
  return Eigen::Vector3d(L.dh.a, L.dh.d * std::sin(L.dh.alpha), L.dh.d * std::cos(L.dh.alpha));
}

double angle_of(const Eigen::Matrix3d& Rz) { return std::atan2(Rz(1, 0), Rz(0, 0)); }

Eigen::Matrix3d rot_x(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()).toRotationMatrix(); }

// Frame-5 pose of the TCP with the jaw open by `opening` (tool on links 5, 6).
Eigen::Isometry3d clamp_tool(const Robot& r, double opening) {
  const Tool& t = r.tool();
  const Eigen::Isometry3d A6 = link_transform(r.links()[5], opening);
  auto F = [&](int link) { return link == 6 ? A6 : Eigen::Isometry3d::Identity(); };
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (F(t.link) * t.offset).linear();
  T.translation() = 0.5 * (F(t.link) * t.offset.translation() + F(t.second_link) * t.second_point);
  return T;
}

struct Candidate {
  VecN q;
  int branch;
};

void planar_error(double r, double reach_lo, double reach_hi, const char* point, std::string& why) {
  why = "target out of reach: the " + std::string(point) + " is " + num(r) +
        " m from the axis of joint 1, the arm reaches " + num(reach_lo) + " .. " + num(reach_hi) + " m";
}

// phi1, the angle of link 1 about joint 1 (rad): the wrist point's azimuth less the arm's own angle in the
// plane, or, with the wrist point on joint 1's axis (singular), q_near's; false (with why) without q_near.
bool joint1_angle(const Link& L0, bool on_axis, double azimuth_less_arm, const VecN* q_near, double& phi1,
                  std::string& why) {
  if (!on_axis) {
    phi1 = azimuth_less_arm;
    return true;
  }
  if (!q_near) {
    why = "singular target: the wrist point is on the axis of joint 1, so theta1 is undetermined "
          "(give q_near to choose it)";
    return false;
  }
  phi1 = (*q_near)[0] + L0.dh.theta;
  return true;
}

// SCARA #1, decoupled: wrist point -> theta1, theta2, d3; orientation -> theta4, theta5.
std::vector<Candidate> scara1_candidates(const Robot& r, const Eigen::Isometry3d& T5, const VecN* q_near,
                                         std::string& why) {
  const auto& L = r.links();
  const Eigen::Matrix3d R5 = T5.linear();
  // wrist point (frame 4 origin) and pitch axis z4 do not depend on theta5
  const Eigen::Vector3d o4 = T5.translation() - R5 * back_offset(L[4]);
  const Eigen::Vector3d z4 = R5 * Eigen::Vector3d(0, std::sin(L[4].dh.alpha), std::cos(L[4].dh.alpha));
  // z2 and z3 are vertical: sign from alpha2, alpha3
  const double c2a = std::cos(L[1].dh.alpha) > 0 ? 1.0 : -1.0, c3a = std::cos(L[2].dh.alpha) > 0 ? 1.0 : -1.0;
  const Eigen::Vector3d o3 = o4 - L[3].dh.d * (c2a * c3a) * Eigen::Vector3d::UnitZ();
  const double d3 = (o3.z() - (L[0].dh.d + L[1].dh.d)) * c2a - L[2].dh.d;
  const double a1 = L[0].dh.a, a2 = L[1].dh.a;
  const double x = o3.x(), y = o3.y(), rr = std::hypot(x, y);
  double c = (x * x + y * y - a1 * a1 - a2 * a2) / (2.0 * a1 * a2);
  if (c > 1.0 + 1e-12 || c < -1.0 - 1e-12) {
    planar_error(rr, std::abs(a1 - a2), a1 + a2, "wrist point", why);
    return {};
  }
  c = std::clamp(c, -1.0, 1.0);
  const double s_abs = std::sqrt(std::max(0.0, 1.0 - c * c));
  std::vector<Candidate> out;
  for (int branch : {+1, -1}) {
    const double s = branch * s_abs;
    const double phi2 = std::atan2(s, c);
    double phi1;
    if (!joint1_angle(L[0], rr < 1e-12 * (a1 + a2), std::atan2(y, x) - std::atan2(a2 * s, a1 + a2 * c), q_near,
                      phi1, why))
      return {};
    VecN q = VecN::Zero(6);
    q[0] = phi1 - L[0].dh.theta;
    q[1] = phi2 - L[1].dh.theta;
    q[2] = d3;
    const Eigen::Matrix3d R03 = (link_transform(L[0], q[0]) * link_transform(L[1], q[1]) *
                                 link_transform(L[2], q[2])).linear();
    // z4 seen from frame 3 is Rz(phi4) [0, -sin a4, cos a4]
    const Eigen::Vector3d z43 = R03.transpose() * z4;
    const double sa4 = std::sin(L[3].dh.alpha);
    const double phi4 = std::atan2(sa4 * z43.x(), -sa4 * z43.y());
    q[3] = phi4 - L[3].dh.theta;
    const Eigen::Matrix3d R04 = R03 * link_transform(L[3], q[3]).linear();
    q[4] = angle_of(R04.transpose() * R5 * rot_x(L[4].dh.alpha).transpose()) - L[4].dh.theta;
    out.push_back({q, branch});
  }
  return out;
}

// SCARA #2 through the homogeneous transforms, theta2 = theta3 = beta.
std::vector<Candidate> scara2_candidates(const Robot& r, const Eigen::Isometry3d& T5, const VecN* q_near,
                                         std::string& why, bool& redundancy) {
  const auto& L = r.links();
  const Eigen::Matrix3d R5 = T5.linear();
  const Eigen::Vector3d o4 = T5.translation() - R5 * back_offset(L[4]);
  // z3 is vertical; o4 = o3 + d4' z3 with o3 at height d1 + d2 + d3
  const double c3a = std::cos(L[2].dh.alpha) > 0 ? 1.0 : -1.0;
  const double d4 = (o4.z() - (L[0].dh.d + L[1].dh.d + L[2].dh.d)) * c3a - L[3].dh.d;
  const double a1 = L[0].dh.a, a2 = L[1].dh.a, a3 = L[2].dh.a;
  const double x = o4.x(), y = o4.y(), rr = std::hypot(x, y);
  const double reach_hi = a1 + a2 + a3;
  // the free arm (theta2 != theta3) reaches free_lo .. reach_hi
  const double free_lo = std::max({0.0, a1 - a2 - a3, a2 - a1 - a3, a3 - a1 - a2});
  // (checked first: r^2 below must not overflow)
  if (!(rr <= reach_hi * (1.0 + 1e-12))) {
    planar_error(rr, free_lo, reach_hi, "wrist point", why);
    return {};
  }
  const double r2 = rr * rr;
  // |a1 + a2 e^{i b} + a3 e^{2 i b}|^2 = r^2 is quadratic in c = cos b:
  //   4 a1 a3 c^2 + 2 a2 (a1 + a3) c + (a1 - a3)^2 + a2^2 - r^2 = 0
  const double A = 4.0 * a1 * a3, B = 2.0 * a2 * (a1 + a3), C = (a1 - a3) * (a1 - a3) + a2 * a2 - r2;
  const double disc = B * B - 4.0 * A * C;
  // smallest reach: the parabola's vertex if inside [-1, 1], else c = -1
  const double cv = -B / (2.0 * A);
  const double reach_lo =
      cv > -1.0 ? std::sqrt(std::max(0.0, C + r2 - B * B / (4.0 * A))) : std::abs(a1 - a2 + a3);
  // inside the free arm's reach but not with theta2 = theta3
  auto rule_error = [&] {
    why = "target out of reach with theta2 = theta3 (the closed form's redundancy rule): the wrist point is " +
          num(rr) + " m from the axis of joint 1, the arm so constrained reaches " + num(reach_lo) + " .. " +
          num(reach_hi) + " m; the free arm reaches from " + num(free_lo) +
          " m (method='numeric' or 'auto' without a branch solves it with theta2 != theta3)";
    redundancy = rr >= free_lo;
  };
  if (disc < -1e-12 * B * B) {
    rule_error();
    return {};
  }
  const double sq = std::sqrt(std::max(0.0, disc));
  // stable roots: larger (the unfolded family) and smaller (folded, near the base)
  const double qq = -0.5 * (B + sq);
  double roots[2] = {qq != 0.0 ? C / qq : cv, qq / A};
  if (roots[0] < roots[1]) std::swap(roots[0], roots[1]);
  std::vector<Candidate> out;
  for (int family = 0; family < 2; ++family) {
    double c = roots[family];
    if (family == 1 && sq == 0.0) break;  // double root: one family
    if (c > 1.0 + 1e-12 || c < -1.0 - 1e-12) continue;
    c = std::clamp(c, -1.0, 1.0);
    const double b_abs = std::acos(c);
    for (int sign : {+1, -1}) {
      const double beta = sign * b_abs;
      const std::complex<double> P = a1 + a2 * std::polar(1.0, beta) + a3 * std::polar(1.0, 2.0 * beta);
      double phi1;
      if (!joint1_angle(L[0], rr < 1e-12 * reach_hi || std::abs(P) < 1e-12 * reach_hi,
                        std::atan2(y, x) - std::arg(P), q_near, phi1, why))
        return {};
      VecN q = VecN::Zero(6);
      q[0] = phi1 - L[0].dh.theta;
      q[1] = beta;
      q[2] = beta;
      q[3] = d4;
      const Eigen::Matrix3d R04 = (link_transform(L[0], q[0]) * link_transform(L[1], q[1]) *
                                   link_transform(L[2], q[2]) * link_transform(L[3], q[3])).linear();
      q[4] = angle_of(R04.transpose() * R5 * rot_x(L[4].dh.alpha).transpose()) - L[4].dh.theta;
      out.push_back({q, sign * (family + 1)});
    }
  }
  if (out.empty()) rule_error();
  return out;
}

}  // namespace

void pose_error(const Eigen::Isometry3d& T, const Eigen::Isometry3d& target, double& position, double& angle) {
  position = (T.translation() - target.translation()).norm();
  const Eigen::Matrix3d D = target.linear().transpose() * T.linear();
  // robust angle: atan2 of the sine (skew part) and cosine (trace)
  const Eigen::Vector3d v(D(2, 1) - D(1, 2), D(0, 2) - D(2, 0), D(1, 0) - D(0, 1));
  angle = std::atan2(0.5 * v.norm(), 0.5 * (D.trace() - 1.0));
}

AnalyticKind analytic_kind(const Robot& robot, std::string* why) {
  auto no = [&](const std::string& w) {
    if (why) *why = w;
    return AnalyticKind::None;
  };
  const std::string types = robot.joint_types();
  const auto& L = robot.links();
  const Tool& t = robot.tool();
  if (types != "RRPRRP" && types != "RRRPRP")
    return no("joint types are " + types + ", not RRPRRP (SCARA #1) or RRRPRP (SCARA #2)");
  if ((t.link != 5 && t.link != 6) || (t.second_link != 5 && t.second_link != 6))
    return no("the tool must sit on links 5 and 6 (clamp body and moving jaw)");
  if (!angle_is(L[0].dh.alpha, 0.0)) return no("alpha1 must be 0 (horizontal arm)");
  if (types == "RRPRRP") {
    if (!zero_or_pi(L[1].dh.alpha)) return no("alpha2 must be 0 or pi (vertical quill)");
    if (std::abs(L[2].dh.a) > kStructTol || !zero_or_pi(L[2].dh.alpha))
      return no("joint 3 must be a vertical quill (a3 = 0, alpha3 = 0 or pi)");
    if (std::abs(L[3].dh.a) > kStructTol) return no("a4 must be 0 (yaw axis on the quill)");
    if (std::abs(std::sin(L[3].dh.alpha)) < 1e-6) return no("alpha4 must not be 0 or pi (pitch axis not vertical)");
    if (!(L[0].dh.a > 0 && L[1].dh.a > 0)) return no("a1 and a2 must be > 0");
    return AnalyticKind::Scara1;
  }
  if (!angle_is(L[1].dh.alpha, 0.0)) return no("alpha2 must be 0 (horizontal arm)");
  if (!zero_or_pi(L[2].dh.alpha)) return no("alpha3 must be 0 or pi (vertical quill)");
  if (!angle_is(L[1].dh.theta, 0.0) || !angle_is(L[2].dh.theta, 0.0))
    return no("theta offsets of joints 2 and 3 must be 0 (the redundancy is resolved by theta2 = theta3)");
  if (std::abs(L[3].dh.a) > kStructTol || !zero_or_pi(L[3].dh.alpha))
    return no("joint 4 must be a vertical quill (a4 = 0, alpha4 = 0 or pi)");
  if (!(L[0].dh.a > 0 && L[1].dh.a >= 0 && L[2].dh.a > 0)) return no("a1, a3 must be > 0 and a2 >= 0");
  return AnalyticKind::Scara2;
}

std::vector<IKSolution> analytic_ik_all(const Robot& robot, const Eigen::Isometry3d& target,
                                        const AnalyticIKOptions& opt) {
  std::string why;
  const AnalyticKind kind = analytic_kind(robot, &why);
  if (kind == AnalyticKind::None) throw std::invalid_argument("no closed-form IK for this robot: " + why);
  if (!target.matrix().allFinite()) throw std::invalid_argument("target must be finite");
  if (!std::isfinite(opt.opening)) throw std::invalid_argument("opening must be finite");
  if (opt.q_near && (opt.q_near->size() != 6 || !opt.q_near->allFinite()))
    throw std::invalid_argument("q_near must be 6 finite numbers");
  const Link& jaw = robot.links()[5];
  if (opt.opening < jaw.q_min - kLimitTol || opt.opening > jaw.q_max + kLimitTol)
    throw IKError("jaw opening d6 = " + num(opt.opening) + " m is outside its limits " + limits_str(jaw));
  const double opening = std::clamp(opt.opening, jaw.q_min, jaw.q_max);

  // frame-5 target in the base frame
  const Eigen::Isometry3d T0 = robot.base().inverse() * target;
  const Eigen::Isometry3d T5 = T0 * clamp_tool(robot, opening).inverse();
  bool redundancy = false;
  std::vector<Candidate> cands = kind == AnalyticKind::Scara1
                                     ? scara1_candidates(robot, T5, opt.q_near, why)
                                     : scara2_candidates(robot, T5, opt.q_near, why, redundancy);
  if (cands.empty()) throw IKError(why, redundancy);

  std::vector<IKSolution> sols;
  std::vector<std::string> failures;
  Workspace ws;
  for (auto& c : cands) {
    if (opt.branch != 0 && c.branch != opt.branch) continue;
    c.q[5] = opening;
    std::string err;
    int i = 0;
    for (; i < 6 && err.empty(); ++i) err = fit_joint(robot, i, c.q[i], opt.q_near ? (*opt.q_near)[i] : 0.0);
    const std::string tag = "branch " + std::string(c.branch > 0 ? "+" : "") + std::to_string(c.branch) + ": ";
    if (!err.empty()) {
      failures.push_back(tag + err);
      // SCARA #2: the angles 1, 2, 3 and 5 depend on the theta2 = theta3 rule
      if (kind == AnalyticKind::Scara2 && i - 1 != 3 && i - 1 != 5) redundancy = true;
      continue;
    }
    robot.kinematics(c.q.data(), ws);
    IKSolution s{c.q, c.branch, 0.0, 0.0};
    pose_error(robot.tool_pose(ws), target, s.position_error, s.orientation_error);
    if (!(s.orientation_error <= opt.tol)) {
      failures.push_back(tag + "target orientation not reachable (off by " + num(s.orientation_error) +
                         " rad): " +
                         (kind == AnalyticKind::Scara1
                              ? "SCARA #1's clamp can only yaw about the vertical and pitch about its jaw axis"
                              : "SCARA #2's clamp points straight down and can only yaw about the vertical"));
      continue;
    }
    if (!(s.position_error <= opt.tol)) {
      failures.push_back(tag + "position residual " + num(s.position_error) + " m exceeds tol");
      continue;
    }
    sols.push_back(s);
  }
  if (sols.empty()) {
    if (failures.empty())
      throw IKError("no solution on branch " + std::to_string(opt.branch) + " (" +
                    (kind == AnalyticKind::Scara1 ? "SCARA #1 has branches +1, -1" : "SCARA #2 has branches +-1, +-2 (folded, near the base)") + ")");
    std::string msg = "no inverse kinematics solution within the limits: ";
    for (size_t i = 0; i < failures.size(); ++i) msg += (i ? "; " : "") + failures[i];
    if (redundancy) msg += " (with theta2 = theta3; method='numeric' may find one with theta2 != theta3)";
    throw IKError(msg, redundancy);
  }
  if (opt.q_near) {
    std::stable_sort(sols.begin(), sols.end(), [&](const IKSolution& a, const IKSolution& b) {
      return (a.q - *opt.q_near).squaredNorm() < (b.q - *opt.q_near).squaredNorm();
    });
  }
  return sols;
}

IKSolution analytic_ik(const Robot& robot, const Eigen::Isometry3d& target, const AnalyticIKOptions& options) {
  return analytic_ik_all(robot, target, options).front();
}

NumericIKResult numeric_ik(const Robot& robot, const Eigen::Isometry3d& target, const VecN& q0,
                           const NumericIKOptions& opt) {
  const int n = robot.dof();
  if (q0.size() != n || !q0.allFinite()) throw std::invalid_argument("q0 must be n finite numbers");
  if (!target.matrix().allFinite()) throw std::invalid_argument("target must be finite");
  if (!(opt.tol > 0) || opt.max_iterations < 1 || opt.restarts < 0 || !(opt.length > 0))
    throw std::invalid_argument("tol and length must be > 0, max_iterations >= 1, restarts >= 0");
  std::array<double, 6> w = opt.weights;
  bool any = false;
  for (int k = 0; k < 6; ++k) {
    if (!(w[k] >= 0) || !std::isfinite(w[k])) throw std::invalid_argument("weights must be finite and >= 0");
    any = any || w[k] > 0;
  }
  if (!any) throw std::invalid_argument("weights must not all be 0");
  std::vector<bool> free(n, true);
  for (int i : opt.locked) {
    if (i < 0 || i >= n) throw std::invalid_argument("locked joint index " + std::to_string(i) + " out of range");
    free[i] = false;
  }
  Eigen::Matrix<double, 6, 1> W;
  for (int k = 0; k < 6; ++k) W[k] = w[k] * (k < 3 ? 1.0 : opt.length);

  const VecN qmin = robot.q_min(), qmax = robot.q_max();
  if (w[0] > 0 && w[1] > 0 && w[2] > 0) {
    // no point of the robot gets further from its base than the sum of its
    // links' offsets and strokes plus the tool's offset
    double reach = std::max(robot.tool().offset.translation().norm(), robot.tool().second_point.norm());
    for (int i = 0; i < n; ++i) {
      const Link& L = robot.links()[i];
      reach += std::abs(L.dh.a) + std::abs(L.dh.d);
      if (L.type == JointType::Prismatic) reach += std::max(std::abs(L.q_min), std::abs(L.q_max));
    }
    const double dist = (robot.base().inverse() * target).translation().stableNorm();
    if (dist > reach * (1.0 + 1e-9) + 1e-12)
      throw IKError("target out of reach: it is " + num(dist) + " m from the robot's base, and no point of the "
                    "robot gets further than " + num(reach) + " m (sum of link offsets, strokes and the tool)");
  }
  // into the limits: a revolute joint first tries the same angle 2 pi k away
  // (a +-180 deg limit is no wall), then clamps
  auto project = [&](VecN& q) {
    for (int i = 0; i < n; ++i) {
      if (robot.links()[i].type == JointType::Revolute && (q[i] < qmin[i] || q[i] > qmax[i])) {
        const double k = std::round((0.5 * (qmin[i] + qmax[i]) - q[i]) / kTwoPi);
        if (std::isfinite(k)) {
          const double w = q[i] + kTwoPi * k;
          if (w >= qmin[i] && w <= qmax[i]) q[i] = w;
        }
      }
      q[i] = std::clamp(q[i], qmin[i], qmax[i]);
    }
  };
  Workspace ws;
  Mat6N J;
  // weighted error (6,) and the unweighted residual norms of the weighted components
  auto error = [&](const VecN& q, Eigen::Matrix<double, 6, 1>& e, double& pe, double& re) {
    robot.kinematics(q.data(), ws);
    const Eigen::Isometry3d T = robot.tool_pose(ws);
    e.head<3>() = target.translation() - T.translation();
    const Eigen::AngleAxisd aa(target.linear() * T.linear().transpose());
    e.tail<3>() = aa.angle() * aa.axis();
    double p2 = 0, r2 = 0;
    for (int k = 0; k < 6; ++k)
      if (w[k] > 0) (k < 3 ? p2 : r2) += e[k] * e[k];
    pe = std::sqrt(p2);
    re = std::sqrt(r2);
    e = W.cwiseProduct(e);
  };

  std::mt19937_64 rng(opt.seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  NumericIKResult best;
  best.position_error = best.orientation_error = kInf;
  double best_cost = kInf;
  int total_it = 0;
  for (int attempt = 0; attempt <= opt.restarts; ++attempt) {
    VecN q = q0;
    if (attempt > 0) {
      for (int i = 0; i < n; ++i) {
        if (!free[i]) continue;
        const bool rev = robot.links()[i].type == JointType::Revolute;
        const double lo = std::isfinite(qmin[i]) ? qmin[i] : (rev ? -kPi : q0[i] - 1.0);
        const double hi = std::isfinite(qmax[i]) ? qmax[i] : (rev ? kPi : q0[i] + 1.0);
        q[i] = lo + (hi - lo) * U(rng);
      }
    }
    project(q);
    Eigen::Matrix<double, 6, 1> e, e_new;
    double pe, re, pe_new, re_new;
    error(q, e, pe, re);
    double lambda = 1e-3;
    int polish = 0;
    for (int it = 0; it < opt.max_iterations; ++it) {
      // once within tol, two more Gauss-Newton-like steps take it to round-off
      if (pe < opt.tol && re < opt.tol && ++polish > 2) break;
      ++total_it;
      robot.tool_jacobian(ws, J);  // ws holds the kinematics of q
      Mat6N JW = W.asDiagonal() * J;
      for (int i = 0; i < n; ++i)
        if (!free[i]) JW.col(i).setZero();
      MatN H = JW.transpose() * JW;
      const VecN g = JW.transpose() * e;
      const double scale = std::max(H.diagonal().maxCoeff(), 1e-12);
      bool improved = false;
      while (lambda < 1e10) {
        MatN A = H;
        A.diagonal().array() += lambda * scale;
        VecN q_new = q + A.ldlt().solve(g);
        project(q_new);
        error(q_new, e_new, pe_new, re_new);
        if (e_new.squaredNorm() < e.squaredNorm()) {
          q = q_new;
          e = e_new;
          pe = pe_new;
          re = re_new;
          lambda = std::max(lambda / 5.0, 1e-12);
          improved = true;
          break;
        }
        lambda *= 4.0;
      }
      robot.kinematics(q.data(), ws);
      if (!improved) break;  // stuck: a local minimum or a limit
    }
    const double cost = e.squaredNorm();
    if (cost < best_cost || attempt == 0) {
      best_cost = cost;
      best.q = q;
      best.position_error = pe;
      best.orientation_error = re;
    }
    if (pe < opt.tol && re < opt.tol) {
      // shift free angles by 2 pi k towards q0 where the limits allow
      for (int i = 0; i < n; ++i) {
        if (robot.links()[i].type == JointType::Revolute) fit_joint(robot, i, best.q[i], q0[i]);
      }
      best.iterations = total_it;
      best.attempts = attempt + 1;
      robot.kinematics(best.q.data(), ws);
      Eigen::Matrix<double, 6, 1> e_fit;
      error(best.q, e_fit, best.position_error, best.orientation_error);
      return best;
    }
  }
  std::string at_limits;
  for (int i = 0; i < n; ++i) {
    if (!free[i]) continue;
    const Link& L = robot.links()[i];
    if (best.q[i] <= qmin[i] || best.q[i] >= qmax[i])
      at_limits += (at_limits.empty() ? "" : ", ") + joint_name(robot, i) + " = " + value_str(L, best.q[i]) +
                   " at its " + (best.q[i] <= qmin[i] ? "lower" : "upper") + " limit";
  }
  throw IKError("numeric IK found no configuration within the joint limits reaching the target after " +
                std::to_string(opt.restarts + 1) + " attempts: best residual " + num(best.position_error) +
                " m, " + num(best.orientation_error) + " rad (tol " + num(opt.tol) + ")" +
                (at_limits.empty() ? "" : "; " + at_limits) + " - the target is probably unreachable");
}

}  // namespace coopsim
