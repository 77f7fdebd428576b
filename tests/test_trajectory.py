"""Piecewise cubic joint trajectories (paper eqs. 6-8, Hermite form in local time)."""
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import coopsim as cs


def random_knots(rng, N=7, n=3):
    times = np.cumsum(rng.uniform(0.2, 1.5, N)) - 0.3
    q = rng.uniform(-2.0, 2.0, (N, n))
    return times, q


def hermite_solve(h, q0, q1, v0, v1):
    """Coefficients by a direct 4x4 solve of the Hermite conditions in local time."""
    A = np.array([[1.0, 0.0, 0.0, 0.0],
                  [1.0, h, h**2, h**3],
                  [0.0, 1.0, 0.0, 0.0],
                  [0.0, 1.0, 2 * h, 3 * h**2]])
    return np.linalg.solve(A, [q0, q1, v0, v1])


def poly(c, tau, deriv=0):
    if deriv == 0:
        return c[..., 0] + c[..., 1] * tau + c[..., 2] * tau**2 + c[..., 3] * tau**3
    if deriv == 1:
        return c[..., 1] + 2 * c[..., 2] * tau + 3 * c[..., 3] * tau**2
    return 2 * c[..., 2] + 6 * c[..., 3] * tau


@pytest.fixture(params=["heuristic", "given", "spline"])
def trajectory(request):
    rng = np.random.default_rng(4)
    times, q = random_knots(rng)
    if request.param == "given":
        return cs.CubicTrajectory(times, q, rng.uniform(-1, 1, q.shape))
    return cs.CubicTrajectory(times, q, spline=request.param == "spline",
                              qd_start=rng.uniform(-1, 1, 3), qd_end=rng.uniform(-1, 1, 3))


def test_position_and_velocity_continuous_at_knots(trajectory):
    c, t = trajectory.coefficients, trajectory.times
    h = np.diff(t)
    for k in range(trajectory.segments - 1):
        left_q = poly(c[k], h[k])
        left_qd = poly(c[k], h[k], 1)
        np.testing.assert_allclose(left_q, poly(c[k + 1], 0.0), rtol=0, atol=1e-12)
        np.testing.assert_allclose(left_qd, poly(c[k + 1], 0.0, 1), rtol=0, atol=1e-12)
        # and through evaluate(): just before and at the knot
        q_at, qd_at, _ = trajectory.evaluate(t[k + 1])
        np.testing.assert_allclose(q_at, trajectory.q_points[k + 1], rtol=0, atol=1e-12)
        np.testing.assert_allclose(qd_at, trajectory.qd_points[k + 1], rtol=0, atol=1e-12)
    # the knots themselves are interpolated
    q_knots, qd_knots, _ = trajectory.evaluate(t)
    np.testing.assert_allclose(q_knots, trajectory.q_points, rtol=0, atol=1e-12)
    np.testing.assert_allclose(qd_knots, trajectory.qd_points, rtol=0, atol=1e-12)


def test_end_conditions_exact():
    rng = np.random.default_rng(1)
    times, q = random_knots(rng, N=5, n=4)
    v0, v1 = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4)
    for spline in (False, True):
        tr = cs.CubicTrajectory(times, q, spline=spline, qd_start=v0, qd_end=v1)
        qa, qda, _ = tr.evaluate(times[0])
        assert np.array_equal(qa, q[0]) and np.array_equal(qda, v0)
        qb, qdb, _ = tr.evaluate(times[-1])
        np.testing.assert_allclose(qb, q[-1], rtol=0, atol=1e-13)
        np.testing.assert_allclose(qdb, v1, rtol=0, atol=1e-12)
    # default ends: at rest
    tr = cs.CubicTrajectory(times, q)
    assert np.array_equal(tr.qd_points[0], np.zeros(4)) and np.array_equal(tr.qd_points[-1], np.zeros(4))


def test_holds_end_points_outside_the_time_range():
    rng = np.random.default_rng(2)
    times, q = random_knots(rng, N=4, n=2)
    tr = cs.CubicTrajectory(times, q, rng.uniform(-1, 1, q.shape))
    for t, row in ((times[0] - 5.0, 0), (times[-1] + 1e-9, -1), (times[-1] + 100.0, -1)):
        qa, qda, qdda = tr.evaluate(t)
        assert np.array_equal(qa, q[row])
        assert np.array_equal(qda, np.zeros(2)) and np.array_equal(qdda, np.zeros(2))
    assert tr.t_start == times[0] and tr.t_end == times[-1]
    assert tr.duration == pytest.approx(times[-1] - times[0])


