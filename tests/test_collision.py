"""Bullet is really linked: a collision world detects overlapping boxes."""
from __future__ import annotations

import numpy as np
import pytest

import coopsim as cs


def at(x, y=0.0, z=0.0):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def test_two_overlapping_boxes_collide():
    w = cs.CollisionWorld()
    a = w.add_box([0.1, 0.1, 0.1], at(0.0), name="a")
    b = w.add_box([0.1, 0.1, 0.1], at(0.15), name="b")
    assert (len(w), w.name(a), w.name(b)) == (2, "a", "b")
    contacts = w.contacts()
    assert contacts, "overlapping boxes must be reported"
    for c in contacts:
        assert {c.a, c.b} == {a, b}
        # 5 cm overlap along x, normal along x
        assert c.depth == pytest.approx(-0.05, abs=1e-9)
        assert abs(abs(c.normal[0]) - 1.0) < 1e-9
    # moved apart: no contact
    w.set_pose(b, at(0.25))
    assert w.contacts() == []
    # and back into contact
    w.set_pose(b, at(0.19))
    assert all(c.depth == pytest.approx(-0.01, abs=1e-9) for c in w.contacts()) and w.contacts()


def test_sphere_resting_on_box_face():
    w = cs.CollisionWorld()
    w.add_box([1.0, 1.0, 0.1], at(0, 0, -0.1))
    s = w.add_sphere(0.05, at(0.2, 0.3, 0.04))
    (c, *_) = w.contacts()
    assert c.depth == pytest.approx(-0.01, abs=1e-9)
    p = c.point_a if c.a == s else c.point_b
    np.testing.assert_allclose(p[:2], [0.2, 0.3], atol=1e-9)


def test_collision_world_rejects_bad_input():
    w = cs.CollisionWorld()
    with pytest.raises(ValueError, match="half_extents"):
        w.add_box([0.1, -0.1, 0.1], at(0))
    with pytest.raises(ValueError, match="radius"):
        w.add_sphere(float("nan"), at(0))
    with pytest.raises(ValueError, match="pose"):
        w.add_box([0.1, 0.1, 0.1], np.ones((4, 4)))
    with pytest.raises(ValueError, match="id"):
        w.set_pose(3, at(0))
