// Two holders of one body (held_body.hpp): the grasp matrix, the external and internal wrenches, the
// load shares, the clamps' relative pose error; the log's columns of a pair of robots and the log
// stage's part that writes them (Simulation::cooperation_row_), and Simulation::cooperation.
#include "coopsim/held_body.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "coopsim/simulation.hpp"
#include "internal.hpp"

#include "stages.hpp"

namespace coopsim {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kSamePoint = 1e-9;  // m: points closer count as one

}  // namespace

Eigen::Matrix<double, 6, 12> grasp_matrix(const Eigen::Vector3d& c, const Eigen::Vector3d& pa,
                                          const Eigen::Vector3d& pb) {
  Eigen::Matrix<double, 6, 12> W = Eigen::Matrix<double, 6, 12>::Zero();
  const Eigen::Vector3d* p[2] = {&pa, &pb};
  for (int k = 0; k < 2; ++k) {
    W.block<3, 3>(0, 6 * k).setIdentity();
    W.block<3, 3>(3, 6 * k + 3).setIdentity();
    W.block<3, 3>(3, 6 * k) = detail::skew(*p[k] - c);
  }
  return W;
}

Cooperation cooperation(const Eigen::Vector3d& centre, const Eigen::Vector3d& pa, const Vec6& ha,
                        const Eigen::Vector3d& pb, const Vec6& hb, const Eigen::Vector3d& up) {
  Cooperation out;
  out.centre = centre;
  out.point_a = pa;
  out.point_b = pb;
  const Eigen::Vector3d fa = ha.head<3>(), ma = ha.tail<3>(), fb = hb.head<3>(), mb = hb.tail<3>();
  // h_c = sum_k W_k h_k
  out.external.head<3>() = fa + fb;
  out.external.tail<3>() = ma + mb + (pa - centre).cross(fa) + (pb - centre).cross(fb);
  const Eigen::Vector3d d = pb - pa;
  const double L = d.norm();
  if (!(L >= kSamePoint)) {
    // one point: forces and moments each split evenly, the rest is internal
    const Vec6 half = 0.5 * (ha - hb);
    out.internal << half, -half;
    out.squeeze = out.twist = out.shear = kNaN;
    out.bending.setConstant(kNaN);
  } else {
    const Eigen::Vector3d e = d / L, sum = ma + mb;
    const double m = 0.5 * sum.dot(e);
    out.squeeze = 0.5 * (fa - fb).dot(e);
    const Eigen::Vector3d across = e.cross(sum) / L;
    const Eigen::Vector3d t = out.squeeze * e - across;
    out.internal << t, ma - m * e, -t, mb - m * e;
    out.twist = 0.5 * (ma - mb).dot(e);
    out.shear = across.norm();
    out.bending << (ma - ma.dot(e) * e).norm(), (mb - mb.dot(e) * e).norm();
  }
  const double up_norm = up.norm();
  if (!(up_norm > 0) || !std::isfinite(up_norm)) throw std::invalid_argument("up must be a finite nonzero vector");
  const double fa_up = fa.dot(up) / up_norm, fb_up = fb.dot(up) / up_norm, total = fa_up + fb_up;
  if (total != 0.0)
    out.load_share << fa_up / total, fb_up / total;
  else
    out.load_share.setConstant(kNaN);
  return out;
}

Vec6 relative_pose_error(const Eigen::Isometry3d& Ta, const Eigen::Isometry3d& Tb, const Eigen::Isometry3d& X0) {
  const Eigen::Isometry3d expected = Ta * X0;
  Vec6 out;
  out.head<3>() = Tb.translation() - expected.translation();
  const Eigen::AngleAxisd r(Tb.linear() * expected.linear().transpose());
  out.tail<3>() = r.angle() * r.axis();
  return out;
}

const std::array<CooperationColumn, kCooperationColumns>& cooperation_schema() {
  static const std::array<CooperationColumn, kCooperationColumns> schema = {{
      {"body", 1, "world id of the body both robots hold (-1: none; every other value NaN then)"},
      {"centre", 3, "the body's centre of mass c (m, world)"},
      {"point_a", 3, "robot a's weld point p_a on the body (m, world)"},
      {"point_b", 3, "robot b's weld point p_b on the body (m, world)"},
      {"external", 6, "net wrench of both welds on the body about c, W [h_a; h_b] (N, N m)"},
      {"internal", 12, "internal wrench [f_a; mu_a; f_b; mu_b], each about its weld point (N, N m)"},
      {"squeeze", 1, "internal force along the line p_a -> p_b, > 0 pushing the body together (N)"},
      {"twist", 1, "internal moment about that line, a's (N m)"},
      {"bending", 2, "each weld's moment across the line, magnitude, a and b (N m)"},
      {"shear", 1, "internal force across the line, magnitude (N)"},
      {"load_share", 2, "a's and b's part of the vertical (against gravity) load"},
      {"relative_pose_error", 6, "b's pose against a's since the second weld attached: dp (m), rotation vector "
                                 "(rad), world axes"},
  }};
  return schema;
}

