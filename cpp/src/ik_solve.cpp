// Inverse kinematics' entry points: ik() picks the solver (closed form or
// numeric), fills in the defaults of its options and holds the jaw of a robot
// with a clamp at the opening asked for; ik_solutions() lists the closed
// form's solutions.
#include "coopsim/ik.hpp"
#include "internal.hpp"

#include <algorithm>
#include <cmath>

namespace coopsim {

namespace {

using detail::num;

// The index (0-based) of the jaw joint the pose does not determine: joint 6 of the SCARA structures, the
// clamp's moving joint of any other robot with a clamp; -1 for a robot without either.
int jaw_index(const Robot& r, AnalyticKind kind) {
  if (kind != AnalyticKind::None) return 5;
  return r.clamp().present() ? r.clamp().moving_joint - 1 : -1;
}

// The jaw opening the closed forms (and the numeric solver on a robot with a
// jaw, joint j) use: the given one, else q_near's, else 0 clamped into the jaw's limits.
double jaw_opening(const Robot& r, const IKOptions& o, int j) {
  if (o.opening) return *o.opening;
  if (o.q_near) return (*o.q_near)[j];
  const Link& jaw = r.links()[j];
  return std::clamp(0.0, jaw.q_min, jaw.q_max);
}

// The numeric solver's start point without q_near: mid-limits, or 0 clamped
// into the limits where one of them is infinite.
VecN default_start(const Robot& r) {
  VecN q = VecN::Zero(r.dof());
  for (int i = 0; i < r.dof(); ++i) {
    const Link& L = r.links()[i];
    if (std::isfinite(L.q_min) && std::isfinite(L.q_max)) q[i] = 0.5 * (L.q_min + L.q_max);
    else q[i] = std::clamp(0.0, L.q_min, L.q_max);
  }
  return q;
}

void check_tol(const IKOptions& o) {
  if (o.tol && !(*o.tol > 0)) throw std::invalid_argument("tol must be > 0");
}

void check_q_near(const Robot& r, const IKOptions& o) {
  if (o.q_near && (o.q_near->size() != r.dof() || !o.q_near->allFinite()))
    throw std::invalid_argument("q_near must be n = " + std::to_string(r.dof()) + " finite numbers");
}

// The closed form's options: branch checked, opening and tol defaulted.
AnalyticIKOptions analytic_options(const Robot& r, AnalyticKind kind, const IKOptions& o) {
  AnalyticIKOptions a;
  if (o.branch) {
    const int v = *o.branch;
    const bool ok = v == 1 || v == -1 || (kind == AnalyticKind::Scara2 && (v == 2 || v == -2));
    if (!ok)
      throw std::invalid_argument("branch must be +1 or -1" +
                                  std::string(kind == AnalyticKind::Scara2 ? " (or +-2, folded)" : "") + ", got " +
                                  std::to_string(v));
    a.branch = v;
  }
  a.q_near = o.q_near ? &*o.q_near : nullptr;
  a.opening = jaw_opening(r, o, 5);
  if (o.tol) a.tol = *o.tol;
  return a;
}

std::array<double, 6> numeric_weights(const std::optional<IKWeights>& w) {
  std::array<double, 6> out{1, 1, 1, 1, 1, 1};
  if (!w) return out;
  if (const auto* name = std::get_if<std::string>(&*w)) {
    if (*name == "pose") return out;
    if (*name == "position") return {1, 1, 1, 0, 0, 0};
    throw std::invalid_argument("weights must be 'pose', 'position' or (6,) numbers, got '" + *name + "'");
  }
  out = std::get<std::array<double, 6>>(*w);
  double largest = -kInf;
  for (double v : out) {
    if (v < 0) throw std::invalid_argument("weights must be >= 0");
    largest = std::max(largest, v);
  }
  if (largest <= 0) throw std::invalid_argument("weights must not all be 0");
  return out;
}

// The target and the robot, for an IKError's message: " (robot 'ur5', target TCP position [x, y, z] m,
// rotation vector [rx, ry, rz] rad)".
std::string target_str(const Robot& r, const Eigen::Isometry3d& target) {
  const Eigen::AngleAxisd aa(target.linear());
  const Eigen::Vector3d p = target.translation(), w = aa.angle() * aa.axis();
  return " (robot '" + r.name() + "', target TCP position [" + num(p.x()) + ", " + num(p.y()) + ", " +
         num(p.z()) + "] m, rotation vector [" + num(w.x()) + ", " + num(w.y()) + ", " + num(w.z()) + "] rad)";
}

IKResult numeric(const Robot& r, AnalyticKind kind, const Eigen::Isometry3d& target, const IKOptions& o) {
  if (o.branch) throw std::invalid_argument("branch applies to the closed-form solvers only");
  NumericIKOptions no;
  no.weights = numeric_weights(o.weights);
  if (o.tol) no.tol = *o.tol;
  no.restarts = o.restarts;
  no.max_iterations = o.max_iterations;
  no.seed = o.seed;
  if (o.restarts < 0) throw std::invalid_argument("restarts must be >= 0");
  if (o.max_iterations < 1) throw std::invalid_argument("max_iterations must be >= 1");
  if (o.locked) no.locked = *o.locked;
  VecN q0 = o.q_near ? *o.q_near : default_start(r);
  const int j = jaw_index(r, kind);
  if (j >= 0) {
    // the pose does not fix the jaw opening: hold it
    q0[j] = jaw_opening(r, o, j);
    const Link& jaw = r.links()[j];
    if (!std::isfinite(q0[j])) throw std::invalid_argument("opening must be finite");
    if (q0[j] < jaw.q_min || q0[j] > jaw.q_max)
      throw IKError("jaw opening (joint " + std::to_string(j + 1) + ") = " + num(q0[j]) +
                    " m is outside its limits [" + num(jaw.q_min) + ", " + num(jaw.q_max) + "] m" +
                    target_str(r, target));
    no.locked.push_back(j);
  }
  NumericIKResult res;
  try {
    res = numeric_ik(r, target, q0, no);
  } catch (const IKError& e) {
    throw IKError(e.what() + target_str(r, target), e.redundancy);
  }
  IKResult out;
  out.q = res.q;
  out.method = "numeric";
  out.position_error = res.position_error;
  out.orientation_error = res.orientation_error;
  out.iterations = res.iterations;
  out.attempts = res.attempts;
  return out;
}

}  // namespace

const char* analytic_kind_name(AnalyticKind kind) {
  return kind == AnalyticKind::Scara1 ? "scara1" : kind == AnalyticKind::Scara2 ? "scara2" : nullptr;
}

IKMethod ik_method(const std::string& name) {
  if (name == "auto") return IKMethod::Auto;
  if (name == "analytic") return IKMethod::Analytic;
  if (name == "numeric") return IKMethod::Numeric;
  throw std::invalid_argument("method must be 'auto', 'analytic' or 'numeric', got '" + name + "'");
}

IKResult ik(const Robot& robot, const Eigen::Isometry3d& target, const IKOptions& o) {
  check_q_near(robot, o);
  std::string why;
  const AnalyticKind kind = analytic_kind(robot, &why);
  if (o.method == IKMethod::Analytic && kind == AnalyticKind::None)
    throw std::invalid_argument("no closed-form IK for this robot: " + why + " (use method='numeric')");
  if (jaw_index(robot, kind) < 0 && o.opening)
    throw std::invalid_argument("opening applies to robots with a clamp (Robot.clamp; coopsim.robots.add_clamp "
                                "puts one on an arm) or the SCARA structures only");
  check_tol(o);
  const bool analytic = o.method == IKMethod::Analytic || (o.method == IKMethod::Auto && kind != AnalyticKind::None);
  if (!analytic) return numeric(robot, kind, target, o);

  if (o.weights || o.locked) throw std::invalid_argument("weights and locked apply to method='numeric' only");
  const AnalyticIKOptions a = analytic_options(robot, kind, o);
  IKSolution s;
  try {
    s = analytic_ik(robot, target, a);
  } catch (const IKError& e) {
    // SCARA #2's theta2 = theta3 rule in the way: 'auto' asks the numeric
    // solver for the free arm; if that fails too, the closed form's reason stands
    if (!(e.redundancy && o.method == IKMethod::Auto && !o.branch)) throw;
    IKOptions free_arm = o;
    free_arm.method = IKMethod::Numeric;
    free_arm.opening = a.opening;
    try {
      return numeric(robot, kind, target, free_arm);
    } catch (const IKError&) {
      throw IKError(std::string(e.what()) + "; numeric IK with theta2 != theta3 found none either");
    }
  }
  IKResult out;
  out.q = s.q;
  out.method = analytic_kind_name(kind);
  out.branch = s.branch;
  out.position_error = s.position_error;
  out.orientation_error = s.orientation_error;
  return out;
}

std::vector<IKSolution> ik_solutions(const Robot& robot, const Eigen::Isometry3d& target, const IKOptions& o) {
  std::string why;
  const AnalyticKind kind = analytic_kind(robot, &why);
  if (kind == AnalyticKind::None) throw std::invalid_argument("no closed-form IK for this robot: " + why);
  check_q_near(robot, o);
  check_tol(o);
  return analytic_ik_all(robot, target, analytic_options(robot, kind, o));
}

IKPath ik_path(const Robot& robot, const std::vector<Eigen::Isometry3d>& targets,
               const std::vector<double>* openings, const IKOptions& options, bool keep_branch,
               int later_restarts) {  // targets: the header's poses
  const size_t N = targets.size();
  if (openings && openings->size() != N)
    throw std::invalid_argument("openings must have one value per pose (" + std::to_string(N) + "), got " +
                                std::to_string(openings->size()));
  if (later_restarts < 0)
    throw std::invalid_argument("later_restarts must be >= 0, got " + std::to_string(later_restarts));
  const bool closed = options.method != IKMethod::Numeric && analytic_kind(robot) != AnalyticKind::None;
  IKPath out;
  out.q.resize(static_cast<Eigen::Index>(N), robot.dof());
  IKOptions o = options;
  std::optional<int> branch = options.branch;
  for (size_t i = 0; i < N; ++i) {
    if (openings) o.opening = (*openings)[i];
    if (closed) {
      o.branch = (i == 0 || keep_branch) ? branch : std::nullopt;
    } else if (i > 0) {
      o.restarts = later_restarts;
    }
    IKResult r;
    try {
      r = ik(robot, targets[i], o);
    } catch (const IKError& e) {
      out.failed = static_cast<int>(i);
      out.error = e.what();
      out.q.conservativeResize(static_cast<Eigen::Index>(i), robot.dof());
      break;
    }
    if (closed && i == 0 && !branch && r.method != "numeric") branch = r.branch;
    out.q.row(static_cast<Eigen::Index>(i)) = r.q.transpose();
    o.q_near = r.q;
  }
  if (closed) out.branch = branch;
  return out;
}

}  // namespace coopsim
