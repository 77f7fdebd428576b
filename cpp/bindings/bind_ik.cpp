// Inverse kinematics: Robot.ik, Robot.ik_solutions, Robot.ik_kind and IKError.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "nogil.hpp"
#include "convert.hpp"
#include "coopsim/ik.hpp"
#include "generated/docstrings.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

// ---- the Python arguments as IKOptions: each converted and checked for its
// type and shape here, once; what the values mean is coopsim::ik's business

std::optional<double> opening_arg(const py::object& opening) {
  if (opening.is_none()) return std::nullopt;
  return scalar_arg(opening, "opening");
}

std::optional<int> branch_arg(const py::object& branch) {
  if (branch.is_none()) return std::nullopt;
  try {
    return branch.cast<int>();
  } catch (py::cast_error&) {
    throw py::value_error("branch must be +1, -1 (or +-2 for SCARA #2) or None");
  }
}

std::optional<VecN> q_near_arg(const Robot& r, const py::object& q_near) {
  if (q_near.is_none()) return std::nullopt;
  return vec(q_near, r.dof(), "q_near");
}

// a name ('pose', 'position') or (6,) numbers
std::optional<IKWeights> weights_arg(const py::object& w) {
  if (w.is_none()) return std::nullopt;
  if (py::isinstance<py::str>(w)) return IKWeights(w.cast<std::string>());
  const Eigen::VectorXd v = vecx(w, 6, "weights");
  std::array<double, 6> out;
  for (int k = 0; k < 6; ++k) out[k] = v[k];
  return IKWeights(out);
}

// joint indices, negative ones counted from the end as in Python
std::optional<std::vector<int>> locked_arg(const Robot& r, const py::object& locked) {
  if (locked.is_none()) return std::nullopt;
  if (py::isinstance<py::str>(locked) || !py::isinstance<py::iterable>(locked))
    throw py::value_error("locked must be a sequence of joint indices");
  const int n = r.dof();
  std::vector<int> out;
  for (auto item : locked) {
    const long i = index_arg(item, "locked joint index", -n, n - 1);
    out.push_back(static_cast<int>(i < 0 ? i + n : i));
  }
  return out;
}

std::optional<double> tol_arg(const py::object& tol) {
  if (tol.is_none()) return std::nullopt;
  return scalar_arg(tol, "tol");
}

// The options Robot.ik and Robot.ik_path share, from their keywords.
IKOptions ik_options(const Robot& r, const py::object& q_near, const std::string& method, const py::object& branch,
                     const py::object& weights, const py::object& locked, const py::object& tol, int restarts,
                     int max_iterations, unsigned long seed) {
  IKOptions o;
  o.q_near = q_near_arg(r, q_near);
  o.method = ik_method(method);
  o.tol = tol_arg(tol);
  o.branch = branch_arg(branch);
  o.weights = weights_arg(weights);
  o.locked = locked_arg(r, locked);
  o.restarts = restarts;
  o.max_iterations = max_iterations;
  o.seed = seed;
  return o;
}

py::object py_ik(const Robot& r, const py::object& pose_obj, const py::object& opening, const py::object& branch,
                 const py::object& q_near, const std::string& method, const py::object& weights,
                 const py::object& locked, const py::object& tol, int restarts, int max_iterations,
                 unsigned long seed, bool info) {
  const Eigen::Isometry3d target = pose(pose_obj, "pose");
  IKOptions o = ik_options(r, q_near, method, branch, weights, locked, tol, restarts, max_iterations, seed);
  o.opening = opening_arg(opening);
  IKResult res;
  {
    coopsim::py_nogil::NoGil nogil;
    res = coopsim::ik(r, target, o);
  }
  if (!info) return to_numpy(res.q);
  py::dict d;
  d["method"] = res.method;
  if (res.method != "numeric") d["branch"] = res.branch;
  d["position_error"] = res.position_error;
  d["orientation_error"] = res.orientation_error;
  if (res.method == "numeric") {
    d["iterations"] = res.iterations;
    d["attempts"] = res.attempts;
  }
  return py::make_tuple(to_numpy(res.q), d);
}

