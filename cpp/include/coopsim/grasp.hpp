// The clamp grasp: its options, the rule's conditions and the events it records. The rule and
// the welds themselves run inside a simulation's step (cpp/src/grasp.cpp), between the links'
// poses entering the world and the world's step.
//
// A robot with a clamp grasps a free body when, for hold_time in a row: its jaw is commanded
// closing or closed (q_ref of the moving joint at or below the opening, or closing); a face of the
// body is normal to the jaw axis within `angle`; both inner faces touch the body (gap at most
// `gap`, penetration at most `penetration`); the body covers the pads' centre and does not reach
// into the palm beyond the pads; and it moves with the clamp (relative speed below `speed`,
// relative angular speed below `angular_speed`). The body is then tied to the clamp's link by a
// soft weld at the pose it has at that instant, anchored at the point midway between the pads'
// centres: a 6-DOF spring-damper (stiffness from the reduced mass and inertia between body and
// robot so that omega * h = weld_omega_dt for the world step h, critical damping shared among the
// welds on the body) whose force and moment act on the body and, opposite, on the clamp's link
// through J^T; the moving jaw meets the body as a stop at the body's width. It is released when
// the jaw is commanded open beyond the width plus open_margin, when the weld stretches beyond
// `slip`, or by release(); the body then leaves with the clamp's rigid twist at its centre of
// mass. Opening lets go over release_time: the weld's gains fade smoothly to zero, so the load
// passes to another holder or to the world without a jump; slip and release() let go at once.
#pragma once

#include <array>
#include <string>

namespace coopsim {

// The defaults written here are the only ones: the bindings and the Python package read them.
struct GraspOptions {
  bool enabled = true;
  double hold_time = 2e-3;        // s
  double gap = 5e-4;              // m
  double penetration = 1e-3;      // m
  double angle = 0.17453292519943295;  // rad (10 deg)
  double speed = 0.05;            // m/s
  double angular_speed = 0.5;     // rad/s
  double open_margin = 1e-3;      // m
  double slip = 5e-3;             // m
  double weld_omega_dt = 0.2;
  double release_time = 0.1;      // s
  bool weld_moment = true;        // false: point welds, forces only (a pin at the weld's point)
};

// The numeric options by name, in the order above (each must be >= 0).
struct GraspOptionField {
  const char* name;
  double GraspOptions::*field;
  const char* unit;  // "" when without one
};
constexpr int kGraspOptionFields = 10;
const std::array<GraspOptionField, kGraspOptionFields>& grasp_option_fields();
// The numeric option called `name` of g; throws std::invalid_argument
// "grasp_options: unknown option '<name>'" when there is none ("enabled" and "weld_moment" are
// flags, set as fields).
double& grasp_option(GraspOptions& g, const std::string& name);
// Throws std::invalid_argument naming the first numeric option that is not >= 0 (NaN included).
void check_grasp_options(const GraspOptions& g);

// The clamp rule's conditions for one robot and one body, and the measures behind them.
struct GraspCheck {
  bool closing = false;   // the jaw commanded closing or closed
  bool aligned = false;   // a face of the body normal to the jaw axis within the angle option
  bool touching = false;  // both jaws touch it: each gap within the gap and penetration options
  bool in_pads = false;   // its centre within the pads along the jaw, not into the palm, across their centre line
  bool slow = false;      // moving with the clamp: speed and angular_speed within their options
  double angle = 0, gap_fixed = 0, gap_moving = 0, speed = 0, angular_speed = 0;  // rad, m, m, m/s, rad/s
  double width = 0;  // m, the body's width along the jaw axis
  bool ok() const { return closing && aligned && touching && in_pads && slow; }  // all five conditions
};

// A grasp or a release.
struct GraspEvent {
  double t = 0.0;     // s
  int robot = -1;     // robot index
  int body = -1;      // world body id
  bool grasp = true;  // false: a release
  std::string reason; // "grasp", "opened", "slipped", "released"
};

}  // namespace coopsim
