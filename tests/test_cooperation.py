"""Two holders of one body: the external and internal wrenches of their welds, the squeeze, the load shares
and the clamps' relative pose error, computed by the engine per log row (held_body.hpp), against analytic
cases and coopsim.grasp's Python reference."""
from __future__ import annotations

import numpy as np
import pytest

import coopsim as cs
from coopsim import grasp
from test_grasp import G_BAR, two_holders

UP = np.array([0.0, 0.0, 1.0])


def bar_points(a, b):
    """A bar along x with its centre of mass at the origin, held at x = -a and x = b."""
    return np.zeros(3), np.array([-a, 0.0, 0.0]), np.array([b, 0.0, 0.0])


def test_two_pins_holding_a_bar_off_centre_at_rest_carry_no_internal_wrench_and_share_by_the_lever_rule():
    m_g = 7.3
    for a, b in ((0.05, 0.15), (0.3, 0.1), (0.2, 0.2)):
        c, pa, pb = bar_points(a, b)
        fa, fb = m_g * b / (a + b), m_g * a / (a + b)  # the pins' statics: forces up, no moment about c
        ha, hb = np.r_[0, 0, fa, 0, 0, 0], np.r_[0, 0, fb, 0, 0, 0]
        r = cs.cooperation_wrenches(c, pa, ha, pb, hb)
        np.testing.assert_allclose(r.external, [0, 0, m_g, 0, 0, 0], atol=1e-12)  # balances the weight
        np.testing.assert_allclose(r.internal, 0, atol=1e-12 * m_g)
        assert r.squeeze == 0 and r.twist == 0 and r.shear == 0 and np.all(r.bending == 0)
        np.testing.assert_allclose(r.load_share, [b / (a + b), a / (a + b)], rtol=1e-6)
        # whereas the Euclidean pseudo-inverse would call part of the weight internal when off-centre
        euclid = grasp.internal_wrenches([ha, hb], [pa, pb], c)
        assert (np.abs(euclid).max() > 0.01 * m_g) == (a != b)


def test_a_pure_squeeze_reads_as_squeeze_and_a_twist_as_twist():
    c, pa, pb = bar_points(0.05, 0.15)
    e = (pb - pa) / np.linalg.norm(pb - pa)
    weight = np.r_[0, 0, G_BAR * 0.75, 0, 0, 0], np.r_[0, 0, G_BAR * 0.25, 0, 0, 0]
    for s in (3.0, -2.5, 40.0):  # > 0 pushing together (compression), < 0 pulling apart (tension)
        ha, hb = weight[0] + np.r_[s * e, 0, 0, 0], weight[1] + np.r_[-s * e, 0, 0, 0]
        r = cs.cooperation_wrenches(c, pa, ha, pb, hb)
        assert r.squeeze == pytest.approx(s, rel=1e-2)
        assert r.squeeze == pytest.approx(s, rel=1e-12)  # exactly, in fact
        np.testing.assert_allclose(r.internal, np.r_[s * e, 0, 0, 0, -s * e, 0, 0, 0], atol=1e-12)
        np.testing.assert_allclose(r.external, [0, 0, G_BAR, 0, 0, 0], atol=1e-12)
        np.testing.assert_allclose(r.load_share, [0.75, 0.25], rtol=1e-12)
    # a twist about the line: opposite moments along it, which move nothing
    tw = 0.4
    ha, hb = weight[0] + np.r_[0, 0, 0, tw * e], weight[1] + np.r_[0, 0, 0, -tw * e]
    r = cs.cooperation_wrenches(c, pa, ha, pb, hb)
    assert r.twist == pytest.approx(tw, rel=1e-12)
    assert abs(r.squeeze) < 1e-12 and abs(r.shear) < 1e-12
    np.testing.assert_allclose(r.internal, np.r_[0, 0, 0, tw * e, 0, 0, 0, -tw * e], atol=1e-12)
    np.testing.assert_allclose(r.bending, 0, atol=1e-12)
    # a moment about the line that both apply alike turns the body: external, not internal
    ha, hb = weight[0] + np.r_[0, 0, 0, tw * e], weight[1] + np.r_[0, 0, 0, tw * e]
    r = cs.cooperation_wrenches(c, pa, ha, pb, hb)
    assert abs(r.twist) < 1e-12 and np.abs(r.internal).max() < 1e-12
    np.testing.assert_allclose(r.external[3:], 2 * tw * e, atol=1e-12)
    # bending: opposite moments across the line
    n = np.array([0.0, 1.0, 0.0])
    ha, hb = weight[0] + np.r_[0, 0, 0, 0.3 * n], weight[1] + np.r_[0, 0, 0, -0.3 * n]
    r = cs.cooperation_wrenches(c, pa, ha, pb, hb)
    np.testing.assert_allclose(r.bending, [0.3, 0.3], rtol=1e-12)
    assert abs(r.twist) < 1e-12 and abs(r.squeeze) < 1e-12 and abs(r.shear) < 1e-12


