// The world on Bullet (world.hpp): the Bullet world built from the bodies (world_bodies.cpp holds
// their description and checks), their collision filtering (exclusions, ignored pairs), sleeping, the
// state of a body and the pushes on it, its step and its contacts and contact events, a robot's link
// shapes (boxes, spheres, cylinders, convex hulls as Bullet's own shapes) replaced in place. With box_distance.cpp (which uses Bullet's GJK alone, without a world) the
// only engine file that includes Bullet.
#include "coopsim/world.hpp"
#include "coopsim/robot.hpp"
#include "bullet_hull.hpp"
#include "internal.hpp"

#include <btBulletDynamicsCommon.h>
#include <BulletCollision/CollisionDispatch/btBoxBoxCollisionAlgorithm.h>

#include <algorithm>
#include <limits>
#include <cmath>
#include <iterator>
#include <sstream>
#include <stdexcept>

namespace coopsim {

namespace {

constexpr double kWorldRadius = 1e6;                // m: a free body beyond it has diverged
constexpr double kDivergedSpeed = 1e5;              // m/s and rad/s: a free body faster has diverged
constexpr double kFloorHalf = 100.0;               // m: the floor is the top face of a 200 m cube

using detail::require;

btVector3 bt(const Eigen::Vector3d& v) { return btVector3(v.x(), v.y(), v.z()); }
Eigen::Vector3d eig(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

btTransform bt(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  btMatrix3x3 b(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2));
  return btTransform(b, bt(Eigen::Vector3d(T.translation())));
}

Eigen::Isometry3d eig(const btTransform& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const btMatrix3x3& b = t.getBasis();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) T.linear()(i, j) = b[i][j];
  T.translation() = eig(t.getOrigin());
  return T;
}

bool static_like(BodyKind k) { return k == BodyKind::Floor || k == BodyKind::Static; }

// Bullet's own shape for a body's shape, its margin zero as the boxes' (the shape is exactly its size):
// btBoxShape, btSphereShape (its radius is its margin), btCylinderShapeZ, btConvexHullShape (reduced
// to its hull's vertices, bullet_hull.hpp). With `polyhedra` a box's or a hull's faces and edges are computed
// (initializePolyhedralFeatures) for Bullet's polyhedral contact clipping, which gives a hull the
// patch of points a box gets from the box-box detector.
std::unique_ptr<btCollisionShape> make_shape(const Shape& s, bool polyhedra) {
  switch (s.type) {
    case ShapeKind::Sphere:
      return std::make_unique<btSphereShape>(s.radius);
    case ShapeKind::Cylinder: {
      auto c = std::make_unique<btCylinderShapeZ>(btVector3(s.radius, s.radius, s.half_length));
      c->setMargin(0.0);  // keeps the outer size: the cylinder is exact, its rims sharp
      return c;
    }
    case ShapeKind::Hull:
      return detail::exact_hull(s.points, polyhedra);  // the hull's vertices only, exactly the points
    default: {
      auto b = std::make_unique<btBoxShape>(bt(s.half_extents));
      b->setMargin(0.0);  // the box is exactly its size
      if (polyhedra) b->initializePolyhedralFeatures();
      return b;
    }
  }
}

// A body's own bounding box in the world, without Bullet's contact margin
// (kept by KinematicWorld::updateAabbs, reached through the body's user pointer).
struct Bounds {
  btVector3 lo{0, 0, 0}, hi{0, 0, 0};
};

// The world whose kinematic bodies keep the twist coopsim sets: the base
// class would overwrite it with a one-step-late finite difference.
class KinematicWorld : public btDiscreteDynamicsWorld {
 public:
  using btDiscreteDynamicsWorld::btDiscreteDynamicsWorld;

