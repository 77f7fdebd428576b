// The Bullet world: scenery and free bodies (robots' link bodies come from a
// simulation).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "nogil.hpp"
#include "convert.hpp"
#include "generated/docstrings.hpp"
#include "struct_binding.hpp"
#include "coopsim/box_distance.hpp"
#include "coopsim/robot.hpp"
#include "coopsim/world.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;
using namespace coopsim::docs;

namespace {

Eigen::Isometry3d pose_arg(const py::object& pose, const py::object& position, const py::object& quaternion) {
  return body_pose(optional_table(pose, "pose"), optional_table(position, "position"),
                   optional_table(quaternion, "quaternion"));
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

BodySpec spec_from(const py::handle& h) {
  const py::dict d = h.cast<py::dict>();
  BodySpec b;
  b.name = d["name"].cast<std::string>();
  b.kind = body_kind(d["kind"].cast<std::string>());
  b.half_extents = vecx(d["half_extents"], 3, "half_extents");
  b.mass = d["mass"].cast<double>();
  b.pose = pose(d["pose"], "pose");
  b.velocity = vecx(d["velocity"], 3, "velocity");
  b.angular_velocity = vecx(d["angular_velocity"], 3, "angular_velocity");
  b.friction = d["friction"].cast<double>();
  b.restitution = d["restitution"].cast<double>();
  return b;
}

}  // namespace

void bind_world(py::module_& m) {
  coopsim::py_struct::Struct<BodyState>(m, "BodyState", doc_BodyState)
      .member("pose", &BodyState::pose, doc_BodyState_pose)
      .field("position", [](const BodyState& s) { return Eigen::Vector3d(s.pose.translation()); }, doc_BodyState_pose)
      .field("quaternion", [](const BodyState& s) {
        const Eigen::Quaterniond q(s.pose.linear());
        return Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
      }, doc_BodyState_pose)
      .member("velocity", &BodyState::velocity, doc_BodyState_velocity)
      .member("angular_velocity", &BodyState::angular_velocity, doc_BodyState_angular_velocity)
      .member("asleep", &BodyState::asleep, doc_BodyState_asleep)
      .finish();
  m.def("box_distance", [](const py::object& pa, const py::object& ha, const py::object& pb, const py::object& hb) {
          return box_distance(table(pa, "pose_a"), table(ha, "half_a"), table(pb, "pose_b"), table(hb, "half_b"));
        }, py::arg("pose_a"), py::arg("half_a"), py::arg("pose_b"), py::arg("half_b"),
        "Distance between two boxes, m: the gap between their nearest points (> 0), or minus the depth of "
        "their overlap (<= 0).\n\npose_a, pose_b: (4, 4) world poses of the box centres; half_a, half_b: (3,) "
        "half extents (m, > 0). Bullet's GJK and EPA on exact boxes (no collision margin).");
  m.def("box_clearances", [](const py::object& pa, const py::object& ha, const py::object& pb,
                             const py::object& hb) {
          Arr keep_a, keep_b;
          const ArrayView A = table_view(pa, "poses_a", keep_a), B = table_view(pb, "poses_b", keep_b);
          const Array x = table(ha, "half_a"), y = table(hb, "half_b");
          BoxClearances c;
          {
            coopsim::py_nogil::NoGil nogil;
            c = box_clearances(A, x, B, y);
          }
          const auto n = static_cast<py::ssize_t>(c.d.size());
          return py::make_tuple(py::array_t<double>(n, c.d.data()), py::array_t<long>(n, c.ia.data()),
                                py::array_t<long>(n, c.ib.data()));
        }, py::arg("poses_a"), py::arg("half_a"), py::arg("poses_b"), py::arg("half_b"),
        "The clearance between two sets of boxes in each of N configurations: the smallest box_distance "
        "(m; <= 0: minus the overlap depth) over every pair of a box of one set and a box of the other, and "
        "the pair that has it.\n\nposes_a: (N, ka, 4, 4) world poses of the box centres per row; half_a: (ka, "
        "3) half extents (m, > 0); poses_b: (N, kb, 4, 4), or (kb, 4, 4) for boxes that do not move; half_b: "
        "(kb, 3). Returns (d (N,), ia (N,), ib (N,)): the distance and the indices of the nearest pair. The "
        "same minimum as box_distances on every pair, with far fewer GJK calls (each row starts from the "
        "previous row's nearest pair; an earlier row's bound less the boxes' motion since, bounding spheres "
        "and separating axes rule the others out): rows in time order are fastest. GIL released.");
  m.def("shape_distance", [](const LinkBox& a, const py::object& pa, const LinkBox& b, const py::object& pb) {
          const Eigen::Isometry3d A = rigid_pose(table(pa, "pose_a"), "pose_a"), B = rigid_pose(table(pb, "pose_b"), "pose_b");
          coopsim::py_nogil::NoGil nogil;
          return shape_distance(a, A, b, B);
        }, py::arg("shape_a"), py::arg("pose_a"), py::arg("shape_b"), py::arg("pose_b"),
        "Distance between two convex shapes of any kind (LinkBox: box, sphere, cylinder, hull), m: the gap "
        "between their nearest points (> 0; Bullet's GJK, no collision margin), or minus the depth of their "
        "overlap (<= 0: two boxes by their separating axes, exactly; any other pair by Bullet's EPA).\n\n"
        "shape_a, shape_b: LinkBox (their link and pose are not used); pose_a, pose_b: (4, 4) world poses of the "
        "shapes' frames (for a robot's shapes, Robot.shapes(q)'s poses). Two boxes give box_distance.");
  m.def("shape_clearances", [](const py::object& pa, const std::vector<LinkBox>& sa, const py::object& pb,
                               const std::vector<LinkBox>& sb) {
          Arr keep_a, keep_b;
          const ArrayView A = table_view(pa, "poses_a", keep_a), B = table_view(pb, "poses_b", keep_b);
          const std::vector<Shape> x(sa.begin(), sa.end()), y(sb.begin(), sb.end());
          BoxClearances c;
          {
            coopsim::py_nogil::NoGil nogil;
            c = shape_clearances(A, x, B, y);
          }
          const auto n = static_cast<py::ssize_t>(c.d.size());
          return py::make_tuple(py::array_t<double>(n, c.d.data()), py::array_t<long>(n, c.ia.data()),
                                py::array_t<long>(n, c.ib.data()));
        }, py::arg("poses_a"), py::arg("shapes_a"), py::arg("poses_b"), py::arg("shapes_b"),
        "box_clearances of convex shapes of any kind: the smallest shape_distance (m) in each of N "
        "configurations over every pair of a shape of one set and a shape of the other, and the pair.\n\n"
        "poses_a: (N, ka, 4, 4) world poses of shapes_a's ka shapes (a list of LinkBox, e.g. Robot.boxes) per "
        "row (Robot.shapes(Q)[0]); poses_b: (N, kb, 4, 4), or (kb, 4, 4) for shapes that do not move; shapes_b: "
        "kb LinkBox. Returns (d (N,), ia (N,), ib (N,)). The same lower bounds as box_clearances (each shape lies "
        "in its half_extents' box); boxes alone give box_clearances' values. GIL released.");
  m.def("box_distances", [](const py::object& pa, const py::object& ha, const py::object& pb, const py::object& hb,
                            bool pairwise) {
          const Array A = table(pa, "poses_a"), x = table(ha, "half_a"), B = table(pb, "poses_b"), y = table(hb, "half_b");
          Array d;
          {
            coopsim::py_nogil::NoGil nogil;
            d = box_distances(A, x, B, y, pairwise);
          }
          return to_numpy(d);
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
      .def_property_readonly("body_names", &World::body_names,
                             "Names of every body, by id (robots' link bodies once a simulation has stepped).")
      .def("body", [](const World& w, const std::string& name) { return spec_dict(w.body(name)); }, py::arg("name"),
           "A body's description: name, kind, half_extents, mass, pose, velocity, ... .")
      .def("__len__", &World::body_count)
      .def("__repr__", &World::describe)
      .def(py::pickle(
          [](const World& w) {
            const WorldOptions& o = w.options();
            py::list bodies;
            for (const BodySpec& b : w.own_bodies()) bodies.append(spec_dict(b));
            return py::make_tuple(o.floor, to_numpy(o.gravity), o.floor_friction, o.floor_restitution,
                                  o.solver_iterations, bodies, o.sleep_after);
          },
          [](const py::tuple& t) {
            py::dict later;  // made again as when it was made, by the constructor and add_body
            if (t.size() > 6) later["sleep_after"] = t[6];
            auto w = py::type::of<World>()(t[0], t[1], t[2], t[3], t[4], **later).cast<std::shared_ptr<World>>();
            for (py::handle h : t[5]) w->add_body(spec_from(h));
            return w;
          }));
}
