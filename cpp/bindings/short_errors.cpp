// Short TypeErrors for calls with arguments of the wrong type.
//
// When no overload of a bound function accepts its arguments, pybind11's dispatcher raises a
// TypeError listing every signature and repeating the call ("incompatible function arguments ...
// Invoked with: ..."). short_type_errors() points every function of the module (module-level
// functions, methods, static methods, constructors, property accessors) at a dispatcher that calls
// pybind11's own and, only when it returns that error, rewrites it as one line naming the argument
// and the type expected, e.g. "advance(): n must be an int, got str '3'". The names and types come
// from the function's signature as pybind11 built it; whether a value fits a scalar type is asked
// of pybind11's own type casters. A call that succeeds pays one direct C call and a null test.
#include <pybind11/pybind11.h>

#include <cstring>
#include <string>
#include <vector>

namespace py = pybind11;

namespace {

// pybind11's dispatcher is a protected member of cpp_function.
struct Dispatch : py::cpp_function {
  using py::cpp_function::dispatcher;
};
using Vectorcall = PyObject* (*)(PyObject*, PyObject* const*, size_t, PyObject*);
const Vectorcall pybind11_dispatcher = &Dispatch::dispatcher;

PyObject* core_module = nullptr;  // this module (a strong reference for the interpreter's life)
std::string core_name;            // its __name__, the prefix of its classes in signatures

struct Param {
  std::string name, annotation;
  bool has_default = false, keyword_only = false, positional_only = false;
};

struct Signature {
  std::vector<Param> params;
  bool var_args = false, var_kwargs = false;
};

// The parts of `text` separated by `sep` outside brackets and quotes.
std::vector<std::string> split_top(const std::string& text, const std::string& sep) {
  std::vector<std::string> out;
  int depth = 0;
  char quote = 0;
  size_t start = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quote) {
      if (c == '\\') ++i;
      else if (c == quote) quote = 0;
    } else if (c == '\'' || c == '"') {
      quote = c;
    } else if (c == '(' || c == '[' || c == '{') {
      ++depth;
    } else if (c == ')' || c == ']' || c == '}') {
      --depth;
    } else if (depth == 0 && text.compare(i, sep.size(), sep) == 0) {
      out.push_back(text.substr(start, i - start));
      start = i + sep.size();
      i = start - 1;
    }
  }
  out.push_back(text.substr(start));
  return out;
}

