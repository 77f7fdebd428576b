// The world: a Bullet dynamics world with a floor, static scenery and free
// rigid bodies, into which a simulation brings every robot's link boxes as
// kinematic bodies. Bullet appears only in world.cpp (and, for its GJK
// distance alone, box_distance.cpp): this header and the rest of the engine
// see Eigen types only.
//
// Division of labour: coopsim's dynamics move the robots; Bullet does the
// geometry of everything and moves the free bodies, with its own solver,
// against the scenery and the robot links. A simulation sets each link
// body's pose and exact twist every world step; Bullet never moves them.
//
// Units: m, kg, s, N. Poses are world poses of the box centre with its axes.
// Contact friction and restitution are the products of the two bodies'
// coefficients (Bullet's rule): with the scenery's and links' default of 1,
// a free body's own coefficient decides.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "coopsim/checks.hpp"
#include "coopsim/shape.hpp"

namespace coopsim {

enum class BodyKind { Floor, Static, Free, Link };
const char* body_kind_name(BodyKind k);
// The kind named by body_kind_name; throws std::invalid_argument for another name.
BodyKind body_kind(const std::string& name);

struct BodySpec;
// The kind of a contact between two bodies: "self" (links of one robot),
// "robot-robot", "robot-scenery" (a link and the floor or a static box),
// "robot-body" (a link and a free body), "body-scenery", "body-body".
const char* contact_kind(const BodySpec& a, const BodySpec& b);

// A body of the world: the floor (the plane z = 0 within 100 m of the
// origin: the top face of a static 200 m cube), a static box, a free box
// (mass > 0), or a link shape of a robot (kinematic; added by a simulation):
// a box, or for a link any Shape (sphere, cylinder, convex hull). Its shape's
// fields (Shape): kind, half_extents (m: a box's, or the bound of another kind).
struct BodySpec : Shape {
  std::string name;
  BodyKind kind = BodyKind::Static;
  double mass = 0.0;                                         // kg, > 0 for free bodies
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();    // initial world pose of the centre
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();        // initial, m/s, of the centre
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  // initial, rad/s
  double friction = 1.0;                                     // Coulomb coefficient, >= 0
  double restitution = 0.0;                                  // 0 .. 1
  int robot = -1, link = -1, box = -1;                       // link bodies: robot index, link, box index
};

// The state of a body now.
struct BodyState {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();       // world pose of the centre, (4, 4) m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();          // m/s, of the centre (world)
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  // rad/s (world)
  bool asleep = false;  // a free body at rest that the world no longer solves (WorldOptions::sleep_after)
};

// One contact point between bodies a and b of the last world step.
struct ContactPoint {
  int a = -1, b = -1;               // body ids
  Eigen::Vector3d point_a, point_b;  // m, world: on a's and on b's surface
  Eigen::Vector3d normal;            // unit, world, from b towards a
  double depth = 0.0;                // m, penetration (>= 0 when touching)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // N, world, on a at point_a over the step (b: -force)
  bool solver = false;               // force from Bullet's solver (false: coopsim's penalty, or none)
};

// A contact between two bodies over time: from the first world step where
// they touch to the first where they no longer do (end NaN while ongoing).
struct ContactEvent {
  int a = -1, b = -1;  // body ids
  double begin = 0.0, end = std::numeric_limits<double>::quiet_NaN();  // s
  double peak_force = 0.0;  // N, largest magnitude of the pair's total force
  double max_depth = 0.0;   // m, deepest penetration
  long steps = 0;           // world steps in contact
};

// A free body whose state stopped being finite, left the world (1e6 m) or
// exceeded 1e5 m/s or rad/s in a step: the simulation raises DivergenceError.
class WorldDivergence : public std::runtime_error {
 public:
  WorldDivergence(const std::string& what, int body) : std::runtime_error(what), body(body) {}
  int body;  // the body's id
};

// A body's pose as the API takes it: a (4, 4) pose, or a position (3,) m with a unit quaternion
// (4,) [w, x, y, z] (none: no rotation). Throws std::invalid_argument naming what is wrong: both
// forms or neither, a pose that is not rigid, a quaternion whose norm is off 1 by more than 1e-9.
Eigen::Isometry3d body_pose(const std::optional<Array>& pose, const std::optional<Array>& position,
                            const std::optional<Array>& quaternion);

struct WorldOptions {
  bool floor = true;
  double floor_friction = 1.0, floor_restitution = 0.0;
  Eigen::Vector3d gravity = Eigen::Vector3d(0, 0, -9.81);  // m/s^2
  int solver_iterations = 10;
  // a free body below 0.1 mm/s and 1 mrad/s for this long (s), or none of whose corners moved more than
  // 0.25 mm in that time (a bar on its end rocking in the solver's residual), sleeps, with the bodies it
  // touches (Bullet's islands), until something moving touches it (Bullet's own delay is 2 s)
  double sleep_after = 0.5;
};

class World {
 public:
  explicit World(WorldOptions options = WorldOptions());
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  const WorldOptions& options() const { return options_; }

  // Throws std::invalid_argument naming `who` unless T is a finite rigid transform within 1e6 m of
  // the origin: what every pose in a world must be.
  static void check_pose(const Eigen::Isometry3d& T, const std::string& who);

