"""Fuzzing the world and what uses it: worlds and their bodies, simulations with a world (contacts,
their log and events, applied wrenches, the clamp grasp), the load-sharing functions of
coopsim.grasp, and the views and files written from logs (replay_html, animate, to_csv), given
garbage logs and bad paths.

The property, as in test_bad_input.py: each example takes valid arguments and spoils some of
them with anything (NaN, inf, huge, negative, wrong shapes or types, hostile names and paths);
the answer is a valid result or a clear exception (ValueError or TypeError with a message naming
the argument when one argument is spoiled; DivergenceError naming the step of a run), never a
crash, another exception type (IndexError, KeyError, numpy's own errors ...), a warning, or NaN
for finite input. With nothing spoiled the call succeeds.
"""
from __future__ import annotations

import os
import pickle
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import coopsim as cs
from coopsim import grasp, view
from coopsim.log import STORED, BodyLog, RobotLog, SimulationLog
from test_bad_input import any_float, anything, c_int, draw_arguments, finite_floats, rigid_poses, vectors

# repeatable or exploring by the suite's hypothesis profile (tests/conftest.py)
FUZZ = settings(deadline=None, max_examples=100,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])

KINDS = {"self", "robot-robot", "robot-scenery", "robot-body", "body-scenery", "body-body"}
# a scalar of any value or type
junk = st.one_of(any_float, st.integers(-2**70, 2**70), st.text(max_size=3), st.none(), st.booleans(),
                 st.lists(any_float, max_size=2), st.complex_numbers(max_magnitude=10))
# names: any text (NUL, combining marks, right-to-left, emoji ...), lone surrogates, the floor's, paths
names = st.one_of(st.text(max_size=6), st.sampled_from(["", "floor", "bar", "a/b", "\x00", "é☃", "\u202eab",
                                                        "x" * 300]),
                  st.text(st.characters(categories=["Cs"]), min_size=1, max_size=2))
# (bytes that are not UTF-8 are left out: the world takes them and then cannot give its names back,
# see test_a_name_of_bytes_that_are_not_utf8_is_refused)
bad_names = st.one_of(names, st.none(), st.integers(), st.lists(st.text(max_size=2)),
                      st.binary(max_size=3).filter(lambda b: b.isascii()))


