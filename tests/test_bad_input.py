"""Each kind of bad input raises a clear exception naming what is wrong,
and no input crashes the process (property-based fuzzing)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import coopsim as cs
from conftest import random_robot

R1 = cs.robots.scara1(backend="numeric")
Q = np.zeros(6)


def good_tables(n=2):
    return dict(dh=np.array([[0, 0.1, 0.3, 0], [0, 0, 0.2, 0]])[:n], com=np.array([[0, 0.1, 0.15, 0],
                                                                                     [0, 0, 0.1, 0]])[:n],
                masses=np.ones(n), inertias=np.array([np.diag([0.01, 0.02, 0.025])] * n), joint_types="RR"[:n])


def test_wrong_shape_names_the_argument():
    with pytest.raises(ValueError, match=r"wrong shape for q: expected \(6,\), got \(5,\)"):
        R1.mass_matrix(np.zeros(5))
    with pytest.raises(ValueError, match=r"wrong shape for qd"):
        R1.coriolis(Q, np.zeros((6, 1)))
    with pytest.raises(ValueError, match=r"wrong shape for f_ext"):
        R1.forward_dynamics(Q, Q, Q, f_ext=np.zeros(5))
    with pytest.raises(ValueError, match=r"wrong shape for tau"):
        cs.forward_dynamics_batch(R1, np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((2, 6)))


def test_nan_and_inf_are_rejected():
    with pytest.raises(ValueError, match="q must be finite"):
        R1.fk(np.array([0, np.nan, 0, 0, 0, 0]))
    with pytest.raises(ValueError, match="tau must be finite"):
        R1.forward_dynamics(Q, Q, np.full(6, np.inf))
    with pytest.raises(ValueError, match="inertias must be finite"):
        t = good_tables()
        t["inertias"][0, 0, 0] = np.nan
        cs.Robot.from_dh(**t)


def test_non_numeric_input():
    with pytest.raises(ValueError, match="q must be an array of real numbers"):
        R1.fk(["a"] * 6)
    with pytest.raises(ValueError, match="q must be an array of numbers, got None"):
        R1.fk(None)


def test_non_physical_masses():
    # a link without mass is allowed (tests/test_published_data.py); a negative one is not
    for bad in (-1.0, np.nan, np.inf):
        t = good_tables()
        t["masses"] = np.array([1.0, bad])
        with pytest.raises(ValueError, match=r"link 2: mass must be finite and >= 0|masses must be finite"):
            cs.Robot.from_dh(**t)
    with pytest.raises(ValueError, match="masses"):
        cs.robots.scara1(masses=[1.0, 1.0, 1.0, -0.1, 1.0, 1.0])


def test_inertia_not_symmetric():
    t = good_tables()
    t["inertias"][1, 0, 1] = 0.005
    with pytest.raises(ValueError, match="link 2: inertia tensor must be symmetric"):
        cs.Robot.from_dh(**t)


def test_inertia_not_positive_semidefinite():
    t = good_tables()
    t["inertias"][0] = np.diag([0.01, 0.02, -0.001])
    with pytest.raises(ValueError, match="link 1: inertia tensor must be positive semi-definite"):
        cs.Robot.from_dh(**t)


def test_inertia_violates_triangle_inequality():
    # published data has such tensors: a warning by default, an error on request
    t = good_tables()
    t["inertias"][0] = np.diag([0.01, 0.01, 0.05])
    with pytest.warns(cs.InertiaWarning, match="link 1: inertia tensor breaks the triangle inequality"):
        r = cs.Robot.from_dh(**t)
    assert len(r.inertia_warnings) == 1
    with pytest.raises(ValueError, match="link 1: inertia tensor breaks the triangle inequality"):
        cs.Robot.from_dh(**t, inertia_check="error")
    with pytest.raises(ValueError, match="inertia_check must be"):
        cs.Robot.from_dh(**t, inertia_check="strict")


def test_limits_out_of_order_and_bad_actuator_limits():
    with pytest.raises(ValueError, match="link 1: joint limits must satisfy q_min < q_max"):
        cs.Robot.from_dh(**good_tables(), q_limits=[[1.0, -1.0], [-1, 1]])
    with pytest.raises(ValueError, match="link 2: actuator limit tau_max must be > 0"):
        cs.Robot.from_dh(**good_tables(), tau_limits=[1.0, 0.0])
    with pytest.raises(ValueError, match="friction K must be finite and >= 0"):
        cs.Robot.from_dh(**good_tables(), friction=[0.1, -0.1])


def test_row_counts_must_agree():
    t = good_tables()
    t["com"] = t["com"][:1]
    with pytest.raises(ValueError, match=r"wrong shape for com: expected \(2, 4\)"):
        cs.Robot.from_dh(**t)
    t = good_tables()
    t["joint_types"] = "RRP"
    with pytest.raises(ValueError, match="joint_types must have one letter per DH row"):
        cs.Robot.from_dh(**t)
    t = good_tables()
    t["joint_types"] = "RX"
    with pytest.raises(ValueError, match=r"joint_types\[1\] must be 'R' or 'P'"):
        cs.Robot.from_dh(**t)
    with pytest.raises(ValueError, match="1 to 12 rows"):
        cs.Robot.from_dh(np.zeros((13, 4)), np.zeros((13, 4)), np.ones(13), np.tile(np.eye(3), (13, 1, 1)),
                         joint_types="R" * 13)


def test_bad_dimension_keywords():
    with pytest.raises(ValueError, match="L1 must be finite and > 0 m"):
        cs.robots.scara1(L1=-0.3)
    with pytest.raises(TypeError, match="unknown dimension"):
        cs.robots.scara2(L4=0.1)   # scara2 has no wrist L4
    with pytest.raises(ValueError, match="backend"):
        cs.robots.scara1(backend="fast")


def test_bad_time_step_and_steps():
    with pytest.raises(ValueError, match="dt must be > 0 and at most 1 s"):
        cs.rk4_step(R1, Q, Q, Q, dt=0.0)
    with pytest.raises(ValueError, match="dt must be > 0 and at most 1 s"):
        cs.integrate(R1, Q, Q, Q, dt=-1e-3, steps=10)
    with pytest.raises(ValueError, match="steps"):
        cs.integrate(R1, Q, Q, Q, steps=-1)
    with pytest.raises(ValueError, match="method must be 'rk4' or 'euler'"):
        cs.integrate(R1, Q, Q, Q, steps=1, method="rk45")
    with pytest.raises(ValueError, match=r"wrong shape for tau: expected \(10, 6\)"):
        cs.integrate(R1, Q, Q, np.zeros((9, 6)), steps=10)


def test_bad_link_and_tool():
    with pytest.raises(ValueError, match=r"link must be in \[-6, 6\], got 7"):
        R1.jacobian(Q, link=7)
    with pytest.raises(ValueError, match="tool must be a rigid transform"):
        cs.Robot.from_dh(**good_tables(), tool=np.diag([2.0, 1, 1, 1]))
    with pytest.raises(ValueError, match="external wrench link"):
        R1.external_torques(Q, [cs.Wrench(9, [0, 0, 0], np.zeros(6))])


def test_unknown_backend_and_missing_generated_code():
    r = cs.Robot.from_dh(**good_tables())
    with pytest.raises(ValueError, match="backend must be 'generated' or 'numeric'"):
        r.with_backend("magic")
    with pytest.raises(ValueError, match="no generated code attached"):
        r.with_backend("generated")
    with pytest.raises(ValueError, match="no generated dynamics named 'nothing'"):
        r.with_generated("nothing")


def test_out_of_range_values_give_an_error_not_a_wrong_answer():
    r = cs.Robot.from_dh(**good_tables(2))
    # centrifugal terms ~ qd^2 overflow to inf
    with pytest.raises(ValueError, match="forward_dynamics: result is not finite"):
        r.forward_dynamics([0.0, 0.5], [1e200, 1e200], [0.0, 0.0])
    with pytest.raises(ValueError, match="coriolis: result is not finite"):
        r.coriolis([0.0, 0.5], [1e200, 1e200])


# ---- property-based fuzzing of the public functions --------------------------

floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
arrays = hnp.arrays(np.float64, hnp.array_shapes(min_dims=0, max_dims=3, max_side=8), elements=floats)
anything = st.one_of(arrays, st.none(), st.text(max_size=3), st.lists(floats, max_size=8), floats)

ROBOT_METHODS = {
    "fk": 1, "frames": 1, "com_frames": 1, "mass_matrix": 1, "gravity": 1, "tool_jacobian": 1,
    "mass_matrix_derivatives": 1, "friction": 1, "coriolis": 2, "coriolis_matrix": 2, "energy": 2,
    "external_torques": 2, "end_stop_torques": 2, "inverse_dynamics": 3, "forward_dynamics": 3,
}
ROBOTS = [cs.robots.scara1(backend="numeric"), cs.robots.scara2()]


def check_output(out):
    for o in (out if isinstance(out, tuple) else (out,)):
        assert np.all(np.isfinite(o)), "a result must never be NaN or inf"


@pytest.mark.parametrize("method", sorted(ROBOT_METHODS))
def test_every_robot_method_refuses_a_result_that_overflows(method):
    # a prismatic coordinate of 1.6e170 m: squares overflow; mass_matrix_derivatives returned NaN
    # here (found by test_fuzz_robot_methods) rather than the error every other method gives
    huge = [0.0, 120.0, 1.592369152400559e170, 0.0, 0.0, 0.0]
    for robot in ROBOTS + [cs.robots.scara1()]:
        args = [huge, np.ones(6), np.ones(6)][:ROBOT_METHODS[method]]
        if method == "friction":
            args = [np.full(6, 1e170)]
        try:
            out = getattr(robot, method)(*args)
        except ValueError as e:
            assert "not finite" in str(e) or "out of range" in str(e), e
            continue
        check_output(out)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(method=st.sampled_from(sorted(ROBOT_METHODS)), robot=st.sampled_from(ROBOTS),
       args=st.lists(anything, min_size=3, max_size=3))
def test_fuzz_robot_methods(method, robot, args):
    fn = getattr(robot, method)
    try:
        out = fn(*args[:ROBOT_METHODS[method]])
    except (ValueError, TypeError):
        return
    check_output(out)


good_vec = hnp.arrays(np.float64, 6, elements=st.floats(-1e3, 1e3))
maybe_bad = st.one_of(good_vec, anything)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(robot=st.sampled_from(ROBOTS), q=maybe_bad, qd=maybe_bad, tau=maybe_bad,
       dt=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(2e-4)),
       link=st.integers(-10, 10), point=maybe_bad)
def test_fuzz_steps_and_jacobians(robot, q, qd, tau, dt, link, point):
    import warnings

    calls = [lambda: robot.jacobian(q, link, point), lambda: cs.integrate(robot, q, qd, tau, dt=dt, steps=3),
             lambda: cs.rk4_step(robot, q, qd, tau, dt), lambda: cs.euler_step(robot, q, qd, tau, dt)]
    for call in calls:
        try:
            with warnings.catch_warnings():
                # a large dt is warned about (end stops too stiff for it): a valid answer here
                warnings.filterwarnings("ignore", message="the end stops", category=RuntimeWarning)
                out = call()
        except (ValueError, TypeError):
            continue
        except RuntimeError as e:  # divergence of a finite but absurd state, reported with its step
            assert "step" in str(e)
            continue
        check_output(out)


@settings(max_examples=150, deadline=None)
@given(dh=anything, com=anything, masses=anything, inertias=anything,
       types=st.one_of(st.text(alphabet="RPX", max_size=4), st.none()))
def test_fuzz_robot_construction(dh, com, masses, inertias, types):
    try:
        r = cs.Robot.from_dh(dh, com, masses, inertias, joint_types=types)
    except (ValueError, TypeError):
        return
    q = np.zeros(r.dof)
    try:
        check_output(r.mass_matrix(q))
    except ValueError:
        pass


# ---- fuzzing of the remaining entry points: a valid, finite result or a -----
# ValueError (IKError is one), nothing else. Each example takes valid
# arguments and spoils up to two of them: array arguments with anything
# (NaN, inf, huge, wrong shapes, wrong types), scalars with any value of
# their own Python type (any float, any C int, any text). With nothing
# spoiled the call must succeed.

def valid_or_value_error(call):
    """The call's result, or None when it raised ValueError; any other
    exception fails the test."""
    try:
        return call()
    except ValueError:
        return None


def draw_arguments(data, good, bad, max_spoiled=2):
    """Keyword arguments from the `good` strategies, except up to
    `max_spoiled` of them drawn from `bad`; returns (arguments, spoiled names)."""
    spoiled = data.draw(st.sets(st.sampled_from(sorted(bad)), max_size=max_spoiled), label="spoiled")
    return {k: data.draw(bad[k] if k in spoiled else good[k], label=k) for k in good}, spoiled


any_float = st.floats(allow_nan=True, allow_infinity=True, width=64)
c_int = st.integers(-2**31, 2**31 - 1)
# names without the characters XML 1.0 cannot hold (control characters, lone
# surrogates): to_urdf writes those into invalid XML
xml_text = st.text(st.characters(blacklist_categories=("Cc", "Cs")) | st.sampled_from("\t\n\r"), max_size=8)


def finite_floats(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@st.composite
def rigid_poses(draw):
    """A valid (4, 4) rigid transform: rotation from a random quaternion."""
    v = draw(hnp.arrays(np.float64, 4, elements=finite_floats(-1, 1)).filter(lambda v: np.linalg.norm(v) > 0.1))
    w, x, y, z = v / np.linalg.norm(v)
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                 [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                 [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = draw(hnp.arrays(np.float64, 3, elements=finite_floats(-2, 2)))
    return T


def vectors(n, lo=-10.0, hi=10.0):
    return hnp.arrays(np.float64, n, elements=finite_floats(lo, hi))


poses = st.one_of(rigid_poses(), anything)
vec3 = st.one_of(vectors(3), anything)
# sizes outside 1e-4 .. 1e4 m are refused
sizes = st.one_of(finite_floats(-1e308, 1e308), st.sampled_from([np.nan, np.inf, -np.inf, 1e-4, 1e4]))


@settings(max_examples=100, deadline=None)
@given(robot=st.sampled_from(ROBOTS), rows=st.integers(0, 5), data=st.data())
def test_fuzz_forward_dynamics_batch(robot, rows, data):
    good = {k: vectors((rows, robot.dof)) for k in ("q", "qd", "tau")}
    good["threads"] = st.integers(0, 4)
    bad = {k: anything for k in ("q", "qd", "tau")}
    bad["threads"] = st.one_of(c_int, st.integers(2**31, 2**70), st.floats(), st.none(), st.text(max_size=2))
    args, spoiled = draw_arguments(data, good, bad)
    out = valid_or_value_error(lambda: cs.forward_dynamics_batch(robot, **args))
    if spoiled == {"threads"} and isinstance(args["threads"], int) and 0 <= args["threads"] <= 4096:
        assert out is not None  # any thread count in range is fine
    assert out is not None or spoiled
    if out is not None:
        # every row is the single-state forward dynamics
        check_output(out)
        assert out.shape == (len(args["q"]), robot.dof)
        for row, (q, qd, tau) in enumerate(zip(args["q"], args["qd"], args["tau"])):
            np.testing.assert_array_equal(out[row], robot.forward_dynamics(q, qd, tau))


@settings(max_examples=100, deadline=None)
@given(robot=st.sampled_from(ROBOTS), data=st.data())
def test_fuzz_with_base(robot, data):
    args, spoiled = draw_arguments(data, {"position": vectors(3), "yaw": finite_floats(-10, 10)},
                                   {"position": anything, "yaw": any_float})
    moved = valid_or_value_error(lambda: robot.with_base(**args))
    assert moved is not None or spoiled
    if moved is None:
        return
    position, yaw = args["position"], args["yaw"]
    np.testing.assert_array_equal(moved.base_position, position)
    assert moved.base_yaw == yaw
    # the same robot placed elsewhere: its TCP pose is the placement times the unplaced one
    T = valid_or_value_error(lambda: moved.fk(np.zeros(6)))
    assert T is not None or spoiled
    if T is not None:
        check_output(T)
        B = np.eye(4)
        B[:3, :3] = [[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]]
        B[:3, 3] = position
        unplaced = robot.with_base(np.zeros(3), 0.0).fk(np.zeros(6))
        np.testing.assert_allclose(T, B @ unplaced, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(position).max()))


def check_urdf(robot, name=None):
    """to_urdf's text parses as XML and carries the name and the masses."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(cs.to_urdf(robot, name))
    assert root.get("name") == (name or robot.name)
    got = [float(root.find(f"link[@name='link{i + 1}']/inertial/mass").get("value")) for i in range(robot.dof)]
    np.testing.assert_array_equal(got, robot.masses)
    # world, base_link and flange: explicit zero masses
    assert [float(m.get("value")) for m in root.iter("mass")] == [0.0, 0.0, *robot.masses, 0.0]