  // ---- building (before the first step) ----
  // Throw std::invalid_argument naming what is wrong: sizes outside
  // 1e-4 .. 1e4 m, non-positive or non-finite mass, friction < 0,
  // restitution outside 0 .. 1, a pose that is not a finite rigid
  // transform within 1e6 m, an empty or duplicate name. Return the body id.
  int add_static_box(const std::string& name, const Eigen::Vector3d& half_extents, const Eigen::Isometry3d& pose,
                     double friction = 1.0, double restitution = 0.0);
  int add_free_box(const std::string& name, const Eigen::Vector3d& half_extents, double mass,
                   const Eigen::Isometry3d& pose, double friction = 0.5, double restitution = 0.0,
                   const Eigen::Vector3d& velocity = Eigen::Vector3d::Zero(),
                   const Eigen::Vector3d& angular_velocity = Eigen::Vector3d::Zero());
  // Link bodies of one robot (its shapes at their first poses: boxes, spheres,
  // cylinders, convex hulls, finished by finish_shape), named
  // "<label>/<box name>"; `excluded` lists pairs of box indices that never
  // collide (the robot's adjacent, same-link and always-touching boxes).
  // Called by the simulation that owns the world.
  void add_robot(int robot, const std::string& label, const std::vector<std::string>& box_names,
                 const std::vector<int>& box_links, const std::vector<Shape>& shapes,
                 const std::vector<Eigen::Isometry3d>& poses, const std::vector<std::pair<int, int>>& excluded,
                 double friction);
  // A static or free body as add_static_box or add_free_box adds it (spec's fields; the kind
  // decides which).
  int add_body(const BodySpec& spec);
  // Removes the robots' link bodies (the world keeps its own).
  void clear_robots();
  // New shapes, first poses and exclusions of one robot's link bodies, ids first .. first + k - 1 (the
  // same count, the same links), in place: the other bodies keep their states. Called by the
  // simulation that owns the world when it replaces a robot.
  void replace_robot_boxes(int first, const std::vector<Shape>& shapes,
                           const std::vector<Eigen::Isometry3d>& poses,
                           const std::vector<std::pair<int, int>>& excluded);

  // ---- bodies ----
  int body_count() const { return static_cast<int>(specs_.size()); }
  const BodySpec& body(int id) const;
  int find(const std::string& name) const;  // -1 if none
  // The id and the body of that name; throw std::invalid_argument if none: "no body named 'x' in
  // the world".
  int id(const std::string& name) const;
  const BodySpec& body(const std::string& name) const { return specs_[id(name)]; }
  std::vector<std::string> body_names() const;  // by id
  // The world's own bodies, static and free, in order added: what add_body needs to build the
  // world again (with its options; the floor comes with them).
  std::vector<BodySpec> own_bodies() const;
  // "<coopsim.World floor=True, 2 static, 3 free bodies>".
  std::string describe() const;
  BodyState state(int id) const;
  std::vector<int> free_bodies() const;     // ids of the free bodies, in order added
  std::vector<std::string> names(const std::vector<int>& ids) const;  // the bodies' names

  // ---- stepping (by the owning simulation) ----
  // Sets a link body's pose and twist (velocity of the box centre); a base box (link 0) stays
  // where it was added.
  void set_link(int id, const Eigen::Isometry3d& pose, const Eigen::Vector3d& velocity,
                const Eigen::Vector3d& angular_velocity);
  // A force (N, at the centre) and moment (N m) on a free body over the next step.
  void apply_wrench(int id, const Eigen::Vector3d& force, const Eigen::Vector3d& moment);
  // Sets a free body's velocity (of its centre) and angular velocity.
  void set_velocity(int id, const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity);
  // Pairs that do not collide for now (a held body and its holder's clamp);
  // set again whenever it changes.
  void set_ignored(std::vector<std::pair<int, int>> pairs);
  // Inertia tensor (kg m^2) of a free body about its centre, in the world.
  Eigen::Matrix3d inertia(int id) const;
  // Advances the free bodies by dt (s) at simulated time t (the step's
  // start), then gathers the contacts with the solver's forces.
  void step(double dt, double t);
  // The contact points of the last world step: bodies, points, normal, depth and force (ContactPoint).
  const std::vector<ContactPoint>& contacts() const { return contacts_; }
  std::vector<ContactPoint>& contacts() { return contacts_; }
  // Folds this step's contacts (forces final) into the events at time t.
  void record_events(double t);
  const std::vector<ContactEvent>& events() const { return events_; }
  // Back to the initial state of every body, no contacts, no events; the
  // robots' link bodies leave (the simulation adds them again).
  void reset();

  // Whether a simulation owns this world (one at most; throws when a
  // second one tries).
  bool attached() const { return attached_; }
  void attach();
  void detach() { attached_ = false; }

 private:
  struct Impl;
  int add_(BodySpec spec);
  void build_();
  void unbuild_();  // drops the Bullet world (world.cpp, where Impl is complete): built again at the next step
  WorldOptions options_;
  std::vector<BodySpec> specs_;
  std::vector<std::vector<int>> exclusions_;  // per body: ids never to collide with
  std::vector<std::pair<int, int>> ignored_;  // pairs not colliding for now (a < b)
  std::map<std::string, int> names_;
  std::unique_ptr<Impl> impl_;
  std::vector<ContactPoint> contacts_;
  std::vector<ContactEvent> events_;
  std::map<std::pair<int, int>, size_t> open_;  // pair -> index of its ongoing event
  std::vector<ContactEvent> touching_;           // scratch of record_events
  std::vector<Eigen::Vector3d> touching_force_;
  bool attached_ = false;
};

}  // namespace coopsim
