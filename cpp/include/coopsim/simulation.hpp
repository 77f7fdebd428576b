// The simulation loop: one or more robots, each driven by a controller
// towards a reference, integrated at a fixed step by RK4 (or semi-implicit
// Euler) through coopsim::step, with a data log (the paper's DataManager)
// and tracking metrics. A simulation is one model (what the run is: robots, controllers,
// references, options; SimulationModel) and one data (where it is: q, qd, held torques, applied
// inputs, world, welds, sensors, log; SimulationData), both in simulation_model.hpp; the step's
// stages are free functions over them (cpp/src/stages.hpp). Runs of one model share it.
//
// Time: step k is at t_k = k dt. The controller of every robot runs at the
// steps k that are multiples of control_every, with period control_every * dt;
// its torque, saturated at the actuator limits, is held constant until the
// next update (zero-order hold), also inside the RK4 stages.
//
// Applied inputs (MuJoCo's qfrc_applied / xfrc_applied): each robot carries
// applied joint forces (n) and applied link wrenches (ExternalWrench: world
// force and moment at a point of a link), set between steps and kept until
// changed. At every step their joint torques tau_ext = f + sum J^T w are
// evaluated at q(t_k) and held over [t_k, t_k+1) like the torque: they enter
// eq. (2) as tau + tau_ext. A change takes effect at once, for the next
// step; if the row of this time is already logged, the next advance logs a
// second row at the same time with the new inputs, so the log always shows
// what acted over each step.
//
// Log: a row is written at every step k that is a multiple of log_every
// (log_every = 0: no log), including k = 0. Its columns are log_schema():
// t_k, then per robot q and qd at t_k, the acceleration at t_k, the torque
// and the external torque applied over [t_k, t_k+1) (held), and the
// reference q_ref, qd_ref, qdd_ref at t_k. Log storage is reserved before each
// advance, so the stepping loop does not allocate.
//
// Metrics (every step, whatever log_every): per joint, the sum of squared
// and the largest absolute tracking error e = q_ref - q and the largest
// absolute applied torque.
//
// Divergence: after each step every robot's q and qd must be finite with
// |qd_i| <= max_speed and |q_i| <= max_position (divergence_reason). If not, the simulation goes
// back to the last good state (whose row, when due, is already logged),
// marks itself diverged and throws DivergenceError naming the step, time,
// robot and state. A controller that throws leaves the state at t_k with
// the log complete up to t_k-1; advancing again retries that update.
//
// The step's stages, in order (stages::run and stages::advance in simulation.cpp):
//   control      references and controllers at t_k                        simulation.cpp
//   world        (world steps) link poses and twists into the world       contact_coupling.cpp
//   grasp        the clamp rule, the welds' wrenches                      grasp.cpp
//   world step   Bullet's step; its contacts as joint torques, held       contact_coupling.cpp
//   external     applied inputs and contacts: tau_ext over the step       simulation.cpp
//   sense        the force/torque sensors at the tool centre points        sensor.cpp
//   log          the row at t_k, when due                                 log.cpp
//   integrate    RK4 or Euler to t_k+1 under the held torques             simulation.cpp
// Divergence checks and their messages are in divergence.cpp, the self-collision exclusions in
// self_collision.cpp, run_batch (batch.hpp) in batch.cpp.
//
// One driver at a time (simulation_hold.cpp): the simulation has a holder, the thread that is
// advancing or changing the run. Every call that advances it (advance, run) or changes it (every
// set_*, add_*, remove_cooperative, release, reset, reserve, set_profiling, and the calls that
// compute on the simulation's scratch: grasp_check, cooperation, ft_*) made from another thread
// while it is held throws SimulationBusyError at once, naming the holder: two threads never step
// one simulation. A call with no holder takes the hold for its own duration (implicit, labelled
// "another thread"); a driver takes it across many calls with hold(label) (explicit, re-entrant on
// its thread). The reads (state, time, log, metrics, options, ...) take no hold and are not
// guarded: read from another thread while the holder runs, they may see a step half done.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "coopsim/simulation_model.hpp"

