"""The dual carry's scene: the handover's two SCARAs, the floor, the bar and four stands (two under the
bar's start, two under its end), as a :class:`coopsim.World`."""
from __future__ import annotations

import math
from typing import List, Tuple

import numpy as np

from ..._core import World
from ...planning import rotz
from .. import scene as handover_scene
from .constants import END, STAND_AT, STAND_FRICTION, STAND_HALF, START

__all__ = ["BAR", "bar_pose", "scaras", "stands", "world"]

#: the bar's world name
BAR = "bar"
BAR_HALF_EXTENTS = handover_scene.BAR_HALF_EXTENTS
BAR_MASS = handover_scene.BAR_MASS

#: SCARA #1 and #2 as placed in the scene (the handover's)
scaras = handover_scene.scaras


def bar_pose(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    """The horizontal bar with its centre at (x, y, z) m and its axis at `yaw` rad: pose (4, 4)."""
    T = np.eye(4)
    T[:3, :3] = rotz(yaw)
    T[:3, 3] = [x, y, z]
    return T


def stands(start=START, end=END) -> List[Tuple[str, np.ndarray, np.ndarray]]:
    """The four stands as (name, half extents (3,), pose (4, 4)): 'start_stand_a', 'start_stand_b' under the
    bar's pose `start` (x, y, z, yaw), 'end_stand_a', 'end_stand_b' under `end`; each STAND_AT m from the bar's
    centre along it (a on its +x side), from the floor up to the bar's underside."""
    out = []
    for which, (x, y, z, yaw) in (("start", start), ("end", end)):
        top = z - BAR_HALF_EXTENTS[2]
        d = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        for tag, sign in (("a", 1.0), ("b", -1.0)):
            T = np.eye(4)
            T[:3, :3] = rotz(yaw)
            T[:3, 3] = np.array([x, y, top / 2]) + sign * STAND_AT * d
            out.append((f"{which}_stand_{tag}", np.array([STAND_HALF[0], STAND_HALF[1], top / 2]), T))
    return out


def world(start=START, end=END) -> World:
    """A World with the floor, the four stands (:func:`stands`) and the bar lying on the start stands."""
    w = World(floor=True, floor_friction=handover_scene.FLOOR_FRICTION)
    for name, he, T in stands(start, end):
        w.add_static_box(name, he, T, friction=STAND_FRICTION)
    w.add_free_box(BAR, BAR_HALF_EXTENTS, BAR_MASS, bar_pose(*start), friction=handover_scene.BAR_FRICTION)
    return w
