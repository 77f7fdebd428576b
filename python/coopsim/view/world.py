"""The Bullet world in the views: scenery and free bodies as boxes, colliding boxes and contact lines from a
simulation's contacts or from its log.

- :func:`world_bodies`: a World's static boxes (grey scenery) and free
  boxes (the bar red, others purple) as :class:`~coopsim.view.Body`, fixed
  or at their logged poses per row.
- :func:`colliding_from_log`: per robot a (rows, boxes) mask, True in the
  rows where one of the box's contact events is active.
- :func:`contacts_from_log`: per log row the contact points and directions
  from ``log.contact_points`` (``log_contacts=True``).
- :func:`holding_from_log`: per robot a (rows,) mask, True in the rows
  where the robot holds a body that another robot holds too (the paper's
  dual hold, its Fig. 18), or with ``mode='any'`` anything at all;
  :func:`holding_now` the same for a simulation's state now.
- :func:`colliding_from_contacts` and :func:`contact_lines`: the same from
  ``sim.contacts()``, for one picture of a simulation now.

Which log row a contact belongs to: the row that held at its time, the
last row at or before it (:func:`coopsim.log.rows_at`, the rule of the
animation's frames and the replay's keyframes too). Row r stands for the
interval [t[r], t[r + 1]), so a contact of any length, even one shorter than
the logging interval, shows in the row that held at its beginning and in
every row until its end. A contact event is active over [begin, end) (end
NaN: still active at the log's end); a contact point at time t (the
contacts of the state at t) belongs to the row that held at t.
"""
from __future__ import annotations

from typing import List, Optional

import numpy as np

from .._core import World
from ..log import rows_at
from .bodies import COLORS, Body, _is_simulation, _robot_list

__all__ = ["colliding_from_contacts", "colliding_from_log", "contact_lines", "contacts_from_log", "holding_from_log",
           "holding_now", "is_bar", "world_bodies"]


def is_bar(name: str) -> bool:
    """Whether a free body is drawn as the bar (the paper's red): named 'bar' or starting with 'bar'."""
    return str(name).startswith("bar")


def resolve_world(world, what: str = "world"):
    """(World or None, Simulation or None) from a World, a Simulation (its world, maybe None) or None;
    ValueError naming `what` otherwise."""
    if world is None or world is False:
        return None, None
    if isinstance(world, World):
        return world, None
    if _is_simulation(world):
        return world.world, world
    raise ValueError(f"{what} must be a coopsim.World, a coopsim.Simulation (its world) or None, "
                     f"got {type(world).__name__}")


def robot_labels(robots) -> List[str]:
    """The robots' names made unique with _<index> when repeated, as ``SimulationLog.labels`` and the
    world's link body names ('<label>/<box name>')."""
    names = [r.name for r in robots]
    return [n if names.count(n) == 1 else f"{n}_{i}" for i, n in enumerate(names)]


def _box_index(robots, labels=None) -> dict:
    """Link body name -> (robot index, box index)."""
    labels = robot_labels(robots) if labels is None else labels
    return {f"{lab}/{b.name}": (i, k) for i, (lab, r) in enumerate(zip(labels, robots))
            for k, b in enumerate(r.boxes)}


def _free_color(name: str):
    return COLORS["body"] if is_bar(name) else COLORS["free_body"]


def world_bodies(world, log=None, *, rows: Optional[int] = None, scenery: bool = True,
                 free: bool = True) -> List[Body]:
    """The world's bodies as :class:`~coopsim.view.Body` boxes to draw.

    world: a coopsim.World, or a Simulation (its world, and its free bodies
    at their current state, ``sim.body_state(name)``). Static boxes are
    scenery (``COLORS['scenery']``, fixed); free boxes are the bar (a body
    named 'bar' or starting with 'bar', ``COLORS['body']``, the paper's red)
    or other bodies (``COLORS['free_body']``). log: a SimulationLog whose
    ``log.bodies`` gives each free body one pose per row (for
    :func:`~coopsim.view.animate`); a free body the log lacks stays at its
    pose now. rows: the expected row count (default len(log.t)). The floor
    is not a box: the scene draws its own tiles. Every body is ``tiled``
    (its big faces drawn in pieces, for depth sorting). Link bodies (the robots')
    are drawn by the robots themselves. scenery / free: include those.
    """
    w, sim = resolve_world(world)
    if w is None:
        return []
    if hasattr(log, "check"):
        log.check(poses=True)
    out = []
    for name in w.body_names:
        d = w.body(name)
        kind = d["kind"]
        if kind == "static" and scenery:
            out.append(Body(name, np.array(d["half_extents"]), np.array(d["pose"]), COLORS["scenery"], scenery=True,
                            tiled=True))
        elif kind == "free" and free:
            if log is not None and name in getattr(log, "bodies", {}):
                pose = log.bodies[name].poses()
                if rows is not None and len(pose) != rows:
                    raise ValueError(f"log.bodies[{name!r}] has {len(pose)} rows, the log {rows}")
            elif sim is not None:
                pose = np.array(sim.body_state(name).pose)
            else:
                pose = np.array(d["pose"])
            out.append(Body(name, np.array(d["half_extents"]), pose, _free_color(name), tiled=True))
    return out


