"""The carry's disturbances: what changes in a run, by name (the command line's ``--disturbance``) or as a
:class:`Disturbances` (the API's).

- ``mass+50``, ``mass-50``: the bar's mass in the controllers' models wrong by +50 % / -50 %
  (``plan.model_bar_mass`` = 1.5 or 0.5 times the world's 0.15 kg). What it changes depends on the controller:
  the baseline (``ct``) models no bar at all, so it does not change it (its model is wrong by the bar's whole
  share throughout the hold, by design); ``ct-payload`` models each arm's share of the bar during the hold and
  takes the wrong mass there.
- ``push``: a horizontal push of PUSH_FORCE N on the bar's centre, across its start axis, for PUSH_TIME s in the
  middle of the carry (:meth:`coopsim.Simulation.set_body_wrench`).
- ``grip-offset``: SCARA #2's clamp comes down and grips GRIP_OFFSET m along the bar from its planned point;
  from the lift on its reference is the plan's, made for the planned point, so the two clamps' references
  disagree by that much along the bar and the welds take it up.
- ``noise``: both force/torque sensors noisy (NOISE_FORCE N, NOISE_MOMENT N m per component, seeded). The
  baseline controllers read no sensor: it changes the sensed wrenches the report scores, not the motion.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Iterable, Optional, Sequence, Tuple, Union

import numpy as np

__all__ = ["DISTURBANCES", "Disturbances", "disturbances"]

PUSH_FORCE = 2.0      # N: more than the bar's weight (1.47 N), horizontal
PUSH_TIME = 0.2       # s
GRIP_OFFSET = 0.005   # m
NOISE_FORCE = 0.5     # N
NOISE_MOMENT = 0.02   # N m


@dataclasses.dataclass(frozen=True)
class Disturbances:
    """What a run changes from the plan.

    mass_factor: the bar's mass in the controllers' models over the world's (> 0). push: (force (3,) N in world
    axes, the time of its middle as a fraction of the carry (0 .. 1), its duration s) or None.
    grip_offset: (2,) m, each clamp's grip along the bar off its planned point. sensor_noise: (force N,
    moment N m) standard deviations of both force/torque sensors' noise, or None. names: the named
    disturbances it was made of."""

    mass_factor: float = 1.0
    push: Optional[Tuple[Tuple[float, float, float], float, float]] = None
    grip_offset: Tuple[float, float] = (0.0, 0.0)
    sensor_noise: Optional[Tuple[float, float]] = None
    names: Tuple[str, ...] = ()

    def __post_init__(self):
        m = self.mass_factor
        if isinstance(m, bool) or not isinstance(m, (int, float, np.floating, np.integer)) or not (m > 0 and math.isfinite(m)):
            raise ValueError(f"mass_factor must be a finite number > 0, got {m!r}")
        g = np.asarray(self.grip_offset, float)
        if g.shape != (2,) or not np.all(np.isfinite(g)) or np.any(np.abs(g) > 0.02):
            raise ValueError(f"grip_offset must be two finite offsets of at most 0.02 m, got {self.grip_offset!r}")
        if self.push is not None:
            bad = ValueError(f"push must be (force (3,) N finite, the middle as a fraction 0 .. 1 of the carry, "
                             f"a duration > 0 s), got {self.push!r}")
            try:
                f, at, T = self.push
                f, at, T = np.asarray(f, float), float(at), float(T)
            except (TypeError, ValueError):
                raise bad from None
            if f.shape != (3,) or not np.all(np.isfinite(f)) or not (0.0 <= at <= 1.0) or not (T > 0 and math.isfinite(T)):
                raise bad
        names = self.names
        if isinstance(names, str) or not isinstance(names, (tuple, list)) or \
                not all(isinstance(n, str) and n for n in names):
            raise ValueError(f"names must be a tuple of the disturbances' names (non-empty strings), got {names!r}")
        if self.sensor_noise is not None:
            s = np.asarray(self.sensor_noise, float)
            if s.shape != (2,) or not np.all(np.isfinite(s)) or np.any(s < 0):
                raise ValueError(f"sensor_noise must be (force N, moment N m), finite and >= 0, got "
                                 f"{self.sensor_noise!r}")


def _push_force(start_yaw: float) -> Tuple[float, float, float]:
    # across the bar's axis at the start, horizontal
    return (-PUSH_FORCE * math.sin(start_yaw), PUSH_FORCE * math.cos(start_yaw), 0.0)


#: the named disturbances: each a function of the start's yaw (the push goes across the bar) to the fields of
#: :class:`Disturbances` it sets
DISTURBANCES = {
    "none": lambda yaw: {},
    "mass+50": lambda yaw: dict(mass_factor=1.5),
    "mass-50": lambda yaw: dict(mass_factor=0.5),
    "push": lambda yaw: dict(push=(_push_force(yaw), 0.5, PUSH_TIME)),
    "grip-offset": lambda yaw: dict(grip_offset=(0.0, GRIP_OFFSET)),
    "noise": lambda yaw: dict(sensor_noise=(NOISE_FORCE, NOISE_MOMENT)),
}


def disturbances(spec: Union[None, str, Iterable[str], Disturbances], start_yaw: float) -> Disturbances:
    """The Disturbances of `spec`: None or 'none' (nothing), a name of :data:`DISTURBANCES`, several names
    (a list, or one string with commas) combined, or a Disturbances as it is. `start_yaw` (rad) orients the
    push. ValueError naming an unknown disturbance or two that set the same thing."""
    if isinstance(spec, Disturbances):
        return spec
    if spec is None:
        names: Sequence[str] = ()
    elif isinstance(spec, str):
        names = [s.strip() for s in spec.split(",") if s.strip()]
    else:
        names = list(spec)
    fields, seen = {}, {}
    for name in names:
        if not isinstance(name, str) or name not in DISTURBANCES:
            raise ValueError(f"unknown disturbance {name!r}: choose from {', '.join(DISTURBANCES)}")
        for k, v in DISTURBANCES[name](start_yaw).items():
            if k in fields:
                raise ValueError(f"disturbances {seen[k]!r} and {name!r} both set {k}: give one of them")
            fields[k], seen[k] = v, name
    return Disturbances(**fields, names=tuple(n for n in names if n != "none"))