@settings(max_examples=100, deadline=None)
@given(robot=st.sampled_from(ROBOTS), name=st.one_of(st.none(), xml_text))
def test_fuzz_to_urdf_names(robot, name):
    check_urdf(robot, name)


@settings(max_examples=150, deadline=None)
@given(make=st.sampled_from([cs.robots.scara1, cs.robots.scara2]), data=st.data())
def test_fuzz_scara_keywords(make, data):
    defaults = cs.robots.SCARA1_DEFAULTS if make is cs.robots.scara1 else cs.robots.SCARA2_DEFAULTS
    bounds = cs.robots.SCARA1_BOUNDS if make is cs.robots.scara1 else cs.robots.SCARA2_BOUNDS
    keys = data.draw(st.sets(st.sampled_from(sorted(defaults)), max_size=4), label="dimensions")
    good = {k: finite_floats(bounds[k].low, bounds[k].high) for k in keys}
    bad = {k: st.one_of(any_float, st.text(max_size=4), arrays, st.none(), st.lists(any_float, max_size=2))
           for k in keys}
    good |= dict(masses=st.one_of(st.none(), vectors(6, 0.01, 10)), friction=st.one_of(st.none(), vectors(6, 0, 5)),
                 base_position=vectors(3), base_yaw=finite_floats(-10, 10), gravity=vectors(3),
                 backend=st.sampled_from(["generated", "numeric"]))
    bad |= dict(masses=anything, friction=anything, base_position=anything, base_yaw=any_float, gravity=anything,
                backend=st.one_of(st.text(max_size=4), st.none()))
    args, spoiled = draw_arguments(data, good, bad)
    r = valid_or_value_error(lambda: make(**args))
    assert r is not None or spoiled
    if r is None:
        return
    for key in keys:
        assert r.dimensions[key] == float(args[key]) and np.isfinite(r.dimensions[key]) and r.dimensions[key] > 0
    # the engine's rule of a link's mass: finite and >= 0 kg (a massless link is allowed; a mass matrix it leaves
    # singular is a ValueError where the dynamics need it, as the calls below accept)
    assert np.all(np.isfinite(r.masses)) and np.all(r.masses >= 0)
    q = np.array([0.1, 0.2, 0.1, 0.3, 0.4, 0.01])
    for call in (lambda: r.fk(q), lambda: r.mass_matrix(q), lambda: r.gravity(q),
                 lambda: r.forward_dynamics(q, np.ones(6), np.zeros(6))):
        out = valid_or_value_error(call)
        if out is not None:
            check_output(out)


