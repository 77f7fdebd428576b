"""The built-in SCARAs: tables, geometry at known poses, dimension keywords
with mass properties following them, pickling."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import coopsim as cs


def test_scara1_geometry_at_known_poses():
    r = cs.robots.scara1(backend="numeric")
    assert (r.dof, r.joint_types) == (6, "RRPRRP")
    # arm stretched along x, clamp horizontal: TCP at L1 + L2 + L5 + jaw/2, height L_base - L4
    T = r.fk(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [0.30 + 0.25 + 0.08 + 0.02, 0.0, 0.42 - 0.05], atol=1e-15)
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-15)  # approach along the clamp
    # clamp pointing down, quill at 0.1, jaws 0.03 apart: the TCP moves by half the opening
    q = np.array([np.pi / 2, 0.0, 0.1, 0.0, np.pi / 2, 0.03])
    T = r.fk(q)
    np.testing.assert_allclose(T[:3, 2], [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(T[:3, 3], [0.0, 0.55, 0.42 - 0.1 - 0.05 - 0.08 - 0.02] + 0.015 * T[:3, 1],
                               atol=1e-15)
    # moving jaw frame sits d6 along the jaw axis from the fixed jaw
    F = r.frames(q)
    np.testing.assert_allclose(F[6][:3, 3] - F[5][:3, 3], 0.03 * F[5][:3, 2], atol=1e-15)


def test_scara2_geometry_at_known_poses():
    r = cs.robots.scara2(backend="numeric")
    assert (r.dof, r.joint_types) == (6, "RRRPRP")
    T = r.fk(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [0.53, 0.0, 0.40 - 0.06 - 0.02], atol=1e-15)
    np.testing.assert_allclose(T[:3, 2], [0, 0, -1], atol=1e-15)  # approach from above
    # theta2 = theta3 (the paper's IK convention) folds the arm symmetrically
    q = np.array([0.0, 0.4, 0.4, 0.2, 0.0, 0.0])
    T = r.fk(q)
    x = 0.20 + 0.18 * np.cos(0.4) + 0.15 * np.cos(0.8)
    y = 0.18 * np.sin(0.4) + 0.15 * np.sin(0.8)
    np.testing.assert_allclose(T[:3, 3], [x, y, 0.40 - 0.2 - 0.06 - 0.02], atol=1e-15)


def test_paper_table2_quill_centre_of_mass():
    """Table 2 row 4 (corrected): the quill's CoM sits Lc4 above its tip, d4 - Lc4."""
    r = cs.robots.scara2(backend="numeric")
    q = np.array([0.1, 0.2, -0.3, 0.17, 0.5, 0.01])
    F, C = r.frames(q), r.com_frames(q)
    np.testing.assert_allclose(C[3][:3, 3], F[4][:3, 3] - 0.15 * F[3][:3, 2], atol=1e-15)


@pytest.mark.parametrize("make", [cs.robots.scara1, cs.robots.scara2])
def test_dimensions_change_tables_and_mass_properties(make):
    r0 = make(backend="numeric")
    r1 = make(L1=0.35, width=0.07, backend="numeric")
    assert r1.dimensions["L1"] == 0.35 and r0.dimensions["L1"] != 0.35
    assert r1.dh[0, 2] == 0.35 and r1.com[0, 2] == pytest.approx(0.175)
    # constant density: link 1 mass scales with its volume L1 * width * height
    ratio = (0.35 * 0.07) / (r0.dimensions["L1"] * r0.dimensions["width"])
    assert r1.masses[0] == pytest.approx(r0.masses[0] * ratio, rel=1e-14)
    m = r1.masses[0]
    np.testing.assert_allclose(r1.inertias[0], cs.box_inertia(m, 0.35, 0.07, r1.dimensions["height"]), rtol=1e-14)
    assert not np.allclose(r1.mass_matrix(np.zeros(6)), r0.mass_matrix(np.zeros(6)))
    # given masses override the density rule
    r2 = make(masses=np.full(6, 0.5), backend="numeric")
    np.testing.assert_array_equal(r2.masses, np.full(6, 0.5))


# ---- every dimension keyword, against the documented box model ------------