std::string strip(const std::string& s) {
  const size_t a = s.find_first_not_of(' '), b = s.find_last_not_of(' ');
  return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

// "(self: m.Robot, q: object, link: typing.SupportsInt | typing.SupportsIndex = -1, *, x: str = 'a') -> T"
Signature parse(const char* signature) {
  Signature sig;
  const std::string text(signature ? signature : "");
  if (text.empty() || text[0] != '(') return sig;
  // the parameters: up to the parenthesis that closes the first one (the return type follows)
  int depth = 0;
  char quote = 0;
  size_t close = std::string::npos;
  for (size_t i = 0; i < text.size() && close == std::string::npos; ++i) {
    const char c = text[i];
    if (quote) {
      if (c == '\\') ++i;
      else if (c == quote) quote = 0;
    } else if (c == '\'' || c == '"') {
      quote = c;
    } else if (c == '(' || c == '[' || c == '{') {
      ++depth;
    } else if ((c == ')' || c == ']' || c == '}') && --depth == 0) {
      close = i;
    }
  }
  if (close == std::string::npos) return sig;
  const std::string inside = strip(text.substr(1, close - 1));
  if (inside.empty()) return sig;
  bool keyword_only = false;
  for (const std::string& raw : split_top(inside, ",")) {
    const std::string p = strip(raw);
    if (p == "/") {
      for (Param& q : sig.params) q.positional_only = true;
      continue;
    }
    if (p == "*") {
      keyword_only = true;
      continue;
    }
    if (p.rfind("**", 0) == 0) {
      sig.var_kwargs = true;
      continue;
    }
    if (p[0] == '*') {
      sig.var_args = keyword_only = true;
      continue;
    }
    Param param;
    const std::vector<std::string> with_default = split_top(p, " = ");
    param.has_default = with_default.size() > 1;
    const std::string decl = with_default[0];
    const size_t colon = decl.find(':');
    param.name = strip(decl.substr(0, colon));
    if (colon != std::string::npos) param.annotation = strip(decl.substr(colon + 1));
    param.keyword_only = keyword_only;
    sig.params.push_back(param);
  }
  return sig;
}

// A type's name without its module ("str", "ndarray", "Robot").
std::string class_name(PyObject* cls) {
  const std::string full = reinterpret_cast<PyTypeObject*>(cls)->tp_name;
  return full.substr(full.rfind('.') + 1);
}

std::string type_name(PyObject* value) { return class_name(reinterpret_cast<PyObject*>(Py_TYPE(value))); }

std::string short_repr(PyObject* value) {
  std::string r;
  try {
    r = py::repr(value);
  } catch (const py::error_already_set&) {
    return "";
  }
  if (r.size() > 40) r = r.substr(0, 37) + "...";
  return " " + r;
}

// The class of this module an annotation names ("coopsim._core.Robot"), or null.
PyObject* module_class(const std::string& annotation) {
  if (!core_module || annotation.size() <= core_name.size() + 1 || annotation.compare(0, core_name.size(), core_name) ||
      annotation[core_name.size()] != '.')
    return nullptr;
  PyObject* cls = PyObject_GetAttrString(core_module, annotation.c_str() + core_name.size() + 1);
  if (!cls) {
    PyErr_Clear();
    return nullptr;
  }
  Py_DECREF(cls);  // the module keeps it alive
  return PyType_Check(cls) ? cls : nullptr;
}

template <typename T>
bool loads(PyObject* value, bool convert) {
  py::detail::make_caster<T> caster;
  const bool ok = caster.load(py::handle(value), convert);
  PyErr_Clear();
  return ok;
}

// What is wrong with `value` for a parameter annotated `annotation` ("must be a float, got str 'x'"),
// or "" when the annotation is not one judged here (arrays, objects) or the value fits it.
std::string misfit(const std::string& annotation, PyObject* value, bool convert) {
  std::vector<std::string> kinds;  // "a float", ... one per alternative of the annotation
  bool fits = false, none_ok = false, out_of_range = false;
  for (const std::string& raw : split_top(annotation, " | ")) {
    const std::string alt = strip(raw);
    if (alt == "None") {
      none_ok = true;
      fits = fits || value == Py_None;
      continue;
    }
    if (alt == "typing.SupportsIndex") continue;  // the second half of an int's or a float's annotation
    std::string kind;
    bool ok = false;
    if (alt == "typing.SupportsFloat" || alt == "float") {
      kind = "a float";
      ok = loads<double>(value, convert);
      out_of_range = out_of_range || (!ok && PyLong_Check(value));
    } else if (alt == "typing.SupportsInt" || alt == "int") {
      kind = "an int";
      ok = loads<long long>(value, convert);
      out_of_range = out_of_range || (!ok && PyIndex_Check(value) && !PyFloat_Check(value));
    } else if (alt == "bool") {
      kind = "a bool";
      ok = loads<bool>(value, convert);
    } else if (alt == "str") {
      kind = "a str";
      ok = loads<std::string>(value, convert);
    } else if (PyObject* cls = module_class(alt)) {
      kind = "a " + class_name(cls);
      const int is = PyObject_IsInstance(value, cls);
      if (is < 0) PyErr_Clear();
      ok = is == 1 || value == Py_None;  // None: the binding itself says whether it takes None
    } else {
      return "";
    }
    kinds.push_back(kind);
    fits = fits || ok;
  }
  if (fits || kinds.empty()) return "";
  if (out_of_range) return "is out of range, got " + type_name(value) + short_repr(value);
  std::string expected = kinds[0];
  for (size_t i = 1; i < kinds.size(); ++i) expected += (i + 1 == kinds.size() && !none_ok ? " or " : ", ") + kinds[i];
  if (none_ok) expected += " or None";
  return "must be " + expected + ", got " + type_name(value) + short_repr(value);
}

std::string join_names(const Signature& sig, size_t first) {
  std::string names;
  for (size_t i = first; i < sig.params.size(); ++i) names += (names.empty() ? "" : ", ") + sig.params[i].name;
  return names.empty() ? "none" : names;
}

// The package's Python code that called the function, when it did for a user's call: the innermost
// caller in the package (its folder) that is public and takes a parameter named `argument`, e.g.
// "Simulation.step" for sim.step("3"), which calls SimulationCore.advance(n); "" for none.
std::string package_caller(const std::string& argument) {
  std::string found;
  try {
    const std::string folder = py::str(py::module_::import("os.path").attr("dirname")(
                                   py::reinterpret_borrow<py::object>(core_module).attr("__file__"))).cast<std::string>() + "/";
    PyFrameObject* frame = PyEval_GetFrame();
    Py_XINCREF(frame);
    while (frame && found.empty()) {
      py::object code = py::reinterpret_steal<py::object>(reinterpret_cast<PyObject*>(PyFrame_GetCode(frame)));
      const std::string file = py::str(code.attr("co_filename"));
      if (file.compare(0, folder.size(), folder) != 0) break;  // out of the package: the user's code
      const std::string qualname = py::str(code.attr("co_qualname"));
      const std::string last = qualname.substr(qualname.rfind('.') + 1);
      const size_t n = code.attr("co_argcount").cast<size_t>() + code.attr("co_kwonlyargcount").cast<size_t>();
      const py::tuple names = code.attr("co_varnames");
      bool takes = false;
      for (size_t i = 0; i < n && i < names.size(); ++i) takes = takes || py::str(names[i]).cast<std::string>() == argument;
      if (takes && qualname.find('<') == std::string::npos && (last[0] != '_' || last == "__init__"))
        found = last == "__init__" ? qualname.substr(0, qualname.size() - 9) : qualname;
      PyFrameObject* back = PyFrame_GetBack(frame);
      Py_DECREF(frame);
      frame = back;
    }
    Py_XDECREF(frame);
  } catch (const py::error_already_set&) {
    PyErr_Clear();
    return "";
  }
  return found;
}

// The one-line message for a call of `rec` (no overloads) with these arguments, or "" when no
// argument can be blamed (the long message then stands).
std::string short_message(const py::detail::function_record* rec, PyObject* const* args, size_t nargs,
                          PyObject* kwnames) {
  const Signature sig = parse(rec->signature);
  std::string name = rec->name;
  // a constructor by its class's name, a method as Class.method
  const bool in_class = rec->scope && PyType_Check(rec->scope.ptr());
  if (rec->is_constructor && in_class) name = class_name(rec->scope.ptr());
  else if (in_class) name = class_name(rec->scope.ptr()) + "." + name;
  const std::string where = name + "(): ";
  // a method's self is its first argument; it is neither counted nor named
  const size_t skip = (rec->is_method && !sig.params.empty() && sig.params[0].name == "self") ? 1 : 0;
  std::vector<PyObject*> given(sig.params.size(), nullptr);
  size_t positional = 0;
  while (positional < sig.params.size() && !sig.params[positional].keyword_only) ++positional;
  if (nargs > positional && !sig.var_args)
    return where + "takes " + std::to_string(positional - skip) + " positional argument" +
           (positional - skip == 1 ? "" : "s") + ", got " + std::to_string(nargs - skip);
  for (size_t i = 0; i < nargs && i < positional; ++i) given[i] = args[i];
  const Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
  for (Py_ssize_t k = 0; k < nkw; ++k) {
    const char* key = PyUnicode_AsUTF8(PyTuple_GET_ITEM(kwnames, k));
    if (!key) {
      PyErr_Clear();
      return "";
    }
    size_t i = skip;
    while (i < sig.params.size() && (sig.params[i].name != key || sig.params[i].positional_only)) ++i;
    if (i == sig.params.size()) {
      if (sig.var_kwargs) continue;
      return where + "no argument named " + key + " (its arguments: " + join_names(sig, skip) + ")";
    }
    if (given[i]) return where + "got two values for " + key;
    given[i] = args[nargs + static_cast<size_t>(k)];
  }
  for (size_t i = skip; i < sig.params.size(); ++i)
    if (!given[i] && !sig.params[i].has_default) return where + "missing argument " + sig.params[i].name;
  for (size_t i = skip; i < sig.params.size(); ++i) {
    if (!given[i]) continue;
    const bool convert = i < rec->args.size() ? rec->args[i].convert : true;
    const std::string what = misfit(sig.params[i].annotation, given[i], convert);
    if (what.empty()) continue;
    if (rec->is_setter) return name + " " + what;  // obj.prop = value
    const std::string caller = package_caller(sig.params[i].name);
    return (caller.empty() ? where : caller + "(): ") + sig.params[i].name + " " + what;
  }
  return "";
}

// Called with pybind11's TypeError set: replaces it by the short message when there is one.
void shorten(PyObject* self, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  const py::detail::function_record* rec = py::detail::function_record_ptr_from_PyObject(self);
  if (!rec || rec->next || !PyErr_ExceptionMatches(PyExc_TypeError)) return;  // overloads: no one argument to blame
  PyObject *type, *value, *traceback;
  PyErr_Fetch(&type, &value, &traceback);
  std::string message;
  try {
    PyObject* text = value ? PyObject_Str(value) : nullptr;
    const char* utf8 = text ? PyUnicode_AsUTF8(text) : nullptr;
    // only the dispatcher's own error: a TypeError raised inside the function passes unchanged
    const std::string own = std::string(rec->name) + "(): incompatible ";
    if (utf8 && std::strncmp(utf8, own.c_str(), own.size()) == 0)
      message = short_message(rec, args, PyVectorcall_NARGS(nargsf), kwnames);
    Py_XDECREF(text);
  } catch (...) {
    message.clear();
  }
  PyErr_Clear();
  if (message.empty()) {
    PyErr_Restore(type, value, traceback);
    return;
  }
  Py_XDECREF(type);
  Py_XDECREF(value);
  Py_XDECREF(traceback);
  PyErr_SetString(PyExc_TypeError, message.c_str());
}

PyObject* dispatcher(PyObject* self, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  PyObject* result = pybind11_dispatcher(self, args, nargsf, kwnames);
  if (!result) shorten(self, args, nargsf, kwnames);
  return result;
}

// Points a function object of pybind11 at the dispatcher above (once).
void redirect(PyObject* function) {
  if (!function || !PyCFunction_Check(function)) return;
  PyMethodDef* def = reinterpret_cast<PyCFunctionObject*>(function)->m_ml;
  if (def->ml_meth != reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(pybind11_dispatcher))) return;
  if (!py::detail::function_record_ptr_from_PyObject(PyCFunction_GET_SELF(function))) return;
  def->ml_meth = reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(&dispatcher));
}

