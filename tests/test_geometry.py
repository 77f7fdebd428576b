"""Link geometry in the engine: boxes fixed to the links, the clamp, Robot.shapes(q)."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

import coopsim as cs
from conftest import random_robot

MAKERS = [cs.robots.scara1, cs.robots.scara2]


def poses(robot, count, seed=0):
    lo, hi = robot.q_limits.T
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    return np.random.default_rng(seed).uniform(lo, hi, (count, robot.dof))


def penetration(Ta, ha, Tb, hb):
    """Separating-axis test of two boxes: the smallest overlap over the 15
    axes (m); > 0 means they overlap by that much, <= 0 that they are apart."""
    A, B = Ta[:3, :3], Tb[:3, :3]
    d = Tb[:3, 3] - Ta[:3, 3]
    axes = [A[:, i] for i in range(3)] + [B[:, i] for i in range(3)]
    for i, j in itertools.product(range(3), range(3)):
        c = np.cross(A[:, i], B[:, j])
        if np.linalg.norm(c) > 1e-9:
            axes.append(c / np.linalg.norm(c))
    return min(np.sum(ha * np.abs(A.T @ u)) + np.sum(hb * np.abs(B.T @ u)) - abs(d @ u) for u in axes)


def overlapping(robot, q, tol=1e-9):
    P, H = robot.shapes(q)
    names = [b.name for b in robot.boxes]
    return {(names[i], names[j]) for i, j in itertools.combinations(range(len(P)), 2)
            if penetration(P[i], H[i], P[j], H[j]) > -tol}


@pytest.mark.parametrize("robot", [m() for m in MAKERS] + [cs.robots.scara2(base_position=(0.8, 0.2, 0.0),
                                                                           base_yaw=2.0, L1=0.25),
                                                           random_robot(3, mixed=True)],
                         ids=["scara1", "scara2", "scara2-placed", "random"])
def test_shapes_are_the_boxes_placed_by_the_frames(robot):
    boxes = robot.boxes
    assert len(boxes) >= robot.dof
    for q in poses(robot, 5):
        P, H = robot.shapes(q)
        F = robot.frames(q)
        assert P.shape == (len(boxes), 4, 4) and H.shape == (len(boxes), 3)
        for b, T, h in zip(boxes, P, H):
            np.testing.assert_allclose(T, F[b.link] @ b.pose, rtol=0, atol=1e-12)
            np.testing.assert_array_equal(h, b.half_extents)


@pytest.mark.parametrize("make", MAKERS)
def test_scara_link_boxes_are_their_mass_boxes_on_the_com_frames(make):
    robot = make()
    by_name = {b.name: i for i, b in enumerate(robot.boxes)}
    for q in poses(robot, 5):
        P, _ = robot.shapes(q)
        C = robot.com_frames(q)
        for i in range(robot.dof):
            np.testing.assert_allclose(P[by_name[f"link{i + 1}"]], C[i], rtol=0, atol=1e-12)
    # the box of each link is the one whose inertia the link carries
    for i in range(robot.dof):
        h = robot.boxes[by_name[f"link{i + 1}"]].half_extents
        np.testing.assert_allclose(robot.inertias[i], cs.box_inertia(robot.masses[i], *(2 * h)), rtol=1e-14)
    # the base column stands on the floor and reaches link 1's underside
    P, H = robot.shapes(np.zeros(6))
    base, link1 = by_name["base"], by_name["link1"]
    assert P[base][2, 3] - H[base][2] == pytest.approx(0.0, abs=1e-15)
    assert P[base][2, 3] + H[base][2] == pytest.approx(P[link1][2, 3] - H[link1][2], abs=1e-15)


@pytest.mark.parametrize("make", MAKERS)
def test_clamp_faces_hold_the_tool_centre_point_between_the_jaws(make):
    robot = make()
    c = robot.clamp
    assert c.fixed_link == 5 and c.moving_joint == 6 and c.jaw_length == robot.dimensions["jaw_length"]
    by_name = {b.name: i for i, b in enumerate(robot.boxes)}
    tj = robot.dimensions["jaw_thickness"]
    for q in poses(robot, 6):
        fixed, moving = robot.clamp_faces(q)
        T = robot.fk(q)
        # the TCP is midway between the inner faces, with its y along the jaw axis
        np.testing.assert_allclose((fixed[:3, 3] + moving[:3, 3]) / 2, T[:3, 3], rtol=0, atol=1e-12)
        assert np.linalg.norm(moving[:3, 3] - fixed[:3, 3]) == pytest.approx(q[5], abs=1e-12)
        np.testing.assert_allclose(fixed[:3, 2], T[:3, 1], atol=1e-12)
        np.testing.assert_allclose(moving[:3, 2], -T[:3, 1], atol=1e-12)
        # x along the jaw: the TCP's approach axis
        np.testing.assert_allclose(fixed[:3, 0], T[:3, 2], atol=1e-12)
        # each jaw's box lies behind its inner face, its face on the face frame's plane
        P, H = robot.shapes(q)
        for face, name in ((fixed, "fixed_jaw"), (moving, "link6")):
            centre = P[by_name[name]][:3, 3]
            np.testing.assert_allclose(centre, face[:3, 3] - face[:3, 2] * tj / 2, rtol=0, atol=1e-12)


def test_default_boxes_follow_the_dh_segments():
    robot = random_robot(11, mixed=True, dof=5)
    boxes = robot.boxes
    assert [b.link for b in boxes if b.name != "base"] == list(range(1, robot.dof + 1))
    dh = robot.dh
    t = 0.02
    for b in boxes:
        if b.name == "base":
            continue
        i = b.link
        theta, d, a, alpha = dh[i - 1]
        ends = b.pose[:3, 3] + np.outer([-1, 1], b.pose[:3, 0] * b.half_extents[0])
        foot = np.array([-a, 0.0, 0.0])
        if robot.joint_types[i - 1] == "R" and abs(d) > abs(a):
            A = cs.dh_transform(theta, d, a, alpha)
            start = np.linalg.solve(A, [0.0, 0.0, 0.0, 1.0])[:3]  # frame i-1's origin in frame i
            seg = (start, foot)
        else:
            seg = (foot, np.zeros(3))
        length = np.linalg.norm(seg[1] - seg[0])
        if length >= t:
            seg = np.array(seg)
            gap = min(np.abs(ends - seg).max(), np.abs(ends - seg[::-1]).max())  # either way round
            assert gap < 1e-12, (ends, seg)
        np.testing.assert_allclose(b.half_extents[1:], [t / 2, t / 2])
    # a base above the floor stands on a column from z = 0
    base = [b for b in boxes if b.name == "base"]
    z = robot.base_position[2]
    assert (len(base) == 1) == (z > t)
    if base:
        P, H = robot.shapes(np.zeros(robot.dof))
        T = P[[b.name for b in boxes].index("base")]
        low = T[:3, 3] - T[:3, :3] @ (H[0] * [1, 0, 0])
        high = T[:3, 3] + T[:3, :3] @ (H[0] * [1, 0, 0])
        assert sorted([low[2], high[2]]) == pytest.approx([0.0, z], abs=1e-12)


def test_boxes_and_clamp_can_be_given_and_are_checked():
    base = dict(dh=[[0, 0.5, 0.4, 0]], com=[[0, 0.5, 0.2, 0]], masses=[1.0], inertias=[np.eye(3) * 0.01],
                joint_types="R")
    box = cs.LinkBox(1, [0.2, 0.02, 0.02], cs.dh_transform(0, 0, -0.2, 0), "arm")
    r = cs.Robot.from_dh(**base, boxes=[box])
    assert [b.name for b in r.boxes] == ["arm"] and r.clamp is None
    P, _ = r.shapes([0.5])
    np.testing.assert_allclose(P[0], r.frames([0.5])[1] @ box.pose, atol=1e-15)
    with pytest.raises(ValueError, match="half extents"):
        cs.Robot.from_dh(**base, boxes=[cs.LinkBox(1, [0.2, 0.0, 0.02])])
    with pytest.raises(ValueError, match="link must be"):
        cs.Robot.from_dh(**base, boxes=[cs.LinkBox(2, [0.2, 0.1, 0.02])])
    with pytest.raises(ValueError, match="boxes"):
        cs.Robot.from_dh(**base, boxes=[])
    with pytest.raises(ValueError, match="pose"):
        cs.LinkBox(1, [0.1, 0.1, 0.1], np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="clamp: fixed_link"):
        cs.Robot.from_dh(**base, clamp=cs.Clamp(1, np.eye(4), 2, 0.04, 0.05))
    r1 = cs.robots.scara1()
    with pytest.raises(ValueError, match="prismatic"):
        r1.with_geometry(r1.boxes, cs.Clamp(4, np.eye(4), 5, 0.04, 0.05))
    with pytest.raises(ValueError, match="z axis"):
        r1.with_geometry(r1.boxes, cs.Clamp(5, cs.dh_transform(0, 0, 0, np.pi / 2), 6, 0.04, 0.05))
    with pytest.raises(ValueError, match="jaw_length"):
        r1.with_geometry(r1.boxes, cs.Clamp(5, np.eye(4), 6, 0.0, 0.05))
    with pytest.raises(ValueError, match="no clamp"):
        r.clamp_faces([0.0])
    # geometry survives pickling and the other copies
    import pickle

    for copy in (pickle.loads(pickle.dumps(r1)), r1.with_base([1, 0, 0], 0.5), r1.with_backend("numeric")):
        assert [b.name for b in copy.boxes] == [b.name for b in r1.boxes]
        np.testing.assert_array_equal(copy.clamp.fixed_face, r1.clamp.fixed_face)
    assert pickle.loads(pickle.dumps(r)).boxes[0].name == "arm"


# Boxes of one SCARA that touch at every pose (documented in coopsim.robots):
# each link with the next at their joint, the base column with link 1, the
# fixed jaw with the clamp body it is fixed to; the jaws touch each other
# when the clamp is closed.
TOUCHING = {("base", "link1"), ("link1", "link2"), ("link2", "link3"), ("link3", "link4"), ("link4", "link5"),
            ("link5", "link6"), ("link5", "fixed_jaw"), ("link6", "fixed_jaw")}
ALWAYS = TOUCHING - {("link5", "link6"), ("link6", "fixed_jaw")}


@pytest.mark.parametrize("make", MAKERS)
def test_scara_boxes_overlap_only_where_they_touch(make):
    robot = make()
    quill = 2 if robot.name == "scara1" else 3
    arm = range(1, quill)  # elbow joints
    # over the whole joint range, the pairs that meet at every pose are the documented ones
    counts = {}
    samples = poses(robot, 80, seed=1)
    for q in samples:
        for pair in overlapping(robot, q):
            counts[pair] = counts.get(pair, 0) + 1
    assert {p for p, c in counts.items() if c == len(samples)} == ALWAYS
    # in the working range (quill down 6 cm or more, elbows within +-90 deg, jaw open) nothing else meets
    lo, hi = robot.q_limits.T.copy()
    lo[quill], lo[5] = 0.06, 0.001
    for j in arm:
        lo[j], hi[j] = max(lo[j], -np.pi / 2), min(hi[j], np.pi / 2)
    for q in np.random.default_rng(2).uniform(lo, hi, (80, 6)):
        assert overlapping(robot, q) <= TOUCHING - {("link6", "fixed_jaw")}, q
    # a closed clamp: the jaws' faces meet
    q = samples[0].copy()
    q[5] = 0.0
    assert ("link6", "fixed_jaw") in overlapping(robot, q)
    # the self-contacts outside it are real: a quill at its top brings the wrist into the arm
    q = 0.5 * (robot.q_limits[:, 0] + robot.q_limits[:, 1])
    q[quill] = 0.0
    extra = overlapping(robot, q) - TOUCHING
    assert extra and all(a in {"link2", "link3"} and b in {"link4", "link5"} for a, b in extra), extra


def random_pose(rng, spread=0.3):
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-spread, spread, 3)
    return T


def nearest_points_gap(Ta, ha, Tb, hb, tol):
    """The reference distance: min |p_a - p_b| over points of both boxes, p = t + R u with |u_k| <= h_k, by
    scipy's bounded linear least squares."""
    from scipy.optimize import lsq_linear

    A = np.hstack([Ta[:3, :3], -Tb[:3, :3]])
    res = lsq_linear(A, Tb[:3, 3] - Ta[:3, 3], bounds=(-np.r_[ha, hb], np.r_[ha, hb]), tol=tol)
    return np.linalg.norm(A @ res.x - (Tb[:3, 3] - Ta[:3, 3]))


