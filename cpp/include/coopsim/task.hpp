// Task-space control: controllers that act in the space of the robot's tool centre point (TCP,
// for a clamp the point between the jaws) and see the force/torque sensor there.
//
// The task axes. Six directions, in this order: x, y, z (the TCP's position along the world
// axes) and roll, pitch, yaw (rotations about three orthonormal world axes that follow the tool):
//   yaw   about the world's vertical z,
//   pitch about the tool's y axis (the jaw axis of the SCARAs' clamps) laid into the horizontal
//         plane: p = normalize(y_tool - (y_tool . z) z),
//   roll  about r = p x z (horizontal, across the pitch axis).
// For the SCARAs these are the clamp's physical rotations: SCARA #1's fifth joint turns the clamp
// about y_tool (always horizontal), so it commands x, y, z, yaw and pitch; SCARA #2 commands x, y,
// z and yaw with five arm joints (one redundant). The axes are undefined when y_tool is vertical
// (a std::domain_error names the pose).
//
// Errors are reference minus measured: for x, y, z the position difference (m); for the rotations
// the rotation vector of R_ref R^T (world) projected on the axes (rad), exact for yaw about the
// fixed vertical and to first order otherwise. Velocities and accelerations are the geometric
// twist [v; w] and its derivative [a; alpha] of the TCP projected on the axes; the reference's
// come from the joint reference by the robot's kinematics: x_ref = FK(q_ref), xd_ref = J(q_ref)
// qd_ref, xdd_ref = J(q_ref) qdd_ref + Jd(q_ref, qd_ref) qd_ref (a plan_cartesian trajectory is
// such a reference), with the jaw's position and velocity the measured ones: the TCP, midway between
// the jaws, is referred to the opening the jaw has (a jaw squeezing a body stops short of its
// reference).
//
// The commanded directions: those whose row of the task Jacobian (the arm's joints, the jaw
// excluded) is not zero somewhere in the joint limits (checked at reset at the reference's
// configuration and at random samples). The others are reported (TaskState's errors hold all
// six), never commanded: a gain or setpoint along one of them is refused.
//
// The law's common part (TaskController::torques): given a task acceleration a* for the commanded
// directions and a wrench w to apply (task axes, [force N; moment N m about the TCP], what the
// clamp applies to its environment), the joints' accelerations are
//   jaw:  qdd_ref + jaw_kd (qd_ref - qd) + jaw_kp (q_ref - q)   (position-controlled),
//   arm:  J_c qdd_arm = a*_c - (Jd qd)_c - J_c,jaw qdd_ref,jaw (J_c: the commanded rows; the jaw's
//         planned motion, not its correction, which a jaw closed on a body cannot follow),
//         solved exactly when the arm has as many joints as commanded directions, else as
//         qdd_arm = qdd_0 + J_c^T (J_c J_c^T)^-1 (rhs - J_c qdd_0) (the pseudo-inverse) with
//         qdd_0 = qdd_ref + null_kd (qd_ref - qd) + null_kp (q_ref - q): the joints' motion in J_c's
//         null space tracks the joint reference, so at rest the deviation from the reference has
//         no component there (SCARA #2's elbow stays on the planned one as far as the task allows);
//         with the inverse dynamics below the null-space motion does not disturb the task,
// then tau = M qdd + C + G + K qd (one Newton-Euler pass of `model`, default the robot, with the jaw's
// planned acceleration) + J^T w_world, plus on the jaw its correction times its own inertia M_jj (the
// arm does not answer a jaw correction that a jaw squeezing a body does not follow), saturated at the
// actuator limits by the simulation.
#pragma once

#include <array>
#include <memory>
#include <string>

#include "coopsim/controller.hpp"

