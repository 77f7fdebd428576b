"""The committed type stubs of the compiled module match the build."""
from __future__ import annotations

import difflib
import importlib.util
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))

pytest.importorskip("pybind11_stubgen", reason="pybind11-stubgen is installed by the test extra")


def test_stubs_match_the_compiled_module():
    import generate_stubs

    fresh = generate_stubs.generate()
    with open(generate_stubs.TARGET) as f:
        committed = f.read()
    if fresh != committed:
        diff = "".join(difflib.unified_diff(committed.splitlines(True), fresh.splitlines(True), "committed",
                                            "generated", n=1))
        pytest.fail("python/coopsim/_core.pyi is out of date; run `python3 scripts/generate_stubs.py`:\n"
                    + diff[:4000])


def test_stubs_ship_with_the_package():
    spec = importlib.util.find_spec("coopsim")
    pkg = os.path.dirname(spec.origin)
    assert os.path.exists(os.path.join(pkg, "_core.pyi"))
    assert os.path.exists(os.path.join(pkg, "py.typed"))


def test_the_defaults_are_written_once_in_the_engine():
    """simulation_defaults() is the engine's SimulationOptions: what SimulationCore holds when every argument
    is left out, and what the committed stub shows as SimulationCore's defaults."""
    import ast

    from coopsim import _core

    d = _core.simulation_defaults()
    assert d["dt"] == 2e-4 and d["integrator"] == "rk4" and d["grasp_options"]["hold_time"] == 2e-3
    core = _core.SimulationCore()
    for name, value in d.items():
        got = core.grasp_options() if name == "grasp_options" else getattr(core, name)
        assert got == value and type(got) is type(value), name
    import generate_stubs

    with open(generate_stubs.TARGET) as f:
        tree = ast.parse(f.read())
    init = next(n for c in tree.body if isinstance(c, ast.ClassDef) and c.name == "SimulationCore"
                for n in c.body if isinstance(n, ast.FunctionDef) and n.name == "__init__")
    args = init.args.args[-len(init.args.defaults):] if init.args.defaults else []
    args += init.args.kwonlyargs
    defaults = list(init.args.defaults) + list(init.args.kw_defaults)
    shown = {a.arg: ast.literal_eval(v) for a, v in zip(args, defaults) if a.arg in d and a.arg != "grasp_options"}
    assert shown and shown == {k: v for k, v in d.items() if k in shown}