def clear(call, spoiled=(), aliases=None):
    """call()'s result, or None when it raised ValueError or TypeError with a message that, when one
    argument is spoiled, names it (or one of its `aliases`). Any warning is an error."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            # end stops too stiff for a large dt are warned about: a valid answer (tests/test_student.py)
            warnings.filterwarnings("ignore", message="the end stops", category=RuntimeWarning)
            return call()
    except (ValueError, TypeError) as e:
        message = str(e)
        assert message, "an error must say what is wrong"
        if len(spoiled) == 1:
            (name,) = spoiled
            words = (aliases or {}).get(name, (name,))
            assert any(w in message for w in words), f"the error does not name {name!r}: {message}"
        return None


def finite(*arrays):
    for a in arrays:
        assert np.all(np.isfinite(np.asarray(a, dtype=float))), "a result must never be NaN or inf"


def unit_quaternions():
    return vectors(4, -1, 1).filter(lambda v: np.linalg.norm(v) > 0.1).map(lambda v: v / np.linalg.norm(v))


def rotation(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


# ---- the world's options ----------------------------------------------------------------------

@FUZZ
@given(data=st.data())
def test_fuzz_world_options(data):
    good = dict(floor=st.booleans(), gravity=vectors(3, -20, 20), floor_friction=finite_floats(0, 2),
                floor_restitution=finite_floats(0, 1), solver_iterations=st.integers(1, 50))
    bad = dict(floor=st.one_of(st.text(max_size=2), st.lists(st.booleans(), min_size=2, max_size=3)),
               gravity=anything, floor_friction=junk, floor_restitution=junk,
               solver_iterations=st.one_of(c_int, st.integers(2**31, 2**70), junk))
    args, spoiled = draw_arguments(data, good, bad)
    w = clear(lambda: cs.World(**args), spoiled)
    assert w is not None or spoiled
    if w is None:
        return
    finite(w.gravity)
    assert w.floor == bool(args["floor"]) and w.body_names == (["floor"] if w.floor else [])
    np.testing.assert_array_equal(w.gravity, np.asarray(args["gravity"], dtype=float))
    again = pickle.loads(pickle.dumps(w))
    assert again.body_names == w.body_names and again.floor == w.floor


# ---- bodies ------------------------------------------------------------------------------------

POSE_FORMS = ["pose", "position", "position+quaternion"]


class _Data:
    """draw_arguments draws from a `data` object; inside a composite strategy `draw` is a function."""

    def __init__(self, draw):
        self.draw = lambda strategy, label=None: draw(strategy)


@st.composite
def body_calls(draw, free):
    """(keyword arguments of add_static_box / add_free_box, the spoiled ones, the expected pose)."""
    form = draw(st.sampled_from(POSE_FORMS + ["pose and position", "no pose"]))
    good = dict(name=st.text(min_size=1, max_size=6), half_extents=vectors(3, 1e-3, 0.5),
                friction=finite_floats(0, 2), restitution=finite_floats(0, 1))
    bad = dict(name=bad_names, half_extents=st.one_of(anything, vectors(3, -1e6, 1e6)), friction=junk,
               restitution=junk)
    if free:
        good |= dict(mass=finite_floats(1e-3, 1e3), velocity=vectors(3, -5, 5), angular_velocity=vectors(3, -5, 5))
        bad |= dict(mass=junk, velocity=anything, angular_velocity=anything)
    if form in ("pose", "pose and position"):
        good["pose"] = rigid_poses()
        # not rigid: scaled, sheared or mirrored rotations, a wrong last row
        bad["pose"] = st.one_of(anything, rigid_poses().map(lambda T: T * [[1], [1.01], [1], [1]]),
                                rigid_poses().map(lambda T: T @ np.diag([-1.0, 1, 1, 1])),
                                rigid_poses().map(lambda T: T + np.eye(4)[[3]] * 0.5))
    if form != "pose" and form != "no pose":
        good["position"] = vectors(3, -2, 2)
        bad["position"] = st.one_of(anything, vectors(3, -1e7, 1e7))
    if form == "position+quaternion":
        good["quaternion"] = unit_quaternions()
        bad["quaternion"] = st.one_of(anything, vectors(4, -2, 2))
    args, spoiled = draw_arguments(_Data(draw), good, bad)
    T = np.eye(4)  # the pose the body should have, when the arguments make one
    try:
        if "pose" in args:
            T = np.array(args["pose"], dtype=float).reshape(4, 4)
        else:
            if "position" in args:
                T[:3, 3] = np.asarray(args["position"], dtype=float).reshape(3)
            if "quaternion" in args:
                T[:3, :3] = rotation(np.asarray(args["quaternion"], dtype=float).reshape(4))
    except (ValueError, TypeError):
        T = None
    if form in ("pose and position", "no pose"):
        spoiled = spoiled | {form}
    return args, spoiled, T


BODY_ALIASES = {"pose and position": ("not both",), "no pose": ("needs a pose",), "name": ("name",),
                "position": ("position", "pose"), "quaternion": ("quaternion",), "pose": ("pose",),
                "half_extents": ("half_extents", "half extents"), "velocity": ("velocit",),
                "angular_velocity": ("velocit",)}


def add_body(w, free, args):
    kw = dict(args)
    name, he = kw.pop("name"), kw.pop("half_extents")
    if free:
        mass = kw.pop("mass")
        return w.add_free_box(name, he, mass, **kw)
    return w.add_static_box(name, he, **kw)


def sane(spec):
    """Within the ranges the engine simulates correctly (see the xfail tests at the end)."""
    return spec["kind"] != "free" or (spec["mass"] <= 1e6 and np.abs(spec["velocity"]).max() <= 1e3
                                      and np.abs(spec["angular_velocity"]).max() <= 1e3)


def check_world_run(sim, log):
    w = sim.world
    for name in w.body_names:
        if w.body(name)["kind"] in ("static", "free"):
            s = sim.body_state(name)
            finite(s.pose, s.velocity, s.angular_velocity)
    for c in sim.contacts():
        assert c.kind in KINDS and c.a in w.body_names and c.b in w.body_names
        finite(c.point_a, c.point_b, c.normal, c.depth, c.force)
    for b in log.bodies.values():
        finite(b.data)
    ev = log.contacts
    assert set(ev["kind"]) <= KINDS
    finite(ev["begin"], ev["peak_force"], ev["max_depth"], ev["steps"])
    assert np.all(np.isnan(ev["end"]) | (ev["end"] >= ev["begin"]))
    if log.contact_points is not None:
        finite(log.contact_points.drop(columns=["a", "b"]).to_numpy(dtype=float))
    finite(log.to_dataframe().to_numpy(dtype=float))


@settings(FUZZ, max_examples=60)
@given(data=st.data())
def test_fuzz_world_bodies(data):
    w = cs.World()
    for _ in range(data.draw(st.integers(1, 5), label="bodies")):
        free = data.draw(st.booleans(), label="free")
        args, spoiled, T = data.draw(body_calls(free), label="body")
        before = list(w.body_names)
        if isinstance(args["name"], str) and args["name"] in before:
            spoiled = spoiled | {"name"}  # a name already in the world
        i = clear(lambda: add_body(w, free, args), spoiled, BODY_ALIASES)
        assert i is not None or spoiled
        if i is None:
            assert w.body_names == before, "a refused body must leave the world as it was"
            continue
        assert i == len(before) and w.body_names[:-1] == before
        d = w.body(w.body_names[-1])
        if isinstance(args["name"], str):  # any text, kept as it is
            assert w.body_names[-1] == d["name"] == args["name"]
        assert d["kind"] == ("free" if free else "static")
        np.testing.assert_array_equal(d["half_extents"], np.asarray(args["half_extents"], dtype=float))
        assert d["friction"] == float(args["friction"]) and d["restitution"] == float(args["restitution"])
        if T is not None:
            np.testing.assert_allclose(d["pose"], T, rtol=0, atol=1e-12 * max(1.0, np.abs(T).max()))
        if free:
            assert d["mass"] == float(args["mass"]) and d["mass"] > 0
    again = pickle.loads(pickle.dumps(w))
    assert again.body_names == w.body_names
    for name in w.body_names:
        a, b = w.body(name), again.body(name)
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    specs = [w.body(n) for n in w.body_names]
    if not all(sane(s) for s in specs):
        return
    sim = cs.Simulation(dt=2e-4, world=w, log_every=5, log_contacts=True)
    log = sim.run(0.004, progress=False)
    check_world_run(sim, log)


# ---- a simulation with a world: robot, contacts, applied wrenches, the grasp -----------------

SCARA = cs.robots.scara1()
LIMITS = SCARA.q_limits
GRASP_RANGES = dict(hold_time=(0, 0.01), gap=(0, 0.005), penetration=(0, 0.005), angle=(0, 0.5), speed=(0, 0.5),
                    angular_speed=(0, 2), open_margin=(0, 0.005), slip=(0, 0.02), weld_omega_dt=(0.01, 0.5),
                    release_time=(0, 0.2))
inside = vectors(6, 0, 1).map(lambda u: LIMITS[:, 0] + 0.1 + u * (LIMITS[:, 1] - LIMITS[:, 0] - 0.2))
indices = st.one_of(st.integers(-2, 2), junk)


@st.composite
def grasp_options(draw):
    keys = draw(st.sets(st.sampled_from(sorted(GRASP_RANGES) + ["weld_moment"]), max_size=4))
    return {k: draw(st.booleans() if k == "weld_moment" else finite_floats(*GRASP_RANGES[k])) for k in keys}


bad_grasp_options = st.one_of(
    anything, st.dictionaries(st.one_of(st.sampled_from(sorted(GRASP_RANGES) + ["weld_moment"]), st.text(max_size=3),
                                        st.integers(), st.none()), junk, min_size=1, max_size=3))


@st.composite
def wrenches(draw):
    """A list of Wrench, valid or spoiled, or junk where the list goes."""
    kind = draw(st.sampled_from(["link", "tool", "junk"]))
    if kind == "junk":
        return draw(st.one_of(anything, st.lists(junk, max_size=2)))
    if kind == "tool":
        return [cs.Wrench.at_tool(draw(vectors(6, -10, 10)))]
    link = draw(st.one_of(st.integers(1, 6), st.integers(-6, -1), c_int))
    point, wrench = draw(st.one_of(vectors(3, -1, 1), anything)), draw(st.one_of(vectors(6, -10, 10), anything))
    made = clear(lambda: cs.Wrench(link, point, wrench))
    return [made] if made is not None else [point]


def step(sim, n):
    """sim.step(n): True, or False when it diverged (a DivergenceError naming the step, or once
    diverged, a RuntimeError saying so)."""
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="the end stops", category=RuntimeWarning)
            sim.step(n)
        return True
    except cs.DivergenceError as e:
        assert "step" in str(e)
        return False
    except RuntimeError as e:
        assert sim.diverged and "diverged" in str(e), e
        return False
    except ValueError as e:  # a state the world cannot hold (a link beyond 1e6 m), named
        assert "link body" in str(e), e
        return False


def world_with_bodies():
    w = cs.World()
    w.add_static_box("table", [0.1, 0.1, 0.05], position=[0.45, 0.0, 0.05])
    w.add_free_box("bar", [0.05, 0.015, 0.01], 0.1, position=[0.35, 0.2, 0.01], friction=0.5)
    w.add_free_box("cube", [0.02, 0.02, 0.02], 0.05, position=[0.45, 0.0, 0.12])
    return w


@settings(FUZZ, max_examples=60)
@given(data=st.data())
def test_fuzz_simulation_with_a_world(data):
    good = dict(dt=finite_floats(1e-4, 5e-4), world_every=st.integers(1, 4), contact_forces=st.booleans(),
                log_contacts=st.booleans(), grasp=st.booleans(), grasp_options=grasp_options())
    bad = dict(dt=junk, world_every=st.one_of(c_int, junk), contact_forces=st.one_of(st.text(max_size=2)),
               log_contacts=st.text(max_size=2), grasp=st.text(max_size=2), grasp_options=bad_grasp_options)
    args, spoiled = draw_arguments(data, good, bad)
    sim = clear(lambda: cs.Simulation(world=world_with_bodies(), log_every=5, **args), spoiled)
    assert sim is not None or spoiled
    if sim is None:
        return
    # a robot with its reference and initial state, valid or not
    robot_args, robot_spoiled = draw_arguments(data, dict(reference=inside, q0=st.one_of(st.none(), inside)),
                                               dict(reference=anything, q0=anything))
    i = clear(lambda: sim.add_robot(SCARA, cs.PID(200.0, 0.0, 20.0), robot_args["reference"], q0=robot_args["q0"]),
              robot_spoiled)
    assert i is not None or robot_spoiled
    ok = step(sim, data.draw(st.integers(1, 20), label="steps"))
    assert ok or i is None or robot_spoiled or spoiled, "a valid simulation must not diverge"
    names = sim.world.body_names
    # the world's bodies are not checked for divergence: a step far too large gives NaN silently
    # (test_a_world_step_far_too_large_is_refused_or_diverges); only the types of the answers are checked then
    check = finite if sim.dt <= 1e-2 else (lambda *a: None)
    # every query with a valid or a spoiled argument
    name = data.draw(st.one_of(st.sampled_from(names), bad_names), label="name")
    r = data.draw(indices, label="robot")
    for call, spoiled_args in ((lambda: sim.body_state(name), {"name"}), (lambda: sim.holding(r), {"robot"}),
                               (lambda: sim.weld_wrench(r), {"robot"}), (lambda: sim.grasp_check(r, name), set()),
                               (lambda: sim.release(r), {"robot"})):
        out = clear(call, spoiled_args, {"name": ("name", "body", "robot's link", "free bod"),
                                         "robot": ("robot", "incompatible function arguments")})
        if isinstance(out, dict):
            check(*[v for v in out.values() if not isinstance(v, (bool, np.bool_))])
        elif isinstance(out, np.ndarray):
            check(out)
        elif isinstance(out, str):
            assert out in names
    for c in clear(lambda: sim.contacts()) or []:
        assert c.kind in KINDS
        check(c.point_a, c.point_b, c.normal, c.depth, c.force)
    # applied forces and wrenches, valid or not, then more steps
    if sim.robot_count:
        forces = data.draw(st.one_of(st.none(), vectors(6, -5, 5), anything), label="forces")
        ws = data.draw(st.one_of(st.none(), wrenches()), label="wrenches")
        clear(lambda: sim.set_applied(0, forces=forces, wrenches=ws))
        applied = sim.applied(0)
        finite(applied["forces"], applied["tau_ext"])
    if step(sim, data.draw(st.integers(1, 20), label="more steps")) and sim.dt <= 1e-2:
        log = sim.log
        if sim.robot_count:
            q, qd = sim.state(0)
            finite(q, qd)
        check_world_run(sim, log)
        g = log.grasps
        assert set(g["event"]) <= {"grasp", "release"} and set(g["body"]) <= set(names)
        for a, b in ((0, 0), (0, 1), (1, 0), (-1, 0), ("a", 0)):
            out = clear(lambda: log.cooperation(a, b), {"robot"}, {"robot": ("robot",)})
            if out is not None:
                finite(out["external"][out["holding"]], out["internal"][out["holding"]])


# ---- the grasp: the clamp rule, welds, release ----------------------------------------------

from test_grasp import BOX, closing, scene  # noqa: E402


@settings(FUZZ, max_examples=25)
@given(options=grasp_options(), data=st.data())
def test_fuzz_grasp_hold_release_and_wrenches(options, data):
    """The clamp closes on a box and lifts it, under any valid grasp options, with releases,
    queries and wrenches at random moments: every answer finite, the events consistent."""
    r, w = scene(BOX * [1, 2 / 3, 1])
    sim = closing(r, w, lift=0.02, grasp_options=options)
    if not step(sim, 600):  # the jaw closes on the box by then: held with the default options
        return
    for _ in range(data.draw(st.integers(1, 4), label="moments")):
        if not step(sim, data.draw(st.integers(1, 500), label="steps")):
            return
        action = data.draw(st.sampled_from(["release", "check", "wrench", "none"]), label="action")
        if action == "release":
            sim.release(0)
            assert sim.holding(0) is None
        elif action == "check":
            c = sim.grasp_check(0, "box")
            finite(*[v for v in (getattr(c, k) for k in type(c).fields) if not isinstance(v, (bool, np.bool_))])
        elif action == "wrench":
            sim.set_applied(0, wrenches=[cs.Wrench(-1, data.draw(vectors(3, -0.5, 0.5)), data.draw(vectors(6, -5, 5)))])
        assert sim.holding(0) in (None, "box")
        finite(sim.weld_wrench(0), sim.body_state("box").pose, *sim.state(0))
    log = sim.log
    g = log.grasps
    assert list(g["t"]) == sorted(g["t"]) and set(g["body"]) <= {"box"}
    events = list(g["event"])
    assert all(a != b for a, b in zip(events, events[1:])), "grasps and releases alternate"
    assert set(g["reason"]) <= {"grasp", "opened", "slipped", "released"}
    finite(log[0].weld, log.bodies["box"].data)
    assert set(log[0].holding) <= {"", "box"}


# ---- coopsim.grasp: grasp matrix, load split, internal wrenches -----------------------------

@settings(FUZZ, max_examples=150)
@given(k=st.integers(1, 4), data=st.data())
def test_fuzz_load_sharing(k, data):
    good = dict(points=hnp.arrays(np.float64, (k, 3), elements=finite_floats(-2, 2)), centre=vectors(3, -2, 2),
                wrench=vectors(6, -50, 50), internal=st.one_of(st.none(), hnp.arrays(np.float64, (k, 6),
                                                                                    elements=finite_floats(-9, 9))),
                wrenches=hnp.arrays(np.float64, (k, 6), elements=finite_floats(-50, 50)))
    bad = {key: st.one_of(anything, st.lists(st.text(max_size=1), max_size=3), st.complex_numbers(),
                          hnp.arrays(np.complex128, 3)) for key in good}
    args, spoiled = draw_arguments(data, good, bad)
    G = clear(lambda: grasp.grasp_matrix(args["points"], args["centre"]), spoiled & {"points", "centre"})
    assert G is not None or spoiled & {"points", "centre"}
    if G is None:
        return
    finite(G)
    # points of another count than the wrenches' rows: an error about those
    count = {"points": ("points", "internal", "wrenches")}
    f = clear(lambda: grasp.load_split(args["wrench"], args["points"], args["centre"], args["internal"]),
              spoiled & {"wrench", "internal", "points"}, count)
    assert f is not None or spoiled & {"wrench", "internal", "points"}
    if f is not None:
        finite(f)
        # the holders' wrenches give the body wrench asked for
        np.testing.assert_allclose(G @ f.reshape(-1), args["wrench"], atol=1e-9 * (1 + np.abs(G).max()) ** 2
                                   * (1 + np.abs(f).max()))
    e = clear(lambda: grasp.internal_wrenches(args["wrenches"], args["points"], args["centre"]),
              spoiled & {"wrenches", "points"}, count)
    assert e is not None or spoiled & {"wrenches", "points"}
    if e is not None:
        finite(e)
        np.testing.assert_allclose(G @ e.reshape(-1), 0, atol=1e-9 * (1 + np.abs(G).max()) ** 2
                                   * (1 + np.abs(args["wrenches"]).max()))


# ---- views and files from garbage logs, to bad paths --------------------------------------------

def _view_sim():
    sim = cs.Simulation(world=world_with_bodies(), log_every=20, log_contacts=True)
    sim.add_robot(SCARA, cs.PID(200.0, 0.0, 20.0), np.array([0.3, 0.5, 0.1, 0.2, 0.6, 0.02]))
    sim.run(0.02, progress=False)
    return sim


VIEW_SIM = _view_sim()
VIEW_LOG = VIEW_SIM.log


def spoil_rows(a, rows, draw):
    """A log array (rows, ...) made wrong: rows missing or extra, columns, NaN, inf, 1-D, text."""
    a = np.array(a, dtype=float)
    how = draw(st.sampled_from(["rows", "columns", "nan", "inf", "flat", "text", "huge", "empty"]))
    if how == "rows":
        return a[:max(0, rows - draw(st.integers(1, rows)))] if draw(st.booleans()) else np.vstack([a, a[:1]])
    if how == "columns":
        return a[:, :-1] if a.ndim == 2 and a.shape[1] > 1 else a[..., None]
    if how in ("nan", "inf", "huge"):
        b = a.copy()
        b.flat[draw(st.integers(0, b.size - 1))] = {"nan": np.nan, "inf": np.inf, "huge": 1e300}[how]
        return b
    if how == "flat":
        return a.reshape(-1)
    if how == "text":
        return a.astype(str)
    return a[:0]


@st.composite
def garbage_logs(draw):
    """VIEW_LOG with up to three parts spoiled; returns (log, robots, spoiled parts)."""
    t = np.array(VIEW_LOG.t)
    rows = len(t)
    parts = draw(st.sets(st.sampled_from(["t", "q", "q_ref", "holding", "body", "robots", "rows"]), max_size=3))
    if "t" in parts:
        how = draw(st.sampled_from(["reversed", "nan", "inf", "2d", "huge", "constant", "text", "empty"]))
        t = {"reversed": lambda: t[::-1].copy(), "nan": lambda: np.where(np.arange(rows) == rows // 2, np.nan, t),
             "inf": lambda: np.append(t[:-1], np.inf), "2d": lambda: np.tile(t, (2, 1)).T,
             "huge": lambda: t * 1e300, "constant": lambda: np.zeros(rows), "text": lambda: t.astype(str),
             "empty": lambda: t[:0]}[how]()
    arrays = {k: np.array(getattr(VIEW_LOG[0], k)) for k in STORED}
    for k in ("q", "q_ref"):
        if k in parts:
            arrays[k] = spoil_rows(arrays[k], rows, draw)
    holding = np.array(VIEW_LOG[0].holding)
    if "holding" in parts:
        holding = draw(st.sampled_from([holding[:-1], np.arange(rows), np.full(rows, None), np.full(rows, "bar")]))
    bodies = [BodyLog(b.name, t, np.array(b.data)) for b in VIEW_LOG.bodies.values()]
    if "body" in parts:
        b = bodies[0]
        bodies[0] = BodyLog(b.name, t, spoil_rows(b.data, rows, draw))
    log = SimulationLog(t, [RobotLog(VIEW_LOG[0].name, t, holding=holding, weld=VIEW_LOG[0].weld, **arrays)],
                        dt=VIEW_LOG.dt, bodies=bodies, contacts=VIEW_LOG._contacts,
                        contact_points=VIEW_LOG._contact_points, grasps=VIEW_LOG._grasps)
    robots = [SCARA]
    if "robots" in parts:
        robots = draw(st.sampled_from([[], [SCARA, SCARA], [cs.robots.scara2()], ["scara1"], None]))
    return log, robots, parts


@st.composite
def paths(draw, tmp_path, suffix):
    """(path, its kind): a file in a folder that exists or not, or a bad one."""
    kind = draw(st.sampled_from(["file", "new folder", "folder", "empty", "in a file", "nul", "long", "bytes",
                                 "number", "no suffix"]))
    base = tmp_path / draw(st.sampled_from(["a", "b é", "c"]))
    base.mkdir(exist_ok=True)
    (base / "plain.txt").write_text("x")
    return {"file": str(base / f"out{suffix}"), "new folder": str(base / "new" / "deeper" / f"out{suffix}"),
            "folder": str(base), "empty": "", "in a file": str(base / "plain.txt" / f"out{suffix}"),
            "nul": str(base / f"o\x00ut{suffix}"), "long": str(base / ("x" * 300 + suffix)),
            "bytes": os.fsencode(base / f"out{suffix}"), "number": 5, "no suffix": str(base / "out")}[kind], kind


GOOD_PATHS = ("file", "new folder")


def written(call, path, kind, spoiled):
    """call() writes `path`: it must when nothing is spoiled and the path is good; a bad path gives
    ValueError naming the path or an OSError naming the path the user gave (not a temporary file)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            out = call()
    except OSError as e:
        assert kind not in GOOD_PATHS, f"{kind} path: {e!r}"
        assert os.fspath(path) in str(e) or (e.filename is not None and os.fspath(e.filename) == os.fspath(path)), \
            f"the error does not name the path given: {e!r}"
        return None
    except (ValueError, TypeError) as e:
        assert str(e)
        if not spoiled:
            assert kind not in GOOD_PATHS, f"a good log to a good path failed: {e!r}"
            assert "path" in str(e), f"the error does not name the path: {e}"
        return None
    assert kind in GOOD_PATHS or kind == "no suffix", f"{kind} path {path!r} accepted"
    assert out == os.fspath(path) and os.path.getsize(path) > 0
    return out


