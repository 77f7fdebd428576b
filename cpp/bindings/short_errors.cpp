// Short TypeErrors for calls with arguments of the wrong type.
//
// When no overload of a bound function accepts its arguments, pybind11's dispatcher raises a TypeError
// listing every signature and repeating the call. coopsim._arguments (at import) points every function of
// the module at the dispatcher below, which calls pybind11's own and, only when that fails with a
// TypeError, asks _arguments for one line naming the argument and the type expected. A call that succeeds
// pays one more C call and a null test.
#include <pybind11/pybind11.h>

namespace py = pybind11;

// pybind11's dispatcher is a protected member. It is called through a volatile pointer: pybind11's own runs,
// not a copy inlined below (which the optimiser would lay out otherwise, making calls a little faster or slower)
struct Dispatch : py::cpp_function { using py::cpp_function::dispatcher; };
static PyObject* (*volatile pybind11_dispatcher)(PyObject*, PyObject* const*, size_t, PyObject*) = &Dispatch::dispatcher;
static PyObject* message_of = nullptr;  // coopsim._arguments.short_type_error, for the interpreter's life

static PyObject* dispatcher(PyObject* self, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  PyObject* result = pybind11_dispatcher(self, args, nargsf, kwnames);
  if (result || !PyErr_ExceptionMatches(PyExc_TypeError)) return result;
  PyObject *type, *value, *traceback;
  PyErr_Fetch(&type, &value, &traceback);
  const Py_ssize_t n = PyVectorcall_NARGS(nargsf), all = n + (kwnames ? PyTuple_GET_SIZE(kwnames) : 0);
  PyObject* given = PyTuple_New(all);  // positional arguments, then the keywords' values
  for (Py_ssize_t i = 0; given && i < all; ++i) PyTuple_SET_ITEM(given, i, Py_NewRef(args[i]));
  PyObject* message = given ? PyObject_CallFunction(message_of, "OOOnO", value ? value : Py_None, self, given, n,
                                                    kwnames ? kwnames : Py_None)
                            : nullptr;
  Py_XDECREF(given);
  PyErr_Restore(type, value, traceback);  // pybind11's error, which stands unless there is a short message
  if (message && PyUnicode_Check(message)) PyErr_SetObject(PyExc_TypeError, message);
  Py_XDECREF(message);
  return nullptr;
}

void short_type_errors(py::module_& m) {
  m.def("_short_type_errors", [](py::object short_type_error, py::object function) {
    if (!message_of) message_of = short_type_error.release().ptr();  // kept: the functions call it
    PyObject* f = function.ptr();
    if (!PyCFunction_Check(f) || !py::detail::function_record_ptr_from_PyObject(PyCFunction_GET_SELF(f))) return false;
    PyMethodDef* def = reinterpret_cast<PyCFunctionObject*>(f)->m_ml;
    const auto ours = reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(&dispatcher));
    if (def->ml_meth == reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(pybind11_dispatcher)))
      def->ml_meth = ours;
    return def->ml_meth == ours;
  }, "Points a compiled function at the dispatcher whose TypeErrors short_type_error shortens (coopsim._arguments).");
}
