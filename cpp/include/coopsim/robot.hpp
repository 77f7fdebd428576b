// Serial robot description: standard Denavit-Hartenberg table, the paper's
// centre-of-mass table, mass properties, friction and limits.
//
// Conventions (SI units, radians):
// - Standard (distal) DH: A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i); joint i
//   moves about / along z_{i-1}. For a revolute joint q_i is added to theta_i,
//   for a prismatic joint q_i is added to d_i (theta_i, d_i are offsets).
// - A centre-of-mass row uses the same four parameters, applied from frame i-1
//   to the centre-of-mass (CoM) frame of link i, with q_i added in the same
//   slot as in the DH row, so the CoM frame moves with its link.
// - Link i (1-based) is the body moved by joint i; link 0 is the fixed base.
// - The inertia tensor of link i is about its CoM, expressed in its CoM frame.
// - Frame 0 is the base frame, placed in the world by a position, a yaw and
//   (for a first joint axis that is not vertical) a fixed base orientation:
//   base = T(position) Rz(yaw) R_orientation.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "coopsim/checks.hpp"
#include "coopsim/shape.hpp"

namespace coopsim {

// Largest number of joints; workspaces use fixed storage of this size so that
// hot paths never allocate.
constexpr int kMaxDof = 12;

using VecN = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxDof, 1>;
using MatN = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDof, kMaxDof>;
using Mat6N = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxDof>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

constexpr double kInf = std::numeric_limits<double>::infinity();

enum class JointType : char { Revolute = 'R', Prismatic = 'P' };

// Four Denavit-Hartenberg parameters [theta, d, a, alpha] (rad, m, m, rad).
struct DHParams {
  double theta = 0.0;
  double d = 0.0;
  double a = 0.0;
  double alpha = 0.0;
};

// One joint and the link it moves.
struct Link {
  JointType type = JointType::Revolute;
  DHParams dh;                 // joint frame i-1 -> frame i (q added to theta or d)
  DHParams com;                // frame i-1 -> CoM frame of link i (q in the same slot)
  double mass = 1.0;           // kg, >= 0 (0: a link that only carries the next joint)
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Identity() * 1e-3;  // kg m^2 about CoM, CoM frame
  double friction = 0.0;       // viscous K_i: N m s/rad or N s/m, >= 0
  // rotor inertia reflected through the gear, J_m G^2 (kg m^2, or kg for a
  // prismatic joint), >= 0: added to M_ii (MuJoCo's and Pinocchio's armature)
  double armature = 0.0;
  // Coulomb friction F_c (N m or N), >= 0, regularised as F_c tanh(qd / v_c)
  // with v_c = coulomb_width (rad/s or m/s), > 0: smooth, odd, and its power
  // qd F_c tanh(qd / v_c) >= 0, so it never adds energy. Within |qd| < v_c it
  // acts as a damper of about F_c / v_c: RK4 stays stable for
  // dt F_c / (v_c M_ii) below about 2.5.
  double coulomb = 0.0;
  double coulomb_width = 0.01;
  double q_min = -kInf;        // rad or m (may be -inf)
  double q_max = kInf;         // rad or m (may be +inf)
  double tau_max = kInf;       // actuator limit |tau_i| <= tau_max: N m or N, > 0
};

// The tool centre point; documentation (Python's too):
inline constexpr char kToolDoc[] = R"doc(The tool centre point (TCP).

Its orientation is that of `offset` (4, 4) on `link`; its position is the
midpoint between the point offset[:3, 3] on `link` and `second_point` (3,)
on `second_link`, both in their link's DH frame (links 1..n, -1 the last). A
fixed tool uses the same link and point twice; a clamp with one fixed and
one moving jaw uses a point on each jaw, so the TCP stays between the jaws.)doc";
struct Tool {
  int link = -1;                                     // 1..n, or -1 for the last link
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  int second_link = -1;                              // 1..n, or -1 for the last link
  Eigen::Vector3d second_point = Eigen::Vector3d::Zero();
};

// A wrench on a link; documentation (Python's too):
inline constexpr char kWrenchDoc[] = R"doc(An external wrench on a link.

Force (N) and moment (N m), both in world coordinates, [fx, fy, fz, mx, my,
mz], acting at `point` (3,) m given in the DH frame of `link` (1..n, negative
counts from the last); or, made by Wrench.at_tool, at the tool centre point,
mapped by the tool Jacobian as a (6,) f_ext is.)doc";
struct ExternalWrench {
  int link = -1;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Vec6 wrench = Vec6::Zero();  // [fx, fy, fz, mx, my, mz]
  bool at_tool = false;
};