  // btCollisionWorld::updateAabbs and updateSingleAabb, the same arithmetic,
  // also keeping each moving body's own box (its Bounds) for near_callback
  void updateAabbs() override {
    const btVector3 margin(gContactBreakingThreshold, gContactBreakingThreshold, gContactBreakingThreshold);
    btBroadphaseInterface* bp = getBroadphase();
    for (int i = 0; i < m_collisionObjects.size(); ++i) {
      btCollisionObject* o = m_collisionObjects[i];
      if (!(m_forceUpdateAllAabbs || o->isActive())) continue;
      Bounds& b = *static_cast<Bounds*>(o->getUserPointer());
      o->getCollisionShape()->getAabb(o->getWorldTransform(), b.lo, b.hi);
      btVector3 lo = b.lo - margin, hi = b.hi + margin;
      if (getDispatchInfo().m_useContinuous && o->getInternalType() == btCollisionObject::CO_RIGID_BODY &&
          !o->isStaticOrKinematicObject()) {
        btVector3 lo2, hi2;
        o->getCollisionShape()->getAabb(o->getInterpolationWorldTransform(), lo2, hi2);
        lo2 -= margin;
        hi2 += margin;
        lo.setMin(lo2);
        hi.setMax(hi2);
      }
      if (o->isStaticObject() || (hi - lo).length2() < btScalar(1e12))
        bp->setAabb(o->getBroadphaseHandle(), lo, hi, m_dispatcher1);
      else
        o->setActivationState(DISABLE_SIMULATION);  // as Bullet: something went badly wrong
    }
  }

 protected:
  void saveKinematicState(btScalar) override {}
};

// A body at rest: below these speeds (m/s, rad/s) a free body counts
// towards sleeping, and its contacts are warm-started in full (RestingSolver).
constexpr btScalar kRestSpeed = 1e-4, kRestTurn = 1e-3;
// A free body none of whose corners moves farther than this (m) from where it was over sleep_after is at
// rest too, whatever its speed: a bar standing on its 2 cm end rocks in the contact solver's residual at
// a few mm/s and tens of mrad/s for ever, going nowhere (0.06 mm back and forth, 0.1 mm/s of drift).
constexpr double kStillDistance = 2.5e-4;

bool at_rest(const btCollisionObject* o) {
  if (o->isStaticObject() && !o->isKinematicObject()) return true;  // floor and scenery
  const btRigidBody* b = btRigidBody::upcast(o);
  return b->getLinearVelocity().length2() < kRestSpeed * kRestSpeed &&
         b->getAngularVelocity().length2() < kRestTurn * kRestTurn;
}

// Bullet's solver, warm-starting the contacts between bodies at rest with
// their whole last impulses rather than Bullet's 85 %: a body resting on
// another meets the same problem step after step, so its last impulses are
// the answer, and with the world's convergence threshold its solve ends
// after one sweep instead of running all its iterations to win back the 15 %
// (never quite: a resting bar crept by 3e-8 m/s). Contacts where either body
// moves keep Bullet's factor. Bullet 3.24 warm-starts no friction.
class RestingSolver : public btSequentialImpulseConstraintSolver {
 protected:
  void convertContacts(btPersistentManifold** manifolds, int n, const btContactSolverInfo& info) override {
    btContactSolverInfo resting = info;
    resting.m_warmstartingFactor = 1;
    for (int i = 0; i < n; ++i) {
      const bool rest = at_rest(manifolds[i]->getBody0()) && at_rest(manifolds[i]->getBody1());
      convertContact(manifolds[i], rest ? resting : info);
    }
  }
};

// Bullet's box-box narrow phase, not run again for a pair while neither box
// has moved more than kStill (m, and the same in rotation) since it last ran:
// it would find the same points (a body at rest on another; moving bodies run
// it every step). The points kept are refreshed with the boxes' poses all the
// same, so their positions and depths stay exact.
constexpr btScalar kStill = 1e-12;

bool still(const btTransform& a, const btTransform& b) {
  const btVector3 d = a.getOrigin() - b.getOrigin();
  if (btMax(btMax(btFabs(d.x()), btFabs(d.y())), btFabs(d.z())) > kStill) return false;
  for (int i = 0; i < 3; ++i) {
    const btVector3 r = a.getBasis()[i] - b.getBasis()[i];
    if (btMax(btMax(btFabs(r.x()), btFabs(r.y())), btFabs(r.z())) > kStill) return false;
  }
  return true;
}

class BoxBox : public btBoxBoxCollisionAlgorithm {
 public:
  using btBoxBoxCollisionAlgorithm::btBoxBoxCollisionAlgorithm;

  void processCollision(const btCollisionObjectWrapper* a, const btCollisionObjectWrapper* b,
                        const btDispatcherInfo& info, btManifoldResult* out) override {
    const btTransform& A = a->getWorldTransform();
    const btTransform& B = b->getWorldTransform();
    if (manifold_ && still(A, a_) && still(B, b_)) {
      out->setPersistentManifold(manifold_);
      out->refreshContactPoints();
      return;
    }
    btBoxBoxCollisionAlgorithm::processCollision(a, b, info, out);
    a_ = A;
    b_ = B;
    if (!manifold_) {
      thread_local btManifoldArray manifolds;
      manifolds.resize(0);
      getAllContactManifolds(manifolds);
      if (manifolds.size() == 1) manifold_ = manifolds[0];
    }
  }

