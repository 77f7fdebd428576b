// Robot: construction from tables, kinematics and dynamics.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "nogil.hpp"
#include "convert.hpp"
#include "coopsim/generated.hpp"
#include "coopsim/robot.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

namespace {

Tool make_tool(const py::object& tool) {
  Tool t;
  if (tool.is_none()) return t;
  if (py::isinstance<Tool>(tool)) return tool.cast<Tool>();
  t.offset = pose(tool, "tool");
  t.second_point = t.offset.translation();
  return t;
}

std::vector<LinkBox> boxes_arg(const py::object& obj) {
  std::vector<LinkBox> out;
  if (obj.is_none()) return out;
  if (!py::isinstance<py::list>(obj) && !py::isinstance<py::tuple>(obj))
    throw py::value_error("boxes must be a list of coopsim.LinkBox");
  for (py::handle h : obj) {
    if (!py::isinstance<LinkBox>(h)) throw py::value_error("boxes must hold coopsim.LinkBox objects only");
    out.push_back(h.cast<LinkBox>());
  }
  if (out.empty()) throw py::value_error("boxes must not be empty (None gives the default boxes)");
  return out;
}

Clamp clamp_arg(const py::object& obj) {
  if (obj.is_none()) return Clamp();
  if (!py::isinstance<Clamp>(obj)) throw py::value_error("clamp must be a coopsim.Clamp or None");
  return obj.cast<Clamp>();
}

py::object inertia_warning_category() {
  static py::object cat = py::reinterpret_steal<py::object>(
      PyErr_NewException("coopsim._core.InertiaWarning", PyExc_UserWarning, nullptr));
  return cat;
}

// Robot.from_dh: the arguments as the engine's tables; InertiaWarning for what the engine allows with a warning
Robot from_dh(const py::object& dh, const py::object& com, const py::object& masses, const py::object& inertias,
              const std::string& joint_types, const py::object& friction, const py::object& q_limits,
              const py::object& tau_limits, const py::object& gravity, const py::object& base_position,
              double base_yaw, const py::object& tool, const std::string& name, double end_stop_frequency,
              double end_stop_damping_ratio, const py::object& boxes, const py::object& clamp,
              const py::object& dimensions, const py::object& armature, const py::object& coulomb,
              const py::object& coulomb_width, const py::object& base_orientation, const std::string& inertia_check) {
  RobotTables t{table(dh, "dh"), table(com, "com"), table(masses, "masses"), table(inertias, "inertias"),
                joint_types, optional_table(friction, "friction"), optional_table(tau_limits, "tau_limits"),
                optional_table(q_limits, "q_limits"), optional_table(armature, "armature"),
                optional_table(coulomb, "coulomb"), optional_table(coulomb_width, "coulomb_width"),
                table(gravity, "gravity"), table(base_position, "base_position"), base_yaw,
                optional_table(base_orientation, "base_orientation"), make_tool(tool),
                name, EndStop{end_stop_frequency, end_stop_damping_ratio}};
  if (!boxes.is_none()) t.boxes = boxes_arg(boxes);
  t.clamp = clamp_arg(clamp);
  if (!dimensions.is_none()) t.dimensions = dimensions.cast<std::map<std::string, double>>();
  t.inertia_check = inertia_check;
  std::vector<std::string> warnings;
  Robot r = Robot::from_tables(t, &warnings);
  for (const std::string& w : warnings)
    if (PyErr_WarnEx(inertia_warning_category().ptr(), w.c_str(), 1) < 0) throw py::error_already_set();
  return r;
}

// q converted for robot r, with a workspace holding its kinematics (when kin).
struct At {
  VecN q;
  Workspace ws;
  At(const Robot& r, const py::object& q_obj, bool kin = true) : q(vec(q_obj, r.dof(), "q")) {
    if (kin) r.kinematics(q.data(), ws);
  }
  // joint torques of f_ext (zeros for None), leaving the kinematics of q in ws
  VecN external(const Robot& r, const py::object& f_ext) {
    VecN t = VecN::Zero(r.dof());
    if (f_ext.is_none()) return t;
    r.kinematics(q.data(), ws);
    r.external_torques(wrenches_arg(f_ext, "f_ext"), ws, t);
    return t;
  }
};

py::array_t<double> checked_pose(const Eigen::Isometry3d& T, const char* what) {
  checked(T.matrix(), what);
  return to_numpy(T);
}

// Ts checked finite and written row-major into p (16 doubles each): no Python, callable without the GIL
void write_poses(const std::vector<Eigen::Isometry3d>& Ts, double* p) {
  for (const auto& T : Ts)
    if (!T.matrix().allFinite()) throw py::value_error("frames: result is not finite for this input (values out of range?)");
  for (size_t i = 0; i < Ts.size(); ++i)
    Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(p + 16 * i) = Ts[i].matrix();
}

py::array_t<double> poses(const std::vector<Eigen::Isometry3d>& Ts) {
  py::array_t<double> out({static_cast<py::ssize_t>(Ts.size()), py::ssize_t(4), py::ssize_t(4)});
  write_poses(Ts, out.mutable_data());
  return out;
}

// Robot.poses_of_states for q (N, n): (N, 4, 4) of the tool, (N, k, 4, 4) of the k boxes or (N, n + 1, 4, 4) of
// the DH frames; the poses computed, checked and written into the array with the GIL released
py::array_t<double> poses_of_states(const Robot& r, const py::object& q, Robot::PosesOf what) {
  Arr Q = array(q, {-1, r.dof()}, "q");
  std::vector<py::ssize_t> shape{Q.shape(0), py::ssize_t(4), py::ssize_t(4)};
  if (what == Robot::PosesOf::kBoxes) shape.insert(shape.begin() + 1, static_cast<py::ssize_t>(r.boxes().size()));
  if (what == Robot::PosesOf::kFrames) shape.insert(shape.begin() + 1, static_cast<py::ssize_t>(r.dof() + 1));
  py::array_t<double> out(shape);
  double* p = out.mutable_data();
  coopsim::py_nogil::NoGil nogil;
  std::vector<Eigen::Isometry3d> T;
  r.poses_of_states(Q.data(), static_cast<long>(Q.shape(0)), what, T);
  write_poses(T, p);
  return out;
}

}  // namespace

