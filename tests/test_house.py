"""The house rules of the code base, checked on its source."""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

import coopsim

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "python" / "coopsim"


# ---- the package's import graph and the engine behind its facade ----

def package_modules() -> dict:
    """{dotted name: (path, is a package)} of every module of coopsim: the .py files, and the compiled
    module by its stub (_core.pyi)."""
    mods = {}
    for p in sorted(PACKAGE.rglob("*.py")) + sorted(PACKAGE.rglob("*.pyi")):
        parts = list(p.relative_to(PACKAGE.parent).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        name = ".".join(parts[:-1] if is_package else parts)
        mods.setdefault(name, (p, is_package))
    return mods


def _target(mods: dict, name: str) -> str:
    """The module of mods that importing `name` runs last: the name itself, or its nearest package."""
    while name not in mods:
        name = name.rpartition(".")[0]
    return name


def imports_of(name: str, path: Path, is_package: bool, mods: dict):
    """[(module imported, line, at module level)] for every import in a module's source, at any depth
    (module level, functions, methods), of coopsim's own modules."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top = {id(n) for n in tree.body}
    here = name if is_package else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names if a.name.split(".")[0] == "coopsim"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = here.split(".")
                base = ".".join(parts[:len(parts) - node.level + 1] + [node.module or ""]).strip(".")
            elif (node.module or "").split(".")[0] == "coopsim":
                base = node.module
            else:
                continue
            # `from pkg import sub` imports the module pkg.sub; `from mod import name` the module mod
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
        else:
            continue
        for t in targets:
            out.append((_target(mods, t), node.lineno, id(node) in top))
    return out


def import_graph() -> dict:
    mods = package_modules()
    graph = {}
    for name, (path, is_package) in mods.items():
        if path.suffix == ".pyi":
            graph[name] = set()        # the compiled engine imports nothing of the package
            continue
        graph[name] = {t for t, _, _ in imports_of(name, path, is_package, mods) if t != name}
    return graph


def find_cycle(graph: dict):
    """One cycle of the graph as a list of modules [a, b, ..., a], or None."""
    state, stack = {}, []

    def visit(v):
        state[v] = "open"
        stack.append(v)
        for w in sorted(graph[v]):
            if state.get(w) == "open":
                return stack[stack.index(w):] + [w]
            if w not in state:
                found = visit(w)
                if found:
                    return found
        state[v] = "done"
        stack.pop()
        return None

    for v in sorted(graph):
        if v not in state:
            found = visit(v)
            if found:
                return found
    return None


def test_the_cycle_finder_finds_cycles_and_only_cycles():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None          # a diamond is no cycle
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"b2"}, "b2": {"b"}}) == ["b", "b2", "b"]


def test_the_graph_sees_module_and_function_level_imports(tmp_path):
    # a package as the graph reads it: a module-level import, a function-level one, a package's submodule
    mods = {"coopsim": (None, True), "coopsim.a": (None, False), "coopsim.b": (None, False),
            "coopsim.view": (None, True), "coopsim.view.scene": (None, False), "coopsim._core": (None, False)}
    src = tmp_path / "a.py"
    src.write_text("from ._core import World\nfrom .view import scene\n\ndef f():\n    from . import b\n")
    got = imports_of("coopsim.a", src, False, mods)
    assert got == [("coopsim._core", 1, True), ("coopsim.view.scene", 2, True), ("coopsim.b", 5, False)]


def test_the_package_imports_without_cycles():
    graph = import_graph()
    assert {"coopsim", "coopsim._core", "coopsim.simulation", "coopsim.view.scene",
            "coopsim.tasks.handover.sequence"} <= set(graph)
    assert "coopsim.view.world" in graph["coopsim.view.scene"] and "coopsim._core" in graph["coopsim.simulation"]
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


#: modules a function may import where it needs them: their import is heavy (matplotlib, pandas, the
#: standard library's importlib.metadata, ...) or optional (dask's distributed; SciPy, for the held bar's
#: observer), and ``import coopsim``
#: loads none of them
LOCAL_IMPORTS = {"matplotlib", "mpl_toolkits", "pandas", "PIL", "imageio_ffmpeg", "tqdm", "xlsxwriter", "distributed",
                 "importlib.metadata", "viser", "rich", "IPython", "trimesh", "mujoco", "scipy"}


def _heavy(name: str) -> bool:
    return any(name == m or name.startswith(m + ".") for m in LOCAL_IMPORTS)


def test_function_level_imports_are_only_of_heavy_or_optional_dependencies():
    mods = package_modules()
    bad = []
    for name, (path, is_package) in mods.items():
        if path.suffix == ".pyi":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        top = {id(n) for n in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                    ["." if node.level else node.module or ""]
                if not all(_heavy(n) for n in names):
                    bad.append(f"{path.relative_to(ROOT)}:{node.lineno}: {ast.unparse(node)}")
    assert not bad, "imports inside functions (move them to the top of the module):\n" + "\n".join(bad)
    # and the reason they may wait: importing coopsim loads none of them
    code = ("import sys, coopsim, coopsim.tasks.handover, coopsim.view; "
            f"print(sorted(m for m in {sorted(LOCAL_IMPORTS)!r} if m in sys.modules))")
    # the coopsim this test imports (installed, or a staged tree with its compiled module), not the bare
    # source tree, which has no compiled module in a fresh checkout
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(coopsim.__file__).resolve().parent.parent)] + sys.path))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]", out.stdout


# ---- the engine (coopsim._core) behind the package's facade ----

#: where the compiled module may be named outside the package: its stubs and their test (and this file,
#: which names it to look for it)
ENGINE_NAMED = {"python/coopsim/_core.pyi", "tests/test_stubs.py", "tests/test_house.py"}
#: the package's modules that hold the engine's module object: the package (re-exports) and the simulation
#: (its engine object, ``sim._core``, a SimulationCore, is nobody else's business)
ENGINE_HOLDERS = {"python/coopsim/__init__.py", "python/coopsim/simulation.py"}


def _sources():
    """The package, its tests, benchmarks, examples and notebooks (the build scripts name the build target)."""
    for folder in ("python", "tests", "benchmarks", "examples", "notebooks"):
        for p in sorted((ROOT / folder).rglob("*")):
            if p.suffix in (".py", ".pyi", ".ipynb") and "_core" in p.name + p.read_text(encoding="utf-8"):
                yield p.relative_to(ROOT).as_posix(), p


def test_nothing_outside_the_facade_touches_the_engine_module():
    """Outside the package, only the stubs' own files name ``_core``; inside it, the package's __init__ and
    simulation.py hold the module, and other modules import from it only named engine classes and functions,
    at their top (``from .._core import World``): the bottom of the import graph, never ``sim._core``."""
    bad = []
    for rel, p in _sources():
        if rel in ENGINE_NAMED or rel in ENGINE_HOLDERS:
            continue
        if not rel.startswith("python/coopsim/") or p.suffix != ".py":
            bad.append(f"{rel}: names _core")
            continue
        tree = ast.parse(p.read_text(encoding="utf-8"))
        allowed = set()
        for node in tree.body:   # module level only
            if isinstance(node, ast.ImportFrom) and node.level and (node.module or "").split(".")[-1] == "_core":
                allowed.update(range(node.lineno, node.end_lineno + 1))
        for k, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            if "_core" in line and k not in allowed:
                bad.append(f"{rel}:{k}: {line.strip()}")
    assert not bad, "the engine module used outside the facade:\n" + "\n".join(bad)


def test_only_the_simulation_reaches_into_a_simulations_engine():
    bad = []
    for rel, p in _sources():
        if p.suffix != ".py" or rel == "python/coopsim/simulation.py" or rel in ENGINE_NAMED:
            continue
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and node.attr == "_core":
                bad.append(f"{rel}:{node.lineno}")
            if isinstance(node, ast.ImportFrom) and any(a.name == "_core" for a in node.names) \
                    and rel not in ENGINE_HOLDERS:
                bad.append(f"{rel}:{node.lineno}: imports the module")
    assert not bad, "._core outside simulation.py:\n" + "\n".join(bad)


@pytest.mark.parametrize("text, ok", [("from .._core import World\n", True),
                                      ("from . import _core\n", False),
                                      ("def f(sim):\n    return sim._core.run(1.0, None)\n", False),
                                      ("def f():\n    from .._core import World\n", False)])
def test_the_facade_check_tells_allowed_from_forbidden(tmp_path, monkeypatch, text, ok):
    pkg = tmp_path / "python" / "coopsim"
    pkg.mkdir(parents=True)
    (pkg / "m.py").write_text(text)
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    checks = (test_nothing_outside_the_facade_touches_the_engine_module,
              test_only_the_simulation_reaches_into_a_simulations_engine)
    failed = 0
    for check in checks:
        try:
            check()
        except AssertionError:
            failed += 1
    assert (failed == 0) == ok


def test_the_files_the_package_reads_ship_in_its_wheel():
    """The files beside the modules that the package reads (the replay's page, the stubs, py.typed) lie in
    the folder the wheel takes whole: scikit-build-core's wheel.packages copies every file under it that
    no exclusion (wheel.exclude, .gitignore) drops."""
    import fnmatch
    import tomllib

    conf = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["scikit-build"]["wheel"]
    assert conf["packages"] == ["python/coopsim"] and not conf.get("exclude")
    ignored = [p.strip() for p in (ROOT / ".gitignore").read_text(encoding="utf-8").splitlines()
               if p.strip() and not p.startswith("#")]
    for data in ("view/replay_template.html", "py.typed", "_core.pyi"):
        assert (PACKAGE / data).is_file(), data
        assert not any(fnmatch.fnmatch(Path(data).name, p) for p in ignored), data
    from coopsim.view import replay

    assert replay._template().startswith("<!DOCTYPE html>") and "@COMMANDS@" in replay._template()


# ---- the bindings declare, the engine decides ----

def _binding_ratio():
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import binding_ratio
    finally:
        sys.path.pop(0)
    return binding_ratio


# ---- one model, many runs (the engine's SimulationModel and SimulationData) ----

class _PD(coopsim.Controller):
    """A joint PD law written in Python (copied for another run by copy.deepcopy)."""

    def __init__(self, kp, kd):
        super().__init__()
        self.kp, self.kd, self.calls = kp, kd, 0

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        self.calls += 1
        return self.kp * (q_ref - q) + self.kd * (qd_ref - qd)


def _model_scene():
    """Both SCARAs of the task in its world (floor, container, three bars), one on a PID with a noisy,
    filtered sensor, the other on a PD law written in Python, each moving to a set-point."""
    import numpy as np
    from coopsim.tasks import scene as task_scene

    bars = [task_scene.bar_pose(0.95, 0.30 + 0.07 * k) for k in range(3)]
    sim = coopsim.Simulation(dt=2e-4, world=task_scene.world(bars), log_every=5)
    q0s = ([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03], [0.4, -0.5, -0.5, 0.0, 0.0, 0.02])
    laws = (coopsim.PID([300.0] * 6, [30.0] * 6, [20.0] * 6), _PD(np.full(6, 300.0), np.full(6, 30.0)))
    for r, q0, law in zip(task_scene.scaras(), q0s, laws):
        q0 = np.array(q0)
        sim.add_robot(r, law, q0 + np.array([0.05, -0.05, 0.02, 0.0, 0.1, 0.0]), q0=q0)
    sim.set_sensor(0, noise_force=0.2, noise_moment=0.01, time_constant=2e-3, seed=7)
    return sim


def test_one_model_shared_by_n_runs_gives_the_runs_of_n_separate_simulations():
    """Three runs of one model (Simulation.from_model: one SimulationModel, three SimulationData, the
    controllers copied, a world each) give what three simulations built separately give, to round-off
    (here exactly: the same operations in the same order), stepped side by side on threads; the model is
    one object shared by the runs, and a run that changes its model changes a copy."""
    import numpy as np

    first = _model_scene()
    model = first.model()
    runs = [coopsim.Simulation.from_model(model) for _ in range(3)]
    alone = [_model_scene() for _ in range(3)]
    assert all(r.model() is model for r in runs) and model.robot_count == 2 and model.has_world
    # the data are the runs' own: controllers, worlds, logs
    laws = [r.controllers[1] for r in [first] + runs]
    worlds = [r.world for r in [first] + runs]
    assert len({id(c) for c in laws}) == 4 and all(type(c) is _PD for c in laws)
    assert len({id(w) for w in worlds}) == 4
    coopsim.run_batch(runs + alone, t_end=0.04, threads=2)
    for r, a in zip(runs, alone):
        assert r.time == a.time > 0.039
        for i in range(2):
            for col in ("q", "qd", "tau", "tau_ext", "ft_world"):
                np.testing.assert_allclose(getattr(r.log[i], col), getattr(a.log[i], col), rtol=0, atol=1e-12)
        assert np.abs(r.log[0].ft_world).max() > 0  # the noisy sensor read something
        assert len(r.log.bodies) == 3
        for name, b in r.log.bodies.items():
            np.testing.assert_allclose(b.data, a.log.bodies[name].data, rtol=0, atol=1e-12)
    assert runs[0].controllers[1].calls == alone[0].controllers[1].calls > 0
    assert first.time == 0.0 and first.controllers[1].calls == 0  # the model's run did not move
    # a change goes to a copy of the model: the other runs keep the shared one
    runs[0].set_reference(0, np.zeros(6))
    assert runs[0].model() is not model and runs[1].model() is model
    assert np.array_equal(runs[1].references[0].q, first.references[0].q)


def test_a_run_of_a_model_refuses_what_it_cannot_copy():
    import numpy as np

    sim = _model_scene()
    with pytest.raises(ValueError, match="model must be a coopsim.SimulationModel"):
        coopsim.Simulation.from_model(sim)
    reps = sim.replicate(2)
    assert len(reps) == 2 and all(r.model() is reps[0].model() for r in reps)
    with pytest.raises(ValueError, match="n must be an int >= 0"):
        sim.replicate(-1)


def test_code_lines_count_code_not_comments():
    # the counting rule of scripts/binding_ratio.py on a known text: comments and blank lines out, the lines
    # of a raw string literal (but for blank ones) and a "//" inside a string in
    text = ('// a comment\n'
            'int a = 1;  // trailing\n'
            '\n'
            '/* a block\n'
            '   comment */\n'
            'const char* u = "http://x";\n'
            'const char* d = R"doc(one\n'
            '\n'
            'two // not a comment)doc";\n'
            'int b; /* c */ int c;\n'
            '   /* only a comment */   \n')
    assert _binding_ratio().code_lines(text) == 5


def test_the_bindings_are_at_most_a_third_of_the_engine():
    # the bindings declare (types, argument names, docstrings, GIL release) and convert Python objects;
    # every check and default lives in the engine, which the bindings call
    binding, engine = _binding_ratio().measure(ROOT)
    b, e = sum(binding.values()), sum(engine.values())
    assert b / e <= 0.33, f"bindings {b} code lines / engine {e} = {b / e:.3f} > 0.33: {binding}"


# ---- no module of the package over 600 code lines ----

#: the most code lines a module of the package may have: past it, a module holds more than one job
MODULE_MAX_CODE_LINES = 600


def python_code_lines(text: str) -> int:
    """Lines of Python source `text` holding a token other than a comment, a docstring (the first statement of
    a module, class or function when it is a string), a line end or indentation: blank lines, comment lines
    and docstrings do not count. Every line of another token spread over lines (a string) counts, but for
    blank ones."""
    import io
    import tokenize

    lines = text.splitlines()

    def chars(row: int, col: int) -> tuple:       # ast's columns are UTF-8 bytes, tokenize's are characters
        return row, len(lines[row - 1].encode("utf-8")[:col].decode("utf-8", "replace"))

    docs = []         # each docstring's (start, end), (row, column) in characters
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                docs.append((chars(first.lineno, first.col_offset), chars(first.end_lineno, first.end_col_offset)))
    skip = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENCODING,
            tokenize.ENDMARKER}
    code = set()
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type in skip:
            continue
        if tok.type == tokenize.STRING and any(a <= tok.start and tok.end <= b for a, b in docs):
            continue
        code.update(r for r in range(tok.start[0], tok.end[0] + 1) if r == tok.start[0] or lines[r - 1].strip())
    return len(code)


def test_python_code_lines_count_code_not_comments_or_docstrings():
    text = ('"""The module\'s docstring,\n'
            '\n'
            'over three lines."""\n'
            'import os  # a comment after code\n'           # 1
            '# a comment alone\n'
            '\n'
            'def f(x):\n'                                   # 2
            '    """f\'s docstring: ü."""\n'
            '    s = """a string, no docstring: its lines count\n'   # 3
            '\n'
            'but for the blank one"""\n'                    # 4
            '    return (x +\n'                             # 5
            '            1)\n'                              # 6
            '\n'
            '\n'
            'class A:\n'                                    # 7
            '    "a docstring" " in two strings"\n'
            '    y = "ü"; """a string after code"""\n'      # 8
            '    def g(self): """g\'s docstring"""; return os\n')   # 9
    assert python_code_lines(text) == 9
    assert python_code_lines("") == 0 and python_code_lines('"""Only a docstring."""\n# and a comment\n') == 0


def package_code_lines() -> dict:
    """{path in the repository: code lines (:func:`python_code_lines`)} of every module of the package, the
    compiled module's stubs (_core.pyi) aside."""
    return {p.relative_to(ROOT).as_posix(): python_code_lines(p.read_text(encoding="utf-8"))
            for p in sorted(PACKAGE.rglob("*.py"))}


def modules_over_the_bound() -> dict:
    """{path: code lines} of the package's modules over MODULE_MAX_CODE_LINES."""
    return {path: n for path, n in package_code_lines().items() if n > MODULE_MAX_CODE_LINES}


def test_no_package_module_is_over_600_code_lines():
    over = modules_over_the_bound()
    assert not over, (f"package modules over {MODULE_MAX_CODE_LINES} code lines (split them by job): "
                      + ", ".join(f"{path} ({n})" for path, n in sorted(over.items())))
    assert {"python/coopsim/__init__.py", "python/coopsim/view/scene.py",
            "python/coopsim/view/live/panels.py"} <= set(package_code_lines())


def test_the_module_size_rule_names_each_module_over_it(tmp_path, monkeypatch):
    pkg = tmp_path / "python" / "coopsim"
    (pkg / "sub").mkdir(parents=True)
    body = "".join(f"x{k} = {k}\n" for k in range(MODULE_MAX_CODE_LINES))
    (pkg / "at.py").write_text('"""A docstring\nof two lines."""\n# a comment\n\n' + body)      # 600: allowed
    (pkg / "sub" / "over.py").write_text(body + "y = 1\n")                                       # 601
    (pkg / "_core.pyi").write_text(body + body)                                                  # the stubs
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", pkg)
    assert package_code_lines() == {"python/coopsim/at.py": 600, "python/coopsim/sub/over.py": 601}
    with pytest.raises(AssertionError, match="code lines") as failed:
        test_no_package_module_is_over_600_code_lines()
    assert "python/coopsim/sub/over.py (601)" in str(failed.value) and "at.py" not in str(failed.value)


# ---- engine files sized by job ----

ENGINE_MAX_CODE_LINES = 600
ENGINE_DIRS = ("cpp/src", "cpp/include/coopsim", "cpp/bindings")  # cpp/generated aside


def engine_code_lines(root: Path = ROOT) -> dict:
    """{path in the repository: code lines (scripts/binding_ratio.py's code_lines: comments and blank lines
    out)} of every C++ file of the engine's sources and headers and of the bindings."""
    count = _binding_ratio().code_lines
    return {p.relative_to(root).as_posix(): count(p.read_text(encoding="utf-8"))
            for d in ENGINE_DIRS for p in sorted((root / d).iterdir()) if p.suffix in (".cpp", ".hpp")}


def engine_files_over_the_bound(root: Path = ROOT) -> dict:
    """{path: code lines} of the engine's files over ENGINE_MAX_CODE_LINES."""
    return {path: n for path, n in engine_code_lines(root).items() if n > ENGINE_MAX_CODE_LINES}


def test_no_engine_file_is_over_600_code_lines():
    # one file, one job: robot.cpp and world.cpp were split by job to pass it
    over = engine_files_over_the_bound()
    assert not over, (f"engine files over {ENGINE_MAX_CODE_LINES} code lines (split them by job): "
                      + ", ".join(f"{path} ({n})" for path, n in sorted(over.items())))
    assert {"cpp/src/robot.cpp", "cpp/src/world.cpp", "cpp/include/coopsim/simulation.hpp",
            "cpp/bindings/bind_simulation.cpp"} <= set(engine_code_lines())


def test_the_engine_file_rule_names_each_file_over_it(tmp_path):
    for d in (*ENGINE_DIRS, "cpp/generated"):
        (tmp_path / d).mkdir(parents=True)
    body = "".join(f"int x{k} = {k};\n" for k in range(ENGINE_MAX_CODE_LINES))
    (tmp_path / "cpp/src/at.cpp").write_text("// a comment\n/* a block\n   comment */\n\n" + body)  # 600: allowed
    (tmp_path / "cpp/include/coopsim/over.hpp").write_text(body + "int y;\n")                      # 601
    (tmp_path / "cpp/bindings/notes.txt").write_text(body + body)                                  # not C++
    (tmp_path / "cpp/generated/big.cpp").write_text(body + body)                                   # generated
    assert engine_code_lines(tmp_path) == {"cpp/src/at.cpp": 600, "cpp/include/coopsim/over.hpp": 601}
    assert engine_files_over_the_bound(tmp_path) == {"cpp/include/coopsim/over.hpp": 601}


# ---- one rule per value: the argument checks of the three layers ----

def _check_sites():
    sys.path.insert(0, str(ROOT / "tests"))
    try:
        import check_sites
    finally:
        sys.path.pop(0)
    return check_sites


def test_each_value_is_checked_in_one_layer_with_one_rule():
    # tests/check_sites.py lists every check site of the engine, the bindings and the package with the value
    # each names and its rule; a value checked with a bound in a layer must share it with a check of that
    # value in each layer below (a link's mass is finite and >= 0 kg in the engine, so in Python too)
    cs_ = _check_sites()
    sites = cs_.scan(ROOT)
    found = cs_.disagreements(sites)
    assert not found, "values checked in two layers with two rules (make one rule, in the engine " \
                      "function that uses the value):\n" + "\n".join(str(d) for d in found)
    # the scanner sees each layer (about 300 engine, 180 binding and 390 Python sites when written)
    per_layer = {layer: [s for s in sites if s.layer == layer] for layer in cs_.LAYERS}
    assert all(len(v) > 100 for v in per_layer.values()), {k: len(v) for k, v in per_layer.items()}
    assert all(sum(1 for s in v if s.value and s.bound) > 2 for v in per_layer.values())


def test_the_check_scanner_finds_a_planted_disagreement(tmp_path, monkeypatch):
    cs_ = _check_sites()
    (tmp_path / "cpp" / "src").mkdir(parents=True)
    (tmp_path / "cpp" / "bindings").mkdir(parents=True)
    (tmp_path / "python" / "coopsim" / "sub").mkdir(parents=True)
    (tmp_path / "cpp" / "src" / "a.cpp").write_text(
        '// require(x, "mass must be > 5") in a comment is no check\n'
        'void check_finite(double x, const char* name);\n'
        'void f(double m, double dt, const std::string& who) {\n'
        '  require(std::isfinite(m) && m >= 0,\n'
        '          who + ": mass must be finite and >= 0 kg, got " + num(m));\n'
        '  if (!(dt > 0)) throw std::invalid_argument("dt must be > 0, got " + num(dt));\n'
        '  check_finite(dt, "dt");\n'
        '}\n')
    (tmp_path / "cpp" / "bindings" / "b.cpp").write_text(
        'double g(const py::handle& o) { return scalar_arg(o, "dt") + index_arg(o, "threads", 0, 4096); }\n')
    (tmp_path / "python" / "coopsim" / "sub" / "m.py").write_text(
        "from .. import _checks\n"
        "LIMIT = 4096\n\n\n"
        "def f(masses, dt, threads):\n"
        "    if min(masses) <= 0:\n"
        "        raise ValueError(f'masses must be finite and > 0 kg, got {masses!r}')\n"
        "    _checks.positive(dt, 'dt')\n"
        "    _checks.integer(threads, 'threads', 1, LIMIT)\n")
    sites = cs_.scan(tmp_path)
    got = {(s.layer, s.path, s.line, s.value, s.rule) for s in sites}
    assert got == {
        ("engine", "cpp/src/a.cpp", 4, "*: mass", "finite and >= 0 kg"),
        ("engine", "cpp/src/a.cpp", 6, "dt", "> 0"),
        ("engine", "cpp/src/a.cpp", 7, "dt", "finite"),
        ("bindings", "cpp/bindings/b.cpp", 1, "dt", "a real number, finite"),
        ("bindings", "cpp/bindings/b.cpp", 1, "threads", "an integer in 0 .. 4096"),
        ("python", "python/coopsim/sub/m.py", 7, "masses", "finite and > 0 kg"),
        ("python", "python/coopsim/sub/m.py", 8, "dt", "finite and > 0"),
        ("python", "python/coopsim/sub/m.py", 9, "threads", "an integer in 1 .. 4096"),
    }
    found = sorted(cs_.disagreements(sites), key=lambda d: d.value)
    # dt agrees (> 0 in both), the mass and the thread count do not; each names the value, both sites, both rules
    assert [d.value for d in found] == ["mass", "thread"]
    said = str(found[0])
    assert all(w in said for w in ("'mass'", "python/coopsim/sub/m.py:7", "'finite and > 0 kg'",
                                   "cpp/src/a.cpp:4", "'finite and >= 0 kg'")), said
    said = str(found[1])
    assert all(w in said for w in ("python/coopsim/sub/m.py:9", "1 .. 4096", "cpp/bindings/b.cpp:1",
                                   "0 .. 4096")), said
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    with pytest.raises(AssertionError, match="two layers with two rules") as failed:
        test_each_value_is_checked_in_one_layer_with_one_rule()
    assert "python/coopsim/sub/m.py:7" in str(failed.value) and "cpp/src/a.cpp:4" in str(failed.value)


# the names of the package's former local checkers of one number, and the parameters naming the argument
_SCALAR_CHECKER_NAMES = {"_positive", "_finite", "_number", "_numbers", "_real", "_nonnegative", "_integer"}


def local_scalar_checkers(package: Path) -> list:
    """["path:line name"] of every function outside coopsim/_checks.py, at any depth, that checks one
    number for a caller: it takes the argument's name (a parameter `what`) and returns a float or an int
    (annotated so, or one of the former checkers' names), and raises."""
    out = []
    for p in sorted(package.rglob("*.py")):
        if p.name == "_checks.py" and p.parent == package:
            continue
        for fn in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            params = {a.arg for a in fn.args.args + fn.args.kwonlyargs}
            returns = ast.unparse(fn.returns) if fn.returns is not None else ""
            raises = any(isinstance(n, ast.Raise) for n in ast.walk(fn))
            if raises and "what" in params and (returns in ("float", "int") or fn.name in _SCALAR_CHECKER_NAMES):
                out.append(f"{p.relative_to(package.parent.parent).as_posix()}:{fn.lineno} {fn.name}")
    return out


def test_python_checks_go_through_the_shared_module(tmp_path):
    # one rule, one message format: the package's checks of a number are coopsim._checks' functions
    found = local_scalar_checkers(PACKAGE)
    assert not found, "local checkers of a number (use coopsim._checks): " + ", ".join(found)
    pkg = tmp_path / "python" / "coopsim"
    pkg.mkdir(parents=True)
    (pkg / "_checks.py").write_text("def number(x, what) -> float:\n    raise ValueError(what)\n")
    (pkg / "view.py").write_text(
        "def _zoom(x, what: str) -> float:\n    if x <= 0:\n        raise ValueError(what)\n    return x\n\n\n"
        "def _colour(c, what: str) -> str:\n    raise ValueError(what)\n\n\n"
        "class A:\n    @staticmethod\n    def _finite(x, what):\n        raise ValueError(what)\n")
    assert local_scalar_checkers(pkg) == ["python/coopsim/view.py:1 _zoom", "python/coopsim/view.py:13 _finite"]


def test_the_shared_checks_speak_the_engines_format():
    # "<argument> must be <rule>, got <value>", one line, a ValueError; the rule as the scanner reads it
    import math

    import numpy as np

    from coopsim import _checks

    cs_ = _check_sites()
    for call, said, bound in (
            (lambda: _checks.positive(-1.0, "tile"), "tile must be finite and > 0, got -1.0", {(">", 0.0)}),
            (lambda: _checks.positive(-1, "L1", unit="m"), "L1 must be finite and > 0 m, got -1", {(">", 0.0)}),
            (lambda: _checks.positive(math.nan, "gap", zero=True), "gap must be finite and >= 0, got nan",
             {(">=", 0.0)}),
            (lambda: _checks.number(0, "fps", 0.0, 1000.0, lo_open=True), "fps must be in (0, 1000], got 0",
             {(">", 0.0), ("<=", 1000.0)}),
            (lambda: _checks.number(10 ** 400, "t_end"), "t_end must be finite, got 1000", set()),
            (lambda: _checks.number("fast", "kp[0]", text=True), "kp[0] must be a number, got 'fast'", set()),
            (lambda: _checks.number(True, "zoom"), "zoom must be a number, got True", set()),
            (lambda: _checks.integer(-1, "threads", 0, 4096), "threads must be an integer in 0 .. 4096, got -1",
             {(">=", 0.0), ("<=", 4096.0)}),
            (lambda: _checks.numbers("1, x", 2, "target", text=True), "target[1] must be a number, got 'x'", set()),
            (lambda: _checks.numbers("1, 2", 3, "target", text=True), "target must be 3 numbers, got 2 ('1, 2')",
             set())):
        with pytest.raises(ValueError) as e:
            call()
        msg = str(e.value)
        assert msg.startswith(said) and "\n" not in msg, msg
        value, rule = cs_.parse_message(msg)
        assert value == said.split(" must ")[0] and cs_.bound_of(rule) == bound, (msg, value, rule)
    assert _checks.number("0.5", "move time", 0.0, 60.0, lo_open=True, text=True) == 0.5
    assert _checks.positive(np.float32(2), "tile") == 2.0 and _checks.integer(np.int64(3), "threads", 0, 9) == 3


# ---- the simulation's interface written once ----

# py::dicts the bindings still build key by key, per file, and why each is not an engine struct's copy
DICT_EXCEPTIONS = {
    "bind_simulation.cpp": 13,  # simulation_defaults() (12) and grasp_options (weld_moment beside the table of
                                # numeric options by name): the constructor's keyword arguments by name (**defaults)
    "bind_task.cpp": 10,        # the task laws' pickling: their constructors' keyword arguments
    "bind_world.cpp": 10,       # spec_dict (9): World's pickle and World.body(), a BodySpec by name (old pickles
                                # load); the pickle's keyword sleep_after (1)
    "bind_ik.cpp": 6,          # Robot.ik(info=True): keys per method (closed form: branch; numeric: iterations)
    "bind_codegen.cpp": 8,     # generated_info(): what a robot has attached (derivatives too), with in_use beside the library's
    "bind_build_info.cpp": 7,  # build_toolchain(): the compiler, flags and versions the build knows (no struct)
}


def _dict_keys_set(text: str) -> int:
    """Keys a C++ source writes one by one into a dict: d["key"] = ..., "key"_a = ..."""
    import re

    return len(re.findall(r"\b\w+\[\"\w+\"\]\s*=[^=]", text)) + len(re.findall(r"\"\w+\"_a\s*=", text))


def test_the_bindings_build_no_dictionary_of_an_engine_struct():
    """The quantities a run exposes are engine structs bound once (struct_binding.hpp), not dicts filled key
    by key; the dicts that stay are listed above with the reason. A new one fails here."""
    found = {p.name: _dict_keys_set(p.read_text(encoding="utf-8")) for p in sorted((ROOT / "cpp" / "bindings").glob("*.cpp"))}
    found = {k: v for k, v in found.items() if v}
    assert found == {k: v for k, v in DICT_EXCEPTIONS.items() if v}, found
    assert _dict_keys_set('d["force"] = to_numpy(c.force); py::dict("dt"_a = o.dt);') == 2  # the count can fail
    from coopsim import _core

    for cls in (_core.Contact, _core.GraspCheck, _core.Cooperation, _core.HeldCooperation, _core.TrackingMetrics,
                _core.SensorOptions, _core.SensorReading, _core.StepProfile, _core.BodyState):
        assert cls.fields and all(isinstance(getattr(cls, f), property) and getattr(cls, f).__doc__ for f in cls.fields)


def test_each_simulation_quantity_is_declared_once():
    """Each of SimulationCore's names is bound once in bind_simulation.cpp (the model's in bind_model.cpp), and coopsim.Simulation re-declares
    none that only forwards to it: those are FORWARDED, made from the bound class with its docstring."""
    import re
    from collections import Counter

    from coopsim import _core
    from coopsim.simulation import FORWARDED, Simulation

    text = (ROOT / "cpp" / "bindings" / "bind_simulation.cpp").read_text(encoding="utf-8")
    core = text[text.index('py::class_<Simulation>(m, "SimulationCore"'):text.index('m.def("simulation_defaults"')]
    model = (ROOT / "cpp" / "bindings" / "bind_model.cpp").read_text(encoding="utf-8")
    core += model[model.index('py::class_<Simulation>>(m.attr("SimulationCore"))'):]  # the model's side of it
    bound = Counter(re.findall(r"\.def(?:_property_readonly|_static)?\(\"(\w+)\"", core))
    assert bound and all(n == 1 for n in bound.values()), {k: n for k, n in bound.items() if n > 1}
    tree = ast.parse((PACKAGE / "simulation.py").read_text(encoding="utf-8"))
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Simulation")
    declared = {f.name for f in cls.body if isinstance(f, ast.FunctionDef)}
    only_forwarding = []
    for f in cls.body:
        if not isinstance(f, ast.FunctionDef):
            continue
        body = [s for s in f.body if not (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant))]
        if len(body) != 1 or not isinstance(body[0], (ast.Return, ast.Expr)) or body[0].value is None:
            continue
        v = body[0].value
        target = v.func if isinstance(v, ast.Call) else v
        params = [a.arg for a in f.args.args[1:]]
        if (isinstance(target, ast.Attribute) and target.attr == f.name and isinstance(target.value, ast.Attribute)
                and target.value.attr == "_core"
                and (not isinstance(v, ast.Call) or [getattr(a, "id", None) for a in v.args] == params)):
            only_forwarding.append(f.name)
    assert not only_forwarding, f"Simulation re-declares what it only forwards (add them to FORWARDED): {only_forwarding}"
    assert not set(FORWARDED) & declared
    for name in FORWARDED:
        assert name in bound, name
        engine, facade = getattr(_core.SimulationCore, name), getattr(Simulation, name)
        assert facade.__doc__ == engine.__doc__, name
    assert Simulation.dt.__doc__ == "s, > 0" and "Advances" not in (Simulation.contacts.__doc__ or "")
    assert Simulation.body_state.__doc__.splitlines()[0].startswith("body_state(self")


