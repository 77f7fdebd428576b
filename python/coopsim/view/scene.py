"""A 3D matplotlib scene of robots drawn as shaded boxes, updated cheaply from new joint positions.

Every box (robot links, the desired-pose ghost, extra bodies) is in one
``Poly3DCollection`` whose vertices and colours are replaced on each update
(``set_verts``): matplotlib sorts its polygons by depth as a whole
(painter's algorithm), and a redraw costs one collection, not a new axes.
The floor, at z = 0 below everything and seen from above, is a second,
fixed collection drawn first; contact points are a ``Line3DCollection``
drawn over the boxes.

Colours follow the paper: the desired pose as a transparent blue ghost,
robots green while they hold something, collision boxes green (free) or red
(in contact), contact points as red lines along the normal, the bar red.
"""
from __future__ import annotations

from typing import List, Optional

import numpy as np

from .bodies import COLORS, Body, _array, _is_simulation, _robot_list
from .geometry import (box_corners, box_faces, box_normals, box_samples, floor_tiles, hidden, light_direction, shade,
                       split_quads, view_direction)
from .world import _holding_mode, colliding_from_contacts, contact_lines, holding_now, resolve_world, world_bodies

__all__ = ["Body", "COLORS", "Scene", "draw", "inclines"]

_KEEP = object()   # update(): leave as it is

#: The default camera (degrees, matplotlib's convention): from the front right, above the floor.
DEFAULT_ELEV = 22.0
DEFAULT_AZIM = -62.0
#: A scenery box whose longest axis rises more than this (degrees) from level, and less than 90 minus this, is
#: an incline: the default camera looks at its side, and a label gives its slope.
INCLINE_MIN = 2.0
#: The inset's places in the figure (x0, y0, width, height, figure fractions): the upper right or the upper left,
#: whichever covers fewer of the scene's boxes when it first shows.
INSET_PLACES = ((0.60, 0.47, 0.38, 0.43), (0.02, 0.47, 0.38, 0.43))


def inclines(items) -> List[dict]:
    """The inclines among scenery boxes: items are (name, poses (k, 4, 4), half extents (k, 3)); boxes with the
    same orientation (a tube's walls) are one incline. Per incline a dict: names, slope (degrees, of the
    longest axis from level), axis (3,) the unit longest axis pointing downhill, top (3,) m the highest corner."""
    out = []
    for name, poses, half in items:
        for T, h in zip(np.asarray(poses, float).reshape(-1, 4, 4), np.asarray(half, float).reshape(-1, 3)):
            a = T[:3, int(np.argmax(h))]
            a = -a if a[2] > 0 else a
            slope = float(np.degrees(np.arcsin(min(1.0, abs(a[2])))))
            if not INCLINE_MIN < slope < 90.0 - INCLINE_MIN:
                continue
            top = box_corners(T[None], h[None])[0]
            top = top[np.argmax(top[:, 2])]
            for inc in out:
                if np.allclose(inc["rotation"], T[:3, :3], atol=1e-9):
                    inc["names"].append(name) if name not in inc["names"] else None
                    inc["top"] = top if top[2] > inc["top"][2] else inc["top"]
                    inc["size"] += float(np.prod(h))
                    break
            else:
                out.append(dict(names=[name], slope=slope, axis=a, top=top, rotation=T[:3, :3].copy(),
                                size=float(np.prod(h))))
    return out


def _per_robot_q(q, robots, what: str, allow_none: bool = False) -> list:
    """One (n_i,) float array per robot (or None where allowed) from q for one robot or a sequence."""
    n = len(robots)
    if q is None:
        if allow_none:
            return [None] * n
        raise ValueError(f"{what} must be given")
    if n == 1 and not (isinstance(q, (list, tuple)) and len(q) == 1 and (q[0] is None or np.ndim(q[0]) == 1)):
        items = [q]
    else:
        if isinstance(q, np.ndarray) and q.ndim != 2:
            raise ValueError(f"wrong shape for {what}: expected one (n,) array per robot for {n} robots, "
                             f"got {q.shape}")
        items = list(q)
        if len(items) != n:
            raise ValueError(f"{what} must hold one joint vector per robot ({n}), got {len(items)}")
    out = []
    for i, (x, r) in enumerate(zip(items, robots)):
        name = what if n == 1 else f"{what}[{i}]"
        if x is None and allow_none:
            out.append(None)
            continue
        a = _array(x, name)
        if a.shape != (r.dof,):
            raise ValueError(f"wrong shape for {name}: expected ({r.dof},), got {a.shape}")
        out.append(a)
    return out


def _per_robot_bool(x, robots, what: str) -> list:
    n = len(robots)
    if x is None or isinstance(x, (bool, np.bool_)):
        return [bool(x)] * n
    items = list(x) if isinstance(x, (list, tuple, np.ndarray)) else None
    if items is None or len(items) != n:
        raise ValueError(f"{what} must be a bool or one bool per robot ({n}), got {x!r}")
    out = []
    for i, v in enumerate(items):
        if not isinstance(v, (bool, np.bool_, int, np.integer)) or v not in (0, 1):
            raise ValueError(f"{what}[{i}] must be a bool, got {v!r}")
        out.append(bool(v))
    return out


def _per_robot_mask(x, robots, what: str) -> list:
    """One (k_i,) bool array per robot (k_i = its box count); None (for all or one robot) -> all False."""
    n = len(robots)
    ks = [len(r.boxes) for r in robots]
    if x is None:
        return [np.zeros(k, dtype=bool) for k in ks]
    if n == 1 and np.ndim(x) == 1 and not (isinstance(x, (list, tuple)) and len(x) == 1 and np.ndim(x[0]) == 1):
        items = [x]
    else:
        items = list(x)
        if len(items) != n:
            raise ValueError(f"{what} must hold one (boxes,) mask per robot ({n}), got {len(items)}")
    out = []
    for i, (m, k) in enumerate(zip(items, ks)):
        name = what if n == 1 else f"{what}[{i}]"
        if m is None:
            out.append(np.zeros(k, dtype=bool))
            continue
        a = np.asarray(m)
        if a.shape != (k,):
            raise ValueError(f"wrong shape for {name}: expected ({k},), one flag per box of robot {i}, got {a.shape}")
        if a.dtype != bool and not (np.issubdtype(a.dtype, np.integer) and np.isin(a, (0, 1)).all()):
            raise ValueError(f"{name} must be booleans, got dtype {a.dtype}")
        out.append(a.astype(bool))
    return out


def _contacts(x, what: str = "contacts") -> np.ndarray:
    """(m, 2, 3): contact points and unit normals."""
    if x is None:
        return np.zeros((0, 2, 3))
    if isinstance(x, (list, tuple)) and len(x) == 0:
        return np.zeros((0, 2, 3))
    a = _array(x, what)
    if a.ndim != 3 or a.shape[1:] != (2, 3):
        raise ValueError(f"wrong shape for {what}: expected (m, 2, 3), m pairs of (point, normal), got {a.shape}")
    norm = np.linalg.norm(a[:, 1], axis=1)
    if np.any(norm <= 0):
        raise ValueError(f"{what}: every normal must be non-zero")
    a = a.copy()
    a[:, 1] /= norm[:, None]
    return a