void bind_robot(py::module_& m) {
  m.def("box_inertia", [](double mass, double lx, double ly, double lz) {
         return to_numpy(box_inertia(mass, lx, ly, lz));
       }, py::arg("mass"), py::arg("lx"), py::arg("ly"), py::arg("lz"),
        "Inertia tensor (3, 3) in kg m^2 of a solid box of `mass` kg and edges lx, ly, lz (m) along x, y, z, "
        "about its centre.");
  m.def(
      "dh_transform",
      [](double theta, double d, double a, double alpha) { return to_numpy(dh_transform(theta, d, a, alpha)); },
      py::arg("theta"), py::arg("d"), py::arg("a"), py::arg("alpha"),
      "Homogeneous transform (4, 4) Rz(theta) Tz(d) Tx(a) Rx(alpha) of one standard DH row.");

  py::class_<Tool>(m, "Tool", kToolDoc)
      .def(py::init([](int link, const py::object& offset, int second_link, const py::object& second_point) {
             Tool t;
             t.link = link;
             t.offset = pose(offset, "offset");
             t.second_link = second_link;
             t.second_point = vecx(second_point, 3, "second_point");
             return t;
           }),
           py::arg("link") = -1, py::arg("offset") = py::module_::import("numpy").attr("eye")(4),
           py::arg("second_link") = -1, py::arg("second_point") = py::make_tuple(0.0, 0.0, 0.0))
      .def_readonly("link", &Tool::link)
      .def_property_readonly("offset", [](const Tool& t) { return to_numpy(t.offset); })
      .def_readonly("second_link", &Tool::second_link)
      .def_property_readonly("second_point", [](const Tool& t) { return to_numpy(t.second_point); })
      .def(pickle_by_call<Tool>([](const Tool& t) {
        return py::make_tuple(py::make_tuple(t.link, to_numpy(t.offset), t.second_link, to_numpy(t.second_point)),
                              py::dict());
      }));

  py::class_<ExternalWrench>(m, "Wrench", kWrenchDoc)
      .def(py::init([](int link, const py::object& point, const py::object& wrench) {
             ExternalWrench w;
             w.link = link;
             w.point = vecx(point, 3, "point");
             w.wrench = vecx(wrench, 6, "wrench");
             return w;
           }),
           py::arg("link"), py::arg("point"), py::arg("wrench"))
      .def_static("at_tool", [](const py::object& wrench) {
             ExternalWrench w;
             w.at_tool = true;
             w.wrench = vecx(wrench, 6, "wrench");
             return w;
           }, py::arg("wrench"),
           "A wrench [fx, fy, fz, mx, my, mz] (world, N and N m) at the tool centre point, as a (6,) f_ext.")
      .def_readonly("link", &ExternalWrench::link)
      .def_readonly("at_tool_point", &ExternalWrench::at_tool, "True for a wrench at the tool centre point.")
      .def_property_readonly("point", [](const ExternalWrench& w) { return to_numpy(w.point); })
      .def_property_readonly("wrench", [](const ExternalWrench& w) { return to_numpy(w.wrench); })
      .def("__repr__", [](const ExternalWrench& w) {
         std::ostringstream s;
         s << "Wrench(";
         if (w.at_tool) s << "at_tool";
         else s << "link=" << w.link << ", point=[" << w.point.transpose() << "]";
         s << ", wrench=[" << w.wrench.transpose() << "])";
         return s.str();
       })
      .def(py::pickle(
          [](const ExternalWrench& w) { return py::make_tuple(w.link, to_numpy(w.point), to_numpy(w.wrench), w.at_tool); },
          [](const py::tuple& t) {  // made again as it was made, checked
            const py::object W = py::type::of<ExternalWrench>();
            return (t[3].cast<bool>() ? W.attr("at_tool")(t[2]) : W(t[0], t[1], t[2])).cast<ExternalWrench>();
          }));

  py::class_<LinkBox>(m, "LinkBox", kLinkBoxDoc)
      .def(py::init([](int link, const py::object& half_extents, const py::object& pose_obj, const std::string& name) {
             LinkBox b;
             b.link = link;
             b.half_extents = vecx(half_extents, 3, "half_extents");
             b.pose = pose(pose_obj, "pose");
             b.name = name;
             return b;
           }),
           py::arg("link"), py::arg("half_extents"), py::arg("pose") = py::module_::import("numpy").attr("eye")(4),
           py::arg("name") = "")
      .def_static("sphere", [](int link, double radius, const py::object& pose_obj, const std::string& name) {
             return LinkBox::sphere(link, radius, pose(pose_obj, "pose"), name);
           }, py::arg("link"), py::arg("radius"), py::arg("pose") = py::module_::import("numpy").attr("eye")(4),
           py::arg("name") = "",
           "A sphere of `radius` (m, > 0) on `link` (0 .. n), centred at `pose`'s origin ((4, 4) in the link's "
           "DH frame); the world collides it as Bullet's btSphereShape.")
      .def_static("cylinder", [](int link, double radius, double length, const py::object& pose_obj,
                                 const std::string& name) {
             return LinkBox::cylinder(link, radius, length, pose(pose_obj, "pose"), name);
           }, py::arg("link"), py::arg("radius"), py::arg("length"),
           py::arg("pose") = py::module_::import("numpy").attr("eye")(4), py::arg("name") = "",
           "A cylinder of `radius` and `length` (m, > 0) on `link` (0 .. n), centred at `pose`'s origin ((4, 4) "
           "in the link's DH frame) with its axis along `pose`'s z (URDF's convention); the world collides it as "
           "Bullet's btCylinderShapeZ.")
      .def_static("hull", [](int link, const py::object& points, const py::object& pose_obj, const std::string& name) {
             const Arr a = array(points, {-1, 3}, "points", false);
             std::vector<Eigen::Vector3d> pts;
             for (py::ssize_t i = 0; i < a.shape(0); ++i) pts.emplace_back(a.at(i, 0), a.at(i, 1), a.at(i, 2));
             return LinkBox::hull(link, pts, pose(pose_obj, "pose"), name);
           }, py::arg("link"), py::arg("points"), py::arg("pose") = py::module_::import("numpy").attr("eye")(4),
           py::arg("name") = "",
           "The convex hull of `points` (k, 3) m (4 <= k <= 4096, not on one plane) given in the frame `pose` "
           "((4, 4) in the DH frame of `link`, 0 .. n; the identity: points in the link's frame). Kept about the "
           "centre of the points' bounding box: `pose` moves there and `points` are given back less it, so "
           "that half_extents is the points' bounding box. The world collides it as Bullet's btConvexHullShape "
           "(reduced to the hull's vertices); its cost grows with k: coopsim.Robot.from_urdf keeps 64 points of "
           "a mesh's hull by default.")
      .def("moved", [](const LinkBox& b, int link, const py::object& pose_obj) {
             LinkBox out = b;
             out.link = link;
             out.pose = pose(pose_obj, "pose");
             return out;
           }, py::arg("link"), py::arg("pose"),
           "The same shape (kind, sizes, points, name) on `link` at `pose` ((4, 4) in that link's DH frame).")
      .def_readonly("link", &LinkBox::link)
      .def_property_readonly("kind", [](const LinkBox& b) { return shape_kind_name(b.type); },
                             "\"box\", \"sphere\", \"cylinder\" or \"hull\".")
      .def_property_readonly("half_extents", [](const LinkBox& b) { return to_numpy(b.half_extents); })
      .def_property_readonly("radius", [](const LinkBox& b) { return b.radius; },
                             "A sphere's or a cylinder's radius, m (0 for the other kinds).")
      .def_property_readonly("length", [](const LinkBox& b) { return 2.0 * b.half_length; },
                             "A cylinder's length along its z, m (0 for the other kinds).")
      .def_property_readonly("points", [](const LinkBox& b) {
         py::array_t<double> out({static_cast<py::ssize_t>(b.points.size()), py::ssize_t(3)});
         for (size_t i = 0; i < b.points.size(); ++i)
           for (int k = 0; k < 3; ++k) out.mutable_at(i, k) = b.points[i][k];
         return out;
       }, "A hull's points (k, 3) m in its frame (pose); (0, 3) for the other kinds.")
      .def_property_readonly("pose", [](const LinkBox& b) { return to_numpy(b.pose); })
      .def_readonly("name", &LinkBox::name)
      .def("__repr__", [](const LinkBox& b) {
         std::ostringstream s;
         s << "LinkBox";
         switch (b.type) {
           case ShapeKind::Sphere: s << ".sphere(link=" << b.link << ", radius=" << b.radius; break;
           case ShapeKind::Cylinder:
             s << ".cylinder(link=" << b.link << ", radius=" << b.radius << ", length=" << 2.0 * b.half_length;
             break;
           case ShapeKind::Hull: s << ".hull(link=" << b.link << ", points=<" << b.points.size() << " points>"; break;
           default: s << "(link=" << b.link << ", half_extents=[" << b.half_extents.transpose() << "]";
         }
         s << ", name='" << b.name << "')";
         return s.str();
       })
      .def(py::pickle(
          [](const LinkBox& b) {
            py::array_t<double> pts({static_cast<py::ssize_t>(b.points.size()), py::ssize_t(3)});
            for (size_t i = 0; i < b.points.size(); ++i)
              for (int k = 0; k < 3; ++k) pts.mutable_at(i, k) = b.points[i][k];
            return py::make_tuple(b.link, to_numpy(b.half_extents), to_numpy(b.pose), b.name, shape_kind_name(b.type),
                                  b.radius, 2.0 * b.half_length, pts);
          },
          [](const py::tuple& t) {  // made again as it was made, checked
            const py::object L = py::type::of<LinkBox>();
            const std::string kind = t.size() > 4 ? t[4].cast<std::string>() : "box";
            py::object b;
            if (kind == "sphere") b = L.attr("sphere")(t[0], t[5], t[2], t[3]);
            else if (kind == "cylinder") b = L.attr("cylinder")(t[0], t[5], t[6], t[2], t[3]);
            else if (kind == "hull") b = L.attr("hull")(t[0], t[7], t[2], t[3]);
            else b = L(t[0], t[1], t[2], t[3]);
            return b.cast<LinkBox>();
          }));

  py::class_<Clamp>(m, "Clamp", kClampDoc)
      .def(py::init([](int fixed_link, const py::object& fixed_face, int moving_joint, double jaw_length,
                       double pad_width) {
             Clamp c;
             c.fixed_link = fixed_link;
             c.fixed_face = pose(fixed_face, "fixed_face");
             c.moving_joint = moving_joint;
             c.jaw_length = jaw_length;
             c.pad_width = pad_width;
             if (c.fixed_link < 1) throw py::value_error("fixed_link must be >= 1");
             return c;
           }),
           py::arg("fixed_link"), py::arg("fixed_face"), py::arg("moving_joint"), py::arg("jaw_length"),
           py::arg("pad_width"))
      .def_readonly("fixed_link", &Clamp::fixed_link)
      .def_property_readonly("fixed_face", [](const Clamp& c) { return to_numpy(c.fixed_face); })
      .def_readonly("moving_joint", &Clamp::moving_joint)
      .def_readonly("jaw_length", &Clamp::jaw_length)
      .def_readonly("pad_width", &Clamp::pad_width)
      .def(pickle_by_call<Clamp>([](const Clamp& c) {
        return py::make_tuple(
            py::make_tuple(c.fixed_link, to_numpy(c.fixed_face), c.moving_joint, c.jaw_length, c.pad_width), py::dict());
      }));

  py::class_<Robot> R(m, "Robot",
                      "A serial robot: standard DH table, centre-of-mass table, mass properties, friction, "
                      "limits and link shapes, placed in the world. Immutable: with_base, with_backend, ... "
                      "make changed copies. Build one with Robot.from_dh, Robot.from_urdf or coopsim.robots.");
  R.def_static("from_dh", &from_dh, py::arg("dh"), py::arg("com"), py::arg("masses"), py::arg("inertias"),
               py::arg("joint_types"), py::arg("friction") = py::none(), py::arg("q_limits") = py::none(),
               py::arg("tau_limits") = py::none(),
               py::arg("gravity") = py::make_tuple(0.0, 0.0, -9.81),
               py::arg("base_position") = py::make_tuple(0.0, 0.0, 0.0), py::arg("base_yaw") = 0.0,
               py::arg("tool") = py::none(), py::arg("name") = "robot",
               py::arg("end_stop_frequency") = EndStop().frequency,
               py::arg("end_stop_damping_ratio") = EndStop().damping_ratio, py::arg("boxes") = py::none(),
               py::arg("clamp") = py::none(), py::arg("dimensions") = py::none(),
               py::arg("armature") = py::none(), py::arg("coulomb") = py::none(),
               py::arg("coulomb_width") = py::none(), py::arg("base_orientation") = py::none(),
               py::arg("inertia_check") = "warn",
               RobotTables::kDoc);
  R.def_property_readonly("dof", &Robot::dof, "Number of joints n.")
      .def_property_readonly("name", &Robot::name)
      .def_property_readonly("joint_types", &Robot::joint_types, "e.g. 'RRPRRP'.")
      .def_property_readonly("joint_names", &Robot::joint_names,
                             "Names of the joints (n,), in the order of q: from a URDF its joints' names, else "
                             "'joint1'..'jointn'.")
      .def_property_readonly("link_names", &Robot::link_names,
                             "Names of the moving links (n,), link i moved by joint i: from a URDF the child "
                             "link of each chain joint, else 'link1'..'linkn'.")
      .def("with_names", &Robot::with_names, py::arg("joint_names"), py::arg("link_names"),
           "A copy with these joint and link names (n each, unique, not empty); all else equal.")
      .def_property_readonly("dh", [](const Robot& r) { return to_numpy(r.tables().dh); }, "(n, 4) [theta, d, a, alpha].")
      .def_property_readonly("com", [](const Robot& r) { return to_numpy(r.tables().com); }, "(n, 4) CoM rows.")
      .def_property_readonly("masses", [](const Robot& r) { return to_numpy(r.tables().masses); }, "(n,) kg.")
      .def_property_readonly("inertias", [](const Robot& r) { return to_numpy(r.tables().inertias); },
                             "(n, 3, 3) kg m^2 about each CoM in its CoM frame.")
      .def_property_readonly("friction_coefficients", [](const Robot& r) { return to_numpy(*r.tables().friction); },
                             "(n,) viscous K.")
      .def_property_readonly("armature", [](const Robot& r) { return to_numpy(*r.tables().armature); },
                             "(n,) reflected rotor inertia J_m G^2 on M's diagonal, kg m^2 or kg.")
      .def_property_readonly("coulomb", [](const Robot& r) { return to_numpy(*r.tables().coulomb); },
                             "(n,) Coulomb friction F_c, N m or N.")
      .def_property_readonly("coulomb_width", [](const Robot& r) { return to_numpy(*r.tables().coulomb_width); },
                             "(n,) v_c of F_c tanh(qd / v_c), rad/s or m/s.")
      .def_property_readonly("com_positions", [](const Robot& r) {
             py::array_t<double> out({r.dof(), 3});
             for (int i = 1; i <= r.dof(); ++i)
               Eigen::Map<Eigen::RowVector3d>(out.mutable_data() + 3 * (i - 1)) = r.com_position(i).transpose();
             return out;
           }, "(n, 3) CoM of each link in its DH frame i, m (the Robotics Toolbox's and URDF's convention).")
      .def_property_readonly("link_inertias", [](const Robot& r) {
             py::array_t<double> out({r.dof(), 3, 3});
             for (int i = 1; i <= r.dof(); ++i)
               Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(out.mutable_data() + 9 * (i - 1)) =
                   r.link_inertia(i);
             return out;
           }, "(n, 3, 3) inertia of each link about its CoM in DH frame i's axes, kg m^2.")
      .def_property_readonly("inertia_warnings", &Robot::inertia_warnings,
                             "Links whose inertia tensor breaks the triangle inequality, one message each.")
      .def_property_readonly("base_orientation", [](const Robot& r) { return to_numpy(Eigen::MatrixXd(r.base_orientation())); },
                             "(3, 3) fixed rotation of the base after its yaw.")
      .def_property_readonly("q_limits", [](const Robot& r) { return to_numpy(*r.tables().q_limits); },
                             "(n, 2) [q_min, q_max].")
      .def_property_readonly("tau_limits", [](const Robot& r) { return to_numpy(*r.tables().tau_limits); }, "(n,) N m or N.")
      .def_property_readonly("gravity_acceleration", [](const Robot& r) { return to_numpy(r.gravity_acceleration()); },
                             "The world's gravitational acceleration (3,) m/s^2 (G(q) is gravity(q)).")
      .def_property_readonly("boxes", &Robot::boxes, "The LinkBox shapes fixed to the links, [LinkBox].")
      .def_property_readonly("clamp", [](const Robot& r) { return r.clamp().present() ? py::cast(r.clamp()) : py::none(); },
                             "The Clamp, or None.")
      .def_property_readonly("dimensions", &Robot::dimensions, "{name: metres} the robot was built from (may be empty).")
      .def("default_boxes", &Robot::default_boxes, Robot::kDefaultBoxesDoc)
      .def_property_readonly("base_position", [](const Robot& r) { return to_numpy(r.base_position()); })
      .def_property_readonly("base_yaw", &Robot::base_yaw)
      .def_property_readonly("base", [](const Robot& r) { return to_numpy(r.base()); },
                             "(4, 4) pose of DH frame 0 in the world.")
      .def_property_readonly("tool", &Robot::tool)
      .def_property_readonly("end_stop_frequency", [](const Robot& r) { return r.end_stop().frequency; })
      .def_property_readonly("end_stop_damping_ratio", [](const Robot& r) { return r.end_stop().damping_ratio; })
      .def_property_readonly("parameter_vector",
                             [](const Robot& r) {
                               const auto& p = r.parameter_vector();
                               return to_numpy(Eigen::Map<const Eigen::VectorXd>(p.data(), p.size()));
                             },
                             "(19 n + 3,) parameters read by generated code: per link [theta d a alpha, "
                             "com theta d a alpha, m, Ixx Iyy Izz Ixy Ixz Iyz, K, armature, F_c, v_c], then "
                             "gravity in frame 0.")
      .def_property_readonly("backend", &Robot::backend, "'generated' or 'numeric'.")
      .def_property_readonly("has_generated", &Robot::has_generated)
      .def("with_backend", &Robot::with_backend, py::arg("backend"),
           "A copy using 'generated' (closed-form code, if attached) or 'numeric' (recursive algorithms).")
      .def("with_generated", py::overload_cast<const std::string&>(&Robot::with_generated, py::const_), py::arg("name"),
           "A copy with the generated dynamics `name` attached (structure checked) and selected: code compiled "
           "into the engine (compiled_generated_names()) or built by coopsim.codegen.compile.")
      .def("with_geometry", [](const Robot& r, const py::object& boxes, const py::object& clamp) {
             return r.with_geometry(boxes_arg(boxes), clamp_arg(clamp));
           }, py::arg("boxes") = py::none(), py::arg("clamp") = py::none(),
           "A copy with other link boxes (None: the default boxes) and clamp (None: none).")
      .def("with_base_orientation", [](const Robot& r, const py::object& R) {
             return r.with_base_orientation(Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
                 array(R, {3, 3}, "base_orientation").data()));
           }, py::arg("base_orientation"), "A copy with another fixed base rotation (3, 3) after the yaw.")
      .def("with_base", [](const Robot& r, const py::object& position, double yaw) {
             return r.with_base(vecx(position, 3, "position"), yaw);
           }, py::arg("position"), py::arg("yaw") = 0.0, "A copy placed at `position` (3,) m with `yaw` rad.")
      .def("with_gravity", [](const Robot& r, const py::object& g) { return r.with_gravity(vecx(g, 3, "gravity")); },
           py::arg("gravity"), "A copy with another gravity vector (3,) m/s^2.");

  // kinematics
  R.def("fk", [](const Robot& r, const py::object& q) -> py::object {
         if (as_array(q, "q").ndim() != 2) return checked_pose(r.tool_pose(At(r, q).ws), "fk");
         return poses_of_states(r, q, Robot::PosesOf::kTool);  // N states at once
       },
        py::arg("q"), "Tool centre point pose (4, 4) in the world for joint positions q (n,); for N states q (N, n), "
        "the poses (N, 4, 4).")
      .def("frames", [](const Robot& r, const py::object& q) -> py::object {
         if (as_array(q, "q").ndim() == 2) return poses_of_states(r, q, Robot::PosesOf::kFrames);  // N states
         const At at(r, q);
         std::vector<Eigen::Isometry3d> T;
         for (int i = 0; i <= r.dof(); ++i) T.push_back(r.frame(at.ws, i));
         return poses(T);
       }, py::arg("q"), "World poses (n + 1, 4, 4) of DH frames 0..n at q (n,); for N states q (N, n), the poses "
       "(N, n + 1, 4, 4) (computed with the GIL released).")
      .def("com_frames", [](const Robot& r, const py::object& q) {
         const At at(r, q);
         std::vector<Eigen::Isometry3d> T;
         for (int i = 1; i <= r.dof(); ++i) T.push_back(r.com_frame(at.ws, i));
         return poses(T);
       }, py::arg("q"), "World poses (n, 4, 4) of the CoM frames of links 1..n.")
      .def("jacobian", [](const Robot& r, const py::object& q, int link, const py::object& point) {
         const Eigen::Vector3d p = point.is_none() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(vecx(point, 3, "point"));
         Mat6N J;
         r.jacobian(At(r, q).ws, link, p, J);
         return checked(J, "jacobian");
       }, py::arg("q"), py::arg("link") = -1, py::arg("point") = py::none(),
       "Geometric Jacobian (6, n), linear rows first, of `point` (3,) m given in the DH frame of `link` "
       "(1..n, negative from the last; 0 is the base); world coordinates.")
      .def("shapes", [](const Robot& r, const py::object& q) -> py::tuple {
         const py::ssize_t k = static_cast<py::ssize_t>(r.boxes().size());
         py::array_t<double> he({k, py::ssize_t(3)});
         for (py::ssize_t i = 0; i < k; ++i)
           Eigen::Map<Eigen::RowVector3d>(he.mutable_data() + 3 * i) = r.boxes()[i].half_extents.transpose();
         if (as_array(q, "q").ndim() == 2)
           return py::make_tuple(poses_of_states(r, q, Robot::PosesOf::kBoxes), he);  // (N, k, 4, 4)
         std::vector<Eigen::Isometry3d> T;
         r.box_poses(At(r, q).ws, T);
         return py::make_tuple(poses(T), he);
       }, py::arg("q"),
       "World poses (k, 4, 4) and half extents (k, 3) m of the robot's k boxes (Robot.boxes order) at q (n,); "
       "for N states q (N, n), the poses (N, k, 4, 4).")
      .def("clamp_faces", [](const Robot& r, const py::object& q) {
         const At at(r, q);
         Eigen::Isometry3d a, b;
         r.clamp_faces(at.ws, at.q.data(), a, b);
         return poses({a, b});
       }, py::arg("q"),
       "World poses (2, 4, 4) of the clamp's fixed and moving inner faces at q: origin at the face's centre, z "
       "the face normal pointing to the other jaw, x along the jaw towards its tip.")
      .def("tool_jacobian", [](const Robot& r, const py::object& q) {
         Mat6N J;
         r.tool_jacobian(At(r, q).ws, J);
         return checked(J, "tool_jacobian");
       }, py::arg("q"), "Jacobian (6, n) of the tool centre point, linear rows first.")
      .def("tool_bias", [](const Robot& r, const py::object& q, const py::object& qd) {
         At at(r, q);
         const VecN v = vec(qd, r.dof(), "qd");
         Vec6 b;
         r.tool_bias(at.ws, v.data(), b);
         return checked(b, "tool_bias");
       }, py::arg("q"), py::arg("qd"),
           "Jd qd (6,): the tool centre point's linear (m/s^2) and its link's angular (rad/s^2) acceleration "
           "at joint velocities qd (n,) with zero joint accelerations; the TCP's acceleration is "
           "tool_jacobian(q) @ qdd + tool_bias(q, qd).");

  // dynamics
  R.def("mass_matrix", [](const Robot& r, const py::object& q) {
         At at(r, q, false);
         MatN M;
         r.mass_matrix(at.q.data(), at.ws, M);
         return checked(M, "mass_matrix");
       }, py::arg("q"), "Inertia matrix M(q) (n, n).")
      .def("gravity", [](const Robot& r, const py::object& q) {
         At at(r, q, false);
         VecN g;
         r.gravity(at.q.data(), at.ws, g);
         return checked(g, "gravity");
       }, py::arg("q"), "Gravity vector G(q) (n,) in N m or N.")
      .def("coriolis", [](const Robot& r, const py::object& q, const py::object& qd) {
         At at(r, q, false);
         VecN c;
         r.coriolis_vector(at.q.data(), vec(qd, r.dof(), "qd").data(), at.ws, c);
         return checked(c, "coriolis");
       }, py::arg("q"), py::arg("qd"), "Coriolis and centrifugal vector C(q, qd) (n,) = coriolis_matrix @ qd.")
      .def("coriolis_matrix", [](const Robot& r, const py::object& q, const py::object& qd) {
         At at(r, q, false);
         MatN C;
         r.coriolis_matrix(at.q.data(), vec(qd, r.dof(), "qd").data(), at.ws, C);
         return checked(C, "coriolis_matrix");
       }, py::arg("q"), py::arg("qd"), "Coriolis matrix (n, n) in Christoffel form; Mdot - 2 C is skew.")
      .def("mass_matrix_derivatives", [](const Robot& r, const py::object& q) {
         At at(r, q, false);
         std::vector<MatN> dM;
         r.mass_matrix_derivatives(at.q.data(), at.ws, dM);
         const int n = r.dof();
         py::array_t<double> out({n, n, n});
         for (int k = 0; k < n; ++k) {
           if (!dM[k].allFinite())
             throw py::value_error("mass_matrix_derivatives: result is not finite for this input (values out of range?)");
           Eigen::Map<Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(out.mutable_data() + k * n * n, n, n) = dM[k];
         }
         return out;
       }, py::arg("q"), "dM/dq (n, n, n); [k] is the derivative with respect to q_k.")
      .def("friction", [](const Robot& r, const py::object& qd) {
         const VecN v = vec(qd, r.dof(), "qd");
         VecN t;
         r.friction_torques(v.data(), t);
         return checked(t, "friction");
       }, py::arg("qd"), "Friction torques (n,): viscous and Coulomb, K qd + F_c tanh(qd / v_c) (N m or N).")
      .def("external_torques", [](const Robot& r, const py::object& q, const py::object& f_ext) {
         At at(r, q);
         VecN t;
         r.external_torques(wrenches_arg(f_ext, "f_ext"), at.ws, t);
         return checked(t, "external_torques");
       }, py::arg("q"), py::arg("f_ext"),
       "Joint torques J^T F (n,) of f_ext: a (6,) wrench [f; m] (world, N and N m) at the tool centre point, "
       "or a Wrench or list of Wrench on any point of any link.")
      .def("inverse_dynamics", [](const Robot& r, const py::object& q, const py::object& qd, const py::object& qdd,
                                  const py::object& f_ext) {
         At at(r, q, false);
         const VecN te = at.external(r, f_ext), qdv = vec(qd, r.dof(), "qd"), qddv = vec(qdd, r.dof(), "qdd");
         VecN tau;
         r.inverse_dynamics(at.q.data(), qdv.data(), qddv.data(), f_ext.is_none() ? nullptr : te.data(), at.ws, tau);
         return checked(tau, "inverse_dynamics");
       }, py::arg("q"), py::arg("qd"), py::arg("qdd"), py::arg("f_ext") = py::none(),
       "Eq. (1): tau (n,) with tau + J^T F = M qdd + C + G + friction(qd) (M with the armature).")
      .def("forward_dynamics", [](const Robot& r, const py::object& q, const py::object& qd, const py::object& tau,
                                  const py::object& f_ext) {
         At at(r, q, false);
         const VecN te = at.external(r, f_ext), qdv = vec(qd, r.dof(), "qd"), tv = vec(tau, r.dof(), "tau");
         VecN qdd;
         r.forward_dynamics(at.q.data(), qdv.data(), tv.data(), f_ext.is_none() ? nullptr : te.data(), at.ws, qdd);
         return checked(qdd, "forward_dynamics");
       }, py::arg("q"), py::arg("qd"), py::arg("tau"), py::arg("f_ext") = py::none(),
       "Eq. (2): qdd (n,) = M^-1 (tau + J^T F - C - G - friction(qd)), solved by Cholesky (M with the "
       "armature); ValueError naming q where M is not positive definite.")
      .def("end_stop_torques", [](const Robot& r, const py::object& q, const py::object& qd) {
         At at(r, q, false);
         MatN M;
         r.mass_matrix(at.q.data(), at.ws, M);
         VecN t;
         r.end_stop_torques(at.q.data(), vec(qd, r.dof(), "qd").data(), M, t);
         return checked(t, "end_stop_torques");
       }, py::arg("q"), py::arg("qd"), "Soft end-stop torques (n,) beyond the joint limits.")
      .def("energy", [](const Robot& r, const py::object& q, const py::object& qd) {
         At at(r, q, false);
         const double T = r.kinetic_energy(at.q.data(), vec(qd, r.dof(), "qd").data(), at.ws);
         const double V = r.potential_energy(at.q.data(), at.ws);
         if (!std::isfinite(T) || !std::isfinite(V))
           throw py::value_error("energy: result is not finite for this input (values out of range?)");
         return py::make_tuple(T, V);
       }, py::arg("q"), py::arg("qd"), "(kinetic, potential) energy in J; potential relative to z = 0.")
      .def("__repr__", [](const Robot& r) {
         return "<coopsim.Robot '" + r.name() + "' " + r.joint_types() + ", " + std::to_string(r.dof()) +
                " dof, backend=" + r.backend() + ">";
       })
      .def(py::pickle(
          [](const Robot& r) {  // from_dh's arguments, in its order, the dynamics backend, the names
            const RobotTables t = r.tables();
            return py::make_tuple(
                py::make_tuple(to_numpy(t.dh), to_numpy(t.com), to_numpy(t.masses), to_numpy(t.inertias),
                               t.joint_types, to_numpy(t.friction), to_numpy(t.q_limits), to_numpy(t.tau_limits),
                               to_numpy(t.gravity), to_numpy(t.base_position), t.base_yaw, t.tool, t.name,
                               t.end_stop.frequency, t.end_stop.damping_ratio, t.boxes,
                               t.clamp.present() ? py::cast(t.clamp) : py::none(), t.dimensions,
                               to_numpy(t.armature), to_numpy(t.coulomb), to_numpy(t.coulomb_width),
                               to_numpy(t.base_orientation), t.inertia_check),
                r.backend(), r.has_generated() ? r.generated()->name : std::string(), r.joint_names(),
                r.link_names());
          },
          [](const py::tuple& t) {
            Robot r = py::type::of<Robot>().attr("from_dh")(*t[0]).cast<Robot>().with_names(
                t[3].cast<std::vector<std::string>>(), t[4].cast<std::vector<std::string>>());
            const std::string gen = t[2].cast<std::string>();
            if (gen.empty()) return r;
            if (!find_generated(gen))
              throw py::value_error("cannot unpickle: generated dynamics '" + gen + "' not in this build");
            return r.with_generated(gen).with_backend(t[1].cast<std::string>());
          }));

  m.attr("InertiaWarning") = inertia_warning_category();
  m.def("compiled_generated_names", &compiled_generated_names,
        "Names of the robots whose generated dynamics are compiled into this build.");
}