def test_box_distance_is_the_nearest_points_gap_of_a_bounded_least_squares_problem():
    # the reference: nearest_points_gap; overlapping boxes give minus the separating-axis overlap
    rng = np.random.default_rng(7)
    apart = 0
    for _ in range(300):
        Ta, Tb = random_pose(rng), random_pose(rng)
        ha, hb = rng.uniform(0.01, 0.15, 3), rng.uniform(0.01, 0.15, 3)
        d = cs.box_distance(Ta, ha, Tb, hb)
        gap = nearest_points_gap(Ta, ha, Tb, hb, tol=1e-14)
        if gap > 1e-9:
            apart += 1
            assert d == pytest.approx(gap, abs=1e-9)
        else:
            assert d <= 0.0
    assert apart > 100
    # analytic cases: faces 0.2 apart, an overlap of 5 cm, a corner gap, touching
    I, T = np.eye(4), np.eye(4)
    for p, want in (([0.5, 0, 0], 0.2), ([0.25, 0, 0], -0.05), ([0.5, 0.4, 0.3], np.linalg.norm([0.2, 0.2, 0.1])),
                    ([0.3, 0.0, 0.0], 0.0)):
        T[:3, 3] = p
        assert cs.box_distance(I, [0.1, 0.1, 0.1], T, [0.2, 0.1, 0.1]) == pytest.approx(want, abs=1e-12)