def test_the_docstrings_come_from_the_headers_and_are_regenerated(tmp_path):
    """cpp/bindings/generated/docstrings.hpp is what `python3 scripts/header_docs.py` writes from the headers,
    byte for byte; a header's comment changed without regenerating shows as a difference; the bound module and
    its stubs carry the header's text."""
    import importlib.util

    run = subprocess.run([sys.executable, str(ROOT / "scripts" / "header_docs.py"), "--out", str(tmp_path / "d.hpp")],
                         capture_output=True, text=True, check=True)
    assert "wrote" in run.stdout
    committed = ROOT / "cpp" / "bindings" / "generated" / "docstrings.hpp"
    assert (tmp_path / "d.hpp").read_bytes() == committed.read_bytes(), "run python3 scripts/header_docs.py"
    spec = importlib.util.spec_from_file_location("header_docs", ROOT / "scripts" / "header_docs.py")
    docs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docs)
    header = (ROOT / "cpp" / "include" / "coopsim" / "grasp.hpp").read_text(encoding="utf-8")
    changed = tmp_path / "grasp.hpp"
    changed.write_text(header.replace("// all five conditions", "// all five conditions met"), encoding="utf-8")
    before = dict(docs.parse(str(ROOT / "cpp" / "include" / "coopsim" / "grasp.hpp")))
    after = dict(docs.parse(str(changed)))
    assert before["GraspCheck_ok"] == "all five conditions" and after["GraspCheck_ok"] == "all five conditions met"
    from coopsim import _core

    text = committed.read_text(encoding="utf-8")
    assert _core.GraspCheck.ok.__doc__ == before["GraspCheck_ok"] and "doc_Simulation_advance" in text
    assert before["GraspCheck_ok"] in (PACKAGE / "_core.pyi").read_text(encoding="utf-8")
    assert "Advances n >= 0 steps" in _core.SimulationCore.advance.__doc__
