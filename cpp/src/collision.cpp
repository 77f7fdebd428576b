#include "coopsim/collision.hpp"

#include <btBulletCollisionCommon.h>

#include <cmath>
#include <stdexcept>

namespace coopsim {

namespace {

constexpr double kMinSize = 1e-4, kMaxSize = 1e4;  // m: shape sizes Bullet handles well
constexpr double kMaxDistance = 1e6;               // m: positions from the world origin

btTransform to_bt(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  btMatrix3x3 b(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2));
  return btTransform(b, btVector3(T.translation().x(), T.translation().y(), T.translation().z()));
}

Eigen::Isometry3d from_bt(const btTransform& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const btMatrix3x3& b = t.getBasis();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) T.linear()(i, j) = b[i][j];
  T.translation() << t.getOrigin().x(), t.getOrigin().y(), t.getOrigin().z();
  return T;
}

Eigen::Vector3d from_bt(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

void check_pose(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) throw std::invalid_argument("pose must be finite");
  if (T.translation().norm() > kMaxDistance) throw std::invalid_argument("pose must lie within 1e6 m of the origin");
  const Eigen::Matrix3d R = T.linear();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-9 || R.determinant() <= 0)
    throw std::invalid_argument("pose must be a rigid transform (orthonormal rotation)");
}

}  // namespace

struct CollisionWorld::Impl {
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btCollisionWorld world{&dispatcher, &broadphase, &config};
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btCollisionObject>> objects;
  std::vector<std::string> names;

  ~Impl() {
    for (auto& o : objects) world.removeCollisionObject(o.get());
  }

  int add(std::unique_ptr<btCollisionShape> shape, const Eigen::Isometry3d& pose, const std::string& name) {
    check_pose(pose);
    auto obj = std::make_unique<btCollisionObject>();
    obj->setCollisionShape(shape.get());
    obj->setWorldTransform(to_bt(pose));
    const int id = static_cast<int>(objects.size());
    obj->setUserIndex(id);
    world.addCollisionObject(obj.get());
    shapes.push_back(std::move(shape));
    objects.push_back(std::move(obj));
    names.push_back(name.empty() ? "shape" + std::to_string(id) : name);
    return id;
  }
};

CollisionWorld::CollisionWorld() : impl_(std::make_unique<Impl>()) {}
CollisionWorld::~CollisionWorld() = default;

void CollisionWorld::check_id_(int id) const {
  if (id < 0 || id >= size())
    throw std::invalid_argument("shape id " + std::to_string(id) + " out of range [0, " +
                                std::to_string(size()) + ")");
}

int CollisionWorld::add_box(const Eigen::Vector3d& half_extents, const Eigen::Isometry3d& pose,
                            const std::string& name) {
  // Bullet's collision margins and tolerances are absolute: sizes far from
  // a metre lose contacts or report wrong depths
  if (!half_extents.allFinite() || (half_extents.array() < kMinSize).any() || (half_extents.array() > kMaxSize).any())
    throw std::invalid_argument("half_extents must be in 1e-4 .. 1e4 m");
  auto shape = std::make_unique<btBoxShape>(btVector3(half_extents.x(), half_extents.y(), half_extents.z()));
  shape->setMargin(0.0);
  return impl_->add(std::move(shape), pose, name);
}

int CollisionWorld::add_sphere(double radius, const Eigen::Isometry3d& pose, const std::string& name) {
  if (!std::isfinite(radius) || radius < kMinSize || radius > kMaxSize)
    throw std::invalid_argument("radius must be in 1e-4 .. 1e4 m");
  return impl_->add(std::make_unique<btSphereShape>(radius), pose, name);
}

void CollisionWorld::set_pose(int id, const Eigen::Isometry3d& pose) {
  check_id_(id);
  check_pose(pose);
  impl_->objects[id]->setWorldTransform(to_bt(pose));
}

Eigen::Isometry3d CollisionWorld::pose(int id) const {
  check_id_(id);
  return from_bt(impl_->objects[id]->getWorldTransform());
}

const std::string& CollisionWorld::name(int id) const {
  check_id_(id);
  return impl_->names[id];
}

int CollisionWorld::size() const { return static_cast<int>(impl_->objects.size()); }

std::vector<Contact> CollisionWorld::contacts() {
  impl_->world.updateAabbs();
  impl_->world.performDiscreteCollisionDetection();
  std::vector<Contact> out;
  btDispatcher* d = impl_->world.getDispatcher();
  const int nm = d->getNumManifolds();
  for (int i = 0; i < nm; ++i) {
    btPersistentManifold* m = d->getManifoldByIndexInternal(i);
    const int ia = static_cast<const btCollisionObject*>(m->getBody0())->getUserIndex();
    const int ib = static_cast<const btCollisionObject*>(m->getBody1())->getUserIndex();
    for (int j = 0; j < m->getNumContacts(); ++j) {
      const btManifoldPoint& p = m->getContactPoint(j);
      if (p.getDistance() > 0.0) continue;  // manifold points kept past separation
      Contact c;
      c.a = ia;
      c.b = ib;
      c.point_a = from_bt(p.getPositionWorldOnA());
      c.point_b = from_bt(p.getPositionWorldOnB());
      c.normal = from_bt(p.m_normalWorldOnB);
      c.depth = p.getDistance();
      out.push_back(c);
    }
  }
  return out;
}

}  // namespace coopsim
