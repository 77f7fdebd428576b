"""Every argument check of coopsim, per layer, with the value it checks and its rule.

Three layers check arguments:

- engine (cpp/src, cpp/include/coopsim): ``throw std::invalid_argument(...)`` and the calls of the engine's
  check helpers (``require``, ``require_nonnegative``, ``check_finite``, ``check_shape``, ``vector_of``, ...;
  cpp/src/checks.cpp, cpp/src/internal.hpp);
- bindings (cpp/bindings): ``throw py::value_error(...)``, ``throw std::invalid_argument(...)`` and the calls
  of convert.hpp's helpers (``scalar_arg``, ``index_arg``, ``array``, ``vec``, ``pose``, ...);
- python (python/coopsim): ``raise SomeError(...)`` and the calls of the shared checks
  (``_checks.number``, ``_checks.positive``, ...).

Each site is read for the value it checks (the argument as its message names it: "mass" in
"link 2: mass must be finite and >= 0 kg", "dt" in ``scalar_arg(obj, "dt")``) and its rule (the text after
"must be", or what the helper checks: "finite", "shape (N, 4)", "in (0, 1000]"). A rule's bounds ("> 0",
">= 0", "in [0, 1]", "in 1e-6 .. 1e9") are read as a set of comparisons.

A disagreement: a value checked with a bound in one layer whose bound no check of that value in another
layer shares (e.g. a mass "> 0" in Python where every engine check of a mass says ">= 0" or
"in 1e-6 .. 1e9"). Values whose names are alike but mean different things (a link's mass, a free body's)
keep their own rules in one layer; a check in another layer must agree with one of them.

Run as a script for a per-layer summary: ``python tests/check_sites.py [root]``.
"""
from __future__ import annotations

import ast
import re
import sys
from collections import defaultdict
from pathlib import Path
from typing import Dict, List, NamedTuple, Optional, Tuple

ROOT = Path(__file__).resolve().parent.parent
LAYERS = ("engine", "bindings", "python")
ENGINE_DIRS = ("cpp/src", "cpp/include/coopsim")
BINDINGS_DIRS = ("cpp/bindings",)
PYTHON_DIR = "python/coopsim"
SHARED_MODULE = "python/coopsim/_checks.py"

# C++ helpers that check an argument: {name: (index of the argument's name, what it checks)}; index -1:
# the last argument. A rule of None: read from the message (require's second argument).
ENGINE_HELPERS: Dict[str, Tuple[int, Optional[str]]] = {
    "require": (1, None),
    "require_nonnegative": (-1, "finite and >= 0"),
    "check_finite": (-1, "finite"),
    "check_shape": (-1, "shape"),
    "vector_of": (-1, "shape (n,), finite"),
    "per_joint": (-1, "one number or shape (n,), finite"),
    "check_rotation": (-1, "a rotation matrix"),
    "check_rigid": (-1, "a rigid transform"),
    "rigid_pose": (-1, "a rigid transform"),
    "rigid_poses": (-1, "shape (N, 4, 4), rigid transforms"),
}
BINDING_HELPERS: Dict[str, Tuple[int, Optional[str]]] = {
    "as_array": (1, "an array of real numbers"),
    "table": (1, "an array of real numbers"),
    "optional_table": (1, "an array of real numbers or None"),
    "scalar_arg": (1, "a real number, finite"),
    "index_arg": (1, "an integer"),
    "array": (2, "shape"),
    "vec": (2, "shape (n,), finite"),
    "vecx": (2, "shape (n,), finite"),
    "vector_arg": (2, "shape (n,), finite"),
    "pose": (1, "a rigid transform"),
    "pose_from": (1, "a rigid transform"),
    "wrenches_arg": (1, "wrenches or shape (6,)"),
    **{k: v for k, v in ENGINE_HELPERS.items() if k != "require"},
}
_THROWS = r"throw\s+(?:std::invalid_argument|py::value_error)\s*\("
# words before a helper's name that make it a definition or declaration, not a call
_DECLARING = re.compile(r"(?:\b(?:void|double|bool|long|int|auto|Arr|V|VecN|Array|std::string)|[>&*])\s*$")


