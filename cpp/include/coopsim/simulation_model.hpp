// A simulation's model and data, as MuJoCo's mjModel / mjData and Pinocchio's Model / Data.
//
// The model (SimulationModel) is what a run is: its options, its robots as configured (each with
// its controller, reference, initial state and sensor options), its cooperative groups and, when
// shared, the description of its world (the world's options and bodies). The data
// (SimulationData) is where a run is: time, the robots' states, the torques held, the controllers'
// live instances, the world's bodies (Bullet), the welds, the sensors' filters, the log. The step's
// stages are free functions (cpp/src/stages.hpp) taking the model read-only and the data to
// write; Simulation (simulation.hpp) is one model and one data behind the public interface.
//
// N runs of one model share it: Simulation::model() gives the model (a snapshot frozen while it is
// shared: a simulation whose model is shared copies it before changing it), and
// Simulation(model) makes a run of it with data of its own (each controller copied by clone(),
// a world of its own built from the description). The runs then differ only by their data.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>

#include "coopsim/controller.hpp"
#include "coopsim/cooperative_laws.hpp"
#include "coopsim/grasp.hpp"
#include "coopsim/held_body.hpp"
#include "coopsim/integrator.hpp"
#include "coopsim/log.hpp"
#include "coopsim/reference.hpp"
#include "coopsim/robot.hpp"
#include "coopsim/world.hpp"