  struct CreateFunc : public btCollisionAlgorithmCreateFunc {
    btCollisionAlgorithm* CreateCollisionAlgorithm(btCollisionAlgorithmConstructionInfo& ci,
                                                   const btCollisionObjectWrapper* a,
                                                   const btCollisionObjectWrapper* b) override {
      void* mem = ci.m_dispatcher1->allocateCollisionAlgorithm(sizeof(BoxBox));
      return new (mem) BoxBox(nullptr, ci, a, b);
    }
  };

 private:
  btPersistentManifold* manifold_ = nullptr;  // set once the narrow phase has run
  btTransform a_, b_;                          // the boxes' poses when it last ran
};

// How far apart two bodies' boxes are along the world axes (m; <= 0: they overlap).
btScalar separation(const Bounds& A, const Bounds& B) {
  btVector3 d = A.lo - B.hi;
  d.setMax(B.lo - A.hi);
  return btMax(btMax(d.x(), d.y()), d.z());
}

// Whether two bodies that Bullet would test by separating axes (both polyhedral with their faces, not
// two boxes) are certainly apart: along the line between their centres (their shapes' origins) their
// supports leave a gap of more than a nanometre. Separating axes would then find an axis too and report
// nothing, at many times the cost (every face normal and edge pair of two hulls projected). Shapes that
// are apart but not along that line go to separating axes as before.
bool polyhedra_apart(const btCollisionObject* a, const btCollisionObject* b, const btDispatcherInfo& info) {
  if (!info.m_enableSatConvex) return false;
  const btCollisionShape* sa = a->getCollisionShape();
  const btCollisionShape* sb = b->getCollisionShape();
  if (!sa->isPolyhedral() || !sb->isPolyhedral()) return false;
  if (sa->getShapeType() == BOX_SHAPE_PROXYTYPE && sb->getShapeType() == BOX_SHAPE_PROXYTYPE) return false;
  const auto* pa = static_cast<const btPolyhedralConvexShape*>(sa);
  const auto* pb = static_cast<const btPolyhedralConvexShape*>(sb);
  if (!pa->getConvexPolyhedron() || !pb->getConvexPolyhedron()) return false;
  const btTransform& ta = a->getWorldTransform();
  const btTransform& tb = b->getWorldTransform();
  btVector3 n = ta.getOrigin() - tb.getOrigin();  // from B towards A
  const btScalar length = n.length();
  if (!(length > 1e-9)) return false;
  n /= length;
  const btVector3 lowest_a = ta(pa->localGetSupportingVertexWithoutMargin(-n * ta.getBasis()));
  const btVector3 highest_b = tb(pb->localGetSupportingVertexWithoutMargin(n * tb.getBasis()));
  return n.dot(lowest_a) - n.dot(highest_b) > 1e-9;
}

// Bullet's near callback, for the pairs its broad phase keeps: those within
// its contact margin (2 cm) plus its tree's margin (5 cm), most of them far
// from touching.
// - No collision algorithm and manifold is made for a pair whose boxes are
//   more than the contact margin apart: an empty manifold with a robot's link
//   wakes the free body every step (Bullet's islands), so that a body at rest
//   with an arm moving a few centimetres away would never sleep.
// - The narrow phase is skipped for a pair whose boxes are apart (by more than
//   a micrometre) and whose manifold holds no point: it would find nothing and
//   change nothing.
// - So is the narrow phase of two polyhedra (a hull and a box or a hull) whose manifold holds no point
//   and which are certainly apart (polyhedra_apart): separating axes would find nothing either.
void near_callback(btBroadphasePair& pair, btCollisionDispatcher& dispatcher, const btDispatcherInfo& info) {
  const auto* a = static_cast<const btCollisionObject*>(pair.m_pProxy0->m_clientObject);
  const auto* b = static_cast<const btCollisionObject*>(pair.m_pProxy1->m_clientObject);
  const btScalar apart = separation(*static_cast<const Bounds*>(a->getUserPointer()),
                                    *static_cast<const Bounds*>(b->getUserPointer()));
  if (!pair.m_algorithm) {
    if (apart > gContactBreakingThreshold || polyhedra_apart(a, b, info)) return;
  } else {
    thread_local btManifoldArray manifolds;
    manifolds.resize(0);
    pair.m_algorithm->getAllContactManifolds(manifolds);
    bool empty = true;
    for (int m = 0; m < manifolds.size(); ++m) empty = empty && manifolds[m]->getNumContacts() == 0;
    if (empty && (apart > 1e-6 || polyhedra_apart(a, b, info))) return;
  }
  btCollisionDispatcher::defaultNearCallback(pair, dispatcher, info);
}

}  // namespace

