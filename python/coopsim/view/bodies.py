"""What the views draw, below the scene and the world: the colour conventions (:data:`COLORS`), extra boxes
(:class:`Body`) and the robots given as a Robot, a list of them or a Simulation."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from .._core import Robot
from ..simulation import Simulation

__all__ = ["Body", "COLORS"]

#: The colour conventions (any matplotlib colour). robots: the normal colour of robot i's links, cycling;
#: base: base columns; jaw: the clamp's jaws; holding: a robot that holds something; free / colliding:
#: collision boxes without / with contact; ghost: the desired pose (drawn with ghost_alpha);
#: contact: contact lines; body: extra boxes without their own colour (the bar); floor: two tile colours;
#: scenery: a world's static boxes; free_body: a world's free bodies other than the bar; holding_shades: robot
#: i's green while it holds (cycling; the first is holding), so that two holding robots tell apart in the
#: matplotlib views.
COLORS = {
    "robots": ("#f0a23c", "#e4e4e8", "#c07a4a", "#a5a5a5"),
    "base": "#757575",
    "jaw": "#2f3237",
    "holding": "#2ca02c",
    "holding_shades": ("#2ca02c", "#00e000", "#176b17", "#5fd35f"),
    "free": "#3cc43c",
    "colliding": "#e8231e",
    "ghost": "#1f5bff",
    "ghost_alpha": 0.3,
    "contact": "#e8231e",
    "body": "#d62728",
    "floor": ("#b9bec6", "#a9aeb7"),
    "scenery": "#8d9099",
    "free_body": "#8a5fb8",
}


@dataclass
class Body:
    """Extra boxes drawn with the robots: world bodies such as the bar, or scenery.

    name: a label. half_extents: (3,) m for one box, or (m, 3) for m boxes.
    poses: the boxes' centres and axes in the world, (4, 4) (one box, fixed),
    (m, 4, 4) (m boxes, fixed), or one pose per log row for
    :func:`~coopsim.view.animate`: (rows, 4, 4) for one box, (rows, m, 4, 4)
    for m boxes. color: any matplotlib colour (default the bar's red);
    alpha: 0..1. scenery: fixed surroundings (a world's static boxes; see
    :meth:`Scene.choose_azimuth` for how they turn the default camera).
    tiled: faces longer than the scene's tile drawn as tiles without
    edges between them, so that they sort by depth piece by piece against
    what lies on them or beside them (matplotlib sorts whole polygons);
    the world's bodies are tiled.
    """

    name: str
    half_extents: object
    poses: object
    color: object = COLORS["body"]
    alpha: float = 1.0
    scenery: bool = False
    tiled: bool = False

    def _checked(self, what: str, rows: Optional[int] = None):
        """(half (m, 3), poses, rgba (4,)), checked; poses (m, 4, 4), or with `rows` given either that
        (fixed boxes) or (rows, m, 4, 4) (one pose per log row)."""
        from matplotlib.colors import to_rgba  # matplotlib's import is heavy: only when drawing

        h = _array(self.half_extents, f"{what}.half_extents")
        if h.ndim == 1:
            h = h[None, :]
        if h.ndim != 2 or h.shape[1] != 3 or not np.all((h >= 1e-4) & (h <= 1e4)):
            # a world body's rule (World.add_box): the view draws what a world may hold
            got = f"shape {np.shape(self.half_extents)}" if h.ndim != 2 or h.shape[1] != 3 or not h.size \
                else f"{h.min():g} .. {h.max():g} m"
            raise ValueError(f"{what}.half_extents must be (3,) or (m, 3) lengths in 1e-4 .. 1e4 m, got {got}")
        m = h.shape[0]
        p = _array(self.poses, f"{what}.poses")
        fixed = [(m, 4, 4)] + ([(4, 4)] if m == 1 else [])
        moving = [] if rows is None else [(rows, m, 4, 4)] + ([(rows, 4, 4)] if m == 1 else [])
        if p.shape in fixed:
            p = p.reshape(m, 4, 4)
        elif p.shape in moving:
            p = p.reshape(rows, m, 4, 4)
        else:
            raise ValueError(f"wrong shape for {what}.poses: expected {' or '.join(map(str, fixed + moving))} "
                             f"for {m} box(es), got {p.shape}")
        try:
            rgba = np.array(to_rgba(self.color, float(self.alpha)))
        except (ValueError, TypeError) as e:
            raise ValueError(f"{what}.color / alpha: {e}") from None
        return h, p, rgba


def _array(x, what: str) -> np.ndarray:
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be an array of numbers, got {type(x).__name__}") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite (no NaN or inf)")
    return a


def _is_simulation(x) -> bool:
    return isinstance(x, Simulation)


def _robot_list(robots, allow_empty: bool = False) -> list:
    """A list of Robot from one Robot, a sequence of them or a Simulation (its robots); empty only when
    allowed (a scene of a world's bodies alone)."""
    if isinstance(robots, Robot):
        return [robots]
    if _is_simulation(robots):
        robots = robots.robots
    elif robots is None and allow_empty:
        robots = []
    try:
        robots = list(robots)
    except TypeError:
        raise ValueError(f"robots must be a coopsim.Robot, a sequence of them or a Simulation, got "
                         f"{type(robots).__name__}") from None
    if (not robots and not allow_empty) or not all(isinstance(r, Robot) for r in robots):
        raise ValueError("robots must be a coopsim.Robot or a non-empty sequence of them")
    return robots