# ---- colliding boxes ----

def _log_and_robots(log, robots):
    if _is_simulation(log):
        sim = log
        log = sim.log
        if robots is None:
            robots = sim.robots
    if not hasattr(log, "t") or not hasattr(log, "robots") or not hasattr(log, "contacts"):
        raise ValueError(f"log must be a coopsim.SimulationLog or a Simulation, got {type(log).__name__}")
    if hasattr(log, "check"):
        log.check()
    if robots is None:
        raise ValueError("robots must be given with a log (the robots in log order, for their boxes)")
    robots = _robot_list(robots, allow_empty=True)
    if len(robots) != len(log.robots):
        raise ValueError(f"robots must match the log's robots: the log has {len(log.robots)}, got {len(robots)}")
    return log, robots


def colliding_from_log(log, robots=None) -> List[np.ndarray]:
    """Per robot a (rows, boxes) bool array: True in the log rows where the box (robot.boxes order) is in
    contact with anything (another link, another robot, scenery, the floor, a free body).

    log: a SimulationLog with contact events (``log.contacts``), or a
    Simulation (its log and robots). robots: the simulated robots in log
    order (default the Simulation's). Row r is True when one of the box's
    contact events, active over [begin, end) (end NaN: until the end), meets
    [t[r], t[r + 1]): a contact shorter than the logging interval still shows
    in one row. Link bodies are matched by name, '<log label>/<box name>'.
    Give the result to ``animate(..., collision_boxes=True, colliding=...)``;
    with collision_boxes=True and no colliding, animate derives it itself.
    """
    log, robots = _log_and_robots(log, robots)
    t = np.asarray(log.t, dtype=float)
    rows = len(t)
    masks = [np.zeros((rows, len(r.boxes)), dtype=bool) for r in robots]
    if rows == 0:
        return masks
    ev = log.contacts
    if ev is None or len(ev) == 0:
        return masks
    index = _box_index(robots, log.labels)
    begin = ev["begin"].to_numpy(dtype=float)
    end = ev["end"].to_numpy(dtype=float)
    first = rows_at(t, begin)                                   # the row that held at the beginning
    # the last row: the last one whose interval [t[r], t[r + 1]) starts before the end (t[r] < end): the
    # row that held just before it, unless it began in that row
    eps = 1e-9 * max(1.0, abs(float(t[0])), abs(float(t[-1])))
    last = np.where(np.isnan(end), rows - 1, np.maximum(rows_at(t, np.nan_to_num(end) - 2 * eps), first))
    for side in ("a", "b"):
        for name, r0, r1 in zip(ev[side].to_numpy(), first, last):
            ik = index.get(name)
            if ik is not None and r0 <= r1:
                masks[ik[0]][r0:r1 + 1, ik[1]] = True
    return masks


def colliding_from_contacts(contacts, robots, labels=None) -> List[np.ndarray]:
    """Per robot a (boxes,) bool mask: True for boxes in one of `contacts` (``sim.contacts()``: dicts with
    a and b; every point the world reports, touching or pushing)."""
    index = _box_index(robots, labels)
    masks = [np.zeros(len(r.boxes), dtype=bool) for r in robots]
    for c in contacts:
        for side in ("a", "b"):
            ik = index.get(getattr(c, side))
            if ik is not None:
                masks[ik[0]][ik[1]] = True
    return masks


# ---- contact lines ----

def contact_lines(contacts) -> np.ndarray:
    """(m, 2, 3) (point, direction) pairs from ``sim.contacts()``: each point on a (the body added first:
    the floor, scenery, a free body before a link) with the direction a pushes b (-normal), so that
    lines stand out of the floor and the walls towards what touches them."""
    pts = [(c.point_a, -np.asarray(c.normal, dtype=float)) for c in contacts]
    return np.array(pts, dtype=float).reshape(-1, 2, 3)