def test_random_holds_match_the_python_reference_and_the_weighted_limit():
    rng = np.random.default_rng(7)
    for _ in range(50):
        c, pa, pb = rng.normal(size=(3, 3))
        ha, hb = rng.normal(size=(2, 6)) * [5, 5, 5, 0.5, 0.5, 0.5]
        r = cs.cooperation_wrenches(c, pa, ha, pb, hb)
        G = grasp.grasp_matrix([pa, pb], c)
        np.testing.assert_allclose(r.external, G @ np.r_[ha, hb], atol=1e-12)
        ref = grasp.internal_wrenches([ha, hb], [pa, pb], c, metric="forces").reshape(-1)
        np.testing.assert_allclose(r.internal, ref, atol=1e-12)
        np.testing.assert_allclose(G @ r.internal, 0, atol=1e-12)  # in W's null space
        # the metric's definition: the weighted least norm |f|^2 + lambda^2 |mu|^2 as lambda grows
        lam = 1e4
        Winv = np.diag(np.tile(np.r_[np.ones(3), np.full(3, lam ** -2)], 2))
        h = np.r_[ha, hb]
        weighted = h - Winv @ G.T @ np.linalg.solve(G @ Winv @ G.T, G @ h)
        np.testing.assert_allclose(r.internal, weighted, atol=1e-6)
        # the squeeze is the internal force along the line
        e = (pb - pa) / np.linalg.norm(pb - pa)
        assert r.squeeze == pytest.approx(r.internal[:3] @ e, abs=1e-12)
    # both points at one place: the old half difference is the internal part there
    c, p = np.zeros(3), np.array([0.1, 0.2, 0.0])
    ha, hb = rng.normal(size=(2, 6))
    r = cs.cooperation_wrenches(c, p, ha, p, hb)
    np.testing.assert_allclose(r.internal, np.r_[(ha - hb) / 2, (hb - ha) / 2], atol=1e-12)
    assert np.isnan(r.squeeze)
    with pytest.raises(ValueError, match="up must be a finite nonzero vector"):
        cs.cooperation_wrenches(c, p, ha, p, hb, up=np.zeros(3))
    with pytest.raises(ValueError, match="wrench_a"):
        cs.cooperation_wrenches(c, p, ha[:5], p, hb)


def test_the_old_half_difference_reads_an_uneven_weight_split_as_internal_the_squeeze_does_not():
    sim = two_holders(-0.05, 0.15)  # 6-DOF welds at -0.05 and +0.15 m from the bar's centre
    log = sim.run(1.0, progress=False)
    co = log.cooperation(0, 1)
    both = co["holding"]
    with pytest.warns(DeprecationWarning, match="not the internal wrench"):
        old = log.internal_wrench(0, 1)
    rest = both & (log.t > 0.5)
    # the old figure: half the difference of the welds' vertical forces, 1 % of the weight here
    assert np.linalg.norm(old[rest, :3], axis=1).min() > 0.01 * G_BAR
    # the squeeze along the line between the welds: nothing pushes or pulls the bar along it
    assert np.abs(co["squeeze"][rest]).max() < 1e-3 * G_BAR
    # the same with pins: the old figure reads a quarter of the weight
    sim = two_holders(-0.05, 0.15, grasp_options=dict(weld_moment=False))
    log = sim.run(1.0, progress=False)
    co = log.cooperation(0, 1)
    rest = co["holding"] & (log.t > 0.5)
    with pytest.warns(DeprecationWarning):
        old = log.internal_wrench(0, 1)
    np.testing.assert_allclose(np.abs(old[rest, 2]), 0.25 * G_BAR, rtol=1e-3)
    assert np.abs(co["squeeze"][rest]).max() < 0.01 * G_BAR


