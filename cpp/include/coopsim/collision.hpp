// Collision detection with Bullet (double precision): shapes placed in the
// world and queried for contacts. Bullet appears only behind this interface.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <memory>
#include <string>
#include <vector>

namespace coopsim {

// One contact point between two shapes. normal points from b to a (Bullet's
// convention for the normal on b); depth < 0 means penetration, in metres.
struct Contact {
  int a = -1, b = -1;
  Eigen::Vector3d point_a, point_b, normal;
  double depth = 0.0;
};

class CollisionWorld {
 public:
  CollisionWorld();
  ~CollisionWorld();
  CollisionWorld(const CollisionWorld&) = delete;
  CollisionWorld& operator=(const CollisionWorld&) = delete;

  // Adds a box (half extents in m) / sphere (radius in m) at a world pose;
  // returns its id (0, 1, ...).
  int add_box(const Eigen::Vector3d& half_extents, const Eigen::Isometry3d& pose, const std::string& name = "");
  int add_sphere(double radius, const Eigen::Isometry3d& pose, const std::string& name = "");
  void set_pose(int id, const Eigen::Isometry3d& pose);
  Eigen::Isometry3d pose(int id) const;
  const std::string& name(int id) const;
  int size() const;
  // All contact points between pairs of touching or penetrating shapes.
  std::vector<Contact> contacts();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  void check_id_(int id) const;
};

}  // namespace coopsim
