// The Bullet world: scenery and free bodies (robots' link bodies come from a
// simulation).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "convert.hpp"
#include "coopsim/box_distance.hpp"
#include "coopsim/world.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

// A pose as (4, 4), or as a position (3,) m with a unit quaternion (4,) [w, x, y, z].
Eigen::Isometry3d pose_arg(const py::object& pose_obj, const py::object& position, const py::object& quaternion) {
  if (!pose_obj.is_none()) {
    if (!position.is_none() || !quaternion.is_none())
      throw py::value_error("give either pose (4, 4) or position and quaternion, not both");
    return pose(pose_obj, "pose");
  }
  if (position.is_none()) throw py::value_error("a body needs a pose (4, 4) or a position (3,)");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = vecx(position, 3, "position");
  if (!quaternion.is_none()) {
    const Eigen::VectorXd q = vecx(quaternion, 4, "quaternion");
    if (std::abs(q.norm() - 1.0) > 1e-9)
      throw py::value_error("quaternion must have unit norm [w, x, y, z], got norm " + std::to_string(q.norm()));
    T.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix();
  }
  return T;
}

py::dict spec_dict(const BodySpec& b) {
  py::dict d;
  d["name"] = b.name;
  d["kind"] = body_kind_name(b.kind);
  d["half_extents"] = to_numpy(b.half_extents);
  d["mass"] = b.mass;
  d["pose"] = to_numpy(b.pose);
  d["velocity"] = to_numpy(b.velocity);
  d["angular_velocity"] = to_numpy(b.angular_velocity);
  d["friction"] = b.friction;
  d["restitution"] = b.restitution;
  return d;
}

}  // namespace

py::dict body_state_dict(const BodyState& s) {
  py::dict d;
  const Eigen::Quaterniond q(s.pose.linear());
  d["pose"] = to_numpy(s.pose);
  d["position"] = to_numpy(Eigen::Vector3d(s.pose.translation()));
  d["quaternion"] = to_numpy(Eigen::Vector4d(q.w(), q.x(), q.y(), q.z()));
  d["velocity"] = to_numpy(s.velocity);
  d["angular_velocity"] = to_numpy(s.angular_velocity);
  d["asleep"] = s.asleep;
  return d;
}

std::string index_name(const char* name, std::initializer_list<py::ssize_t> idx) {
  std::string s = name;
  for (py::ssize_t i : idx) s += "[" + std::to_string(i) + "]";
  return s;
}

std::vector<Eigen::Isometry3d> pose_list(const py::handle& obj, const char* name) {
  Arr a = array(obj, {-1, 4, 4}, name);
  std::vector<Eigen::Isometry3d> out;
  out.reserve(static_cast<size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) out.push_back(pose_from(a.data() + 16 * i, index_name(name, {i})));
  return out;
}

std::vector<Eigen::Vector3d> half_list(const py::handle& obj, size_t n, const char* name) {
  Arr a = array(obj, {static_cast<py::ssize_t>(n), 3}, name);
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < n; ++i) out.emplace_back(a.data()[3 * i], a.data()[3 * i + 1], a.data()[3 * i + 2]);
  return out;
}