@st.composite
def limit_pairs(draw, n):
    lo = draw(vectors(n, -5, 4.9))
    return np.column_stack([lo, lo + draw(vectors(n, 0.01, 5))])


@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_fuzz_robot_construction_arguments(data):
    good = dict(friction=st.one_of(st.none(), vectors(2, 0, 5)), q_limits=st.one_of(st.none(), limit_pairs(2)),
                tau_limits=st.one_of(st.none(), vectors(2, 0.1, 100)), gravity=vectors(3), base_position=vectors(3),
                base_yaw=finite_floats(-10, 10),
                tool=st.one_of(st.none(), rigid_poses(),
                               st.tuples(st.sampled_from([1, 2, -1, -2]), rigid_poses(), st.sampled_from([-1, 1, 2]),
                                         vectors(3, -1, 1))),
                name=xml_text, end_stop_frequency=finite_floats(0, 1e3), end_stop_damping_ratio=finite_floats(0, 5))
    bad = dict(friction=anything, q_limits=st.one_of(anything, hnp.arrays(np.float64, (2, 2), elements=any_float)),
               tau_limits=anything, gravity=anything, base_position=anything, base_yaw=any_float,
               tool=st.one_of(anything, st.tuples(c_int, poses, c_int, vec3)), end_stop_frequency=any_float,
               end_stop_damping_ratio=any_float)
    args, spoiled = draw_arguments(data, good, bad)
    if isinstance(args["tool"], tuple):  # a Tool(link, offset, second_link, second_point)
        tool = valid_or_value_error(lambda: cs.Tool(*args["tool"]))
        assert tool is not None or "tool" in spoiled
        if tool is None:
            return
        args["tool"] = tool
    r = valid_or_value_error(lambda: cs.Robot.from_dh(**good_tables(), **args))
    assert r is not None or spoiled
    if r is None:
        return
    assert r.name == args["name"] and r.base_yaw == args["base_yaw"]
    assert np.all(r.friction_coefficients >= 0) and np.all(r.tau_limits > 0)
    assert np.all(r.q_limits[:, 0] < r.q_limits[:, 1])
    check_urdf(r)
    q = np.array([0.2, 0.1])
    calls = [lambda: r.fk(q), lambda: r.tool_jacobian(q), lambda: r.gravity(q),
             lambda: r.inverse_dynamics(q, np.ones(2), np.ones(2))]
    # a step from beyond a limit, with the end stops
    beyond = np.minimum(r.q_limits[:, 1] + 0.01, 1e3)

    def step_beyond():
        with warnings.catch_warnings():  # stiff stops warn (omega dt > 1): tested in test_student.py
            warnings.filterwarnings("ignore", "the end stops of robot", RuntimeWarning)
            return cs.rk4_step(r, beyond, np.ones(2), np.zeros(2), 2e-4)

    calls.append(step_beyond)
    for call in calls:
        out = valid_or_value_error(call)
        assert out is not None or spoiled
        if out is not None:
            check_output(out)


