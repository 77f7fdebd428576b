// Joint-space references: the abstract Reference (subclassable from Python)
// and the piecewise cubic CubicTrajectory.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <stdexcept>

#include "nogil.hpp"
#include "convert.hpp"
#include "coopsim/reference.hpp"
#include "coopsim/trajectory.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

using RowMat = CubicTrajectory::RowMat;

// Lets a Python class implement Reference: it defines dof, t_start, t_end
// (read as methods or properties) and evaluate(t) -> (q, qd, qdd), each (n,).
class PyReference : public Reference {
 public:
  int dof() const override { return attr_("dof").cast<int>(); }
  double t_start() const override { return attr_("t_start").cast<double>(); }
  double t_end() const override { return attr_("t_end").cast<double>(); }
  void evaluate(double t, double* q, double* qd, double* qdd) const override {
    coopsim::py_nogil::GilAgain gil;
    py::function f = py::get_override(static_cast<const Reference*>(this), "evaluate");
    if (!f) throw std::runtime_error("Reference subclass must define evaluate(t) -> (q, qd, qdd)");
    py::object out = f(t);
    const int n = dof();
    py::sequence s = out;
    if (py::len(s) != 3) throw py::value_error("Reference.evaluate(t) must return (q, qd, qdd)");
    double* dst[3] = {q, qd, qdd};
    const char* names[3] = {"q returned by evaluate", "qd returned by evaluate", "qdd returned by evaluate"};
    for (int i = 0; i < 3; ++i)
      if (dst[i]) {
        const Eigen::VectorXd v = vecx(s[i], n, names[i]);
        for (int j = 0; j < n; ++j) dst[i][j] = v[j];
      }
  }

 private:
  // the subclass's own attribute (method, property or value), never the
  // base binding's property, which would call back here
  py::object attr_(const char* name) const {
    coopsim::py_nogil::GilAgain gil;
    py::object self = py::cast(static_cast<const Reference*>(this));
    py::object base = py::type::of<Reference>();
    bool found = py::hasattr(self, "__dict__") && self.attr("__dict__").contains(name);
    for (auto cls : py::type::of(self).attr("__mro__")) {
      if (found || cls.is(base)) break;
      found = cls.attr("__dict__").contains(name);
    }
    if (!found) throw py::type_error(std::string("Reference subclass must define ") + name);
    py::object a = self.attr(name);
    if (PyCallable_Check(a.ptr())) a = a();
    return a;
  }
};

// A scalar or a 1-D array of finite times.
Arr times_arg(const py::object& t, const char* name) {
  Arr a = as_array(t, name);
  if (a.ndim() > 1) throw py::value_error(std::string("wrong shape for ") + name + ": expected a scalar or (N,), got " + shape_str(a));
  check_finite(a.data(), static_cast<size_t>(a.size()), name);
  return a;
}

// (q, qd, qdd) of a Reference at a scalar time -> (n,) each, or at (N,) times -> (N, n) each.
// A CubicTrajectory asked with Extrapolate::Error refuses times outside its range (the engine checks).
py::tuple evaluate_ref(const Reference& r, const py::object& t, Extrapolate extrapolate = Extrapolate::Hold) {
  Arr ta = times_arg(t, "t");
  const py::ssize_t n = r.dof();
  const bool scalar = ta.ndim() == 0;
  const py::ssize_t m = scalar ? 1 : ta.shape(0);
  py::array_t<double> q = scalar ? py::array_t<double>(n) : py::array_t<double>({m, n});
  py::array_t<double> qd = scalar ? py::array_t<double>(n) : py::array_t<double>({m, n});
  py::array_t<double> qdd = scalar ? py::array_t<double>(n) : py::array_t<double>({m, n});
  double *pq = q.mutable_data(), *pqd = qd.mutable_data(), *pqdd = qdd.mutable_data();
  const double* pt = ta.data();
  if (auto* c = dynamic_cast<const CubicTrajectory*>(&r)) {
    coopsim::py_nogil::NoGil nogil;
    c->evaluate_many(pt, static_cast<long>(m), pq, pqd, pqdd, extrapolate);
  } else {
    for (py::ssize_t i = 0; i < m; ++i) r.evaluate(pt[i], pq + i * n, pqd + i * n, pqdd + i * n);
  }
  return py::make_tuple(q, qd, qdd);
}

// (N, n) even for one joint (to_numpy would flatten a single column)
py::array_t<double> rows(const RowMat& M) {
  py::array_t<double> out({static_cast<py::ssize_t>(M.rows()), static_cast<py::ssize_t>(M.cols())});
  Eigen::Map<RowMat>(out.mutable_data(), M.rows(), M.cols()) = M;
  return out;
}

const char* rule_name(KnotVelocities r) {
  switch (r) {
    case KnotVelocities::Given: return "given";
    case KnotVelocities::Spline: return "spline";
    default: return "heuristic";
  }
}

}  // namespace

