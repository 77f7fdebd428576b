"""The stamp of every report (coopsim.stamp): what made an output, written by the one function behind the
handover's, the carry's and the sweeps' report.json."""
from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import coopsim as cs
from coopsim import stamp as S
from coopsim.tasks.handover import report as HR

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_the_stamp_names_version_build_python_numpy_machine_seed_and_arguments():
    s = S.stamp(seed=[0, 1, 2], arguments=dict(out="out", speed=1.5, names=("a", "b"), seed=np.int64(3)))
    assert s["coopsim"] == cs.__version__
    assert s["python"] == platform.python_version() and s["numpy"] == np.__version__
    assert s["machine"] == platform.machine() and s["platform"] == platform.platform()
    assert s["seed"] == [0, 1, 2]
    assert s["arguments"] == dict(out="out", speed=1.5, names=["a", "b"], seed=3)   # JSON's values
    b = s["build"]
    assert b["optimised"] == cs.build_info()["optimised"] and b["sanitizers"] == cs.build_info()["sanitizers"]
    assert b["compiler"] and b["compiler_version"] and b["build_type"] and b["eigen"].count(".") == 2
    assert b["cxx_standard"] >= 201703 and b["pybind11"].count(".") == 2
    # a Release build says so in its flags (CMake's), and a sanitized one names its sanitizers there
    if b["build_type"] == "Release":
        assert "-O" in b["flags"]
    if b["sanitizers"]:
        assert "-fsanitize=" in b["flags"]
    assert json.loads(json.dumps(s)) == s


@pytest.mark.skipif(shutil.which("git") is None or not os.path.exists(os.path.join(ROOT, ".git")),
                    reason="needs git and a checkout")
def test_the_stamp_names_the_checkout_s_commit_when_run_from_one():
    if S._checkout_root() is None:
        pytest.skip("coopsim is imported from an installed package here, not from the checkout")
    head = subprocess.run(["git", "-C", ROOT, "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    g = S.stamp()["git"]
    assert g["commit"] == head and isinstance(g["dirty"], bool)


def test_no_commit_outside_a_checkout_or_without_git(tmp_path, monkeypatch):
    assert S.git_commit(str(tmp_path)) is None                      # a folder that is no checkout
    monkeypatch.setattr(S, "_PACKAGE", str(tmp_path / "site-packages" / "coopsim"))
    assert S._checkout_root() is None and S.stamp()["git"] is None  # an installed package
    monkeypatch.setenv("PATH", str(tmp_path))                       # no git at all
    assert S.git_commit(ROOT) is None


def test_every_report_written_carries_the_stamp(tmp_path):
    p = HR.write_report(dict(seed=7, success=True), tmp_path / "report.json", arguments=dict(cycles=1))
    rep = json.loads(Path(p).read_text())
    assert rep["success"] and rep["stamp"]["seed"] == 7 and rep["stamp"]["arguments"] == dict(cycles=1)
    p = HR.write_report(dict(runs=[]), tmp_path / "sweep.json", seed=[0, 1])
    assert json.loads(Path(p).read_text())["stamp"]["seed"] == [0, 1]
