// Inverse kinematics: Robot.ik, Robot.ik_solutions, Robot.ik_kind and IKError.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "convert.hpp"
#include "coopsim/ik.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

const char* kind_name(AnalyticKind k) {
  return k == AnalyticKind::Scara1 ? "scara1" : k == AnalyticKind::Scara2 ? "scara2" : nullptr;
}

std::array<double, 6> weights_arg(const py::object& w) {
  std::array<double, 6> out{1, 1, 1, 1, 1, 1};
  if (w.is_none()) return out;
  if (py::isinstance<py::str>(w)) {
    const std::string s = w.cast<std::string>();
    if (s == "pose") return out;
    if (s == "position") return {1, 1, 1, 0, 0, 0};
    throw py::value_error("weights must be 'pose', 'position' or (6,) numbers, got '" + s + "'");
  }
  const Eigen::VectorXd v = vecx(w, 6, "weights");
  for (int k = 0; k < 6; ++k) {
    if (v[k] < 0) throw py::value_error("weights must be >= 0");
    out[k] = v[k];
  }
  if (v.maxCoeff() <= 0) throw py::value_error("weights must not all be 0");
  return out;
}

// The accepted residual (m and rad), or -1 for the solver's default when None.
double tol_arg(const py::object& tol) {
  if (tol.is_none()) return -1.0;
  const double t = scalar_arg(tol, "tol");
  if (!(t > 0)) throw py::value_error("tol must be > 0");
  return t;
}

int branch_arg(const py::object& b, AnalyticKind kind) {
  if (b.is_none()) return 0;
  int v;
  try {
    v = b.cast<int>();
  } catch (py::cast_error&) {
    throw py::value_error("branch must be +1, -1 (or +-2 for SCARA #2) or None");
  }
  const bool ok = v == 1 || v == -1 || (kind == AnalyticKind::Scara2 && (v == 2 || v == -2));
  if (!ok)
    throw py::value_error("branch must be +1 or -1" + std::string(kind == AnalyticKind::Scara2 ? " (or +-2, folded)" : "") +
                          ", got " + std::to_string(v));
  return v;
}

// The jaw opening the analytic solvers (and the numeric one on a SCARA) use.
double opening_arg(const Robot& r, const py::object& opening, const VecN* q_near) {
  if (!opening.is_none()) {
    return scalar_arg(opening, "opening");
  }
  if (q_near) return (*q_near)[5];
  const Link& jaw = r.links()[5];
  return std::clamp(0.0, jaw.q_min, jaw.q_max);
}

VecN default_start(const Robot& r) {
  VecN q = VecN::Zero(r.dof());
  for (int i = 0; i < r.dof(); ++i) {
    const Link& L = r.links()[i];
    if (std::isfinite(L.q_min) && std::isfinite(L.q_max)) q[i] = 0.5 * (L.q_min + L.q_max);
    else q[i] = std::clamp(0.0, L.q_min, L.q_max);
  }
  return q;
}

py::object ik(const Robot& r, const py::object& pose_obj, const py::object& opening, const py::object& branch,
              const py::object& q_near_obj, const std::string& method, const py::object& weights,
              const py::object& locked, const py::object& tol, int restarts, int max_iterations, unsigned long seed,
              bool info) {
  const Eigen::Isometry3d target = pose(pose_obj, "pose");
  const int n = r.dof();
  VecN q_near;
  const bool has_near = !q_near_obj.is_none();
  if (has_near) q_near = vec(q_near_obj, n, "q_near");
  if (method != "auto" && method != "analytic" && method != "numeric")
    throw py::value_error("method must be 'auto', 'analytic' or 'numeric', got '" + method + "'");
  std::string why;
  const AnalyticKind kind = analytic_kind(r, &why);
  if (method == "analytic" && kind == AnalyticKind::None)
    throw py::value_error("no closed-form IK for this robot: " + why + " (use method='numeric')");
  if (kind == AnalyticKind::None && !opening.is_none())
    throw py::value_error("opening applies to the SCARA clamps only (joint 6 of RRPRRP / RRRPRP robots)");
  const double t = tol_arg(tol);

  const bool analytic = method == "analytic" || (method == "auto" && kind != AnalyticKind::None);
  if (analytic) {
    if (!weights.is_none() || !locked.is_none())
      throw py::value_error("weights and locked apply to method='numeric' only");
    AnalyticIKOptions o;
    o.branch = branch_arg(branch, kind);
    o.q_near = has_near ? &q_near : nullptr;
    o.opening = opening_arg(r, opening, o.q_near);
    if (t > 0) o.tol = t;
    IKSolution s;
    try {
      s = analytic_ik(r, target, o);
    } catch (const IKError& e) {
      // SCARA #2's theta2 = theta3 rule in the way: 'auto' asks the numeric
      // solver for the free arm; if that fails too, the closed form's reason stands
      if (!(e.redundancy && method == "auto" && branch.is_none())) throw;
      try {
        return ik(r, pose_obj, py::float_(o.opening), py::none(), q_near_obj, "numeric", py::none(), py::none(), tol,
                  restarts, max_iterations, seed, info);
      } catch (const IKError&) {
        throw IKError(std::string(e.what()) + "; numeric IK with theta2 != theta3 found none either");
      }
    }
    if (!info) return to_numpy(s.q);
    py::dict d;
    d["method"] = kind_name(kind);
    d["branch"] = s.branch;
    d["position_error"] = s.position_error;
    d["orientation_error"] = s.orientation_error;
    return py::make_tuple(to_numpy(s.q), d);
  }
  if (!branch.is_none()) throw py::value_error("branch applies to the closed-form solvers only");
  NumericIKOptions o;
  o.weights = weights_arg(weights);
  if (t > 0) o.tol = t;
  o.restarts = restarts;
  o.max_iterations = max_iterations;
  o.seed = seed;
  if (restarts < 0) throw py::value_error("restarts must be >= 0");
  if (max_iterations < 1) throw py::value_error("max_iterations must be >= 1");
  if (!locked.is_none()) {
    if (py::isinstance<py::str>(locked) || !py::isinstance<py::iterable>(locked))
      throw py::value_error("locked must be a sequence of joint indices");
    for (auto item : locked) {
      const long i = index_arg(item, "locked joint index", -n, n - 1);
      o.locked.push_back(static_cast<int>(i < 0 ? i + n : i));
    }
  }
  VecN q0 = has_near ? q_near : default_start(r);
  if (kind != AnalyticKind::None) {
    // the pose does not fix the jaw opening: hold it
    q0[5] = opening_arg(r, opening, has_near ? &q_near : nullptr);
    const Link& jaw = r.links()[5];
    if (q0[5] < jaw.q_min || q0[5] > jaw.q_max)
      throw IKError("jaw opening d6 = " + std::to_string(q0[5]) + " m is outside its limits [" +
                    std::to_string(jaw.q_min) + ", " + std::to_string(jaw.q_max) + "] m");
    o.locked.push_back(5);
  }
  NumericIKResult res;
  {
    py::gil_scoped_release nogil;
    res = numeric_ik(r, target, q0, o);
  }
  if (!info) return to_numpy(res.q);
  py::dict d;
  d["method"] = "numeric";
  d["position_error"] = res.position_error;
  d["orientation_error"] = res.orientation_error;
  d["iterations"] = res.iterations;
  d["attempts"] = res.attempts;
  return py::make_tuple(to_numpy(res.q), d);
}

}  // namespace