void bind_trajectory(py::module_& m) {
  // the controllers' side may bind Reference too; register it once
  if (!py::detail::get_type_info(typeid(Reference))) {
    py::class_<Reference, PyReference, std::shared_ptr<Reference>>(
        m, "Reference",
        "A joint-space reference: desired q, qd, qdd at any time; holds its end point after t_end. "
        "Subclass it in Python by defining dof, t_start, t_end and evaluate(t) -> (q, qd, qdd), each (n,).")
        .def(py::init<>())
        .def_property_readonly("dof", &Reference::dof, "Number of joints n.")
        .def_property_readonly("t_start", &Reference::t_start, "First time (s).")
        .def_property_readonly("t_end", &Reference::t_end, "Last time (s); the end point is held after it.")
        .def("evaluate", [](const Reference& r, const py::object& t) { return evaluate_ref(r, t); }, py::arg("t"),
             "(q, qd, qdd) at time t (s): each (n,) for a scalar t, (N, n) for an array of N times; "
             "rad, rad/s, rad/s^2 (m, m/s, m/s^2 for prismatic joints).");
  }

  py::class_<CubicTrajectory, Reference, std::shared_ptr<CubicTrajectory>>(m, "CubicTrajectory", CubicTrajectory::kDoc)
      .def("evaluate", [](const CubicTrajectory& c, const py::object& t, const std::string& extrapolate) {
             return evaluate_ref(c, t, extrapolate_from_name(extrapolate));
           }, py::arg("t"), py::kw_only(), py::arg("extrapolate") = "hold", CubicTrajectory::kEvaluateDoc)
      .def(py::init([](const py::object& times, const py::object& q_points, const py::object& qd_points, bool spline,
                       const py::object& qd_start, const py::object& qd_end) {
             return std::make_shared<CubicTrajectory>(CubicTrajectory::from_tables(
                 table(times, "times"), table(q_points, "q_points"), optional_table(qd_points, "qd_points"), spline,
                 optional_table(qd_start, "qd_start"), optional_table(qd_end, "qd_end")));
           }),
           py::arg("times"), py::arg("q_points"), py::arg("qd_points") = py::none(),
           py::kw_only(), py::arg("spline") = false, py::arg("qd_start") = py::none(),
           py::arg("qd_end") = py::none())
      .def_property_readonly("times", [](const CubicTrajectory& c) {
         return to_numpy(Eigen::Map<const Eigen::VectorXd>(c.times().data(), c.times().size()));
       }, "(N,) knot times, s.")
      .def_property_readonly("q_points", [](const CubicTrajectory& c) { return rows(c.points()); },
                             "(N, n) via-points.")
      .def_property_readonly("qd_points", [](const CubicTrajectory& c) { return rows(c.velocities()); },
                             "(N, n) knot velocities used (given, heuristic or spline).")
      .def_property_readonly("segments", &CubicTrajectory::segments, "Number of segments N - 1.")
      .def_property_readonly("duration", [](const CubicTrajectory& c) { return c.t_end() - c.t_start(); },
                             "t_end - t_start, s.")
      .def_property_readonly("velocity_rule", [](const CubicTrajectory& c) { return rule_name(c.rule()); },
                             "'given', 'heuristic' or 'spline'.")
      .def_property_readonly("coefficients", [](const CubicTrajectory& c) {
         const py::ssize_t S = c.segments(), n = c.dof();
         py::array_t<double> out({S, n, py::ssize_t(4)});
         double* p = out.mutable_data();
         for (int k = 0; k < S; ++k)
           for (int j = 0; j < n; ++j)
             for (int i = 0; i < 4; ++i) *p++ = c.coefficients(k, j)[i];
         return out;
       }, "(N - 1, n, 4) [c0, c1, c2, c3] of each segment and joint, in local time tau = t - times[k].")
      .def("segment", [](const CubicTrajectory& c, double t) {
         if (!std::isfinite(t)) throw py::value_error("t must be finite");
         return c.segment(t);
       }, py::arg("t"), "Index of the segment containing time t (clamped to 0 .. segments - 1).")
      .def("__repr__", [](const CubicTrajectory& c) {
         return "CubicTrajectory(dof=" + std::to_string(c.dof()) + ", segments=" + std::to_string(c.segments()) +
                ", t=[" + std::to_string(c.t_start()) + ", " + std::to_string(c.t_end()) + "] s, velocities='" +
                rule_name(c.rule()) + "')";
       })
      .def(pickle_by_call<CubicTrajectory>([](const CubicTrajectory& c) {
        // the knot velocities used when given, else the rule and the end velocities
        const py::object V = rows(c.velocities()), none = py::none();
        const bool given = c.rule() == KnotVelocities::Given;
        return py::make_tuple(
            py::make_tuple(to_numpy(Eigen::Map<const Eigen::VectorXd>(c.times().data(), c.times().size())),
                           rows(c.points()), given ? V : none),
            py::dict(py::arg("spline") = c.rule() == KnotVelocities::Spline,
                     py::arg("qd_start") = given ? none : py::object(V[py::int_(0)]),
                     py::arg("qd_end") = given ? none : py::object(V[py::int_(-1)])));
      }));

  py::class_<ConstantReference, Reference, std::shared_ptr<ConstantReference>>(
      m, "SetPoint", "A constant reference: q_ref = q (n,) at all times, qd_ref = qdd_ref = 0.")
      .def(py::init([](const py::object& q) { return std::make_shared<ConstantReference>(table(q, "q")); }),
           py::arg("q"))
      .def_property_readonly("q", [](const ConstantReference& r) { return to_numpy(r.point()); }, "(n,) rad or m.")
      .def("__repr__", [](const ConstantReference& r) { return "SetPoint(dof=" + std::to_string(r.dof()) + ")"; })
      .def(pickle_by_call<ConstantReference>(
          [](const ConstantReference& r) { return py::make_tuple(py::make_tuple(to_numpy(r.point())), py::dict()); }));
}
