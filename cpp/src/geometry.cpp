// Link geometry: the boxes fixed to a robot's links and its clamp.
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "coopsim/robot.hpp"

namespace coopsim {

namespace {

void require(bool ok, const std::string& msg) {
  if (!ok) throw std::invalid_argument(msg);
}

bool rigid(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) return false;
  const Eigen::Matrix3d R = T.linear();
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9 && R.determinant() > 0;
}

// A box of square section t around the segment from a to b (frame
// coordinates), at least t long.
LinkBox segment_box(int link, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t, std::string name) {
  LinkBox box;
  box.link = link;
  box.name = std::move(name);
  const Eigen::Vector3d d = b - a;
  const double len = d.norm();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  if (len > 1e-12) {
    // x along the segment; y, z any orthonormal completion
    const Eigen::Vector3d x = d / len;
    const Eigen::Vector3d helper = std::abs(x.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d y = helper.cross(x).normalized();
    R.col(0) = x;
    R.col(1) = y;
    R.col(2) = x.cross(y);
  }
  box.pose = Eigen::Isometry3d::Identity();
  box.pose.linear() = R;
  box.pose.translation() = 0.5 * (a + b);
  box.half_extents = Eigen::Vector3d(0.5 * std::max(len, t), 0.5 * t, 0.5 * t);
  return box;
}

}  // namespace

std::vector<LinkBox> Robot::default_boxes() const {
  const double t = kDefaultLinkThickness;
  std::vector<LinkBox> out;
  if (base_p_.z() > t) {
    // a column from the floor to the base frame's origin, in frame 0
    out.push_back(segment_box(0, Eigen::Vector3d(0, 0, -base_p_.z()), Eigen::Vector3d::Zero(), t, "base"));
  }
  for (int k = 0; k < n_; ++k) {
    const Link& L = links_[k];
    const Eigen::Vector3d foot(-L.dh.a, 0, 0);  // on joint axis k+1, in frame k+1
    Eigen::Vector3d from = foot;
    if (L.type == JointType::Revolute && std::abs(L.dh.d) > std::abs(L.dh.a)) {
      // frame k's origin, fixed in link k+1 because the joint turns about z_k through it
      const Eigen::Isometry3d A = dh_transform(L.dh.theta, L.dh.d, L.dh.a, L.dh.alpha);
      from = A.inverse() * Eigen::Vector3d::Zero();
      out.push_back(segment_box(k + 1, from, foot, t, "link" + std::to_string(k + 1)));
    } else {
      out.push_back(segment_box(k + 1, foot, Eigen::Vector3d::Zero(), t, "link" + std::to_string(k + 1)));
    }
  }
  return out;
}

void Robot::build_geometry_() {
  if (default_boxes_) boxes_ = default_boxes();
  for (size_t b = 0; b < boxes_.size(); ++b) {
    const LinkBox& box = boxes_[b];
    const std::string who = "box " + std::to_string(b) + (box.name.empty() ? "" : " '" + box.name + "'");
    require(box.link >= 0 && box.link <= n_,
            who + ": link must be 0 (the base) .. " + std::to_string(n_) + ", got " + std::to_string(box.link));
    require(box.half_extents.allFinite() && box.half_extents.minCoeff() > 0,
            who + ": half extents must be finite and > 0 m");
    require(rigid(box.pose), who + ": pose must be a finite rigid transform");
  }
  if (!clamp_.present()) {
    clamp_ = Clamp();
    return;
  }
  const Clamp& c = clamp_;
  require(c.fixed_link >= 1 && c.fixed_link < n_,
          "clamp: fixed_link must be 1 .. " + std::to_string(n_ - 1) + ", got " + std::to_string(c.fixed_link));
  require(c.moving_joint == c.fixed_link + 1, "clamp: moving_joint must be fixed_link + 1 = " +
                                                  std::to_string(c.fixed_link + 1) + ", got " +
                                                  std::to_string(c.moving_joint));
  require(links_[c.moving_joint - 1].type == JointType::Prismatic,
          "clamp: moving_joint " + std::to_string(c.moving_joint) + " must be prismatic (its q is the opening)");
  require(rigid(c.fixed_face), "clamp: fixed_face must be a finite rigid transform");
  // the moving joint slides along z of fixed_link's frame: the face's z must be that axis
  require(c.fixed_face.linear().col(2).z() > 1.0 - 1e-9,
          "clamp: fixed_face's z axis must be the moving joint's axis (z of fixed_link's DH frame)");
  require(std::isfinite(c.jaw_length) && c.jaw_length > 0, "clamp: jaw_length must be finite and > 0 m");
  require(std::isfinite(c.pad_width) && c.pad_width > 0, "clamp: pad_width must be finite and > 0 m");
}

double box_penetration(const Eigen::Isometry3d& a, const Eigen::Vector3d& half_a, const Eigen::Isometry3d& b,
                       const Eigen::Vector3d& half_b) {
  const Eigen::Matrix3d& A = a.linear();
  const Eigen::Matrix3d& B = b.linear();
  const Eigen::Vector3d d = b.translation() - a.translation();
  double depth = std::numeric_limits<double>::infinity();
  auto along = [&](const Eigen::Vector3d& u) {
    const double ra = (A.transpose() * u).cwiseAbs().dot(half_a);
    const double rb = (B.transpose() * u).cwiseAbs().dot(half_b);
    depth = std::min(depth, ra + rb - std::abs(d.dot(u)));
  };
  for (int i = 0; i < 3; ++i) {
    along(A.col(i));
    along(B.col(i));
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d c = A.col(i).cross(B.col(j));
      const double len = c.norm();
      if (len > 1e-9) along(c / len);
    }
  return depth;
}

void Robot::frame_velocities(const Workspace& ws, const double* qd, Eigen::Vector3d* w, Eigen::Vector3d* v) const {
  w[0].setZero();
  v[0].setZero();
  for (int i = 1; i <= n_; ++i) {
    const Eigen::Vector3d z = ws.R[i - 1].col(2);
    const Eigen::Vector3d r = ws.o[i] - ws.o[i - 1];
    if (links_[i - 1].type == JointType::Revolute) {
      // joint axis i passes through o_{i-1}: link i turns about it
      w[i] = w[i - 1] + z * qd[i - 1];
      v[i] = v[i - 1] + w[i].cross(r);
    } else {
      w[i] = w[i - 1];
      v[i] = v[i - 1] + w[i - 1].cross(r) + z * qd[i - 1];
    }
  }
}

void Robot::box_poses(const Workspace& ws, std::vector<Eigen::Isometry3d>& out) const {
  out.resize(boxes_.size());
  for (size_t b = 0; b < boxes_.size(); ++b) {
    const LinkBox& box = boxes_[b];
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = ws.R[box.link];
    T.translation() = ws.o[box.link];
    out[b] = T * box.pose;
  }
}

void Robot::clamp_faces(const Workspace& ws, const double* q, Eigen::Isometry3d& fixed,
                        Eigen::Isometry3d& moving) const {
  require(clamp_.present(), "robot '" + name_ + "' has no clamp");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = ws.R[clamp_.fixed_link];
  T.translation() = ws.o[clamp_.fixed_link];
  fixed = T * clamp_.fixed_face;
  moving = fixed;
  moving.translation() += q[clamp_.moving_joint - 1] * fixed.linear().col(2);
  moving.linear().col(1) = -fixed.linear().col(1);
  moving.linear().col(2) = -fixed.linear().col(2);
}

}  // namespace coopsim