namespace coopsim {

enum TaskAxis : int { kX = 0, kY, kZ, kRoll, kPitch, kYaw };
constexpr int kTaskAxes = 6;
// "x", "y", "z", "roll", "pitch", "yaw"
const char* task_axis_name(int axis);
// The axis index of a name; std::invalid_argument naming `what` and the names allowed otherwise.
int task_axis(const std::string& name, const char* what);

// A rigid payload the controller knows (e.g. the held body): its weight and inertia are taken out
// of the sensed wrench. mass kg >= 0; com (3,) m and inertia (3, 3) kg m^2 about the com, both in
// the tool frame.
struct Payload {
  double mass = 0.0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
};

// The TCP's pose at q in the world: its position and the task axes' rotation basis
// B = [r p z] (columns, world). Throws std::domain_error when y_tool is vertical.
Eigen::Matrix3d task_axes(const Eigen::Isometry3d& tool);

// What a task-space law sees at one update (task axes, see the header comment).
struct TaskState {
  double t = 0.0;
  int n = 0;
  int jaw = -1;                       // the jaw's joint index (0-based), -1 without a clamp
  VecN q, qd, q_ref, qd_ref, qdd_ref;  // the joints' state and reference
  Eigen::Isometry3d pose, pose_ref;   // TCP, world
  Eigen::Matrix3d axes;               // B: columns r, p, z (world) at the measured pose
  Vec6 error, error_rate;             // reference minus measured: m, rad; m/s, rad/s
  Vec6 velocity, velocity_ref, accel_ref;  // task-axis twist, reference twist and acceleration
  Vec6 wrench = Vec6::Zero();         // sensed: what the clamp applies to its environment (task axes)
  Vec6 external = Vec6::Zero();       // estimated wrench of the environment on the clamp: -wrench
                                      //   minus the payload's weight and inertia (task axes)
  bool sensed = false;                // a sensor reading was given
  Mat6N J;                            // task Jacobian (rows x..yaw), n columns
  Vec6 bias;                          // (Jd qd) in task axes
  std::array<bool, kTaskAxes> commanded{};
};

// The defaults (the bindings read them): the jaw's and the null space's gains, 1/s^2 and 1/s (jaw:
// critically damped at 50 rad/s; null space at 20 rad/s), the hybrid law's force PI and damping.
struct TaskDefaults {
  static constexpr double jaw_kp = 2500.0, jaw_kd = 100.0, null_kp = 400.0, null_kd = 40.0;
  static constexpr double kp_force = 0.5, ki_force = 20.0, kv = 20.0, kp = 900.0, kd = 60.0, integral_limit = 100.0;
};

class TaskController : public Controller {
 public:
  // directions: names (see TaskAxis), empty: every direction the robot can command. Gains for the
  // jaw and the null space: scalars (1/s^2, 1/s), >= 0. payload: see Payload (mass 0: none).
  TaskController(std::vector<std::string> directions = {}, double jaw_kp = TaskDefaults::jaw_kp,
                 double jaw_kd = TaskDefaults::jaw_kd, double null_kp = TaskDefaults::null_kp,
                 double null_kd = TaskDefaults::null_kd, Payload payload = Payload(),
                 std::shared_ptr<const Robot> model = nullptr);

  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute(const ControlInput& in, double* tau) override;
  bool senses() const override { return true; }
  // Throws std::invalid_argument naming what is wrong with a payload (negative mass, non-finite or
  // asymmetric inertia).
  static void check_payload(const Payload& p);

  // The law: writes n torques from the state (usually via torques()).
  virtual void compute_task(const TaskState& s, double* tau) = 0;
  // A reference given in the task instead of the joint reference's image (world: the TCP's pose,
  // twist [v; w] and acceleration [a; alpha]), e.g. a follower's from its leader.
  struct TaskReference {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    Vec6 twist = Vec6::Zero(), accel = Vec6::Zero();
  };
  // Builds the state at one update (compute() = observe() then compute_task()); `ref` replaces the
  // reference's image when given. The state stays valid until the next call.
  const TaskState& observe(const ControlInput& in, const TaskReference* ref = nullptr);
  // The common part (header comment): a* (6, task axes; the commanded entries are used) and the
  // wrench to apply (6, task axes) to joint torques.
  void torques(const TaskState& s, const Vec6& accel, const Vec6& wrench, double* tau);