def rotation_angle(R):
    return np.arccos(np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0))


IK_ROBOTS = ROBOTS + [random_robot(3, dof=6)]


@settings(max_examples=150, deadline=None)
@given(robot=st.sampled_from(IK_ROBOTS), data=st.data())
def test_fuzz_ik(robot, data):
    n, lim = robot.dof, robot.q_limits
    lo, hi = np.maximum(lim[:, 0], -3), np.minimum(lim[:, 1], 3)
    inside = vectors(n, 0, 1).map(lambda u: lo + u * (hi - lo))
    scara = robot.ik_kind is not None
    # mostly reachable targets: the pose of a configuration within the limits
    good = dict(pose=st.one_of(inside.map(robot.fk), rigid_poses()),
                opening=st.one_of(st.none(), finite_floats(0, 0.05)) if scara else st.none(),
                branch=st.sampled_from([None, 1, -1] + ([2, -2] if robot.ik_kind == "scara2" else []))
                if scara else st.none(),
                q_near=st.one_of(st.none(), inside),
                method=st.sampled_from(["auto", "analytic", "numeric"] if scara else ["auto", "numeric"]),
                tol=st.one_of(st.none(), finite_floats(1e-12, 1e-3)),
                restarts=st.integers(0, 2), max_iterations=st.integers(1, 40), seed=st.integers(0, 2**32 - 1),
                info=st.booleans())
    # counts above the good range are valid but only make a failing search long
    bad = dict(pose=anything, opening=any_float, branch=st.one_of(c_int, any_float, st.text(max_size=2)),
               q_near=anything, method=st.text(max_size=3), weights=st.one_of(anything, st.text(max_size=3)),
               locked=st.lists(st.integers(-8, 8), max_size=3), tol=any_float,
               restarts=st.integers(-2**31, 2), max_iterations=st.integers(-2**31, 40))
    good["weights"] = st.just(None)
    good["locked"] = st.just(None)
    args, spoiled = draw_arguments(data, good, bad)
    if args["method"] == "numeric" or (args["method"] == "auto" and not scara):
        # the numeric solver's own options, valid ones unless spoiled
        if "weights" not in spoiled:
            args["weights"] = data.draw(st.one_of(st.none(), st.sampled_from(["pose", "position"]),
                                                  vectors(6, 0, 2).filter(lambda w: w.max() > 0.1)))
        if "locked" not in spoiled:
            args["locked"] = data.draw(st.one_of(st.none(), st.lists(st.integers(0, n - 1), max_size=2)))
    out = valid_or_value_error(lambda: robot.ik(**args))
    if out is None:
        return
    q, details = out if args["info"] else (out, {})
    assert q.shape == (n,) and isinstance(details, dict)
    check_output(q)
    # a returned configuration lies within the limits and reaches the target
    # to the accepted residual (the weighted components)
    assert np.all(q >= lim[:, 0]) and np.all(q <= lim[:, 1])
    weights = args["weights"]
    if weights is None or isinstance(weights, str):
        accepted = 10 * (args["tol"] if args["tol"] is not None else 1e-9)
        T, pose = robot.fk(q), args["pose"]
        assert np.linalg.norm(T[:3, 3] - pose[:3, 3]) <= accepted
        if weights != "position":
            # arccos loses half the digits near 0
            assert rotation_angle(T[:3, :3].T @ pose[:3, :3]) <= max(accepted, 1e-7)