namespace coopsim {

// Thrown by a call that advances or changes a simulation (see "One driver at a time" above) from
// another thread than the one holding it. holder(): the holder's label ("another thread" for an
// implicit hold); thread(): its thread's id (std::thread::id as printed; on Linux pthread_self(),
// Python's threading.get_ident()). The message is one line:
//   this simulation is being run by '<label>' (thread <id>); one driver at a time: pause or close it first
class SimulationBusyError : public std::runtime_error {
 public:
  SimulationBusyError(const std::string& holder, const std::string& thread);
  const std::string& holder() const { return holder_; }
  const std::string& thread() const { return thread_; }

 private:
  std::string holder_, thread_;
};

class Simulation {
  struct Driver;  // the holder: an atomic thread id, a re-entrant depth, the label (simulation_hold.cpp)

 public:
  // An explicit hold on the run (hold()): while it lives, only its thread may advance or change
  // the simulation. Movable, not copyable; release() (or the destructor) gives it back, and must
  // run on the thread that took it (release() from another thread throws std::logic_error).
  class Hold {
   public:
    Hold() = default;
    Hold(Hold&& o) noexcept : driver_(std::move(o.driver_)) {}
    Hold& operator=(Hold&& o) noexcept;
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;
    ~Hold();
    void release();
    bool held() const { return driver_ != nullptr; }

   private:
    friend class Simulation;
    explicit Hold(std::shared_ptr<Driver> d) : driver_(std::move(d)) {}
    std::shared_ptr<Driver> driver_;
  };

  // With a world, every robot added brings its boxes into it as kinematic
  // bodies at the first step, and the step runs, in order: controllers;
  // link poses and twists into the world; the grasp rule and the welds; the
  // world's step (free bodies advance, contacts with the solver's forces);
  // penalty forces where both sides are robots or scenery; contact wrenches
  // mapped by J^T into each robot's tau_ext, held over the world step; the
  // log; the robots' integration. A world belongs to one simulation.
  // Throws std::invalid_argument naming an option out of range.
  explicit Simulation(SimulationOptions options = SimulationOptions(), std::shared_ptr<World> world = nullptr);
  ~Simulation();
  // (a simulation moved while held, or from, is not to be used: its holder stays with the moved-to one)
  Simulation(Simulation&&) = default;
  Simulation& operator=(Simulation&&) = default;
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  // ---- model and data (simulation_model.hpp) ----
  // A run of `model` with data of its own, at t = 0: each robot's controller and each cooperative
  // law copied by clone() (std::invalid_argument naming the robot or the group for one that cannot
  // be copied), a world of its own built from the model's world description. Runs of one model
  // share it; a run changing its model (set_*, add_*, remove_cooperative) first takes a copy.
  explicit Simulation(std::shared_ptr<const SimulationModel> model);
  // The model of this run, shared: the runs made from it use it as it is now (with the world's
  // description: its options and bodies as configured). While it is held elsewhere this run's
  // changes go to a copy of it.
  std::shared_ptr<const SimulationModel> model();
  // The data of this run (read-only: the stages write it).
  const SimulationData& data() const { return data_; }

  // ---- one driver at a time (see the header comment) ----
  // Takes the run for the calling thread until the Hold is released: another thread's advance,
  // run, reset or set_* then throws SimulationBusyError naming `label` (non-empty, e.g. "the live
  // view at http://127.0.0.1:8080"). Re-entrant: the holding thread may take it again (the label
  // of the outermost hold stays) and may call everything. Throws SimulationBusyError when another
  // thread holds the run, std::invalid_argument for an empty label.
  Hold hold(const std::string& label);
  // The holder's label now ("" when nobody holds the run; "another thread" for an implicit hold)
  // and, in *thread when given, its thread id (std::thread::id() when none), read together. A
  // snapshot: it may change at once.
  std::string holder(std::thread::id* thread = nullptr) const;

  // Adds a robot (copied) driven by `controller` towards `reference`, from
  // q0, qd0 (null: the reference's q and qd at t = 0). Only before the first
  // step (or after reset()). Returns the robot's index. Throws
  // std::invalid_argument on mismatched sizes, naming the argument.
  int add_robot(const Robot& robot, std::shared_ptr<Controller> controller,
                std::shared_ptr<const Reference> reference, const double* q0 = nullptr,
                const double* qd0 = nullptr);

  // Replaces robot i's reference (same number of joints). It is evaluated
  // from the next controller update on: a change before the first step (or
  // after reset()) acts at once; between runs, the torque already held over
  // the step at the present time stays (the controller runs once per step),
  // and the new reference acts from the next step. Plan it continuous with
  // the old one at the present time for a smooth hand-over.
  void set_reference(int i, std::shared_ptr<const Reference> reference);

