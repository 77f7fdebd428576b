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

#include <cstdint>
#include <memory>
#include <string>

#include "coopsim/checks.hpp"
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
  // The force/torque sensor's reading for a controller that senses() (else null): 6 values, world
  // axes, [force N; moment N m about the TCP], the wrench the robot's end applies to its
  // environment (see SensorOptions). In a simulation it is read at the start of the step, from
  // the contact and weld wrenches of the last world step.
  const double* wrench = nullptr;
  // The simulated robot's workspace (a Workspace keeps the kinematics at q it last computed) and that
  // robot's kinematics_id(), when the caller has them (a simulation's stages), else null and 0. A
  // controller evaluates a model with that kinematics_id at q there (Controller::workspace): the
  // kinematics one stage computed at q serve the others, with the same numbers, bit for bit.
  Workspace* workspace = nullptr;
  std::uint64_t robot = 0;
};

// A controller's linearisation at one update (Controller::linearize). With c its internal state (m values),
// the update gives tau = g(q, qd, c) and leaves c+ = h(q, qd, c); a saturated output's row is zero.
struct ControllerJacobians {
  Eigen::VectorXd tau;                         // (n,) the output at this update (N m or N)
  Eigen::VectorXd c;                           // (m,) the internal state before the update
  Eigen::VectorXd c_next;                      // (m,) and after it
  Eigen::MatrixXd dtau_dq, dtau_dqd, dtau_dc;  // (n, n), (n, n), (n, m)
  Eigen::MatrixXd dc_dq, dc_dqd, dc_dc;        // (m, n), (m, n), (m, m)
  std::vector<std::string> states;  // (m,) the names of c's entries
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
  // True for a controller that reads the force/torque sensor (ControlInput::wrench).
  virtual bool senses() const { return false; }
  // A copy with its configuration and state, for another run of the same model
  // (SimulationModel); null for a controller that cannot be copied (the default).
  virtual std::shared_ptr<Controller> clone() const { return nullptr; }
  // Fills J at the update `in` for `robot` with the period (s) between updates, without changing the
  // controller: at its state when it has run (reset for this robot), else at a new run's. False for a
  // controller that does not give its linearisation (the default).
  virtual bool linearize(const Robot& robot, double period, const ControlInput& in, ControllerJacobians& J) const {
    return false;
  }

 protected:
  // Where to evaluate `model` at in.q: the simulated robot's workspace when the model has its kinematics
  // (the robot or a copy of it), else `own`.
  static Workspace& workspace(const ControlInput& in, const Robot& model, Workspace& own) {
    return in.workspace && in.robot == model.kinematics_id() ? *in.workspace : own;
  }
};

// Controller::compute for numbers given as tables: q, qd, q_ref, qd_ref,
// qdd_ref (n,) each, finite, 1 <= n <= kMaxDof; t (s) finite. Each checked,
// naming it (std::invalid_argument); returns tau (n,).
// wrench: null, or (6,) finite, the sensor's reading (ControlInput::wrench) for a controller that
// senses() (without one such a controller sees no reading).
VecN compute(Controller& controller, double t, const Array& q, const Array& qd, const Array& q_ref,
             const Array& qd_ref, const Array& qdd_ref, const Array* wrench = nullptr);

// Gains as a table: one number (every joint) or (n,); the shape is checked
// here, the values by the controllers.
Eigen::VectorXd gains(const Array& a, const char* name);

// Clamps each tau_i to [-tau_max_i, tau_max_i].
inline void saturate(int n, const double* tau_max, double* tau) {
  for (int i = 0; i < n; ++i) {
    if (tau[i] > tau_max[i]) tau[i] = tau_max[i];
    else if (tau[i] < -tau_max[i]) tau[i] = -tau_max[i];
  }
}