void cooperation_row(int body, const Cooperation* c, double* row) {
  row[0] = c ? static_cast<double>(body) : -1.0;
  if (!c) {
    std::fill(row + 1, row + kCooperationWidth, kNaN);
    return;
  }
  double* p = row + 1;
  auto put = [&p](const auto& v) {
    for (int i = 0; i < v.size(); ++i) *p++ = v[i];
  };
  put(c->centre);
  put(c->point_a);
  put(c->point_b);
  put(c->external);
  put(c->internal);
  *p++ = c->squeeze;
  *p++ = c->twist;
  put(c->bending);
  *p++ = c->shear;
  put(c->load_share);
  put(c->relative_pose_error);
}

// ---- the simulation's side ----

namespace stages {

namespace {

// Robot i's clamp frame: the clamp link's orientation at the weld's point (kinematics at its q).
Eigen::Isometry3d clamp_frame(const Robot& r, RobotData& s) {
  r.kinematics(s.state.q.data(), s.ws, false);
  Eigen::Isometry3d T = r.frame(s.ws, r.clamp().fixed_link);
  T.translation() = T * s.grasp.anchor_link;
  return T;
}

}  // namespace

BodyState body_state(const Model& m, const Data& d, int id) {
  (void)m;
  if (!d.world) throw std::invalid_argument("the simulation has no world");
  const BodySpec& b = d.world->body(id);
  if (b.kind == BodyKind::Link) throw std::invalid_argument("body '" + b.name + "' is a robot's link: see the robot's state");
  if (b.kind == BodyKind::Free && d.world_at >= 0) {
    for (size_t k = 0; k < d.free_ids.size(); ++k)
      if (d.free_ids[k] == id) return d.body_now[k];
  }
  return d.world->state(id);
}

bool cooperation(const Model& m, Data& d, PairData& pair, Cooperation& out) {
  RobotData& a = d.robots[pair.a];
  RobotData& b = d.robots[pair.b];
  if (!d.world || a.grasp.held < 0 || a.grasp.held != b.grasp.held) return false;
  const int id = a.grasp.held;
  const BodyState st = body_state(m, d, id);
  const Eigen::Vector3d g = d.world->options().gravity;
  const Eigen::Vector3d up = g.squaredNorm() > 0 ? Eigen::Vector3d(-g.normalized()) : Eigen::Vector3d::UnitZ();
  out = coopsim::cooperation(st.pose.translation(), st.pose * a.grasp.anchor_body, a.grasp.weld,
                             st.pose * b.grasp.anchor_body, b.grasp.weld, up);
  const Eigen::Isometry3d Ta = clamp_frame(m.robots[pair.a].robot, a), Tb = clamp_frame(m.robots[pair.b].robot, b);
  if (!pair.attached) {  // a hold that began before this pair was looked at: from now
    pair.X0 = Ta.inverse() * Tb;
    pair.attached = true;
  }
  out.relative_pose_error = relative_pose_error(Ta, Tb, pair.X0);
  return true;
}

void pairs_attach(const Model& m, Data& d, int i) {
  for (PairData& p : d.pairs) {
    if (p.a != i && p.b != i) continue;
    RobotData& a = d.robots[p.a];
    RobotData& b = d.robots[p.b];
    p.attached = false;
    if (a.grasp.held >= 0 && a.grasp.held == b.grasp.held) {
      p.X0 = clamp_frame(m.robots[p.a].robot, a).inverse() * clamp_frame(m.robots[p.b].robot, b);
      p.attached = true;
    }
  }
}

}  // namespace stages

namespace {

PairData& pair_of(SimulationData& d, int n, int a, int b) {
  if (a < 0 || a >= n || b < 0 || b >= n || a >= b)
    throw std::invalid_argument("cooperation: robots a < b in [0, " + std::to_string(n) + ") expected, got a = " +
                                std::to_string(a) + ", b = " + std::to_string(b));
  for (PairData& p : d.pairs)
    if (p.a == a && p.b == b) return p;
  throw std::logic_error("cooperation: no pair");  // every pair a < b is made with the robots
}

}  // namespace

Cooperation Simulation::cooperation(int a, int b, bool* holding) {
  const Entry driving = enter_();  // one driver at a time
  PairData& p = pair_of(data_, robot_count(), a, b);
  Cooperation out;
  const bool both = stages::cooperation(*model_, data_, p, out);
  if (holding) *holding = both;
  return out;
}

const LogColumn& Simulation::cooperation_log(int a, int b) { return pair_of(data_, robot_count(), a, b).log; }

}  // namespace coopsim