@settings(FUZZ, max_examples=60)
@given(data=st.data())
def test_fuzz_replay_html_of_garbage_logs_to_bad_paths(tmp_path, data):
    log, robots, spoiled = data.draw(garbage_logs(), label="log")
    path, kind = data.draw(paths(tmp_path, ".html"), label="path")
    note(f"spoiled: {spoiled}, path: {kind}")
    written(lambda: view.replay_html(log, path, robots=robots, world=VIEW_SIM.world), path, kind, spoiled)


@settings(FUZZ, max_examples=30)
@given(data=st.data())
def test_fuzz_animate_garbage_logs(tmp_path, data):
    log, robots, spoiled = data.draw(garbage_logs(), label="log")
    to_file = data.draw(st.booleans(), label="to a file")
    path, kind = data.draw(paths(tmp_path, ".gif"), label="path") if to_file else (None, "none")
    note(f"spoiled: {spoiled}, path: {kind}")

    def call():
        anim = view.animate(log, robots, world=VIEW_SIM.world, fps=50, path=path)
        assert len(anim.times) >= 1
        return anim if path is None else os.fspath(path)

    if path is None:
        clear(call)
    else:
        written(call, path, kind, spoiled)


@settings(FUZZ, max_examples=60)
@given(data=st.data())
def test_fuzz_log_tables_of_garbage_logs_to_bad_paths(tmp_path, data):
    log, _, spoiled = data.draw(garbage_logs(), label="log")
    df = clear(log.to_dataframe)
    assert df is not None or spoiled
    path, kind = data.draw(paths(tmp_path, ".csv"), label="path")
    note(f"spoiled: {spoiled}, path: {kind}")
    if written(lambda: log.to_csv(path), path, kind, spoiled) is not None:
        back = SimulationLog.read_csv(path)
        np.testing.assert_array_equal(back.t, np.asarray(log.t, dtype=float))