// Which pairs are even looked at: never two static bodies, never a pair
// the robots' descriptions exclude, never a base box and the floor it
// stands on.
struct PairFilter : public btOverlapFilterCallback {
  const std::vector<BodySpec>* specs = nullptr;
  const std::vector<std::vector<int>>* exclusions = nullptr;
  const std::vector<std::pair<int, int>>* ignored = nullptr;
  bool needBroadphaseCollision(btBroadphaseProxy* p0, btBroadphaseProxy* p1) const override {
    const int a = static_cast<const btCollisionObject*>(p0->m_clientObject)->getUserIndex();
    const int b = static_cast<const btCollisionObject*>(p1->m_clientObject)->getUserIndex();
    const BodySpec& A = (*specs)[a];
    const BodySpec& B = (*specs)[b];
    if (static_like(A.kind) && static_like(B.kind)) return false;
    if ((A.kind == BodyKind::Link && A.link == 0 && B.kind == BodyKind::Floor) ||
        (B.kind == BodyKind::Link && B.link == 0 && A.kind == BodyKind::Floor))
      return false;
    const std::vector<int>& ex = (*exclusions)[a];
    if (std::find(ex.begin(), ex.end(), b) != ex.end()) return false;
    const std::pair<int, int> p(std::min(a, b), std::max(a, b));
    return std::find(ignored->begin(), ignored->end(), p) == ignored->end();
  }
};

// Bullet's pools for manifolds and collision algorithms: its default of 4096
// each is about 7 MB written when the world is built (a millisecond of page
// faults); a few dozen pairs ever touch here, and more than the pool holds
// come from the heap.
static btDefaultCollisionConstructionInfo pool_sizes() {
  btDefaultCollisionConstructionInfo info;
  info.m_defaultMaxPersistentManifoldPoolSize = 256;
  info.m_defaultMaxCollisionAlgorithmPoolSize = 256;
  info.m_customCollisionAlgorithmMaxElementSize = sizeof(BoxBox);  // the pool's blocks must hold one
  return info;
}

struct World::Impl {
  btDefaultCollisionConfiguration config{pool_sizes()};
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  RestingSolver solver;
  KinematicWorld world{&dispatcher, &broadphase, &solver, &config};
  PairFilter filter;
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btRigidBody>> bodies;  // by body id
  std::vector<Bounds> bounds;                         // by body id
  // per free body, by id: the pose it has stayed near (kStillDistance) and for how long (s; < 0: not
  // anchored), and whether it was pushed (apply_wrench, set_velocity) since the last step
  std::vector<btTransform> anchor;
  std::vector<double> still;
  std::vector<char> pushed;
  bool polyhedra = false;  // a hull among the bodies: boxes and hulls with their faces (make_shape)

  ~Impl() {
    for (auto& b : bodies) world.removeRigidBody(b.get());
  }
};

World::World(WorldOptions options) : options_(options) {
  require(options_.gravity.allFinite() && options_.gravity.norm() <= 1e3, "gravity must be finite and at most 1e3 m/s^2");
  require(std::isfinite(options_.floor_friction) && options_.floor_friction >= 0,
          "floor_friction must be finite and >= 0");
  require(std::isfinite(options_.floor_restitution) && options_.floor_restitution >= 0 &&
              options_.floor_restitution <= 1,
          "floor_restitution must be in 0 .. 1");
  require(options_.solver_iterations >= 1 && options_.solver_iterations <= 1000,
          "solver_iterations must be in 1 .. 1000");
  require(std::isfinite(options_.sleep_after) && options_.sleep_after >= 1e-3 && options_.sleep_after <= 1e3,
          "sleep_after must be in 1e-3 .. 1e3 s");
  if (options_.floor) {
    BodySpec floor;
    floor.name = "floor";
    floor.kind = BodyKind::Floor;
    floor.friction = options_.floor_friction;
    floor.restitution = options_.floor_restitution;
    add_(floor);
  }
}

World::~World() = default;

void World::unbuild_() { impl_.reset(); }

