// Cooperative control: one controller drives several robots at once (Simulation::add_cooperative),
// seeing all their states, their clamps' sensed wrenches and what each holds; the simulation calls
// it where it calls the robots' own controllers, which stand aside while it drives them.
//
// The held object, as the controllers see it (member 0 is the reference member, the leader):
//   its pose  T_o = T_tcp,0 G_0, G_k the body's pose in clamp k's TCP frame from its weld and the
//             present kinematics (the weld's pose at attach carried by the clamp link);
//   its reference T_o,ref = T_tcp,0,ref G_0, the reference member's TCP at its joint reference;
//   twists and accelerations carried from the TCP to the object's centre as a rigid body's.
// The clamps' wrenches h_k = [f_k; mu_k] are what each clamp applies to the object at its TCP
// (the sensor's reading, world axes); the object-level quantities (external wrench about the
// object's centre, squeeze, load share) are held_body.hpp's.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "coopsim/held_body.hpp"
#include "coopsim/task.hpp"

namespace coopsim {

// One robot of a cooperative group at an update.
struct CoopMember {
  int robot = -1;                 // its index in the simulation
  ControlInput in;                // q, qd, the joint reference and the sensor (ControlInput::wrench)
  int held = -1;                  // the free body it holds (world id), -1: none
  Eigen::Isometry3d grip = Eigen::Isometry3d::Identity();  // the held body's pose in the TCP frame
};

class CooperativeController {
 public:
  virtual ~CooperativeController() = default;
  // Throws std::invalid_argument when it cannot drive these robots (their number, gains' sizes).
  virtual void check(const std::vector<const Robot*>& robots) const {}
  // Once before the first update of a run (or when it starts driving a running simulation).
  virtual void reset(const std::vector<const Robot*>& robots, double period) = 0;
  // Writes each member's torques (members[k].in.n values) to tau[k].
  virtual void compute(double t, const std::vector<CoopMember>& members, const std::vector<double*>& tau) = 0;
  // A copy with its configuration and state, for another run of the same model; null when it
  // cannot be copied (the default).
  virtual std::shared_ptr<CooperativeController> clone() const { return nullptr; }
};

// Object-level control of two arms holding one object (documentation, Python's too).
class ObjectControl : public CooperativeController {
 public:
  std::shared_ptr<CooperativeController> clone() const override { return std::make_shared<ObjectControl>(*this); }
  static constexpr char kDoc[] = R"doc(
Object-level (symmetric) control of two arms holding one object.

The object's desired motion becomes the wrench on it, distributed to the clamps with a commanded
load share and internal squeeze, closed on the sensed wrenches, and each arm's task-space torques:

1. object error e = reference - measured (position m; rotation vector of R_ref R^T, rad; world) and
   its rate; a* = a_ref + kd e_rate + kp e (kp 1/s^2, kd 1/s: scalars or (6,) over x, y, z, rx, ry, rz);
   with `impedance` = (stiffness, damping, mass) (scalars or (6,): N/m, N m/rad; N s/m, N m s/rad;
   kg, kg m^2) the object yields to a push as that mass-spring-damper: a compliant offset x_c from
   the reference obeys mass x_c'' + damping x_c' + stiffness x_c = h_push (an admittance, integrated
   at each update) and the motion loop tracks the reference moved by x_c. h_push is estimated from
   the object's Newton-Euler equations: its model times its measured acceleration (the twist's
   difference, low-pass filtered with time constant accel_filter s) less its weight and the clamps'
   sensed wrenches. The motion loop (kp, kd) should be several times faster than the impedance;
2. the object wrench from the controller's model of the object (mass kg, inertia (3, 3) kg m^2
   about its centre in its own frame): h_d = [m (a* - g); I alpha* + w x I w] (less h_push with an
   impedance: the clamps take the push, the motion loop follows x_c without an error);
