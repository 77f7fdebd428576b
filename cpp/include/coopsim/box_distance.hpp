// Distances between boxes (cpp/src/box_distance.cpp): queries on poses and sizes alone, apart
// from any world. The separating-axis bounds they build on (box_gap, box_penetration) are declared
// in robot.hpp with the links' geometry.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "coopsim/checks.hpp"
#include "coopsim/shape.hpp"

namespace coopsim {

// Distance between two boxes (world poses of their centres, half extents), m:
// > 0 the gap between their nearest points, <= 0 minus the depth of their
// overlap (Bullet's GJK with EPA, margins zero, double precision). Rows i, j
// of `out` (na x nb) for every pair of the two lists (box_distances).
double box_distance(const Eigen::Isometry3d& a, const Eigen::Vector3d& half_a, const Eigen::Isometry3d& b,
                    const Eigen::Vector3d& half_b);
void box_distances(const std::vector<Eigen::Isometry3d>& a, const std::vector<Eigen::Vector3d>& half_a,
                   const std::vector<Eigen::Isometry3d>& b, const std::vector<Eigen::Vector3d>& half_b,
                   double* out);
// The clearance between two sets of boxes in each of `rows` configurations: the smallest
// box_distance over every pair (box of set A, box of set B) and the pair that has it (d, ia, ib:
// rows values each). a: rows x na poses, row by row; b: rows x nb poses, or nb poses when
// b_static (boxes that do not move). The same minimum as box_distances on every pair, found with
// far fewer GJK calls: each row starts from the previous row's nearest pair, and a pair goes to
// GJK only if no lower bound of its distance shows it cannot be nearer: its bound from an earlier
// row less how far its boxes can have moved since, its bounding spheres, its separating axes.
void box_clearances(int rows, const std::vector<Eigen::Isometry3d>& a, const std::vector<Eigen::Vector3d>& half_a,
                    const std::vector<Eigen::Isometry3d>& b, const std::vector<Eigen::Vector3d>& half_b,
                    bool b_static, double* d, long* ia, long* ib);

// Distance between two convex shapes of any kind (Shape: box, sphere, cylinder, hull) at the world poses
// of their frames, m: > 0 the gap between their nearest points (Bullet's GJK, margins zero), <= 0 minus
// the depth of their overlap (two boxes: the separating-axis depth, exact; any other pair: Bullet's
// EPA). Two boxes give box_distance's value.
double shape_distance(const Shape& a, const Eigen::Isometry3d& pose_a, const Shape& b, const Eigen::Isometry3d& pose_b);
// box_clearances of shapes of any kind (the world poses of their frames): shape_distance's minimum
// over every pair, with the same lower bounds (their bounds' spheres and separating axes: a shape lies
// in its bound); for boxes alone box_clearances itself.
void shape_clearances(int rows, const std::vector<Eigen::Isometry3d>& a, const std::vector<Shape>& shapes_a,
                      const std::vector<Eigen::Isometry3d>& b, const std::vector<Shape>& shapes_b, bool b_static,
                      double* d, long* ia, long* ib);

// The same from tables, with the checks of their shapes (throwing std::invalid_argument naming
// the argument): box_distance of pose_a (4, 4), half_a (3,), pose_b, half_b; box_distances of
// poses_a (Na, 4, 4), half_a (Na, 3), poses_b (Nb, 4, 4), half_b (Nb, 3): (Na, Nb), or with
// pairwise (Na == Nb) (Na,) for box i with box i.
double box_distance(const Array& pose_a, const Array& half_a, const Array& pose_b, const Array& half_b);
Array box_distances(const Array& poses_a, const Array& half_a, const Array& poses_b, const Array& half_b,
                    bool pairwise);
// box_clearances of poses_a (N, ka, 4, 4) (read in place: the caller keeps the tables), half_a (ka, 3), poses_b (N, kb, 4, 4) or (kb, 4, 4)
// (boxes that do not move), half_b (kb, 3): N rows each of d, ia, ib.
struct BoxClearances {
  std::vector<double> d;
  std::vector<long> ia, ib;
};
BoxClearances box_clearances(const ArrayView& poses_a, const Array& half_a, const ArrayView& poses_b, const Array& half_b);
// The same of shapes of any kind: poses_a (N, ka, 4, 4) of shapes_a's ka shapes, poses_b (N, kb, 4, 4)
// or (kb, 4, 4) of shapes_b's kb.
BoxClearances shape_clearances(const ArrayView& poses_a, const std::vector<Shape>& shapes_a, const ArrayView& poses_b,
                               const std::vector<Shape>& shapes_b);

}  // namespace coopsim
