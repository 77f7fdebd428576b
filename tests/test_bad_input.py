"""Each kind of bad input raises a clear exception naming what is wrong,
and no input crashes the process (property-based fuzzing)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import coopsim as cs

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
    for bad in (0.0, -1.0):
        t = good_tables()
        t["masses"] = np.array([1.0, bad])
        with pytest.raises(ValueError, match=r"link 2: mass must be finite and > 0"):
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
    t = good_tables()
    t["inertias"][0] = np.diag([0.01, 0.01, 0.05])
    with pytest.raises(ValueError, match="triangle inequality"):
        cs.Robot.from_dh(**t)


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
    with pytest.raises(ValueError, match="dt must be finite and > 0"):
        cs.rk4_step(R1, Q, Q, Q, dt=0.0)
    with pytest.raises(ValueError, match="dt must be finite and > 0"):
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
        r.set_backend("magic")
    with pytest.raises(ValueError, match="no generated code attached"):
        r.set_backend("generated")


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
    for call in (lambda: cs.rk4_step(robot, q, qd, tau, dt), lambda: cs.euler_step(robot, q, qd, tau, dt),
                 lambda: robot.jacobian(q, link, point),
                 lambda: cs.integrate(robot, q, qd, tau, dt=dt, steps=3)):
        try:
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