class Site(NamedTuple):
    layer: str
    path: str          # in the repository, e.g. "cpp/src/robot.cpp"
    line: int
    value: Optional[str]   # the argument checked, as named in the message (None: not read from the source)
    rule: str          # what the check asks, e.g. "finite and > 0 m", "shape (N, 4)"
    bound: frozenset   # the rule's comparisons, e.g. {(">", 0.0)}; empty: no bound

    def where(self) -> str:
        return f"{self.path}:{self.line}"


# ---- messages: the value and the rule ----

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?|[-+]?inf"


def _float(text: str) -> float:
    return float(text)


def bound_of(rule: str) -> frozenset:
    """The comparisons a rule's text states: "finite and > 0 m" -> {(">", 0)}; "in (0, 1000]" ->
    {(">", 0), ("<=", 1000)}; "in 1e-6 .. 1e9 kg" -> {(">=", 1e-6), ("<=", 1e9)}; "positive" -> {(">", 0)}."""
    out = set()
    m = re.search(rf"\bin\s*([\[(])\s*({_NUM})\s*,\s*({_NUM})\s*([\])])", rule)
    if m:
        out |= {(">" if m[1] == "(" else ">=", _float(m[2])), ("<" if m[4] == ")" else "<=", _float(m[3]))}
    m = re.search(rf"(?:^|\s)({_NUM})\s*\.\.\s*({_NUM})(?:\s|$|[,;)])", rule)
    if m:
        out |= {(">=", _float(m[1])), ("<=", _float(m[2]))}
    for op, x in re.findall(rf"(>=|<=|>|<)\s*({_NUM})", rule):
        out.add((op, _float(x)))
    if re.search(r"\bpositive\b", rule) and not re.search(r"semi-?definite|non-?negative", rule):
        out.add((">", 0.0))
    if re.search(r"\bnon-?negative\b", rule):
        out.add((">=", 0.0))
    return frozenset((op, x) for op, x in out if x not in (float("inf"), float("-inf")))


def _key(name: str) -> Optional[str]:
    """The value's key for comparing layers: lower case, the parts a message fills in at run time ("*")
    and indices dropped, a leading "<something>: " of a run-time name dropped, plurals as singular
    ("masses" -> "mass")."""
    s = name.strip().strip("'\"`").lower()
    s = re.sub(r"\[[^\]]*\]", "", s)
    s = re.sub(r"^(?:[^:]*\*[^:]*:\s*)+", "", s)        # "link *: mass", "*: mass" -> "mass"
    s = s.replace("*", "").strip(" :.,")
    if not s or not re.search(r"[a-z]", s):
        return None
    words = s.split()
    last = words[-1]
    if last.endswith("sses"):
        last = last[:-2]
    elif last.endswith("s") and not last.endswith("ss") and len(last) > 3:
        last = last[:-1]
    return " ".join(words[:-1] + [last])


def parse_message(msg: str) -> Tuple[Optional[str], str]:
    """(value, rule) of a check's message, "*" standing for what the message fills in at run time:
    "wrong shape for q: expected (3,), got *" -> ("q", "shape (3,)"); "*: mass must be finite and >= 0 kg"
    -> ("*: mass", "finite and >= 0 kg"); "dt must be > 0, got *" -> ("dt", "> 0")."""
    msg = " ".join(msg.split())
    m = re.match(r"wrong (shape|size) for (.+?): expected (.+?)(?:, got .*)?$", msg)
    if m:
        return m[2], f"{m[1]} {m[3]}"
    m = re.match(r"(.+?) must (be|have|name|lie|not be|hold) (.*)$", msg)
    if m:
        rule = re.split(r",? \(?got\b", m[3])[0].strip()
        return m[1], (rule if m[2] == "be" else f"{m[2]} {rule}")
    return None, msg


# ---- C++ ----