// End stops: beyond a joint limit a spring-damper scaled by the joint's own
// inertia M_ii(q) pushes the joint back,
//   tau_stop = -M_ii (w^2 (q - q_lim) + 2 zeta w qd),
// and never pulls it towards the limit. Scaling by M_ii makes the stop
// equally stiff for a light jaw and a heavy arm: a joint hitting its stop
// behaves like a critically damped oscillator of natural frequency w, so it
// penetrates about v / (e w) at impact speed v and sags g / w^2 at rest. RK4
// stays stable for w dt below about 2.5; at the default w = 500 rad/s and
// dt = 0.2 ms, w dt = 0.1.
struct EndStop {
  double frequency = 500.0;    // natural frequency w, rad/s
  double damping_ratio = 1.0;  // zeta
};

struct GeneratedDynamics;  // see generated.hpp

// A shape fixed to a link; documentation (Python's too):
inline constexpr char kLinkBoxDoc[] = R"doc(A shape fixed to a link: what the world collides and the views draw.

A box (LinkBox(link, half_extents, pose, name)), or made by LinkBox.sphere,
LinkBox.cylinder or LinkBox.hull: kind is "box", "sphere", "cylinder" or
"hull". link: 0 (the base, fixed to DH frame 0) .. n. pose: (4, 4) the
shape's frame in the DH frame of `link` (frame i for link i; frame 0, the
base frame, for link 0): a box's centre and axes, a sphere's centre, a
cylinder's centre with its axis along z, the frame of a hull's points.
half_extents: (3,) m, > 0: a box spans +-half_extents along its own x, y,
z; for the other kinds the box centred at the frame's origin that holds
the shape (its bound, which the box views draw). radius (m): a sphere's or
a cylinder's; length (m): a cylinder's, along its z; points (k, 3) m: a
hull's points in its frame. name: a label (e.g. "link1", "base",
"fixed_jaw").)doc";
struct LinkBox : Shape {
  int link = 0;                                               // 0..n
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();     // in the DH frame of `link`
  std::string name;                                           // e.g. "link1", "base", "fixed_jaw"
  // (half_extents, from Shape: m, each > 0: the box's, or the bound of another kind)

  // A sphere of `radius` (m, > 0) centred at `pose`'s origin.
  static LinkBox sphere(int link, double radius, const Eigen::Isometry3d& pose, std::string name);
  // A cylinder of `radius` and `length` (m, > 0) centred at `pose`'s origin, its axis `pose`'s z.
  static LinkBox cylinder(int link, double radius, double length, const Eigen::Isometry3d& pose, std::string name);
  // The convex hull of `points` (k >= 4, not on one plane, m) given in the frame `pose` (in the DH frame
  // of `link`): stored about the centre of their bounding box (pose moved there, points less it), so
  // that its bound is tight.
  static LinkBox hull(int link, const std::vector<Eigen::Vector3d>& points, const Eigen::Isometry3d& pose,
                      std::string name);
};

// A parallel-jaw clamp; documentation (Python's too):
inline constexpr char kClampDoc[] = R"doc(A parallel-jaw clamp.

fixed_link: the link (1..n-1) carrying the fixed jaw. fixed_face: (4, 4) the
fixed jaw's inner face in that link's DH frame: origin at the face's centre,
z along the jaw axis towards the moving jaw (the moving joint's axis), x
along the jaw towards its tip, y across the jaw. moving_joint: the prismatic
joint fixed_link + 1 whose variable is the opening between the inner faces
(m); the moving face is the fixed one moved by the opening along z, turned
to face back (Rx(pi)). jaw_length (along x) and pad_width (along y): the
pads' size, m. The tool centre point is the robot's Tool.)doc";
struct Clamp {
  int fixed_link = 0;                                         // 1..n; 0: the robot has no clamp
  Eigen::Isometry3d fixed_face = Eigen::Isometry3d::Identity();
  int moving_joint = 0;                                       // 1..n, prismatic, = fixed_link + 1
  double jaw_length = 0.0;                                    // m, > 0
  double pad_width = 0.0;                                     // m, > 0
  bool present() const { return fixed_link > 0; }
};

