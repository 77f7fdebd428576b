// The world's bodies (world.hpp), their description apart from Bullet: body kinds and contact kinds,
// the checks of a body's name, size, pose, mass and velocities, adding static and free bodies and a
// robot's link boxes (with its exclusions), names and ids, a free body's inertia. The Bullet world built
// from them, its step and contacts: world.cpp.
#include "coopsim/world.hpp"
#include "internal.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>

namespace coopsim {

namespace {

constexpr double kMinSize = 1e-4, kMaxSize = 1e4;  // m: box sizes Bullet handles well
constexpr double kMinMass = 1e-6, kMaxMass = 1e9;   // kg: a free body's mass
constexpr double kMaxSpeed = 1e4;                   // m/s and rad/s: a free body's initial velocities
constexpr double kMaxDistance = 1e6;                // m: positions from the world origin

using detail::require;

// Whether `s` is well-formed UTF-8 (names come back to Python as text).
bool valid_utf8(const std::string& s) {
  size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    int more;
    unsigned int cp;
    if (c < 0x80) { ++i; continue; }
    if ((c & 0xE0) == 0xC0) { more = 1; cp = c & 0x1F; }
    else if ((c & 0xF0) == 0xE0) { more = 2; cp = c & 0x0F; }
    else if ((c & 0xF8) == 0xF0) { more = 3; cp = c & 0x07; }
    else return false;
    if (i + more >= s.size()) return false;
    for (int k = 1; k <= more; ++k) {
      const unsigned char d = static_cast<unsigned char>(s[i + k]);
      if ((d & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (d & 0x3F);
    }
    // overlong forms, surrogates and values beyond U+10FFFF
    if ((more == 1 && cp < 0x80) || (more == 2 && cp < 0x800) || (more == 3 && cp < 0x10000) ||
        (cp >= 0xD800 && cp <= 0xDFFF) || cp > 0x10FFFF)
      return false;
    i += more + 1;
  }
  return true;
}

}  // namespace

const char* body_kind_name(BodyKind k) {
  switch (k) {
    case BodyKind::Floor: return "floor";
    case BodyKind::Static: return "static";
    case BodyKind::Free: return "free";
    default: return "link";
  }
}

BodyKind body_kind(const std::string& name) {
  for (BodyKind k : {BodyKind::Floor, BodyKind::Static, BodyKind::Free, BodyKind::Link})
    if (name == body_kind_name(k)) return k;
  throw std::invalid_argument("no body kind '" + name + "' (floor, static, free, link)");
}

const char* contact_kind(const BodySpec& a, const BodySpec& b) {
  const bool la = a.kind == BodyKind::Link, lb = b.kind == BodyKind::Link;
  const bool fa = a.kind == BodyKind::Free, fb = b.kind == BodyKind::Free;
  if (la && lb) return a.robot == b.robot ? "self" : "robot-robot";
  if (la || lb) return (fa || fb) ? "robot-body" : "robot-scenery";
  if (fa && fb) return "body-body";
  return "body-scenery";
}

int World::add_(BodySpec spec) {
  require(valid_utf8(spec.name), "a body's name must be UTF-8 text");
  const std::string who = std::string(body_kind_name(spec.kind)) + " body '" + spec.name + "'";
  require(!spec.name.empty(), "a body needs a name");
  require(!names_.count(spec.name), "a body named '" + spec.name + "' is already in the world");
  if (spec.kind != BodyKind::Floor) {
    require(spec.half_extents.allFinite() && spec.half_extents.minCoeff() >= kMinSize &&
                spec.half_extents.maxCoeff() <= kMaxSize,
            who + ": half_extents must be in 1e-4 .. 1e4 m");
    check_pose(spec.pose, who);
  }
  require(std::isfinite(spec.friction) && spec.friction >= 0, who + ": friction must be finite and >= 0");
  require(std::isfinite(spec.restitution) && spec.restitution >= 0 && spec.restitution <= 1,
          who + ": restitution must be in 0 .. 1");
  if (spec.kind == BodyKind::Free) {
    require(std::isfinite(spec.mass) && spec.mass >= kMinMass && spec.mass <= kMaxMass,
            who + ": mass must be in 1e-6 .. 1e9 kg");
    require(spec.velocity.allFinite() && spec.angular_velocity.allFinite() && spec.velocity.norm() <= kMaxSpeed &&
                spec.angular_velocity.norm() <= kMaxSpeed,
            who + ": velocities must be finite and at most 1e4 m/s and 1e4 rad/s");
  }
  const int id = body_count();
  specs_.push_back(std::move(spec));
  exclusions_.emplace_back();
  names_[specs_.back().name] = id;
  unbuild_();  // built again, with the new body, at the next step
  return id;
}

int World::add_static_box(const std::string& name, const Eigen::Vector3d& half_extents,
                          const Eigen::Isometry3d& pose, double friction, double restitution) {
  require(!impl_, "bodies can only be added before the first step (or after reset())");
  BodySpec s;
  s.name = name;
  s.kind = BodyKind::Static;
  s.half_extents = half_extents;
  s.pose = pose;
  s.friction = friction;
  s.restitution = restitution;
  return add_(s);
}

int World::add_free_box(const std::string& name, const Eigen::Vector3d& half_extents, double mass,
                        const Eigen::Isometry3d& pose, double friction, double restitution,
                        const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity) {
  require(!impl_, "bodies can only be added before the first step (or after reset())");
  BodySpec s;
  s.name = name;
  s.kind = BodyKind::Free;
  s.half_extents = half_extents;
  s.mass = mass;
  s.pose = pose;
  s.friction = friction;
  s.restitution = restitution;
  s.velocity = velocity;
  s.angular_velocity = angular_velocity;
  return add_(s);
}

int World::add_body(const BodySpec& s) {
  require(s.kind == BodyKind::Static || s.kind == BodyKind::Free,
          std::string("add_body: a world adds static and free bodies, not a ") + body_kind_name(s.kind) + " body");
  if (s.kind == BodyKind::Static) return add_static_box(s.name, s.half_extents, s.pose, s.friction, s.restitution);
  return add_free_box(s.name, s.half_extents, s.mass, s.pose, s.friction, s.restitution, s.velocity,
                      s.angular_velocity);
}

Eigen::Isometry3d body_pose(const std::optional<Array>& pose, const std::optional<Array>& position,
                            const std::optional<Array>& quaternion) {
  if (pose) {
    require(!position && !quaternion, "give either pose (4, 4) or position and quaternion, not both");
    return rigid_pose(*pose, "pose");
  }
  require(position.has_value(), "a body needs a pose (4, 4) or a position (3,)");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = vector_of(*position, 3, "position");
  if (quaternion) {
    const Eigen::VectorXd q = vector_of(*quaternion, 4, "quaternion");
    require(std::abs(q.norm() - 1.0) <= 1e-9,
            "quaternion must have unit norm [w, x, y, z], got norm " + std::to_string(q.norm()));
    T.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix();
  }
  return T;
}

void World::check_pose(const Eigen::Isometry3d& T, const std::string& who) {
  require(T.matrix().allFinite(), who + ": pose must be finite");
  require(T.translation().norm() <= kMaxDistance, who + ": pose must lie within 1e6 m of the origin");
  require(is_rotation(T.linear()), who + ": pose must be a rigid transform (orthonormal rotation)");
}

void World::add_robot(int robot, const std::string& label, const std::vector<std::string>& box_names,
                      const std::vector<int>& box_links, const std::vector<Shape>& shapes,
                      const std::vector<Eigen::Isometry3d>& poses, const std::vector<std::pair<int, int>>& excluded,
                      double friction) {
  const int first = body_count();
  for (size_t k = 0; k < box_names.size(); ++k) {
    BodySpec s;
    static_cast<Shape&>(s) = shapes[k];
    s.name = label + "/" + box_names[k];
    s.kind = BodyKind::Link;
    s.pose = poses[k];
    s.friction = friction;
    s.robot = robot;
    s.link = box_links[k];
    s.box = static_cast<int>(k);
    add_(s);
  }
  for (const auto& [i, j] : excluded) {
    exclusions_[first + i].push_back(first + j);
    exclusions_[first + j].push_back(first + i);
  }
}

void World::clear_robots() {
  while (!specs_.empty() && specs_.back().kind == BodyKind::Link) {
    names_.erase(specs_.back().name);
    specs_.pop_back();
    exclusions_.pop_back();
  }
  require(std::none_of(specs_.begin(), specs_.end(), [](const BodySpec& s) { return s.kind == BodyKind::Link; }),
          "clear_robots: link bodies must come last");
  unbuild_();
}

int World::id(const std::string& name) const {
  const int id = find(name);
  require(id >= 0, "no body named '" + name + "' in the world");
  return id;
}

std::vector<std::string> World::body_names() const {
  std::vector<std::string> out;
  for (const BodySpec& s : specs_) out.push_back(s.name);
  return out;
}

std::vector<std::string> World::names(const std::vector<int>& ids) const {
  std::vector<std::string> out;
  for (int id : ids) out.push_back(body(id).name);
  return out;
}

std::vector<BodySpec> World::own_bodies() const {
  std::vector<BodySpec> out;
  std::copy_if(specs_.begin(), specs_.end(), std::back_inserter(out),
               [](const BodySpec& s) { return s.kind == BodyKind::Static || s.kind == BodyKind::Free; });
  return out;
}

std::string World::describe() const {
  const auto count = [this](BodyKind k) {
    return std::to_string(std::count_if(specs_.begin(), specs_.end(), [k](const BodySpec& s) { return s.kind == k; }));
  };
  return "<coopsim.World floor=" + std::string(options_.floor ? "True" : "False") + ", " + count(BodyKind::Static) +
         " static, " + count(BodyKind::Free) + " free bodies>";
}

const BodySpec& World::body(int id) const {
  if (id < 0 || id >= body_count())
    throw std::invalid_argument("body id " + std::to_string(id) + " out of range [0, " +
                                std::to_string(body_count()) + ")");
  return specs_[id];
}

int World::find(const std::string& name) const {
  auto it = names_.find(name);
  return it == names_.end() ? -1 : it->second;
}

std::vector<int> World::free_bodies() const {
  std::vector<int> out;
  for (int i = 0; i < body_count(); ++i)
    if (specs_[i].kind == BodyKind::Free) out.push_back(i);
  return out;
}

void World::attach() {
  require(!attached_, "this world already belongs to another simulation: give each simulation its own World");
  attached_ = true;
}

Eigen::Matrix3d World::inertia(int id) const {
  const BodySpec& s = body(id);
  const Eigen::Vector3d e = 2.0 * s.half_extents;
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  I(0, 0) = s.mass * (e.y() * e.y() + e.z() * e.z()) / 12.0;
  I(1, 1) = s.mass * (e.x() * e.x() + e.z() * e.z()) / 12.0;
  I(2, 2) = s.mass * (e.x() * e.x() + e.y() * e.y()) / 12.0;
  const Eigen::Matrix3d R = state(id).pose.linear();
  return R * I * R.transpose();
}

}  // namespace coopsim
