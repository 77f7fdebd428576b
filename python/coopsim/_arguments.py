"""Short TypeErrors for calls into the compiled module with arguments of the wrong type.

When no overload of a compiled function accepts its arguments, pybind11 raises a TypeError that lists
every signature and repeats the call. :func:`install` points every function of the compiled module at a
dispatcher of its own (cpp/bindings/short_errors.cpp), which calls pybind11's and, only when that fails
with a TypeError, calls :func:`short_type_error`: its answer, when there is one, replaces the error with
one line naming the argument and the type expected, e.g. ``Simulation.step(): n must be an int, got str
'3'``, read from the signature pybind11 wrote. ``COOPSIM_PYBIND11_ERRORS=1`` keeps pybind11's messages
and dispatcher (to debug the bindings, or to measure what this costs a call).
"""
from __future__ import annotations

import operator
import os
import reprlib
import sys
from typing import List, Optional, Tuple

_SHORT = reprlib.Repr()
_SHORT.maxstring = _SHORT.maxother = 40
_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def _is_float(v, convert: bool) -> bool:
    # pybind11's float caster: a float, or (converting) anything with __float__ or __index__ but a str
    if isinstance(v, float):
        return True
    return convert and not isinstance(v, (str, bytes)) and (hasattr(v, "__float__") or hasattr(v, "__index__"))


def _is_int(v, convert: bool) -> bool:
    # pybind11's integer caster: never a float; an int, or anything with __index__
    return not isinstance(v, float) and hasattr(type(v), "__index__")


def _is_bool(v, convert: bool) -> bool:
    # pybind11's bool caster: True, False, numpy.bool_; converting, None or anything with __bool__ as a number
    if isinstance(v, bool) or type(v).__name__ in ("bool_", "bool"):
        return True
    return convert and (v is None or hasattr(type(v), "__bool__"))      # (str and list have no __bool__)


def _is_str(v, convert: bool) -> bool:
    return isinstance(v, (str, bytes))


#: what each scalar annotation of pybind11's signatures expects, and whether a value is taken as one
_SCALARS = {"typing.SupportsFloat": ("a float", _is_float), "float": ("a float", _is_float),
            "typing.SupportsInt": ("an int", _is_int), "int": ("an int", _is_int),
            "bool": ("a bool", _is_bool), "str": ("a str", _is_str)}


def _split(text: str, sep: str) -> List[str]:
    """The parts of text separated by sep outside brackets and quotes."""
    out, depth, quote, start, i = [], 0, "", 0, 0
    while i < len(text):
        c = text[i]
        if quote:
            i += c == "\\"
            quote = "" if c == quote else quote
        elif c in "'\"":
            quote = c
        elif c in "([{":
            depth += 1
        elif c in ")]}" and not (depth == 0 and text.startswith(sep, i)):
            depth -= 1
        elif depth == 0 and text.startswith(sep, i):
            out.append(text[start:i])
            start = i + len(sep)
            i = start - 1
        i += 1
    out.append(text[start:])
    return out


def _parameters(signature: str) -> Tuple[list, bool, bool]:
    """([(name, annotation, has_default, keyword_only)], *args, **kwargs) of pybind11's '(a: T, b: U = 1) -> R'."""
    # the parameters: up to the parenthesis closing the first one (the part of ")" split at depth -1)
    inside = _split(signature[1:] + ",", ")")[0] if signature.startswith("(") else ""
    params, var_args, var_kwargs, keyword_only = [], False, False, False
    for p in (p.strip() for p in _split(inside, ",") if p.strip()):
        if p == "/":
            continue
        if p == "*" or (p.startswith("*") and not p.startswith("**")):
            var_args = var_args or p != "*"
            keyword_only = True
            continue
        if p.startswith("**"):
            var_kwargs = True
            continue
        decl = _split(p, " = ")
        name, _, annotation = decl[0].partition(":")
        params.append((name.strip(), annotation.strip(), len(decl) > 1, keyword_only))
    return params, var_args, var_kwargs


def _misfit(annotation: str, value, convert: bool) -> Optional[str]:
    """What is wrong with value for a parameter annotated so, or None (it fits, or the type is not a scalar's)."""
    kinds, none_ok = [], False
    for alt in (a.strip() for a in _split(annotation, " | ")):
        if alt == "None":
            none_ok = True
        elif alt != "typing.SupportsIndex":      # the second half of an int's or a float's annotation
            if alt not in _SCALARS:
                return _misfit_class(alt, value)
            kinds.append(_SCALARS[alt])
    if not kinds or (none_ok and value is None):
        return None
    if any(ok(value, convert) for _, ok in kinds):
        # an int too large for the engine's 64 bits (smaller integer types are not known here)
        if _is_int in [ok for _, ok in kinds] and _is_int(value, convert) and \
                not -2 ** 63 <= operator.index(value) < 2 ** 63:
            return f"is out of range, got {type(value).__name__} {_SHORT.repr(value)}"
        return None
    expected = " or ".join([k for k, _ in kinds] + (["None"] if none_ok else []))
    return f"must be {expected}, got {type(value).__name__} {_SHORT.repr(value)}"