def test_steps_that_overflow_raise():
    r = cs.robots.scara1(backend="numeric")
    with pytest.raises(ValueError, match="euler_step: result is not finite"):
        cs.euler_step(r, np.zeros(6), np.full(6, 1e154), np.zeros(6))
    with pytest.raises(ValueError, match="not finite|overflow"):
        cs.rk4_step(r, np.zeros(6), np.full(6, 1e154), np.zeros(6))
    arm = cs.Robot.from_dh(**{**good_tables(), "friction": [0.0, 1e80]})
    with pytest.raises(ValueError, match="rk4_step: result is not finite|overflow"):
        cs.rk4_step(arm, np.zeros(2), np.ones(2), np.zeros(2))


def test_ik_scalar_arguments_are_checked():
    r = cs.robots.scara1()
    T = r.fk(np.array([0.3, 0.5, 0.1, 0.2, 0.6, 0.01]))
    for kw, word in ((dict(opening=[0.1, 0.2]), "opening"), (dict(opening="a"), "opening"),
                     (dict(opening=np.nan), "opening"), (dict(tol=[1, 2]), "tol"), (dict(tol=-1.0), "tol"),
                     (dict(method="numeric", locked=[0.5]), "locked"), (dict(method="numeric", locked=[2**70]), "locked"),
                     (dict(method="numeric", locked="ab"), "locked"), (dict(method="numeric", locked=[6]), "locked")):
        with pytest.raises(ValueError, match=word):
            r.ik(T, **kw)