BodyState World::state(int id) const {
  const BodySpec& s = body(id);
  BodyState out;
  if (!impl_) {
    out.pose = s.pose;
    out.velocity = s.velocity;
    out.angular_velocity = s.angular_velocity;
    return out;
  }
  const btRigidBody& b = *impl_->bodies[id];
  out.pose = s.kind == BodyKind::Floor ? Eigen::Isometry3d::Identity() : eig(b.getWorldTransform());
  out.velocity = eig(b.getLinearVelocity());
  out.angular_velocity = eig(b.getAngularVelocity());
  out.asleep = s.kind == BodyKind::Free && b.getActivationState() == ISLAND_SLEEPING;
  return out;
}

void World::build_() {
  impl_ = std::make_unique<Impl>();
  Impl& I = *impl_;
  I.filter.specs = &specs_;
  I.filter.exclusions = &exclusions_;
  I.filter.ignored = &ignored_;
  I.world.getPairCache()->setOverlapFilterCallback(&I.filter);
  I.dispatcher.setNearCallback(near_callback);
  static BoxBox::CreateFunc box_box;
  I.dispatcher.registerCollisionCreateFunc(BOX_SHAPE_PROXYTYPE, BOX_SHAPE_PROXYTYPE, &box_box);
  I.bounds.resize(specs_.size());
  I.anchor.resize(specs_.size());
  I.still.assign(specs_.size(), -1.0);
  I.pushed.assign(specs_.size(), 0);
  I.world.setGravity(bt(options_.gravity));
  // static bodies keep their bounding boxes: only moving ones are updated
  I.world.setForceUpdateAllAabbs(false);
  btContactSolverInfo& info = I.world.getSolverInfo();
  info.m_numIterations = options_.solver_iterations;
  // split impulses for every penetration: the default (-0.04) folds
  // penetrations under 4 cm into the velocity impulse, which launches bodies
  info.m_splitImpulsePenetrationThreshold = 0;
  // two friction directions: one lets a body creep on an incline it should stick to
  info.m_solverMode |= SOLVER_USE_2_FRICTION_DIRECTIONS;
  // contacts settle 1e-11 m deep rather than at zero depth: a resting body's converged solve
  // holds it there exactly, and at zero it would sit a round-off (1e-14 m) off its support half
  // the time, where a manifold made afresh (filters changed at a grasp) finds no contact. (A
  // body set down exactly touching sinks those 1e-11 m in its first step: the next step's
  // force exceeds its weight by 1e-11 m / (g dt^2), 3e-5 at 0.2 ms.)
  info.m_linearSlop = 1e-11;
  // the solver's sweeps stop once one changes no velocity by more than 1e-10 m/s
  // (converged; Bullet's default 0 always runs every iteration)
  info.m_leastSquaresResidualThreshold = 1e-20;
  // a world with a hull gives its boxes and hulls their faces (the polyhedral contacts, exact by
  // separating axes); a world of boxes alone keeps Bullet's box-box detector and nothing else
  I.polyhedra = std::any_of(specs_.begin(), specs_.end(), [](const BodySpec& s) { return s.type == ShapeKind::Hull; });
  if (I.polyhedra) I.world.getDispatchInfo().m_enableSatConvex = true;
  for (size_t id = 0; id < specs_.size(); ++id) {
    const BodySpec& s = specs_[id];
    std::unique_ptr<btCollisionShape> shape;
    if (s.kind == BodyKind::Floor) {
      // a slab under z = 0 rather than a plane: a plane's bounding box is
      // infinite, so every link box would be tested against it every step
      Shape slab;
      slab.half_extents.setConstant(kFloorHalf);
      shape = make_shape(slab, I.polyhedra);
    } else {
      shape = make_shape(s, I.polyhedra);
    }
    btVector3 inertia(0, 0, 0);
    const double mass = s.kind == BodyKind::Free ? s.mass : 0.0;
    if (mass > 0) shape->calculateLocalInertia(mass, inertia);
    btRigidBody::btRigidBodyConstructionInfo ci(mass, nullptr, shape.get(), inertia);
    ci.m_friction = s.friction;
    ci.m_restitution = s.restitution;
    ci.m_startWorldTransform = s.kind == BodyKind::Floor ? btTransform(btMatrix3x3::getIdentity(), btVector3(0, 0, -kFloorHalf))
                                                         : bt(s.pose);
    auto body = std::make_unique<btRigidBody>(ci);
    body->setUserIndex(static_cast<int>(id));
    body->setUserPointer(&I.bounds[id]);
    shape->getAabb(body->getWorldTransform(), I.bounds[id].lo, I.bounds[id].hi);
    // a robot's base boxes (link 0) never move: they stay static bodies, which Bullet never
    // updates; the others are kinematic, moved every step
    const bool moving_link = s.kind == BodyKind::Link && s.link != 0;
    if (moving_link) body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
    if (s.kind == BodyKind::Free) {
      body->setLinearVelocity(bt(s.velocity));
      body->setAngularVelocity(bt(s.angular_velocity));
    }
    if (moving_link) body->setActivationState(DISABLE_DEACTIVATION);
    // a free body at rest (below 0.1 mm/s and 1 mrad/s) for Bullet's 2 s sleeps: it costs nothing
    // then, keeps the contact forces it last had, and wakes when touched or pushed
    if (s.kind == BodyKind::Free) body->setSleepingThresholds(kRestSpeed, kRestTurn);
    I.world.addRigidBody(body.get());
    I.shapes.push_back(std::move(shape));
    I.bodies.push_back(std::move(body));
  }
}