py::tuple py_ik_path(const Robot& r, const py::object& poses_obj, const py::object& openings, const py::object& q_start,
                     const py::object& branch, const std::string& method, bool keep_branch, const py::object& weights,
                     const py::object& locked, const py::object& tol, int restarts, int later_restarts,
                     int max_iterations, unsigned long seed) {
  const std::vector<Eigen::Isometry3d> targets = rigid_poses(table(poses_obj, "poses"), "poses");
  std::optional<std::vector<double>> op;
  if (!openings.is_none()) op = table(openings, "openings").values;
  const IKOptions o = ik_options(r, q_start, method, branch, weights, locked, tol, restarts, max_iterations, seed);
  IKPath p;
  {
    coopsim::py_nogil::NoGil nogil;
    p = ik_path(r, targets, op ? &*op : nullptr, o, keep_branch, later_restarts);
  }
  const py::object br = p.branch ? py::object(py::int_(*p.branch)) : py::object(py::none());
  return py::make_tuple(py::array_t<double>({p.q.rows(), p.q.cols()}, p.q.data()), br,
                        p.failed < 0 ? py::object(py::none()) : py::object(py::int_(p.failed)), p.error);
}

py::list py_ik_solutions(const Robot& r, const py::object& pose_obj, const py::object& opening,
                         const py::object& q_near, const py::object& tol) {
  const Eigen::Isometry3d target = pose(pose_obj, "pose");
  IKOptions o;
  o.q_near = q_near_arg(r, q_near);
  o.opening = opening_arg(opening);
  o.tol = tol_arg(tol);
  py::list out;
  for (const auto& s : coopsim::ik_solutions(r, target, o)) out.append(py::make_tuple(to_numpy(s.q), s.branch));
  return out;
}

}  // namespace

void bind_ik(py::module_& m) {
  py::register_exception<IKError>(m, "IKError", PyExc_ValueError);
  m.attr("IKError").attr("__doc__") =
      "No joint configuration within the limits reaches the IK target; the message says why. A ValueError.";

  auto R = py::reinterpret_borrow<py::class_<Robot>>(m.attr("Robot"));
  R.def("ik", &py_ik, py::arg("pose"), py::kw_only(), py::arg("opening") = py::none(), py::arg("branch") = py::none(),
        py::arg("q_near") = py::none(), py::arg("method") = "auto", py::arg("weights") = py::none(),
        py::arg("locked") = py::none(), py::arg("tol") = py::none(), py::arg("restarts") = 10,
        py::arg("max_iterations") = 100, py::arg("seed") = 0, py::arg("info") = false,
        kIkDoc);
  R.def("ik_path", &py_ik_path, py::arg("poses"), py::kw_only(), py::arg("openings") = py::none(),
        py::arg("q_start") = py::none(), py::arg("branch") = py::none(), py::arg("method") = "auto",
        py::arg("keep_branch") = true, py::arg("weights") = py::none(), py::arg("locked") = py::none(),
        py::arg("tol") = py::none(), py::arg("restarts") = 10, py::arg("later_restarts") = 10,
        py::arg("max_iterations") = 100, py::arg("seed") = 0, coopsim::docs::doc_ik_path);
  R.def("ik_solutions", &py_ik_solutions, py::arg("pose"), py::kw_only(), py::arg("opening") = py::none(),
        py::arg("q_near") = py::none(), py::arg("tol") = py::none(),
        "Every closed-form solution within the limits as a list of (q (n,), branch), nearest q_near first "
        "(else +1 first). Raises IKError when there is none.");
  R.def_property_readonly("ik_kind", [](const Robot& r) -> py::object {
         const char* k = analytic_kind_name(analytic_kind(r));
         return k ? py::object(py::str(k)) : py::object(py::none());
       }, "'scara1' or 'scara2' when the closed-form IK fits this robot's structure, else None.");
  R.def("ik_kind_reason", [](const Robot& r) {
         std::string why;
         analytic_kind(r, &why);
         return why;
       }, "Why the closed-form IK does not fit (empty when it does).");
}