// Thickness (m) of the default link boxes of a robot given none (see
// Robot::default_boxes).
constexpr double kDefaultLinkThickness = 0.02;

// Fixed-size scratch memory for evaluating a robot: kinematics of every frame
// and CoM, and recursion buffers. One per thread; reused across calls.
struct Workspace {
  int n = 0;
  // What R, o (level 1) and c, Iw (level 2) hold: Robot::kinematics at kin_q of the robot whose
  // kinematics_id() is kin_robot (0: nothing). Only Robot::kinematics writes them; a second call at the
  // same q (bit for bit) returns at once, one asking for the inertias after the frames adds them.
  std::uint64_t kin_robot = 0;
  int kin_level = 0;
  std::array<double, kMaxDof> kin_q{};
  // The recursive mass matrix (armature in) at those kinematics, once computed (M_valid): each new q or
  // robot clears it.
  bool M_valid = false;
  MatN M;
  std::array<Eigen::Matrix3d, kMaxDof + 1> R;   // world rotation of DH frames 0..n
  std::array<Eigen::Vector3d, kMaxDof + 1> o;   // world origin of DH frames 0..n
  std::array<Eigen::Vector3d, kMaxDof> c;       // world CoM of links 1..n (index i-1)
  std::array<Eigen::Matrix3d, kMaxDof> Iw;      // world inertia about CoM, links 1..n
  // recursion buffers
  std::array<Eigen::Vector3d, kMaxDof> w, wd, a, f, nm;
  std::array<Eigen::Vector3d, kMaxDof> cm_c;    // composite CoM
  std::array<double, kMaxDof> cm_m;             // composite mass
  std::array<Eigen::Matrix3d, kMaxDof> cm_I;    // composite inertia about composite CoM
};

struct RobotTables;

class Robot {
 public:
  // Validates every field; throws std::invalid_argument naming what is wrong.
  Robot(std::vector<Link> links, Eigen::Vector3d gravity = Eigen::Vector3d(0, 0, -9.81),
        Eigen::Vector3d base_position = Eigen::Vector3d::Zero(), double base_yaw = 0.0,
        Tool tool = Tool(), std::string name = "robot", EndStop end_stop = EndStop(),
        Eigen::Matrix3d base_orientation = Eigen::Matrix3d::Identity());

  // A robot from tables (Robot.from_dh): each table's shape and values
  // checked, naming it; CoM vectors converted to CoM rows; the inertia policy
  // applied (tables.inertia_check). With "warn", the warnings to issue are
  // appended to *warnings (if given).
  static Robot from_tables(const RobotTables& tables, std::vector<std::string>* warnings = nullptr);
  // The tables this robot is (from_tables(tables()) is this robot, bar
  // attached generated code): CoM rows (n, 4), inertias (n, 3, 3).
  RobotTables tables() const;

  int dof() const { return n_; }
  const std::string& name() const { return name_; }  // the robot's label, e.g. "scara1"
  // The identity of this robot's kinematics and inertias: new for every robot built (build_), shared by
  // its copies, which have the same; a Workspace remembers whose kinematics it holds by it.
  std::uint64_t kinematics_id() const { return kinematics_id_; }
  // What is computed once per geometry (the boxes, links and clamp) and shared by the robot's copies:
  // made anew whenever the geometry is (build_geometry_), so a robot with other boxes or links never
  // reads another's. Simulation::excluded_pairs keeps its default sampling's result here.
  struct GeometryMemo {
    std::once_flag excluded_once;
    std::vector<std::pair<int, int>> excluded;
  };
  GeometryMemo& geometry_memo() const { return *geometry_memo_; }
  std::vector<std::string> joint_names() const;
  std::vector<std::string> link_names() const;
  std::string joint_types() const;
  const std::vector<Link>& links() const { return links_; }
  // The world's gravitational acceleration (3), m/s^2 (G(q) is gravity()).
  const Eigen::Vector3d& gravity_acceleration() const { return gravity_; }
  const Eigen::Vector3d& base_position() const { return base_p_; }
  double base_yaw() const { return base_yaw_; }
  // Fixed rotation after the yaw (identity unless the first joint axis is tilted).
  const Eigen::Matrix3d& base_orientation() const { return base_R_; }
  const Eigen::Isometry3d& base() const { return base_; }
  const Tool& tool() const { return tool_; }
  const EndStop& end_stop() const { return end_stop_; }
  VecN q_min() const;
  VecN q_max() const;
  VecN tau_max() const;
  VecN friction_coefficients() const;
  // Friction torques K qd + F_c tanh(qd / v_c) (n), N m or N.
  void friction_torques(const double* qd, VecN& tau) const;
  // Links whose inertia tensor breaks the triangle inequality (I1 + I2 >= I3
  // of its principal moments), one message each: allowed, since published
  // data has them; the bindings warn or refuse on request.
  const std::vector<std::string>& inertia_warnings() const { return inertia_warnings_; }
  // CoM position (3) in DH frame i and inertia about the CoM in DH frame i's
  // axes (3 x 3) of link i = 1..n: the convention of URDF and the Robotics
  // Toolbox, equivalent to the CoM row.
  Eigen::Vector3d com_position(int i) const { return pre_.at(i - 1).p_com; }
  Eigen::Matrix3d link_inertia(int i) const { return pre_.at(i - 1).I_local; }