def test_joint_types_must_be_ascii_letters():
    with pytest.raises(ValueError, match="joint_types must be letters 'R' or 'P' only"):
        cs.Robot.from_dh(**{**good_tables(), "joint_types": "R\u00e9"})


def test_scara_keywords_are_checked():
    for kw, word in ((dict(L1=10**400), "L1"), (dict(L1=1j), "L1"), (dict(masses={1: 2}), "masses"),
                     (dict(masses=np.ones(6) * 1j), "masses"), (dict(masses=[10**400] * 6), "masses"),
                     (dict(masses=[None] * 6), "masses"), (dict(base_yaw="abc"), "base_yaw")):
        with pytest.raises(ValueError, match=word):
            cs.robots.scara1(**kw)


def test_urdf_names_must_be_xml_text():
    r = cs.robots.scara2()
    for bad in (5, "a\x01b", "\ud800"):
        with pytest.raises(ValueError, match="name must be"):
            r.to_urdf(name=bad)
    with pytest.raises(ValueError, match="name must be"):
        cs.Robot.from_dh(**good_tables(), name="\x00").to_urdf()


# ---- a wrong argument type: one short line naming the argument and the type expected ----

@pytest.mark.parametrize("call, message", [
    (lambda: R1.jacobian(Q, link="a"), "Robot.jacobian(): link must be an int, got str 'a'"),
    (lambda: R1.jacobian(Q, "a"), "Robot.jacobian(): link must be an int, got str 'a'"),
    (lambda: R1.with_base([0.0, 0.0, 0.0], yaw="x"), "Robot.with_base(): yaw must be a float, got str 'x'"),
    (lambda: R1.with_backend(3), "Robot.with_backend(): backend must be a str, got int 3"),
    (lambda: R1.ik(R1.fk(Q), restarts=1.5), "Robot.ik(): restarts must be an int, got float 1.5"),
    (lambda: R1.fk(Q, link=2), "Robot.fk(): no argument named link (its arguments: q)"),
    (lambda: R1.fk(Q, 1, 2), "Robot.fk(): takes 1 positional argument, got 3"),
    (lambda: cs.integrate(R1, Q, Q, Q, dt="x"), "integrate(): dt must be a float, got str 'x'"),
    (lambda: cs.integrate(R1, Q, Q, Q, steps=[3]), "integrate(): steps must be an int, got list [3]"),
    (lambda: cs.integrate("scara1", Q, Q, Q), "integrate(): robot must be a Robot, got str 'scara1'"),
    (lambda: cs.integrate(R1, Q), "integrate(): missing argument qd0"),
    (lambda: cs.rk4_step(R1, Q, Q, Q, dt=None), "rk4_step(): dt must be a float, got NoneType None"),
    (lambda: cs.PID(kp=1.0, ki=0.0, kd=1.0, gravity_compensation="no"),
     "PID(): gravity_compensation must be a bool, got str 'no'"),
    (lambda: cs.CubicTrajectory([0.0, 1.0], np.zeros((2, 6))).evaluate(0.5, extrapolate=0),
     "CubicTrajectory.evaluate(): extrapolate must be a str, got int 0"),
    (lambda: cs.CubicTrajectory([0.0, 1.0], np.zeros((2, 6)), extrapolate="hold"),
     "CubicTrajectory(): no argument named extrapolate (its arguments: times, q_points, qd_points, spline, "
     "qd_start, qd_end)"),
    # through the Python classes that call the engine: named as the user called them
    (lambda: cs.Simulation(dt="x"), "Simulation(): dt must be a float, got str 'x'"),
    (lambda: cs.Simulation(control_every=1.5), "Simulation(): control_every must be an int, got float 1.5"),
    (lambda: cs.Simulation(end_stops="yes"), "Simulation(): end_stops must be a bool, got str 'yes'"),
    (lambda: cs.Simulation().step("3"), "Simulation.step(): n must be an int, got str '3'"),
    (lambda: cs.Simulation().step(10**19), "Simulation.step(): n is out of range, got int 10000000000000000000"),
    (lambda: cs.Simulation().advance("3"), "Simulation.advance(): t_end must be a float, got str '3'"),
])
def test_a_wrong_argument_type_is_one_short_line_naming_the_argument(call, message):
    # pybind11's own message lists every signature and repeats the call ("Invoked with: ...")
    with pytest.raises(TypeError) as e:
        call()
    assert str(e.value) == message