def _bodies(bodies, what: str = "bodies") -> list:
    if bodies is None:
        return []
    if isinstance(bodies, Body):
        bodies = [bodies]
    out = []
    for i, b in enumerate(bodies):
        if not isinstance(b, Body):
            raise ValueError(f"{what}[{i}] must be a coopsim.view.Body, got {type(b).__name__}")
        out.append(b._checked(f"{what}[{i}]"))
    return out


def _rgba(c, what: str) -> np.ndarray:
    from matplotlib.colors import to_rgba  # matplotlib loads only to draw

    try:
        return np.array(to_rgba(c))
    except (ValueError, TypeError):
        raise ValueError(f"{what}: not a matplotlib colour: {c!r}") from None


_KINDS = ("robot", "body", "ghost")


class Scene:
    """Robots as shaded boxes on a tiled floor in a 3D matplotlib Axes; :meth:`update` moves them.

    Made by :func:`draw` (see there for the options). Artists: ``polys``,
    the one Poly3DCollection of every box (robots, bodies, ghosts), sorted
    by depth as a whole; ``floor``, the floor tiles, drawn before it (the
    floor lies at z = 0 under everything and the camera looks from above,
    so it never hides a box; it does not change with the frames);
    ``lines``, the contact lines, drawn over the boxes; ``label``, a figure
    text at the top left. :meth:`faces` and :meth:`colors` give what is
    drawn, :meth:`project` where a world point lands in the image.
    """

    def __init__(self, ax, robots, *, colors=None, collision_boxes: bool = False, floor=True, tile: float = 0.1,
                 limits=None, elev: Optional[float] = 22.0, azim: Optional[float] = None, axis: bool = False,
                 zoom: Optional[float] = None, contact_length: float = 0.04, edges: bool = True, linewidth: float = 0.4,
                 cull: bool = False, ghost_margin: float = 0.002, triad: bool = True, names: bool = True,
                 inset: bool = False, _inset_of: Optional["Scene"] = None):
        from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # matplotlib loads only to draw

        self.robots = _robot_list(robots, allow_empty=True)
        self.ax = ax
        self.fig = ax.figure
        self.collision_boxes = bool(collision_boxes)
        self.contact_length = _positive(contact_length, "contact_length")
        self.tile = _positive(tile, "tile")
        self.ghost_margin = _positive(ghost_margin, "ghost_margin", zero=True)
        # by default as large as the boxes allow: the floor's edges may leave the picture, the boxes may not
        self._zoom_auto = zoom is None and not axis and limits is None
        self._zoom = (0.9 if axis else 1.6) if zoom is None else _positive(zoom, "zoom")
        # azim None: DEFAULT_AZIM, turned at the first fit when that hides bodies behind the robots
        self._auto_azim = azim is None
        elev = DEFAULT_ELEV if elev is None else _finite(elev, "elev")
        azim = DEFAULT_AZIM if azim is None else _finite(azim, "azim")
        self._edges = bool(edges)
        self.cull = bool(cull)
        self._colors = self._robot_colors(colors)
        c = COLORS
        self._ghost_face = _rgba(c["ghost"], "COLORS['ghost']")
        self._ghost_face[3] = c["ghost_alpha"]
        self._holding = _rgba(c["holding"], "COLORS['holding']")
        shades = c.get("holding_shades") or (c["holding"],)
        self._holding_shades = [_rgba(x, "COLORS['holding_shades']") for x in shades]
        self._show_triad, self._show_names = bool(triad) and not axis, bool(names)
        self.triad_labels: list = []     # x, y, z and the scale, figure texts placed in 3D (fit)
        self.triad_segments = np.zeros((0, 2, 3))
        self.scale = None                # m, the axes' length
        self.names: list = []            # the robots' names over their bases
        self.inclines: List[dict] = []   # the inclined scenery (:func:`inclines`), found at the first update
        self._inclines_found = False
        self.level_segments = np.zeros((0, 2, 3))     # the inclines' level lines, m
        self.incline_labels: list = []   # per incline its slope, written over its top
        self._held: list = [None] * len(self.robots)   # per robot the name of the body it holds, or None
        self.inset: Optional[Scene] = None             # the zoom on the held body (inset=True)
        self.inset_label = None
        self.inset_frame = None
        self._free = _rgba(c["free"], "COLORS['free']")
        self._colliding = _rgba(c["colliding"], "COLORS['colliding']")

        # what is shown (update changes it)
        n = len(self.robots)
        self._q = [np.zeros(r.dof) for r in self.robots]
        self._ref: List[Optional[np.ndarray]] = [None] * n
        self._hold = [False] * n
        self._mask = [np.zeros(len(r.boxes), dtype=bool) for r in self.robots]
        self._moving = [np.array([b.link != 0 for b in r.boxes], dtype=bool) for r in self.robots]
        self._contacts = np.zeros((0, 2, 3))
        self._bodies: list = []
        self._body_names: List[str] = []
        self._body_scenery: List[bool] = []
        self._body_tiled: List[bool] = []

        self._floor_given = None          # "auto", (x0, x1, y0, y1) or None (no floor)
        if floor is True:
            self._floor_given = "auto"
        elif floor is not False and floor is not None:
            f = _array(floor, "floor")
            if f.shape != (4,) or not (f[0] < f[1] and f[2] < f[3]):
                raise ValueError(f"floor must be True, False or (x0, x1, y0, y1) m with x0 < x1, y0 < y1, "
                                 f"got {floor!r}")
            self._floor_given = f
        self._given_limits = None if limits is None else self._check_limits(limits)
        self._limits = self._given_limits
        self._fitted = False

        self._inset_of = _inset_of
        ax.set_proj_type("ortho" if _inset_of is not None else "persp", focal_length=None if _inset_of else 0.9)
        ax.computed_zorder = False       # floor, then the boxes (sorted among themselves), then contact lines
        ax.view_init(elev=elev, azim=azim)
        if not axis:
            ax.set_axis_off()
        else:
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
            ax.set_zlabel("z (m)")
        self.floor = Poly3DCollection(np.zeros((0, 4, 3)), linewidths=0.0, zorder=0.5)
        ax.add_collection3d(self.floor, autolim=False)
        self._linewidth = float(linewidth)
        self.polys = Poly3DCollection(np.zeros((0, 4, 3)), linewidths=linewidth if edges else 0.0, zorder=1)
        ax.add_collection3d(self.polys, autolim=False)
        self.lines = Line3DCollection(np.zeros((0, 2, 3)), colors=[_rgba(c["contact"], "COLORS['contact']")],
                                      linewidths=2.2, zorder=3)
        ax.add_collection3d(self.lines, autolim=False)
        # the world's axes at the floor's near corner, one scale length long (fit places them)
        self.triad = Line3DCollection(np.zeros((0, 2, 3)), colors=["#d62728", "#2ca02c", "#1f5bff"], linewidths=1.8,
                                      zorder=0.7)
        ax.add_collection3d(self.triad, autolim=False)
        # a level line from each incline's top along its axis in plan view: the slope shows against it
        self.levels = Line3DCollection(np.zeros((0, 2, 3)), colors=["#555555"], linewidths=1.0, linestyles="--",
                                       zorder=3)
        ax.add_collection3d(self.levels, autolim=False)
        if _inset_of is None:
            for a in (self.floor, self.polys, self.lines, self.triad, self.levels):
                a.set_clip_on(False)       # a 3D Axes draws into a square: use the whole (wider) figure
        self.label = self.fig.text(0.02, 0.975, "", va="top", ha="left", fontsize=9, zorder=4)
        # the boxes may use the whole subplot, not only the square a 3D Axes draws into: an empty frame over
        # the subplot keeps all of it in a tight bounding box (notebooks show figures with bbox_inches='tight')
        from matplotlib.patches import Rectangle  # matplotlib loads only to draw

        pos = ax.get_position(original=True)
        self.extent = Rectangle((pos.x0, pos.y0), pos.width, pos.height, transform=self.fig.transFigure,
                                fill=False, edgecolor="none", linewidth=0.0, zorder=0)
        self.fig.add_artist(self.extent)
        if _inset_of is not None:
            self.label.set_visible(False)
            self.extent.set_visible(False)
        elif inset:
            self._make_inset(colors=colors, edges=edges, linewidth=linewidth, cull=cull, ghost_margin=ghost_margin,
                             contact_length=contact_length, tile=tile, elev=elev)
        self._verts = np.zeros((0, 4, 3))
        self._owner = np.zeros((0, 4), dtype=int)     # per polygon: kind, robot or body index, box, face
        self._cols = np.zeros((0, 4))
        self._segments = np.zeros((0, 2, 3))

    def _make_inset(self, **options) -> None:
        """The inset: a second scene of the same robots and bodies in a framed Axes at INSET_PLACE, seen from the
        same camera (orthographic), its limits framing the held body and the clamps that hold it."""
        from matplotlib.patches import Rectangle  # matplotlib loads only to draw

        x0, y0, w, h = INSET_PLACES[0]
        iax = self.fig.add_axes((x0, y0, w, h), projection="3d", zorder=2)
        iax.patch.set_alpha(0.0)
        # over the scene's boxes (drawn unclipped), under the inset's
        self.inset_frame = Rectangle((x0, y0), w, h, transform=self.fig.transFigure, facecolor="white",
                                     edgecolor="#444444", linewidth=1.0, zorder=1.5)
        self.fig.add_artist(self.inset_frame)
        self.inset_label = self.fig.text(x0 + 0.01, y0 + h - 0.01, "", va="top", ha="left", fontsize=7.5, zorder=4,
                                         bbox=dict(boxstyle="square,pad=0.2", fc="white", ec="none", alpha=0.85))
        self._inset_placed = False
        self.inset = Scene(iax, self.robots, floor=False, axis=False, triad=False, names=False,
                           _inset_of=self, **options)
        self.inset._fitted = True
        self._show_inset(False)

    def _show_inset(self, visible: bool) -> None:
        for a in (self.inset.ax, self.inset_frame, self.inset_label):
            a.set_visible(visible)

    def _place_inset(self) -> None:
        """Moves the inset to the place of INSET_PLACES that covers the fewest of the scene's box corners."""
        from mpl_toolkits.mplot3d import proj3d  # matplotlib loads only to draw

        self._inset_placed = True
        pts = self._verts.reshape(-1, 3)
        if not len(pts):
            return
        self.ax.apply_aspect()
        x, y, _ = proj3d.proj_transform(pts[:, 0], pts[:, 1], pts[:, 2], self.ax.get_proj())
        f = self.fig.transFigure.inverted().transform(self.ax.transData.transform(np.column_stack([x, y])))
        inside = [int(np.sum((f[:, 0] >= x0) & (f[:, 0] <= x0 + w) & (f[:, 1] >= y0) & (f[:, 1] <= y0 + h)))
                  for x0, y0, w, h in INSET_PLACES]
        x0, y0, w, h = INSET_PLACES[int(np.argmin(inside))]
        self.inset.ax.set_position((x0, y0, w, h))
        self.inset_frame.set_bounds(x0, y0, w, h)
        self.inset_label.set_position((x0 + 0.01, y0 + h - 0.01))

    def held_points(self) -> np.ndarray:
        """The corners (m, 3) m of what the inset frames: every held body's boxes and the clamp boxes (links from
        the clamp's fixed link on) of the robots holding it; empty when nothing is held."""
        pts = []
        for i, name in enumerate(self._held):
            if not name or name not in self._body_names:
                continue
            half, poses, _ = self._bodies[self._body_names.index(name)]
            pts.append(box_corners(poses, half).reshape(-1, 3))
            r = self.robots[i]
            first = r.clamp.fixed_link if r.clamp is not None else r.dof
            poses_r, half_r = r.shapes(self._q[i])
            on = np.array([b.link >= first for b in r.boxes], dtype=bool)
            pts.append(box_corners(poses_r[on], half_r[on]).reshape(-1, 3))
        return np.concatenate(pts) if pts else np.zeros((0, 3))

    def _update_inset(self, changed: dict) -> None:
        """The inset shows what the scene shows, framed on the held body and its clamps (hidden when nothing is
        held): a cube 1.3 times the larger of their extents (at least 6 cm), centred on them."""
        pts = self.held_points()
        self._show_inset(bool(len(pts)))
        if not len(pts):
            return
        inset = self.inset
        if not self._inset_placed:
            self._place_inset()
        inset.ax.view_init(elev=self.ax.elev, azim=self.ax.azim)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        side = max(1.3 * float((hi - lo).max()), 0.06)
        c = (lo + hi) / 2
        inset._limits = np.column_stack([c - side / 2, c + side / 2])
        inset._given_limits = inset._limits
        for set_lim, (a, b) in zip((inset.ax.set_xlim, inset.ax.set_ylim, inset.ax.set_zlim), inset._limits):
            set_lim(a, b)
        inset.ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.25)
        inset.update(**changed)
        holders = [self.robots[i].name or f"robot {i}" for i, n in enumerate(self._held) if n]
        bodies = sorted({n for n in self._held if n})
        self.inset_label.set_text(f"zoom: {', '.join(bodies)} held by {' and '.join(holders)} "
                                  f"(a {side * 100:.0f} cm cube)")

    # ---- set-up ----

    def _robot_colors(self, colors) -> list:
        """Per robot, the (k, 4) normal colours of its boxes."""
        n = len(self.robots)
        if colors is None:
            colors = [None] * n
        elif _is_colour(colors):
            colors = [colors] * n
        else:
            colors = list(colors)
            if len(colors) != n:
                raise ValueError(f"colors must hold one colour (or one per box) per robot ({n}), got {len(colors)}")
        out = []
        for i, (r, c) in enumerate(zip(self.robots, colors)):
            k = len(r.boxes)
            if c is not None and not _is_colour(c):
                c = list(c)
                if len(c) != k:
                    raise ValueError(f"colors[{i}] must be a colour or {k} colours, one per box, got {len(c)}")
                out.append(np.array([_rgba(x, f"colors[{i}]") for x in c]).reshape(k, 4))
                continue
            link = _rgba(COLORS["robots"][i % len(COLORS["robots"])] if c is None else c, f"colors[{i}]")
            base, jaw = _rgba(COLORS["base"], "COLORS['base']"), _rgba(COLORS["jaw"], "COLORS['jaw']")
            moving = r.clamp.moving_joint if r.clamp is not None else -1
            rows = [base if b.link == 0 else jaw if ("jaw" in b.name or b.link == moving) else link
                    for b in r.boxes]
            out.append(np.array(rows).reshape(k, 4))
        return out

    @staticmethod
    def _check_limits(limits) -> np.ndarray:
        a = _array(limits, "limits")
        if a.shape != (3, 2) or not np.all(a[:, 0] < a[:, 1]):
            raise ValueError(f"limits must be ((x0, x1), (y0, y1), (z0, z1)) m with each low < high, got {limits!r}")
        return a

    def choose_azimuth(self, frames) -> float:
        """Turns the camera, when the scene was made with azim=None, so that robots and bodies are seen
        past each other; returns the azimuth (degrees).

        frames: one or more arrangements of the scene (e.g. a few frames of
        an animation), each a list of (robot, poses (k, 4, 4), half extents
        (k, 3), scenery) tuples: robot True for a robot's boxes, False for
        a body's; scenery True for fixed surroundings (a world's static
        boxes).

        The preferred azimuth looks across low scenery (all of it below the
        robots' top) at the robots, from the robots' centre towards the
        scenery's in plan view, when it is away from them; else (no
        scenery, or tall scenery such as a wall, which stays behind the
        robots) DEFAULT_AZIM. With an incline among the scenery (a box tilted
        from level, :func:`inclines`; the largest if several), the preferred
        azimuth looks at the incline's side instead, square to its axis in
        plan view, so that its slope shows, and the search below stays within
        45 degrees of it. The score of an azimuth is the mean over the
        boxes of every frame of the square of the fraction of the box's
        sample points (:func:`~coopsim.view.geometry.box_samples`) hidden
        behind boxes of the other kind (bodies behind robots, robots behind
        bodies; a box out of sight weighs more than parts of several).
        From the preferred azimuth outwards in 7.5 degree steps either way,
        the first whose score is at most 0.02 wins (if none, the best).
        Without bodies, or with a given azim, the camera stays."""
        if not self._auto_azim:
            return float(self.ax.azim)
        frames = [[(bool(rb), np.asarray(p, float).reshape(-1, 4, 4), np.asarray(h, float).reshape(-1, 3), bool(sc))
                   for rb, p, h, sc in f] for f in frames]

        def stack(items):
            items = [(p, h) for p, h in items if len(h)]
            if not items:
                return np.zeros((0, 4, 4)), np.zeros((0, 3))
            return np.concatenate([p for p, _ in items]), np.concatenate([h for _, h in items])

        tests = []      # per frame and kind: its boxes' sample points, their count, the other kind's boxes
        for f in frames:
            robots = stack([(p, h) for rb, p, h, _ in f if rb])
            bodies = stack([(p, h) for rb, p, h, _ in f if not rb])
            if len(robots[1]) and len(bodies[1]):
                tests.append((box_samples(*bodies), len(bodies[1]), *robots))
                tests.append((box_samples(*robots), len(robots[1]), *bodies))
        preferred = DEFAULT_AZIM
        robot = stack([(p, h) for rb, p, h, _ in frames[0] if rb])
        scen = stack([(p, h) for rb, p, h, sc in frames[0] if sc and not rb])
        if len(robot[1]) and len(scen[1]):
            # low scenery (a container, a table) is looked across; tall scenery (a wall) stays behind
            low = box_corners(*scen)[..., 2].max() < box_corners(*robot)[..., 2].max()
            d = scen[0][:, :2, 3].mean(axis=0) - robot[0][:, :2, 3].mean(axis=0)
            if low and np.hypot(*d) > 0.1:
                preferred = float(np.degrees(np.arctan2(d[1], d[0])))
        steps = 24
        slopes = inclines([("", p, h) for rb, p, h, sc in frames[0] if sc and not rb])
        if slopes:
            # an incline is seen from its side, square to its axis in plan view (of the two sides, the one
            # nearer the camera's preferred direction), or its slope would not show: at most 45 degrees off
            a = max(slopes, key=lambda inc: inc["size"])["axis"]
            side = float(np.degrees(np.arctan2(a[0], -a[1])))
            preferred = min((side, side + 180.0), key=lambda x: abs((x - preferred + 180.0) % 360.0 - 180.0))
            steps = 6
        if not tests:
            if slopes:
                self.ax.view_init(elev=self.ax.elev, azim=(preferred + 180.0) % 360.0 - 180.0)
            return float(self.ax.azim)
        n_boxes = sum(t[1] for t in tests)
        elev = self.ax.elev
        candidates = preferred + 7.5 * np.array([0] + [s * k for k in range(1, steps + 1) for s in (1, -1)])

        def score(a):
            v = view_direction(elev, a)
            return sum((hidden(pts, v, OP, OH).reshape(k, 15).mean(axis=1) ** 2).sum()
                       for pts, k, OP, OH in tests) / n_boxes

        scores = []
        for a in candidates:
            scores.append(score(a))
            if scores[-1] <= 0.02:
                break
        best = float(candidates[len(scores) - 1] if scores[-1] <= 0.02 else candidates[int(np.argmin(scores))])
        best = (best + 180.0) % 360.0 - 180.0
        self.ax.view_init(elev=elev, azim=best)
        return best

    def fit(self, points) -> None:
        """Fixes the floor, the axis limits (equal scales) and the box aspect so that the points (m, 3) m
        are in view. The first update fits what it shows; an animation fits all its frames first."""
        corners = _array(points, "points").reshape(-1, 3)
        if not len(corners):
            raise ValueError("points must hold at least one point")
        self._fitted = True
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        if self._floor_given is not None:
            if isinstance(self._floor_given, str):
                pad = 1.5 * self.tile
                ext = (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)
            else:
                ext = tuple(self._floor_given)
            tiles = floor_tiles(ext[:2], ext[2:], self.tile)
            cols = [_rgba(c, "COLORS['floor']") for c in COLORS["floor"]]
            ij = np.round(tiles[:, 0, :2] / self.tile).astype(int).sum(axis=1) % 2
            self.floor.set_verts(tiles)
            self.floor.set_facecolor(np.array([cols[k] for k in ij]).reshape(-1, 4))
            lo = np.minimum(lo, [tiles[..., 0].min(), tiles[..., 1].min(), 0.0])
            hi = np.maximum(hi, [tiles[..., 0].max(), tiles[..., 1].max(), 0.0])
        if self._given_limits is None:
            self._limits = np.column_stack([lo - 0.02, hi + 0.02])
        L = self._limits
        self.ax.set_xlim(*L[0])
        self.ax.set_ylim(*L[1])
        self.ax.set_zlim(*L[2])
        self.ax.set_box_aspect(tuple(L[:, 1] - L[:, 0]), zoom=self._zoom)
        if self._zoom_auto:
            # no box out of the picture: zoom less where they would reach past its edges
            zoom = self._zoom
            for _ in range(3):
                reach = self._reach(corners)
                if reach <= 0.97:
                    break
                zoom *= 0.95 / reach
                self.ax.set_box_aspect(tuple(L[:, 1] - L[:, 0]), zoom=zoom)
            self._zoom_now = zoom
        else:
            self._zoom_now = self._zoom
        self._place_triad()
        self._name_robots()      # the bases (link 0) do not move: where they are with any q

    #: lengths (m) the world's axes may have: the largest below a fifth of the floor's (or the view's) smaller side
    SCALES = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)

    def _place_triad(self) -> None:
        """The world's x, y, z axes (red, green, blue) from the floor's corner nearest the camera's left, each
        ``scale`` m long, labelled, with the scale written beside them."""
        for t in self.triad_labels:
            t.remove()
        self.triad_labels = []
        self.triad_segments = np.zeros((0, 2, 3))
        if not self._show_triad or self._limits is None:
            self.triad.set_segments(self.triad_segments)
            return
        ext = self.floor_extent or (*self._limits[0], *self._limits[1])
        side = min(ext[1] - ext[0], ext[3] - ext[2])
        self.scale = max([s for s in self.SCALES if s <= side / 5] or [self.SCALES[0]])
        o = np.array([ext[0], ext[2], 0.0]) + 0.25 * self.scale
        L = self.scale
        ends = o + L * np.eye(3)
        self.triad_segments = np.stack([np.tile(o, (3, 1)), ends], axis=1)    # (3, 2, 3) m: x, y, z
        self.triad.set_segments(self.triad_segments)
        for name, e in zip("xyz", ends):
            self.triad_labels.append(self.ax.text(*(e + 0.12 * L * (e - o) / L), name, fontsize=8, ha="center",
                                                  va="center", zorder=4))
        text = f"{L * 100:g} cm" if L < 0.1 else f"{L:g} m"
        self.triad_labels.append(self.ax.text(*(o + np.array([0.0, 0.0, 1.45 * L])), f"axes {text}", fontsize=7,
                                              ha="center", va="bottom", zorder=4, color="#333333"))

    def _name_robots(self) -> None:
        """Each robot's name on the floor at the foot of its base (its boxes on link 0), on the camera's side,
        framed in its links' colour; drawn over the floor and under the boxes, so that it hides nothing."""
        for t in self.names:
            t.remove()
        self.names = []
        if not self._show_names:
            return
        for i, r in enumerate(self.robots):
            poses, half = r.shapes(self._q[i])
            base = [j for j, b in enumerate(r.boxes) if b.link == 0] or list(range(len(r.boxes)))
            pts = box_faces(poses[base], half[base]).reshape(-1, 3)
            centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
            towards = view_direction(self.ax.elev, self.ax.azim)[:2]
            towards = towards / max(np.linalg.norm(towards), 1e-12)
            reach = float(np.abs((pts[:, :2] - centre[:2]) @ towards).max())     # the base's half width that way
            x, y = centre[:2] + (reach + 0.06) * towards
            label = r.name or f"robot {i}"
            colour = COLORS["robots"][i % len(COLORS["robots"])]
            self.names.append(self.ax.text(x, y, 0.0, label, fontsize=8, ha="center",
                                           va="center", zorder=0.9, fontweight="bold",
                                           bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=colour, lw=1.2,
                                                     alpha=0.8)))

    def label_inclines(self) -> None:
        """Finds the inclines among the scenery bodies (:func:`inclines`) and writes each one's slope over its
        top, with a dashed level line from the top along its axis in plan view, the slope's run: the incline
        shows its angle against it. The scene's first fit calls it; the camera looks at an incline's side
        (:meth:`choose_azimuth`)."""
        for t in self.incline_labels:
            t.remove()
        self.incline_labels = []
        items = [(name, poses, half) for (half, poses, _), name, scenery
                 in zip(self._bodies, self._body_names, self._body_scenery) if scenery and poses.ndim == 3]
        self.inclines = [{k: v for k, v in inc.items() if k != "rotation"} for inc in inclines(items)]
        segments = []
        for inc in self.inclines:
            names = [n for n in inc["names"] if n in self._body_names]
            corners = np.concatenate([box_corners(*self._bodies[self._body_names.index(n)][1::-1]).reshape(-1, 3)
                                      for n in names])
            a = inc["axis"]
            run = float(np.ptp(corners @ (np.array([a[0], a[1], 0.0]) / max(np.hypot(a[0], a[1]), 1e-12))))
            top = inc["top"]
            segments.append([top, top + run * np.array([a[0], a[1], 0.0]) / max(np.hypot(a[0], a[1]), 1e-12)])
            if self._show_names and self._inset_of is None:
                self.incline_labels.append(self.ax.text(*(top + [0.0, 0.0, 0.04]), f"{inc['slope']:.0f}° incline",
                                                        fontsize=8, ha="center", va="bottom", zorder=4,
                                                        color="#222222"))
        self.level_segments = np.array(segments).reshape(-1, 2, 3)     # (m, 2, 3) m
        self.levels.set_segments(self.level_segments)

    def _reach(self, points) -> float:
        """How far the points (m, 3) reach from the middle of the axes' place in the figure towards its edges,
        at most: 1 at an edge (the larger of x and y, as fractions of the half width and half height). A 3D
        Axes draws into a square, but its artists are not clipped: the place is the whole subplot."""
        from mpl_toolkits.mplot3d import proj3d  # matplotlib loads only to draw

        self.ax.apply_aspect()           # as drawing will: the square the Axes draws into
        x, y, _ = proj3d.proj_transform(points[:, 0], points[:, 1], points[:, 2], self.ax.get_proj())
        disp = self.ax.transData.transform(np.column_stack([x, y]))
        bb = self.ax.get_position(original=True).transformed(self.fig.transFigure)
        fx = np.abs(disp[:, 0] - (bb.x0 + bb.x1) / 2) / (bb.width / 2)
        fy = np.abs(disp[:, 1] - (bb.y0 + bb.y1) / 2) / (bb.height / 2)
        return float(max(fx.max(), fy.max()))

    # ---- state ----

    def update(self, q=_KEEP, *, reference=_KEEP, holding=_KEEP, colliding=_KEEP, contacts=_KEEP, bodies=_KEEP,
               label=_KEEP, held=_KEEP) -> list:
        """Shows the robots at q; returns the changed artists. Nothing is drawn here: call
        ``fig.canvas.draw_idle()`` or save the figure afterwards.

        q: joint positions, (n,) for one robot or one (n_i,) array per robot
        (rad or m). reference: the desired pose drawn as a ghost, the same
        layout (None: no ghost; a robot's entry None: no ghost for it).
        holding: bool or one bool per robot (its links green while True).
        colliding: per robot a (boxes,) bool mask in robot.boxes order,
        shown when the scene draws collision boxes. contacts: (m, 2, 3)
        pairs of (point m, normal), drawn as red lines of contact_length
        along the normal. bodies: a list of :class:`Body` with (4, 4) or
        (m, 4, 4) poses. label: text at the top left. An argument left out
        keeps its value; None removes what it shows (holding None: not
        holding; colliding None: all free). held: per robot the name of the
        body it holds ('' or None: none), which the inset (inset=True) frames
        with the robot's clamp.
        """
        changed = dict(q=q, reference=reference, holding=holding, colliding=colliding, contacts=contacts,
                       bodies=bodies)
        changed = {k: v for k, v in changed.items() if v is not _KEEP}
        if held is not _KEEP:
            names = [None] * len(self.robots) if held is None else list(held)
            if len(names) != len(self.robots) or not all(n is None or isinstance(n, str) for n in names):
                raise ValueError(f"held must hold one body name (or None) per robot ({len(self.robots)}), got "
                                 f"{held!r}")
            self._held = [n or None for n in names]
        if q is not _KEEP:
            self._q = _per_robot_q(q, self.robots, "q")
        if reference is not _KEEP:
            self._ref = _per_robot_q(reference, self.robots, "reference", allow_none=True)
        if holding is not _KEEP:
            self._hold = _per_robot_bool(holding, self.robots, "holding")
        if colliding is not _KEEP:
            self._mask = _per_robot_mask(colliding, self.robots, "colliding")
        if contacts is not _KEEP:
            self._contacts = _contacts(contacts)
        if bodies is not _KEEP:
            self._bodies = _bodies(bodies)
            listed = [] if bodies is None else [bodies] if isinstance(bodies, Body) else list(bodies)
            self._body_names = [b.name for b in listed]
            self._body_scenery = [bool(b.scenery) for b in listed]
            self._body_tiled = [bool(b.tiled) for b in listed]
        if label is not _KEEP:
            self.label.set_text("" if label is None else str(label))
        self._rebuild()
        if self.inset is not None:
            self._update_inset(changed)
            return [self.polys, self.lines, self.label, self.inset.polys, self.inset.lines, self.inset_label]
        return [self.polys, self.lines, self.label]

    def _rebuild(self) -> None:
        # every box to draw: (kind, owner, poses (k, 4, 4), half extents (k, 3), base colours (k, 4))
        boxes = []
        for i, r in enumerate(self.robots):
            poses, half = r.shapes(self._q[i])
            if self.collision_boxes:
                col = np.where(self._mask[i][:, None], self._colliding, self._free)
            elif self._hold[i]:
                col = self._colors[i].copy()
                col[self._moving[i]] = self._holding_shades[i % len(self._holding_shades)]
            else:
                col = self._colors[i]
            boxes.append((0, i, poses, half, col, np.arange(len(half))))
        for j, (half, poses, col) in enumerate(self._bodies):
            boxes.append((1, j, poses, half, np.tile(col, (len(half), 1)), np.arange(len(half))))
        for i, r in enumerate(self.robots):
            if self._ref[i] is not None:
                # no ghost of the base (it never moves); ghost boxes a little smaller, so a robot on its
                # reference hides its ghost and the ghost shows only where the robot is not
                poses, half = r.shapes(self._ref[i])
                moving = self._moving[i]
                half = half[moving] - np.minimum(self.ghost_margin, 0.25 * half[moving])
                boxes.append((2, i, poses[moving], half, np.tile(self._ghost_face, (len(half), 1)),
                              np.flatnonzero(moving)))
        if not self._fitted:
            self.choose_azimuth([[(b[0] == 0, b[2], b[3], b[0] == 1 and self._body_scenery[b[1]])
                                  for b in boxes if b[0] < 2]])
            self.fit(np.concatenate([box_faces(b[2], b[3]).reshape(-1, 3) for b in boxes]))
        if not self._inclines_found and self._inset_of is None:
            self._inclines_found = True     # scenery does not move: once, with the first bodies shown
            self.label_inclines()

        poses = np.concatenate([b[2] for b in boxes])
        half = np.concatenate([b[3] for b in boxes])
        base = np.repeat(np.concatenate([b[4] for b in boxes]), 6, axis=0)
        owner = np.concatenate([np.column_stack([np.full(len(b[3]), b[0]), np.full(len(b[3]), b[1]), b[5]])
                                for b in boxes])
        owner = np.column_stack([np.repeat(owner, 6, axis=0), np.tile(np.arange(6), len(owner))])
        verts = box_faces(poses, half)
        normals = box_normals(poses)
        elev, azim = self.ax.elev, self.ax.azim
        if self.cull:
            # faces turned clearly away from the camera are hidden behind their own box
            keep = normals @ view_direction(elev, azim) > -0.2
            verts, normals, base, owner = verts[keep], normals[keep], base[keep], owner[keep]
        cols = shade(base, normals, light_direction(elev, azim))
        # tiled bodies' big faces in tiles, so that they sort by depth piece by piece; no edges between them
        seamless = np.zeros(len(verts), dtype=bool)
        if any(self._body_tiled):
            big = owner[:, 0] == 1
            big[big] = np.array(self._body_tiled, dtype=bool)[owner[big, 1]]
            if big.any():
                pieces, counts = split_quads(verts[big], self.tile)
                n = np.ones(len(verts), dtype=int)
                n[big] = counts
                slots = np.repeat(np.arange(len(verts)), n)
                new = verts[slots]
                new[np.repeat(big, n)] = pieces
                verts, owner, cols = new, owner[slots], cols[slots]
                seamless = np.repeat(big & (n > 1), n)
        self._verts, self._owner, self._cols = verts, owner, cols
        self.polys.set_verts(verts)
        self.polys.set_facecolor(cols)
        if self._edges or seamless.any():
            edge = cols.copy()
            if self._edges:
                edge[~seamless, :3] *= 0.55
                ghost = owner[:, 0] == 2
                edge[ghost, 3] = min(1.0, 2.0 * self._ghost_face[3])
            self.polys.set_edgecolor(edge)
            # tiles edged in their own colour, wide enough to close the antialiased seams between them
            width = np.full(len(verts), self._linewidth if self._edges else 0.0)
            width[seamless] = 1.0
            self.polys.set_linewidth(width)
        c = self._contacts
        self._segments = (np.stack([c[:, 0], c[:, 0] + self.contact_length * c[:, 1]], axis=1)
                          if len(c) else np.zeros((0, 2, 3)))
        self.lines.set_segments(self._segments)

    # ---- drawing ----

    def redraw(self) -> None:
        """Draws the figure after :meth:`update`, cheaply: the first call draws everything but the boxes,
        contact lines and label once as a background and keeps it; later calls restore it and draw only
        those (blitting; the background is drawn again when the figure's size, the camera or the limits
        change). On a canvas that cannot blit, a full draw. For live views and animations."""
        canvas = self.fig.canvas
        if not getattr(canvas, "supports_blit", False):
            canvas.draw()
            return
        inset = self.inset if self.inset is not None and self.inset.ax.get_visible() else None
        key = (canvas.get_width_height(physical=True), self.ax.elev, self.ax.azim, self.ax.roll,
               None if self._limits is None else self._limits.tobytes(), self.fig.dpi, inset is not None)
        # the inset's boxes, contact lines and text move with its limits: drawn over the background as the scene's
        moving = [(self.ax, a) for a in (self.polys, self.lines, self.levels)]
        if inset is not None:
            moving += [(inset.ax, a) for a in (inset.polys, inset.lines)]
        if getattr(self, "_background", None) is None or self._background[0] != key:
            dynamic = ([a for _, a in moving] + [self.label] + self.incline_labels
                       + ([self.inset_label, self.inset_frame] if inset is not None else []))
            visible = [a.get_visible() for a in dynamic]
            for a in dynamic:
                a.set_visible(False)
            try:
                canvas.draw()
                self._background = (key, canvas.copy_from_bbox(self.fig.bbox))
            finally:
                for a, v in zip(dynamic, visible):
                    a.set_visible(v)
        canvas.restore_region(self._background[1])
        if inset is not None:
            inset.ax.M = inset.ax.get_proj()     # its limits change from frame to frame (Axes3D.draw would do it)
            inset.ax.invM = np.linalg.inv(inset.ax.M)
        for ax, a in moving:
            if inset is not None and ax is inset.ax and a is inset.polys:
                self.fig.draw_artist(self.inset_frame)     # over the scene's boxes, under the inset's
            if a.get_visible():
                a.do_3d_projection()
                ax.draw_artist(a)
            if a is self.levels:
                for t in self.incline_labels:              # over the boxes, as a full draw puts them
                    self.ax.draw_artist(t)
        for t in [self.label] + ([self.inset_label] if inset is not None else []):
            if t.get_visible() and t.get_text():
                self.fig.draw_artist(t)
        canvas.blit(self.fig.bbox)

    # ---- what is drawn ----

    def _select(self, kind: str, index, box, face) -> np.ndarray:
        if kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {kind!r}")
        sel = self._owner[:, 0] == _KINDS.index(kind)
        for col, v in ((1, index), (2, box), (3, face)):
            if v is not None:
                sel &= self._owner[:, col] == v
        return sel

    def faces(self, kind: str = "robot", index: Optional[int] = None, box: Optional[int] = None,
              face: Optional[int] = None) -> np.ndarray:
        """The drawn polygons (m, 4, 3) m: kind 'robot' or 'ghost' (index: the robot, box: its box in
        robot.boxes order) or 'body' (index: the Body, box: its box); face: 0..5 for the box's -z, +z,
        -y, +x, +y, -x face; None: all. Boxes in order, six faces each, less the faces culled
        (cull=True). The floor: :meth:`floor_faces`."""
        return self._verts[self._select(kind, index, box, face)]

    def colors(self, kind: str = "robot", index: Optional[int] = None, box: Optional[int] = None,
               face: Optional[int] = None) -> np.ndarray:
        """The shaded RGBA face colours (m, 4) of the polygons :meth:`faces` returns."""
        return self._cols[self._select(kind, index, box, face)]

    @property
    def body_names(self) -> List[str]:
        """The names of the :class:`Body` boxes shown, in order: ``faces('body', index)`` is the body
        ``body_names[index]``."""
        return list(self._body_names)

    def body_index(self, name: str) -> int:
        """The index of the body named `name` for :meth:`faces` and :meth:`colors`; ValueError when none."""
        try:
            return self._body_names.index(name)
        except ValueError:
            raise ValueError(f"no body named {name!r} in the scene (bodies: {self._body_names})") from None

    def contact_lines(self) -> np.ndarray:
        """The contact lines drawn, (m, 2, 3) m: from each contact point along its normal."""
        return self._segments.copy()

    def floor_faces(self) -> np.ndarray:
        """The floor tiles (m, 4, 3) m."""
        return np.asarray(self.floor._faces) if hasattr(self.floor, "_faces") else np.zeros((0, 4, 3))

    @property
    def floor_extent(self):
        """(x0, x1, y0, y1) m of the floor tiles, or None without a floor (or before the first update)."""
        f = self.floor_faces()
        if not len(f):
            return None
        return (float(f[..., 0].min()), float(f[..., 0].max()), float(f[..., 1].min()), float(f[..., 1].max()))

    @property
    def zoom(self) -> float:
        """The zoom of the picture (matplotlib's box aspect zoom): the one given, or the default as fitted."""
        return float(getattr(self, "_zoom_now", self._zoom))

    @property
    def limits(self) -> np.ndarray:
        """((x0, x1), (y0, y1), (z0, z1)) m of the axes, (3, 2)."""
        return None if self._limits is None else self._limits.copy()

    def project(self, points) -> np.ndarray:
        """Pixel coordinates (m, 2) of world points (m, 3) m in the figure's image: x to the right, y down
        from the top-left corner, as in ``np.asarray(fig.canvas.buffer_rgba())[y, x]``. Draw the figure
        first (e.g. ``fig.canvas.draw()``) so that the layout is final."""
        from mpl_toolkits.mplot3d import proj3d  # matplotlib loads only to draw

        p = _array(points, "points").reshape(-1, 3)
        x, y, _ = proj3d.proj_transform(p[:, 0], p[:, 1], p[:, 2], self.ax.get_proj())
        disp = self.ax.transData.transform(np.column_stack([x, y]))
        h = self.fig.bbox.height
        return np.column_stack([disp[:, 0], h - disp[:, 1]])