void bind_world(py::module_& m) {
  m.def("box_distance", [](const py::object& pa, const py::object& ha, const py::object& pb, const py::object& hb) {
          const Eigen::Isometry3d a = pose(pa, "pose_a"), b = pose(pb, "pose_b");
          Arr x = array(ha, {3}, "half_a"), y = array(hb, {3}, "half_b");
          return box_distance(a, Eigen::Vector3d(x.data()[0], x.data()[1], x.data()[2]), b,
                              Eigen::Vector3d(y.data()[0], y.data()[1], y.data()[2]));
        }, py::arg("pose_a"), py::arg("half_a"), py::arg("pose_b"), py::arg("half_b"),
        "Distance between two boxes, m: the gap between their nearest points (> 0), or minus the depth of "
        "their overlap (<= 0).\n\npose_a, pose_b: (4, 4) world poses of the box centres; half_a, half_b: (3,) "
        "half extents (m, > 0). Bullet's GJK and EPA on exact boxes (no collision margin).");
  m.def("box_clearances", [](const py::object& pa, const py::object& ha, const py::object& pb,
                             const py::object& hb) {
          Arr A = array(pa, {-1, -1, 4, 4}, "poses_a");
          const py::ssize_t rows = A.shape(0), na = A.shape(1);
          const auto x = half_list(ha, static_cast<size_t>(na), "half_a");
          Arr B = as_array(pb, "poses_b");
          const bool fixed = B.ndim() == 3;
          if (fixed) B = array(pb, {-1, 4, 4}, "poses_b");
          else B = array(pb, {rows, -1, 4, 4}, "poses_b");
          const py::ssize_t nb = fixed ? B.shape(0) : B.shape(1);
          const auto y = half_list(hb, static_cast<size_t>(nb), "half_b");
          if (na == 0 || nb == 0) throw py::value_error("poses_a and poses_b need at least one box each");
          std::vector<Eigen::Isometry3d> a, b;
          a.reserve(static_cast<size_t>(rows * na));
          for (py::ssize_t r = 0; r < rows; ++r)
            for (py::ssize_t i = 0; i < na; ++i) a.push_back(pose_from(A.data() + 16 * (r * na + i), index_name("poses_a", {r, i})));
          const py::ssize_t mb = fixed ? nb : rows * nb;
          for (py::ssize_t k = 0; k < mb; ++k)
            b.push_back(pose_from(B.data() + 16 * k, fixed ? index_name("poses_b", {k}) : index_name("poses_b", {k / nb, k % nb})));
          py::array_t<double> d(rows);
          py::array_t<long> ia(rows), ib(rows);
          {
            py::gil_scoped_release nogil;
            box_clearances(static_cast<int>(rows), a, x, b, y, fixed, d.mutable_data(), ia.mutable_data(),
                           ib.mutable_data());
          }
          return py::make_tuple(d, ia, ib);
        }, py::arg("poses_a"), py::arg("half_a"), py::arg("poses_b"), py::arg("half_b"),
        "The clearance between two sets of boxes in each of N configurations: the smallest box_distance "
        "(m; <= 0: minus the overlap depth) over every pair of a box of one set and a box of the other, and "
        "the pair that has it.\n\nposes_a: (N, ka, 4, 4) world poses of the box centres per row; half_a: (ka, "
        "3) half extents (m, > 0); poses_b: (N, kb, 4, 4), or (kb, 4, 4) for boxes that do not move; half_b: "
        "(kb, 3). Returns (d (N,), ia (N,), ib (N,)): the distance and the indices of the nearest pair. The "
        "same minimum as box_distances on every pair, with far fewer GJK calls (each row starts from the "
        "previous row's nearest pair; an earlier row's bound less the boxes' motion since, bounding spheres "
        "and separating axes rule the others out): rows in time order are fastest. GIL released.");
  m.def("box_distances", [](const py::object& pa, const py::object& ha, const py::object& pb, const py::object& hb,
                            bool pairwise) {
          const auto a = pose_list(pa, "poses_a"), b = pose_list(pb, "poses_b");
          const auto x = half_list(ha, a.size(), "half_a"), y = half_list(hb, b.size(), "half_b");
          if (pairwise && a.size() != b.size())
            throw py::value_error("pairwise: poses_a and poses_b must have the same length, got " +
                                  std::to_string(a.size()) + " and " + std::to_string(b.size()));
          std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(a.size())};
          if (!pairwise) shape.push_back(static_cast<py::ssize_t>(b.size()));
          py::array_t<double> out(shape);
          double* o = out.mutable_data();
          {
            py::gil_scoped_release nogil;
            if (pairwise) {
              for (size_t i = 0; i < a.size(); ++i) o[i] = box_distance(a[i], x[i], b[i], y[i]);
            } else {
              box_distances(a, x, b, y, o);
            }
          }
          return out;
        }, py::arg("poses_a"), py::arg("half_a"), py::arg("poses_b"), py::arg("half_b"), py::arg("pairwise") = false,
        "Distances between boxes, m (as box_distance): (Na, Nb) for every box of one list with every box of "
        "the other, or with pairwise=True (N,) for box i of one with box i of the other.\n\n"
        "poses_a: (Na, 4, 4), half_a: (Na, 3); poses_b: (Nb, 4, 4), half_b: (Nb, 3). Robot.shapes(q) gives a "
        "robot's boxes in this form.");

  py::class_<World, std::shared_ptr<World>>(m, "World", R"doc(A Bullet dynamics world: an optional floor (the plane z = 0), static boxes
(scenery) and free boxes with mass. Give it to a Simulation (world=...),
which brings every robot's link boxes into it as kinematic bodies; one world
belongs to one simulation. Friction and restitution of a contact are the
products of the two bodies' coefficients (the floor's, static boxes' and
links' default 1, so a free body's own coefficient decides).