void World::set_link(int id, const Eigen::Isometry3d& pose, const Eigen::Vector3d& velocity,
                     const Eigen::Vector3d& angular_velocity) {
  if (!impl_) build_();
  btRigidBody& b = *impl_->bodies[id];
  if (!b.isKinematicObject()) return;  // a base box: where it was built, at rest
  const btTransform T = bt(pose);
  b.setWorldTransform(T);
  b.setInterpolationWorldTransform(T);
  b.setLinearVelocity(bt(velocity));
  b.setAngularVelocity(bt(angular_velocity));
}

void World::apply_wrench(int id, const Eigen::Vector3d& force, const Eigen::Vector3d& moment) {
  if (!impl_) build_();
  btRigidBody& b = *impl_->bodies[id];
  b.activate();
  impl_->pushed[id] = 1;
  b.applyCentralForce(bt(force));
  b.applyTorque(bt(moment));
}

void World::set_velocity(int id, const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity) {
  if (!impl_) build_();
  btRigidBody& b = *impl_->bodies[id];
  b.activate();
  impl_->pushed[id] = 1;
  b.setLinearVelocity(bt(velocity));
  b.setAngularVelocity(bt(angular_velocity));
}

void World::set_ignored(std::vector<std::pair<int, int>> pairs) {
  for (auto& p : pairs)
    if (p.first > p.second) std::swap(p.first, p.second);
  std::sort(pairs.begin(), pairs.end());
  if (pairs == ignored_) return;
  std::vector<std::pair<int, int>> changed;
  std::set_symmetric_difference(pairs.begin(), pairs.end(), ignored_.begin(), ignored_.end(),
                                std::back_inserter(changed));
  ignored_ = std::move(pairs);
  if (!impl_) return;
  // the pairs of the free bodies whose filtering changed are made again, through the filter
  // (only theirs: a body's pairs made again lose their contacts' last impulses)
  Impl& I = *impl_;
  std::vector<int> ids;
  for (const auto& [a, b] : changed)
    for (int id : {a, b})
      if (specs_[id].kind == BodyKind::Free && std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);
  std::sort(ids.begin(), ids.end());
  for (int id : ids) I.world.refreshBroadphaseProxy(I.bodies[id].get());
}