# link i is a uniform box of its length along its own axis x robot width x
# link height (x, y, z edges in its CoM frame); the jaw a jaw_length x width x
# jaw_thickness plate (the robots module's docstring)
BOXES = {
    "scara1": [("L1", "width", "height"), ("L2", "width", "height"), ("width", "height", "quill_length"),
               ("width", "height", "L4"), ("L5", "width", "height"), ("jaw_length", "width", "jaw_thickness")],
    "scara2": [("L1", "width", "height"), ("L2", "width", "height"), ("L3", "width", "height"),
               ("width", "height", "quill_length"), ("width", "height", "L5"),
               ("jaw_length", "width", "jaw_thickness")],
}
# table entries (table, row, column, factor) that equal factor * keyword; DH
# columns are [theta, d, a, alpha]; a CoM sits halfway along its link, the
# quill's CoM half its length above the tip, the jaw's at half its length and
# half its thickness
TABLE_ENTRIES = {
    "scara1": {"L_base": [("dh", 0, 1, 1.0), ("com", 0, 1, 1.0)], "L1": [("dh", 0, 2, 1.0), ("com", 0, 2, 0.5)],
               "L2": [("dh", 1, 2, 1.0), ("com", 1, 2, 0.5)], "L4": [("dh", 3, 1, 1.0), ("com", 3, 1, 0.5)],
               "L5": [("dh", 4, 2, 1.0), ("com", 4, 2, 0.5)], "quill_length": [("com", 2, 1, -0.5)],
               "jaw_length": [("com", 5, 2, 0.5)], "jaw_thickness": [("com", 5, 1, 0.5)],
               "width": [], "height": []},
    "scara2": {"L_base": [("dh", 0, 1, 1.0), ("com", 0, 1, 1.0)], "L1": [("dh", 0, 2, 1.0), ("com", 0, 2, 0.5)],
               "L2": [("dh", 1, 2, 1.0), ("com", 1, 2, 0.5)], "L3": [("dh", 2, 2, 1.0), ("com", 2, 2, 0.5)],
               "L5": [("dh", 4, 1, 1.0), ("com", 4, 1, 0.5)], "quill_length": [("com", 3, 1, -0.5)],
               "jaw_length": [("com", 5, 2, 0.5)], "jaw_thickness": [("com", 5, 1, 0.5)],
               "width": [], "height": []},
}
# the TCP is halfway along the jaws: (frame, axis) along which the jaws extend
JAW_DIRECTION = {"scara1": (5, 0), "scara2": (5, 1)}
KEYWORD_CASES = [(name, key) for name in ("scara1", "scara2") for key in TABLE_ENTRIES[name]]


def solid_box_inertia(m, lx, ly, lz):
    return m / 12.0 * np.diag([ly**2 + lz**2, lx**2 + lz**2, lx**2 + ly**2])


def translated(frames, shifts):
    out = frames.copy()
    out[:, :3, 3] += shifts
    return out


def test_keyword_table_covers_every_dimension():
    # a new keyword must be added to the model above
    assert set(TABLE_ENTRIES["scara1"]) == set(cs.robots.SCARA1_DEFAULTS)
    assert set(TABLE_ENTRIES["scara2"]) == set(cs.robots.SCARA2_DEFAULTS)
    for name, defaults in (("scara1", cs.robots.SCARA1_DEFAULTS), ("scara2", cs.robots.SCARA2_DEFAULTS)):
        assert {k for box in BOXES[name] for k in box} <= set(defaults)


