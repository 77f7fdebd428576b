// Cooperative controllers: CoopMember, the abstract CooperativeController (subclassable from
// Python), ObjectControl and LeaderFollower.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <vector>

#include "nogil.hpp"
#include "convert.hpp"
#include "py_clone.hpp"
#include "coopsim/cooperative_laws.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

// What Python sees of a member: values copied (a CoopMember points into the simulation)
struct Member {
  int robot = -1;
  double t = 0.0;
  VecN q, qd, q_ref, qd_ref, qdd_ref;
  Vec6 wrench = Vec6::Zero();
  bool holding = false;
  Eigen::Isometry3d grip = Eigen::Isometry3d::Identity();
  explicit Member(const CoopMember& c)
      : robot(c.robot), t(c.in.t), q(Eigen::Map<const VecN>(c.in.q, c.in.n)),
        qd(Eigen::Map<const VecN>(c.in.qd, c.in.n)), q_ref(Eigen::Map<const VecN>(c.in.q_ref, c.in.n)),
        qd_ref(Eigen::Map<const VecN>(c.in.qd_ref, c.in.n)), qdd_ref(Eigen::Map<const VecN>(c.in.qdd_ref, c.in.n)),
        holding(c.held >= 0), grip(c.grip) {
    if (c.in.wrench) wrench = Eigen::Map<const Vec6>(c.in.wrench);
  }
};

// A Python law: compute(t, members) -> [tau_0, tau_1, ...]; optionally reset(robots, period).
class PyCooperative : public CooperativeController {
 public:
  std::shared_ptr<CooperativeController> clone() const override { return python_clone<CooperativeController>(this); }
  void reset(const std::vector<const Robot*>& robots, double period) override {
    coopsim::py_nogil::GilAgain gil;
    py::function f = py::get_override(static_cast<const CooperativeController*>(this), "reset");
    if (!f) return;
    py::list rs;
    for (const Robot* r : robots) rs.append(py::cast(*r));
    f(rs, period);
  }
  void compute(double t, const std::vector<CoopMember>& members, const std::vector<double*>& tau) override {
    coopsim::py_nogil::GilAgain gil;
    py::function f = py::get_override(static_cast<const CooperativeController*>(this), "compute");
    if (!f) throw py::type_error("CooperativeController subclass must define compute(t, members) -> list of tau");
    py::list ms;
    for (const CoopMember& c : members) ms.append(py::cast(Member(c)));
    py::object out = f(t, ms);
    py::sequence seq = out.cast<py::sequence>();
    if (py::len(seq) != members.size())
      throw py::value_error("compute must return one tau per member (" + std::to_string(members.size()) + "), got " +
                            std::to_string(py::len(seq)));
    for (size_t k = 0; k < members.size(); ++k) {
      Arr a = array(seq[k], {members[k].in.n}, "tau returned by compute", false);
      std::copy(a.data(), a.data() + members[k].in.n, tau[k]);
    }
  }
};

Vec6 six(const py::object& v, const char* name) {
  Arr a = as_array(v, name);
  if (a.ndim() == 0 || (a.ndim() == 1 && a.shape(0) == 1)) return Vec6::Constant(a.data()[0]);
  return vector_arg<Vec6>(v, 6, name);
}

}  // namespace

