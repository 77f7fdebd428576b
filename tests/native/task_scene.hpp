// The cooperative task's scene (coopsim.tasks.scene) built in C++ for the native drivers of tests/native:
// SCARA #1 and #2 (the tables of coopsim.robots with the scene's base heights and placement), the floor,
// the inclined container's four walls and a free bar on the floor. make_run() gives one simulation of
// it: SCARA #2 comes down over the bar, closes its jaw (the clamp rule grasps it), lifts and carries
// it; SCARA #1 presses its clamp onto the container (penalty contacts). The runs differ in the bar's
// start (the task's randomised region), the controllers (computed torque on the generated dynamics,
// PID on the numeric ones) and the step sizes.
#pragma once

#include <array>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "coopsim/controller.hpp"
#include "coopsim/generated.hpp"
#include "coopsim/ik.hpp"
#include "coopsim/robot.hpp"
#include "coopsim/simulation.hpp"
#include "coopsim/trajectory.hpp"
#include "coopsim/world.hpp"

namespace task_scene {

using namespace coopsim;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

Eigen::Isometry3d translation(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

Eigen::Isometry3d rotz(double a) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// One of the built-in SCARAs as coopsim.robots makes it (default dimensions, masses and friction),
// from its tables: rows [theta, d, a, alpha], box edges, and the tool and jaw face in frame 5.
struct ScaraSpec {
  std::string name, types;
  double L_base, width, height, jaw_length, jaw_thickness;
  std::vector<std::array<double, 4>> dh, com;
  std::vector<std::array<double, 3>> boxes;
  std::array<double, 6> masses, friction, tau_max;
  std::array<std::array<double, 2>, 6> limits;
  Eigen::Matrix3d tool_R, face_R;
  Eigen::Vector3d tool_p, second_point, face_p;
};

Robot make_scara(const ScaraSpec& s, const Eigen::Vector3d& base, const std::string& backend) {
  std::vector<Link> links(6);
  for (int i = 0; i < 6; ++i) {
    Link& L = links[i];
    L.type = s.types[i] == 'P' ? JointType::Prismatic : JointType::Revolute;
    L.dh = {s.dh[i][0], s.dh[i][1], s.dh[i][2], s.dh[i][3]};
    L.com = {s.com[i][0], s.com[i][1], s.com[i][2], s.com[i][3]};
    L.mass = s.masses[i];
    L.inertia = box_inertia(s.masses[i], s.boxes[i][0], s.boxes[i][1], s.boxes[i][2]);
    L.friction = s.friction[i];
    L.q_min = s.limits[i][0];
    L.q_max = s.limits[i][1];
    L.tau_max = s.tau_max[i];
  }
  Tool tool;
  tool.link = 5;
  tool.offset.linear() = s.tool_R;
  tool.offset.translation() = s.tool_p;
  tool.second_link = 6;
  tool.second_point = s.second_point;
  Robot r(links, Eigen::Vector3d(0, 0, -9.81), base, 0.0, tool, s.name);
  // shapes: the base column, each link's mass box on its CoM frame, the fixed jaw
  std::vector<LinkBox> boxes;
  const auto box = [](int link, const Eigen::Isometry3d& pose, const Eigen::Vector3d& half, std::string name) {
    LinkBox b;
    b.link = link;
    b.pose = pose;
    b.half_extents = half;
    b.name = std::move(name);
    return b;
  };
  const double col = s.L_base - s.height / 2;
  boxes.push_back(box(0, translation(0, 0, col / 2), Eigen::Vector3d(s.width, s.width, col / 2), "base"));
  for (int i = 0; i < 6; ++i) {
    const auto& a = s.dh[i];
    const auto& c = s.com[i];
    const Eigen::Isometry3d pose = dh_transform(a[0], a[1], a[2], a[3]).inverse() * dh_transform(c[0], c[1], c[2], c[3]);
    boxes.push_back(box(i + 1, pose, Eigen::Vector3d(s.boxes[i][0], s.boxes[i][1], s.boxes[i][2]) / 2,
                        "link" + std::to_string(i + 1)));
  }
  Eigen::Isometry3d face = Eigen::Isometry3d::Identity();
  face.linear() = s.face_R;
  face.translation() = s.face_p;
  const Eigen::Vector3d centre = s.face_p - s.face_R.col(2) * s.jaw_thickness / 2;
  const Eigen::Vector3d half =
      s.face_R.cwiseAbs() * Eigen::Vector3d(s.jaw_length / 2, s.width / 2, s.jaw_thickness / 2);
  boxes.push_back(box(5, translation(centre.x(), centre.y(), centre.z()), half, "fixed_jaw"));
  Clamp clamp;
  clamp.fixed_link = 5;
  clamp.fixed_face = face;
  clamp.moving_joint = 6;
  clamp.jaw_length = s.jaw_length;
  clamp.pad_width = s.width;
  r = r.with_geometry(boxes, clamp);
  const GeneratedDynamics* gen = find_generated(s.name);
  if (!gen) throw std::runtime_error("no generated dynamics for " + s.name + " in the engine");
  r = r.with_generated(std::shared_ptr<const GeneratedDynamics>(gen, [](const GeneratedDynamics*) {}));
  return r.with_backend(backend);
}

// What both SCARAs' tables give alike: name, joint types, base height, link section and jaw (m).
ScaraSpec scara_spec(const char* name, const char* types, double L_base, double w, double h, double Lj, double tj) {
  ScaraSpec s;
  s.name = name;
  s.types = types;
  s.L_base = L_base;
  s.width = w;
  s.height = h;
  s.jaw_length = Lj;
  s.jaw_thickness = tj;
  return s;
}

ScaraSpec scara1_spec(double L_base) {
  const double L1 = 0.30, L2 = 0.25, L4 = 0.05, L5 = 0.08, quill = 0.30, Lj = 0.04, tj = 0.01, w = 0.06, h = 0.04;
  ScaraSpec s = scara_spec("scara1", "RRPRRP", L_base, w, h, Lj, tj);
  s.dh = {{0, L_base, L1, 0}, {0, 0, L2, kPi}, {0, 0, 0, 0}, {0, L4, 0, kPi / 2}, {0, 0, L5, 0}, {0, 0, 0, 0}};
  s.com = {{0, L_base, L1 / 2, 0}, {0, 0, L2 / 2, 0}, {0, -quill / 2, 0, 0},
           {0, L4 / 2, 0, 0},      {0, 0, L5 / 2, 0}, {0, tj / 2, Lj / 2, 0}};
  s.boxes = {{L1, w, h}, {L2, w, h}, {w, h, quill}, {w, h, L4}, {L5, w, h}, {Lj, w, tj}};
  s.masses = {3.0, 2.2, 0.8, 0.3, 0.25, 0.05};
  s.friction = {1.0, 0.8, 4.0, 0.05, 0.05, 2.0};
  s.tau_max = {30.0, 20.0, 100.0, 2.0, 2.0, 15.0};
  s.limits = {{{-160 * kDeg, 160 * kDeg}, {-145 * kDeg, 145 * kDeg}, {0.0, 0.25},
               {-180 * kDeg, 180 * kDeg}, {-10 * kDeg, 120 * kDeg}, {0.0, 0.05}}};
  s.tool_R << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  s.tool_p = Eigen::Vector3d(Lj / 2, 0, 0);
  s.second_point = Eigen::Vector3d(Lj / 2, 0, 0);
  s.face_R.setIdentity();
  s.face_p = Eigen::Vector3d(Lj / 2, 0, 0);
  return s;
}

ScaraSpec scara2_spec(double L_base) {
  const double L1 = 0.20, L2 = 0.18, L3 = 0.15, L5 = 0.06, quill = 0.30, Lj = 0.04, tj = 0.01, w = 0.05, h = 0.04;
  ScaraSpec s = scara_spec("scara2", "RRRPRP", L_base, w, h, Lj, tj);
  s.dh = {{0, L_base, L1, 0}, {0, 0, L2, 0}, {0, 0, L3, kPi}, {0, 0, 0, 0}, {0, L5, 0, kPi / 2}, {0, 0, 0, 0}};
  s.com = {{0, L_base, L1 / 2, 0}, {0, 0, L2 / 2, 0}, {0, 0, L3 / 2, 0},
           {0, -quill / 2, 0, 0},  {0, L5 / 2, 0, 0}, {kPi / 2, tj / 2, Lj / 2, 0}};
  s.boxes = {{L1, w, h}, {L2, w, h}, {L3, w, h}, {w, h, quill}, {w, h, L5}, {Lj, w, tj}};
  s.masses = {2.0, 1.6, 1.2, 0.6, 0.25, 0.05};
  s.friction = {0.8, 0.6, 0.4, 3.0, 0.05, 2.0};
  s.tau_max = {25.0, 15.0, 8.0, 80.0, 1.5, 15.0};
  s.limits = {{{-170 * kDeg, 170 * kDeg}, {-150 * kDeg, 150 * kDeg}, {-150 * kDeg, 150 * kDeg},
               {0.0, 0.30}, {-180 * kDeg, 180 * kDeg}, {0.0, 0.05}}};
  s.tool_R << -1, 0, 0, 0, 0, 1, 0, 1, 0;
  s.tool_p = Eigen::Vector3d(0, Lj / 2, 0);
  s.second_point = Eigen::Vector3d(0, Lj / 2, 0);
  s.face_R << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  s.face_p = Eigen::Vector3d(0, Lj / 2, 0);
  return s;
}

// coopsim.tasks.scene and the planning values of coopsim.tasks.handover
const Eigen::Vector3d kBarHalf(0.175, 0.01, 0.01);
constexpr double kBarMass = 0.15, kOpen = 0.035, kSqueeze = 0.012, kFixedGap = 0.001, kGrip2 = 0.125,
                 kPickHeight = 0.015, kClearAbove = 0.08;

std::shared_ptr<World> task_world(const Eigen::Isometry3d& bar) {
  WorldOptions wo;
  wo.floor_friction = 0.6;
  auto w = std::make_shared<World>(wo);
  // the container: upper mouth centre, axis descending 25 deg towards +y, inner 0.06 m, 0.40 m long, 5 mm walls
  const double slope = 25 * kDeg, half_in = 0.03, t = 0.005, L = 0.40;
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(0, std::cos(slope), -std::sin(slope));
  R.col(1) = Eigen::Vector3d(-1, 0, 0);
  R.col(2) = R.col(0).cross(R.col(1));
  const Eigen::Vector3d centre = Eigen::Vector3d(-0.25, 0.35, 0.22) + R.col(0) * L / 2;
  struct Wall {
    const char* name;
    Eigen::Vector3d offset, half;
  };
  const Wall walls[] = {
      {"container_bottom", {0, 0, -(half_in + t / 2)}, {L / 2, half_in + t, t / 2}},
      {"container_top", {0, 0, half_in + t / 2}, {L / 2, half_in + t, t / 2}},
      {"container_left", {0, half_in + t / 2, 0}, {L / 2, t / 2, half_in}},
      {"container_right", {0, -(half_in + t / 2), 0}, {L / 2, t / 2, half_in}},
  };
  for (const Wall& wall : walls) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = centre + R * wall.offset;
    w->add_static_box(wall.name, wall.half, T, 0.2);
  }
  w->add_free_box("bar", kBarHalf, kBarMass, bar, 0.5);
  return w;
}

Eigen::Isometry3d bar_on_floor(double x, double y, double yaw) {
  Eigen::Isometry3d T = rotz(yaw);
  T.translation() = Eigen::Vector3d(x, y, kBarHalf.z());
  return T;
}

// handover._grip_down: the clamp pointing down over the bar, s m along it, its TCP `height` above
// the bar's centre, open by kOpen with the fixed jaw kFixedGap from the bar's side
Eigen::Isometry3d grip_down(double s, double height) {
  const double shift = (kOpen - 2 * kBarHalf.y()) / 2 - kFixedGap;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();
  T.translation() = Eigen::Vector3d(s, -shift, height);
  return T;
}

VecN ik_or_throw(const Robot& r, const Eigen::Isometry3d& T, double opening, const VecN* near = nullptr) {
  AnalyticIKOptions o;
  o.opening = opening;
  o.q_near = near;
  return analytic_ik(r, T, o).q;
}

std::shared_ptr<const Reference> joint_path(const std::vector<double>& times, const std::vector<VecN>& points) {
  CubicTrajectory::RowMat P(points.size(), points[0].size());
  for (size_t i = 0; i < points.size(); ++i) P.row(i) = points[i].transpose();
  return std::make_shared<CubicTrajectory>(times, P);
}

struct RunSpec {
  double x, y, yaw;      // the bar's start
  bool computed_torque;  // on the generated dynamics; else numeric dynamics, and SCARA #1 by PID
  double dt;
};

// What the runs share, as a sweep from Python does: SCARA #1's reference and the model robot of its
// computed-torque controllers (both immutable, evaluated from every thread at once).
struct Shared {
  std::shared_ptr<const Reference> ref1;
  std::shared_ptr<const Robot> model1;
};

Shared make_shared_parts() {
  // #1: over the container, its clamp pointing down, then down onto the container's top wall (0.1 m
  // lower than touching: coopsim's penalty contacts push it back), up again and away
  VecN start(6), above(6), pressed(6), away(6);
  start << 0.9, 0.9, 0.05, 0.0, kPi / 2, 0.03;
  above << 1.709, 0.848, 0.07, 2.557, kPi / 2, 0.03;
  pressed = above;
  pressed[2] = 0.17;
  away << 1.2, 1.2, 0.08, -0.4, 1.0, 0.04;
  Shared s;
  s.ref1 = joint_path({0.0, 0.8, 1.6, 2.0, 2.5, 3.0}, {start, above, pressed, pressed, above, away});
  s.model1 = std::make_shared<const Robot>(make_scara(scara1_spec(0.52), Eigen::Vector3d::Zero(), "generated"));
  return s;
}

// One simulation of the scene: SCARA #2 picks the bar up and carries it, SCARA #1 moves over the container.
std::unique_ptr<Simulation> make_run(const RunSpec& spec, const Shared& shared) {
  const std::string backend = spec.computed_torque ? "generated" : "numeric";
  const Robot r1 = make_scara(scara1_spec(0.52), Eigen::Vector3d::Zero(), backend);
  const Robot r2 = make_scara(scara2_spec(0.38), Eigen::Vector3d(0.75, 0, 0), backend);
  const Eigen::Isometry3d bar = bar_on_floor(spec.x, spec.y, spec.yaw);

  // #2's grip: the first of the bar's two ends and the clamp's two ways round that it reaches
  VecN q_grip, q_above;
  bool found = false;
  for (double label : {0.0, kPi}) {
    for (double flip : {0.0, kPi}) {
      const Eigen::Isometry3d G = bar * rotz(label) * grip_down(kGrip2, kPickHeight) * rotz(flip);
      Eigen::Isometry3d A = G;
      A.translation().z() += kClearAbove;
      try {
        q_grip = ik_or_throw(r2, G, kOpen);
        q_above = ik_or_throw(r2, A, kOpen, &q_grip);
        found = true;
      } catch (const IKError&) {
        continue;
      }
      break;
    }
    if (found) break;
  }
  if (!found) throw std::runtime_error("SCARA #2 reaches no grip on the bar");
  // from beside, above the grip, down, the jaw fast to 2 mm over the bar's width and slowly (2 cm/s)
  // on to kSqueeze, as handover.close does: the clamp rule grasps; then up, and carried aside
  VecN q_start = q_above, q_near = q_grip, q_closed = q_grip, q_lifted = q_above, q_carried = q_above;
  q_start[0] -= 0.3;
  q_near[5] = 2 * kBarHalf.y() + 0.002;
  q_closed[5] = q_lifted[5] = q_carried[5] = kSqueeze;
  q_carried[0] += 0.4;
  q_carried[1] -= 0.3;
  auto ref2 = joint_path({0.0, 0.5, 1.1, 1.3, 1.8, 2.0, 2.5, 3.0},
                         {q_start, q_above, q_grip, q_near, q_closed, q_closed, q_lifted, q_carried});

  auto gains = [](double omega, double omega_wrist, bool kp) {
    VecN g(6);
    for (int i = 0; i < 6; ++i) {
      const double w = i >= 3 ? omega_wrist : omega;
      g[i] = kp ? w * w : 2 * w;
    }
    return Eigen::VectorXd(g);
  };
  SimulationOptions o;
  o.dt = spec.dt;
  o.control_every = 5;
  o.world_every = 5;
  o.log_every = 10;
  o.log_contacts = true;
  auto sim = std::make_unique<Simulation>(o, task_world(bar));
  for (int i = 0; i < 2; ++i) {
    const Robot& r = i == 0 ? r1 : r2;
    // #2 by computed torque (on its own dynamics) always; #1 by computed torque or PID
    std::shared_ptr<Controller> ctl;
    if (spec.computed_torque || i == 1)
      ctl = std::make_shared<ComputedTorque>(gains(30, 60, true), gains(30, 60, false), i == 0 ? shared.model1 : nullptr);
    else
      ctl = std::make_shared<PID>(gains(40, 60, true), gains(40, 60, true) * 0.5, gains(40, 60, false));
    sim->add_robot(r, ctl, i == 0 ? shared.ref1 : ref2);
  }
  return sim;
}

}  // namespace task_scene
