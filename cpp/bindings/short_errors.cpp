// Short TypeErrors for calls with arguments of the wrong type.
//
// When no overload of a bound function accepts its arguments, pybind11's dispatcher raises a TypeError
// listing every signature and repeating the call. short_type_errors() points every function of the module
// (module-level functions, methods, static methods, constructors, property accessors) at a dispatcher that
// calls pybind11's own and, only when that fails with its TypeError, asks coopsim._arguments for one line
// naming the argument and the type expected, read from the signature pybind11 built. A call that succeeds
// pays one direct C call and a null test.
#include <pybind11/pybind11.h>

#include <cstdlib>
#include <string>

namespace py = pybind11;

namespace {

struct Dispatch : py::cpp_function {  // pybind11's dispatcher is a protected member
  using py::cpp_function::dispatcher;
};
// called through a volatile pointer: pybind11's own dispatcher runs, not a copy inlined here (which the
// optimiser would lay out differently, making calls a little faster or slower than without this file)
PyObject* (*volatile pybind11_dispatcher)(PyObject*, PyObject* const*, size_t, PyObject*) = &Dispatch::dispatcher;
std::string package;  // "coopsim": its _arguments module writes the message

// Called with pybind11's error set: replaces it by the short message, when there is one.
void shorten(PyObject* self, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  const py::detail::function_record* rec = py::detail::function_record_ptr_from_PyObject(self);
  if (!rec || rec->next || !PyErr_ExceptionMatches(PyExc_TypeError)) return;  // overloads: no one argument
  py::error_already_set error;  // takes the error out
  try {
    const size_t n = PyVectorcall_NARGS(nargsf);
    py::tuple given(n);
    for (size_t i = 0; i < n; ++i) given[i] = py::reinterpret_borrow<py::object>(args[i]);
    py::dict keywords;
    for (Py_ssize_t k = 0; kwnames && k < PyTuple_GET_SIZE(kwnames); ++k)
      keywords[PyTuple_GET_ITEM(kwnames, k)] = py::reinterpret_borrow<py::object>(args[n + static_cast<size_t>(k)]);
    py::list convert;
    for (const auto& a : rec->args) convert.append(py::bool_(a.convert));
    const bool in_class = rec->scope && PyType_Check(rec->scope.ptr());
    py::object scope = in_class ? py::object(rec->scope.attr("__name__")) : py::object(py::none());
    py::object message = py::module_::import((package + "._arguments").c_str())
                             .attr("short_type_error")(py::str(error.value()), rec->name, rec->signature,
                                                       scope,
                                                       rec->is_constructor, rec->is_setter, convert, given, keywords);
    if (!message.is_none()) {
      PyErr_SetObject(PyExc_TypeError, message.ptr());
      return;
    }
  } catch (...) {  // (a Python error in the message's making) the long message stands
    PyErr_Clear();
  }
  error.restore();
}

PyObject* dispatcher(PyObject* self, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  PyObject* result = pybind11_dispatcher(self, args, nargsf, kwnames);
  if (!result) shorten(self, args, nargsf, kwnames);
  return result;
}

// Points a function object of pybind11 at the dispatcher above.
void redirect(PyObject* function) {
  if (!function || !PyCFunction_Check(function)) return;
  PyMethodDef* def = reinterpret_cast<PyCFunctionObject*>(function)->m_ml;
  if (def->ml_meth == reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(pybind11_dispatcher)) &&
      py::detail::function_record_ptr_from_PyObject(PyCFunction_GET_SELF(function)))
    def->ml_meth = reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(&dispatcher));
}

void redirect_all(PyObject* dict) {
  PyObject *key, *value;
  Py_ssize_t pos = 0;
  while (PyDict_Next(dict, &pos, &key, &value)) {
    if (PyInstanceMethod_Check(value)) {
      redirect(PyInstanceMethod_GET_FUNCTION(value));
    } else if (PyType_Check(value)) {
      auto* type = reinterpret_cast<PyTypeObject*>(value);
      if (py::detail::get_type_info(type) && type->tp_dict != dict) redirect_all(type->tp_dict);  // a bound class
    } else if (PyObject_TypeCheck(value, &PyStaticMethod_Type) || PyObject_TypeCheck(value, &PyProperty_Type)) {
      for (const char* a : {"__func__", "fget", "fset"}) {
        py::object f = py::getattr(value, a, py::none());
        redirect(f.ptr());
      }
    } else {
      redirect(value);
    }
  }
}

}  // namespace

void short_type_errors(py::module_& m) {
  // COOPSIM_PYBIND11_ERRORS=1 keeps pybind11's own messages (every signature, the call repeated) and its
  // dispatcher: for debugging the bindings, and to measure what this one costs (benchmarks/bench_dynamics.py)
  const char* keep = std::getenv("COOPSIM_PYBIND11_ERRORS");
  if (keep && *keep && std::string(keep) != "0") return;
  const std::string name = py::str(m.attr("__name__"));
  package = name.substr(0, name.rfind('.'));
  redirect_all(PyModule_GetDict(m.ptr()));
}