def _strip_comments(src: str) -> str:
    """src with comments blanked (newlines kept), string and character literals kept."""
    out, i, n = [], 0, len(src)
    while i < n:
        c = src[i]
        if c in "\"'":
            j = i + 1
            while j < n and src[j] != c:
                j += 2 if src[j] == "\\" else 1
            out.append(src[i:j + 1])
            i = j + 1
        elif src.startswith("//", i):
            j = src.find("\n", i)
            i = n if j < 0 else j
        elif src.startswith("/*", i):
            j = src.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * src.count("\n", i, j))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def _call_args(src: str, open_paren: int) -> Tuple[List[str], int]:
    """The top-level arguments of the call whose "(" is at open_paren, and the index after its ")"."""
    depth, i, start, args = 0, open_paren, open_paren + 1, []
    while i < len(src):
        c = src[i]
        if c in "\"'":
            j = i + 1
            while j < len(src) and src[j] != c:
                j += 2 if src[j] == "\\" else 1
            i = j
        elif c in "([{":
            depth += 1
        elif c in ")]}":
            depth -= 1
            if depth == 0:
                args.append(src[start:i])
                return [a.strip() for a in args if a.strip()], i + 1
        elif c == "," and depth == 1:
            args.append(src[start:i])
            start = i + 1
        elif c == "<" and depth == 1 and re.match(r"\{", src[i + 1:i + 2] or ""):
            pass
        i += 1
    return [a.strip() for a in args], len(src)


def _literal_text(expr: str) -> str:
    """The text a C++ string expression makes: its literals joined, "*" for each part filled in at run time
    (`who + ": mass must be " + num(m)` -> "*: mass must be *")."""
    parts, pos = [], 0
    for m in re.finditer(r'"((?:[^"\\]|\\.)*)"', expr):
        between = expr[pos:m.start()]
        if re.search(r"[\w)\]]", re.sub(r"\b(std::string|std::to_string)\b|[+(\s]", "", between)):
            parts.append("*")
        parts.append(bytes(m[1], "utf-8").decode("unicode_escape", errors="replace"))
        pos = m.end()
    tail = expr[pos:]
    if re.search(r"[\w\]]", re.sub(r"[+)\s;.]|\bc_str\b", "", tail)):
        parts.append("*")
    return re.sub(r"(\*\s*)+\*", "*", "".join(parts))


def _line_of(src: str, index: int) -> int:
    return src.count("\n", 0, index) + 1


def scan_cpp(path: Path, rel: str, layer: str) -> List[Site]:
    helpers = ENGINE_HELPERS if layer == "engine" else BINDING_HELPERS
    src = _strip_comments(path.read_text(encoding="utf-8"))
    names = "|".join(sorted(helpers, key=len, reverse=True))
    pattern = re.compile(rf"{_THROWS}|(?<![\w.])(?:(?:coopsim|detail|py_convert)::)*({names})\s*(?:<[^<>()]*>)?\s*\(")
    sites = []
    for m in pattern.finditer(src):
        open_paren = m.end() - 1
        args, _ = _call_args(src, open_paren)
        helper = m[1]
        if helper:
            line_start = src.rfind("\n", 0, m.start()) + 1
            if _DECLARING.search(src[line_start:m.start()]):
                continue                                  # a definition or declaration of the helper
            index, rule = helpers[helper]
            if not args or len(args) <= max(index, -1 - index) - (1 if index < 0 else 0):
                continue
            if rule is None:                              # require(ok, message)
                value, rule = parse_message(_literal_text(args[index]))
            else:
                value = _literal_text(args[index]) or None
                if value and '"' not in args[index]:
                    value = None                          # a name handed on: the caller's site names it
                if helper in ("check_shape", "array") and len(args) >= 2:
                    rule = "shape " + args[-2 if helper == "check_shape" else 1].replace("{", "(").replace("}", ")")
                if helper == "index_arg" and len(args) >= 4:
                    rule = f"an integer in {args[2]} .. {args[3]}"
        else:
            value, rule = parse_message(_literal_text(args[0]) if args else "*")
        sites.append(Site(layer, rel, _line_of(src, m.start()), value, rule, bound_of(rule)))
    return sites