namespace coopsim {

// The defaults written here are the only ones: the bindings and the Python package read them.
struct SimulationOptions {
  double dt = 2e-4;           // s, > 0
  int control_every = 1;      // controller update every k-th step, >= 1
  int log_every = 1;          // log row every n-th step; 0: no log
  bool end_stops = true;      // robot's spring-damper end stops beyond q_limits
  Method integrator = Method::RK4;  // RK4 (default) or semi-implicit Euler ("rk4", "euler")
  // with a world:
  int world_every = 1;         // the world steps every k-th robot step, its contacts held in between
  bool contact_forces = true;  // contacts push the robots (false: reported only)
  bool log_contacts = false;   // keep every contact point of every world step (else events only)
  double contact_frequency_dt = 0.2;  // penalty contacts: omega * (world step) for the stiffness
  GraspOptions grasp;
  double max_speed = 1e4;     // rad/s or m/s: faster counts as divergence
  double max_position = 1e6;  // rad or m: farther counts as divergence
};

// A robot's force/torque sensor (set_sensor). It sits at the tool centre point (TCP; for a clamp,
// between the jaws) and measures the wrench the robot's end, links >= L, applies to its
// environment: L is the clamp's fixed link (the tool's link for a robot without a clamp). That wrench
// is minus the sum of what acts on those links from outside: the weld's reaction (so a held body
// reads the weld's wrench on it), every contact on their boxes (with free bodies, scenery, other
// links) and the applied link wrenches (set_applied_wrenches; applied joint forces are not
// wrenches and are not sensed). The links' own weight and inertia are not in it (an ideal,
// gravity-compensated sensor). The true wrench, [force N; moment N m about the TCP], is taken in
// the sensor frame (the tool frame: the TCP's orientation); Gaussian noise of standard deviation
// noise_force (each force component) and noise_moment (each moment component) is added in that
// frame, then a first-order low-pass filter of time constant `time_constant` runs at every step:
//   y_k = y_{k-1} + a (x_k - y_{k-1}),  a = 1 - exp(-dt / time_constant)  (a = 1 when 0),
// the exact discretisation of tau dy/dt = x - y for an input held over each step, with the
// sample of step k included (no delay); it starts at the first sample. The world reading is the
// sensor-frame reading turned into world axes (the same point). The contact wrenches are those
// held over the world step, at the links' present pose. The noise is drawn from a generator seeded
// with `seed` (std::mt19937_64) at set_sensor() and at reset(): a seed gives the same noise.
struct SensorOptions {
  double noise_force = 0.0;    // N, standard deviation per force component, >= 0
  double noise_moment = 0.0;   // N m, standard deviation per moment component, >= 0
  double time_constant = 0.0;  // s, >= 0 (0: no filter)
  std::int64_t seed = 0;       // >= 0
};
// Throws std::invalid_argument naming the first option that is negative or not finite.
void check_sensor_options(const SensorOptions& o);

// A contact point of one world step, with the time the step began.
struct LoggedContact {
  double t = 0.0;
  ContactPoint contact;
};

// Time spent per part of the loop (with SimulationOptions profiling on), s.
struct StepProfile {
  double controllers = 0, world = 0, contacts = 0, robots = 0, grasp = 0;  // grasp: the rule and the welds
  long steps = 0, world_steps = 0;
};


// ---- the model: what a run is ----

// One robot as configured: the robot (an immutable copy), its controller and reference as given,
// its initial state, its actuator limits, its sensor's options and the cooperative group driving
// it. A model's controller is the one configured: the run a model was made by drives with it, the
// other runs of the model with copies of it (Controller::clone).
struct RobotModel {
  Robot robot;
  std::shared_ptr<Controller> controller;
  std::shared_ptr<const Reference> reference;
  VecN q0, qd0;      // initial state
  VecN tau_max;      // actuator limits (N m or N)
  SensorOptions sensor;
  int coop = -1;     // the cooperative group driving it (-1: its own controller)
};

// A cooperative group as configured: its law and its robots; an inactive group drives no more.
struct CooperativeModel {
  std::shared_ptr<CooperativeController> controller;
  std::vector<int> robots;
  bool active = true;
};

// A world as described: its options and its own bodies (floor, static and free bodies, with their
// initial states), the robots' link bodies aside: enough to build it again for another run.
struct WorldDescription {
  WorldOptions options;
  std::vector<BodySpec> bodies;
};

struct SimulationModel {
  SimulationOptions options;
  std::vector<RobotModel> robots;
  std::vector<CooperativeModel> cooperatives;
  // the world's description: set when the model is shared (Simulation::model()), for the runs made
  // from it; a run's own world is in its data
  std::optional<WorldDescription> world;
  int robot_count() const { return static_cast<int>(robots.size()); }
};

// ---- the data: where a run is ----

// One robot's part of a run, grouped by the stage that uses it.
struct RobotData {
  // contact.M_llt starts as the factor of the identity: Eigen leaves a decomposition's info unset
  // until compute(), and moving a RobotData (the vector growing) would copy that unset enum (UB)
  explicit RobotData(int dof) { contact.M_llt.compute(MatN::Identity(dof, dof)); }
  Workspace ws;  // the robot's kinematics and dynamics scratch, shared by every stage
  struct Control {  // the control stage: the reference at t_k and the torque held until the next update
    std::shared_ptr<Controller> controller;  // the live controller (its state: a PID's integral, ...)
    VecN q_ref, qd_ref, qdd_ref;  // the reference at the last update
    VecN tau;                     // held torque (saturated at the model's tau_max)
    long updated_at = -1;         // step of the last controller / reference update
  } control;
  struct State {  // the integration: the state and the first stage of the next step
    VecN q, qd;
    VecN q_prev, qd_prev;         // before the last step: where a rejected step goes back to
    VecN k1;                      // qdd at (q, qd, tau, tau_ext), valid when k1_valid
    bool k1_valid = false;
  } state;
  struct External {  // applied inputs (kept until changed) and the external torque held over a step
    VecN forces;                            // applied joint forces
    std::vector<ExternalWrench> wrenches;   // applied link wrenches
    bool applied = false;                   // any applied input nonzero
    VecN tau;                               // applied forces + the wrenches' J^T w + contact.tau, held
    bool held = false;                      // tau held nonzero from the step before
  } external;
  struct Contact {  // the coupling with the world: link bodies, contact wrenches and their torques
    int first_body = -1;                                        // world body of box 0
    std::array<Eigen::Vector3d, kMaxDof + 1> frame_w, frame_v;  // frame velocities at the last world step
    std::vector<ExternalWrench> wrenches;                       // on the links, of the last world step
    VecN tau;                                                   // their J^T, held over the world step
    bool any = false;                                           // contact wrenches or a jaw stop act
    Eigen::LLT<MatN> M_llt;                                     // M = L L^T at the last world step
    bool M_valid = false;
  } contact;
  struct Grasp {  // the clamp's hold on a free body
    int held = -1, candidate = -1;  // world body ids (-1: none)
    long candidate_since = -1;      // step from which the candidate met the rule
    Eigen::Isometry3d weld_X = Eigen::Isometry3d::Identity();  // the body's pose in the clamp link's frame at attach
    Eigen::Vector3d anchor_link = Eigen::Vector3d::Zero();     // the weld's point: between the pads, in the link frame
    Eigen::Vector3d anchor_body = Eigen::Vector3d::Zero();     // the same point in the body's frame
    double width = 0.0;             // m, the body's width between the jaws
    double fade = 1.0;              // the weld's gain while letting go by opening (1: holding)
    double release_progress = 0.0;
    bool releasing = false;
    Vec6 weld = Vec6::Zero();       // force, moment on the body
  } grasp;
  struct Sensor {  // the sense stage: the force/torque sensor at the TCP (its options in the model)
    std::mt19937_64 rng;
    std::normal_distribution<double> normal;
    Vec6 noise = Vec6::Zero();                 // drawn for step `at`
    Vec6 prev = Vec6::Zero();                  // the filter's output before step `at`
    Vec6 true_clamp = Vec6::Zero(), true_world = Vec6::Zero(), clamp = Vec6::Zero(), world = Vec6::Zero();
    long at = -1;                              // the step of the last reading (-1: none yet)
    bool has_prev = false;                     // prev holds a reading of an earlier step
    bool stale = false;                        // an ideal sensor not read at step `at` (no log row)
  } sensor;
  struct Record {  // the log stage
    RobotLog log;
    TrackingMetrics metrics;
  } record;
};

// A pair of robots a < b: the clamps' relative pose when both began to hold one body, and the
// pair's log column.
struct PairData {
  int a = 0, b = 0;
  bool attached = false;  // X0 holds the relative pose of the present dual hold
  Eigen::Isometry3d X0 = Eigen::Isometry3d::Identity();
  LogColumn log{kCooperationWidth};
};

struct SimulationData {
  std::shared_ptr<World> world;             // the run's world (null: none)
  std::vector<RobotData> robots;            // one per model robot
  std::vector<PairData> pairs;              // every pair a < b
  std::vector<std::shared_ptr<CooperativeController>> cooperatives;  // the groups' live laws
  std::vector<CoopMember> members;          // scratch of the cooperative stage
  std::vector<VecN> coop_tau;
  std::vector<double*> coop_out;            // scratch: the members' torque outputs
  std::vector<LogColumn> body_log;
  std::vector<int> free_ids;
  std::vector<BodyState> body_now;
  std::vector<Eigen::Isometry3d> box_poses;  // scratch of the world stage
  std::vector<LoggedContact> contact_log;
  std::vector<std::pair<int, Vec6>> body_wrenches;  // (world id, wrench), nonzero
  std::vector<GraspEvent> grasp_events;
  long world_at = -1;
  bool profiling = false;
  StepProfile profile;
  LogColumn log_t{1};
  long k = 0;
  long logged_at = -1;
  bool started = false;
  bool diverged = false;
  std::string divergence;
  double time(const SimulationModel& m) const { return k * m.options.dt; }
};

}  // namespace coopsim
