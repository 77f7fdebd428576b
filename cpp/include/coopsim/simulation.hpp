// The simulation loop: one or more robots, each driven by a controller
// towards a reference, integrated by fixed-step RK4, with a data log (the
// paper's DataManager) and tracking metrics.
//
// Time: step k is at t_k = k dt. The controller of every robot runs at the
// steps k that are multiples of control_every, with period control_every * dt;
// its torque, saturated at the actuator limits, is held constant until the
// next update (zero-order hold), also inside the RK4 stages.
//
// Log: a row is written at every step k that is a multiple of log_every
// (log_every = 0: no log), including k = 0. Row k holds t_k, q and qd at t_k,
// the torque applied over [t_k, t_k+1) (the held one), the acceleration that
// torque gives at t_k, and the reference q_ref, qd_ref at t_k. Log storage is
// reserved before each advance, so the stepping loop does not allocate.
//
// Metrics (every step, whatever log_every): per joint, the sum of squared
// and the largest absolute tracking error e = q_ref - q and the largest
// absolute applied torque.
//
// Divergence: after each step every robot's q and qd must be finite with
// |qd_i| <= max_speed and |q_i| <= max_position. If not, the simulation goes
// back to the last good state (whose row, when due, is already logged),
// marks itself diverged and throws DivergenceError naming the step, time,
// robot and state. A controller that throws leaves the state at t_k with
// the log complete up to t_k-1; advancing again retries that update.
#pragma once

#include <algorithm>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "coopsim/controller.hpp"
#include "coopsim/reference.hpp"
#include "coopsim/robot.hpp"

namespace coopsim {

class DivergenceError : public std::runtime_error {
 public:
  DivergenceError(const std::string& what, long step, double time, int robot, VecN q, VecN qd)
      : std::runtime_error(what), step(step), time(time), robot(robot), q(std::move(q)), qd(std::move(qd)) {}
  long step;    // the step whose result was rejected (1-based count of steps)
  double time;  // s, t at the end of that step
  int robot;    // index of the robot that diverged
  VecN q, qd;   // its rejected state
};

// A constant set-point: q_ref = q, qd_ref = qdd_ref = 0 at all times.
class ConstantReference : public Reference {
 public:
  explicit ConstantReference(VecN q) : q_(std::move(q)) {}
  int dof() const override { return static_cast<int>(q_.size()); }
  double t_start() const override { return 0.0; }
  double t_end() const override { return 0.0; }
  void evaluate(double, double* q, double* qd, double* qdd) const override {
    for (int i = 0; i < q_.size(); ++i) {
      if (q) q[i] = q_[i];
      if (qd) qd[i] = 0.0;
      if (qdd) qdd[i] = 0.0;
    }
  }
  const VecN& point() const { return q_; }

 private:
  VecN q_;
};

struct SimulationOptions {
  double dt = 2e-4;           // s, > 0
  int control_every = 1;      // controller update every k-th step, >= 1
  int log_every = 1;          // log row every n-th step; 0: no log
  bool end_stops = true;      // robot's spring-damper end stops beyond q_limits
  double max_speed = 1e4;     // rad/s or m/s: faster counts as divergence
  double max_position = 1e6;  // rad or m: farther counts as divergence
};

// Append-only rows of `width` doubles, row-major in one memory block.
// Growing moves the rows to a new block and clear() starts a new one, so
// rows already written never change in a block: whoever shares a block
// (e.g. a numpy view) sees a fixed history. Blocks come from, and go back
// to, a bounded process-wide pool, so that repeated runs reuse memory whose
// pages are already mapped.
class LogColumn {
 public:
  explicit LogColumn(int width = 1) : width_(width) {}
  int width() const { return width_; }
  long rows() const { return rows_; }
  long capacity() const { return cap_; }
  const std::shared_ptr<double[]>& block() const { return block_; }
  const double* data() const { return block_.get(); }
  double back() const { return block_[(rows_ - 1) * width_ + width_ - 1]; }
  // Room for `rows` rows in all; grows at least geometrically.
  void reserve(long rows);
  // Appends one row (reserve first to keep allocation out of loops).
  void push(const double* row) {
    if (rows_ == cap_) reserve(rows_ + 1);
    std::copy(row, row + width_, block_.get() + rows_ * width_);
    ++rows_;
  }
  void clear() {
    block_.reset();
    rows_ = cap_ = 0;
  }

