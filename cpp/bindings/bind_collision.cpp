// Bullet collision world.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "convert.hpp"
#include "coopsim/collision.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;

void bind_collision(py::module_& m) {
  py::class_<Contact>(m, "Contact", "A contact point between shapes a and b (ids); normal points from b to a; "
                                    "depth < 0 is penetration (m).")
      .def_readonly("a", &Contact::a)
      .def_readonly("b", &Contact::b)
      .def_property_readonly("point_a", [](const Contact& c) { return to_numpy(c.point_a); })
      .def_property_readonly("point_b", [](const Contact& c) { return to_numpy(c.point_b); })
      .def_property_readonly("normal", [](const Contact& c) { return to_numpy(c.normal); })
      .def_readonly("depth", &Contact::depth)
      .def("__repr__", [](const Contact& c) {
        return "<Contact " + std::to_string(c.a) + "-" + std::to_string(c.b) + " depth=" + std::to_string(c.depth) + ">";
      });
  py::class_<CollisionWorld>(m, "CollisionWorld", "Shapes in the world, checked for contact by Bullet.")
      .def(py::init<>())
      .def("add_box", [](CollisionWorld& w, const py::object& half_extents, const py::object& pose_, const std::string& name) {
             return w.add_box(vecx(half_extents, 3, "half_extents"), pose(pose_, "pose"), name);
           }, py::arg("half_extents"), py::arg("pose"), py::arg("name") = "",
           "Adds a box with half extents (3,) m at pose (4, 4); returns its id.")
      .def("add_sphere", [](CollisionWorld& w, double radius, const py::object& pose_, const std::string& name) {
             return w.add_sphere(radius, pose(pose_, "pose"), name);
           }, py::arg("radius"), py::arg("pose"), py::arg("name") = "", "Adds a sphere; returns its id.")
      .def("set_pose", [](CollisionWorld& w, int id, const py::object& p) { w.set_pose(id, pose(p, "pose")); },
           py::arg("id"), py::arg("pose"))
      .def("pose", [](const CollisionWorld& w, int id) { return to_numpy(w.pose(id)); }, py::arg("id"))
      .def("name", &CollisionWorld::name, py::arg("id"))
      .def("__len__", &CollisionWorld::size)
      .def("contacts", &CollisionWorld::contacts,
           "Contact points (list of Contact) of all pairs of touching or penetrating shapes.");
}