def test_extrapolate_error_refuses_times_outside_the_range_hold_is_the_default():
    tr = cs.CubicTrajectory([0.5, 1.0, 2.5], [[0.0, 1.0], [0.4, 0.2], [1.0, -1.0]])
    # default and explicit "hold": the end points at rest, as the docstring says
    for mode in ({}, {"extrapolate": "hold"}):
        q, qd, qdd = tr.evaluate(3.0, **mode)
        np.testing.assert_array_equal(q, [1.0, -1.0])
        np.testing.assert_array_equal(qd, [0.0, 0.0])
        np.testing.assert_array_equal(qdd, [0.0, 0.0])
    assert "held at rest" in cs.CubicTrajectory.__doc__
    assert "extrapolate" in cs.CubicTrajectory.evaluate.__doc__
    # "error": ValueError naming t and the range, scalar or array, on either side
    for t in (3.0, 0.4999, [0.6, 2.6]):
        with pytest.raises(ValueError, match=r"t = (3|0\.4999|2\.6) s is outside the trajectory's time range \[0\.5, 2\.5\]"):
            tr.evaluate(t, extrapolate="error")
    # inside the range (both ends included) "error" equals "hold"
    t = np.array([0.5, 0.7, 1.0, 2.0, 2.5])
    for a, b in zip(tr.evaluate(t, extrapolate="error"), tr.evaluate(t)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(tr.evaluate(2.5, extrapolate="error")[0], [1.0, -1.0], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="extrapolate must be 'hold' or 'error', got 'clamp'"):
        tr.evaluate(1.0, extrapolate="clamp")


def test_coefficients_equal_direct_4x4_solve(trajectory):
    c, t = trajectory.coefficients, trajectory.times
    Q, V = trajectory.q_points, trajectory.qd_points
    assert c.shape == (len(t) - 1, trajectory.dof, 4)
    for k in range(len(t) - 1):
        for j in range(trajectory.dof):
            direct = hermite_solve(t[k + 1] - t[k], Q[k, j], Q[k + 1, j], V[k, j], V[k + 1, j])
            np.testing.assert_allclose(c[k, j], direct, rtol=1e-10, atol=1e-12)


def test_via_points_of_a_single_cubic_reproduce_it():
    rng = np.random.default_rng(3)
    a = rng.uniform(-1, 1, (4, 2))  # p(t) = a0 + a1 t + a2 t^2 + a3 t^3, two joints
    p = lambda t: a[0] + np.outer(t, a[1]) + np.outer(t**2, a[2]) + np.outer(t**3, a[3])
    dp = lambda t: a[1] + np.outer(2 * t, a[2]) + np.outer(3 * t**2, a[3])
    ddp = lambda t: 2 * a[2] + np.outer(6 * t, a[3])
    times = np.sort(rng.uniform(0.0, 2.0, 6))
    dense = np.linspace(times[0], times[-1], 501)
    given = cs.CubicTrajectory(times, p(times), dp(times))
    # a clamped spline with the cubic's end slopes is that cubic, too
    spline = cs.CubicTrajectory(times, p(times), spline=True, qd_start=dp(times[:1])[0], qd_end=dp(times[-1:])[0])
    for tr in (given, spline):
        q, qd, qdd = tr.evaluate(dense)
        np.testing.assert_allclose(q, p(dense), rtol=0, atol=1e-12)
        np.testing.assert_allclose(qd, dp(dense), rtol=0, atol=1e-11)
        np.testing.assert_allclose(qdd, ddp(dense), rtol=0, atol=1e-10)


def test_spline_option_has_continuous_acceleration():
    rng = np.random.default_rng(5)
    times, q = random_knots(rng, N=9, n=3)
    spline = cs.CubicTrajectory(times, q, spline=True)
    heur = cs.CubicTrajectory(times, q)
    assert spline.velocity_rule == "spline" and heur.velocity_rule == "heuristic"
    h = np.diff(times)

    def jumps(tr):
        c = tr.coefficients
        return np.array([poly(c[k], h[k], 2) - poly(c[k + 1], 0.0, 2) for k in range(len(h) - 1)])

    assert np.abs(jumps(spline)).max() < 1e-9
    # the check can fail: the heuristic rule is only C1
    assert np.abs(jumps(heur)).max() > 1e-2


def test_heuristic_rule_averages_slopes_and_stops_at_turning_points():
    times = np.array([0.0, 1.0, 3.0, 4.0, 5.0])
    q = np.array([0.0, 1.0, 2.0, 0.0, 0.0])
    tr = cs.CubicTrajectory(times, q)
    v = tr.qd_points[:, 0]
    assert v[1] == pytest.approx(0.5 * (1.0 + 0.5))  # same sign: average of slopes
    assert v[2] == 0.0                               # slope changes sign
    assert v[3] == 0.0                               # next segment is flat
    assert q.ndim == 1 and tr.dof == 1               # a flat array is one joint


def test_vectorised_evaluation_equals_scalar(trajectory):
    ts = np.linspace(trajectory.t_start - 0.5, trajectory.t_end + 0.5, 97)
    Q, QD, QDD = trajectory.evaluate(ts)
    assert Q.shape == QD.shape == QDD.shape == (97, trajectory.dof)
    for i, t in enumerate(ts):
        q, qd, qdd = trajectory.evaluate(float(t))
        assert q.shape == (trajectory.dof,)
        assert np.array_equal(q, Q[i]) and np.array_equal(qd, QD[i]) and np.array_equal(qdd, QDD[i])


def test_derivatives_match_finite_differences(trajectory):
    t = np.linspace(trajectory.t_start + 1e-3, trajectory.t_end - 1e-3, 41)
    eps = 1e-6
    q_p, qd_p, _ = trajectory.evaluate(t + eps)
    q_m, qd_m, _ = trajectory.evaluate(t - eps)
    _, qd, qdd = trajectory.evaluate(t)
    np.testing.assert_allclose((q_p - q_m) / (2 * eps), qd, atol=1e-6)
    # acceleration may jump at knots (C1 rules), so compare away from them
    away = np.min(np.abs(t[:, None] - trajectory.times[None, :]), axis=1) > 1e-4
    np.testing.assert_allclose(((qd_p - qd_m) / (2 * eps))[away], qdd[away], atol=1e-5)


def test_pickle_round_trip(trajectory):
    back = pickle.loads(pickle.dumps(trajectory))
    assert back.velocity_rule == trajectory.velocity_rule
    assert np.array_equal(back.coefficients, trajectory.coefficients)
    assert np.array_equal(back.qd_points, trajectory.qd_points)


def test_is_a_reference_and_python_subclasses_work():
    tr = cs.CubicTrajectory([0.0, 1.0], [[0.0], [1.0]])
    assert isinstance(tr, cs.Reference)

    class Ramp(cs.Reference):
        dof = 1
        t_start = 0.0
        t_end = 2.0

        def evaluate(self, t):
            return np.array([t]), np.array([1.0]), np.array([0.0])

    r = Ramp()
    # through the C++ interface (the virtual call lands in Python)
    q, qd, qdd = cs.Reference.evaluate(r, np.array([0.5, 1.5]))
    np.testing.assert_array_equal(q[:, 0], [0.5, 1.5])
    assert cs.Reference.dof.fget(r) == 1 and cs.Reference.t_end.fget(r) == 2.0



@settings(max_examples=150, deadline=None)
@given(data=st.data(), N=st.integers(2, 8), n=st.integers(1, 3), rule=st.sampled_from(["heuristic", "given", "spline"]))
def test_continuity_and_interpolation_property(data, N, n, rule):
    steps = data.draw(hnp.arrays(float, N, elements=st.floats(0.01, 5.0)))
    times = np.cumsum(steps) - data.draw(st.floats(-10.0, 10.0))
    q = data.draw(hnp.arrays(float, (N, n), elements=st.floats(-10.0, 10.0)))
    v = data.draw(hnp.arrays(float, (N, n), elements=st.floats(-10.0, 10.0)))
    if rule == "given":
        tr = cs.CubicTrajectory(times, q, v)
    else:
        tr = cs.CubicTrajectory(times, q, spline=rule == "spline", qd_start=v[0], qd_end=v[-1])
    c, h = tr.coefficients, np.diff(times)
    scale = 1.0 + np.abs(q).max() + np.abs(v).max()
    np.testing.assert_allclose(tr.evaluate(times)[0], q, rtol=0, atol=1e-12 * scale)
    for k in range(N - 2):
        np.testing.assert_allclose(poly(c[k], h[k]), poly(c[k + 1], 0.0), rtol=0, atol=1e-12 * scale)
        # velocity: round-off of the closed form grows like 1/h
        np.testing.assert_allclose(poly(c[k], h[k], 1), poly(c[k + 1], 0.0, 1), rtol=0,
                                   atol=1e-12 * scale / min(h[k], h[k + 1]))
        if rule == "spline":
            np.testing.assert_allclose(poly(c[k], h[k], 2), poly(c[k + 1], 0.0, 2), rtol=0,
                                       atol=1e-11 * scale / min(h[k], h[k + 1]) ** 2)


# ---- bad input: one test per kind ----

def test_non_increasing_times_rejected():
    with pytest.raises(ValueError, match="times must be strictly increasing"):
        cs.CubicTrajectory([0.0, 1.0, 1.0], np.zeros((3, 2)))
    with pytest.raises(ValueError, match="times must be strictly increasing"):
        cs.CubicTrajectory([0.0, 2.0, 1.0], np.zeros((3, 2)))


def test_mismatched_lengths_rejected():
    with pytest.raises(ValueError, match="q_points"):
        cs.CubicTrajectory([0.0, 1.0, 2.0], np.zeros((2, 2)))
    with pytest.raises(ValueError, match="qd_points"):
        cs.CubicTrajectory([0.0, 1.0, 2.0], np.zeros((3, 2)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="qd_start"):
        cs.CubicTrajectory([0.0, 1.0, 2.0], np.zeros((3, 2)), qd_start=np.zeros(3))


def test_nan_rejected():
    with pytest.raises(ValueError, match="times must be finite"):
        cs.CubicTrajectory([0.0, np.nan, 2.0], np.zeros((3, 2)))
    with pytest.raises(ValueError, match="q_points must be finite"):
        cs.CubicTrajectory([0.0, 1.0, 2.0], [[0.0, 0.0], [np.nan, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match="qd_points must be finite"):
        cs.CubicTrajectory([0.0, 1.0], np.zeros((2, 1)), [[0.0], [np.inf]])
    tr = cs.CubicTrajectory([0.0, 1.0], np.zeros((2, 1)))
    with pytest.raises(ValueError, match="t must be finite"):
        tr.evaluate(np.nan)


def test_single_point_rejected():
    with pytest.raises(ValueError, match="at least 2 points"):
        cs.CubicTrajectory([0.0], np.zeros((1, 2)))


def test_conflicting_velocity_options_rejected():
    with pytest.raises(ValueError, match="spline"):
        cs.CubicTrajectory([0.0, 1.0], np.zeros((2, 1)), np.zeros((2, 1)), spline=True)
    with pytest.raises(ValueError, match="qd_start"):
        cs.CubicTrajectory([0.0, 1.0], np.zeros((2, 1)), np.zeros((2, 1)), qd_start=[0.0])


# ---- plotting and the example ----

def test_plot_trajectory(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from coopsim.plotting import plot_trajectory

    tr = cs.CubicTrajectory([0.0, 1.0, 2.0], [[0.0, 0.1], [1.0, 0.2], [0.5, 0.0]])
    fig = plot_trajectory(tr, "RP", samples=50, margin=0.2)
    axes = fig.axes
    assert len(axes) == 6  # q, qd, qdd for the revolute joint, then their twins (right) for the prismatic one
    # one curve per joint and panel, plus knot markers on q and qd
    # (and the knots' vertical lines on the left axes)
    assert len(axes[0].lines) == 2 + 3 and len(axes[3].lines) == 2 and len(axes[2].lines) == 1 + 3
    np.testing.assert_allclose(axes[0].lines[0].get_xdata()[[0, -1]], [-0.2, 2.2])
    assert axes[0].get_legend().get_texts()[1].get_text() == "d2 (m)"
    fig.savefig(tmp_path / "t.png")
    plt.close(fig)
    with pytest.raises(ValueError, match="joints"):
        plot_trajectory(tr, joints=[2])


def test_plan_trajectory_example_runs(tmp_path):
    import importlib.util
    import pathlib

    path = pathlib.Path(__file__).resolve().parents[1] / "examples" / "plan_trajectory.py"
    spec = importlib.util.spec_from_file_location("plan_trajectory_example", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--out", str(tmp_path), "--points", "3"])
    for name in ("plan_trajectory_joints.png", "plan_trajectory_path.png"):
        assert (tmp_path / name).stat().st_size > 10_000


def test_overflowing_segments_rejected():
    # finite knots whose cubics would overflow: refused when built, never NaN when evaluated
    with pytest.raises(ValueError, match="segment 0 of joint 0 .* overflows"):
        cs.CubicTrajectory([0.0, 1.0, 2.0], [[0.0], [1e308], [-1e308]])
    with pytest.raises(ValueError, match="overflows"):
        cs.CubicTrajectory([0.0, 1e-300, 1.0], [[0.0], [1.0], [0.0]])