  // ---- configuration ----
  const std::vector<std::string>& directions() const { return names_; }  // as given
  double jaw_kp() const { return jaw_kp_; }
  double jaw_kd() const { return jaw_kd_; }
  double null_kp() const { return null_kp_; }
  double null_kd() const { return null_kd_; }
  const Payload& payload() const { return payload_; }
  const std::shared_ptr<const Robot>& model() const { return model_; }
  // ---- after reset ----
  const std::array<bool, kTaskAxes>& commanded() const { return commanded_; }  // the run's directions
  const std::array<bool, kTaskAxes>& commandable() const { return commandable_; }
  // ---- after the last update ----
  const TaskState& state() const { return s_; }

 protected:
  // The commanded directions' order as given (indices), valid after reset.
  const std::vector<int>& order() const { return order_; }
  // Checks a per-direction parameter: 1 or len(directions) values (directions given), else 1 or
  // the commandable count; returns the 6 values by axis (0 where not commanded).
  Vec6 per_axis(const Eigen::VectorXd& v, const char* name) const;
  std::array<bool, kTaskAxes> commandable_{};
  std::array<bool, kTaskAxes> commanded_{};

 private:
  std::vector<std::string> names_;
  std::vector<int> order_;
  double jaw_kp_, jaw_kd_, null_kp_, null_kd_;
  Payload payload_;
  std::shared_ptr<const Robot> model_;
  // run state
  std::shared_ptr<const Robot> robot_, run_model_;
  Workspace ws_, wsr_;
  // observe()'s caller's workspace and robot (ControlInput), for torques() at the same update
  ControlInput shared_;
  TaskState s_;
  Vec6 prev_accel_ = Vec6::Zero();  // world [a; alpha] commanded at the last update (payload inertia)
  // the reference's image at the last update, reused while the joint reference stays the same
  bool ref_valid_ = false;
  VecN ref_q_, ref_qd_, ref_qdd_;
  Eigen::Isometry3d ref_pose_;
  Vec6 ref_twist_, ref_accel_;
  Eigen::Vector3d ref_jaw_ = Eigen::Vector3d::Zero();  // the tool Jacobian's jaw column (linear) at the reference
  VecN out_, qdd_;
  double jaw_inertia_ = 0.0;  // M_jj of the jaw (kg), for its own correction's torque
  int n_ = 0;
};

// Which task directions `robot` can command with its arm (the jaw excluded): a direction whose
// Jacobian row is nonzero at q0 or at one of `samples` seeded random configurations in the limits.
std::array<bool, kTaskAxes> commandable_directions(const Robot& robot, const double* q0 = nullptr, int samples = 32);

// Operational-space impedance (documentation, Python's too).
class Impedance : public TaskController {
 public:
  std::shared_ptr<Controller> clone() const override { return std::make_shared<Impedance>(*this); }
  static constexpr char kDoc[] = R"doc(
Operational-space impedance control of the tool centre point (TCP).

In each commanded task direction the TCP behaves as the chosen mass-spring-damper
around the reference (errors e = reference - measured, see TaskController):

    mass (xdd - xdd_ref) + damping (xd - xd_ref) + stiffness (x - x_ref) = h_ext

h_ext the wrench the environment applies to the clamp, from the force/torque sensor (minus the
known payload's weight and inertia); the law commands a* = xdd_ref + (h_ext + damping e_rate +
stiffness e) / mass and turns it into torques with the robot's model (TaskController.torques),
cancelling the sensed wrench (force_feedback=True). Without the sensor's feedback the arm's own
inertia is felt instead of `mass`. stiffness N/m and N m/rad, damping N s/m and N m s/rad, mass kg
and kg m^2: scalars or one per direction (in the order of `directions`), stiffness and damping
>= 0, mass > 0. Natural frequency sqrt(stiffness / mass), damping ratio
damping / (2 sqrt(stiffness mass)).)doc";
  Impedance(Eigen::VectorXd stiffness, Eigen::VectorXd damping, Eigen::VectorXd mass,
            std::vector<std::string> directions = {}, bool force_feedback = true,
            double jaw_kp = TaskDefaults::jaw_kp, double jaw_kd = TaskDefaults::jaw_kd,
            double null_kp = TaskDefaults::null_kp, double null_kd = TaskDefaults::null_kd, Payload payload = Payload(),
            std::shared_ptr<const Robot> model = nullptr);
  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute_task(const TaskState& s, double* tau) override;
  const Eigen::VectorXd& stiffness() const { return k_; }
  const Eigen::VectorXd& damping() const { return d_; }
  const Eigen::VectorXd& mass() const { return m_; }
  bool force_feedback() const { return feedback_; }

