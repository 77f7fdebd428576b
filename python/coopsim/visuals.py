"""The ``<visual>`` geometry of the robots read from URDF files, kept for the views (:mod:`coopsim.view.parts`).

A Robot (the engine's) holds what its dynamics and collisions need, not how it looks: :func:`coopsim.urdf.from_urdf`
keeps each imported robot's visuals here, under what identifies its geometry, so that its copies (``with_base``,
``Simulation.robots``) find them, and :func:`coopsim.robots.add_clamp` carries them over to the clamped copy.
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Optional

import numpy as np

__all__ = ["Visual", "visuals"]


@dataclass(frozen=True, eq=False)
class Visual:
    """A ``<visual>`` of a URDF link, kept for the views (:mod:`coopsim.view.parts`).

    link: the Robot link that carries it (0 the base .. n: the chain joint's child, with the links fixed
    to it). pose (4, 4): the visual's origin in that link's DH frame. shape: 'mesh', 'box' or 'cylinder'.
    scale (3,): a mesh's scale factors, a box's size (m), a cylinder's (2 radius, 2 radius, length) (m,
    its axis along the pose's z). path: the mesh file, resolved (shape 'mesh'). name: the URDF link's.
    """

    link: int
    pose: np.ndarray
    shape: str
    scale: np.ndarray
    path: Optional[str]
    name: str


# the visuals of the robots from_urdf read, by what identifies a robot's geometry (its copies, e.g.
# Simulation.robots, are other objects with the same data); the last 256 robots read
_VISUALS: "OrderedDict[tuple, tuple]" = OrderedDict()
_VISUALS_KEPT = 256


def _visual_key(robot) -> tuple:
    return (robot.name, robot.joint_types, tuple(robot.joint_names), tuple(robot.link_names),
            np.ascontiguousarray(robot.dh, dtype=float).tobytes())


def visuals(robot) -> list:
    """The ``<visual>`` geometry (meshes whose file was found, boxes, cylinders) of a robot that
    :func:`coopsim.urdf.from_urdf` read, as a list of :class:`Visual`; [] for any other robot (or a URDF without
    visuals). Known by the robot's name, joint types, joint and link names and DH table, so a copy
    (``Simulation.robots``, ``with_base``) has them too; kept for the last 256 robots read."""
    return list(_VISUALS.get(_visual_key(robot), ()))


def _register_visuals(robot, visual_list) -> None:
    """Keeps `visual_list` as `robot`'s visuals (none: forgets any kept under its key)."""
    key = _visual_key(robot)
    _VISUALS.pop(key, None)
    if visual_list:
        _VISUALS[key] = tuple(visual_list)
        while len(_VISUALS) > _VISUALS_KEPT:
            _VISUALS.popitem(last=False)


def _follow_visuals(old, new, X, parts) -> None:
    """add_clamp's copy `new` of an imported arm `old` keeps its look: old's visuals, those of its last link n
    moved by X (4, 4: old frame n -> new frame n, the DH row add_clamp turned), plus the clamp's parts as
    boxes (`parts`: (link, size (3,) m, pose (4, 4) in that link's frame, name) each). Nothing for a robot
    without visuals (it is drawn as its boxes, the clamp's among them)."""
    vis = visuals(old)
    if not vis:
        return
    n = old.dof
    moved = [v if v.link != n else Visual(n, X @ v.pose, v.shape, v.scale, v.path, v.name) for v in vis]
    moved += [Visual(link, np.asarray(pose, float), "box", np.asarray(size, float), None, name)
              for link, size, pose, name in parts]
    _register_visuals(new, moved)