@settings(FUZZ, max_examples=60)
@given(data=st.data())
def test_fuzz_view_helpers_of_garbage_logs(data):
    """What the views derive from a log (bodies at their logged poses, colliding boxes, contact lines,
    who holds): a valid answer for each row or a clear error."""
    log, robots, spoiled = data.draw(garbage_logs(), label="log")
    mode = data.draw(st.one_of(st.sampled_from(["shared", "any"]), junk), label="mode")
    rows = len(log.t) if np.ndim(log.t) == 1 else None
    bodies = clear(lambda: view.world_bodies(VIEW_SIM.world, log, rows=rows))
    for b in bodies or []:
        finite(b.poses)
    masks = clear(lambda: view.colliding_from_log(log, robots))
    assert masks is not None or spoiled
    for m, r in zip(masks or [], robots or []):
        assert m.shape == (rows, len(r.boxes)) and m.dtype == bool
    lines = clear(lambda: view.contacts_from_log(log))
    assert lines is None or len(lines) == rows
    for x in lines or []:
        if x is not None:
            assert x.ndim == 3 and x.shape[1:] == (2, 3)
            finite(x)
    held = clear(lambda: view.holding_from_log(log, mode=mode),
                 {"mode"} if mode not in ("shared", "any") and not spoiled else set())
    for h in held or []:
        assert h.shape == (rows,) and h.dtype == bool


