// Joint-space controllers (the paper's Controller, PID and NLController).
//
// A controller maps the measured state and the reference at time t to joint
// torques. The simulation calls reset() once before a run and compute() at
// every controller update (every k-th integration step; the torque is held
// constant in between, zero-order hold), then saturates the result at the
// robot's actuator limits |tau_i| <= tau_max_i whatever the controller did.
// Controllers keep state (integrals, filters), so one instance drives one
// robot in one simulation at a time.
#pragma once

#include <memory>
#include <string>

#include "coopsim/robot.hpp"

namespace coopsim {

// What a controller sees at one update; every pointer holds n values.
struct ControlInput {
  int n = 0;
  double t = 0.0;                 // s
  const double* q = nullptr;      // measured position (rad or m)
  const double* qd = nullptr;     // measured velocity (rad/s or m/s)
  const double* q_ref = nullptr;  // reference position
  const double* qd_ref = nullptr;
  const double* qdd_ref = nullptr;
};

class Controller {
 public:
  virtual ~Controller() = default;
  // Throws std::invalid_argument when the controller cannot drive `robot`
  // (e.g. gains of the wrong size), naming the argument.
  virtual void check(const Robot& robot) const {}
  // Called once before the first update of a run. period (s) is the time
  // between two updates (dt times the controller's step divisor).
  virtual void reset(const Robot& robot, double period) {}
  // Writes n commanded torques (N m or N) to tau.
  virtual void compute(const ControlInput& in, double* tau) = 0;
};

// Clamps each tau_i to [-tau_max_i, tau_max_i].
inline void saturate(int n, const double* tau_max, double* tau) {
  for (int i = 0; i < n; ++i) {
    if (tau[i] > tau_max[i]) tau[i] = tau_max[i];
    else if (tau[i] < -tau_max[i]) tau[i] = -tau_max[i];
  }
}

// Per-joint PID with
// - derivative on measurement: D = kd (qd_ref - v), where v is the measured
//   position differentiated by backward difference and passed through a
//   first-order low-pass of time constant derivative_filter (s; 0: none);
//   v starts at the measured velocity. The reference velocity is the
//   trajectory's own derivative, so a reference step gives no derivative kick;
// - integral anti-windup: the integral stops growing while the output is
//   saturated in the direction the error pushes, and |ki I| is clamped to
//   integral_limit (default: the actuator limits);
// - optional gravity compensation G(q) from `model` (default: the simulated
//   robot itself);
// - output saturated at the actuator limits.
//   tau = sat(kp e + ki I + kd (qd_ref - v) [+ G(q)]),  e = q_ref - q,
//   I_k = I_{k-1} + e_k h (h: controller period).
// Gains are (n,) vectors, or (1,) applied to every joint; all >= 0.
class PID : public Controller {
 public:
  PID(Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd, bool gravity_compensation = true,
      double derivative_filter = 0.0, Eigen::VectorXd integral_limit = Eigen::VectorXd(),
      std::shared_ptr<const Robot> model = nullptr);

  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute(const ControlInput& in, double* tau) override;

  const Eigen::VectorXd& kp() const { return kp_; }
  const Eigen::VectorXd& ki() const { return ki_; }
  const Eigen::VectorXd& kd() const { return kd_; }
  bool gravity_compensation() const { return gravity_; }
  double derivative_filter() const { return tf_; }
  const Eigen::VectorXd& integral_limit() const { return ilim_; }
  const std::shared_ptr<const Robot>& model() const { return model_; }
  // State after the last update: integral of the error (rad s or m s) and
  // the filtered measured velocity.
  const VecN& integral() const { return integral_; }
  const VecN& velocity_estimate() const { return v_; }

 private:
  Eigen::VectorXd kp_, ki_, kd_, ilim_;
  bool gravity_ = true;
  double tf_ = 0.0;
  std::shared_ptr<const Robot> model_;
  // run state
  std::shared_ptr<const Robot> gmodel_;  // model used for G(q) in this run
  Workspace ws_;
  VecN Kp_, Ki_, Kd_, Ilim_, tau_max_, integral_, v_, q_prev_, g_;
  int n_ = 0;
  double h_ = 0.0;
  bool first_ = true;
};

// Computed torque (the paper's nonlinear controller):
//   tau = M(q) (qdd_ref + kd (qd_ref - qd) + kp (q_ref - q)) + C(q, qd) + G(q) + K qd
// evaluated by one recursive Newton-Euler pass of `model` (default: the
// simulated robot; give a deliberately wrong copy, e.g. masses x 1.2, for
// robustness studies), saturated at the actuator limits.
class ComputedTorque : public Controller {
 public:
  ComputedTorque(Eigen::VectorXd kp, Eigen::VectorXd kd, std::shared_ptr<const Robot> model = nullptr);

  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute(const ControlInput& in, double* tau) override;

  const Eigen::VectorXd& kp() const { return kp_; }
  const Eigen::VectorXd& kd() const { return kd_; }
  const std::shared_ptr<const Robot>& model() const { return model_; }

 private:
  Eigen::VectorXd kp_, kd_;
  std::shared_ptr<const Robot> model_;
  std::shared_ptr<const Robot> run_model_;
  Workspace ws_;
  VecN Kp_, Kd_, tau_max_, v_, out_;
  int n_ = 0;
};

}  // namespace coopsim