  // A robot is immutable once built; these make changed copies (all else
  // equal): another base placement, gravity, shapes and clamp, dimensions
  // record, generated code (attached, checked against this robot's
  // structure, and selected; std::invalid_argument when the structure
  // differs) or backend ("generated", if attached, or "numeric").
  Robot with_base(const Eigen::Vector3d& position, double yaw) const;
  Robot with_base_orientation(const Eigen::Matrix3d& R) const;
  Robot with_gravity(const Eigen::Vector3d& gravity) const;
  Robot with_geometry(std::vector<LinkBox> boxes, Clamp clamp) const;
  Robot with_dimensions(std::map<std::string, double> dimensions) const;
  // Names of the joints and of the moving links (n each, link i the one joint i moves; unique, not
  // empty); default "joint1".."jointn" and "link1".."linkn".
  Robot with_names(std::vector<std::string> joint_names, std::vector<std::string> link_names) const;
  Robot with_generated(std::shared_ptr<const GeneratedDynamics> gen) const;
  // the generated code named `name` (find_generated); std::invalid_argument when there is none
  Robot with_generated(const std::string& name) const;
  Robot with_backend(const std::string& backend) const;

  // Dynamics backend: the numeric recursive algorithms (always available) or
  // generated closed-form code for this robot's structure.
  bool has_generated() const { return static_cast<bool>(generated_); }
  bool uses_generated() const { return use_generated_ && generated_; }
  std::string backend() const { return uses_generated() ? "generated" : "numeric"; }
  const std::shared_ptr<const GeneratedDynamics>& generated() const { return generated_; }

  // ---- geometry ----
  // Boxes fixed to the links (any number per link, link 0 = the base), and
  // the clamp. Built from the tables unless given (with_geometry).
  const std::vector<LinkBox>& boxes() const { return boxes_; }
  const Clamp& clamp() const { return clamp_; }
  bool has_default_boxes() const { return default_boxes_; }
  // Named dimensions (m) the robot was built from, for reference (the
  // built-in SCARAs record theirs); empty for a robot defined by tables.
  const std::map<std::string, double>& dimensions() const { return dimensions_; }
  // documentation (Python's too):
  static constexpr char kDefaultBoxesDoc[] = R"doc(Thin boxes along the links, for a robot given no shapes.

For link i the segment between the two points its DH row fixes in it: the
foot of the common normal on joint axis i, (-a_i, 0, 0) in frame i, and the
origin of frame i (along x_i, length |a_i|); for a revolute joint with
|d_i| > |a_i|, the segment from frame i-1's origin to that foot along
z_{i-1} instead. Square section 0.02 m, at least that long. A base placed
above the floor stands on a column of that section from the floor (z = 0)
to the base frame's origin.)doc";
  std::vector<LinkBox> default_boxes() const;
  // Angular velocity w[i] (rad/s) and velocity v[i] (m/s) of the origin of
  // DH frames i = 0..n in the world, for the kinematics in ws and qd.
  void frame_velocities(const Workspace& ws, const double* qd, Eigen::Vector3d* w, Eigen::Vector3d* v) const;
  // World poses of every box, in the order of boxes(), for the kinematics
  // in ws (see kinematics()).
  void box_poses(const Workspace& ws, std::vector<Eigen::Isometry3d>& out) const;
  // What poses_of_states gives per state: the tool pose, every box's pose (boxes() order), or the
  // DH frames 0..n.
  enum class PosesOf : int { kTool, kBoxes, kFrames };
  // For N states Q (row-major N x n): the poses `what` names of each, state by state (N, N x
  // boxes().size() or N x (n + 1) poses).
  void poses_of_states(const double* Q, long N, PosesOf what, std::vector<Eigen::Isometry3d>& out) const;
  // World poses of the clamp's fixed and moving inner faces (see Clamp)
  // for the kinematics of q in ws; throws when the robot has no clamp.
  void clamp_faces(const Workspace& ws, const double* q, Eigen::Isometry3d& fixed,
                   Eigen::Isometry3d& moving) const;
  // Parameter vector read by generated code: per link [theta d a alpha,
  // com theta d a alpha, m, Ixx Iyy Izz Ixy Ixz Iyz, K, armature, F_c, v_c]
  // then gravity in frame 0.
  const std::vector<double>& parameter_vector() const { return params_; }

