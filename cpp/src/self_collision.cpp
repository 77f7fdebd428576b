// The self-collision exclusion list of a robot: the pairs of its link shapes that the world never
// tests against each other (Simulation::excluded_pairs). Boxes by their separating axes, any other
// pair of convex shapes (spheres, cylinders, hulls) by GJK where their bounds overlap.
#include <cmath>
#include <random>

#include "coopsim/box_distance.hpp"
#include "coopsim/simulation.hpp"

namespace coopsim {

namespace {

std::vector<std::pair<int, int>> sampled_exclusions(const Robot& r, int samples) {
  const std::vector<LinkBox>& boxes = r.boxes();
  const int k = static_cast<int>(boxes.size()), n = r.dof();
  std::vector<std::pair<int, int>> out, candidates;
  for (int i = 0; i < k; ++i)
    for (int j = i + 1; j < k; ++j) {
      if (std::abs(boxes[i].link - boxes[j].link) <= 1) out.emplace_back(i, j);
      else candidates.emplace_back(i, j);
    }
  // the others that touch at every sampled pose (MoveIt's way), from a fixed seed
  std::mt19937 rng(12345);
  std::vector<char> always(candidates.size(), 1);
  Workspace ws;
  std::vector<Eigen::Isometry3d> poses;
  VecN q(n);
  for (int s = 0; s < samples; ++s) {
    for (int j = 0; j < n; ++j) {
      const Link& L = r.links()[j];
      const double span = L.type == JointType::Revolute ? M_PI : 0.5;
      const double lo = std::isfinite(L.q_min) ? L.q_min : -span, hi = std::isfinite(L.q_max) ? L.q_max : span;
      q[j] = std::uniform_real_distribution<double>(lo, hi)(rng);
    }
    r.kinematics(q.data(), ws);
    r.box_poses(ws, poses);
    for (size_t c = 0; c < candidates.size(); ++c) {
      const auto [i, j] = candidates[c];
      if (!always[c]) continue;
      // apart: their bounds are (for boxes, the boxes themselves), or GJK says so
      if (box_penetration(poses[i], boxes[i].half_extents, poses[j], boxes[j].half_extents) <= -1e-9 ||
          (!(boxes[i].is_box() && boxes[j].is_box()) && shape_distance(boxes[i], poses[i], boxes[j], poses[j]) >= 1e-9))
        always[c] = 0;
    }
  }
  for (size_t c = 0; c < candidates.size(); ++c)
    if (always[c]) out.push_back(candidates[c]);
  return out;
}

}  // namespace

std::vector<std::pair<int, int>> Simulation::excluded_pairs(const Robot& r, int samples) {
  if (samples != kExclusionSamples) return sampled_exclusions(r, samples);
  // the default sampling's pairs: once per geometry, every simulation of the robot's copies reads them
  Robot::GeometryMemo& memo = r.geometry_memo();
  std::call_once(memo.excluded_once, [&] { memo.excluded = sampled_exclusions(r, samples); });
  return memo.excluded;
}

}  // namespace coopsim
