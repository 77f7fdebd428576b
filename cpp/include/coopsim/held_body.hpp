// Two holders of one free body (two clamps welded to it): what their welds do to it together.
//
// Holder k (a, b) acts on the body at its weld's point p_k (world, m) with the wrench h_k = [f_k; mu_k]
// (force N, moment N m about p_k, world axes): Simulation::weld_wrench. About the body's reference
// point c, its centre of mass, the grasp matrix W = [W_a W_b], W_k = [[I, 0], [S(p_k - c), I]] (6 x 12,
// S(r) x = r x x) maps the holders' wrenches to the net wrench on the body, the external wrench
// h_c = W [h_a; h_b]: what moves the body (at rest it balances the body's weight).
//
// The internal wrench is the part of [h_a; h_b] in W's null space, which does nothing to the body's
// motion. Which part that is depends on how the external wrench is said to be shared (a metric); here
// it is shared as two pins would share it: the weighted least norm sum_k |f_k|^2 + lambda^2 |mu_k|^2 in
// the limit lambda -> infinity, i.e. the holders' forces carry all they can (the lever rule across the
// line between the points, an even split along it) and their moments only what forces at two points
// cannot, the moment about that line (split evenly). With e = (p_b - p_a) / |p_b - p_a|, L = |p_b - p_a|
// and m = (mu_a + mu_b) . e / 2, that gives in closed form
//   internal = [t; mu_a - m e; -t; mu_b - m e],  t = s e - e x (mu_a + mu_b) / L,  s = (f_a - f_b) . e / 2
// so that two pins (mu_k = 0) holding a body at rest carry no internal wrench however unevenly they
// share its weight. Its parts:
//   squeeze s (N): the internal force along the line, > 0 when the clamps push the body together
//     (compression), < 0 when they pull it apart (tension), the virtual linkage's force with the sign
//     turned; the same whatever the metric, as long as it treats both holders alike;
//   twist (N m): (mu_a - mu_b) . e / 2, the moment about the line that holder a applies and b opposes
//     (wringing the body);
//   bending (N m, 2): |mu_a - (mu_a . e) e|, |mu_b - (mu_b . e) e|, each weld's moment across the line;
//   shear (N): |e x (mu_a + mu_b)| / L, the opposite forces across the line that balance those moments.
// Points less than 1e-9 m apart count as one: then no line, internal = [d; -d] with d = (h_a - h_b) / 2,
// and squeeze, twist, bending, shear are NaN.
//
// Load share: each holder's part of the vertical load, f_k . up / (f_a + f_b) . up (up: against
// gravity); NaN when the sum is zero. For pins at rest it is the lever rule,
// |c_perp - p_b| / L for a (c's projection on the line).
//
// Relative pose error: the clamps' relative pose now against the one they had when the second weld
// attached (what a leader-follower controller keeps small). Each clamp's frame is its clamp link's
// orientation at its weld's point (Slot::Grasp::anchor_link); with X0 = T_a0^-1 T_b0 at that instant,
// b's frame is expected at T_a X0, and the error is [p_b - (T_a X0).p; rotation vector of
// R_b (R_a X0.R)^T] (m, rad; world axes).
#pragma once

#include <array>

#include <Eigen/Geometry>

#include "coopsim/robot.hpp"

namespace coopsim {

using Vec12 = Eigen::Matrix<double, 12, 1>;

// W (6 x 12): the net wrench about c of wrenches applied at pa and pb.
Eigen::Matrix<double, 6, 12> grasp_matrix(const Eigen::Vector3d& c, const Eigen::Vector3d& pa,
                                          const Eigen::Vector3d& pb);

// What two welds do to one body, and how the clamps hold together (see the header comment).
struct Cooperation {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero(), point_a = Eigen::Vector3d::Zero(),
                  point_b = Eigen::Vector3d::Zero();  // m, world
  Vec6 external = Vec6::Zero();                        // N, N m about the centre
  Vec12 internal = Vec12::Zero();                      // [h_a; h_b] internal parts, N, N m about each point
  double squeeze = 0.0, twist = 0.0, shear = 0.0;      // N, N m, N
  Eigen::Vector2d bending = Eigen::Vector2d::Zero();   // N m, at a and at b
  Eigen::Vector2d load_share = Eigen::Vector2d::Zero();  // the holders' shares of the body's weight
  Vec6 relative_pose_error = Vec6::Zero();             // m, rad
};

// The wrenches' quantities of two holders (relative_pose_error left zero). up: the vertical, against
// gravity (any length; std::invalid_argument when zero or not finite).
Cooperation cooperation(const Eigen::Vector3d& centre, const Eigen::Vector3d& pa, const Vec6& ha,
                        const Eigen::Vector3d& pb, const Vec6& hb, const Eigen::Vector3d& up);

// b's pose error against a's: [dp (3) m; rotation vector (3) rad], world axes (see the header comment).
Vec6 relative_pose_error(const Eigen::Isometry3d& Ta, const Eigen::Isometry3d& Tb, const Eigen::Isometry3d& X0);

// The log's cooperation columns of a pair of robots, in row order: name, width, what a row holds.
struct CooperationColumn {
  const char* name;
  int width;
  const char* doc;
};
constexpr int kCooperationColumns = 12;
constexpr int kCooperationWidth = 41;  // the widths' sum
const std::array<CooperationColumn, kCooperationColumns>& cooperation_schema();
// One log row (kCooperationWidth values): the world id of the body both hold and c's values, or, with
// c null (they do not hold one body), -1 and NaN elsewhere.
void cooperation_row(int body, const Cooperation* c, double* row);

}  // namespace coopsim