class PID : public Controller {
 public:
  std::shared_ptr<Controller> clone() const override { return std::make_shared<PID>(*this); }
  // documentation (Python's too)
  static constexpr char kDoc[] = R"doc(
Per-joint PID controller (the paper's PID), derivative on measurement.

tau = sat(kp e + ki I + kd (qd_ref - v) [+ G(q)]), e = q_ref - q (rad or m),
I the integral of e (updated as I += e h, h the controller period), v the
measured position differentiated by backward difference and low-pass
filtered with time constant derivative_filter (s; 0: unfiltered; v starts at
the measured velocity); the reference velocity is the trajectory's own
derivative, so a reference step gives no derivative kick. Anti-windup: I
stops growing while the output is saturated in the direction e pushes, and
|ki I| <= integral_limit (default: the actuator limits). gravity_compensation adds G(q) of `model` (default:
the simulated robot). The output is saturated at the actuator limits.

kp (N m/rad), ki (N m/(rad s)), kd (N m s/rad): scalars (every joint) or
(n,) arrays, all >= 0 (N/m ... for prismatic joints).)doc";
  PID(Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd, bool gravity_compensation = true,
      double derivative_filter = 0.0, Eigen::VectorXd integral_limit = Eigen::VectorXd(),
      std::shared_ptr<const Robot> model = nullptr);

  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute(const ControlInput& in, double* tau) override;
  // c = [integral (n); velocity estimate (n); last measured q (n)]: the update's exact Jacobians (the
  // backward difference and its filter, the integral's anti-windup branch, G(q)'s derivative); a new run's
  // state is the integral 0, the estimate qd and the last q = q - period qd (a steady motion).
  bool linearize(const Robot& robot, double period, const ControlInput& in, ControllerJacobians& J) const override;

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

class ComputedTorque : public Controller {
 public:
  std::shared_ptr<Controller> clone() const override { return std::make_shared<ComputedTorque>(*this); }
  // documentation (Python's too)
  static constexpr char kDoc[] = R"doc(
Computed-torque controller (the paper's nonlinear controller):

    tau = M(q) (qdd_ref + kd (qd_ref - qd) + kp (q_ref - q)) + C(q, qd) + G(q) + K qd

evaluated by one recursive Newton-Euler pass, with M, C, G, K from `model` (default: the simulated robot itself; give a
deliberately wrong copy, e.g. scara1(masses=1.2 * r.masses), to study
robustness), saturated at the actuator limits. With the exact model each
joint's error obeys e'' + kd e' + kp e = 0: kp = w^2, kd = 2 w is critically
damped with bandwidth w (rad/s). kp (1/s^2), kd (1/s): scalars or (n,), >= 0.)doc";
  ComputedTorque(Eigen::VectorXd kp, Eigen::VectorXd kd, std::shared_ptr<const Robot> model = nullptr);

  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute(const ControlInput& in, double* tau) override;
  // No internal state: dtau/dx = dID/dx - M [kp, kd] (the model's inverse dynamics' derivatives).
  bool linearize(const Robot& robot, double period, const ControlInput& in, ControllerJacobians& J) const override;

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

class StateFeedback : public Controller {
 public:
  std::shared_ptr<Controller> clone() const override { return std::make_shared<StateFeedback>(*this); }
  // documentation (Python's too)
  static constexpr char kDoc[] = R"doc(
Linear state feedback around the reference (the law of an LQR):

    tau = sat(tau0 [+ G(q)] - K [q - q_ref; qd - qd_ref])

K (n, 2n): the gain on the state error x - x_ref, x = [q; qd] (N m/rad and
N m s/rad for revolute joints), e.g. from scipy.linalg.solve_discrete_are on
coopsim.linearize's (A, B); tau0 (n,): feed-forward torques (N m or N,
default 0; e.g. the linear model's tau0); gravity_compensation adds G(q) of
`model` (default: the simulated robot). Saturated at the actuator limits.
coopsim.linearize closes the loop with it exactly (dtau/dx = -K [+ dG/dq]).)doc";
  StateFeedback(Eigen::MatrixXd K, Eigen::VectorXd tau0 = Eigen::VectorXd(), bool gravity_compensation = false,
                std::shared_ptr<const Robot> model = nullptr);

  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute(const ControlInput& in, double* tau) override;
  bool linearize(const Robot& robot, double period, const ControlInput& in, ControllerJacobians& J) const override;

  const Eigen::MatrixXd& K() const { return K_; }
  const Eigen::VectorXd& tau0() const { return tau0_; }
  bool gravity_compensation() const { return gravity_; }
  const std::shared_ptr<const Robot>& model() const { return model_; }

 private:
  // tau before saturation at (q, qd) and the reference, G(q) of gm when given
  void law_(const Robot* gm, const double* q, const double* qd, const double* q_ref, const double* qd_ref,
            Workspace& ws, Eigen::VectorXd& tau) const;
  Eigen::MatrixXd K_;
  Eigen::VectorXd tau0_;
  bool gravity_ = false;
  std::shared_ptr<const Robot> model_;
  // run state
  std::shared_ptr<const Robot> gmodel_;
  Workspace ws_;
  Eigen::VectorXd out_;
  VecN tau_max_;
  int n_ = 0;
};

}  // namespace coopsim