def test_two_pin_welds_at_rest_in_a_simulation_share_by_the_lever_rule():
    # point welds at -0.05 and +0.15 m from the bar's centre: 0.75 / 0.25 of its weight
    sim = two_holders(-0.05, 0.15, grasp_options=dict(weld_moment=False))
    log = sim.run(1.0, progress=False)
    co = log.cooperation(0, 1)
    rest = co["holding"] & (log.t > 0.5)
    assert rest.sum() > 40
    np.testing.assert_allclose(co["load_share"][rest], np.tile([0.75, 0.25], (rest.sum(), 1)), atol=2e-5)
    # pins carry no moments: no twist, bending or shear; the squeeze is what the clamps do along the
    # bar, 0.8 % of its weight here (the welds are springs, the more loaded clamp sags 0.25 mm more and
    # the bar tilts 1.2 mrad under them: a real pull of the welds along the bar, equal and opposite)
    assert np.all(co["twist"][rest] == 0) and np.all(co["shear"][rest] == 0) and np.all(co["bending"][rest] == 0)
    assert np.abs(co["squeeze"][rest]).max() < 0.01 * G_BAR
    f_a, f_b = log[0].weld[rest, :3], log[1].weld[rest, :3]
    np.testing.assert_allclose(f_a[:, 0], -f_b[:, 0], atol=1e-12)
    np.testing.assert_allclose(co["external"][rest], np.tile([0, 0, G_BAR, 0, 0, 0], (rest.sum(), 1)), atol=1e-6)
    # the weld points lie where the grippers grasped, 0.2 m apart, fixed on the bar
    np.testing.assert_allclose(np.linalg.norm(co["point_b"] - co["point_a"], axis=1)[rest], 0.2, atol=1e-6)
    P = log.bodies["bar"].poses()
    local = np.einsum("nji,nj->ni", P[:, :3, :3], co["point_a"] - P[:, :3, 3])
    np.testing.assert_allclose(local[rest], np.tile(local[rest][0], (rest.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(co["centre"][rest], log.bodies["bar"].position[rest], atol=0)
    # the clamps keep their relative pose within the welds' sag
    assert np.abs(co["relative_pose_error"][rest, :3]).max() < 1e-3
    # the present state is the last row
    now = sim.cooperation(0, 1)
    assert now.holding and now.body == "bar"
    for k in ("external", "internal", "squeeze", "load_share", "relative_pose_error", "point_a"):
        np.testing.assert_array_equal(getattr(now, k), co[k][-1])


def test_the_engines_rows_equal_the_python_computation_on_the_same_rows():
    sim = two_holders(-0.1, 0.12, close_b=0.3, open_a=0.7)  # a handover: b grasps, then a lets go
    log = sim.run(1.5, progress=False)
    co = log.cooperation(0, 1)
    both = co["holding"]
    assert 0 < both.sum() < len(log.t)
    expected_both = (log[0].holding == "bar") & (log[1].holding == "bar")
    np.testing.assert_array_equal(both, expected_both)
    assert np.all(np.isnan(co["internal"][~both])) and np.all(co["body"][~both] == "")
    wa, wb = log[0].weld, log[1].weld
    rows = np.flatnonzero(both)
    for k in rows:
        c, pa, pb = co["centre"][k], co["point_a"][k], co["point_b"][k]
        G = grasp.grasp_matrix([pa, pb], c)
        np.testing.assert_allclose(co["external"][k], G @ np.r_[wa[k], wb[k]], rtol=0, atol=1e-12)
        internal = grasp.internal_wrenches([wa[k], wb[k]], [pa, pb], c, metric="forces").reshape(-1)
        np.testing.assert_allclose(co["internal"][k], internal, rtol=0, atol=1e-12)
        e = (pb - pa) / np.linalg.norm(pb - pa)
        assert co["squeeze"][k] == pytest.approx((wa[k, :3] - wb[k, :3]) @ e / 2, abs=1e-12)
        assert co["twist"][k] == pytest.approx((wa[k, 3:] - wb[k, 3:]) @ e / 2, abs=1e-12)
        share = np.array([wa[k, 2], wb[k, 2]]) / (wa[k, 2] + wb[k, 2])
        np.testing.assert_allclose(co["load_share"][k], share, rtol=0, atol=1e-12)
    # the second weld takes no load at first: a's share falls from all of it to none as it lets go
    assert co["load_share"][rows[0], 0] > 0.99 and co["load_share"][rows[-1], 0] < 0.2
    # a leads, b follows: b's clamp frame stays where the rigid hold at the second grasp puts it
    assert np.abs(co["relative_pose_error"][rows[0]]).max() < 1e-6
    assert np.abs(co["relative_pose_error"][rows, :3]).max() < 2e-3


def test_relative_pose_error_follows_the_clamps_kinematics():
    # b grasps at 0.3 s and a lets go at 0.7 s; both grippers only translate, so b's error against a's
    # lead is the change of p_b - p_a since the second grasp, here from the robots' own kinematics
    sim = two_holders(-0.1, 0.12, close_b=0.3, open_a=0.7)
    log = sim.run(1.0, progress=False)
    co = log.cooperation(0, 1)
    rows = np.flatnonzero(co["holding"])
    frames = [np.array([sim.robots[i].frames(q)[1] for q in log[i].q[rows]]) for i in (0, 1)]
    gap = frames[1][:, :3, 3] - frames[0][:, :3, 3]  # the clamp links' origins; the weld points are fixed in them
    err = co["relative_pose_error"][rows]
    np.testing.assert_allclose(err[:, 3:], 0, atol=1e-15)
    np.testing.assert_allclose(err[:, :3] - err[0, :3], gap - gap[0], atol=1e-12)
    assert np.abs(err[0]).max() < 1e-5  # the first row, a few steps after the grasp
    assert np.abs(err[:, 2]).max() > 1e-5  # the clamps do move against each other while a opens


def test_cooperation_bad_input_names_the_argument():
    sim = two_holders(-0.1, 0.1)
    log = sim.run(0.1, progress=False)
    with pytest.raises(ValueError, match="a must be less than b"):
        log.cooperation(1, 0)
    with pytest.raises(ValueError, match="b must be the index of a robot"):
        log.cooperation(0, 2)
    with pytest.raises(ValueError, match="robots a < b"):
        sim.cooperation(1, 1)
    with pytest.raises(ValueError, match="robot must be an index"):
        sim.cooperation(0, 5)
    table = cs.SimulationLog.from_dataframe(log.to_dataframe())
    with pytest.raises(ValueError, match="no cooperation columns"):
        table.cooperation(0, 1)
    assert [n for n, _, _ in cs.log.cooperation_schema()][:2] == ["body", "centre"]
    with pytest.raises(ValueError, match=r"metric must be one of \['euclidean', 'forces'\], got 'l2'"):
        grasp.internal_wrenches(np.zeros((2, 6)), np.eye(3)[:2], np.zeros(3), metric="l2")
    # the least-norm split in the pin metric: the lever rule, and an internal part that changes nothing
    c, pa, pb = bar_points(0.05, 0.15)
    split = grasp.load_split([0, 0, G_BAR, 0, 0, 0], [pa, pb], c, metric="forces")
    np.testing.assert_allclose(split, [[0, 0, 0.75 * G_BAR, 0, 0, 0], [0, 0, 0.25 * G_BAR, 0, 0, 0]], atol=1e-12)
    squeezed = grasp.load_split([0, 0, G_BAR, 0, 0, 0], [pa, pb], c, internal=[[1, 0, 0, 0, 0, 0], [0] * 6],
                                metric="forces")
    np.testing.assert_allclose(squeezed - split, [[0.5, 0, 0, 0, 0, 0], [-0.5, 0, 0, 0, 0, 0]], atol=1e-12)