void World::step(double dt, double t) {
  if (!impl_) build_();
  Impl& I = *impl_;
  I.world.stepSimulation(dt, 0);  // exactly one step of dt
  // Bullet counts a body's time at rest against its global 2 s (gDeactivationTime, read only
  // here): a body at rest this step is moved on faster so that it sleeps after sleep_after
  const btScalar extra = dt * (gDeactivationTime / options_.sleep_after - 1.0);
  for (const auto& b : I.bodies) {
    if (!b || b->isStaticOrKinematicObject()) continue;
    const int state = b->getActivationState();
    if ((state == ACTIVE_TAG || state == WANTS_DEACTIVATION) && b->getDeactivationTime() > 0)
      b->setDeactivationTime(std::max<btScalar>(b->getDeactivationTime() + extra, dt));
  }
  // a free body that stayed within kStillDistance of a pose for sleep_after sleeps as Bullet's own rule would
  // put it to sleep (its island's other bodies, if any are awake, wake it again at the next step); a body
  // pushed since the last step is not at rest
  for (size_t id = 0; id < I.bodies.size(); ++id) {
    btRigidBody* b = I.bodies[id].get();
    if (!b || specs_[id].kind != BodyKind::Free) continue;
    const int state = b->getActivationState();
    if (I.pushed[id] || (state != ACTIVE_TAG && state != WANTS_DEACTIVATION)) {
      I.pushed[id] = 0;
      I.still[id] = -1.0;
      continue;
    }
    const btTransform& T = b->getWorldTransform();
    const btVector3 h = bt(specs_[id].half_extents);
    double moved = 0.0;
    if (I.still[id] >= 0.0)
      for (int c = 0; c < 8; ++c) {
        const btVector3 p((c & 1 ? 1 : -1) * h.x(), (c & 2 ? 1 : -1) * h.y(), (c & 4 ? 1 : -1) * h.z());
        moved = std::max<double>(moved, (T(p) - I.anchor[id](p)).length());
      }
    if (I.still[id] < 0.0 || moved > kStillDistance) {
      I.anchor[id] = T;
      I.still[id] = 0.0;
    } else if ((I.still[id] += dt) >= options_.sleep_after) {
      b->setLinearVelocity(btVector3(0, 0, 0));
      b->setAngularVelocity(btVector3(0, 0, 0));
      b->setActivationState(ISLAND_SLEEPING);
      I.still[id] = -1.0;
    }
  }
  // a free body that left the world or whose state stopped being finite: the run has diverged
  for (size_t id = 0; id < I.bodies.size(); ++id) {
    const auto& b = I.bodies[id];
    if (!b || specs_[id].kind != BodyKind::Free) continue;
    const btVector3& p = b->getWorldTransform().getOrigin();
    const btVector3 &v = b->getLinearVelocity(), &w = b->getAngularVelocity();
    const bool finite = std::isfinite(p.length2()) && std::isfinite(v.length2()) && std::isfinite(w.length2()) &&
                        std::isfinite(b->getWorldTransform().getBasis()[0].length2() +
                                      b->getWorldTransform().getBasis()[1].length2() +
                                      b->getWorldTransform().getBasis()[2].length2());
    if (!finite || p.length() > kWorldRadius || v.length() > kDivergedSpeed || w.length() > kDivergedSpeed ||
        b->getActivationState() == DISABLE_SIMULATION) {
      std::ostringstream msg;
      msg << "free body '" << specs_[id].name << "' diverged at t = " << t + dt << " s (dt = " << dt
          << " s): position " << eig(p).transpose() << " m, velocity " << eig(v).transpose() << " m/s, angular velocity "
          << eig(w).transpose() << " rad/s"
          << (finite ? " (beyond 1e6 m or 1e5 m/s or rad/s)" : " (no longer finite)");
      throw WorldDivergence(msg.str(), static_cast<int>(id));
    }
  }
  contacts_.clear();
  const int nm = I.dispatcher.getNumManifolds();
  for (int m = 0; m < nm; ++m) {
    const btPersistentManifold* man = I.dispatcher.getManifoldByIndexInternal(m);
    const int i0 = static_cast<const btCollisionObject*>(man->getBody0())->getUserIndex();
    const int i1 = static_cast<const btCollisionObject*>(man->getBody1())->getUserIndex();
    const bool solved = specs_[i0].kind == BodyKind::Free || specs_[i1].kind == BodyKind::Free;
    for (int j = 0; j < man->getNumContacts(); ++j) {
      const btManifoldPoint& p = man->getContactPoint(j);
      const double lambda = p.getAppliedImpulse();
      if (p.getDistance() > 0.0 && lambda == 0.0) continue;  // kept past separation, no force
      ContactPoint c;
      c.a = i0;
      c.b = i1;
      c.point_a = eig(p.getPositionWorldOnA());
      c.point_b = eig(p.getPositionWorldOnB());
      c.normal = eig(p.m_normalWorldOnB);
      c.depth = -p.getDistance();
      c.solver = solved;
      if (solved)
        c.force = (c.normal * lambda + eig(p.m_lateralFrictionDir1) * p.m_appliedImpulseLateral1 +
                   eig(p.m_lateralFrictionDir2) * p.m_appliedImpulseLateral2) /
                  dt;
      // a is the body added first: names come out in a fixed order
      if (c.a > c.b) {
        std::swap(c.a, c.b);
        std::swap(c.point_a, c.point_b);
        c.normal = -c.normal;
        c.force = -c.force;
      }
      contacts_.push_back(c);
    }
  }
}