void bind_ik(py::module_& m) {
  py::register_exception<IKError>(m, "IKError", PyExc_ValueError);
  m.attr("IKError").attr("__doc__") =
      "No joint configuration within the limits reaches the IK target; the message says why. A ValueError.";

  auto R = py::reinterpret_borrow<py::class_<Robot>>(m.attr("Robot"));
  R.def("ik", &ik, py::arg("pose"), py::kw_only(), py::arg("opening") = py::none(), py::arg("branch") = py::none(),
        py::arg("q_near") = py::none(), py::arg("method") = "auto", py::arg("weights") = py::none(),
        py::arg("locked") = py::none(), py::arg("tol") = py::none(), py::arg("restarts") = 10,
        py::arg("max_iterations") = 100, py::arg("seed") = 0, py::arg("info") = false,
        R"doc(Inverse kinematics: joint positions q (n,) whose tool centre point pose is `pose`.

pose: (4, 4) target TCP pose in the world (as fk returns).
method: 'auto' (closed form for the SCARA structures, see ik_kind, else
    numeric), 'analytic' or 'numeric'. SCARA #2's closed form keeps
    theta2 = theta3; where that rule alone stands in the way (reach or a
    joint limit) and no branch is asked for, 'auto' goes on with the
    numeric solver, whose solution has theta2 != theta3.
opening: jaw opening d6 (m) for the SCARA clamps, which the pose does not
    determine; default q_near's, else 0. The numeric solver holds it fixed.
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
    (or mid-limits), then from `restarts` random points within the limits.
info: also return a dict: method ('scara1' or 'scara2' for the closed
    forms, 'numeric'), branch (closed forms), position_error (m),
    orientation_error (rad), iterations and attempts (numeric).
Every result is checked by forward kinematics and lies within the joint
limits; otherwise IKError (a ValueError) says why: out of reach, which
joint limit, an orientation the structure cannot take, a singular target.)doc");
  R.def("ik_solutions", [](const Robot& r, const py::object& pose_obj, const py::object& opening,
                           const py::object& q_near_obj, const py::object& tol) {
         std::string why;
         const AnalyticKind kind = analytic_kind(r, &why);
         if (kind == AnalyticKind::None) throw py::value_error("no closed-form IK for this robot: " + why);
         AnalyticIKOptions o;
         VecN q_near;
         if (!q_near_obj.is_none()) {
           q_near = vec(q_near_obj, r.dof(), "q_near");
           o.q_near = &q_near;
         }
         o.opening = opening_arg(r, opening, o.q_near);
         if (!tol.is_none()) o.tol = tol_arg(tol);
         const auto sols = analytic_ik_all(r, pose(pose_obj, "pose"), o);
         py::list out;
         for (const auto& s : sols) out.append(py::make_tuple(to_numpy(s.q), s.branch));
         return out;
       }, py::arg("pose"), py::kw_only(), py::arg("opening") = py::none(), py::arg("q_near") = py::none(),
       py::arg("tol") = py::none(),
       "Every closed-form solution within the limits as a list of (q (n,), branch), nearest q_near first "
       "(else +1 first). Raises IKError when there is none.");
  R.def_property_readonly("ik_kind", [](const Robot& r) -> py::object {
         const char* k = kind_name(analytic_kind(r));
         return k ? py::object(py::str(k)) : py::object(py::none());
       }, "'scara1' or 'scara2' when the closed-form IK fits this robot's structure, else None.");
  R.def("ik_kind_reason", [](const Robot& r) {
         std::string why;
         analytic_kind(r, &why);
         return why;
       }, "Why the closed-form IK does not fit (empty when it does).");
}