def test_box_distance_where_the_separating_axis_gap_is_the_distance():
    """The nearest features a SCARA's boxes meet: boxes turned about the vertical only (parallel vertical
    edges and faces), face to face, edge to edge, and random, against the bounded least-squares reference
    (9e-10 m): the separating-axis gap stands for the distance only when a face or edge pair is certain
    to hold the nearest points, GJK decides otherwise."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(17)
    checked = 0
    for k in range(600):
        Ta, Tb = np.eye(4), np.eye(4)
        kind = k % 3
        if kind == 0:    # yawed only
            Ta[:3, :3] = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)).as_matrix()
            Tb[:3, :3] = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)).as_matrix()
        elif kind == 1:  # one turned about one of its own axes by a multiple of 90 degrees: faces parallel
            Tb[:3, :3] = Rotation.from_euler("xyz"[k % 3], 90 * rng.integers(0, 4), degrees=True).as_matrix()
        else:
            Ta[:3, :3] = Rotation.random(random_state=rng).as_matrix()
            Tb[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        Ta[:3, 3], Tb[:3, 3] = rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.3, 0.3, 3)
        ha, hb = rng.uniform(0.01, 0.2, 3), rng.uniform(0.01, 0.2, 3)
        d = cs.box_distance(Ta, ha, Tb, hb)
        gap = nearest_points_gap(Ta, ha, Tb, hb, tol=1e-15)
        if gap > 1e-9:
            checked += 1
            assert d == pytest.approx(gap, abs=9e-10), (k, d, gap)
        else:
            assert d <= 0.0
    assert checked > 250


def test_box_distances_is_box_distance_for_every_pair_and_checks_its_arguments():
    r = cs.robots.scara1()
    P, H = r.shapes(np.array([0.3, 0.5, 0.1, 0.2, 1.0, 0.02]))
    T = np.eye(4)
    T[:3, 3] = [0.4, 0.2, 0.3]
    D = cs.box_distances(P, H, np.array([T, np.eye(4)]), np.array([[0.05, 0.05, 0.05], [0.02, 0.02, 0.02]]))
    assert D.shape == (len(P), 2)
    for i in range(len(P)):
        assert D[i, 0] == cs.box_distance(P[i], H[i], T, [0.05, 0.05, 0.05])
    k = np.arange(len(P))[::-1]
    np.testing.assert_array_equal(cs.box_distances(P, H, P[k], H[k], pairwise=True),
                                  [cs.box_distance(P[i], H[i], P[j], H[j]) for i, j in zip(range(len(P)), k)])
    with pytest.raises(ValueError, match="pairwise: poses_a and poses_b must have the same length"):
        cs.box_distances(P, H, P[:2], H[:2], pairwise=True)
    with pytest.raises(ValueError, match=r"wrong shape for half_b: expected \(2, 3\)"):
        cs.box_distances(P, H, np.array([T, T]), np.ones((3, 3)))
    with pytest.raises(ValueError, match="half_a: half extents must be finite and > 0"):
        cs.box_distance(T, [0.1, 0.0, 0.1], T, [0.1, 0.1, 0.1])
    bad = T.copy()
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match=r"poses_b\[1\] must be a rigid transform"):
        cs.box_distances(P, H, np.array([T, bad]), np.ones((2, 3)))


def test_box_clearances_is_the_minimum_of_box_distances_in_every_row():
    """Both SCARAs along random joint paths (poses that move: every pair moves) and against the
    container's walls (poses that do not): the pruned search finds the same minimum as box_distances
    on every pair, bit for bit, and a pair that has it; overlapping rows (negative) included."""
    from coopsim.tasks import scene

    r1, r2 = scene.scaras()  # at the task's bases
    rng = np.random.default_rng(11)
    lo1, hi1 = r1.q_limits[:, 0], r1.q_limits[:, 1]
    lo2, hi2 = r2.q_limits[:, 0], r2.q_limits[:, 1]
    # smooth paths (rows close to each other, as in a log) and jumps (each row on its own)
    n = 300
    s = np.linspace(0, 1, n)[:, None]
    q1 = np.vstack([lo1 + (hi1 - lo1) * (0.5 + 0.5 * np.sin(6 * s + rng.uniform(0, 6, 6))), rng.uniform(lo1, hi1, (n, 6))])
    q2 = np.vstack([lo2 + (hi2 - lo2) * (0.5 + 0.5 * np.sin(5 * s + rng.uniform(0, 6, 6))), rng.uniform(lo2, hi2, (n, 6))])
    P1 = np.array([r1.shapes(q)[0] for q in q1])
    P2 = np.array([r2.shapes(q)[0] for q in q2])
    H1, H2 = r1.shapes(q1[0])[1], r2.shapes(q2[0])[1]
    d, i, j = cs.box_clearances(P1, H1, P2, H2)
    assert d.shape == i.shape == j.shape == (2 * n,)
    for k in range(2 * n):
        D = cs.box_distances(P1[k], H1, P2[k], H2)
        assert d[k] == D.min() and D[i[k], j[k]] == d[k], k
    assert (d < 0).any() and (d > 0).any()
    # boxes that do not move: (kb, 4, 4)
    W = np.array([random_pose(rng, 0.4) for _ in range(4)])
    HW = rng.uniform(0.01, 0.1, (4, 3))
    d, i, j = cs.box_clearances(P1, H1, W, HW)
    for k in range(0, 2 * n, 7):
        D = cs.box_distances(P1[k], H1, W, HW)
        assert d[k] == D.min() and D[i[k], j[k]] == d[k]
    # the tables are read in place when they can be, and copied when numpy must convert them (a strided
    # view, a transposed copy in Fortran order): the same rows
    d2, i2, j2 = cs.box_clearances(P1[::3], H1, np.asfortranarray(P2[::3]), H2)
    e2, k2, l2 = cs.box_clearances(np.ascontiguousarray(P1[::3]), H1, np.ascontiguousarray(P2[::3]), H2)
    assert np.array_equal(d2, e2) and np.array_equal(i2, k2) and np.array_equal(j2, l2)
    # no rows
    d, i, j = cs.box_clearances(P1[:0], H1, P2[:0], H2)
    assert d.shape == (0,)


def test_box_clearances_checks_its_arguments():
    r = cs.robots.scara1()
    P, H = r.shapes(np.zeros(6))
    PA = np.array([P, P])
    with pytest.raises(ValueError, match=r"wrong shape for half_a"):
        cs.box_clearances(PA, H[:2], PA, H)
    with pytest.raises(ValueError, match=r"poses_b"):
        cs.box_clearances(PA, H, PA[:1], H)
    bad = PA.copy()
    bad[1, 2, 0, 0] = 2.0
    with pytest.raises(ValueError, match=r"poses_a\[1\]\[2\] must be a rigid transform"):
        cs.box_clearances(bad, H, PA, H)
    nan = PA.copy()
    nan[0, 0, 0, 3] = np.nan
    with pytest.raises(ValueError, match=r"poses_a must be finite"):
        cs.box_clearances(nan, H, PA, H)
    with pytest.raises(ValueError, match="half_b: half extents must be finite and > 0"):
        cs.box_clearances(PA, H, PA, -H)
    with pytest.raises(ValueError, match="at least one box"):
        cs.box_clearances(PA[:, :0], H[:0], PA, H)


def test_fk_and_shapes_of_many_states_are_those_of_each():
    r = cs.robots.scara2()
    q = np.random.default_rng(4).uniform(r.q_limits[:, 0], r.q_limits[:, 1], (20, 6))
    F = r.fk(q)
    P, H = r.shapes(q)
    assert F.shape == (20, 4, 4) and P.shape == (20, len(r.boxes), 4, 4)
    for i in range(20):
        np.testing.assert_array_equal(F[i], r.fk(q[i]))
        np.testing.assert_array_equal(P[i], r.shapes(q[i])[0])
    np.testing.assert_array_equal(H, r.shapes(q[0])[1])
    assert r.fk(q[:0]).shape == (0, 4, 4) and r.shapes(q[:0])[0].shape == (0, len(r.boxes), 4, 4)
    with pytest.raises(ValueError, match=r"wrong shape for q: expected \(N, 6\), got \(3, 5\)"):
        r.fk(np.ones((3, 5)))
    bad = q.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="q must be finite"):
        r.shapes(bad)