def test_right_scalar_types_pass_as_before():
    # numpy scalars, and ints where floats are expected, as pybind11 accepts them
    np.testing.assert_array_equal(R1.jacobian(Q, link=np.int64(-1)), R1.jacobian(Q))
    np.testing.assert_array_equal(R1.with_base([0.0, 0.0, 0.0], yaw=np.float64(0.5)).fk(Q),
                                  R1.with_base([0.0, 0.0, 0.0], yaw=0.5).fk(Q))
    assert R1.with_base([0.0, 0.0, 0.0], yaw=1).base_yaw == 1.0
    assert cs.Simulation(dt=np.float64(1e-3), control_every=np.int64(2)).control_every == 2
    # errors that are not about an argument's type pass unchanged
    with pytest.raises(ValueError, match="q must be an array of real numbers"):
        R1.fk("a")
    with pytest.raises(ValueError, match="n must"):
        cs.Simulation().step(-1)


def _signature(function):
    """(name, [(parameter, annotation)]) from pybind11's docstring, None for an overloaded function."""
    first = (function.__doc__ or "").splitlines()[0] if function.__doc__ else ""
    if "(" not in first or "Overloaded function" in (function.__doc__ or ""):
        return None
    name, rest = first.split("(", 1)
    depth, params, start = 0, [], 0
    for i, ch in enumerate(rest):
        if ch in "([" or (ch == ")" and depth == 0):
            if ch == ")":
                params.append(rest[start:i])
                break
            depth += 1
        elif ch in ")]":
            depth -= 1
        elif ch == "," and depth == 0:
            params.append(rest[start:i])
            start = i + 1
    out = []
    for p in (p.strip() for p in params):
        if p in ("", "*", "/") or p.startswith("*"):
            continue
        decl = p.split(" = ")[0]
        pname, _, annotation = decl.partition(": ")
        out.append((pname, annotation))
    return name, out


def _compiled_functions():
    # the package's compiled functions and classes (pybind11's function objects are builtins, its classes
    # of the metaclass pybind11_type)
    for name, f in vars(cs).items():
        if type(f).__name__ == "builtin_function_or_method" and _signature(f):
            yield name, f, None
    for cls in (c for c in vars(cs).values() if type(c).__name__ == "pybind11_type"):
        for name, f in vars(cls).items():
            if isinstance(f, staticmethod):
                f = f.__func__
            elif type(f).__name__ == "instancemethod":
                f = f.__func__
            else:
                continue
            if _signature(f) and name == "__init__":
                yield cls.__name__, f, cls           # called as the class
            elif _signature(f) and not name.startswith("__"):
                yield f"{cls.__name__}.{name}", f, None


SCALARS = {"typing.SupportsFloat | typing.SupportsIndex": ("a float", "x"),
           "typing.SupportsInt | typing.SupportsIndex": ("an int", "x"), "bool": ("a bool", "x"), "str": ("a str", 3)}
DUMMIES = {"typing.SupportsFloat | typing.SupportsIndex": 0.0, "typing.SupportsInt | typing.SupportsIndex": 0,
           "bool": False, "str": ""}


def test_every_compiled_function_names_a_wrong_scalar_argument():
    # each scalar parameter of each compiled function, method, static method and constructor (one
    # signature), given a value of the wrong type while the others hold dummies: the short message names
    # it (the engine is never reached: a call whose arguments do not convert runs nothing)
    checked = 0
    for label, f, cls in _compiled_functions():
        _, params = _signature(f)
        if cls is not None:
            f, params = cls, params[1:]      # a constructor: without its self
        for k, (pname, annotation) in enumerate(params):
            if annotation not in SCALARS or pname == "self":
                continue
            kind, bad = SCALARS[annotation]
            args = [None] if params[0][0] == "self" else []     # a method's self None
            kwargs = {p: DUMMIES.get(a) for p, a in params if p != "self"}
            kwargs[pname] = bad
            with pytest.raises(TypeError) as e:
                f(*args, **kwargs)
            assert str(e.value) == f"{label}(): {pname} must be {kind}, got {type(bad).__name__} {bad!r}", label
            checked += 1
    assert checked >= 60, checked   # (62 parameters of float, int, bool and str in all)