# ---- Python ----

def _py_text(node) -> Optional[str]:
    """The text of a string expression, "*" for the parts filled in at run time; None for no string."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "*" for v in node.values)
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Mod)):
        left, right = _py_text(node.left), _py_text(node.right)
        if left is None and right is None:
            return None
        return (left or "*") + ("" if isinstance(node.op, ast.Add) else "") + (right or "*")
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "format":
        return _py_text(node.func.value)
    return None


# the package's module-level number constants by name (MAX_THREADS = 4096), read by scan()
_CONSTANTS: Dict[str, float] = {}


def _py_number(node) -> Optional[float]:
    """The number a bound's expression stands for: a literal, -x, math.inf, a module-level constant."""
    try:
        return float(ast.literal_eval(node))
    except (ValueError, TypeError, SyntaxError):
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            v = _py_number(node.operand)
            return None if v is None else -v
        if isinstance(node, ast.Attribute) and node.attr == "inf":
            return float("inf")
        if isinstance(node, ast.Name):
            return _CONSTANTS.get(node.id)
        return None


def _module_constants(tree: ast.Module) -> Dict[str, float]:
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and isinstance(node.value, ast.Constant) and isinstance(node.value.value, (int, float)) \
                and not isinstance(node.value.value, bool):
            out[node.targets[0].id] = float(node.value.value)
    return out


def _shared_rule(fn: str, call: ast.Call) -> str:
    """The rule of a call of the shared checks (coopsim._checks) as its message states it."""
    kw = {k.arg: k.value for k in call.keywords}
    args = call.args
    const = (lambda node, default: default if node is None else ast.literal_eval(node)
             if isinstance(node, ast.Constant) else default)
    if fn in ("number", "positive"):
        if fn == "positive":
            lo, hi, lo_open, hi_open = 0.0, float("inf"), not const(kw.get("zero"), False), False
        else:
            lo = _py_number(args[2] if len(args) > 2 else kw.get("lo", ast.Constant(float("-inf"))))
            hi = _py_number(args[3] if len(args) > 3 else kw.get("hi", ast.Constant(float("inf"))))
            lo_open, hi_open = const(kw.get("lo_open"), False), const(kw.get("hi_open"), False)
            if lo is None or hi is None:
                return "a number in a range set at run time"
        rule = _range_rule(lo, hi, lo_open, hi_open)
        unit = const(kw.get("unit"), "")
        return f"{rule} {unit}".strip()
    if fn == "integer" and len(args) >= 4:
        lo, hi = _py_number(args[2]), _py_number(args[3])
        span = f"{lo:g} .. {hi:g}" if lo is not None and hi is not None else "a range set at run time"
        return f"an integer in {span}"
    if fn == "numbers":
        n = _py_text(args[1]) if len(args) > 1 and isinstance(args[1], ast.Constant) else None
        return f"{n or 'n'} numbers, each finite"
    return {"real_array": "an array of real numbers", "one_of": "one of the choices",
            "callable_or_none": "a function or None"}.get(fn, fn)


def _range_rule(lo: float, hi: float, lo_open: bool, hi_open: bool) -> str:
    inf = float("inf")
    if lo == -inf and hi == inf:
        return "finite"
    if hi == inf:
        return f"finite and {'>' if lo_open else '>='} {lo:g}"
    if lo == -inf:
        return f"finite and {'<' if hi_open else '<='} {hi:g}"
    return f"in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


SHARED_CHECKS = ("number", "positive", "integer", "numbers", "real_array", "one_of", "callable_or_none")