  // ---- kinematics (all poses in the world frame) ----
  // Computes frames and CoMs of q into ws; the functions below taking a
  // Workspace without q read what this left there. inertia = false: the
  // frames only (R, o), not the centres of mass and world inertias.
  void kinematics(const double* q, Workspace& ws, bool inertia = true) const;
  Eigen::Isometry3d frame(const Workspace& ws, int i) const;      // DH frame i = 0..n
  Eigen::Isometry3d com_frame(const Workspace& ws, int i) const;  // link i = 1..n
  Eigen::Isometry3d tool_pose(const Workspace& ws) const;
  // Geometric Jacobian (6 x n, linear rows first) of a point fixed on `link`
  // (1..n; 0 gives zeros) given in that link's DH frame.
  void jacobian(const Workspace& ws, int link, const Eigen::Vector3d& point, Mat6N& J) const;
  void tool_jacobian(const Workspace& ws, Mat6N& J) const;
  // The tool Jacobian's time derivative times qd, Jd qd (6, world): the TCP's linear and its link's
  // angular acceleration when qdd = 0, for the frames in ws (kinematics of q) and velocities qd.
  void tool_bias(const Workspace& ws, const double* qd, Vec6& out) const;

  // ---- dynamics: tau + J^T F = M qdd + C(q, qd) + G(q) + K qd + F_c tanh(qd / v_c) ----
  // M includes the armature on its diagonal. A link may have no mass; M
  // must still be positive definite, which forward_dynamics checks (a
  // std::domain_error naming q when it is not).
  void mass_matrix(const double* q, Workspace& ws, MatN& M) const;
  // Recursive Newton-Euler: M qdd + C + G (+ friction if with_friction), gravity
  // scaled by gravity_scale (0 to leave it out).
  void rnea(const double* q, const double* qd, const double* qdd, Workspace& ws, VecN& tau,
            double gravity_scale, bool with_friction) const;
  // G(q), the joint torques of gravity (N m or N).
  void gravity(const double* q, Workspace& ws, VecN& g) const;
  void coriolis_vector(const double* q, const double* qd, Workspace& ws, VecN& c) const;
  // C in Christoffel form: C_kj = sum_i Gamma_ijk qd_i, Gamma from dM/dq.
  void coriolis_matrix(const double* q, const double* qd, Workspace& ws, MatN& C) const;
  // dM/dq_k for k = 0..n-1, each n x n.
  void mass_matrix_derivatives(const double* q, Workspace& ws, std::vector<MatN>& dM) const;
  // Joint torques of external wrenches: sum J(link, point)^T w (the tool
  // Jacobian for a wrench at_tool).
  void external_torques(const std::vector<ExternalWrench>& wrenches, Workspace& ws, VecN& tau) const;
  // Eq. (1): tau = M qdd + C + G + K qd - tau_ext.
  void inverse_dynamics(const double* q, const double* qd, const double* qdd, const double* tau_ext,
                        Workspace& ws, VecN& tau) const;
  // Eq. (2): qdd = M^-1 (tau + tau_ext - C - G - K qd), by LDLT; tau_ext may be null.
  void forward_dynamics(const double* q, const double* qd, const double* tau, const double* tau_ext,
                        Workspace& ws, VecN& qdd, bool end_stops = false) const;
  // End-stop torques for (q, qd) given the diagonal of M.
  void end_stop_torques(const double* q, const double* qd, const MatN& M, VecN& tau) const;
  // Kinetic and potential energy (J); potential of gravity relative to z = 0.
  double kinetic_energy(const double* q, const double* qd, Workspace& ws) const;
  double potential_energy(const double* q, Workspace& ws) const;