def _positive(x, what: str, zero: bool = False) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)) or not np.isfinite(x) \
            or x < 0 or (x == 0 and not zero):
        raise ValueError(f"{what} must be {'>= 0' if zero else '> 0'}, got {x!r}")
    return float(x)


def _finite(x, what: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)) or not np.isfinite(x):
        raise ValueError(f"{what} must be a finite number (degrees), got {x!r}")
    return float(x)


def _is_colour(c) -> bool:
    from matplotlib.colors import is_color_like  # matplotlib loads only to draw

    if isinstance(c, str):
        return is_color_like(c)
    return isinstance(c, tuple) and len(c) in (3, 4) and all(isinstance(v, (int, float)) for v in c)


def draw(ax, robots, q=None, *, reference=None, holding=None, collision_boxes: bool = False, colliding=None,
         contacts=None, bodies=None, world=None, floor=None, tile: float = 0.1, colors=None, limits=None,
         elev: Optional[float] = None, azim: Optional[float] = None, axis: bool = False, zoom: Optional[float] = None,
         contact_length: float = 0.04, edges: bool = True, cull: bool = False, ghost_margin: float = 0.002,
         label: Optional[str] = None, triad: bool = True, names: bool = True, inset: bool = False,
         held=None) -> Scene:
    """Draws robots as shaded boxes in a 3D Axes; returns a :class:`Scene` to update with new q cheaply.

    ax: a 3D matplotlib Axes (``fig.add_subplot(projection='3d')``), or
    None for a new 6.4 x 4.8 in pyplot figure. robots: a coopsim.Robot or a
    sequence of them, or a Simulation: its robots, by default at their
    state now and with its world). q: joint positions (rad or m), (n,) for
    one robot or one (n_i,) array per robot (None: a Simulation's state
    now). Every box of ``robot.shapes(q)`` is drawn: base column, links,
    clamp body and both jaws.

    world: a coopsim.World, or a Simulation (default: robots when that is
    a Simulation; False: none). Its static boxes are drawn as grey scenery,
    its free bodies as boxes (the bar, a body named 'bar...', red; others
    purple): a World's at the poses they were added with, a Simulation's
    at their state now (``sim.body_state``). With collision_boxes=True and
    a Simulation, the boxes in ``sim.contacts()`` are red and the contact
    points red lines, unless colliding / contacts are given (contacts=False:
    no lines). The robots' link boxes must be named as the world names them
    (the simulation's robots).

    The paper's colours: reference, desired joint positions in the same
    layout as q, is drawn as a transparent blue ghost of the moving links
    (boxes ghost_margin = 2 mm smaller, so a robot on its reference hides
    it and the ghost shows where the robot lags; None: none). holding:
    bool or one per robot: that robot's moving links are green; with a
    Simulation, None (default) or 'shared' makes a robot green when the
    body it holds now (``sim.holding(i)``) is held by another robot too
    (the paper's dual hold, its Fig. 18), 'any' when it holds anything (see
    :func:`~coopsim.view.holding_now`); without one, None is not holding.
    collision_boxes:
    every box green (free) or red where ``colliding`` (per robot a (boxes,)
    bool mask in robot.boxes order) is True. contacts: (m, 2, 3) array of
    (point, normal) pairs, m, drawn as red lines of contact_length m along
    the normals. bodies: extra boxes, a list of :class:`Body` (the bar,
    scenery) with (4, 4) or (m, 4, 4) poses, drawn before the world's.

    floor: True for a checkered floor at z = 0 under everything drawn (tiles
    of `tile` m), (x0, x1, y0, y1) m for a given extent, False for none;
    default True, or False with a world that has no floor.
    colors: one matplotlib colour per robot (its links; base and jaws stay
    grey), or per robot one colour per box. limits: ((x0, x1), (y0, y1),
    (z0, z1)) m, default fitted to the floor and the boxes; the three axes
    always have equal scales. elev, azim (degrees): the camera, matplotlib's
    convention, looking from above (default elevation 22; default azimuth
    -62, from the front right, turned in steps of 7.5 degrees when that
    hides the scenery or bodies behind the robots: see
    :meth:`Scene.choose_azimuth`); zoom: > 1 enlarges (default 1.6, less
    where a box would reach out of the picture unless limits are given;
    0.9 with axis=True to leave room for the tick labels). axis: draw
    matplotlib's axes, ticks and panes (a frame then costs several times
    more). Faces are flat-shaded by a light over the camera's left
    shoulder, with darker edges (edges=False: none). cull: leave out faces
    turned away from the camera (faster, and right only while the camera
    stays where it is: animations use it). label: text at the top left.
    triad: the world's x, y, z axes (red, green, blue) at the floor's
    corner, ``scene.scale`` m long (0.01 .. 5 m, under a fifth of the
    floor's smaller side), labelled with that length (not with axis=True).
    names: each robot's name over its base, and each incline's slope
    (scenery tilted from level, :func:`inclines`) over its top, beside a
    dashed level line; the default camera looks at an incline's side.
    inset: True adds a zoom on the held body in the upper right (an inset
    3D Axes, ``scene.inset``, a Scene of its own): its limits frame the
    held body and the clamp boxes holding it, hidden while nothing is held.
    held: per robot the name of the body it holds (None: none; default with
    a Simulation, what ``sim.holding(i)`` says). Robots holding are green in
    shades of their own (``COLORS['holding_shades']``), so two holding at
    once tell apart.

    Raises ValueError naming the argument for wrong shapes or values.
    """
    sim = robots if _is_simulation(robots) else None
    if isinstance(holding, str) or (holding is None and sim is not None):
        mode = _holding_mode("shared" if holding is None else holding, "holding")
        if sim is None:
            raise ValueError(f"holding={holding!r} reads what the robots hold from a Simulation: pass the "
                             "Simulation as robots, or give holding as bools")
        holding = holding_now(sim, mode=mode)
    w, wsim = resolve_world(sim if world is None else world, "world")
    robots = _robot_list(robots, allow_empty=w is not None or bodies is not None)
    if q is None:
        if sim is None and robots:
            raise ValueError("q must be given (joint positions per robot), unless robots is a Simulation")
        q = [sim.state(i)[0] for i in range(len(robots))] if robots else []
    if floor is None:
        floor = True if w is None else bool(w.floor)
    shown = [] if bodies is None else ([bodies] if isinstance(bodies, Body) else list(bodies))
    if w is not None:
        shown = shown + world_bodies(wsim if wsim is not None else w)
        if collision_boxes and wsim is not None and wsim.steps > 0:
            now = wsim.contacts()
            if colliding is None:
                colliding = colliding_from_contacts(now, robots)
            if contacts is None:
                contacts = contact_lines(now)
    if contacts is False:
        contacts = None
    if not robots and not shown:
        raise ValueError("nothing to draw: give robots, bodies or a world with bodies")
    if ax is None:
        import matplotlib.pyplot as plt  # matplotlib loads only to draw

        fig = plt.figure(figsize=(6.4, 4.8))
        ax = fig.add_subplot(projection="3d")
        fig.subplots_adjust(0, 0, 1, 1)
    elif getattr(ax, "name", None) != "3d":
        raise ValueError("ax must be a 3D Axes (fig.add_subplot(projection='3d')) or None")
    if held is None and sim is not None:
        held = [sim.holding(i) for i in range(len(robots))]
    scene = Scene(ax, robots, colors=colors, collision_boxes=collision_boxes, floor=floor, tile=tile,
                  limits=limits, elev=elev, azim=azim, axis=axis, zoom=zoom, contact_length=contact_length,
                  edges=edges, cull=cull, ghost_margin=ghost_margin, triad=triad, names=names, inset=inset)
    scene.update(q, reference=reference, holding=holding, colliding=colliding, contacts=contacts, bodies=shown,
                 label=label, held=held)
    return scene
