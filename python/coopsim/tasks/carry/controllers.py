"""The carry's controllers: factories ``(robots, plan) -> per-robot controllers`` that :func:`~.sequence.run`
takes as ``controllers=``.

A factory returns either a list of one :class:`coopsim.Controller` per robot, driving it for the whole run,
or :class:`Phased` controllers: ``free`` ones while the robots do not hold the bar together and ``held``
ones from the moment both clamps hold it (the end of the grasp) until both have let go (the end of the
release), installed with :meth:`coopsim.Simulation.set_controller`. A factory reads what it needs from the
plan (:class:`~.planning.Plan`): its references, its grips, the bar's planned path, and
``plan.model_bar_mass``, the bar's mass its model should take (the 'mass' disturbances scale it).

- :func:`computed_torque` (``ct``), the baseline: each arm on its own, :class:`coopsim.ComputedTorque` on its
  reference with the robot alone as its model. The model knows no bar: it is wrong by the bar's whole share
  throughout the hold, and a wrong bar mass ('mass' disturbances) does not reach it.
- :func:`computed_torque_payload` (``ct-payload``): the same, but while both hold the bar each arm's model
  carries its share of the bar, half of ``plan.model_bar_mass``, as a point mass at its grip on the clamp's
  link (with the bar's mass at the two grips 0.10 m either side of its centre its inertia about the vertical
  through the centre is m 0.01 m^2, within 2 % of the bar's m L^2 / 12). Here a bar mass wrong by +-50 % is a
  model wrong by +-50 % of that share.
"""
from __future__ import annotations

import dataclasses
from typing import Callable, Dict, List, Sequence

import numpy as np

from ..._core import ComputedTorque, Controller, Robot
from .constants import OMEGA

__all__ = ["CONTROLLERS", "Phased", "computed_torque", "computed_torque_payload", "with_point_mass"]


@dataclasses.dataclass
class Phased:
    """Per-robot controllers by phase: `free` (one per robot) outside the dual hold, `held` during it."""

    free: Sequence[Controller]
    held: Sequence[Controller]


def _gains(i):
    return OMEGA[i] ** 2, 2.0 * OMEGA[i]


def computed_torque(robots: Sequence[Robot], plan) -> List[Controller]:
    """The baseline: independent computed torque per arm (kp = omega^2, kd = 2 omega from
    :data:`~.constants.OMEGA`), each with the robot alone as its model."""
    return [ComputedTorque(*_gains(i)) for i in range(len(robots))]


def with_point_mass(robot: Robot, link: int, point, mass: float) -> Robot:
    """A copy of `robot` whose link `link` (1..n) also carries a point mass `mass` (kg) at `point` (3,) m in
    that link's DH frame: the link's mass, centre of mass and inertia (about the new centre, DH axes) combined
    by the parallel-axis rule. Its dynamics are the numeric ones (the generated code is the bare robot's)."""
    n = robot.dof
    if not 1 <= link <= n:
        raise ValueError(f"link must be 1 .. {n}, got {link}")
    if not (mass >= 0.0 and np.isfinite(mass)):
        raise ValueError(f"mass must be finite and >= 0 kg, got {mass!r}")
    p = np.asarray(point, float)
    masses, com, inertia = robot.masses.copy(), robot.com_positions.copy(), robot.link_inertias.copy()
    k = link - 1
    m0, c0 = masses[k], com[k]
    m = m0 + mass
    c = (m0 * c0 + mass * p) / m

    def shift(mm, d):
        return mm * (d @ d * np.eye(3) - np.outer(d, d))

    inertia[k] = inertia[k] + shift(m0, c0 - c) + shift(mass, p - c)
    masses[k], com[k] = m, c
    return Robot.from_dh(robot.dh, com, masses, inertia, robot.joint_types,
                         friction=robot.friction_coefficients, q_limits=robot.q_limits, tau_limits=robot.tau_limits,
                         gravity=robot.gravity_acceleration, base_position=robot.base_position,
                         base_yaw=robot.base_yaw, tool=robot.tool, name=robot.name,
                         end_stop_frequency=robot.end_stop_frequency,
                         end_stop_damping_ratio=robot.end_stop_damping_ratio, boxes=robot.boxes, clamp=robot.clamp,
                         dimensions=robot.dimensions, armature=robot.armature, coulomb=robot.coulomb,
                         coulomb_width=robot.coulomb_width, base_orientation=robot.base_orientation)


def grip_point(robot: Robot, q) -> np.ndarray:
    """The point midway between the clamp's pads' centres at q (where a weld holds), in the DH frame of the
    clamp's link: (3,) m."""
    faces = robot.clamp_faces(q)
    mid = (faces[0, :3, 3] + faces[1, :3, 3]) / 2.0
    F = robot.frames(q)[robot.clamp.fixed_link]
    return np.linalg.solve(F, np.append(mid, 1.0))[:3]


def computed_torque_payload(robots: Sequence[Robot], plan) -> Phased:
    """Computed torque whose models carry the bar during the dual hold: free, the baseline; held, each
    robot's model with half of ``plan.model_bar_mass`` at its grip (:func:`with_point_mass` on the clamp's
    link, at the point between the pads of ``plan.q_grasp``)."""
    held = []
    for i, r in enumerate(robots):
        model = with_point_mass(r, r.clamp.fixed_link, grip_point(r, plan.q_grasp[i]), plan.model_bar_mass / 2.0)
        held.append(ComputedTorque(*_gains(i), model=model))
    return Phased(free=computed_torque(robots, plan), held=held)


#: the controller factories by their command-line names
CONTROLLERS: Dict[str, Callable] = {"ct": computed_torque, "ct-payload": computed_torque_payload}
