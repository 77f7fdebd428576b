"""Coverage-guided fuzzing of the URDF import (coopsim.urdf.from_urdf) with atheris (libFuzzer).

    python tests/fuzz/fuzz_urdf.py --seeds CORPUS          # writes the seed corpus, then exits
    python tests/fuzz/fuzz_urdf.py -max_total_time=25 -dict=tests/fuzz/urdf.dict CORPUS
    python tests/fuzz/fuzz_urdf.py crash-<hash>            # runs one saved input again

An input is one byte choosing keyword arguments (bit 0: tip, a name the text holds; bit 1:
snap=0; bit 2: locked, a name the text holds, at 0.3; the higher bits pick the names), then URDF
text (UTF-8, undecodable bytes replaced). The seeds are coopsim's own exports of its robots (the
SCARAs and random arms, one with Drake's rotor inertias). Half of the mutations are libFuzzer's on
the bytes; the other half parse the text and change one thing a hand-edited file gets wrong (an
attribute set to a dictionary word, its numbers scaled by 0, -1 or 1e-300 .. 1e300, or libFuzzer's
mutation of its value; a link or joint re-wired or renamed, an element deleted or duplicated, a
joint's type), so that most inputs stay
well-formed and reach the import's arithmetic. Coverage of coopsim's Python (atheris instruments
it) guides which inputs are kept.

The property: from_urdf returns a robot whose base, tool and fk(0) are finite (or fk says that
its result is not finite), or raises ValueError with a message; an InertiaWarning is a valid
answer. Anything else (another exception type, a warning such as numpy's overflow, a hang caught
by -timeout) is reported by libFuzzer as a crash, with the input saved (-artifact_prefix).
"""
from __future__ import annotations

import os
import random
import re
import sys
import warnings
import xml.etree.ElementTree as ET

import atheris

with atheris.instrument_imports(include=["coopsim"]):
    import coopsim as cs
    from coopsim import urdf

import numpy as np

_NAME = re.compile(r'name="([^"]{1,40})"')
_DRAKE = "http://drake.mit.edu"
_WORDS = ["nan", "inf", "-inf", "1e308", "-1e308", "1e12", "1e13", "4e-320", "0", "-0", "-1", "", "abc", "1 2",
          "1 2 3 4", "0 0 0", "1e300 0 0", "0 nan 0", "3.141592653589793 0 0", "revolute", "continuous",
          "prismatic", "fixed", "floating"]


def seeds() -> dict:
    """File name -> input: a zero byte (no keywords), then an export of one of coopsim's robots."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    from conftest import random_robot

    texts = {"scara1": cs.robots.scara1().to_urdf(), "scara2": cs.robots.scara2().to_urdf(),
             "arm_drake": random_robot(3, dof=3, armature=[0.01, 0.0, 0.02], coulomb=[0.1, 0.2, 0.0]).to_urdf()}
    for seed in (1, 7):
        texts[f"random{seed}"] = random_robot(seed, mixed=True).to_urdf()
    return {f"{k}.urdf": b"\0" + v.encode() for k, v in texts.items()}


def _decode(data: bytes):
    """(keyword arguments, text) of an input."""
    if not data:
        return {}, ""
    pick, text = data[0], data[1:].decode("utf-8", errors="replace")
    names = _NAME.findall(text)
    kw = {}
    if pick & 1 and names:
        kw["tip"] = names[(pick >> 3) % len(names)]
    if pick & 2:
        kw["snap"] = 0.0
    if pick & 4 and names:
        kw["locked"] = {names[(pick >> 5) % len(names)]: 0.3}
    return kw, text


def check(data: bytes) -> None:
    kw, text = _decode(data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", cs.InertiaWarning)
        try:
            robot = urdf.from_urdf(text, **kw)
        except ValueError as e:
            if not str(e):
                raise AssertionError("a ValueError without a message") from e
            return
        if not (np.all(np.isfinite(robot.base)) and np.all(np.isfinite(robot.tool.offset))):
            raise AssertionError(f"an imported robot with a non-finite base or tool: {robot!r}")
        try:
            T = robot.fk(np.zeros(robot.dof))
        except ValueError as e:  # too large to compute with: a clear error is fine, NaN is not
            if "not finite" not in str(e):
                raise
            return
        if not np.all(np.isfinite(T)):
            raise AssertionError("an imported robot whose fk(0) is not finite")


def _rescale(value: str, factor: float) -> str:
    out = []
    for word in value.split():
        try:
            out.append(repr(float(word) * factor))
        except (ValueError, OverflowError):
            out.append(word)
    return " ".join(out)


def _mutate_tree(root, rng: random.Random, max_size: int) -> None:
    elements = list(root.iter())
    with_attributes = [e for e in elements if e.attrib]
    kind = rng.randrange(20)
    if kind < 10 and with_attributes:  # an attribute: a dictionary word, its numbers scaled, libFuzzer's mutation
        el = rng.choice(with_attributes)
        key = rng.choice(sorted(el.attrib))
        if kind < 3:
            el.set(key, rng.choice(_WORDS))
        elif kind < 7:
            el.set(key, _rescale(el.get(key), rng.choice([0.0, -1.0, 1e-300, 1e-9, 10.0, 1e3, 1e9, 1e12, 1e300])))
        else:
            value = atheris.Mutate(el.get(key).encode(), max(16, min(64, max_size)))
            el.set(key, value.decode("utf-8", errors="replace"))
    elif kind < 13:  # re-wire: a parent or child names another link, or a link or joint takes another's name
        links = [e.get("name") or "" for e in root.iter("link")] or ["a"]
        target = rng.choice([e for e in elements if e.tag in ("parent", "child", "link", "joint")] or elements)
        target.set("name" if target.tag in ("link", "joint") else "link", rng.choice(links))
    elif kind < 17:  # delete or duplicate an element
        el = rng.choice(elements[1:] or elements)
        for parent in elements:
            if el in list(parent):
                if kind < 15:
                    parent.remove(el)
                else:
                    parent.append(ET.fromstring(ET.tostring(el)))
                break
    else:  # a joint's type
        joints = root.findall("joint")
        if joints:
            rng.choice(joints).set("type", rng.choice(["revolute", "continuous", "prismatic", "fixed", "planar"]))


def mutate(data: bytes, max_size: int, seed: int) -> bytes:
    rng = random.Random(seed)
    if len(data) < 2 or rng.random() < 0.5:
        return atheris.Mutate(data, max_size)
    try:
        root = ET.fromstring(data[1:].decode("utf-8"))
    except (ET.ParseError, UnicodeError):
        return atheris.Mutate(data, max_size)
    pick = rng.randrange(256) if rng.random() < 0.1 else data[0]
    try:
        _mutate_tree(root, rng, max_size)
        ET.register_namespace("drake", _DRAKE)
        out = bytes([pick]) + ET.tostring(root, encoding="unicode").encode("utf-8", errors="replace")
    except (ValueError, ET.ParseError):  # text no XML can hold (libFuzzer's bytes): keep the byte mutation
        return atheris.Mutate(data, max_size)
    return out if len(out) <= max_size else atheris.Mutate(data, max_size)


def main(argv) -> None:
    if len(argv) == 3 and argv[1] == "--seeds":
        os.makedirs(argv[2], exist_ok=True)
        for name, data in seeds().items():
            with open(os.path.join(argv[2], name), "wb") as f:
                f.write(data)
        return
    atheris.Setup(argv, check, custom_mutator=mutate)
    atheris.Fuzz()


if __name__ == "__main__":
    main(sys.argv)