  // Replaces robot i's controller (checked as add_robot's: not null, not driving another robot,
  // controller->check(robot): gains' sizes, a model of the robot's dof). The state stays; the
  // new controller is reset now (a PID's integral restarts at zero, its velocity estimate at the
  // measured velocity) and computes from the next controller update on: before the first step
  // (or after reset()) at once; between runs, the torque already held over the step at the
  // present time stays and the new controller drives the next step on.
  void set_controller(int i, std::shared_ptr<Controller> controller);

  // Replaces robot i by `robot` (copied): the same dof and joint types, the same number of boxes on
  // the same links (e.g. the same SCARA with other link lengths). q and qd stay; the held torque
  // stays, saturated at the new robot's limits; the controller is reset now when the run is under
  // way (a PID's integral restarts at zero; a controller without a model of its own takes the new
  // robot as its model, an explicit model stays). With a world, the robot's link bodies take the
  // new sizes and poses at q and its self-collision exclusions are recomputed (excluded_pairs),
  // the other bodies keeping their states. Refused (std::invalid_argument) while the robot holds a
  // body, with another gravity than the world's, or where the world cannot hold a box at q.
  void set_robot(int i, const Robot& robot);

  // ---- cooperative controllers (cooperative_laws.hpp) ----
  // `controller` drives robots `robots` together (their own controllers stand aside) from the next
  // controller update on; it is reset now when the run is under way, else at its start. A robot
  // belongs to one group at most; controller->check() sees the robots. Returns the group's index.
  int add_cooperative(std::shared_ptr<CooperativeController> controller, std::vector<int> robots);
  // Group k stops driving: its robots' own controllers are reset and drive from the next update.
  void remove_cooperative(int k);
  int cooperative_count() const { return static_cast<int>(model_->cooperatives.size()); }
  const std::shared_ptr<CooperativeController>& cooperative(int k) const;
  const std::vector<int>& cooperative_robots(int k) const;
  bool cooperative_active(int k) const;