floor: add the floor. gravity: (3,) m/s^2, the robots' too. floor_friction,
floor_restitution: the floor's coefficients. solver_iterations: Bullet's
contact solver iterations per step. sleep_after: s; a free body below
0.1 mm/s and 1 mrad/s for this long, or none of whose corners moved more than
0.25 mm in that time, sleeps, with the bodies it touches, until
something moving touches it: it costs nothing meanwhile (Bullet's own delay
is 2 s).)doc")
      .def(py::init([](bool floor, const py::object& gravity, double floor_friction, double floor_restitution,
                       int solver_iterations, double sleep_after) {
             WorldOptions o;
             o.floor = floor;
             o.gravity = vecx(gravity, 3, "gravity");
             o.floor_friction = floor_friction;
             o.floor_restitution = floor_restitution;
             o.solver_iterations = solver_iterations;
             o.sleep_after = sleep_after;
             return std::make_shared<World>(o);
           }),
           py::arg("floor") = true, py::arg("gravity") = py::make_tuple(0.0, 0.0, -9.81),
           py::arg("floor_friction") = 1.0, py::arg("floor_restitution") = 0.0, py::arg("solver_iterations") = 10,
           py::arg("sleep_after") = 0.5)
      .def("add_static_box", [](World& w, const std::string& name, const py::object& half_extents,
                                const py::object& pose_obj, const py::object& position, const py::object& quaternion,
                                double friction, double restitution) {
             return w.add_static_box(name, vecx(half_extents, 3, "half_extents"),
                                     pose_arg(pose_obj, position, quaternion), friction, restitution);
           },
           py::arg("name"), py::arg("half_extents"), py::arg("pose") = py::none(), py::kw_only(),
           py::arg("position") = py::none(), py::arg("quaternion") = py::none(), py::arg("friction") = 1.0,
           py::arg("restitution") = 0.0,
           "Adds a static box (scenery): half extents (3,) m, at pose (4, 4) or position (3,) m and quaternion "
           "(4,) [w, x, y, z]; returns its id.")
      .def("add_free_box", [](World& w, const std::string& name, const py::object& half_extents, double mass,
                              const py::object& pose_obj, const py::object& position, const py::object& quaternion,
                              double friction, double restitution, const py::object& velocity,
                              const py::object& angular_velocity) {
             return w.add_free_box(name, vecx(half_extents, 3, "half_extents"), mass,
                                   pose_arg(pose_obj, position, quaternion), friction, restitution,
                                   vecx(velocity, 3, "velocity"), vecx(angular_velocity, 3, "angular_velocity"));
           },
           py::arg("name"), py::arg("half_extents"), py::arg("mass"), py::arg("pose") = py::none(), py::kw_only(),
           py::arg("position") = py::none(), py::arg("quaternion") = py::none(), py::arg("friction") = 0.5,
           py::arg("restitution") = 0.0, py::arg("velocity") = py::make_tuple(0.0, 0.0, 0.0),
           py::arg("angular_velocity") = py::make_tuple(0.0, 0.0, 0.0),
           "Adds a free box: half extents (3,) m, mass kg (a uniform box), at pose (4, 4) or position and "
           "quaternion, with initial velocity (3,) m/s and angular velocity (3,) rad/s; returns its id.")
      .def_property_readonly("gravity", [](const World& w) { return to_numpy(w.options().gravity); })
      .def_property_readonly("floor", [](const World& w) { return w.options().floor; })
      .def_property_readonly("attached", &World::attached, "Whether a simulation owns the world.")
      .def_property_readonly("body_names", [](const World& w) {
             std::vector<std::string> out;
             for (int i = 0; i < w.body_count(); ++i) out.push_back(w.body(i).name);
             return out;
           }, "Names of every body, by id (robots' link bodies once a simulation has stepped).")
      .def("body", [](const World& w, const std::string& name) {
             const int id = w.find(name);
             if (id < 0) throw py::value_error("no body named '" + name + "' in the world");
             return spec_dict(w.body(id));
           }, py::arg("name"), "A body's description: name, kind, half_extents, mass, pose, velocity, ... .")
      .def("__len__", &World::body_count)
      .def("__repr__", [](const World& w) {
         int free = 0, fixed = 0;
         for (int i = 0; i < w.body_count(); ++i) {
           free += w.body(i).kind == BodyKind::Free;
           fixed += w.body(i).kind == BodyKind::Static;
         }
         return "<coopsim.World floor=" + std::string(w.options().floor ? "True" : "False") + ", " +
                std::to_string(fixed) + " static, " + std::to_string(free) + " free bodies>";
       })
      .def(py::pickle(
          [](const World& w) {
            const WorldOptions& o = w.options();
            py::list bodies;
            for (int i = 0; i < w.body_count(); ++i) {
              const BodySpec& b = w.body(i);
              if (b.kind == BodyKind::Static || b.kind == BodyKind::Free) bodies.append(spec_dict(b));
            }
            return py::make_tuple(o.floor, to_numpy(o.gravity), o.floor_friction, o.floor_restitution,
                                  o.solver_iterations, bodies, o.sleep_after);
          },
          [](py::tuple t) {
            WorldOptions o;
            o.floor = t[0].cast<bool>();
            o.gravity = vecx(t[1], 3, "gravity");
            o.floor_friction = t[2].cast<double>();
            o.floor_restitution = t[3].cast<double>();
            o.solver_iterations = t[4].cast<int>();
            if (t.size() > 6) o.sleep_after = t[6].cast<double>();
            auto w = std::make_shared<World>(o);
            for (py::handle h : t[5].cast<py::list>()) {
              py::dict d = h.cast<py::dict>();
              const std::string name = d["name"].cast<std::string>();
              const Eigen::Vector3d he = vecx(d["half_extents"], 3, "half_extents");
              const Eigen::Isometry3d T = pose(d["pose"], "pose");
              if (d["kind"].cast<std::string>() == "static")
                w->add_static_box(name, he, T, d["friction"].cast<double>(), d["restitution"].cast<double>());
              else
                w->add_free_box(name, he, d["mass"].cast<double>(), T, d["friction"].cast<double>(),
                                d["restitution"].cast<double>(), vecx(d["velocity"], 3, "velocity"),
                                vecx(d["angular_velocity"], 3, "angular_velocity"));
            }
            return w;
          }));
}