 private:
  Eigen::VectorXd k_, d_, m_;
  bool feedback_ = true;
  Vec6 K_, D_, Md_;
};

// Hybrid position/force control (documentation, Python's too).
class HybridForce : public TaskController {
 public:
  std::shared_ptr<Controller> clone() const override { return std::make_shared<HybridForce>(*this); }
  static constexpr char kDoc[] = R"doc(
Hybrid position/force control of the tool centre point (TCP).

force_directions (names) are force-controlled: the clamp applies force (N, or N m for a rotation)
along each, what it pushes on its environment (pressing down onto a surface is a negative z),
with a PI on the sensed wrench w_s:

    w_cmd = force + kp_force (force - w_s) + ki_force * integral(force - w_s) dt,  a* = -kv xd

(kp_force dimensionless, ki_force 1/s, kv 1/s: damping of the motion along the force direction).
The other commanded directions are position-controlled like computed torque in task space:
a* = xdd_ref + kd e_rate + kp e (kp 1/s^2, kd 1/s), with the sensed wrench along them cancelled
(force_feedback=True): a friction force does not drag the TCP off its path. Gains: scalars or one
per direction (force ones in the order of force_directions, position ones in the order of the
remaining commanded directions), >= 0; integral windup limited to |ki_force I| <= integral_limit N.
A force direction the robot cannot command is refused, naming it.)doc";
  HybridForce(std::vector<std::string> force_directions, Eigen::VectorXd force, Eigen::VectorXd kp_force,
              Eigen::VectorXd ki_force, Eigen::VectorXd kv, Eigen::VectorXd kp, Eigen::VectorXd kd,
              std::vector<std::string> directions = {}, bool force_feedback = true,
              double integral_limit = TaskDefaults::integral_limit, double jaw_kp = TaskDefaults::jaw_kp,
              double jaw_kd = TaskDefaults::jaw_kd, double null_kp = TaskDefaults::null_kp,
              double null_kd = TaskDefaults::null_kd,
              Payload payload = Payload(), std::shared_ptr<const Robot> model = nullptr);
  void check(const Robot& robot) const override;
  void reset(const Robot& robot, double period) override;
  void compute_task(const TaskState& s, double* tau) override;
  const std::vector<std::string>& force_directions() const { return fnames_; }
  const Eigen::VectorXd& force() const { return f_; }
  const Eigen::VectorXd& kp_force() const { return kpf_; }
  const Eigen::VectorXd& ki_force() const { return kif_; }
  const Eigen::VectorXd& kv() const { return kv_; }
  const Eigen::VectorXd& kp() const { return kp_; }
  const Eigen::VectorXd& kd() const { return kd_; }
  bool force_feedback() const { return feedback_; }
  double integral_limit() const { return ilim_; }
  // The force error's integral (task axes, N s), after the last update.
  const Vec6& integral() const { return I_; }

 private:
  std::vector<std::string> fnames_;
  std::vector<int> forder_, porder_;
  Eigen::VectorXd f_, kpf_, kif_, kv_, kp_, kd_;
  bool feedback_ = true;
  double ilim_ = TaskDefaults::integral_limit;
  std::array<bool, kTaskAxes> is_force_{};
  Vec6 F_, Kpf_, Kif_, Kv_, Kp_, Kd_, I_;
  double h_ = 0.0;
};

}  // namespace coopsim
