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

from .annotations import INCLINE_MIN, _Annotations, inclines  # noqa: F401  (INCLINE_MIN: importable from here)
from .bodies import COLORS, Body, _array, _is_simulation, _robot_list
from .camera import DEFAULT_AZIM, DEFAULT_ELEV, _Camera
from .. import _checks
from .checks import _bodies, _contacts, _is_colour, _per_robot_bool, _per_robot_mask, _per_robot_q, _rgba
from .geometry import box_faces, box_normals, light_direction, shade, split_quads, view_direction
from .inset import INSET_PLACES, _Inset  # noqa: F401  (INSET_PLACES: importable from here)
from .world import _holding_mode, colliding_from_contacts, contact_lines, holding_now, resolve_world, world_bodies

__all__ = ["Body", "COLORS", "Scene", "draw", "inclines"]

_KEEP = object()   # update(): leave as it is


_KINDS = ("robot", "body", "ghost")


class Scene(_Camera, _Annotations, _Inset):
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
        self.contact_length = _checks.positive(contact_length, "contact_length")
        self.tile = _checks.positive(tile, "tile")
        self.ghost_margin = _checks.positive(ghost_margin, "ghost_margin", zero=True)
        # by default as large as the boxes allow: the floor's edges may leave the picture, the boxes may not
        self._zoom_auto = zoom is None and not axis and limits is None
        self._zoom = (0.9 if axis else 1.6) if zoom is None else _checks.positive(zoom, "zoom")
        # azim None: DEFAULT_AZIM, turned at the first fit when that hides bodies behind the robots
        self._auto_azim = azim is None
        elev = DEFAULT_ELEV if elev is None else _checks.number(elev, "elev")
        azim = DEFAULT_AZIM if azim is None else _checks.number(azim, "azim")
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
