"""The Python layer's argument checks, in one place: the checks the engine cannot make (Python types, text
typed into the live page, numbers the engine never sees: a view's frame rate, a task's factors).

A value the engine uses is checked by the engine function that uses it (its message is
"<argument> must be <rule>, got <value>", a ValueError), never here as well. The checks here speak the
engine's format: ``fps must be in (0, 1000], got 0``, ``tile must be finite and > 0, got -1``,
``speed (%) must be a number, got 'fast'``. Every failure is a one-line ValueError naming the argument.
tests/check_sites.py reads the calls of these functions as check sites (the argument named, the rule).
"""
from __future__ import annotations

import math
import numpy as np

_REAL_TYPES = (int, float, np.integer, np.floating)


def rule(lo: float = -math.inf, hi: float = math.inf, lo_open: bool = False, hi_open: bool = False) -> str:
    """The rule of a number in [lo, hi] ((lo, ... with lo_open, ...hi) with hi_open) as a message says it:
    "finite", "finite and > 0", "finite and >= 1", "finite and <= 90", "in (0, 1000]"."""
    if lo == -math.inf and hi == math.inf:
        return "finite"
    if hi == math.inf:
        return f"finite and {'>' if lo_open else '>='} {lo:g}"
    if lo == -math.inf:
        return f"finite and {'<' if hi_open else '<='} {hi:g}"
    return f"in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


def number(x, what: str, lo: float = -math.inf, hi: float = math.inf, *, lo_open: bool = False,
           hi_open: bool = False, unit: str = "", text: bool = False) -> float:
    """x as a float: a real number (int, float or numpy scalar; not a bool) that is finite and in [lo, hi]
    (open ends with lo_open / hi_open). text=True also takes the text of a number ("0.5", as typed in the
    live page). ValueError naming `what` otherwise: "<what> must be a number, got 'abc'",
    "<what> must be <rule>[ <unit>], got <x>" (see rule())."""
    if isinstance(x, np.ndarray) and x.ndim == 0 and x.dtype.kind in "iuf":
        x = x[()]
    if text and isinstance(x, str):
        try:
            v = float(x)
        except ValueError:
            raise ValueError(f"{what} must be a number, got {x!r}") from None
    elif isinstance(x, (bool, np.bool_)) or not isinstance(x, _REAL_TYPES):
        raise ValueError(f"{what} must be a number, got {x!r}")
    else:
        try:
            v = float(x)
        except OverflowError:       # an int beyond a float's range
            v = math.inf if x > 0 else -math.inf
    if not (math.isfinite(v) and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)):
        raise ValueError(f"{what} must be {rule(lo, hi, lo_open, hi_open)}{' ' + unit if unit else ''}, got {x!r}")
    return v


def positive(x, what: str, *, zero: bool = False, unit: str = "", text: bool = False) -> float:
    """x as a float, finite and > 0 (>= 0 with zero=True): "<what> must be finite and > 0, got -1"."""
    return number(x, what, 0.0, lo_open=not zero, unit=unit, text=text)


def items(x) -> list:
    """The items of a text "a, b, c" (commas, semicolons or spaces between them) or of a sequence (one
    number: one item)."""
    if isinstance(x, str):
        return [s for s in x.replace(";", ",").replace(" ", ",").split(",") if s]
    return list(np.atleast_1d(x))


def integer(x, what: str, lo: int, hi: int) -> int:
    """x as an int (a Python or numpy integer; not a bool) in lo .. hi: "<what> must be an integer in 0 ..
    4096, got -1" (the bindings' index_arg says the same)."""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)) or not lo <= x <= hi:
        raise ValueError(f"{what} must be an integer in {lo} .. {hi}, got {x!r}")
    return int(x)


def numbers(x, n: int, what: str, *, text: bool = False) -> np.ndarray:
    """(n,) finite floats from a sequence of n numbers or (text=True) also from a text "a, b, c" (see items()).
    A wrong count: "<what> must be <n> numbers, got 2 ('1, 2')"; a bad item: "<what>[j] must be a number,
    got 'a'", "<what>[j] must be finite, got nan"."""
    got = items(x) if text or not isinstance(x, str) else [x]
    if len(got) != n:
        raise ValueError(f"{what} must be {n} numbers, got {len(got)} ({x!r})")
    return np.array([number(v, f"{what}[{j}]", text=text) for j, v in enumerate(got)])


def real_array(x, what: str) -> np.ndarray:
    """x as a float array; ValueError naming `what` when it holds anything but real numbers (bool, int and
    float kinds; NaN and inf pass): "<what> must be an array of real numbers, got dtype <U3"."""
    a = np.asarray(x)
    if a.dtype.kind not in "biuf":
        raise ValueError(f"{what} must be an array of real numbers, got dtype {a.dtype}")
    return a.astype(float, copy=False)


def one_of(x, what: str, choices) -> None:
    """Unless x is one of `choices` (strings): "<what> must be 'a', 'b' or 'c', got 'd'"."""
    if not isinstance(x, str) or x not in choices:
        names = [repr(c) for c in choices]
        said = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " or " + names[-1]
        raise ValueError(f"{what} must be {said}, got {x!r}")


def callable_or_none(x, what: str, of: str) -> None:
    """Unless x is a function or None: "<what> must be a function of <of> or None, got 1"."""
    if x is not None and not callable(x):
        raise ValueError(f"{what} must be a function of {of} or None, got {x!r}")