# ---- what the fuzzing found the engine getting silently wrong, now refused or a DivergenceError --------

def free_box(**kw):
    args = dict(half_extents=[0.1, 0.1, 0.1], mass=1.0, position=[0.0, 0.0, 0.5])
    args.update(kw)
    w = cs.World(floor=False)
    w.add_free_box("box", **args)
    return w


def test_a_free_body_too_heavy_or_too_light_is_refused():
    # 1e160 kg gave NaN angular velocities in its state and log
    for mass in (1e160, 1e10, 1e-7):
        with pytest.raises(ValueError, match=r"free body 'box': mass must be in 1e-6 .. 1e9 kg"):
            free_box(mass=mass)


def test_a_free_body_too_fast_is_refused():
    # at 1e10 m/s Bullet froze it where it started, reporting its speed
    with pytest.raises(ValueError, match=r"velocities must be finite and at most 1e4 m/s and 1e4 rad/s"):
        free_box(velocity=[1e10, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"at most 1e4 m/s and 1e4 rad/s"):
        free_box(angular_velocity=[0.0, 0.0, 2e4])


def test_a_world_with_gravity_too_large_is_refused():
    # under 1e12 m/s^2 a body left the world's 1e6 m and froze at 5e9 m/s
    with pytest.raises(ValueError, match=r"gravity must be finite and at most 1e3 m/s\^2"):
        cs.World(floor=False, gravity=[0.0, 0.0, -1e12])


def test_a_step_far_too_large_is_refused():
    # dt = 1e160 s put bodies at -inf; at 1e305 s contact forces were NaN
    w = cs.World()
    w.add_free_box("bar", [0.05, 0.015, 0.01], 0.1, position=[0.35, 0.2, 0.01])
    for dt in (1e160, 2.0):
        with pytest.raises(ValueError, match=r"dt must be > 0 and at most 1 s"):
            cs.Simulation(dt=dt, world=w)


def test_a_free_body_leaving_the_world_is_a_divergence_naming_it():
    # the largest speed and gravity allowed, for long enough, carry a body past the world's 1e6 m
    w = cs.World(floor=False, gravity=[0.0, 0.0, -1e3])
    w.add_free_box("runaway", [0.1, 0.1, 0.1], 1.0, position=[0.0, 0.0, 0.5], velocity=[1e4, 0.0, 0.0])
    sim = cs.Simulation(dt=0.01, world=w, log_every=1)
    with pytest.raises(cs.DivergenceError, match=r"free body 'runaway' diverged at t = .* \(beyond 1e6 m or 1e5 m/s") as e:
        sim.run(200.0, progress=False)
    assert e.value.robot == -1 and e.value.time > 0
    log = sim.log
    assert len(log.t) > 1 and np.isfinite(log.bodies["runaway"].data).all()
    assert np.abs(log.bodies["runaway"].position).max() <= 1e6


def test_a_name_of_bytes_that_are_not_utf8_is_refused():
    # it was taken, and then body_names, the log and the views could not turn it back into text
    w = cs.World()
    with pytest.raises(ValueError, match="a body's name must be UTF-8 text"):
        w.add_static_box(b"\x80", [0.1, 0.1, 0.1], position=[0.0, 0.0, 0.1])
    w.add_static_box("wall é", [0.1, 0.1, 0.1], position=[0.0, 0.0, 0.1])
    assert w.body_names == ["floor", "wall é"]


def test_a_robot_started_beyond_the_world_is_refused_when_added():
    # a prismatic joint at 2e6 m was taken by add_robot and refused only at the first step
    r = cs.robots.scara1()
    far = np.zeros(6)
    far[2] = 2e6
    sim = cs.Simulation(dt=2e-4, world=cs.World())
    with pytest.raises(ValueError, match=r"the start of robot 'scara1' \(q0, or its reference at t = 0\) puts its "
                                         r"box 'link3': pose must lie within 1e6 m of the origin"):
        sim.add_robot(r, cs.PID(np.ones(6), np.zeros(6), np.ones(6)), np.zeros(6), q0=far)
    with pytest.raises(ValueError, match=r"reference at t = 0\) puts its box"):
        sim.add_robot(r, cs.PID(np.ones(6), np.zeros(6), np.ones(6)), far)
    # nothing was added; a start within the world is taken and runs (without a world any q0 is taken)
    sim.add_robot(r, cs.PID(np.ones(6), np.zeros(6), np.ones(6)), np.zeros(6))
    sim.run(0.01, progress=False)
    cs.Simulation(dt=2e-4).add_robot(r, cs.PID(np.ones(6), np.zeros(6), np.ones(6)), np.zeros(6), q0=far)