3. the clamps' wrenches: the least-norm solution of  sum_k W_k h_k = h_d, clamp 0 carries
   `load_share` of the vertical load, the squeeze is `squeeze` N (compression positive), each
   clamp's wrench having only the components its arm commands (forces; moments about its commanded
   rotation axes): the rest of the object wrench (e.g. the roll about the bar's own axis) is
   carried by the clamps' structure and is not commanded;
4. each arm: its TCP accelerates as a point of the object (a* carried to it), and applies
   h_k + kp_force (h_k - h_k,sensed) + ki_force * integral(h_k - h_k,sensed) through J^T, with its own
   inverse dynamics (TaskController.torques; the jaw position-controlled).
The object's pose is the reference member's (robot 0 of the group) grip applied to its TCP; its
reference the same grip on its TCP at its joint reference, moved by `offset` ((3,) m, world; 0 at first).

The commands load_share, squeeze and offset may be set during a run (the constructor's rules), taken at
the next control update; a new offset is reached over `offset_ramp` s (0, the default: at once) along a
straight line from the offset of the last update, at a constant rate that the reference's velocity
carries.)doc";
  struct Gains {
    Vec6 kp = Vec6::Constant(400.0), kd = Vec6::Constant(40.0);
    double kp_force = 0.5, ki_force = 10.0, integral_limit = 50.0;
  };
  ObjectControl(double mass, const Eigen::Matrix3d& inertia, Gains gains, double load_share = 0.5,
                double squeeze = 0.0, bool impedance = false, Vec6 stiffness = Vec6::Zero(),
                Vec6 damping = Vec6::Zero(), Vec6 imp_mass = Vec6::Ones(), double accel_filter = 0.002);
  void check(const std::vector<const Robot*>& robots) const override;
  void reset(const std::vector<const Robot*>& robots, double period) override;
  void compute(double t, const std::vector<CoopMember>& members, const std::vector<double*>& tau) override;

  double mass() const { return mass_; }
  const Eigen::Matrix3d& inertia() const { return inertia_; }
  const Gains& gains() const { return gains_; }
  double load_share() const { return share_; }
  double squeeze() const { return squeeze_; }
  // The commands during a run, taken at the next update (std::invalid_argument, the constructor's rules):
  // clamp 0's part of the vertical load in [0, 1]; the squeeze N, finite; the offset of the object's
  // reference (3, world, m, finite), reached over offset_ramp s (finite, >= 0; 0: at once) from the
  // offset of the last update.
  void set_load_share(double load_share);
  void set_squeeze(double squeeze);
  void set_offset(const Eigen::Vector3d& offset);
  void set_offset_ramp(double seconds);
  const Eigen::Vector3d& offset() const { return offset_; }
  double offset_ramp() const { return ramp_; }
  bool impedance() const { return impedance_; }
  // After the last update (impedance): the compliant offset from the reference (6, world: m, rad) and
  // the estimated push on the object (6, N and N m about its centre).
  const Vec6& compliant_offset() const { return xc_; }
  const Vec6& push_estimate() const { return push_; }
  // After the last update: the object's pose error (6, world: m, rad), the wrench commanded on it
  // (6, about its centre), each clamp's commanded wrench (world, about its TCP).
  const Vec6& object_error() const { return err_; }
  const Vec6& object_wrench() const { return hd_; }
  const std::vector<Vec6>& clamp_wrenches() const { return cmd_; }

 private:
  double mass_;
  Eigen::Matrix3d inertia_;
  Gains gains_;
  double share_ = 0.5, squeeze_ = 0.0;
  // the offset commanded and its ramp (s); the run's: the offset of the last update, the ramp under way
  Eigen::Vector3d offset_ = Eigen::Vector3d::Zero(), off_now_ = Eigen::Vector3d::Zero(),
                  ramp_from_ = Eigen::Vector3d::Zero(), ramp_to_ = Eigen::Vector3d::Zero();
  double ramp_ = 0.0, ramp_t0_ = 0.0;
  bool impedance_ = false;
  Vec6 K_, D_, Md_;
  double accel_filter_ = 0.002;
  Vec6 xc_ = Vec6::Zero(), vc_ = Vec6::Zero(), ac_ = Vec6::Zero(), acc_f_ = Vec6::Zero(), tw_prev_ = Vec6::Zero(),
       push_ = Vec6::Zero();
  double acc_alpha_ = 1.0;
  bool has_prev_ = false;
  // run state
  std::vector<std::shared_ptr<TaskController>> arms_;
  std::vector<Vec6> I_, cmd_;
  Vec6 err_ = Vec6::Zero(), hd_ = Vec6::Zero();
  Eigen::Vector3d g_ = Eigen::Vector3d::Zero();
  double h_ = 0.0;
};

// Leader-follower (documentation, Python's too).
class LeaderFollower : public CooperativeController {
 public:
  std::shared_ptr<CooperativeController> clone() const override { return std::make_shared<LeaderFollower>(*this); }
  static constexpr char kDoc[] = R"doc(
Leader-follower control of two arms holding one object (after Luh and Zheng).

The leader (robot 0 of the group) tracks its own reference in task space, like computed torque on
its TCP: a* = a_ref + kd e_rate + kp e (kp 1/s^2, kd 1/s), the sensed wrench cancelled (it carries
what it feels). The follower's reference is where its clamp must be for the grip it holds, given the
leader's clamp: T_f,ref = T_lead G_leader G_f^-1, T_lead the leader's measured position with its planned
orientation (the leader's own rotation errors would swing the follower's reference through the object's
lever), its twist and acceleration carried as a rigid body's from the leader's measured velocity and
commanded acceleration; around it the follower is an impedance (stiffness N/m and N m/rad, damping
N s/m, mass kg: scalars or one per commanded direction) driven by its sensed wrench, less
`follower_share` of the object's weight (`object_mass`, the model's, kg): it carries that part and
yields to the rest, so the internal force stays small. Both arms command the directions both can
(the SCARAs: x, y, z, yaw); the rest follows their joint references.)doc";
  LeaderFollower(double kp, double kd, Eigen::VectorXd stiffness, Eigen::VectorXd damping,
                 Eigen::VectorXd mass, double object_mass, double follower_share = 0.5);
  void check(const std::vector<const Robot*>& robots) const override;
  void reset(const std::vector<const Robot*>& robots, double period) override;
  void compute(double t, const std::vector<CoopMember>& members, const std::vector<double*>& tau) override;
  double kp() const { return kp_; }
  double kd() const { return kd_; }
  const Eigen::VectorXd& stiffness() const { return k_; }
  const Eigen::VectorXd& damping() const { return d_; }
  const Eigen::VectorXd& mass() const { return m_; }
  double object_mass() const { return object_mass_; }
  double follower_share() const { return share_; }
  // The follower's pose error from its reference after the last update (6, task axes: m, rad).
  const Vec6& relative_error() const { return rel_; }

 private:
  double kp_, kd_;
  Eigen::VectorXd k_, d_, m_;
  double object_mass_, share_;
  std::vector<std::shared_ptr<TaskController>> arms_;
  Vec6 K_, D_, Md_, rel_ = Vec6::Zero(), lead_acc_ = Vec6::Zero();
  Eigen::Vector3d g_ = Eigen::Vector3d::Zero();
};

}  // namespace coopsim
