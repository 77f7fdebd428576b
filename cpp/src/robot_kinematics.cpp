// The serial robot's kinematics (robot.hpp): DH frames at q, link and tool frames, Jacobians of points
// on links and of the tool, the tool's bias acceleration (Jdot qd), poses of many states.
#include "coopsim/robot.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "internal.hpp"

namespace coopsim {

namespace {

using detail::require;

}  // namespace

void Robot::kinematics(const double* q, Workspace& ws, bool inertia) const {
  const int level = inertia ? 2 : 1;
  const bool same = ws.kin_robot == kinematics_id_ && ws.n == n_ &&
                    std::memcmp(q, ws.kin_q.data(), sizeof(double) * static_cast<size_t>(n_)) == 0;
  if (same && ws.kin_level >= level) return;  // already there, bit for bit
  if (!same) {                                // the frames at q
    ws.kin_robot = kinematics_id_;
    ws.kin_level = 1;
    ws.M_valid = false;
    std::memcpy(ws.kin_q.data(), q, sizeof(double) * static_cast<size_t>(n_));
    ws.n = n_;
    ws.R[0] = base_.linear();
    ws.o[0] = base_.translation();
    for (int k = 0; k < n_; ++k) {
      const Link& L = links_[k];
      const Pre& P = pre_[k];
      double ct = P.ct, st = P.st, d = L.dh.d;
      if (L.type == JointType::Revolute) {
        ::sincos(L.dh.theta + q[k], &st, &ct);
      } else {
        d += q[k];
      }
      const double ca = P.ca, sa = P.sa, a = L.dh.a;
      Eigen::Matrix3d Rl;
      Rl << ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0, sa, ca;
      const Eigen::Vector3d pl(a * ct, a * st, d);
      ws.o[k + 1].noalias() = ws.o[k] + ws.R[k] * pl;
      ws.R[k + 1].noalias() = ws.R[k] * Rl;
    }
  }
  if (!inertia) return;
  for (int k = 0; k < n_; ++k) {  // the centres of mass and world inertias, from the frames
    const Pre& P = pre_[k];
    ws.c[k].noalias() = ws.o[k + 1] + ws.R[k + 1] * P.p_com;
    const Eigen::Matrix3d RI = ws.R[k + 1] * P.I_local;
    ws.Iw[k].noalias() = RI * ws.R[k + 1].transpose();
  }
  ws.kin_level = 2;
}

void Robot::poses_of_states(const double* Q, long N, PosesOf what, std::vector<Eigen::Isometry3d>& out) const {
  Workspace ws;
  std::vector<Eigen::Isometry3d> T;
  out.clear();
  const size_t per = what == PosesOf::kBoxes ? boxes_.size() : what == PosesOf::kFrames ? n_ + 1 : 1;
  out.reserve(static_cast<size_t>(N) * per);
  for (long i = 0; i < N; ++i) {
    kinematics(Q + i * n_, ws, false);  // the frames only
    if (what == PosesOf::kTool) {
      out.push_back(tool_pose(ws));
    } else if (what == PosesOf::kFrames) {
      for (int j = 0; j <= n_; ++j) out.push_back(frame(ws, j));
    } else {
      box_poses(ws, T);
      out.insert(out.end(), T.begin(), T.end());
    }
  }
}

Eigen::Isometry3d Robot::frame(const Workspace& ws, int i) const {
  const int l = link_index_(i, "frame");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = ws.R[l];
  T.translation() = ws.o[l];
  return T;
}

Eigen::Isometry3d Robot::com_frame(const Workspace& ws, int i) const {
  const int l = link_index_(i, "link");
  require(l >= 1, "com_frame: link must be 1..n (the base has no CoM frame)");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = ws.R[l] * pre_[l - 1].R_com;
  T.translation() = ws.c[l - 1];
  return T;
}

Eigen::Isometry3d Robot::tool_pose(const Workspace& ws) const {
  Eigen::Isometry3d T = frame(ws, tool_.link) * tool_.offset;
  const Eigen::Vector3d pb = ws.o[tool_.second_link] + ws.R[tool_.second_link] * tool_.second_point;
  T.translation() = 0.5 * (T.translation() + pb);
  return T;
}

void Robot::jacobian(const Workspace& ws, int link, const Eigen::Vector3d& point, Mat6N& J) const {
  const int l = link_index_(link, "link");
  J.setZero(6, n_);
  if (l == 0) return;
  const Eigen::Vector3d p = ws.o[l] + ws.R[l] * point;
  for (int j = 0; j < l; ++j) {
    const Eigen::Vector3d z = ws.R[j].col(2);
    if (links_[j].type == JointType::Revolute) {
      J.col(j).head<3>() = z.cross(p - ws.o[j]);
      J.col(j).tail<3>() = z;
    } else {
      J.col(j).head<3>() = z;
    }
  }
}

void Robot::tool_jacobian(const Workspace& ws, Mat6N& J) const {
  Mat6N Jb;
  jacobian(ws, tool_.link, tool_.offset.translation(), J);
  jacobian(ws, tool_.second_link, tool_.second_point, Jb);
  J.topRows<3>() = 0.5 * (J.topRows<3>() + Jb.topRows<3>());
}

// d/dt of a point's Jacobian columns times qd. Frame j's angular velocity w_j and origin velocity
// v_j by the forward recursion (joint j+1 turns or slides along z_j through o_j); for column j,
// with zd_j = w_j x z_j: revolute  [zd_j x (p - o_j) + z_j x (pd - v_j); zd_j],  prismatic
// [zd_j; 0].
//
// link_velocities: the recursion's w_j, v_j up to link l.
using Velocities = std::array<Eigen::Vector3d, kMaxDof + 1>;
static void link_velocities(const Workspace& ws, const std::vector<Link>& links, int l, const double* qd,
                            Velocities& w, Velocities& v) {
  w[0].setZero();
  v[0].setZero();
  for (int j = 0; j < l; ++j) {
    const Eigen::Vector3d z = ws.R[j].col(2);
    const bool revolute = links[j].type == JointType::Revolute;
    w[j + 1] = revolute ? Eigen::Vector3d(w[j] + qd[j] * z) : w[j];
    v[j + 1] = v[j] + w[j + 1].cross(ws.o[j + 1] - ws.o[j]);
    if (!revolute) v[j + 1] += qd[j] * z;
  }
}

// The bias of point p of link l from the velocities of link_velocities (computed at least up to l).
static void point_bias(const Workspace& ws, const std::vector<Link>& links, int l, const Eigen::Vector3d& p,
                       const double* qd, const Velocities& w, const Velocities& v, Eigen::Vector3d& lin,
                       Eigen::Vector3d& ang) {
  const Eigen::Vector3d pd = v[l] + w[l].cross(p - ws.o[l]);
  lin.setZero();
  ang.setZero();
  for (int j = 0; j < l; ++j) {
    const Eigen::Vector3d z = ws.R[j].col(2);
    const Eigen::Vector3d zd = w[j].cross(z);
    if (links[j].type == JointType::Revolute) {
      lin += qd[j] * (zd.cross(p - ws.o[j]) + z.cross(pd - v[j]));
      ang += qd[j] * zd;
    } else {
      lin += qd[j] * zd;
    }
  }
}

void Robot::tool_bias(const Workspace& ws, const double* qd, Vec6& out) const {
  const int la = link_index_(tool_.link, "tool link"), lb = link_index_(tool_.second_link, "tool second link");
  Velocities w, v;  // one recursion serves both points
  link_velocities(ws, links_, std::max(la, lb), qd, w, v);
  Eigen::Vector3d lin_a, ang_a, lin_b, ang_b;
  point_bias(ws, links_, la, ws.o[la] + ws.R[la] * tool_.offset.translation(), qd, w, v, lin_a, ang_a);
  point_bias(ws, links_, lb, ws.o[lb] + ws.R[lb] * tool_.second_point, qd, w, v, lin_b, ang_b);
  out.head<3>() = 0.5 * (lin_a + lin_b);
  out.tail<3>() = ang_a;
}

}  // namespace coopsim