  // ---- derivatives of the dynamics (robot_derivatives.cpp) ----
  // The inverse dynamics' derivatives at (q, qd, qdd): (dtau_dq, dtau_dqd, M), each (n, n), [j, k] =
  // dtau_j / dq_k (N m/rad, N/m, ...), of exactly what inverse_dynamics computes (Eq. (1): tau =
  // M qdd + C + G + friction(qd) - J^T F, armature in M), exact to rounding (no finite differences):
  // with generated code that carries them (the built-in SCARAs, codegen.compile where tractable) the
  // symbolic model's closed forms, else the recursive Newton-Euler algorithm differentiated
  // analytically (Carpentier & Mansard, RSS 2018); both agree to 1e-12. From Python, out= (three
  // float64 C-contiguous (n, n) arrays) receives the results in place. f_ext: as in inverse_dynamics, a
  // (6,) wrench [f; m] (world, N and N m) at the tool centre point, or Wrench(s) on links, fixed in
  // the world while the points they act at move with their links. The Coulomb term
  // F_c tanh(qd / v_c) is smooth: its derivative F_c / v_c (1 - tanh^2(qd / v_c)) is in dtau_dqd's
  // diagonal (with the viscous K); it tends to F_c delta(qd) as v_c -> 0.
  void inverse_dynamics_derivatives(const double* q, const double* qd, const double* qdd,
                                    const std::vector<ExternalWrench>& wrenches, Workspace& ws, MatN& dtau_dq,
                                    MatN& dtau_dqd, MatN& M) const;
  // The forward dynamics' derivatives at (q, qd, tau): (dqdd_dq, dqdd_dqd, dqdd_dtau = M^-1), each
  // (n, n), [j, k] = dqdd_j / dq_k (1/s^2, 1/s, 1/(kg m^2) ...), of exactly what forward_dynamics
  // computes (Eq. (2), friction, armature, f_ext as there, end stops off): dqdd/dx = -M^-1 dtau/dx,
  // the inverse dynamics' derivatives (inverse_dynamics_derivatives) taken at qdd = FD(q, qd, tau).
  // ValueError naming q where M is not positive definite, as forward_dynamics. tau_ext (n, may be null):
  // joint torques added to tau (held: no derivative), as forward_dynamics' tau_ext. Generated code
  // (as inverse_dynamics_derivatives) gives qdd as forward_dynamics does and the derivatives there;
  // out= as there.
  void forward_dynamics_derivatives(const double* q, const double* qd, const double* tau,
                                    const std::vector<ExternalWrench>& wrenches, Workspace& ws, MatN& dqdd_dq,
                                    MatN& dqdd_dqd, MatN& Minv, VecN* qdd = nullptr,
                                    const double* tau_ext = nullptr) const;
  // The same without wrenches, each result written row-major (numpy's (n, n) layout) at its pointer:
  // generated code writes them there directly (the call from Python and the batch).
  void forward_dynamics_derivatives_rows(const double* q, const double* qd, const double* tau, double* dqdd_dq,
                                         double* dqdd_dqd, double* Minv) const;


 private:
  void build_();
  void build_geometry_();
  void attach_generated_(std::shared_ptr<const GeneratedDynamics> gen);
  // tau += the end stops' torques (end_stop_torques without the zeroing)
  void add_end_stop_torques_(const double* q, const double* qd, const MatN& M, VecN& tau) const;
  void refresh_generated_params_();
  void mass_matrix_kin_(Workspace& ws, MatN& M) const;
  void rnea_kin_(const double* qd, const double* qdd, Workspace& ws, VecN& tau, double gravity_scale,
                 bool with_friction) const;
  int link_index_(int link, const char* what) const;
  // the derivatives of rnea with friction and M, for the kinematics in ws, at qdd (0 if null) or, given
  // tau, at qdd = FD(q, qd, tau, tau_ext) (false: M is not positive definite); the qdd used into qdd_out
  bool rnea_derivatives_kin_(const double* qd, const double* qdd, const double* tau, const double* tau_ext,
                             const Workspace& ws, MatN& dtau_dq, MatN& dtau_dqd, MatN& M, VecN& qdd_out) const;
  // d += d(J^T w)/dq of the wrenches, for the kinematics in ws
  void external_torque_derivatives_(const std::vector<ExternalWrench>& wrenches, const Workspace& ws,
                                    MatN& d) const;

