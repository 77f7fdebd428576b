"""The cooperative task's scene (the README's "The cooperative task"): the two SCARAs, the floor, the
bar and the inclined container, with the values checked against the robots' kinematics.

Values (m, kg, rad), where they differ from the paper's defaults because those do not all work with
the SCARAs' default dimensions (the checks are in tests/test_task.py):

- SCARA #1 at the origin with ``L_base = 0.52``; SCARA #2 at (0.75, 0, 0) with ``L_base = 0.38``
  (its arm 0.10 m below #1's, so the arms cannot meet in plan view).
- Floor: the plane z = 0, friction 0.6.
- Bar: 0.35 x 0.02 x 0.02 m, 0.15 kg, friction 0.5, lying on the floor at (0.95, 0.30), yaw 30 deg.
- Container: a tube of four 5 mm walls, inner section 0.06 x 0.06 m, 0.40 m long, open at both
  ends; upper mouth centre (-0.25, 0.35, 0.22), axis descending 25 deg towards +y; friction 0.2.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import robots
from .._core import World

__all__ = ["BAR_HALF_EXTENTS", "BAR_MASS", "CONTAINER", "bar_names", "bar_pose", "container_walls", "scaras", "world"]

BAR_HALF_EXTENTS = np.array([0.175, 0.01, 0.01])
BAR_MASS = 0.15
BAR_FRICTION = 0.5
FLOOR_FRICTION = 0.6

#: The container: mouth centre (m), axis (unit, downhill), inner section (m), length (m), wall (m), friction.
CONTAINER = dict(mouth=np.array([-0.25, 0.35, 0.22]), slope=math.radians(25.0), inner=0.06, length=0.40,
                 wall=0.005, friction=0.2)


@functools.lru_cache(maxsize=None)
def scaras():
    """SCARA #1 and SCARA #2 as placed in the scene. Built once and shared (a Robot is immutable: its changed
    copies are new robots), so each run of a task or a sweep does not build them again."""
    return robots.scara1(L_base=0.52), robots.scara2(L_base=0.38, base_position=(0.75, 0.0, 0.0))


def bar_pose(x=0.95, y=0.30, yaw=math.radians(30.0)):
    """The bar lying on the floor at (x, y) with a yaw (rad): (4, 4)."""
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = [x, y, BAR_HALF_EXTENTS[2]]
    return T


def container_axes(slope=None):
    """(3, 3) columns: the axis (downhill, towards +y), the horizontal across it, and the tube's 'up'."""
    a = CONTAINER["slope"] if slope is None else slope
    x = np.array([0.0, math.cos(a), -math.sin(a)])
    y = np.array([-1.0, 0.0, 0.0])
    return np.column_stack([x, y, np.cross(x, y)])


def container_walls(mouth=None, slope=None):
    """The four walls as (name, half_extents (3,), pose (4, 4)): bottom, top, left, right."""
    c = CONTAINER
    mouth = c["mouth"] if mouth is None else np.asarray(mouth, float)
    R = container_axes(slope)
    centre = mouth + R[:, 0] * c["length"] / 2
    half_in, t, L = c["inner"] / 2, c["wall"], c["length"]
    out = []
    for name, offset, he in (("container_bottom", [0, 0, -(half_in + t / 2)], [L / 2, half_in + t, t / 2]),
                             ("container_top", [0, 0, half_in + t / 2], [L / 2, half_in + t, t / 2]),
                             ("container_left", [0, half_in + t / 2, 0], [L / 2, t / 2, half_in]),
                             ("container_right", [0, -(half_in + t / 2), 0], [L / 2, t / 2, half_in])):
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = centre + R @ offset
        out.append((name, np.array(he, float), T))
    return out


def bar_names(count):
    """The world's names of `count` bars: 'bar', 'bar1', 'bar2', ..."""
    return ["bar" if i == 0 else f"bar{i}" for i in range(count)]


def world(bars=None, mouth=None, slope=None):
    """A World with the floor, the container (upper mouth centre `mouth` (3,) m, `slope` rad; default
    CONTAINER's) and the bars, named by :func:`bar_names` (default: one bar at :func:`bar_pose`)."""
    w = World(floor=True, floor_friction=FLOOR_FRICTION)
    for name, he, T in container_walls(mouth, slope):
        w.add_static_box(name, he, T, friction=CONTAINER["friction"])
    bars = [bar_pose()] if bars is None else list(bars)
    for name, T in zip(bar_names(len(bars)), bars):
        w.add_free_box(name, BAR_HALF_EXTENTS, BAR_MASS, T, friction=BAR_FRICTION)
    return w