void World::record_events(double t) {
  // the pairs touching in this step (contacts come grouped by pair), with
  // their total force and deepest point
  touching_.clear();
  for (const ContactPoint& c : contacts_) {
    // touching: in contact, or carrying a force (the solver holds a body resting a round-off
    // apart, 1e-14 m, as firmly as one resting a round-off in)
    if (c.depth < 0 && c.force.squaredNorm() == 0.0) continue;
    if (touching_.empty() || touching_.back().a != c.a || touching_.back().b != c.b) {
      ContactEvent e;
      e.a = c.a;
      e.b = c.b;
      touching_.push_back(e);
      touching_force_.resize(touching_.size());
      touching_force_.back().setZero();
    }
    touching_force_[touching_.size() - 1] += c.force;
    touching_.back().max_depth = std::max(touching_.back().max_depth, c.depth);
  }
  auto is_touching = [&](const std::pair<int, int>& p) {
    for (const ContactEvent& e : touching_)
      if (e.a == p.first && e.b == p.second) return true;
    return false;
  };
  for (auto it = open_.begin(); it != open_.end();) {
    if (!is_touching(it->first)) {
      events_[it->second].end = t;
      it = open_.erase(it);
    } else {
      ++it;
    }
  }
  for (size_t k = 0; k < touching_.size(); ++k) {
    const std::pair<int, int> pair(touching_[k].a, touching_[k].b);
    auto it = open_.find(pair);
    if (it == open_.end()) {
      ContactEvent e;
      e.a = pair.first;
      e.b = pair.second;
      e.begin = t;
      events_.push_back(e);
      it = open_.emplace(pair, events_.size() - 1).first;
    }
    ContactEvent& e = events_[it->second];
    e.peak_force = std::max(e.peak_force, touching_force_[k].norm());
    e.max_depth = std::max(e.max_depth, touching_[k].max_depth);
    ++e.steps;
  }
}

void World::reset() {
  clear_robots();  // their owner brings them back at its next first step
  ignored_.clear();
  impl_.reset();
  contacts_.clear();
  events_.clear();
  open_.clear();
}

// ---- a robot's link bodies replaced in place ----

void World::replace_robot_boxes(int first, const std::vector<Shape>& shapes,
                                const std::vector<Eigen::Isometry3d>& poses,
                                const std::vector<std::pair<int, int>>& excluded) {
  const int k = static_cast<int>(shapes.size());
  require(first >= 0 && first + k <= body_count() && static_cast<int>(poses.size()) == k,
          "replace_robot_boxes: bodies out of range");
  const int robot = k ? specs_[first].robot : -1;
  for (int b = 0; b < k; ++b)
    require(specs_[first + b].kind == BodyKind::Link && specs_[first + b].robot == robot,
            "replace_robot_boxes: not the bodies of one robot");
  for (int b = 0; b < k; ++b) {
    static_cast<Shape&>(specs_[first + b]) = shapes[b];
    specs_[first + b].pose = poses[b];
    exclusions_[first + b].clear();  // a robot's exclusions are among its own bodies
  }
  for (const auto& [i, j] : excluded) {
    exclusions_[first + i].push_back(first + j);
    exclusions_[first + j].push_back(first + i);
  }
  if (!impl_) return;  // built with these at the next step
  const bool hulls = std::any_of(shapes.begin(), shapes.end(), [](const Shape& s) { return s.type == ShapeKind::Hull; });
  Impl& I = *impl_;
  if (hulls && !I.polyhedra) {  // the boxes get their faces now (make_shape with polyhedra)
    I.polyhedra = true;
    I.world.getDispatchInfo().m_enableSatConvex = true;
    for (auto& shape : I.shapes)
      if (shape->getShapeType() == BOX_SHAPE_PROXYTYPE) static_cast<btBoxShape&>(*shape).initializePolyhedralFeatures();
  }
  for (int b = 0; b < k; ++b) {
    const int id = first + b;
    btRigidBody& body = *I.bodies[id];
    I.world.removeRigidBody(&body);  // its pairs and contact manifolds go with it
    std::unique_ptr<btCollisionShape> shape = make_shape(shapes[b], I.polyhedra);
    body.setCollisionShape(shape.get());
    body.setWorldTransform(bt(poses[b]));
    body.setInterpolationWorldTransform(body.getWorldTransform());
    shape->getAabb(body.getWorldTransform(), I.bounds[id].lo, I.bounds[id].hi);
    I.world.addRigidBody(&body);
    I.shapes.push_back(std::move(shape));  // the old shape stays owned (unused) until the world is rebuilt
  }
}

}  // namespace coopsim
