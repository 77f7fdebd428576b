"""The fast loop (``pytest -m "not slow"``) still touches every module of the package.

Read from the sources, not by running the suite: a module counts as touched when a test file that has a
test not marked slow names it, outside its slow tests:

- it imports it (``import coopsim.x``, ``from coopsim.x import y``, ``from coopsim import x``,
  ``pytest.importorskip("coopsim.x")``, ``importlib.import_module("coopsim.x")``),
- it reaches it as an attribute of an imported package (``cs.grasp.load_split``, ``view.replay.X``),
- or it runs it as a program (``[sys.executable, "-m", "coopsim.x", ...]``: its ``__main__``).

A module that no test names is touched when a touched module of the package other than the top one
imports it (an implementation part, such as a package's submodule that its ``__init__`` imports).
The top package's imports do not count: ``import coopsim`` imports nearly everything, and would
make the check say nothing.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = os.path.join(ROOT, "python", "coopsim")
TESTS = os.path.join(ROOT, "tests")


def package_modules() -> dict[str, str]:
    """Dotted name -> path of every module of python/coopsim (a package is its __init__)."""
    out = {}
    for folder, dirs, files in os.walk(PACKAGE):
        dirs[:] = [d for d in dirs if not d.startswith(("_", "."))]
        rel = os.path.relpath(folder, os.path.dirname(PACKAGE)).replace(os.sep, ".")
        for f in files:
            if f.endswith(".py"):
                out[rel if f == "__init__.py" else f"{rel}.{f[:-3]}"] = os.path.join(folder, f)
    return out


def is_slow(node: ast.AST) -> bool:
    for d in getattr(node, "decorator_list", []):
        if ast.unparse(d) in ("pytest.mark.slow", "mark.slow"):
            return True
    return False


def names_in(tree: ast.AST, modules: dict[str, str]) -> set[str]:
    """The package's modules a piece of test code names."""
    found: set[str] = set()
    aliases: dict[str, str] = {}  # local name -> module it is bound to

    def add(name):
        if name in modules:
            found.add(name)

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("coopsim"):
                    add(a.name)
                    aliases[a.asname or a.name.split(".")[0]] = a.name if a.asname else "coopsim"
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("coopsim"):
            add(node.module)
            for a in node.names:
                full = f"{node.module}.{a.name}"
                add(full)
                if full in modules:
                    aliases[a.asname or a.name] = full
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.startswith("coopsim"):
            add(node.value)
        elif isinstance(node, (ast.List, ast.Tuple)):  # [sys.executable, "-m", "coopsim.x", ...]
            items = [e.value if isinstance(e, ast.Constant) else None for e in node.elts]
            for flag, name in zip(items, items[1:]):
                if flag == "-m" and isinstance(name, str):
                    add(name)
                    add(name + ".__main__")
        elif isinstance(node, ast.Assign) and isinstance(node.value, ast.Call) and len(node.targets) == 1:
            # H = pytest.importorskip("coopsim.tasks.handover") and the like
            args = node.value.args
            if (isinstance(node.targets[0], ast.Name) and args and isinstance(args[0], ast.Constant)
                    and isinstance(args[0].value, str) and args[0].value in modules):
                aliases[node.targets[0].id] = args[0].value
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            chain, n = [], node
            while isinstance(n, ast.Attribute):
                chain.append(n.attr)
                n = n.value
            if isinstance(n, ast.Name) and n.id in aliases:
                name = aliases[n.id]
                for part in reversed(chain):
                    name = f"{name}.{part}"
                    if name not in modules:
                        break
                    found.add(name)
    return found


def touched_by_fast_tests(modules: dict[str, str]) -> dict[str, set[str]]:
    """Test file -> the modules it names outside its slow tests (files with no fast test left out)."""
    out = {}
    for f in sorted(os.listdir(TESTS)):
        if not (f.startswith("test_") and f.endswith(".py")):
            continue
        with open(os.path.join(TESTS, f), encoding="utf-8") as fh:
            tree = ast.parse(fh.read())
        if any(isinstance(n, ast.Assign) and any(getattr(t, "id", None) == "pytestmark" for t in n.targets)
               and "slow" in ast.unparse(n.value) for n in tree.body):
            continue
        tests = [n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and n.name.startswith(
            ("test_", "Test"))]
        if not any(not is_slow(t) for t in tests):
            continue
        kept = ast.Module(body=[n for n in tree.body if not is_slow(n)], type_ignores=[])
        out[f] = names_in(kept, modules)
    return out


def imports_of(path: str, name: str, modules: dict[str, str]) -> set[str]:
    """The package's modules a module imports (absolute or relative), with their parent packages."""
    with open(path, encoding="utf-8") as fh:
        tree = ast.parse(fh.read())
    package = name if path.endswith("__init__.py") else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(tree):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[:len(parts) - node.level + 1] + ([base] if base else []))
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        for t in targets:
            while t:
                if t in modules:
                    out.add(t)
                t = t.rpartition(".")[0]
    return out


def test_every_module_is_touched_by_a_test_that_is_not_slow():
    modules = package_modules()
    assert {"coopsim", "coopsim.grasp", "coopsim.log", "coopsim.sweeps"} <= set(modules)
    named = set().union(*touched_by_fast_tests(modules).values())
    touched, todo = set(), list(named)
    while todo:
        m = todo.pop()
        if m in touched:
            continue
        touched.add(m)
        if m != "coopsim":
            todo.extend(imports_of(modules[m], m, modules) - touched)
    missing = sorted(set(modules) - touched)
    assert not missing, f"no test outside the slow ones reaches these modules: {missing}"


def test_the_check_sees_what_a_test_file_names():
    # the reader above on a small piece of test code: what it must find, and what it must not
    modules = package_modules()
    code = ast.parse("import coopsim as cs\nfrom coopsim import view\nH = pytest.importorskip('coopsim.tasks.handover')\n"
                     "def test_x():\n    cs.grasp.load_split\n    view.replay\n    cs.robots.scara1()\n")
    found = names_in(code, modules)
    assert {"coopsim", "coopsim.view", "coopsim.grasp", "coopsim.robots", "coopsim.tasks.handover"} <= found
    assert "coopsim.view.replay" in found or "coopsim.view.replay" not in modules
    assert "coopsim.sweeps" not in found and "coopsim.codegen" not in found
    assert "coopsim.codegen.__main__" not in names_in(ast.parse("x = 'coopsim.codegen'\n"), modules)
    assert "coopsim.codegen.__main__" in names_in(ast.parse("run([sys.executable, '-m', 'coopsim.codegen'])\n"),
                                                  modules)
    slow = ast.parse("import pytest\n@pytest.mark.slow\ndef test_y():\n    import coopsim.sweeps\n")
    assert not names_in(ast.Module(body=[n for n in slow.body if not is_slow(n)], type_ignores=[]), modules)


def test_the_tasks_command_line_lists_its_options():
    # `python -m coopsim.tasks.handover` in the fast loop: its argument parser, without the run
    res = subprocess.run([sys.executable, "-m", "coopsim.tasks.handover", "--help"], capture_output=True, text=True,
                         timeout=120, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    for option in ("--out", "--cycles", "--seed", "--sweep", "--threads", "--no-video", "--speed"):
        assert option in res.stdout, res.stdout