  // Number of robots added.
  int robot_count() const { return model_->robot_count(); }
  const Robot& robot(int i) const { return model_->robots[check_(i)].robot; }
  const std::shared_ptr<Controller>& controller(int i) const { return slot_(i).control.controller; }
  const std::shared_ptr<const Reference>& reference(int i) const { return model_->robots[check_(i)].reference; }
  const SimulationOptions& options() const { return model_->options; }
  // The run's World (null without one): the one given to the constructor, or built for a run of a shared model.
  const std::shared_ptr<World>& world() const { return data_.world; }
  // The world body of robot i's box b (-1 without a world or before the first step).
  int link_body(int i, int box) const;
  static constexpr int kExclusionSamples = 200;
  // Box index pairs of robot i that never collide: boxes of one link, of
  // adjacent links (the base is link 0), and pairs that overlap at every
  // one of `samples` random poses within the joint limits (from a fixed
  // seed; with the default samples computed once per robot geometry).
  static std::vector<std::pair<int, int>> excluded_pairs(const Robot& robot, int samples = kExclusionSamples);
  // The state of a free or static body at the simulation's time (free bodies
  // as sampled at the last world step).
  BodyState body_state(int id) const;
  const std::vector<LoggedContact>& contact_log() const { return data_.contact_log; }
  const StepProfile& profile() const { return data_.profile; }
  // ---- grasps ----
  // The free body robot i holds (world id), or -1.
  int holding(int i) const { return slot_(i).grasp.held; }
  // Releases what robot i holds (nothing if it holds nothing), now.
  void release(int i);
  const std::vector<GraspEvent>& grasp_events() const { return data_.grasp_events; }
  // The weld's force and moment on the body held by robot i over the last world step, (6).
  // (at the weld's point: midway between the pads' centres when it attached)
  const Vec6& weld_wrench(int i) const { return slot_(i).grasp.weld; }
  // The rule's conditions for robot i and free body `body` in the present state.
  GraspCheck grasp_check(int i, int body);
  // ---- two holders of one body (held_body.hpp) ----
  // Robots a < b: their welds' quantities and relative pose error now (the log's row at t_k: the welds'
  // wrenches of the last world step, the body as sampled then, the clamps at q); *holding, when given,
  // tells whether they hold one body (else the values are zeros). Throws std::invalid_argument unless
  // 0 <= a < b < robot_count().
  Cooperation cooperation(int a, int b, bool* holding = nullptr);
  // Their log column: one row of cooperation_schema() per log row.
  const LogColumn& cooperation_log(int a, int b);
  // ---- two holders of one body read at once (env_readout.cpp) ----
  using ReadoutRows = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  // The width of pair_readout's rows for robots of na and nb joints.
  static int pair_readout_width(int na, int nb) { return 72 + 2 * (na + nb); }
  // Robots a and b and free body `body` (its name) of each of `sims` now, one row per simulation (what
  // a learning environment reads after each step, coopsim.envs): time s; 1 when a and b hold one body
  // (else 0); 1 when a holds `body`, 1 when b does; the counts of contact events and of grasp events so
  // far; then for a and for b: q (n), qd (n), the TCP's position (3) m and quaternion [w, x, y, z] (4,
  // w >= 0), its twist J qd (6) m/s, rad/s, the force/torque sensor in world axes (6) N, N m (as
  // ft_world); the body's position (3) m, quaternion (4), velocity (3) m/s and angular velocity (3) rad/s
  // (as body_state); the pair's internal wrench (12) N, N m, squeeze (1) N and load shares (2), as
  // cooperation (zeros unless a and b hold one body). Each simulation is taken as cooperation() takes
  // it. Throws std::invalid_argument for robots not 0 <= a < b < robot_count(), robots of other joints
  // than sims[0]'s, a simulation without a world or an unknown body.
  static ReadoutRows pair_readout(const std::vector<Simulation*>& sims, int a, int b, const std::string& body);
  void set_profiling(bool on);
  // ---- sensors (see SensorOptions) ----
  // Configures robot i's force/torque sensor; the noise generator restarts from the seed, the
  // filter keeps its state. Throws std::invalid_argument naming a bad option.
  void set_sensor(int i, const SensorOptions& options);
  const SensorOptions& sensor_options(int i) const { return model_->robots[check_(i)].sensor; }
  // Robot i's reading at the present time (as the log's row at t_k), [force N; moment N m about the
  // TCP] (6): in the sensor frame, in world axes, and the true wrench (no noise, no filter) in each.
  // Zero before the first step. (An ideal sensor, without noise or filter, is read only at the log's
  // rows and when asked here: its reading depends on the present state alone.)
  // They may compute the reading on the simulation's scratch: they take the hold as a mutator does.
  const Vec6& ft_clamp(int i) { return fresh_sensor_(i).clamp; }
  const Vec6& ft_world(int i) { return fresh_sensor_(i).world; }
  const Vec6& ft_true_clamp(int i) { return fresh_sensor_(i).true_clamp; }
  const Vec6& ft_true_world(int i) { return fresh_sensor_(i).true_world; }
  // The sensor frame: the TCP's pose in the world at the present state.
  Eigen::Isometry3d sensor_pose(int i) const;
  // ---- state ----
  // Steps taken since the start (t = 0 or the last reset()).
  long step_count() const { return data_.k; }
  // Simulated time, s: step_count() * dt.
  double time() const { return data_.time(*model_); }
  // Whether the run has started (its first step taken since the start); robots are added before it.
  bool started() const { return data_.started; }
  // Whether the run stopped with a DivergenceError (reset() starts it over).
  bool diverged() const { return data_.diverged; }
  const VecN& q(int i) const { return slot_(i).state.q; }
  const VecN& qd(int i) const { return slot_(i).state.qd; }
  const VecN& tau(int i) const { return slot_(i).control.tau; }  // held torque
  const VecN& tau_ext(int i) const { return slot_(i).external.tau; }  // held external torque of the applied inputs

  // ---- applied inputs (kept until changed; cleared by reset()) ----
  // Joint forces (n) N m or N, added to the torque; link wrenches, world
  // force and moment at a point of a link (see ExternalWrench). Throws
  // std::invalid_argument on a wrong size, a non-finite value or a link
  // out of range.
  void set_applied_forces(int i, const VecN& forces);
  void set_applied_wrenches(int i, std::vector<ExternalWrench> wrenches);
  // A wrench on free body `id` (world axes: force N at its centre of mass, moment N m), applied at
  // every world step from the next one on, kept until changed (zero: removed); cleared by reset().
  // Throws std::invalid_argument without a world, for a body that is not free, or a non-finite value.
  void set_body_wrench(int id, const Vec6& wrench);
  Vec6 body_wrench(int id) const;
  const VecN& applied_forces(int i) const { return slot_(i).external.forces; }
  const std::vector<ExternalWrench>& applied_wrenches(int i) const { return slot_(i).external.wrenches; }
  const VecN& initial_q(int i) const { return model_->robots[check_(i)].q0; }
  const VecN& initial_qd(int i) const { return model_->robots[check_(i)].qd0; }