void bind_cooperative(py::module_& m) {
  py::class_<Member>(m, "CoopMember", "One robot of a cooperative group at an update (a copy).")
      .def_readonly("robot", &Member::robot, "Its index in the simulation.")
      .def_readonly("t", &Member::t, "s.")
      .def_property_readonly("q", [](const Member& c) { return to_numpy(c.q); }, "(n,).")
      .def_property_readonly("qd", [](const Member& c) { return to_numpy(c.qd); }, "(n,).")
      .def_property_readonly("q_ref", [](const Member& c) { return to_numpy(c.q_ref); }, "(n,).")
      .def_property_readonly("qd_ref", [](const Member& c) { return to_numpy(c.qd_ref); }, "(n,).")
      .def_property_readonly("qdd_ref", [](const Member& c) { return to_numpy(c.qdd_ref); }, "(n,).")
      .def_property_readonly("wrench", [](const Member& c) { return to_numpy(c.wrench); },
                             "(6,) the sensor, world axes, about the TCP: what the clamp applies.")
      .def_readonly("holding", &Member::holding)
      .def_property_readonly("grip", [](const Member& c) { return to_numpy(c.grip); },
                             "(4, 4) the held body's pose in the TCP frame (identity when holding nothing).");

  py::class_<CooperativeController, PyCooperative, std::shared_ptr<CooperativeController>>(
      m, "CooperativeController", R"doc(
Abstract controller of several robots at once (Simulation.add_cooperative).

Subclass it in Python: call super().__init__(), define compute(t, members) -> list of tau, one (n,)
array per member (a CoopMember: q, qd, the joint reference, the sensor's wrench, what it holds and
the grip), and optionally reset(robots, period). The simulation saturates each tau at its robot's
limits. The built-in laws: ObjectControl, LeaderFollower.)doc")
      .def(py::init<>());

  py::class_<ObjectControl, CooperativeController, std::shared_ptr<ObjectControl>>(m, "ObjectControl",
                                                                                     ObjectControl::kDoc)
      .def(py::init([](double mass, const py::object& inertia, const py::object& kp, const py::object& kd,
                       double load_share, double squeeze, double kp_force, double ki_force, double ilim,
                       const py::object& impedance, double accel_filter) {
             ObjectControl::Gains g;
             g.kp = six(kp, "kp");
             g.kd = six(kd, "kd");
             g.kp_force = kp_force;
             g.ki_force = ki_force;
             g.integral_limit = ilim;
             Arr I = array(inertia, {3, 3}, "inertia");
             const Eigen::Matrix3d In = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(I.data());
             if (impedance.is_none()) return std::make_shared<ObjectControl>(mass, In, g, load_share, squeeze);
             const py::tuple t = py::tuple(impedance);
             if (t.size() != 3) throw py::value_error("impedance must be (stiffness, damping, mass)");
             return std::make_shared<ObjectControl>(mass, In, g, load_share, squeeze, true, six(t[0], "stiffness"),
                                                    six(t[1], "damping"), six(t[2], "impedance mass"), accel_filter);
           }),
           py::arg("mass"), py::arg("inertia"), py::kw_only(), py::arg("kp") = ObjectControl::Gains().kp[0],
           py::arg("kd") = ObjectControl::Gains().kd[0], py::arg("load_share") = 0.5, py::arg("squeeze") = 0.0,
           py::arg("kp_force") = ObjectControl::Gains().kp_force, py::arg("ki_force") = ObjectControl::Gains().ki_force,
           py::arg("integral_limit") = ObjectControl::Gains().integral_limit, py::arg("impedance") = py::none(),
           py::arg("accel_filter") = 0.002)
      .def_property_readonly("compliant_offset", [](const ObjectControl& c) { return to_numpy(c.compliant_offset()); },
                             "(6,) m, rad: the impedance's offset from the reference at the last update (world).")
      .def_property_readonly("push_estimate", [](const ObjectControl& c) { return to_numpy(c.push_estimate()); },
                             "(6,) N, N m: the push on the object estimated at the last update (impedance).")
      .def_property("load_share", &ObjectControl::load_share, &ObjectControl::set_load_share,
                    "Clamp 0's part of the vertical load, [0, 1]; settable during a run (the next update).")
      .def_property("squeeze", &ObjectControl::squeeze, &ObjectControl::set_squeeze,
                    "N, compression positive; settable during a run (the next update).")
      .def_property("offset", [](const ObjectControl& c) { return to_numpy(c.offset()); },
                    [](ObjectControl& c, const py::object& v) { c.set_offset(vector_arg<Eigen::Vector3d>(v, 3, "offset")); },
                    "(3,) m, world: the object's reference moved by it; settable during a run (reached over offset_ramp).")
      .def_property("offset_ramp", &ObjectControl::offset_ramp, &ObjectControl::set_offset_ramp,
                    "s, >= 0: a new offset is reached over it from the last update's (0: at once).")
      .def_property_readonly("object_error", [](const ObjectControl& c) { return to_numpy(c.object_error()); },
                             "(6,) m, rad: the object's pose error at the last update (world).")
      .def_property_readonly("object_wrench", [](const ObjectControl& c) { return to_numpy(c.object_wrench()); },
                             "(6,) N, N m: the wrench commanded on the object, about its centre.")
      .def_property_readonly("clamp_wrenches", [](const ObjectControl& c) {
         py::list out;
         for (const Vec6& w : c.clamp_wrenches()) out.append(to_numpy(w));
         return out;
       }, "Each clamp's commanded wrench on the object (6,), world, about its TCP.");


  py::class_<LeaderFollower, CooperativeController, std::shared_ptr<LeaderFollower>>(m, "LeaderFollower",
                                                                                       LeaderFollower::kDoc)
      .def(py::init([](const py::object& k, const py::object& d, const py::object& mass, double object_mass,
                       double kp, double kd, double share) {
             return std::make_shared<LeaderFollower>(kp, kd, coopsim::gains(table(k, "stiffness"), "stiffness"),
                                                     coopsim::gains(table(d, "damping"), "damping"),
                                                     coopsim::gains(table(mass, "mass"), "mass"), object_mass, share);
           }),
           py::arg("stiffness"), py::arg("damping"), py::arg("mass"), py::kw_only(), py::arg("object_mass"),
           py::arg("kp") = 900.0, py::arg("kd") = 60.0, py::arg("follower_share") = 0.5)
      .def_property_readonly("kp", &LeaderFollower::kp, "The leader's gain, 1/s^2.")
      .def_property_readonly("kd", &LeaderFollower::kd, "The leader's gain, 1/s.")
      .def_property_readonly("stiffness", [](const LeaderFollower& c) { return to_numpy(c.stiffness()); })
      .def_property_readonly("damping", [](const LeaderFollower& c) { return to_numpy(c.damping()); })
      .def_property_readonly("mass", [](const LeaderFollower& c) { return to_numpy(c.mass()); })
      .def_property_readonly("object_mass", &LeaderFollower::object_mass, "kg, the model's.")
      .def_property_readonly("follower_share", &LeaderFollower::follower_share)
      .def_property_readonly("relative_error", [](const LeaderFollower& c) { return to_numpy(c.relative_error()); },
                             "(6,) the follower's pose error from where the grips put it (task axes: m, rad).");
}