def _misfit_class(annotation: str, value) -> Optional[str]:
    # a class of the compiled module, by its qualified name; None is the binding's own to refuse
    module, _, name = annotation.rpartition(".")
    cls = getattr(sys.modules.get(module), name, None)
    if not isinstance(cls, type) or value is None or isinstance(value, cls):
        return None
    return f"must be a {name}, got {type(value).__name__} {_SHORT.repr(value)}"


def _caller(argument: str) -> Optional[str]:
    """The package's own Python function that made the call for the user: the innermost public one in the
    package with a parameter named `argument` (Simulation.step for sim.step('3'), which calls the engine's
    advance(n)), or None."""
    frame = sys._getframe(2)    # above this function and short_type_error: the caller of the compiled function
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        code = frame.f_code
        names = code.co_varnames[:code.co_argcount + code.co_kwonlyargcount]
        last = code.co_qualname.rsplit(".", 1)[-1]
        if argument in names and "<" not in code.co_qualname and (not last.startswith("_") or last == "__init__"):
            return code.co_qualname[:-len(".__init__")] if last == "__init__" else code.co_qualname
        frame = frame.f_back
    return None


#: per compiled function, by the id of its pybind11 record: (the name it is called by, the function, a setter)
_FUNCTIONS: dict = {}


def install(module) -> int:
    """Points every compiled function of `module` (functions, methods, static methods, constructors, property
    accessors) at the dispatcher of short TypeErrors; returns how many (0 with COOPSIM_PYBIND11_ERRORS set)."""
    if os.environ.get("COOPSIM_PYBIND11_ERRORS", "0") not in ("", "0"):
        return 0

    def add(label, f, setter=False):
        if f is not None and module._short_type_errors(short_type_error, f):
            _FUNCTIONS[id(f.__self__)] = (label, f, setter)

    for name, value in vars(module).items():
        if isinstance(value, type) and type(value).__name__ == "pybind11_type":
            for attr, v in vars(value).items():
                label = value.__name__ if attr == "__init__" else f"{value.__name__}.{attr}"
                if isinstance(v, property):
                    add(label, v.fget)
                    add(label, v.fset, setter=True)
                else:
                    add(label, getattr(v, "__func__", v))
        else:
            add(name, value)
    return len(_FUNCTIONS)


def short_type_error(error, record, given: tuple, nargs: int, kwnames) -> Optional[str]:
    """One line for pybind11's TypeError `error` from a call of the compiled function whose record is `record`
    with the arguments `given` (`nargs` positional ones, a method's self first, then the values of `kwnames`),
    or None when no argument can be blamed (pybind11's message stands)."""
    label, function, setter = _FUNCTIONS.get(id(record), (None, None, False))
    if function is None:
        return None
    name, doc = function.__name__, function.__doc__ or ""
    if not doc.startswith(f"{name}(") or not str(error).startswith(f"{name}(): incompatible "):
        return None     # overloads (no one argument to blame), or a TypeError from inside the function
    args, kwargs = given[:nargs], dict(zip(kwnames or (), given[nargs:]))
    params, var_args, var_kwargs = _parameters(doc.split("\n", 1)[0][len(name):])
    where = f"{label}(): "
    skip = 1 if params and params[0][0] == "self" else 0
    positional = [p for p in params if not p[3]]
    if len(args) > len(positional) and not var_args:
        k = len(positional) - skip
        return f"{where}takes {k} positional argument{'' if k == 1 else 's'}, got {len(args) - skip}"
    given = {p[0]: v for p, v in zip(positional, args)}
    names = [p[0] for p in params]
    for key, value in kwargs.items():
        if key not in names[skip:]:
            if var_kwargs:
                continue
            return f"{where}no argument named {key} (its arguments: {', '.join(names[skip:]) or 'none'})"
        if key in given:
            return f"{where}got two values for {key}"
        given[key] = value
    for p in params[skip:]:
        if p[0] not in given and not p[2]:
            return f"{where}missing argument {p[0]}"
    for k, (pname, annotation, _, _) in enumerate(params):
        if k < skip or pname not in given:
            continue
        what = _misfit(annotation, given[pname], True)   # (pybind11 converts every argument here: no noconvert)
        if what is not None:
            if setter:
                return f"{label} {what}"
            caller = _caller(pname)
            return f"{caller + '(): ' if caller else where}{pname} {what}"
    return None
