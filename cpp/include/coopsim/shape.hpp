// A convex shape: a box, a sphere, a cylinder or the convex hull of points, in its own frame (the
// frame a pose places it in). What a robot's links and the world's bodies collide as: the box model
// (half extents) for robots built from tables and for the world's own bodies, the others for robots
// whose geometry came from a description (a URDF's <collision> spheres, cylinders and meshes).
// Eigen only: robot.hpp (LinkBox) and world.hpp (BodySpec) build on it.
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

namespace coopsim {

enum class ShapeKind : char { Box, Sphere, Cylinder, Hull };
// "box", "sphere", "cylinder", "hull"
const char* shape_kind_name(ShapeKind k);

// A convex shape in its own frame (m). Every kind keeps `half_extents`: for a box its half extents, for
// the others the half extents of a box centred at the frame's origin, along its axes, that holds the
// shape (its bound: what separating-axis bounds, bounding spheres and the box views use).
struct Shape {
  ShapeKind type = ShapeKind::Box;
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();  // m, each > 0 (the box, or the bound)
  double radius = 0.0;                                     // sphere, cylinder: m, > 0
  double half_length = 0.0;                                // cylinder: half its length along its z, m, > 0
  std::vector<Eigen::Vector3d> points;                     // hull: its points (4 or more, not coplanar), m
  bool is_box() const { return type == ShapeKind::Box; }
};

// Most points a hull may have (its support function is a linear search over them).
constexpr int kMaxHullPoints = 4096;

// Checks a shape's values for its kind and sets the bound (half_extents) of a sphere, a cylinder or a
// hull from them; throws std::invalid_argument starting with `who` naming what is wrong: sizes not
// finite or not > 0, a hull of fewer than 4 or more than kMaxHullPoints points, or of points on one
// plane (no volume).
void finish_shape(Shape& s, const std::string& who);

}  // namespace coopsim