void redirect_attribute(PyObject* owner, const char* attribute) {
  PyObject* f = PyObject_GetAttrString(owner, attribute);
  if (!f) {
    PyErr_Clear();
    return;
  }
  redirect(f);
  Py_DECREF(f);
}

void redirect_class(PyObject* cls, std::vector<PyObject*>& seen) {
  for (PyObject* s : seen)
    if (s == cls) return;
  seen.push_back(cls);
  PyObject* dict = reinterpret_cast<PyTypeObject*>(cls)->tp_dict;
  PyObject *key, *value;
  Py_ssize_t pos = 0;
  while (PyDict_Next(dict, &pos, &key, &value)) {
    if (PyInstanceMethod_Check(value)) redirect(PyInstanceMethod_GET_FUNCTION(value));
    else if (PyCFunction_Check(value)) redirect(value);
    else if (PyObject_TypeCheck(value, &PyStaticMethod_Type) || PyObject_TypeCheck(value, &PyProperty_Type)) {
      for (const char* a : {"__func__", "fget", "fset"}) redirect_attribute(value, a);
    } else if (PyType_Check(value)) {
      redirect_class(value, seen);
    }
  }
}

}  // namespace

void short_type_errors(py::module_& m) {
  core_module = m.inc_ref().ptr();
  core_name = py::str(m.attr("__name__"));
  std::vector<PyObject*> seen;
  PyObject *key, *value;
  Py_ssize_t pos = 0;
  PyObject* dict = PyModule_GetDict(m.ptr());
  while (PyDict_Next(dict, &pos, &key, &value)) {
    if (PyCFunction_Check(value)) redirect(value);
    else if (PyType_Check(value)) redirect_class(value, seen);
  }
}