  // Back to t = 0 and the initial states; clears the log and the metrics;
  // controllers are reset at the next step.
  void reset();
  // Number of steps from now to the time t_end (s), rounding down, with a
  // tolerance of 1e-9 dt; throws if t_end is before now or not finite.
  long steps_until(double t_end) const;
  // Reserves log storage for `steps` more steps.
  void reserve(long steps);
  // Advances n >= 0 steps (see the header comment for errors).
  void advance(long n);
  // Advances to time t_end (steps_until) in chunks of `chunk` steps,
  // calling progress(done, total) after each; progress returning false, or
  // throwing, stops the run there (the state and log stay consistent).
  // Returns the steps taken.
  long run(double t_end, long chunk = 4096, const std::function<bool(long, long)>& progress = nullptr);
  // What run_until watches for (flags, combined with |): a grasp or a release (grasp_events()
  // grew), a contact beginning between two bodies of the world (world()->events() grew).
  enum Until : int { kUntilGrasp = 1, kUntilContact = 2 };
  // Advances toward t_end as run() does, in pieces of `every` s counted from now (rounded down to
  // whole steps, at least one; the last piece shorter), and stops after the first piece in which an
  // event of `until` happened. The steps
  // are those of run(): where it stops is where a caller advancing piece by piece and looking for
  // the event between pieces would look, so such a caller can hand the waiting to the engine and
  // get the same run. progress(done, total) is called at most every `chunk` steps and at the end,
  // as run() calls it (false or throwing stops there). Returns the events found in the last piece
  // (flags of `until`; 0: t_end reached, or progress stopped the run). Throws
  // std::invalid_argument for an `every` not finite and > 0, chunk < 1 or until without a known flag.
  int run_until(double t_end, int until, double every, long chunk = 4096,
                const std::function<bool(long, long)>& progress = nullptr);

  // ---- log and metrics ----
  // Rows in the log (one per log_every-th step, the start included).
  long log_rows() const { return data_.log_t.rows(); }
  const LogColumn& log_t() const { return data_.log_t; }
  // Free bodies' log, one column each (world.free_bodies() order): 13 values
  // per row, position (3) m, quaternion w x y z (4), velocity (3) m/s,
  // angular velocity (3) rad/s, sampled at the world's steps.
  const std::vector<LogColumn>& body_log() const { return data_.body_log; }
  const RobotLog& log(int i) const { return slot_(i).record.log; }
  const TrackingMetrics& metrics(int i) const { return slot_(i).record.metrics; }

 private:
  int check_(int i) const;  // robot index i, checked (std::out_of_range)
  RobotData& slot_(int i) { return data_.robots[check_(i)]; }
  const RobotData& slot_(int i) const { return data_.robots[check_(i)]; }
  // The model to change: copied first when it is shared (model()), so the other runs keep theirs.
  SimulationModel& edit_();
  // ---- the holder (simulation_hold.cpp) ----
  // The implicit hold of one mutating call: takes the run when nobody holds it, enters it again
  // on the holder's thread, throws SimulationBusyError otherwise. Released at the scope's end.
  class Entry {
   public:
    explicit Entry(Driver& d);
    ~Entry();
    Entry(const Entry&) = delete;
    Entry& operator=(const Entry&) = delete;

   private:
    Driver& driver_;
  };
  Entry enter_() { return Entry(*driver_); }
  static std::shared_ptr<Driver> make_driver_();
  const RobotData::Sensor& fresh_sensor_(int i);  // robot i's sensor, read now if stale

  std::shared_ptr<Driver> driver_;  // on the heap: a Hold keeps it, a move of the simulation carries it
  std::shared_ptr<SimulationModel> model_;  // what the run is (shared with other runs after model())
  SimulationData data_;                     // where the run is
};

}  // namespace coopsim
