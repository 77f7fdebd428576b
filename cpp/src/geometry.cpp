// Link geometry: the shapes fixed to a robot's links (boxes, spheres, cylinders, convex hulls: their
// checks and bounds) and its clamp; separating-axis box bounds.
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "coopsim/robot.hpp"
#include "internal.hpp"

namespace coopsim {

namespace {

using detail::require;

bool rigid(const Eigen::Isometry3d& T) { return T.matrix().allFinite() && is_rotation(T.linear()); }

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

const char* shape_kind_name(ShapeKind k) {
  switch (k) {
    case ShapeKind::Sphere: return "sphere";
    case ShapeKind::Cylinder: return "cylinder";
    case ShapeKind::Hull: return "hull";
    default: return "box";
  }
}

void finish_shape(Shape& s, const std::string& who) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  switch (s.type) {
    case ShapeKind::Box:
      require(s.half_extents.allFinite() && s.half_extents.minCoeff() > 0, who + ": half extents must be finite and > 0 m");
      return;
    case ShapeKind::Sphere:
      require(positive(s.radius), who + ": radius must be finite and > 0 m, got " + detail::num(s.radius));
      s.half_extents.setConstant(s.radius);
      return;
    case ShapeKind::Cylinder:
      require(positive(s.radius), who + ": radius must be finite and > 0 m, got " + detail::num(s.radius));
      require(positive(s.half_length),
              who + ": length must be finite and > 0 m, got " + detail::num(2.0 * s.half_length));
      s.half_extents = Eigen::Vector3d(s.radius, s.radius, s.half_length);
      return;
    case ShapeKind::Hull: {
      const int k = static_cast<int>(s.points.size());
      require(k >= 4 && k <= kMaxHullPoints, who + ": a hull needs 4 .. " + std::to_string(kMaxHullPoints) +
                                                 " points, got " + std::to_string(k));
      Eigen::Vector3d lo = s.points[0], hi = s.points[0], mean = Eigen::Vector3d::Zero();
      for (const Eigen::Vector3d& p : s.points) {
        require(p.allFinite(), who + ": hull points must be finite");
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
        mean += p / k;
      }
      // a volume: the points' spread along their thinnest direction is not nil
      Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
      for (const Eigen::Vector3d& p : s.points) C += (p - mean) * (p - mean).transpose();
      const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(C).singularValues();
      require(sv[2] > 1e-18 * std::max(sv[0], 1e-300) && std::sqrt(sv[2] / k) > 1e-9,
              who + ": hull points must span a volume (they lie on one plane or line)");
      s.half_extents = lo.cwiseAbs().cwiseMax(hi.cwiseAbs());
      return;
    }
  }
}

LinkBox LinkBox::sphere(int link, double radius, const Eigen::Isometry3d& pose, std::string name) {
  LinkBox b;
  b.type = ShapeKind::Sphere;
  b.link = link;
  b.radius = radius;
  b.pose = pose;
  b.name = std::move(name);
  finish_shape(b, "sphere" + (b.name.empty() ? std::string() : " '" + b.name + "'"));
  return b;
}

LinkBox LinkBox::cylinder(int link, double radius, double length, const Eigen::Isometry3d& pose, std::string name) {
  LinkBox b;
  b.type = ShapeKind::Cylinder;
  b.link = link;
  b.radius = radius;
  b.half_length = 0.5 * length;
  b.pose = pose;
  b.name = std::move(name);
  finish_shape(b, "cylinder" + (b.name.empty() ? std::string() : " '" + b.name + "'"));
  return b;
}

LinkBox LinkBox::hull(int link, const std::vector<Eigen::Vector3d>& points, const Eigen::Isometry3d& pose,
                      std::string name) {
  LinkBox b;
  b.type = ShapeKind::Hull;
  b.link = link;
  b.points = points;
  b.pose = pose;
  b.name = std::move(name);
  finish_shape(b, "hull" + (b.name.empty() ? std::string() : " '" + b.name + "'"));
  // about the centre of the points' bounding box: the bound is then tight
  Eigen::Vector3d lo = points[0], hi = points[0];
  for (const Eigen::Vector3d& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3d c = 0.5 * (lo + hi);
  if (c.cwiseAbs().maxCoeff() > 1e-12 * (hi - lo).cwiseAbs().maxCoeff()) {  // (about its centre already: kept as it is)
    for (Eigen::Vector3d& p : b.points) p -= c;
    b.pose.translation() += b.pose.linear() * c;
    finish_shape(b, "hull");
  }
  return b;
}

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
  geometry_memo_ = std::make_shared<GeometryMemo>();  // what the old geometry's copies computed is theirs
  if (default_boxes_) boxes_ = default_boxes();
  for (size_t b = 0; b < boxes_.size(); ++b) {
    const LinkBox& box = boxes_[b];
    const std::string who = "box " + std::to_string(b) + (box.name.empty() ? "" : " '" + box.name + "'");
    require(box.link >= 0 && box.link <= n_,
            who + ": link must be 0 (the base) .. " + std::to_string(n_) + ", got " + std::to_string(box.link));
    finish_shape(boxes_[b], who);
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
  return -box_gap(a, half_a, b, half_b);
}

namespace {

// Whether a box's face (centre c, half extents h, in 2-D coordinates of the face) and the
// parallel projection onto it of the other box's nearest feature (a vertex, edge or face: the
// zonotope p + sum_k lambda_k g_k, |lambda_k| <= 1) have a point in common: no separating axis
// among the axes of both (2-D separating-axis test).
bool feature_over_face(const Eigen::Vector2d& p, const Eigen::Vector2d* g, int m, const Eigen::Vector2d& h) {
  Eigen::Vector2d axes[4] = {Eigen::Vector2d::UnitX(), Eigen::Vector2d::UnitY()};
  int na = 2;
  for (int k = 0; k < m; ++k) axes[na++] = Eigen::Vector2d(-g[k].y(), g[k].x());
  for (int k = 0; k < na; ++k) {
    const Eigen::Vector2d& u = axes[k];
    double reach = h.x() * std::abs(u.x()) + h.y() * std::abs(u.y());
    for (int l = 0; l < m; ++l) reach += std::abs(g[l].dot(u));
    if (std::abs(p.dot(u)) > reach) return false;
  }
  return true;
}

// A direction along which a box's extent projects to less than this is parallel to the face
// (a free direction of the nearest feature): the gap errs by less than 1e-12 m per metre of box.
constexpr double kParallel = 1e-12;

// Whether the gap along face normal k of box F (half extents hF) is the distance to box O
// (centre t, axes the columns of R, half extents hO, all in F's frame).
bool face_gap_exact(int k, const Eigen::Vector3d& t, const Eigen::Matrix3d& R, const Eigen::Vector3d& hF,
                    const Eigen::Vector3d& hO) {
  const double s = t[k] >= 0 ? 1.0 : -1.0;  // the normal towards O
  const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
  Eigen::Vector3d p = t;
  Eigen::Vector2d g[3];
  int m = 0;
  for (int j = 0; j < 3; ++j) {
    const double along = s * R(k, j);
    if (std::abs(along) < kParallel) {
      g[m++] = hO[j] * Eigen::Vector2d(R(k1, j), R(k2, j));
    } else {
      p -= (along > 0 ? hO[j] : -hO[j]) * R.col(j);
    }
  }
  return m < 3 && feature_over_face(Eigen::Vector2d(p[k1], p[k2]), g, m, Eigen::Vector2d(hF[k1], hF[k2]));
}

}  // namespace

double box_gap(const Eigen::Isometry3d& a, const Eigen::Vector3d& half_a, const Eigen::Isometry3d& b,
               const Eigen::Vector3d& half_b, bool* exact) {
  // in A's frame (Gottschalk's OBB test): B's axes are the columns of R, its centre is t
  const Eigen::Matrix3d R = a.linear().transpose() * b.linear();
  const Eigen::Vector3d t = a.linear().transpose() * (b.translation() - a.translation());
  const Eigen::Matrix3d absR = R.cwiseAbs();
  const Eigen::Vector3d& ha = half_a;
  const Eigen::Vector3d& hb = half_b;
  double gap = -std::numeric_limits<double>::infinity();
  int axis = -1;  // 0..2: a face normal of A, 3..5: of B, 6 + 3 i + j: the edge-edge axis A_i x B_j
  for (int i = 0; i < 3; ++i) {
    const double g = std::abs(t[i]) - ha[i] - absR.row(i).dot(hb);
    if (g > gap) {
      gap = g;
      axis = i;
    }
  }
  for (int j = 0; j < 3; ++j) {
    const double g = std::abs(R.col(j).dot(t)) - hb[j] - absR.col(j).dot(ha);
    if (g > gap) {
      gap = g;
      axis = 3 + j;
    }
  }
  // the edge-edge axes A_i x B_j, scaled by their length sqrt(1 - R_ij^2) (parallel edges: no axis)
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int j = 0; j < 3; ++j) {
      const double len2 = 1.0 - R(i, j) * R(i, j);
      if (len2 < 1e-18) continue;
      const int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      const double proj = std::abs(t[i2] * R(i1, j) - t[i1] * R(i2, j));
      const double ra = ha[i1] * absR(i2, j) + ha[i2] * absR(i1, j);
      const double rb = hb[j1] * absR(i, j2) + hb[j2] * absR(i, j1);
      const double g = (proj - ra - rb) / std::sqrt(len2);
      if (g > gap) {
        gap = g;
        axis = 6 + 3 * i + j;
      }
    }
  }
  if (!exact) return gap;
  *exact = false;
  if (!(gap > 0)) return gap;
  if (axis < 3) {
    *exact = face_gap_exact(axis, t, R, ha, hb);
  } else if (axis < 6) {
    // in B's frame: A's centre at -R^T t, its axes the columns of R^T
    *exact = face_gap_exact(axis - 3, -(R.transpose() * t), R.transpose(), hb, ha);
  } else {
    // the nearest edges (A's along i, B's along j): both closest points within them
    const int i = (axis - 6) / 3, j = (axis - 6) % 3;
    Eigen::Vector3d n = Eigen::Vector3d::Unit(i).cross(Eigen::Vector3d(R.col(j)));
    if (n.dot(t) < 0) n = -n;
    Eigen::Vector3d pa = Eigen::Vector3d::Zero(), pb = t;
    for (int k = 0; k < 3; ++k) {
      if (k != i) {
        if (std::abs(n[k]) < kParallel) return gap;
        pa[k] = n[k] > 0 ? ha[k] : -ha[k];
      }
      if (k != j) {
        const double along = R.col(k).dot(n);
        if (std::abs(along) < kParallel) return gap;
        pb -= (along > 0 ? hb[k] : -hb[k]) * R.col(k);
      }
    }
    const double c = R(i, j), denom = 1.0 - c * c;
    const Eigen::Vector3d w = pa - pb;
    const double d = w[i], e = R.col(j).dot(w);
    const double s = (c * e - d) / denom, u = (e - c * d) / denom;
    *exact = std::abs(s) <= ha[i] && std::abs(u) <= hb[j];
  }
  return gap;
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