def test_a_type_error_raised_inside_a_compiled_call_passes_unchanged():
    # a Python controller returning a str: the TypeError comes from inside the step, not from the arguments
    class Bad(cs.Controller):
        def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
            return "torques"

    sim = cs.Simulation(dt=1e-3)
    sim.add_robot(R1, Bad(), Q)
    with pytest.raises((TypeError, ValueError)) as e:
        sim.step(1)
    assert "must be an int" not in str(e.value) and "Simulation.step" not in str(e.value)


def test_writing_a_log_under_a_file_names_the_file(tmp_path):
    import os

    sim = cs.Simulation(dt=1e-3)
    sim.add_robot(R1, cs.PID(kp=10.0, ki=0.0, kd=1.0), cs.SetPoint(Q))
    log = sim.run(0.01, progress=False)
    blocker = tmp_path / "results"
    blocker.write_text("not a folder")
    for path in (blocker / "run.csv", blocker / "deeper" / "run.csv"):
        with pytest.raises(NotADirectoryError, match=f"'{blocker}' is a file, not a folder") as e:
            log.to_csv(path)
        assert e.value.filename == str(path)
    assert blocker.read_text() == "not a folder" and os.listdir(tmp_path) == ["results"]


def test_every_compiled_class_and_function_answers_with_short_type_errors():
    """The short errors reach every compiled entry point, those added since included: coopsim._arguments
    switched them at import (labels as the user calls them)."""
    from coopsim import _arguments

    labels = {v[0] for v in _arguments._FUNCTIONS.values()}
    assert {"Impedance", "HybridForce", "ObjectControl", "Robot.tool_bias", "SimulationCore.add_cooperative",
            "integrate"} <= labels
    with pytest.raises(TypeError, match=r"^Impedance\(\): force_feedback must be a bool"):
        cs.Impedance(1.0, 1.0, 1.0, force_feedback="yes")


# ---- the input gaps a researcher found: each one line naming the argument ----

def _carry():
    from coopsim.tasks import carry

    return carry


@pytest.mark.parametrize("call, error, message", [
    (lambda: cs.ObjectControl(0.15, -np.eye(3)), ValueError,
     r"^inertia \(the object's, in the controller's model\) must be positive semi-definite \(principal moments >= 0 "
     r"kg m\^2\), got principal moments \[-1, -1, -1\]$"),
    (lambda: cs.ObjectControl(0.15, np.diag([1e-3, 1e-3, 1e-3]) + np.triu(np.ones((3, 3)), 1) * 1e-4), ValueError,
     r"^inertia \(the object's, in the controller's model\) must be symmetric$"),
    (lambda: cs.Payload(0.1, inertia=np.diag([1.0, -1.0, 1.0])), ValueError,
     r"^payload inertia must be positive semi-definite"),
    (lambda: _carry().run(controllers="ct", controller_options=dict(kp=1)), ValueError,
     r"^unknown option\(s\) of controller 'ct': kp \(it takes none\)$"),
    (lambda: _carry().run(controllers=_carry().cooperative(5)), ValueError,
     r"^make_law must be callable \(robots, plan, \*\*options\) -> a CooperativeController, got 5$"),
    (lambda: _carry().run(controllers=_carry().cooperative(lambda robots, plan, kp=1.0: None),
                          controller_options=dict(kd=2)), ValueError,
     r"^unknown option\(s\) of the cooperative law '<lambda>': kd \(choose from kp\)$"),
    (lambda: _carry().Disturbances(push=np.nan), ValueError,
     r"^push must be \(force \(3,\) N finite, the middle as a fraction 0 \.\. 1 of the carry, a duration > 0 s\), "
     r"got nan$"),
    (lambda: _carry().Disturbances(names=np.nan), ValueError,
     r"^names must be a tuple of the disturbances' names \(non-empty strings\), got nan$"),
])
def test_the_input_gaps_are_one_line_naming_the_argument(call, error, message):
    with pytest.raises(error, match=message) as e:
        call()
    assert "\n" not in str(e.value)


def test_student_labs_names_a_missing_or_broken_notebook_in_one_line(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "scripts" / "student_labs.py"
    bad = tmp_path / "bad.ipynb"
    bad.write_text("{")
    for arg, rc, line in ((str(tmp_path / "missing.ipynb"), 2, "student_labs.py: error: notebook not found: "),
                          (str(bad), 1, f"student_labs: {bad}: Notebook does not appear to be JSON")):
        r = subprocess.run([sys.executable, str(script), str(tmp_path / "out"), arg], capture_output=True, text=True)
        err = r.stderr.strip().splitlines()
        assert r.returncode == rc and line in err[-1] and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