@pytest.mark.parametrize("name,key", KEYWORD_CASES, ids=[f"{n}-{k}" for n, k in KEYWORD_CASES])
def test_each_dimension_keyword_changes_tables_mass_properties_and_geometry(name, key):
    make = getattr(cs.robots, name)
    r0 = make(backend="numeric")
    v0 = r0.dimensions[key]
    v = 1.3 * v0
    r = make(backend="numeric", **{key: v})
    assert r.dimensions == {**r0.dimensions, key: v}
    # tables: the listed entries follow the keyword, nothing else moves
    dh, com = r0.dh.copy(), r0.com.copy()
    for table, i, j, factor in TABLE_ENTRIES[name][key]:
        (dh if table == "dh" else com)[i, j] = factor * v
    np.testing.assert_allclose(r.dh, dh, rtol=1e-14, atol=0)
    np.testing.assert_allclose(r.com, com, rtol=1e-14, atol=0)
    # boxes, masses at constant density, box inertias about the CoM
    boxes = np.array([[r.dimensions[k] for k in box] for box in BOXES[name]])
    boxes0 = np.array([[r0.dimensions[k] for k in box] for box in BOXES[name]])
    by_name = {b.name: b for b in r.boxes}
    np.testing.assert_array_equal([2 * by_name[f"link{i + 1}"].half_extents for i in range(6)], boxes)
    masses = r0.masses * boxes.prod(axis=1) / boxes0.prod(axis=1)
    np.testing.assert_allclose(r.masses, masses, rtol=1e-14, atol=0)
    for i in range(6):
        np.testing.assert_allclose(r.inertias[i], solid_box_inertia(masses[i], *boxes[i]), rtol=1e-14, atol=0)
        # links whose box does not hold the keyword keep mass and inertia exactly
        if key not in BOXES[name][i]:
            assert r.masses[i] == r0.masses[i]
            np.testing.assert_array_equal(r.inertias[i], r0.inertias[i])
        else:
            assert r.masses[i] != r0.masses[i]
    # limits, actuators and friction do not depend on the dimensions
    np.testing.assert_array_equal(r.q_limits, r0.q_limits)
    np.testing.assert_array_equal(r.tau_limits, r0.tau_limits)
    np.testing.assert_array_equal(r.friction_coefficients, r0.friction_coefficients)
    # geometry at random poses: a d of DH row i moves frames i+1.. by the change
    # along z_i, an a along x_{i+1}; a CoM row moves its CoM frame the same
    # way; the jaw length moves the TCP by half the change along the jaws
    rng = np.random.default_rng(4)
    delta = v - v0
    for _ in range(5):
        q = rng.uniform(r0.q_limits[:, 0], r0.q_limits[:, 1])
        F0, C0, T0 = r0.frames(q), r0.com_frames(q), r0.fk(q)
        shift = np.zeros((7, 3))
        com_shift = np.zeros((6, 3))
        for table, i, j, factor in TABLE_ENTRIES[name][key]:
            if table == "dh":
                axis = F0[i, :3, 2] if j == 1 else F0[i + 1, :3, 0]
                shift[i + 1:] += factor * delta * axis
            else:
                axis = F0[i, :3, 2] if j == 1 else C0[i, :3, 0]
                com_shift[i] += factor * delta * axis
        com_shift += shift[:6]
        tcp_shift = shift[6].copy()
        if key == "jaw_length":
            frame, axis = JAW_DIRECTION[name]
            tcp_shift += 0.5 * delta * F0[frame, :3, axis]
        # round-off of positions of order 1 m
        np.testing.assert_allclose(r.frames(q), translated(F0, shift), rtol=0, atol=1e-14)
        np.testing.assert_allclose(r.com_frames(q), translated(C0, com_shift), rtol=0, atol=1e-14)
        np.testing.assert_allclose(r.fk(q), translated(T0[None], tcp_shift)[0], rtol=0, atol=1e-14)
    # the dynamics see it, except a base height: a vertical shift changes neither M nor G
    q = np.array([0.3, -0.4, 0.1, 0.2, 0.5, 0.02])
    if key == "L_base":
        np.testing.assert_allclose(r.mass_matrix(q), r0.mass_matrix(q), rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(r.gravity(q), r0.gravity(q), rtol=1e-14, atol=1e-14)
    else:
        assert not np.allclose(r.mass_matrix(q), r0.mass_matrix(q), rtol=1e-9, atol=0)


def test_base_height_keyword_moves_the_arm():
    r = cs.robots.scara1(L_base=0.5, backend="numeric")
    assert r.fk(np.zeros(6))[2, 3] == pytest.approx(0.5 - 0.05)


def test_base_placement_keywords():
    r = cs.robots.scara2(base_position=(0.75, 0.0, 0.0), base_yaw=np.pi, backend="numeric")
    T = r.fk(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [0.75 - 0.53, 0.0, 0.32], atol=1e-14)


@pytest.mark.parametrize("make", [cs.robots.scara1, cs.robots.scara2])
def test_limits_and_friction_from_robots_md(make):
    r = make()
    assert np.all(r.q_limits[:, 0] < r.q_limits[:, 1])
    assert np.all(np.isfinite(r.q_limits)) and np.all(r.tau_limits > 0)
    assert np.all(r.friction_coefficients > 0)
    np.testing.assert_allclose(r.friction(np.ones(6)), r.friction_coefficients)


def test_robot_pickles_with_its_dimensions():
    r = cs.robots.scara1(L2=0.27, base_position=(0.1, 0.2, 0.0), base_yaw=0.3)
    s = pickle.loads(pickle.dumps(r))
    assert s.dimensions == r.dimensions and s.name == r.name and s.backend == r.backend
    q = np.array([0.1, 0.2, 0.1, 0.3, 0.4, 0.01])
    np.testing.assert_array_equal(s.fk(q), r.fk(q))
    np.testing.assert_array_equal(s.mass_matrix(q), r.mass_matrix(q))


def test_from_dh_accepts_six_component_inertias():
    I6 = [[0.1, 0.2, 0.25, 0.01, -0.02, 0.03]]
    r = cs.Robot.from_dh([[0, 0.1, 0.2, 0.3]], [[0, 0, 0.1, 0]], [1.0], I6, joint_types="R")
    np.testing.assert_array_equal(r.inertias[0], [[0.1, 0.01, -0.02], [0.01, 0.2, 0.03], [-0.02, 0.03, 0.25]])


@pytest.mark.parametrize("make", [cs.robots.scara1, cs.robots.scara2])
def test_poses_of_many_states_equal_each_states_own(make):
    """Robot.frames, fk and shapes on (N, n) states (one engine call, the GIL released) give each row what the
    call on that state alone gives, bit for bit; a wrong width is a one-line ValueError."""
    r = make()
    rng = np.random.default_rng(3)
    lo, hi = np.asarray(r.q_limits, float).T
    Q = lo + (hi - lo) * rng.random((7, r.dof))
    F, T, (P, H) = r.frames(Q), r.fk(Q), r.shapes(Q)
    assert F.shape == (7, r.dof + 1, 4, 4) and T.shape == (7, 4, 4) and P.shape == (7, len(r.boxes), 4, 4)
    for k, q in enumerate(Q):
        np.testing.assert_array_equal(F[k], r.frames(q))
        np.testing.assert_array_equal(T[k], r.fk(q))
        np.testing.assert_array_equal(P[k], r.shapes(q)[0])
    with pytest.raises(ValueError, match="q") as info:
        r.frames(np.zeros((3, r.dof + 1)))
    assert "\n" not in str(info.value)
