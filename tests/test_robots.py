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
