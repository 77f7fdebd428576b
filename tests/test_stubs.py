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
