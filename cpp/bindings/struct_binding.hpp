// An engine struct bound once as a read-only Python class: each field named once, with its
// docstring (cpp/bindings/generated/docstrings.hpp, from the headers' comments), numpy out for
// Eigen members, a __repr__, and a deprecated mapping view (x["force"] warns "use .force") for
// callers of the dict the struct replaced. The names of a class's fields are its `fields` tuple.
#pragma once

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "convert.hpp"

namespace coopsim::py_struct {

namespace py = pybind11;

// A field's value for Python: numpy arrays (copies) for Eigen members, else pybind11's cast.
template <class V>
py::object out(const V& v) {
  if constexpr (std::is_same_v<V, Eigen::Isometry3d>) {
    return py_convert::to_numpy(v);
  } else if constexpr (std::is_base_of_v<Eigen::EigenBase<V>, V>) {
    return py_convert::to_numpy(v);
  } else if constexpr (std::is_base_of_v<py::handle, V>) {
    return py::reinterpret_borrow<py::object>(v);
  } else {
    return py::cast(v);
  }
}

// The mapping view of a bound struct (deprecated: its attributes are the interface).
inline void warn_mapping(const py::handle& self, const std::string& key) {
  const std::string type = py::str(py::type::of(self).attr("__name__"));
  const std::string text = key.empty()
                               ? type + " is no longer a dict: read its attributes (" + type + ".fields names them)"
                               : type + "[\"" + key + "\"] is deprecated: use ." + key;
  if (PyErr_WarnEx(PyExc_DeprecationWarning, text.c_str(), 2) != 0) throw py::error_already_set();
}

template <class T, class... Options>
class Struct {
 public:
  Struct(py::handle scope, const char* name, const char* doc)
      : cls_(scope, name, doc), names_(std::make_shared<std::vector<std::string>>()) {}

  // A field computed from the struct by `get` (a member's value, or a value derived from them).
  template <class Get>
  Struct& field(const char* name, Get get, const char* doc) {
    cls_.def_property_readonly(name, [get](const T& self) { return out(get(self)); }, doc);
    names_->push_back(name);
    return *this;
  }
  // A data member, read-only.
  template <class M>
  Struct& member(const char* name, M T::*m, const char* doc) {
    return field(name, [m](const T& self) -> const M& { return self.*m; }, doc);
  }
  py::class_<T, Options...>& cls() { return cls_; }

  // The fields tuple, __repr__ and the deprecated mapping view; call once, after the fields.
  py::class_<T, Options...>& finish() {
    auto names = names_;
    cls_.attr("fields") = py::tuple(py::cast(*names));
    cls_.def("__repr__", [names](const py::object& self) {
      std::string s = py::str(py::type::of(self).attr("__name__"));
      s += "(";
      for (size_t i = 0; i < names->size(); ++i) {
        if (i) s += ", ";
        s += (*names)[i] + "=" + std::string(py::repr(self.attr((*names)[i].c_str())));
      }
      return s + ")";
    });
    cls_.def("__eq__", [names](const py::object& self, const py::object& other) -> py::object {
      py::object array_equal = py::module_::import("numpy").attr("array_equal");
      if (py::isinstance<py::dict>(other)) {  // the dict it replaced: deprecated, compared by its items
        warn_mapping(self, "");
        const py::dict d = other.cast<py::dict>();
        if (d.size() != names->size()) return py::bool_(false);
        for (const std::string& n : *names)
          if (!d.contains(n) || !array_equal(self.attr(n.c_str()), d[py::str(n)]).cast<bool>()) return py::bool_(false);
        return py::bool_(true);
      }
      if (!py::type::of(self).is(py::type::of(other))) return py::reinterpret_borrow<py::object>(Py_NotImplemented);
      for (const std::string& n : *names)
        if (!array_equal(self.attr(n.c_str()), other.attr(n.c_str())).cast<bool>()) return py::bool_(false);
      return py::bool_(true);
    }, py::arg("other"), py::is_operator());
    cls_.attr("__hash__") = py::none();
    cls_.def("__getitem__", [names](const py::object& self, const std::string& key) {
      for (const std::string& n : *names)
        if (n == key) {
          warn_mapping(self, key);
          return self.attr(key.c_str());
        }
      throw py::key_error(key);
    }, py::arg("key"), "Deprecated: the field `key` (use the attribute).");
    cls_.def("keys", [names](const py::object& self) {
      warn_mapping(self, "");
      return py::list(py::cast(*names));
    }, "Deprecated: the fields' names (see `fields`).");
    // not iterable: code that iterated the dict it replaced (pandas.DataFrame({...: x}), for k in x)
    // would silently get the fields' names; it is told what to use instead
    cls_.def("__iter__", [](const py::object& self) -> py::object {
      const std::string type = py::str(py::type::of(self).attr("__name__"));
      throw py::type_error(type + " is no longer a dict and is not iterable: use .asdict() for {name: value}, or its "
                           "attributes (" + type + ".fields names them)");
    });
    cls_.def("__len__", [names](const py::object&) { return names->size(); });
    cls_.def("__contains__", [names](const py::object&, const py::object& key) {
      for (const std::string& n : *names)
        if (py::str(n).equal(key)) return true;
      return false;
    });
    cls_.def("asdict", [names](const py::object& self) {
      py::dict d;
      for (const std::string& n : *names) d[py::str(n)] = self.attr(n.c_str());
      return d;
    }, "The fields as a dict {name: value} (for tables: pandas.DataFrame of these).");
    return cls_;
  }

 private:
  py::class_<T, Options...> cls_;
  std::shared_ptr<std::vector<std::string>> names_;
};

}  // namespace coopsim::py_struct
