"""The documentation cannot rot: every ```python block of README.md and docs/*.md runs.

Each file's blocks run in order in one namespace (a block may use what an earlier one of the same file
defined), in a fresh working directory, with MPLBACKEND=Agg, in a process of their own. Two
conventions, written as the block's first line so that a reader sees them too:

- ``# slow: <why>``: the block takes more than a few seconds. The fast test runs a file's other blocks
  (which must not need it); a test marked slow runs the whole file with it.
- ``# not run: <why>``: the block cannot run here (it needs a machine or service a test does not
  have). It is compiled, so its syntax is checked, but not executed. Such blocks are few and each says
  why.

Blocks in other languages (```bash, plain ```) are not run.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = os.path.join(ROOT, "docs")
FILES = ["README.md"] + sorted(os.path.join("docs", f) for f in os.listdir(DOCS) if f.endswith(".md"))
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", flags=re.S | re.M)
MARK = re.compile(r"^# (slow|not run): (.+)$")
MAX_NOT_RUN = 3          # in all the documentation
README_MAX_LINES = 200


def blocks(name: str) -> list[dict]:
    """The fenced blocks of a file: language, first line number of the code (1-based), code, and the
    block's mark ('slow', 'not run' or None) with its reason."""
    with open(os.path.join(ROOT, name), encoding="utf-8") as f:
        text = f.read()
    out = []
    for m in FENCE.finditer(text):
        code = m.group(2)
        first = code.split("\n", 1)[0]
        mark = MARK.match(first)
        out.append(dict(lang=m.group(1).strip(), line=text.count("\n", 0, m.start(2)) + 1, code=code,
                        mark=mark.group(1) if mark else None, why=mark.group(2).strip() if mark else None))
    return out


def python_blocks(name: str) -> list[dict]:
    return [b for b in blocks(name) if b["lang"] == "python"]


RUNNER = r'''
import json, os, sys, traceback

def main():
    todo = json.load(open(sys.argv[1], encoding="utf-8"))
    namespace = {"__name__": "__main__"}
    for b in todo:
        code = compile("\n" * (b["line"] - 1) + b["code"], b["file"], "exec")
        if b["mark"] == "not run":
            continue
        print(f"--- {b['file']}:{b['line']}", flush=True)
        exec(code, namespace)

if __name__ == "__main__":
    main()
'''


def run_file(name: str, tmp_path, with_slow: bool) -> None:
    todo = [dict(b, file=os.path.join(ROOT, name)) for b in python_blocks(name) if with_slow or b["mark"] != "slow"]
    (tmp_path / "blocks.json").write_text(json.dumps(todo), encoding="utf-8")
    (tmp_path / "run_blocks.py").write_text(RUNNER, encoding="utf-8")
    work = tmp_path / "work"
    work.mkdir()
    env = dict(os.environ, MPLBACKEND="Agg", COOPSIM_CACHE_DIR=str(tmp_path / "cache"))
    res = subprocess.run([sys.executable, str(tmp_path / "run_blocks.py"), str(tmp_path / "blocks.json")],
                         cwd=work, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, f"a block of {name} failed:\n{res.stdout[-3000:]}\n{res.stderr[-6000:]}"
    # no warning reaches a reader who copies a block (the suite's warnings are errors too)
    assert "Warning" not in res.stderr, res.stderr[-6000:]


WITH_PYTHON = [f for f in FILES if python_blocks(f)]
WITH_SLOW = [f for f in WITH_PYTHON if any(b["mark"] == "slow" for b in python_blocks(f))]


@pytest.mark.parametrize("name", WITH_PYTHON)
def test_the_python_blocks_run(name, tmp_path):
    run_file(name, tmp_path, with_slow=False)


@pytest.mark.slow
@pytest.mark.parametrize("name", WITH_SLOW)
def test_the_python_blocks_run_with_the_slow_ones(name, tmp_path):
    run_file(name, tmp_path, with_slow=True)


def test_blocks_not_run_are_few_and_say_why():
    marked = [(f, b) for f in FILES for b in python_blocks(f) if b["mark"]]
    not_run = [(f, b) for f, b in marked if b["mark"] == "not run"]
    assert len(not_run) <= MAX_NOT_RUN, [f"{f}:{b['line']}" for f, b in not_run]
    for f, b in marked:
        assert len(b["why"].split()) >= 4, f"{f}:{b['line']}: say why the block is {b['mark']}"
    for f, b in not_run:  # still valid Python
        compile(b["code"], f"{f}:{b['line']}", "exec")
    # a mark anywhere but on the first line would be silently ignored
    for f in FILES:
        for b in python_blocks(f):
            later = [ln for ln in b["code"].split("\n")[1:] if MARK.match(ln)]
            assert not later, f"{f}:{b['line']}: a block's mark goes on its first line"


def test_every_fence_has_a_language_and_most_code_runs():
    for f in FILES:
        for b in blocks(f):
            assert b["lang"], f"{f}:{b['line']}: say the block's language (python, bash, text)"
    assert sum(len(python_blocks(f)) for f in FILES) >= 10  # the reader finds the blocks


def test_the_readme_is_short_and_maps_every_page_of_the_docs():
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        text = f.read()
    assert text.count("\n") <= README_MAX_LINES
    # the two quick-start commands, as they are
    assert "bash scripts/demo.sh" in text and "bash scripts/test.sh" in text
    linked = set(re.findall(r"\]\((docs/[^)#]+\.md)(?:#[^)]*)?\)", text))
    assert linked == {f for f in FILES if f.startswith("docs")}, linked


def test_relative_links_lead_to_files():
    for f in FILES:
        with open(os.path.join(ROOT, f), encoding="utf-8") as fh:
            text = fh.read()
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = os.path.normpath(os.path.join(ROOT, os.path.dirname(f), target.split("#")[0]))
            assert os.path.exists(path), f"{f}: link to {target}"


def knot_acceleration_jumps(traj):
    """Largest |qdd(t_k+) - qdd(t_k-)| over the interior knots, rad/s^2, from the segments' coefficients
    (exact: qdd of segment k is 2 c2 + 6 c3 tau)."""
    c, h = traj.coefficients, np.diff(traj.times)
    left = 2 * c[:-1, :, 2] + 6 * c[:-1, :, 3] * h[:-1, None]   # end of segment k-1
    right = 2 * c[1:, :, 2]                                        # start of segment k
    return np.abs(right - left).max()


def test_the_smooth_tool_speed_example_has_continuous_joint_acceleration():
    # the planning page's example, as written there, up to its "smooth tool speed" line
    code = python_blocks(os.path.join("docs", "planning-and-control.md"))[0]["code"]
    lines = code.split("\n")
    at = next(i for i, line in enumerate(lines) if "# smooth tool speed" in line)
    assert "spline=True" in lines[at], lines[at]
    namespace = {}
    exec("\n".join(lines[:at + 1]), namespace)
    traj = namespace["traj"]
    assert traj.segments == 13 and traj.velocity_rule == "spline"
    # acceleration continuous at the knots (so the computed-torque torque has no jumps)
    assert knot_acceleration_jumps(traj) < 1e-6
    # the same plan without the spline steps by about 2 rad/s^2: what the test would catch
    heuristic = eval(lines[at].split("=", 1)[1].split("#")[0].replace(", spline=True", ""), namespace)
    assert heuristic.velocity_rule == "heuristic"
    assert knot_acceleration_jumps(heuristic) > 1.0
    # both pass through the same poses (only the knot velocities differ)
    np.testing.assert_allclose(traj.q_points, heuristic.q_points, atol=1e-12)
