// The step's stages and their helpers, as free functions over a simulation's model and data
// (simulation_model.hpp): each takes the model read-only (what the run is) and the data it
// writes (where the run is). Simulation (simulation.hpp) calls them; run_batch and the runs of
// one shared model step through them. Internal: included by engine sources only.
//
//   stage          function                              file
//   control        control, cooperate                    simulation.cpp, cooperative_stage.cpp
//   world          links_to_world                        contact_coupling.cpp
//   grasp          grasp (the rule, the welds)           grasp.cpp
//   world step     world_advance, contacts_to_robots     contact_coupling.cpp
//   external       hold_external                         simulation.cpp
//   sense          sense                                 sensor.cpp
//   log            log                                   log.cpp
//   integrate      integrate                             simulation.cpp
#pragma once

#include <string>

#include "coopsim/simulation_model.hpp"

namespace coopsim::stages {

using Model = SimulationModel;
using Data = SimulationData;

// ---- the run (simulation.cpp) ----
// The data of a run of `m` at t = 0 (world: the run's world, attached, or null). The live
// controllers are the model's own (own = true) or clones of them.
void init(const Model& m, Data& d, std::shared_ptr<World> world, bool own);
void add_robot_data(const Model& m, Data& d, int i);  // the data of the model's robot i, just added
void start(const Model& m, Data& d);                  // before the first step: world bodies, controllers reset
void reset(const Model& m, Data& d);                  // back to t = 0
void reserve(const Model& m, Data& d, long steps);    // log storage for `steps` more steps (log.cpp)
void run(const Model& m, Data& d);                    // the stages at t_k, in order
void advance(const Model& m, Data& d, long n);        // n steps: integrate and the stages

// ---- stages ----
bool control(const Model& m, Data& d);  // true when some robot was updated
void cooperate(const Model& m, Data& d);
inline bool world_due(const Model& m, const Data& d) {
  return d.world && d.world_at != d.k && d.k % m.options.world_every == 0;
}
void links_to_world(const Model& m, Data& d);
void grasp(const Model& m, Data& d, double h);
void world_advance(const Model& m, Data& d, double h);
void contacts_to_robots(const Model& m, Data& d, double h);
void hold_external(const Model& m, Data& d);
void sense(const Model& m, Data& d);
void log(const Model& m, Data& d);
void integrate(const Model& m, Data& d);

// ---- one robot ----
void qdd(const Model& m, Data& d, int i, VecN& out);  // forward dynamics at its state and held torques
void external(const RobotModel& r, RobotData& s);     // its external torque at q
void applied_changed(const Model& m, Data& d, int i);
inline bool has_ext(const RobotData& s) { return s.external.applied || s.contact.any; }
// robot i's sensor at t_k (now: an ideal one too, off the log's rows; framed: s.ws holds the frames at q)
void sense_robot(const Model& m, Data& d, int i, bool now = false, bool framed = false);
void reset_sensor(const RobotModel& r, RobotData& s);

// ---- contact coupling (contact_coupling.cpp) ----
void frames(const Robot& r, RobotData& s);  // its kinematics and frame velocities at its q, qd
Eigen::Vector3d point_velocity(const RobotData& s, int link, const Eigen::Vector3d& p);
void factor_mass(const Robot& r, RobotData& s);  // M(q), Cholesky-factored once per world step
double inverse_mass_along(const Robot& r, RobotData& s, const VecN& u);
void contact_wrenches(const Model& m, Data& d, double h);

// ---- grasp (grasp.cpp) ----
GraspCheck grasp_check(const Model& m, const Data& d, int i, const BodyState& st, int body);
void ignore_held(const Model& m, Data& d);
void release(const Model& m, Data& d, int i, const std::string& why, bool set_twist = true);

// ---- two holders of one body (held_body.cpp) ----
BodyState body_state(const Model& m, const Data& d, int id);
bool cooperation(const Model& m, Data& d, PairData& pair, Cooperation& out);  // false: not one body
void pairs_attach(const Model& m, Data& d, int i);  // robot i grasped or let go: its pairs' X0

// ---- divergence (divergence.cpp) ----
[[noreturn]] void diverge(const Model& m, Data& d, int i, const std::string& why, bool in_step, bool state_is_result);
[[noreturn]] void torque_diverged(const Model& m, Data& d, int i, const VecN& u);
[[noreturn]] void world_diverged(const Model& m, Data& d, const WorldDivergence& e, double h);
void state_diverged(const Model& m, Data& d, int i);  // robot i beyond the limits after a step

}  // namespace coopsim::stages