  std::vector<Link> links_;
  std::uint64_t kinematics_id_ = 0;
  int n_ = 0;
  Eigen::Vector3d gravity_;
  Eigen::Vector3d base_p_;
  double base_yaw_ = 0.0;
  Eigen::Matrix3d base_R_ = Eigen::Matrix3d::Identity();
  std::vector<std::string> inertia_warnings_;
  Eigen::Isometry3d base_;
  Tool tool_;
  std::string name_;
  EndStop end_stop_;
  std::shared_ptr<const GeneratedDynamics> generated_;
  bool use_generated_ = false;
  std::vector<double> params_;
  // what the generated functions read: params_ followed by generated_->constants(params_)
  std::vector<double> gen_params_;
  std::vector<LinkBox> boxes_;
  bool default_boxes_ = true;  // boxes_ are default_boxes() (re-made with the base)
  std::shared_ptr<GeometryMemo> geometry_memo_ = std::make_shared<GeometryMemo>();
  Clamp clamp_;
  std::map<std::string, double> dimensions_;
  std::vector<std::string> joint_names_, link_names_;  // empty: the defaults
  // precomputed constants per link: fixed part of the DH transform and the
  // transform from DH frame i to the CoM frame of link i
  struct Pre {
    double ct, st, ca, sa;               // cos/sin of theta offset (prismatic) and alpha
    Eigen::Matrix3d R_com;               // CoM frame rotation in frame i
    Eigen::Vector3d p_com;               // CoM position in frame i
    Eigen::Matrix3d I_local;             // inertia about CoM in frame i
  };
  std::vector<Pre> pre_;
};

// A robot as tables: the arguments of Robot.from_dh, documented here
// (Python's docstring too); an optional table left empty takes the default.
struct RobotTables {
  static constexpr char kDoc[] = R"doc(Defines a serial robot from tables.

dh: (n, 4) standard DH rows [theta, d, a, alpha] (rad, m, m, rad); q_i is added
    to theta_i (revolute) or d_i (prismatic), which are offsets.
com: (n, 4) centre-of-mass rows, same parameters, from frame i-1 to the CoM
    frame of link i, q_i added in the same slot (the paper's table); or
    (n, 3) CoM positions (m) in DH frame i, the convention of URDF, the
    Robotics Toolbox and Corke's data, converted exactly to CoM rows
    (Robot.com; a CoM on the joint axis included).
masses: (n,) kg, >= 0 (a link without mass is allowed; M(q) must still be
    positive definite, which forward dynamics checks, naming q if not).
inertias: (n, 3, 3) or (n, 6) [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], kg m^2, about
    the CoM: in the CoM frame for (n, 4) CoM rows, in DH frame i's axes for
    (n, 3) CoM vectors; symmetric, positive semi-definite. One that breaks
    the triangle inequality (I1 + I2 >= I3; published data has them) is
    allowed with a coopsim.InertiaWarning, or refused (ValueError) with
    inertia_check='error' ('ignore': neither).
joint_types: string of 'R' / 'P', one per row, e.g. "RRPRRP".
friction: (n,) viscous K (N m s/rad or N s/m), default 0.
armature: (n,) or one value: rotor inertia reflected through the gear,
    J_m G^2 (kg m^2, or kg for a prismatic joint), added to M_ii; default 0.
coulomb: (n,) or one value: Coulomb friction F_c (N m or N), default 0,
    acting as F_c tanh(qd / v_c) (smooth, never adding energy);
    coulomb_width: v_c (rad/s or m/s, > 0), (n,) or one value, default 0.01.
    Below |qd| ~ v_c it is a damper of F_c / v_c: keep dt F_c / (v_c M_ii)
    under about 2.5 for RK4.
q_limits: (n, 2) [q_min, q_max] (rad or m), default unbounded (+-inf).
tau_limits: (n,) actuator limits |tau_i| <= tau_max (N m or N), default inf.
gravity: (3,) m/s^2 in the world. base_position: (3,) m; base_yaw: rad;
    base_orientation: (3, 3) rotation after the yaw (default identity), for a
    first joint axis that is not vertical: base = T(p) Rz(yaw) R.
tool: (4, 4) tool transform in the last link's DH frame, or a Tool.
end_stop_frequency (rad/s) and end_stop_damping_ratio: the soft end stops
    used by the integrators beyond q_limits, tau = -M_ii (w^2 (q - q_lim)
    + 2 zeta w qd), pushing only; keep w dt below about 2.5.
boxes: list of LinkBox, the shapes fixed to the links (link 0: the base);
    None: thin default boxes along the links (see Robot.default_boxes).
clamp: a Clamp, or None for a robot without one.
dimensions: {name: metres} the robot was built from, kept for reference.)doc";
  Array dh, com, masses, inertias;
  std::string joint_types;
  std::optional<Array> friction, tau_limits, q_limits, armature, coulomb, coulomb_width;
  Array gravity{{0.0, 0.0, -9.81}, {3}};
  Array base_position{{0.0, 0.0, 0.0}, {3}};
  double base_yaw = 0.0;
  std::optional<Array> base_orientation;
  Tool tool;
  std::string name = "robot";
  EndStop end_stop;
  std::optional<std::vector<LinkBox>> boxes;  // none: the default boxes
  Clamp clamp;
  std::map<std::string, double> dimensions;
  std::string inertia_check = "warn";
};

