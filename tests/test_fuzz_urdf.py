"""URDF import under fuzzing: any text gives a robot or a clear ValueError, never a crash, a hang,
another exception type or a robot whose dynamics are not finite.

The property tests mutate coopsim's own exports (and a Drake-style one with rotor inertias) the
way a hand-edited or broken file differs: elements deleted or duplicated, attributes set to NaN,
inf, huge, empty or non-numeric values, links renamed into loops and branches, joint types
changed, the text cut short. tests/fuzz/fuzz_urdf.py is the coverage-guided (atheris) fuzzer of
the same function; test_coverage_guided_fuzzer_finds_no_crash_in_its_time runs it for a bounded time.
"""
from __future__ import annotations

import copy
import re
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import coopsim as cs
from conftest import random_robot

# repeatable or exploring by the suite's hypothesis profile (tests/conftest.py)
FUZZ = settings(deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

SEEDS = [cs.robots.scara1().to_urdf(), cs.robots.scara2().to_urdf(),
         random_robot(3, dof=3, armature=[0.01, 0.0, 0.02], coulomb=[0.1, 0.2, 0.0]).to_urdf(name="arm/ü")]

# characters XML 1.0 can hold: the mutations keep the file well-formed (cutting it short does not)
XML_CHARS = st.characters(blacklist_categories=("Cc", "Cs")) | st.sampled_from("\t\n\r")
# attribute values a broken file holds: not numbers, too few or too many, NaN, inf, huge, subnormal
HOSTILE = ["nan", "inf", "-inf", "1e308", "-1e308", "1e309", "4e-320", "0", "-0", "-1", "", " ", "abc", "1 2",
           "1 2 3 4", "nan 0 0", "0 inf 0", "1e308 1e308 1e308", "-1e308 1e308 -1e308", "0 0 0", "1e-300 0 0",
           "1e200 1e200 1e200", "0x10", "1_000", "١٢٣", "\u00a01", "1e18 0 0", "0 0 1e-18", "3.1415926 0 0"]
attribute_values = st.one_of(st.sampled_from(HOSTILE), st.sampled_from(HOSTILE),
                             st.floats(allow_nan=True, allow_infinity=True).map(repr),
                             st.lists(st.floats(-1e3, 1e3).map(repr), min_size=1, max_size=4).map(" ".join),
                             st.text(XML_CHARS, max_size=6))
JOINT_TYPES = ["revolute", "continuous", "prismatic", "fixed", "floating", "planar", "spherical", "", "REVOLUTE"]
TAGS = ["origin", "axis", "limit", "dynamics", "mimic", "inertial", "mass", "inertia", "geometry", "box", "link",
        "joint", "parent", "child", "collision", "visual", "transmission", "actuator", "drake:rotor_inertia"]
ATTRIBUTES = ["xyz", "rpy", "value", "name", "link", "type", "lower", "upper", "effort", "velocity", "damping",
              "friction", "size", "ixx", "ixy", "ixz", "iyy", "iyz", "izz", "joint"]


def _ignore_expected_warnings():
    """Inside a catch_warnings block: published-style inertias are warned about (InertiaWarning), a
    valid answer; any other warning (numpy's overflow, say) is an error, as in the test suite."""
    warnings.simplefilter("error")
    warnings.simplefilter("ignore", cs.InertiaWarning)


def _serialize(root) -> str:
    ET.register_namespace("drake", "http://drake.mit.edu")
    return ET.tostring(root, encoding="unicode")


@st.composite
def mutated_urdfs(draw):
    """The text of a coopsim export with up to six mutations."""
    root = ET.fromstring(draw(st.sampled_from(SEEDS)))
    for _ in range(draw(st.integers(0, 6))):
        elements = list(root.iter())
        el = draw(st.sampled_from(elements))
        kind = draw(st.sampled_from(["attr", "attr", "attr", "rename", "type", "delete", "duplicate", "drop",
                                     "add", "text"]))
        if kind == "attr":  # mostly a number of the file
            numbers = [e for e in elements if set(e.attrib) - {"name", "link", "type", "joint"}]
            el = draw(st.sampled_from(numbers)) if numbers and draw(st.booleans()) else el
            key = draw(st.sampled_from(sorted(el.attrib) or ATTRIBUTES))
            el.set(key, draw(attribute_values))
        elif kind == "rename":  # joints re-wired into loops, branches, self-loops; links renamed or duplicated
            names = [e.get("name", "") for e in root.findall("link")] + ["nowhere", ""]  # a dropped name reads ""
            target = draw(st.sampled_from([e for e in elements if e.tag in ("parent", "child", "link")] or [el]))
            target.set("link" if target.tag != "link" else "name", draw(st.sampled_from(names)))
        elif kind == "type":
            joints = root.findall("joint")
            if joints:
                draw(st.sampled_from(joints)).set("type", draw(st.sampled_from(JOINT_TYPES)))
        elif kind == "delete":
            for parent in root.iter():
                if el in list(parent):
                    parent.remove(el)
                    break
        elif kind == "duplicate":
            for parent in root.iter():
                if el in list(parent):
                    parent.append(copy.deepcopy(el))
                    break
        elif kind == "drop":
            if el.attrib:
                del el.attrib[draw(st.sampled_from(sorted(el.attrib)))]
        elif kind == "add":
            tag = draw(st.sampled_from(TAGS)).replace("drake:", "{http://drake.mit.edu}")
            child = ET.SubElement(el, tag)
            for key in draw(st.lists(st.sampled_from(ATTRIBUTES), max_size=3, unique=True)):
                child.set(key, draw(attribute_values))
        else:  # free text inside an element
            el.text = draw(st.text(XML_CHARS, max_size=5))
    text = _serialize(root)
    if draw(st.sampled_from([False] * 9 + [True])):  # cut short: not well-formed
        text = text[:draw(st.integers(0, len(text)))]
    return text


def check_import(text, **kw):
    """from_urdf(text) gives a robot whose dynamics are finite and which exports and imports again,
    or a ValueError with a message; returns the robot or None."""
    try:
        with warnings.catch_warnings():
            _ignore_expected_warnings()
            r = cs.from_urdf(text, **kw)
    except ValueError as e:
        assert str(e), "a ValueError must say what is wrong"
        return None
    assert isinstance(r, cs.Robot) and 1 <= r.dof <= 12
    assert np.all(np.isfinite(r.base)) and np.all(np.isfinite(r.tool.offset))
    q = np.zeros(r.dof)
    for call in (r.fk, r.mass_matrix, r.gravity):
        try:  # a clear error for a robot too large to compute with is fine, a NaN is not
            out = call(q)
        except ValueError as e:
            assert "not finite" in str(e) or "overflow" in str(e)
            continue
        assert np.all(np.isfinite(out)), "an imported robot must have finite kinematics and dynamics"
    # its own export reads back as the same chain
    with warnings.catch_warnings():
        _ignore_expected_warnings()
        back = cs.from_urdf(r.to_urdf())
    assert back.dof == r.dof and back.joint_types == r.joint_types
    np.testing.assert_allclose(back.masses, r.masses, rtol=1e-12)
    return r


@settings(FUZZ, max_examples=400)
@given(text=mutated_urdfs())
def test_fuzz_mutated_urdf(text):
    check_import(text)


@st.composite
def urdfs_with_hostile_numbers(draw):
    """A coopsim export whose numbers (1 to 3 attributes of origins, masses, inertias, limits,
    dynamics, boxes, axes) are NaN, inf, huge, tiny, negative or not numbers: the file stays a valid
    chain otherwise, so each value reaches the arithmetic."""
    root = ET.fromstring(draw(st.sampled_from(SEEDS)))
    numbers = [(e, k) for e in root.iter() for k in sorted(e.attrib) if k not in ("name", "link", "type", "joint")]
    for el, key in draw(st.lists(st.sampled_from(numbers), min_size=1, max_size=3, unique_by=lambda p: id(p))):
        el.set(key, draw(attribute_values))
    return _serialize(root)


@settings(FUZZ, max_examples=300)
@given(text=urdfs_with_hostile_numbers())
def test_fuzz_hostile_numbers_in_a_valid_chain(text):
    check_import(text)


@settings(FUZZ, max_examples=200)
@given(text=mutated_urdfs(), data=st.data())
def test_fuzz_import_arguments(text, data):
    """The keyword arguments, valid or not, on mutated files: a robot or ValueError / TypeError."""
    try:
        root = ET.fromstring(text)
        links = [e.get("name") or "" for e in root.iter("link")]
        joints = [e.get("name") or "" for e in root.iter("joint")]
    except ET.ParseError:
        links, joints = [], []
    names = st.sampled_from(links + joints + ["nowhere", ""]) | st.text(max_size=3)
    any_value = st.one_of(st.floats(), st.none(), st.text(max_size=3), st.integers(-2**70, 2**70),
                          st.lists(st.floats(), max_size=3))
    kw = {}
    if data.draw(st.booleans(), label="with tip"):
        kw["tip"] = data.draw(st.one_of(names, st.none(), st.integers()), label="tip")
    if data.draw(st.booleans(), label="with locked"):
        kw["locked"] = data.draw(st.one_of(st.dictionaries(names, st.floats(-4, 4) | any_value, max_size=3),
                                           st.none(), st.lists(names, max_size=2)), label="locked")
    if data.draw(st.booleans(), label="with snap"):
        kw["snap"] = data.draw(st.one_of(st.floats(), st.text(max_size=2), st.none()), label="snap")
    if data.draw(st.booleans(), label="with name"):
        kw["name"] = data.draw(st.one_of(st.text(max_size=4), st.none(), st.integers()), label="name")
    if data.draw(st.booleans(), label="with gravity"):
        kw["gravity"] = data.draw(st.one_of(st.lists(st.floats(), min_size=3, max_size=3), any_value),
                                  label="gravity")
    if data.draw(st.booleans(), label="with coulomb_width"):
        kw["coulomb_width"] = data.draw(any_value, label="coulomb_width")
    try:
        check_import(text, **kw)
    except TypeError as e:
        assert str(e)


@settings(FUZZ, max_examples=200)
@given(text=st.text(max_size=60) | st.binary(max_size=30))
def test_fuzz_any_text_or_bytes(text):
    try:
        with warnings.catch_warnings():
            _ignore_expected_warnings()
            cs.from_urdf(text)
    except ValueError as e:
        assert str(e)


# ---- the coverage-guided fuzzer, for a bounded time ---------------------------------------------

FUZZ_DIR = Path(__file__).parent / "fuzz"


@pytest.mark.slow
def test_coverage_guided_fuzzer_finds_no_crash_in_its_time(tmp_path):
    """atheris (libFuzzer) mutates coopsim's exports for 25 s (at most 100 000 inputs, each within
    5 s): no exception but ValueError, no warning, no hang; and the mutations reach code the seeds
    do not (coverage grows)."""
    pytest.importorskip("atheris")
    if cs.build_info()["sanitizers"]:
        pytest.skip("against the sanitized engine (scripts/test_sanitized.sh) the preloaded GCC sanitizer runtimes "
                    "provide the coverage hooks libFuzzer needs, and atheris sees no coverage; the plain run fuzzes")
    corpus = tmp_path / "corpus"
    harness = str(FUZZ_DIR / "fuzz_urdf.py")
    subprocess.run([sys.executable, harness, "--seeds", str(corpus)], check=True, capture_output=True, timeout=120)
    args = [sys.executable, harness, "-max_total_time=25", "-runs=100000", "-timeout=5", "-rss_limit_mb=2048",
            "-seed=1", f"-dict={FUZZ_DIR / 'urdf.dict'}", "-print_final_stats=1", f"-artifact_prefix={tmp_path}/",
            str(corpus)]
    run = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    report = run.stderr
    crashes = sorted(str(p) for p in tmp_path.iterdir() if p.name.startswith(("crash-", "timeout-", "oom-")))
    assert run.returncode == 0 and not crashes, f"the fuzzer found a failure, saved as {crashes}:\n{report[-4000:]}"
    start = re.search(r"INITED cov: (\d+)", report)
    end = re.search(r"DONE +cov: (\d+)", report)
    runs = re.search(r"Done (\d+) runs in (\d+) second", report)
    assert start and end and runs, report[-2000:]
    assert int(end.group(1)) > int(start.group(1)), "the mutations reached no new branch of the import"
    print(f"atheris: {runs.group(1)} inputs in {runs.group(2)} s, coverage {start.group(1)} -> {end.group(1)} edges")


def test_inputs_the_fuzzer_once_broke_on_are_handled():
    """Every input in tests/fuzz/regressions (saved from the fuzzer's findings) goes through the harness's
    check: a robot or a clear ValueError, no warning. common_normal_out_of_range: joint axes whose common
    normal overflowed gave numpy's 'invalid value encountered in scalar divide'."""
    import importlib.util

    pytest.importorskip("atheris")  # the harness imports it
    spec = importlib.util.spec_from_file_location("fuzz_urdf_harness", FUZZ_DIR / "fuzz_urdf.py")
    harness = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(harness)
    files = sorted((FUZZ_DIR / "regressions").iterdir())
    assert files
    for f in files:
        harness.check(f.read_bytes())