def contacts_from_log(log) -> Optional[list]:
    """Per log row the contact points as an (m, 2, 3) array of (point, direction) pairs (see
    :func:`contact_lines`), or None where there are none; None altogether when the log has no contact
    points (run the simulation with ``log_contacts=True``).

    Row r shows, for each touching pair, its points at the first world step in [t[r], t[r + 1]) (the row's
    interval, as :func:`colliding_from_log`): the contacts of the row's own state where the pair touched
    then.
    """
    if _is_simulation(log):
        log = log.log
    if hasattr(log, "check"):
        log.check()
    cp = getattr(log, "contact_points", None)
    if cp is None:
        return None
    t = np.asarray(log.t, dtype=float)
    out: list = [None] * len(t)
    if len(cp) == 0 or len(t) == 0:
        return out
    tt = cp["t"].to_numpy(dtype=float)
    row = rows_at(t, tt)
    # per (row, pair): the first world step's points
    key = cp["a"].astype(str).to_numpy() + "\x00" + cp["b"].astype(str).to_numpy()
    import pandas as pd  # pandas' import is heavy: only when the log has contact points

    df = pd.DataFrame({"row": row, "key": key, "t": tt})
    first = df.groupby(["row", "key"])["t"].transform("min").to_numpy()
    sel = tt == first
    P = cp[["point_x", "point_y", "point_z"]].to_numpy(dtype=float)[sel]
    N = -cp[["normal_x", "normal_y", "normal_z"]].to_numpy(dtype=float)[sel]
    r = row[sel]
    order = np.argsort(r, kind="stable")
    r, P, N = r[order], P[order], N[order]
    bounds = np.searchsorted(r, np.arange(len(t) + 1), side="left")
    for k in np.flatnonzero(np.diff(bounds)):
        a, b = bounds[k], bounds[k + 1]
        out[k] = np.stack([P[a:b], N[a:b]], axis=1)
    return out




# ---- holding ----

#: The ways a robot counts as holding (``holding=`` of draw and animate, ``mode`` of holding_from_log):
#: 'shared', a body that another robot holds too (the paper's green robots while both hold the bar), or
#: 'any', any body at all (one robot carrying something).
HOLDING_MODES = ("shared", "any")


def _holding_mode(mode, what: str = "mode") -> str:
    if not isinstance(mode, str) or mode not in HOLDING_MODES:
        raise ValueError(f"{what} must be one of {', '.join(map(repr, HOLDING_MODES))}, got {mode!r}")
    return mode


def _held_masks(held: np.ndarray, mode: str) -> np.ndarray:
    """(rows, robots) bool from (rows, robots) body names ('' for none)."""
    held = np.asarray(held, dtype=object).astype(str)
    some = held != ""
    if mode == "any" or held.shape[1] == 0:
        return some
    out = np.zeros_like(some)
    for i in range(held.shape[1]):
        others = np.delete(held, i, axis=1)
        out[:, i] = some[:, i] & (others == held[:, i:i + 1]).any(axis=1)
    return out


def holding_from_log(log, robots=None, *, mode: str = "shared") -> List[np.ndarray]:
    """Per robot a (rows,) bool array: True in the log rows where the robot counts as holding, for
    ``animate(..., holding=...)`` (which derives it itself when holding is not given).

    log: a SimulationLog (its ``log[i].holding``: per row the name of the
    body robot i holds, '' when none) or a Simulation (its log). robots:
    not needed; if given (the Simulation's or a list), it must match the
    log's robot count, as for :func:`colliding_from_log`. mode: 'shared'
    (default, the paper's convention in its Fig. 18: robots green while both
    hold the bar): a robot holds in a row when the body it holds is held by
    another robot in that row too; 'any': whenever it holds anything (one
    robot carrying a body). A row shows the grasp state at its time t[r].
    """
    mode = _holding_mode(mode)
    if _is_simulation(log):
        sim = log
        log = sim.log
        if robots is None:
            robots = sim.robots
    if not hasattr(log, "t") or not hasattr(log, "robots"):
        raise ValueError(f"log must be a coopsim.SimulationLog or a Simulation, got {type(log).__name__}")
    if hasattr(log, "check"):
        log.check()
    if robots is not None:
        robots = _robot_list(robots, allow_empty=True)
        if len(robots) != len(log.robots):
            raise ValueError(f"robots must match the log's robots: the log has {len(log.robots)}, got {len(robots)}")
    rows = len(log.t)
    held = np.full((rows, len(log.robots)), "", dtype=object)
    for i, rl in enumerate(log.robots):
        h = getattr(rl, "holding", None)
        if h is not None and len(h):
            if len(h) != rows:
                raise ValueError(f"log robot {i} ({rl.name}) has {len(h)} holding rows, the log {rows}")
            held[:, i] = h
    masks = _held_masks(held, mode)
    return [masks[:, i].copy() for i in range(len(log.robots))]


def holding_now(sim, *, mode: str = "shared") -> List[bool]:
    """Per robot whether it counts as holding now (``sim.holding(i)``), as :func:`holding_from_log`."""
    mode = _holding_mode(mode)
    if not _is_simulation(sim):
        raise ValueError(f"sim must be a coopsim.Simulation, got {type(sim).__name__}")
    n = sim.robot_count
    held = np.array([[(sim.holding(i) or "") if sim.world is not None else "" for i in range(n)]], dtype=object)
    return [bool(v) for v in _held_masks(held.reshape(1, n), mode)[0]]