// Separating-axis test of two boxes (world poses of their centres, half
// extents): the smallest overlap over the 15 axes, m; > 0 means they
// overlap by that much, <= 0 that they are that far apart along some axis.
double box_penetration(const Eigen::Isometry3d& a, const Eigen::Vector3d& half_a, const Eigen::Isometry3d& b,
                       const Eigen::Vector3d& half_b);
// The separating-axis gap of two boxes: the largest gap between their
// projections over the 15 axes, m (= -box_penetration). It bounds their
// distance from below; *exact is set when it is the distance itself: the axis
// is a face normal of one box and the other box's nearest vertex along it lies
// over that face (that vertex and the face are then nearest points).
double box_gap(const Eigen::Isometry3d& a, const Eigen::Vector3d& half_a, const Eigen::Isometry3d& b,
               const Eigen::Vector3d& half_b, bool* exact = nullptr);

// Robot.forward_dynamics_derivatives of N states in one call: q, qd, tau (N, n), row-major, ->
// (dqdd_dq, dqdd_dqd, dqdd_dtau), each (N, n, n), row-major, without f_ext (as forward_dynamics_batch);
// on `threads` threads (0: all cores), the GIL released, each taking chunks of 64 states as it becomes
// idle. A state whose dynamics fail (its mass matrix not positive definite, its forces overflowing) is a
// ValueError naming its row, the first such row of the batch. From Python, out=(a, b, c) (three distinct
// float64 C-contiguous (N, n, n) arrays) takes the results instead of new arrays, for loops that reuse
// their buffers; it is returned, and after an error its contents are unspecified.
void forward_dynamics_derivatives_batch(const Robot& robot, const double* Q, const double* QD, const double* TAU,
                                        int N, double* dqdd_dq, double* dqdd_dqd, double* dqdd_dtau, int threads);

// Solves A x = b for symmetric positive definite A by Cholesky, overwriting A
// with its factor; false if A is not positive definite.
bool solve_spd(MatN& A, const VecN& b, VecN& x);

// Solid cuboid inertia about its centre, edges lx, ly, lz along x, y, z (kg m^2).
Eigen::Matrix3d box_inertia(double mass, double lx, double ly, double lz);
// Homogeneous transform of one DH row with the joint variable already added.
Eigen::Isometry3d dh_transform(double theta, double d, double a, double alpha);

// The paper's CoM row (frame i-1 -> CoM frame, q in the joint's slot) and the
// inertia about the CoM in that CoM frame, for a link given the Robotics
// Toolbox's / URDF's way: CoM position r (m) in DH frame i and inertia I
// (kg m^2) about the CoM in DH frame i's axes; `dh` is the link's DH row. The
// CoM frame chosen has its x axis along the CoM's offset from the joint axis
// (theta_c, d_c, a_c in the DH row's slots, a_c >= 0, alpha_c = 0); a CoM on
// the joint axis to rounding (within 16 eps max(|a| + |r|, scale), scale
// the robot's size in m) gets theta_c = theta. Exact for both joint types:
// the CoM frame's pose in frame i is constant and its origin is r.
void com_row_from_vector(JointType type, const DHParams& dh, const Eigen::Vector3d& r, const Eigen::Matrix3d& I,
                         DHParams& com, Eigen::Matrix3d& I_com, double scale = 0.0);

}  // namespace coopsim