 private:
  std::shared_ptr<double[]> block_;
  long rows_ = 0, cap_ = 0;
  int width_ = 1;
};

// One robot's log: (rows x n) columns.
struct RobotLog {
  LogColumn q, qd, qdd, tau, q_ref, qd_ref;
};

struct TrackingMetrics {
  long steps = 0;      // samples counted
  VecN sum_sq_error;   // sum of e_i^2
  VecN max_abs_error;  // max |e_i|
  VecN max_abs_tau;    // max |tau_i| applied
};

class Simulation {
 public:
  explicit Simulation(SimulationOptions options = SimulationOptions());

  // Adds a robot (copied) driven by `controller` towards `reference`, from
  // q0, qd0 (null: the reference's q and qd at t = 0). Only before the first
  // step (or after reset()). Returns the robot's index. Throws
  // std::invalid_argument on mismatched sizes, naming the argument.
  int add_robot(const Robot& robot, std::shared_ptr<Controller> controller,
                std::shared_ptr<const Reference> reference, const double* q0 = nullptr,
                const double* qd0 = nullptr);

  int robot_count() const { return static_cast<int>(slots_.size()); }
  const Robot& robot(int i) const { return slot_(i).robot; }
  const std::shared_ptr<Controller>& controller(int i) const { return slot_(i).controller; }
  const std::shared_ptr<const Reference>& reference(int i) const { return slot_(i).reference; }
  const SimulationOptions& options() const { return opt_; }

  // ---- state ----
  long step_count() const { return k_; }
  double time() const { return k_ * opt_.dt; }
  bool started() const { return started_; }
  bool diverged() const { return diverged_; }
  const VecN& q(int i) const { return slot_(i).q; }
  const VecN& qd(int i) const { return slot_(i).qd; }
  const VecN& tau(int i) const { return slot_(i).tau; }  // held torque
  const VecN& initial_q(int i) const { return slot_(i).q0; }
  const VecN& initial_qd(int i) const { return slot_(i).qd0; }

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

  // ---- log and metrics ----
  long log_rows() const { return log_t_.rows(); }
  const LogColumn& log_t() const { return log_t_; }
  const RobotLog& log(int i) const { return slot_(i).log; }
  const TrackingMetrics& metrics(int i) const { return slot_(i).metrics; }

 private:
  struct Slot {
    explicit Slot(const Robot& r) : robot(r) {}
    Robot robot;
    std::shared_ptr<Controller> controller;
    std::shared_ptr<const Reference> reference;
    VecN q0, qd0, q, qd, tau, tau_max;
    VecN q_ref, qd_ref, qdd_ref;
    VecN k1;  // qdd at (q, qd, tau), valid when k1_valid
    VecN q_prev, qd_prev;
    bool k1_valid = false;
    long updated_at = -1;  // step of the last controller / reference update
    Workspace ws;
    RobotLog log;
    TrackingMetrics metrics;
  };

  Slot& slot_(int i);
  const Slot& slot_(int i) const;
  void start_();
  void update_();
  void step_();
  [[noreturn]] void diverge_(int i, const std::string& why, bool in_step, bool state_is_result);
  void qdd_(Slot& s, VecN& out);

  SimulationOptions opt_;
  std::vector<Slot> slots_;
  LogColumn log_t_{1};
  long k_ = 0;
  long logged_at_ = -1;
  bool started_ = false;
  bool diverged_ = false;
  std::string divergence_;
};

// Runs each simulation up to time t_end on a pool of `threads` threads
// (0: hardware concurrency). Simulations must be distinct and must not share
// controller instances. Returns one exception per simulation (null when it
// finished), so that one failed run does not stop the others.
std::vector<std::exception_ptr> run_batch(const std::vector<Simulation*>& sims, double t_end, int threads,
                                          std::vector<double>* seconds = nullptr);

}  // namespace coopsim