def scan_python(path: Path, rel: str, tree: Optional[ast.Module] = None) -> List[Site]:
    tree = tree or ast.parse(path.read_text(encoding="utf-8"))
    sites = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
            f = node.exc.func
            name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
            if not re.search(r"(Error|Exception)$", name):
                continue
            text = _py_text(node.exc.args[0]) if node.exc.args else None
            value, rule = parse_message(text) if text else (None, "*")
            sites.append(Site("python", rel, node.lineno, value, rule, bound_of(rule)))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and isinstance(node.func.value, ast.Name) and node.func.value.id == "_checks" \
                and node.func.attr in SHARED_CHECKS:
            what = node.args[1] if len(node.args) > 1 else None
            if node.func.attr == "numbers":
                what = node.args[2] if len(node.args) > 2 else None
            value = _py_text(what) if what is not None else None
            rule = _shared_rule(node.func.attr, node)
            sites.append(Site("python", rel, node.lineno, value, rule, bound_of(rule)))
    return sites


# ---- the whole tree ----

def scan(root: Path = ROOT) -> List[Site]:
    """Every check site under root (the repository), in layer, file and line order."""
    sites = []
    for layer, dirs in (("engine", ENGINE_DIRS), ("bindings", BINDINGS_DIRS)):
        for d in dirs:
            folder = root / d
            if folder.is_dir():
                for p in sorted(folder.iterdir()):
                    if p.suffix in (".cpp", ".hpp"):
                        sites += scan_cpp(p, p.relative_to(root).as_posix(), layer)
    pkg = root / PYTHON_DIR
    if pkg.is_dir():
        trees = {p: ast.parse(p.read_text(encoding="utf-8")) for p in sorted(pkg.rglob("*.py"))}
        _CONSTANTS.clear()
        for tree in trees.values():
            _CONSTANTS.update(_module_constants(tree))
        for p, tree in trees.items():
            sites += scan_python(p, p.relative_to(root).as_posix(), tree)
    return sites


class Disagreement(NamedTuple):
    value: str
    site: Site                 # a check whose bound no check of the value in the lower layer shares
    others: Tuple[Site, ...]   # the lower layer's checks of the value, with a bound

    def __str__(self) -> str:
        theirs = "; ".join(f"{o.where()} ({o.layer}): {o.rule!r}" for o in self.others)
        return (f"{self.value!r} is checked as {self.site.rule!r} at {self.site.where()} ({self.site.layer}) "
                f"but as {theirs}")


def disagreements(sites: List[Site]) -> List[Disagreement]:
    """The checks with a bound that no check of the same value in a lower layer (engine below bindings
    below python) shares, each with that layer's checks of the value. A lower layer may check several
    values of one name (a link's mass, a free body's mass) with their own rules; a check above must agree
    with one of them."""
    by = defaultdict(lambda: defaultdict(list))     # key -> layer -> sites with a bound
    for s in sites:
        k = _key(s.value) if s.value else None
        if k and s.bound:
            by[k][s.layer].append(s)
    out = []
    for k, layers in sorted(by.items()):
        for layer, mine in layers.items():
            for lower in LAYERS[:LAYERS.index(layer)]:
                theirs = layers.get(lower)
                if theirs:
                    out += [Disagreement(k, s, tuple(theirs)) for s in mine if all(s.bound != o.bound for o in theirs)]
    return out


def summary(sites: List[Site]) -> str:
    lines = []
    for layer in LAYERS:
        mine = [s for s in sites if s.layer == layer]
        named = [s for s in mine if s.value and _key(s.value)]
        files = len({s.path for s in mine})
        lines.append(f"{layer:9s} {len(mine):4d} check sites in {files:3d} files, {len(named):4d} naming their "
                     f"value, {sum(1 for s in mine if s.bound):4d} with a bound")
    lines.append("")
    values = defaultdict(set)
    for s in sites:
        k = _key(s.value) if s.value else None
        if k:
            values[k].add(s.layer)
    shared = sorted(k for k, v in values.items() if len(v) > 1)
    lines.append(f"values checked in more than one layer: {len(shared)}")
    for k in shared:
        rules = sorted({f"{s.layer}: {s.rule}" for s in sites if s.value and _key(s.value) == k})
        lines.append(f"  {k}: " + " | ".join(rules))
    found = disagreements(sites)
    lines.append("")
    lines.append(f"disagreements: {len(found)}")
    lines += [f"  {d}" for d in found]
    return "\n".join(lines)


if __name__ == "__main__":
    print(summary(scan(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT)))
