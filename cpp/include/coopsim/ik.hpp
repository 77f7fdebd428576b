// Inverse kinematics of the tool centre point (TCP): closed form for the two
// SCARA structures of the paper (section 6) and damped least squares
// (Levenberg-Marquardt) for any robot.
//
// Targets are TCP poses in the world frame (the pose Robot::tool_pose gives).
// Every solution returned has been checked by forward kinematics against the
// target and lies within the joint limits; otherwise IKError is thrown with
// the reason (out of reach, which joint limit, orientation the structure
// cannot take, singular target). No solver returns NaN.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "coopsim/robot.hpp"

namespace coopsim {

// The target cannot be reached within the limits; what() says why.
// `redundancy` is set when only a closed form's redundancy rule (SCARA #2's
// theta2 = theta3) stands in the way: the free arm may still reach the target.
class IKError : public std::runtime_error {
 public:
  explicit IKError(const std::string& what, bool redundancy = false)
      : std::runtime_error(what), redundancy(redundancy) {}
  bool redundancy;
};

// Which closed-form solver fits a robot.
//  Scara1: joints RRPRRP, arm plane horizontal (alpha1 = 0, alpha2 in {0, pi}),
//    vertical quill (a3 = 0, alpha3 in {0, pi}), yaw axis on the quill
//    (a4 = 0), pitch axis not vertical (sin alpha4 != 0), jaw joint 6; solved
//    decoupled: wrist point (frame 4 origin) -> theta1, theta2, d3; clamp
//    orientation -> theta4, theta5.
//  Scara2: joints RRRPRP, alpha1 = alpha2 = 0, alpha3 in {0, pi}, zero theta
//    offsets on joints 2 and 3, a4 = 0, alpha4 in {0, pi}, jaw joint 6;
//    solved through the homogeneous transforms (the paper's eq. 5) with the
//    redundancy resolved by theta2 = theta3 = beta (joint variables): the
//    target times the inverse tool and link-5 transforms gives the wrist
//    point, whose distance from axis 1 is |a1 + a2 e^{i beta} + a3 e^{2 i beta}|,
//    a quadratic in cos beta (two roots: the unfolded family +-1 and the
//    folded one +-2); theta1 from its direction, d4 from its height, theta5
//    from (A1 A2 A3 A4)^-1 times the target's rotation.
//  Both need the tool on links 5 and 6 (clamp body and moving jaw).
enum class AnalyticKind { None, Scara1, Scara2 };
// The solver kind for this robot; when None, `why` (if given) says which
// structural condition failed.
AnalyticKind analytic_kind(const Robot& robot, std::string* why = nullptr);
// "scara1" or "scara2"; nullptr for AnalyticKind::None.
const char* analytic_kind_name(AnalyticKind kind);

struct IKSolution {
  VecN q;
  // elbow branch: +1 / -1 is the sign of the elbow angle (theta2 for SCARA #1,
  // theta2 = theta3 for SCARA #2); +-2 is SCARA #2's folded family (the other
  // root of its distance equation, only near the base).
  int branch = 0;
  double position_error = 0.0;     // m, by forward kinematics
  double orientation_error = 0.0;  // rad, angle of R_target^T R
};

struct AnalyticIKOptions {
  double opening = 0.0;     // jaw opening d6 (m): the pose does not determine it
  int branch = 0;           // +1, -1 (or +-2 for SCARA #2), 0 = any
  const VecN* q_near = nullptr;  // pick the solution nearest this (n,), and shift
                                 // angles by 2 pi k to be nearest it
  double tol = 1e-9;        // m and rad: largest accepted pose residual
};

// Every closed-form solution within the joint limits, sorted by distance to
// q_near (if given) or by branch (+1 first). Throws IKError when there is
// none, saying why each candidate failed; std::invalid_argument when the
// robot's structure does not fit.
std::vector<IKSolution> analytic_ik_all(const Robot& robot, const Eigen::Isometry3d& target,
                                        const AnalyticIKOptions& options);
// The first of analytic_ik_all for the requested branch.
IKSolution analytic_ik(const Robot& robot, const Eigen::Isometry3d& target, const AnalyticIKOptions& options);

struct NumericIKOptions {
  // weights of the pose error [x, y, z, rx, ry, rz] (world frame; 0 drops a
  // component, e.g. position only = {1, 1, 1, 0, 0, 0}); the orientation
  // rows are scaled by `length` (m) so that they weigh like positions
  std::array<double, 6> weights{1, 1, 1, 1, 1, 1};
  double length = 0.1;
  std::vector<int> locked;  // joint indices (0-based) held at their start value
  double tol = 1e-10;       // converged when |position error| and |orientation error| (m, rad) < tol
  int max_iterations = 100;  // per attempt
  int restarts = 10;         // random restarts after the first attempt
  unsigned long seed = 0;    // for the restarts (deterministic)
};

struct NumericIKResult {
  VecN q;
  double position_error = 0.0;     // m (weighted components only)
  double orientation_error = 0.0;  // rad (weighted components only)
  int iterations = 0;              // total over attempts
  int attempts = 0;
};

// Levenberg-Marquardt on the weighted pose error with the geometric tool
// Jacobian, from q0 and then from random points within the limits, each
// iterate projected into the limits. Returns the first converged solution;
// throws IKError with the best residual (and the joints resting at limits)
// when none converges.
NumericIKResult numeric_ik(const Robot& robot, const Eigen::Isometry3d& target, const VecN& q0,
                           const NumericIKOptions& options);

// ---- ik(): one entry point that picks the solver and fills in the defaults ----

// Which solver ik() uses.
enum class IKMethod {
  Auto,      // the closed form when one fits the robot (analytic_kind), else numeric
  Analytic,  // the closed form; std::invalid_argument when none fits
  Numeric,   // numeric_ik, also on the SCARAs
};
// The method named "auto", "analytic" or "numeric"; std::invalid_argument otherwise.
IKMethod ik_method(const std::string& name);

// Weights of the numeric solver's pose error: a name, "pose" (all six
// components) or "position" ({1, 1, 1, 0, 0, 0}), or the six weights
// [x, y, z, rx, ry, rz] (world frame; each >= 0, not all 0).
using IKWeights = std::variant<std::string, std::array<double, 6>>;

// Options of ik(), its arguments in Python (kIkDoc); an option left empty
// takes its default. Given where they do not apply, opening, branch, weights
// and locked are refused (std::invalid_argument); restarts, max_iterations
// and seed are then unused.
struct IKOptions {
  IKMethod method = IKMethod::Auto;
  std::optional<double> opening;             // m
  std::optional<int> branch;
  std::optional<VecN> q_near;                // (n,)
  std::optional<IKWeights> weights;
  std::optional<std::vector<int>> locked;    // joint indices, 0-based
  std::optional<double> tol;                 // m and rad, > 0
  int restarts = 10;                         // >= 0
  int max_iterations = 100;                  // >= 1
  unsigned long seed = 0;
};

struct IKResult {
  VecN q;  // (n,) rad or m
  // the solver that found q: "scara1" or "scara2" (closed forms), "numeric"
  std::string method;
  int branch = 0;                  // closed forms: q's elbow branch (see IKSolution); 0 from the numeric solver
  double position_error = 0.0;     // m, by forward kinematics
  double orientation_error = 0.0;  // rad
  int iterations = 0;              // numeric: total over attempts
  int attempts = 0;                // numeric
};

// Inverse kinematics of the TCP pose `target` (world frame), as documented
// here (Python's docstring too); IKError (a ValueError in Python) when no
// configuration within the limits reaches the target, std::invalid_argument
// for options that are invalid or do not apply.
inline constexpr char kIkDoc[] = R"doc(Inverse kinematics: joint positions q (n,) whose tool centre point pose is `pose`.

pose: (4, 4) target TCP pose in the world (as fk returns).
method: 'auto' (closed form for the SCARA structures, see ik_kind, else
    numeric), 'analytic' or 'numeric'. SCARA #2's closed form keeps
    theta2 = theta3; where that rule alone stands in the way (reach or a
    joint limit) and no branch is asked for, 'auto' goes on with the
    numeric solver, whose solution has theta2 != theta3.
opening: jaw opening (m) of a robot with a clamp (the SCARAs' d6, or the
    jaw joint coopsim.robots.add_clamp adds), which the pose does not
    determine; default q_near's, else 0 clamped into the jaw's limits. The
    numeric solver holds the jaw joint locked at it.
branch: closed form only: +1 / -1 = sign of the elbow angle (theta2; for
    SCARA #2 theta2 = theta3), +-2 = SCARA #2's folded family near the base;
    None = any (the one nearest q_near when given, else +1 first).
q_near: (n,) configuration to stay near: picks the branch and shifts angles
    by 2 pi k (within the limits) to be nearest it; the numeric start point.
weights: numeric only: (6,) weights of the error [x, y, z, rx, ry, rz]
    (world frame; 0 leaves a component out), or 'pose' / 'position'.
locked: numeric only: joint indices held at their start value.
tol: accepted residual (m and rad): closed form 1e-9, numeric 1e-10.
restarts, max_iterations, seed: numeric Levenberg-Marquardt from q_near
    (or mid-limits; 0, clamped into the limits, where a limit is infinite),
    then from `restarts` random points within the limits.
info: also return a dict: method ('scara1' or 'scara2' for the closed
    forms, 'numeric'), branch (closed forms), position_error (m),
    orientation_error (rad), iterations and attempts (numeric).
Every result is checked by forward kinematics and lies within the joint
limits; otherwise IKError (a ValueError) says why: out of reach, which
joint limit, an orientation the structure cannot take, a singular target;
the numeric solver's message ends naming the robot and the target pose.)doc";
IKResult ik(const Robot& robot, const Eigen::Isometry3d& target, const IKOptions& options);

// What ik_path returns.
struct IKPath {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> q;  // (N, n): row i, pose i's solution
  std::optional<int> branch;  // closed forms: the first pose's branch (given or taken), else none
  int failed = -1;            // the first pose out of reach, -1: none
  std::string error;          // ik()'s message for it
};
// The IK along a path of poses (N, 4, 4), in one call with the GIL released: pose i solved as ik()
// solves it, near the solution of pose i - 1 (pose 0 near q_start), with the jaw at openings[i]
// (openings: (N,) m, or none: ik()'s default). With a closed form in use (the robot has one and the
// method is not 'numeric') and keep_branch, every pose after the first is solved on the first one's
// elbow branch (`branch`, else the one the first solution took; none when SCARA #2's closed form gave
// way to the numeric solver); without keep_branch each later pose takes ik()'s own choice. The numeric
// solver makes `restarts` random restarts on pose 0 and later_restarts after it (0: each pose from the
// one before alone, which keeps the arm on that pose's branch); weights, locked, tol, max_iterations
// and seed as ik() takes them. Returns (q (N, n), the first pose's branch with a closed form (given, or
// the one its solution took) or None, the index of the first pose
// out of reach or None, ik()'s message for it): the path stops there, q holding the rows before it.
// ValueError for openings of another length or options ik() refuses.
IKPath ik_path(const Robot& robot, const std::vector<Eigen::Isometry3d>& poses,
               const std::vector<double>* openings, const IKOptions& options, bool keep_branch,
               int later_restarts);

// Every closed-form solution within the limits (analytic_ik_all), with the
// opening, q_near, tol and branch of the options and their defaults as in
// ik(); the numeric solver's options are not used. std::invalid_argument when
// no closed form fits the robot.
std::vector<IKSolution> ik_solutions(const Robot& robot, const Eigen::Isometry3d& target, const IKOptions& options);

// Pose residual between a TCP pose and a target: position (m) and rotation
// angle (rad).
void pose_error(const Eigen::Isometry3d& T, const Eigen::Isometry3d& target, double& position, double& angle);

}  // namespace coopsim
