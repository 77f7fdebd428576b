"""A live view of a running simulation in the browser (and in a notebook cell): the paper's graphic interface.

    v = cs.view.live(sim, t_end=10.0)     # serves http://127.0.0.1:<port>, runs the simulation paced at 100 %
    v.show()                              # in Jupyter: the page in the cell (an IFrame); in a script: the URL
    v.wait()                              # until t_end (re-raises an exception of the run)
    v.close()                             # stops the server, frees the port

The page (served by ``viser``, the ``live`` extra: ``pip install coopsim[live]``) shows every robot as its
parts (:mod:`coopsim.view.parts`: the SCARAs as the paper draws them, a URDF arm with its visual meshes,
another robot as its boxes), placed on the link frames (``Robot.frames(q)``, one call per robot and frame),
the desired pose as a transparent blue ghost of the moving links' parts, the robots green while they hold a
body together, the world's scenery (grey), its free bodies (the bar red) and the floor, with the colours of
:data:`coopsim.view.COLORS`; with "Collision boxes" on, the link boxes (``Robot.shapes(q)``) instead of the
parts, green (free) or red (in contact), and the contact points as red lines.

Panels (tabs): **Run**: speed 0-400 %, pause, resume, one step (one control period), reset to the start,
and the time supervision (simulated and wall time, set and achieved speed, step time mean and max,
frames per second). **Display**: collision boxes, contact lines, ghosts, labels, camera views.
**Robots**: per robot its controller and its gains (editable), its dimensions (editable for the built-in
SCARAs), and a teach mode: joint sliders, a joint target typed in, and a gizmo at the clamp; a target
becomes a cubic from where the robot is (its measured q and qd now) to the target (closed-form IK
``robot.ik`` for the gizmo) as the robot's new reference. **Plots**: a chosen robot's joint positions
against their references and its tracking error over the last seconds. **Data**: the last rows of the
log; the log as CSV or Excel to download.

One writer: the simulation runs paced (:class:`coopsim.Pacer`, the engine stepping with the GIL
released) in one thread, the view's or the caller's (:meth:`LiveView.run_to`). What the page asks for is
queued and applied by that thread between chunks (the pacer's frame hook), where it also takes the
frame's snapshot. A value from the page passes the checks of the API it calls (the pacer's speed,
``CubicTrajectory``, ``Robot.ik``, the joint limits); a bad one is refused with a message in the panel and
the run goes on. Pages may come, go and reconnect; the run does not notice. The server binds 127.0.0.1
unless another host is given, and never opens viser's share tunnel.

Gains typed in and set (:meth:`LiveView.set_gains`) build a new controller of the same kind (``PID`` or
``ComputedTorque``, its other settings kept) that replaces the robot's through ``Simulation.set_controller``
from the next control step; a PID's integral restarts at zero. The constructor and ``set_controller`` check
the values (>= 0, finite, 1 or n of them). A Python controller's gains are its own: shown by name only. A
built-in SCARA's L1, L2 and base height typed in and set (:meth:`LiveView.set_dimensions`) rebuild it by its
maker (``cs.robots.scara1``/``scara2``) and replace it through ``Simulation.set_robot``, the run going on from
the same state; another robot's dimensions are shown without editing. "Reset to the start" keeps the gains
and dimensions last set.
"""
from __future__ import annotations

import math
import os
import queue
import sys
import tempfile
import threading
import time
from collections import deque
from typing import Callable, List, Optional

import numpy as np

from .._core import PID, ComputedTorque, CubicTrajectory
from ..pacing import Pacer
from ..robots import scara1, scara2
from ..simulation import Simulation
from .geometry import box_corners, view_direction
from .parts import UNIT_CUBE, UNIT_CYLINDER, _box_role, mesh_triangles, part_corners, part_poses, robot_parts
from .scene import COLORS, DEFAULT_ELEV, Scene
from .world import colliding_from_contacts, contact_lines, holding_now, is_bar, robot_labels

__all__ = ["LiveView", "live"]

_HOST = "127.0.0.1"
_CONTACT_LENGTH = 0.04        # m, drawn length of a contact line
_GHOST_MARGIN = 0.002         # m, ghost parts this much smaller on each side (a robot on its reference hides its ghost)
_PLOT_EVERY = 0.1             # s of wall time between plot updates
_TABLE_EVERY = 0.5            # s of wall time between updates of the data table
_DIMENSION_FIELDS = (("L1", "L1 (m)"), ("L2", "L2 (m)"), ("L_base", "Base height (m)"))   # the built-in SCARAs'
_TABLE_ROWS = 8
_WINDOW = 1.0                 # s of wall time over which the supervision's rates are measured
_ENVIRONMENT = 0.15          # intensity of the environment map's lighting (viser's default 1 washes colours out)
_FOREVER = 1e7                # s: t_end of a run "until closed"

# a unit cube (side 1, centred) as 8 vertices and 12 outward triangles
_CUBE_V = np.array([[-.5, -.5, -.5], [.5, -.5, -.5], [.5, .5, -.5], [-.5, .5, -.5],
                    [-.5, -.5, .5], [.5, -.5, .5], [.5, .5, .5], [-.5, .5, .5]], dtype=np.float32)
_CUBE_F = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                    [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]], dtype=np.uint32)


def _rgb8(c) -> np.ndarray:
    from matplotlib.colors import to_rgb

    return np.round(np.array(to_rgb(c)) * 255).astype(np.uint8)


def quaternions(R) -> np.ndarray:
    """Unit quaternions (k, 4) [w, x, y, z] of rotation matrices (k, 3, 3) (Shepperd's method, w >= 0)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    tr = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    cand = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(cand, axis=1)
    q = np.empty((len(R), 4))
    for j in range(4):
        s = k == j
        if not s.any():
            continue
        m = R[s]
        if j == 0:
            r = np.sqrt(1.0 + tr[s]) * 2
            q[s] = np.column_stack([0.25 * r, (m[:, 2, 1] - m[:, 1, 2]) / r, (m[:, 0, 2] - m[:, 2, 0]) / r,
                                    (m[:, 1, 0] - m[:, 0, 1]) / r])
        else:
            a, b, c = j - 1, j % 3, (j + 1) % 3
            r = np.sqrt(1.0 + m[:, a, a] - m[:, b, b] - m[:, c, c]) * 2
            v = np.empty((s.sum(), 4))
            v[:, 0] = (m[:, c, b] - m[:, b, c]) / r
            v[:, 1 + a] = 0.25 * r
            v[:, 1 + b] = (m[:, b, a] + m[:, a, b]) / r
            v[:, 1 + c] = (m[:, c, a] + m[:, a, c]) / r
            q[s] = v
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _rotation(wxyz) -> np.ndarray:
    w, x, y, z = np.asarray(wxyz, dtype=float) / np.linalg.norm(wxyz)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _role_colors(roles, i: int) -> np.ndarray:
    """(k, 3) uint8: robot i's colours of parts or boxes by their colour name ('robot', 'base', 'jaw')."""
    c = {"robot": _rgb8(COLORS["robots"][i % len(COLORS["robots"])]), "base": _rgb8(COLORS["base"]),
         "jaw": _rgb8(COLORS["jaw"])}
    return np.array([c[x] for x in roles], dtype=np.uint8).reshape(-1, 3)


def _robot_colors(robot, i: int) -> np.ndarray:
    """(k, 3) uint8: the normal colour of each of robot i's boxes (as coopsim.view.Scene: base columns,
    jaws, links in the robot's colour)."""
    return _role_colors([_box_role(robot, b) for b in robot.boxes], i)


def _number(text, what: str) -> float:
    """A finite float from a number or the text of one; ValueError naming `what` otherwise."""
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number, got {text!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{what} must be finite, got {text!r}")
    return v


def _items(text) -> list:
    """The items of a text "a, b, c" (commas, semicolons or spaces between them) or of a sequence."""
    return [s for s in text.replace(";", ",").replace(" ", ",").split(",") if s] if isinstance(text, str) \
        else list(np.atleast_1d(text))


def _numbers(text, n: int, what: str) -> np.ndarray:
    """n finite floats from a text "a, b, c" (or a sequence); ValueError naming `what` otherwise."""
    items = _items(text)
    if len(items) != n:
        raise ValueError(f"{what} must be {n} numbers, got {len(items)} ({text!r})")
    return np.array([_number(s, f"{what}[{j}]") for j, s in enumerate(items)])


class Frame:
    """One consistent snapshot of the simulation (taken on its thread between chunks).

    t (s), steps; per robot q, qd, q_ref (n,), poses (k, 4, 4) and half (k, 3) of its boxes at q,
    parts (m, 4, 4) the world poses of its parts at q (coopsim.view.parts), ghost the poses of its boxes
    and ghost_parts those of its parts at q_ref,
    holding (bool), colliding (k,) bool; bodies: {name: pose (4, 4)} of the free bodies; lines (m, 2, 3)
    contact points and directions."""

    __slots__ = ("t", "steps", "q", "qd", "q_ref", "poses", "half", "parts", "ghost", "ghost_parts", "holding",
                 "colliding", "bodies", "lines")


class LiveView:
    """A live page of a :class:`coopsim.Simulation`; made by :func:`live` (see there for the options).

    Attributes: ``url``, ``host``, ``port``; ``pacer`` (the :class:`coopsim.Pacer` that runs it: its speed
    and pause are what the page sets); ``server`` (the ``viser.ViserServer``); ``message`` (the last message
    shown in the panel, e.g. a refused value); ``error`` (an exception that stopped the run, or None);
    ``frames`` (frames sent); ``frame`` (the last :class:`Frame`).
    """

    def __init__(self, sim, *, t_end: Optional[float] = None, speed: float = 1.0, frame_rate: float = 40.0,
                 host: str = _HOST, port: int = 0, start: bool = True, collision_boxes: bool = False,
                 contact_lines: bool = True, ghosts: bool = True, labels: bool = False, holding: str = "shared",
                 history: float = 5.0, move_time: float = 1.0, resettable: bool = True,
                 title: Optional[str] = None, quiet: bool = False):
        if not isinstance(sim, Simulation):
            raise ValueError(f"sim must be a coopsim.Simulation, got {type(sim).__name__}")
        if t_end is not None:
            t_end = _number(t_end, "t_end")
            if t_end < sim.time:
                raise ValueError(f"t_end must not be before the simulation's time {sim.time} s, got {t_end}")
        if not isinstance(host, str) or not host:
            raise ValueError(f"host must be a host name or address, got {host!r}")
        if not isinstance(port, (int, np.integer)) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise ValueError(f"port must be 0 (any free port) .. 65535, got {port!r}")
        self.history = _number(history, "history")
        if self.history <= 0:
            raise ValueError(f"history must be > 0 s, got {history!r}")
        self._move_time = self._check_move_time(move_time)
        holding_now(sim, mode=holding)      # checks the mode
        self._holding_mode = holding
        try:
            import viser  # the optional live extra: only for a live view
        except ImportError:
            raise ImportError("coopsim.view.live needs viser: pip install 'coopsim[live]' "
                              "(scripts/setup.sh installs it)") from None

        self.sim = sim
        self.pacer = Pacer(speed=speed, frame_rate=frame_rate)
        self.t_end = t_end
        self.resettable = bool(resettable)
        self.robots = sim.robots
        self.labels = robot_labels(self.robots)
        self._references0 = sim.references
        self._dt = sim.dt
        self._control_every = sim.control_every
        self._show = dict(collision_boxes=bool(collision_boxes), contact_lines=bool(contact_lines),
                          ghosts=bool(ghosts), labels=bool(labels))
        self._queue: "queue.Queue[Callable[[], None]]" = queue.Queue()
        self._lock = threading.Lock()
        self._reset_pending = False
        self._closing = False
        self._thread: Optional[threading.Thread] = None
        self._driving = threading.Lock()     # held by the thread that runs the simulation now
        self.error: Optional[BaseException] = None
        self._finished = threading.Event()
        self.stats: dict = {}
        self.message = ""
        self.frames = 0
        self.frame: Optional[Frame] = None
        self._changes = 0            # requests applied (a frame after one is drawn even if the time stands still)
        self._shown = None
        self._stats: deque = deque()
        self._hist: List[deque] = [deque() for _ in self.robots]
        self._last_plot = self._last_table = -math.inf
        self._plot_robot = 0
        self._table_robot = 0
        self._colors = [_robot_colors(r, i) for i, r in enumerate(self.robots)]
        self._parts = [robot_parts(r) for r in self.robots]      # the look (the boxes: on request)
        self._part_meshes: list = []
        self._ghost_meshes: list = []
        self._moving = [np.array([b.link != 0 for b in r.boxes], dtype=bool) for r in self.robots]
        self._world = sim.world
        self._free_names = [n for n in (self._world.body_names if self._world is not None else [])
                            if self._world.body(n)["kind"] == "free"]
        self._gizmos = {}

        self.server = viser.ViserServer(host=host, port=int(port), label=title or "coopsim", verbose=False)
        try:
            self.host, self.port = host, int(self.server.get_port())
            self._build_scene()
            self._build_panels()
            self._draw(self._snapshot())
        except BaseException:
            self.server.stop()
            raise
        if not quiet and not _in_notebook():
            print(f"coopsim live view: {self.url}", flush=True)
        if start:
            self.start(t_end)

    # ---- the page ----

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else ("[::1]" if self.host == "::" else self.host)
        return f"http://{host}:{self.port}"

    def show(self, height: int = 600):
        """In Jupyter, shows the live page in the cell (an IPython IFrame of :attr:`url`) and returns it;
        elsewhere prints the URL and returns it."""
        if _in_notebook():
            from IPython.display import IFrame, display  # only inside a notebook

            frame = IFrame(self.url, width="100%", height=int(height))
            display(frame)
            return frame
        print(f"coopsim live view: {self.url}", flush=True)
        return self.url

    def _repr_html_(self) -> str:
        return (f'<iframe src="{self.url}" width="100%" height="600" style="border:none"></iframe>'
                f'<p>coopsim live view: <a href="{self.url}" target="_blank">{self.url}</a></p>')

    def _build_scene(self) -> None:
        sc = self.server.scene
        world = self._world
        # everything in view: boxes of robots and world at the start, the floor under them
        pts = [self._corners(*r.shapes(self.sim.state(i)[0])) for i, r in enumerate(self.robots)]
        pts += [part_corners(p, part_poses(r, p, self.sim.state(i)[0])) for i, (r, p) in
                enumerate(zip(self.robots, self._parts)) if p]
        scenery = []
        if world is not None:
            for name in world.body_names:
                d = world.body(name)
                if d["kind"] == "static":
                    scenery.append((name, np.array(d["pose"]), np.array(d["half_extents"])))
                    pts.append(self._corners(np.array(d["pose"])[None], np.array(d["half_extents"])[None]))
                elif d["kind"] == "free":
                    pts.append(self._corners(np.array(self.sim.body_state(name)["pose"])[None],
                                             np.array(d["half_extents"])[None]))
        pts = np.concatenate(pts) if pts else np.zeros((1, 3))
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self._centre = 0.5 * (lo + hi)
        self._radius = max(0.3, float(np.linalg.norm(hi - lo)) / 2)
        self._azim = self._choose_azimuth(scenery)
        size = max(hi[0] - lo[0], hi[1] - lo[1]) + 0.6
        floor = world is None or world.floor
        # the environment's light at a little under half: the paper's colours stay recognisable
        sc.configure_environment_map("warehouse", environment_intensity=_ENVIRONMENT)
        if floor:
            sc.add_box("/floor", color=_rgb8(COLORS["floor"][0]), dimensions=(size, size, 0.01),
                       position=(self._centre[0], self._centre[1], -0.005), cast_shadow=False)
            sc.add_grid("/floor/grid", width=size, height=size, cell_size=0.1, section_size=0.5,
                        cell_color=_rgb8(COLORS["floor"][1]), position=(0.0, 0.0, 0.0051), shadow_opacity=0.0)
        for name, P, H in scenery:          # fixed: one box each, sent once
            sc.add_box(f"/scenery/{name}", color=_rgb8(COLORS["scenery"]), dimensions=2 * H,
                       wxyz=quaternions(P[:3, :3])[0], position=P[:3, 3])
        k = sum(len(r.boxes) for r in self.robots)
        half = np.concatenate([self.sim.robots[i].shapes(self.sim.state(i)[0])[1] for i in range(len(self.robots))]) \
            if self.robots else np.zeros((0, 3))
        self._half = half
        self._robot_mesh = None
        if k:
            self._robot_mesh = sc.add_batched_meshes_simple(
                "/robots", _CUBE_V, _CUBE_F, np.tile([1.0, 0, 0, 0], (k, 1)), np.zeros((k, 3)),
                batched_scales=2 * half, batched_colors=np.concatenate(self._colors), lod="off", flat_shading=True)
            self._robot_mesh.visible = self._show["collision_boxes"]
            self._build_parts()
        self._body_mesh = None
        if self._free_names:
            H = np.array([world.body(n)["half_extents"] for n in self._free_names])
            cols = np.array([_rgb8(COLORS["body"] if is_bar(n) else COLORS["free_body"]) for n in self._free_names])
            self._body_mesh = sc.add_batched_meshes_simple(
                "/bodies", _CUBE_V, _CUBE_F, np.tile([1.0, 0, 0, 0], (len(H), 1)), np.zeros((len(H), 3)),
                batched_scales=2 * H, batched_colors=cols, lod="off", flat_shading=True)
        self._lines = sc.add_line_segments("/contacts", np.zeros((1, 2, 3), dtype=np.float32),
                                           colors=_rgb8(COLORS["contact"]), thickness=4.0,
                                           thickness_units="screen", visible=False)
        self._label_nodes = []
        for i, r in enumerate(self.robots):
            p = r.base_position + np.array([0.0, 0.0, 0.05])
            self._label_nodes.append(sc.add_label(f"/labels/robot{i}", self.labels[i], position=p,
                                                  visible=self._show["labels"]))
        for n in self._free_names:
            self._label_nodes.append(sc.add_label(f"/labels/{n}", n, position=self.sim.body_state(n)["position"],
                                                  visible=self._show["labels"]))
        self._set_camera("perspective", initial=True)

    def _build_parts(self) -> None:
        """The robots' parts as batched meshes, one per shape (unit cube, unit cylinder, each mesh file), each
        instance a part scaled and placed every frame; shown unless the collision boxes are."""
        for m in self._part_meshes + self._ghost_meshes:
            m[0].remove()
        self._part_meshes = self._batched_parts("/parts", False)
        self._ghost_meshes = self._batched_parts("/ghosts", True)

    def _batched_parts(self, root: str, ghost: bool) -> list:
        """[(handle, part indices in the frame's concatenated parts, robot of each, colours, on a moving link)]
        of the parts grouped by shape; ghost: the moving links' parts only, _GHOST_MARGIN smaller, in the
        ghost's colour and transparency (a robot on its reference hides its ghost)."""
        groups: dict = {}
        flat = 0
        for i, parts in enumerate(self._parts):
            for p in parts:
                if not ghost or p.link != 0:
                    groups.setdefault((p.shape, p.mesh), []).append((i, flat, p))
                flat += 1
        out = []
        for (shape, mesh), members in groups.items():
            v, fc = UNIT_CUBE if shape == "box" else UNIT_CYLINDER if shape == "cylinder" else mesh_triangles(mesh)
            parts = [p for _, _, p in members]
            k = len(members)
            scales = np.array([p.scale for p in parts])
            if ghost:
                cols = np.tile(_rgb8(COLORS["ghost"]), (k, 1))
                if shape != "mesh":
                    scales = np.maximum(scales - 2 * _GHOST_MARGIN, 0.5 * scales)
                style = dict(opacity=float(COLORS["ghost_alpha"]), cast_shadow=False, receive_shadow=False,
                             visible=self._show["ghosts"])
            else:
                cols = np.concatenate([_role_colors([p.color], i) for i, _, p in members])
                style = dict(visible=not self._show["collision_boxes"])
            handle = self.server.scene.add_batched_meshes_simple(
                f"{root}/{len(out)}", v, fc, np.tile([1.0, 0, 0, 0], (k, 1)), np.zeros((k, 3)),
                batched_scales=scales, batched_colors=cols, lod="off", flat_shading=shape == "box",
                side="double" if shape == "mesh" else "front", **style)
            moving = np.array([p.link != 0 for p in parts])
            out.append((handle, np.array([x[1] for x in members]), np.array([x[0] for x in members]), cols, moving))
        return out

    def _choose_azimuth(self, scenery) -> float:
        """The default camera's azimuth (degrees), chosen as coopsim.view.Scene chooses it: robots, scenery and
        bodies seen past each other (Scene.choose_azimuth, on a figure never drawn)."""
        from matplotlib.figure import Figure

        ax = Figure().add_subplot(projection="3d")
        frame = [(True, *r.shapes(self.sim.state(i)[0]), False) for i, r in enumerate(self.robots)]
        frame += [(False, P[None], H[None], True) for _, P, H in scenery]
        frame += [(False, np.asarray(self.sim.body_state(n)["pose"])[None],
                   np.asarray(self._world.body(n)["half_extents"])[None], False) for n in self._free_names]
        return Scene(ax, self.robots).choose_azimuth([frame])

    @staticmethod
    def _corners(poses, half):
        return box_corners(poses, half).reshape(-1, 3)

    def _split(self, rows) -> list:
        """A (sum k_i, ...) array cut into one part per robot."""
        ks = np.cumsum([len(r.boxes) for r in self.robots])[:-1]
        return np.split(rows, ks)

    def _set_camera(self, view: str, initial: bool = False) -> None:
        c, r = self._centre, self._radius
        if view == "top":
            pos, up = c + r * np.array([0.0, -0.3, 2.6]), (0.0, 0.0, 1.0)
        elif view == "side":
            pos, up = c + r * np.array([0.0, -2.4, 0.3]), (0.0, 0.0, 1.0)
        else:
            pos, up = c + 2.1 * r * view_direction(DEFAULT_ELEV + 8.0, self._azim), (0.0, 0.0, 1.0)
        if initial:
            self.server.initial_camera.position = tuple(pos)
            self.server.initial_camera.look_at = tuple(c)
            return
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.up_direction = up
                client.camera.position = tuple(pos)
                client.camera.look_at = tuple(c)

    def _build_panels(self) -> None:
        gui = self.server.gui
        # the panel docked beside the scene (not over it); no share button: the page never leaves this host
        gui.configure_theme(control_width="medium", show_share_button=False)
        gui.main_panel.dock_right()
        self._msg = gui.add_markdown("", order=0)
        tabs = gui.add_tab_group(order=1)
        n = len(self.robots)
        names = tuple(f"{i}: {lab}" for i, lab in enumerate(self.labels)) or ("none",)

        with tabs.add_tab("Run"):
            self._speed = gui.add_slider("Speed (%)", min=0, max=400, step=1,
                                         initial_value=round(self.pacer.speed_percent))
            self._speed.on_update(lambda e: self.set_speed_percent(e.target.value))
            pause, resume = gui.add_button("Pause"), gui.add_button("Resume")
            pause.on_click(lambda e: self.pause())
            resume.on_click(lambda e: self.resume())
            step = gui.add_button("One step")
            step.on_click(lambda e: self.one_step())
            reset = gui.add_button("Reset to start", disabled=not self.resettable)
            reset.on_click(lambda e: self.reset())
            self._time = gui.add_markdown("")

        with tabs.add_tab("Display"):
            for key, label in (("collision_boxes", "Collision boxes"), ("contact_lines", "Contact lines"),
                               ("ghosts", "Ghosts"), ("labels", "Labels")):
                box = gui.add_checkbox(label, initial_value=self._show[key])
                box.on_update(lambda e, key=key: self.set_display(key, e.target.value))
            cam = gui.add_button_group("Camera", ("Top", "Side", "Perspective"))
            cam.on_click(lambda e: self._set_camera(e.target.value.lower()))

        self._teach = []
        self._controller_md = []
        self._dimensions_md = []
        with tabs.add_tab("Robots"):
            for i, r in enumerate(self.robots):
                with gui.add_folder(f"{i}: {self.labels[i]}", expand_by_default=(i == 0)):
                    self._controller_md.append(gui.add_markdown(self._controller_text(i)))
                    fields = {name: gui.add_text(label, initial_value=self._gain_text(i, name))
                              for name, label in self._gain_labels(i)}
                    if fields:
                        apply = gui.add_button("Set gains")
                        apply.on_click(lambda e, i=i, fields=fields: self.set_gains(
                            i, **{name: f.value for name, f in fields.items()}))
                    sliders = []
                    q_ref = self.sim.references[i].evaluate(self.sim.time)[0]
                    for j in range(r.dof):
                        lo, hi = (float(x) for x in r.q_limits[j])
                        unit = "rad" if r.joint_types[j] == "R" else "m"
                        s = gui.add_slider(f"q{j + 1} ({unit})", min=lo, max=hi, step=(hi - lo) / 1000,
                                           initial_value=float(np.clip(q_ref[j], lo, hi)))
                        s.on_update(lambda e, i=i: self.teach_joints(i, [x.value for x in self._teach[i][0]],
                                                                     client=e.client))
                        sliders.append(s)
                    target = gui.add_text("Joint target", initial_value=", ".join(f"{x:.4g}" for x in q_ref))
                    go = gui.add_button("Move to joint target")
                    go.on_click(lambda e, i=i, target=target: self.teach_joints(i, target.value, client=e.client))
                    move = gui.add_text("Move time (s)", initial_value=f"{self._move_time:g}")
                    move.on_update(lambda e: self._refusing(lambda: self.set_move_time(e.target.value)))
                    giz = gui.add_checkbox("Clamp gizmo (IK)", initial_value=False)
                    giz.on_update(lambda e, i=i: self._toggle_gizmo(i, e.target.value))
                    self._dimensions_md.append(gui.add_markdown(self._dimensions_text(i)))
                    if self._factory(i) is not None:
                        dims = {key: gui.add_text(label, initial_value=repr(float(r.dimensions[key])))
                                for key, label in _DIMENSION_FIELDS}
                        rebuild = gui.add_button("Set dimensions")
                        rebuild.on_click(lambda e, i=i, dims=dims: self.set_dimensions(
                            i, **{key: f.value for key, f in dims.items()}))
                    self._teach.append((sliders, target))

        with tabs.add_tab("Plots"):
            if n:
                pick = gui.add_dropdown("Robot", names, initial_value=names[0])
                pick.on_update(lambda e: self._pick_plot(names.index(e.target.value)))
                self._plot_q, self._plot_e = self._make_plots(0)
            else:
                self._plot_q = self._plot_e = None
        with tabs.add_tab("Data"):
            if n:
                pick = gui.add_dropdown("Robot", names, initial_value=names[0])
                pick.on_update(lambda e: self._pick_table(names.index(e.target.value)))
            self._table = gui.add_markdown("")
            csv_btn, xls_btn = gui.add_button("Download CSV"), gui.add_button("Download Excel")
            csv_btn.on_click(lambda e: self.download("csv", e.client))
            xls_btn.on_click(lambda e: self.download("xlsx", e.client))

    def _controller_text(self, i: int) -> str:
        c = self.sim.controllers[i]
        fmt = lambda a: ", ".join(f"{x:.4g}" for x in np.atleast_1d(a))      # noqa: E731
        if isinstance(c, PID):
            body = f"PID: kp [{fmt(c.kp)}], ki [{fmt(c.ki)}], kd [{fmt(c.kd)}]"
        elif isinstance(c, ComputedTorque):
            body = f"Computed torque: kp [{fmt(c.kp)}] 1/s², kd [{fmt(c.kd)}] 1/s"
        else:
            return f"**Controller** {type(c).__name__} (a Python controller: its gains are its own)"
        return f"**Controller** {body}  \n_(gains: 1 or {self.robots[i].dof} values, from the next control step)_"

    def _gain_labels(self, i: int) -> tuple:
        """(gain name, field label) of robot i's controller: PID kp, ki, kd; ComputedTorque kp, kd; else none."""
        c = self.sim.controllers[i]
        if isinstance(c, PID):
            return (("kp", "kp"), ("ki", "ki"), ("kd", "kd"))
        if isinstance(c, ComputedTorque):
            return (("kp", "kp (1/s²)"), ("kd", "kd (1/s)"))
        return ()

    def _gain_text(self, i: int, name: str) -> str:
        """Robot i's gain `name` as a field's text: the shortest that reads back as the same floats (a field
        set unchanged gives the same gain)."""
        return ", ".join(repr(float(x)) for x in np.atleast_1d(getattr(self.sim.controllers[i], name)))

    def set_gains(self, i: int, **gains) -> None:
        """Replaces robot i's controller by one of the same kind with the given gains (kp, ki, kd for a PID;
        kp, kd for a ComputedTorque; each numbers or a text "a, b, ...", 1 or n values; the gains not given
        and the other settings kept), through ``Simulation.set_controller`` on the simulation's thread: it
        acts from the next control step, a PID's integral restarting at zero. Refused with a message: text,
        NaN, a negative gain, a wrong count (the constructor's and set_controller's checks)."""
        try:
            i = self._robot_index(i)
            allowed = [name for name, _ in self._gain_labels(i)]
            if not allowed:
                raise ValueError(f"{self.labels[i]}'s controller is a Python controller: its gains are its own")
            values = {}
            for name, text in gains.items():
                if name not in allowed:
                    raise ValueError(f"gain must be one of {allowed} for {self.labels[i]}, got {name!r}")
                items = _items(text)
                if not items:
                    raise ValueError(f"{name} of {self.labels[i]} must be 1 or {self.robots[i].dof} numbers, got none")
                values[name] = np.array([_number(t, f"{name}[{j}] of {self.labels[i]}") for j, t in enumerate(items)])
        except ValueError as e:
            self._say(f"Refused: {e}")
            return

        def go():
            c = self.sim.controllers[i]
            g = {name: values.get(name, getattr(c, name)) for name in allowed}
            if isinstance(c, PID):
                new = PID(g["kp"], g["ki"], g["kd"], gravity_compensation=c.gravity_compensation,
                          derivative_filter=c.derivative_filter, integral_limit=c.integral_limit, model=c.model)
            else:
                new = ComputedTorque(g["kp"], g["kd"], model=c.model)
            self.sim.set_controller(i, new)
            self._controller_md[i].content = self._controller_text(i)
            self._say(f"{self.labels[i]}: new gains " + "; ".join(f"{k} [{self._gain_text(i, k)}]" for k in g))
        self.submit(go)

    def _dimensions_text(self, i: int) -> str:
        dims = self.robots[i].dimensions
        if not dims:
            return "**Dimensions**: none recorded"
        rows = ", ".join(f"{k} {v:.4g} m" for k, v in dims.items())
        if self._factory(i) is None:
            return f"**Dimensions** {rows}  \n_(not a built-in SCARA: fixed here)_"
        return f"**Dimensions** {rows}  \n_(L1, L2, base height: the robot rebuilt, the run going on)_"

    def _factory(self, i: int):
        """The function of coopsim.robots that made robot i (scara1, scara2: known by its name, its joints and
        its recorded dimensions), or None."""
        r = self.robots[i]
        make = {"scara1": scara1, "scara2": scara2}.get(r.name)
        if make is None or not r.dimensions or set(r.dimensions) != set(make().dimensions) or \
                r.joint_types != make().joint_types:
            return None
        return make

    def set_dimensions(self, i: int, **dims) -> None:
        """Rebuilds robot i (a built-in SCARA) with other dimensions (m; e.g. L1, L2, L_base; numbers or texts)
        by its maker (``cs.robots.scara1``/``scara2``: the other dimensions, base pose, friction, gravity and
        backend kept, each link's mass scaled by its box's volume as the maker does), and replaces it through
        ``Simulation.set_robot`` on the simulation's thread: the run goes on from the same q and qd. Refused
        with a message: text, NaN, a dimension <= 0 or unknown, a robot not made by coopsim.robots, a start
        that puts a box beyond the world (the maker's and set_robot's checks)."""
        try:
            i = self._robot_index(i)
            make = self._factory(i)
            if make is None:
                raise ValueError(f"{self.labels[i]} is not a built-in SCARA: its dimensions are fixed here")
            r = self.robots[i]
            new_dims = dict(r.dimensions)
            for key, text in dims.items():
                if key not in new_dims:
                    raise ValueError(f"dimension must be one of {sorted(new_dims)}, got {key!r}")
                new_dims[key] = _number(text, f"{key} of {self.labels[i]}")
            keep = dict(base_position=r.base_position, base_yaw=r.base_yaw, friction=r.friction_coefficients,
                        gravity=r.gravity_acceleration, backend=r.backend)
            # the masses as they are (given or the maker's), scaled by each box's volume as the maker scales them
            scale = make(**new_dims).masses / make(**r.dimensions).masses
            new = make(masses=r.masses * scale, **keep, **new_dims)
        except ValueError as e:
            self._say(f"Refused: {e}")
            return

        def go():
            self.sim.set_robot(i, new)
            self.robots[i] = self.sim.robots[i]
            self._rescale()
            self._dimensions_md[i].content = self._dimensions_text(i)
            self._say(f"{self.labels[i]}: rebuilt with " + ", ".join(f"{k} {float(v):.4g} m" for k, v in dims.items()))
        self.submit(go)

    def _rescale(self) -> None:
        """The robots' drawn boxes and parts at their sizes now (after a robot was replaced)."""
        self._half = np.concatenate([r.shapes(self.sim.state(i)[0])[1] for i, r in enumerate(self.robots)])
        if self._robot_mesh is not None:
            self._robot_mesh.batched_scales = 2 * self._half
            self._parts = [robot_parts(r) for r in self.robots]
            self._build_parts()

    def _make_plots(self, i: int):
        import viser.uplot as up  # the optional live extra

        r = self.robots[i]
        palette = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]
        x = np.zeros(2)
        series_q = [up.Series(label="t (s)")]
        for j in range(r.dof):
            c = palette[j % len(palette)]
            series_q += [up.Series(label=f"q{j + 1}", stroke=c, width=1.5, points={"show": False}),
                         up.Series(label=f"ref{j + 1}", stroke=c, width=1, dash=[4, 4], points={"show": False})]
        series_e = [up.Series(label="t (s)")] + [up.Series(label=f"e{j + 1}", stroke=palette[j % len(palette)],
                                                           width=1.5, points={"show": False}) for j in range(r.dof)]
        gui = self.server.gui
        scales = {"x": {"time": False}}
        pq = gui.add_uplot((x,) + (x,) * (2 * r.dof), tuple(series_q), title=f"{self.labels[i]}: q and q_ref",
                           scales=scales, aspect=1.4)
        pe = gui.add_uplot((x,) + (x,) * r.dof, tuple(series_e), title=f"{self.labels[i]}: error q_ref - q",
                           scales=scales, aspect=1.4)
        return pq, pe

    def _pick_table(self, i: int) -> None:
        self._table_robot = i
        self._last_table = -math.inf
        self._changes += 1

    def _pick_plot(self, i: int) -> None:
        with self._lock:
            self._plot_robot = i
            self._plot_q.remove()
            self._plot_e.remove()
            self._plot_q, self._plot_e = self._make_plots(i)
            self._last_plot = -math.inf
            self._changes += 1

    # ---- requests from the page (or from Python): queued, applied by the simulation's thread ----

    def submit(self, fn: Callable[[], None]) -> None:
        """Queues fn() to run on the simulation's thread between chunks (a ValueError it raises is
        refused with a message in the panel)."""
        self._queue.put(fn)

    def call(self, fn: Callable, timeout: Optional[float] = 60.0):
        """fn() run on the simulation's thread between chunks (at once when nothing runs it); returns its
        value or raises its exception. For reading a running simulation consistently from another thread."""
        done = threading.Event()
        out = {}

        def go():
            try:
                out["value"] = fn()
            except BaseException as e:      # handed to the caller, not refused
                out["error"] = e
            done.set()
        if self._driving.acquire(blocking=False):      # nobody runs the simulation now
            try:
                go()
            finally:
                self._driving.release()
        else:
            self.submit(go)
            if not done.wait(timeout):
                raise TimeoutError(f"the simulation's thread did not answer in {timeout} s")
        if "error" in out:
            raise out["error"]
        return out.get("value")

    def _refusing(self, fn: Callable[[], None]) -> None:
        try:
            fn()
        except ValueError as e:
            self._say(f"Refused: {e}")

    def _say(self, text: str) -> None:
        self.message = text
        self._msg.content = f"**{text}**" if text else ""

    def set_speed_percent(self, value) -> None:
        """Sets the pacer's speed (0 .. 400 %), as the page's slider."""
        self.submit(lambda: setattr(self.pacer, "speed_percent", value))

    def pause(self) -> None:
        self.submit(self.pacer.pause)

    def resume(self) -> None:
        self.submit(self.pacer.resume)

    def one_step(self) -> None:
        """Pauses and advances one control period (control_every steps)."""
        def go():
            self.pacer.pause()
            self.sim.step(self._control_every)
        self.submit(go)

    def reset(self) -> None:
        """Back to t = 0, the initial states and the references the simulation had when the view was made."""
        if not self.resettable:
            self._say("Refused: this run is sequenced from Python and cannot go back to its start")
            return
        with self._lock:
            self._reset_pending = True

    def set_display(self, what: str, on: bool) -> None:
        if what not in self._show:
            raise ValueError(f"what must be one of {sorted(self._show)}, got {what!r}")
        self._show[what] = bool(on)
        if what == "ghosts" and self._robot_mesh is not None:
            for m in self._ghost_meshes:
                m[0].visible = bool(on)
        if what == "collision_boxes" and self._robot_mesh is not None:
            self._robot_mesh.visible = bool(on)
            for m in self._part_meshes:
                m[0].visible = not on
        if what == "labels":
            for node in self._label_nodes:
                node.visible = bool(on)

    @staticmethod
    def _check_move_time(value) -> float:
        v = _number(value, "move time")
        if not 0 < v <= 60:
            raise ValueError(f"move time must be in (0, 60] s, got {value!r}")
        return v

    def set_move_time(self, value) -> None:
        """Duration (s) of the cubic of a teach move."""
        self._move_time = self._check_move_time(value)

    def teach_joints(self, i: int, q, client=None) -> None:
        """Moves robot i to joint positions q (n,) (numbers or a text "a, b, ..."): a cubic from where it is
        (its q and qd now) to q, at rest there after the move time, as its new reference. Refused with a
        message: a wrong count, text, NaN, a value beyond the joint limits."""
        try:
            i = self._robot_index(i)
            r = self.robots[i]
            target = _numbers(q, r.dof, f"joint target of {self.labels[i]}")
            lo, hi = r.q_limits[:, 0], r.q_limits[:, 1]
            bad = np.flatnonzero((target < lo) | (target > hi))
            if len(bad):
                j = bad[0]
                raise ValueError(f"joint target of {self.labels[i]}: q{j + 1} = {target[j]:.6g} is beyond its "
                                 f"limits [{lo[j]:.6g}, {hi[j]:.6g}]")
        except ValueError as e:
            self._say(f"Refused: {e}")
            return
        self.submit(lambda: self._move(i, target))

    def teach_pose(self, i: int, pose) -> None:
        """Moves robot i's clamp to `pose` (4, 4) in the world: closed-form IK (``robot.ik``, nearest the
        robot's q now, its jaw opening kept), then a cubic to it as for :meth:`teach_joints`. An
        unreachable pose is refused with the IK's message. The gizmo's drag ends here."""
        try:
            i = self._robot_index(i)
            T = np.asarray(pose, dtype=float)
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                raise ValueError(f"pose must be a finite (4, 4) matrix, got shape {T.shape}")
        except (ValueError, TypeError) as e:
            self._say(f"Refused: {e}")
            return

        def go():
            q_now = self.sim.state(i)[0]
            q = self.robots[i].ik(T, q_near=q_now)
            self._move(i, q)
        self.submit(go)

    def _robot_index(self, i) -> int:
        n = len(self.robots)
        if not isinstance(i, (int, np.integer)) or isinstance(i, bool) or not 0 <= i < n:
            raise ValueError(f"robot must be an index in [0, {n}), got {i!r}")
        return int(i)

    def _move(self, i: int, target: np.ndarray) -> None:
        """On the simulation's thread: robot i's new reference, a cubic from its state now to target."""
        q, qd = self.sim.state(i)
        t = self.sim.time
        ref = CubicTrajectory([t, t + self._move_time], np.vstack([q, target]),
                              np.vstack([qd, np.zeros_like(qd)]))
        self.sim.set_reference(i, ref)
        self._say(f"{self.labels[i]}: moving to [{', '.join(f'{x:.4g}' for x in target)}] "
                  f"in {self._move_time:g} s")

    def _toggle_gizmo(self, i: int, on: bool) -> None:
        if not on:
            g = self._gizmos.pop(i, None)
            if g is not None:
                g.remove()
            return
        T = np.asarray(self.robots[i].fk(self.frame.q[i]))      # the clamp where the last frame showed it
        g = self.server.scene.add_transform_controls(f"/gizmo{i}", scale=0.15, wxyz=quaternions(T[:3, :3])[0],
                                                     position=T[:3, 3], depth_test=False)

        def moved(e, i=i):
            if e.phase == "end":
                self.teach_pose(i, self.gizmo_pose(i))
        g.on_update(moved)
        self._gizmos[i] = g

    def gizmo_pose(self, i: int) -> np.ndarray:
        """The pose (4, 4) of robot i's clamp gizmo now."""
        g = self._gizmos[i]
        T = np.eye(4)
        T[:3, :3] = _rotation(g.wxyz)
        T[:3, 3] = g.position
        return T

    def download(self, kind: str, client=None) -> None:
        """Sends the log as 'csv' or 'xlsx' to the page that asked (every page if client is None). The
        log is taken on the simulation's thread (its arrays are views later steps do not change) and
        written on another thread, so the run goes on meanwhile."""
        if kind not in ("csv", "xlsx"):
            raise ValueError(f"kind must be 'csv' or 'xlsx', got {kind!r}")

        def take():
            log = self.sim.log
            threading.Thread(target=self._send_log, args=(log, kind, client), daemon=True).start()
        self.submit(take)

    def _send_log(self, log, kind, client) -> None:
        try:
            with tempfile.TemporaryDirectory() as d:
                path = os.path.join(d, f"coopsim_log.{kind}")
                (log.to_csv if kind == "csv" else log.to_excel)(path)
                with open(path, "rb") as f:
                    data = f.read()
            target = client if client is not None else self.server
            target.send_file_download(f"coopsim_log.{kind}", data, save_immediately=True)
            self._say(f"Log sent as {kind.upper()}: {len(log.t)} rows")
        except ValueError as e:
            self._say(f"Refused: {e}")

    # ---- running: one thread changes the simulation ----

    def start(self, t_end: Optional[float] = None) -> None:
        """Runs the simulation paced in a thread of the view up to t_end (s; default the view's, else until
        closed), then keeps serving the page (and its requests) until :meth:`close`."""
        if self._thread is not None and self._thread.is_alive():
            raise RuntimeError("the live view is already running its simulation")
        t_end = self.t_end if t_end is None else _number(t_end, "t_end")
        self._thread = threading.Thread(target=self._loop, args=(_FOREVER if t_end is None else t_end,),
                                        name="coopsim-live", daemon=True)
        self._thread.start()

    def run_to(self, t_end: float) -> None:
        """Runs the simulation paced up to t_end (s) in the calling thread (the simulation's thread), with
        the page live; returns at t_end, or at once if the page closed the view. For a run sequenced from
        Python (e.g. a task that plans phase by phase). An exception of the run shows in the panel and
        propagates."""
        t_end = _number(t_end, "t_end")
        if self._thread is not None and self._thread.is_alive():
            raise RuntimeError("the live view runs its simulation in its own thread (start()); use wait()")
        with self._driving:
            while not self._closing and self.sim.time < t_end - 0.5 * self._dt:
                try:
                    self.pacer.run(self.sim, t_end, on_frame=self._on_frame, keep_clock=True)
                except BaseException as e:
                    self._failed(e)
                    raise
                if self._reset_pending:
                    self._do_reset()

    def wait(self, timeout: Optional[float] = None) -> bool:
        """Waits until the view's run reaches its t_end (or timeout s); re-raises the exception that
        stopped it. Returns True when the run is over."""
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            if self.error is not None:
                raise self.error
            if self._finished.is_set():
                return True
            if end is not None and time.monotonic() >= end:
                return False
            time.sleep(0.02)

    def _loop(self, t_end: float) -> None:
        with self._driving:
            while not self._closing:
                if self._reset_pending:
                    self._do_reset()
                    self._finished.clear()
                if self.error is None and self.sim.time < t_end - 0.5 * self._dt:
                    try:
                        self.pacer.run(self.sim, t_end, on_frame=self._on_frame)
                    except BaseException as e:
                        self._failed(e)
                else:
                    if self.sim.time >= t_end - 0.5 * self._dt:
                        self._finished.set()
                    try:
                        self._on_frame(self.sim, self.pacer)
                    except BaseException as e:
                        self._failed(e)
                        return
                    time.sleep(1.0 / self.pacer.frame_rate)

    def _failed(self, e: BaseException) -> None:
        self.error = e
        try:
            self._say(f"Run stopped: {type(e).__name__}: {e}")
        except Exception:      # pragma: no cover - the server may be gone
            pass

    def _do_reset(self) -> None:
        with self._lock:
            self._reset_pending = False
        self.sim.reset()
        for i, ref in enumerate(self._references0):
            self.sim.set_reference(i, ref)
        self.error = None
        self._changes += 1
        for h in self._hist:
            h.clear()
        self._stats.clear()
        self._say("Reset to the start")

    def _on_frame(self, sim, pacer):
        """The pacer's frame hook, on the simulation's thread: apply the page's requests, then draw."""
        while True:
            try:
                fn = self._queue.get_nowait()
            except queue.Empty:
                break
            self._changes += 1
            try:
                fn()
            except ValueError as e:          # IKError is a ValueError
                self._say(f"Refused: {e}")
        if self._closing or self._reset_pending:
            return False
        self._draw(self._snapshot())
        return None

    def _snapshot(self) -> Frame:
        sim = self.sim
        f = Frame()
        f.t, f.steps = sim.time, sim.steps
        f.q, f.qd, f.q_ref, f.poses, f.half, f.ghost, f.parts, f.ghost_parts = [], [], [], [], [], [], [], []
        refs = sim.references
        for i, r in enumerate(self.robots):
            q, qd = sim.state(i)
            q_ref = refs[i].evaluate(f.t)[0]
            P, H = r.shapes(np.vstack([q, q_ref]))       # one engine call: the boxes at q and at q_ref
            f.q.append(q)
            f.qd.append(qd)
            f.q_ref.append(q_ref)
            f.poses.append(P[0])
            f.ghost.append(P[1])
            f.half.append(H)
            f.parts.append(part_poses(r, self._parts[i], q))
            f.ghost_parts.append(part_poses(r, self._parts[i], q_ref))
        f.holding = holding_now(sim, mode=self._holding_mode) if self.robots else []
        f.bodies = {n: np.asarray(sim.body_state(n)["pose"]) for n in self._free_names}
        need = self._world is not None and (self._show["collision_boxes"] or self._show["contact_lines"])
        contacts = sim.contacts() if need else []
        f.colliding = colliding_from_contacts(contacts, self.robots, self.labels)
        f.lines = contact_lines(contacts)
        return f

    def _robot_colours(self, f: Frame) -> np.ndarray:
        cols = []
        ok, bad, hold = _rgb8(COLORS["free"]), _rgb8(COLORS["colliding"]), _rgb8(COLORS["holding"])
        for i in range(len(self.robots)):
            if self._show["collision_boxes"]:
                c = np.where(f.colliding[i][:, None], bad, ok)
            else:
                c = self._colors[i].copy()
                if f.holding[i]:
                    c[self._moving[i]] = hold
            cols.append(c)
        return np.concatenate(cols).astype(np.uint8)

    def _draw(self, f: Frame) -> None:
        now = time.perf_counter()
        # nothing new to show (paused, or past the end): the scene is left as it is, the panels go on
        key = (f.steps, self._changes, tuple(self._show.values()))
        same, self._shown = key == self._shown, key
        with self._lock, self.server.atomic():
            if not same:
                self._draw_scene(f)
            self._supervise(f, now)
            if not same:
                self._plots(f, now)
            if now - self._last_table >= _TABLE_EVERY:
                self._last_table = now
                self._table.content = self._table_text()
        self.frame = f
        self.frames += 1

    def _draw_scene(self, f: Frame) -> None:
        # the collision boxes while they are shown (and in the first frame), else the parts
        if self._robot_mesh is not None and (self._show["collision_boxes"] or self.frame is None):
            P = np.concatenate(f.poses)
            self._robot_mesh.batched_positions = P[:, :3, 3]
            self._robot_mesh.batched_wxyzs = quaternions(P[:, :3, :3])
            cols = self._robot_colours(f)
            if self.frame is None or not np.array_equal(cols, self._robot_mesh.batched_colors):
                self._robot_mesh.batched_colors = cols
        if self._robot_mesh is not None and (not self._show["collision_boxes"] or self.frame is None):
            hold = _rgb8(COLORS["holding"])
            every = np.concatenate(f.parts)
            holding = np.array(f.holding, dtype=bool)
            for handle, index, robot, cols, moving in self._part_meshes:
                P = every[index]
                handle.batched_positions = P[:, :3, 3]
                handle.batched_wxyzs = quaternions(P[:, :3, :3])
                c = cols.copy()
                c[holding[robot] & moving] = hold
                if self.frame is None or not np.array_equal(c, handle.batched_colors):
                    handle.batched_colors = c
        if self._robot_mesh is not None:
            if self._show["ghosts"]:
                every = np.concatenate(f.ghost_parts)
                for handle, index, *_ in self._ghost_meshes:
                    G = every[index]
                    handle.batched_positions = G[:, :3, 3]
                    handle.batched_wxyzs = quaternions(G[:, :3, :3])
        if self._body_mesh is not None:
            B = np.array([f.bodies[n] for n in self._free_names])
            self._body_mesh.batched_positions = B[:, :3, 3]
            self._body_mesh.batched_wxyzs = quaternions(B[:, :3, :3])
            if self._show["labels"]:
                for node, n in zip(self._label_nodes[len(self.robots):], self._free_names):
                    node.position = B[self._free_names.index(n), :3, 3] + np.array([0, 0, 0.05])
        show_lines = self._show["contact_lines"] and len(f.lines) > 0
        if show_lines:
            seg = np.stack([f.lines[:, 0], f.lines[:, 0] + _CONTACT_LENGTH * f.lines[:, 1]], axis=1)
            self._lines.points = seg.astype(np.float32)
        if self._lines.visible != show_lines:
            self._lines.visible = show_lines

    def _supervise(self, f: Frame, now: float) -> None:
        st = self.pacer.stats
        busy, steps = (st.busy_time, st.steps) if st is not None else (0.0, 0)
        self._stats.append((now, f.t, busy, steps))
        while len(self._stats) > 2 and now - self._stats[0][0] > _WINDOW:
            self._stats.popleft()
        s = list(self._stats)
        wall = s[-1][0] - s[0][0]
        fps = (len(s) - 1) / wall if wall > 0 else 0.0
        achieved = (s[-1][1] - s[0][1]) / wall if wall > 0 else 0.0
        per = [(b1 - b0) / (n1 - n0) for (_, _, b0, n0), (_, _, b1, n1) in zip(s, s[1:]) if n1 > n0]
        dn = sum(n1 - n0 for (_, _, _, n0), (_, _, _, n1) in zip(s, s[1:]) if n1 > n0)
        db = sum(b1 - b0 for (_, _, b0, n0), (_, _, b1, n1) in zip(s, s[1:]) if n1 > n0)
        mean = db / dn if dn else float("nan")
        top = max(per) if per else float("nan")
        wall_total = st.wall_time if st is not None else 0.0
        state = "paused" if self.pacer.paused else "running"
        self._time.content = (
            f"| | |\n|---|---|\n| Simulated time | {f.t:.4f} s |\n| Wall time (this run) | {wall_total:.2f} s |\n"
            f"| Speed set | {self.pacer.speed_percent:.0f} % ({state}) |\n| Speed achieved | {100 * achieved:.0f} % |\n"
            f"| Step size | {self._dt * 1e3:.4g} ms |\n"
            f"| Step time mean / max | {mean * 1e6:.2f} / {top * 1e6:.2f} µs |\n"
            f"| Frames per second | {fps:.1f} |\n| Steps | {f.steps} |")
        self.stats = dict(t=f.t, wall=wall_total, speed_set=self.pacer.speed_percent, speed_achieved=100 * achieved,
                          step_mean=mean, step_max=top, fps=fps, steps=f.steps)

    def _plots(self, f: Frame, now: float) -> None:
        for i, h in enumerate(self._hist):
            h.append((f.t, f.q[i], f.q_ref[i]))
            while h and h[0][0] < f.t - self.history:
                h.popleft()
        if self._plot_q is not None and now - self._last_plot >= _PLOT_EVERY and self._hist[self._plot_robot]:
            self._last_plot = now
            h = self._hist[self._plot_robot]
            t = np.array([x[0] for x in h])
            q = np.array([x[1] for x in h])
            qr = np.array([x[2] for x in h])
            cols = [t]
            for j in range(q.shape[1]):
                cols += [q[:, j], qr[:, j]]
            self._plot_q.data = tuple(cols)
            self._plot_e.data = (t,) + tuple((qr - q).T)

    def _table_text(self) -> str:
        if not self.robots or self.sim.log_every == 0:
            return "_no log (log_every = 0)_" if self.robots else ""
        log = self.sim.log
        rows = len(log.t)
        if rows == 0:
            return "_the log is empty_"
        i = self._table_robot
        rl = log.robots[i]
        lo = max(0, rows - _TABLE_ROWS)
        head = "| t (s) | " + " | ".join(f"q{j + 1}" for j in range(rl.dof)) + " |"
        sep = "|---" * (rl.dof + 1) + "|"
        body = "\n".join(f"| {log.t[k]:.4f} | " + " | ".join(f"{x:.3f}" for x in rl.q[k]) + " |"
                         for k in range(lo, rows))
        return f"{self.labels[i]}, last {rows - lo} of {rows} rows ({len(log.columns())} columns)\n\n" \
               f"{head}\n{sep}\n{body}"

    def hold(self, seconds: Optional[float] = None) -> None:
        """Keeps serving the page for `seconds` (None: until Ctrl-C when run from a terminal, else not at all),
        then closes the view. For a script whose run is over but whose page should stay."""
        if seconds is None:
            seconds = math.inf if sys.stdout.isatty() else 0.0
        try:
            if seconds > 0:
                print(f"the live page stays at {self.url}: Ctrl-C to stop", flush=True)
                end = time.monotonic() + seconds
                while time.monotonic() < end and self.server is not None:
                    time.sleep(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    # ---- closing ----

    def close(self) -> None:
        """Stops the run (between chunks) and the server, and frees the port."""
        if self._closing and self.server is None:
            return
        self._closing = True
        self.pacer.stop()
        th = self._thread
        if th is not None and th is not threading.current_thread():
            th.join(timeout=30)
        with self._driving:         # a run_to in progress ends at its next frame
            pass
        if self.server is not None:
            self.server.stop()
            self.server = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self) -> str:
        return f"<coopsim.view.LiveView {self.url} t={self.sim.time:.4g} s, {self.frames} frames>"


def _in_notebook() -> bool:
    ip = sys.modules.get("IPython")
    if ip is None:
        return False
    try:
        shell = ip.get_ipython()
    except Exception:      # pragma: no cover
        return False
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"


def live(sim, *, t_end: Optional[float] = None, speed: float = 1.0, frame_rate: float = 40.0, host: str = _HOST,
         port: int = 0, start: bool = True, collision_boxes: bool = False, contact_lines: bool = True,
         ghosts: bool = True, labels: bool = False, holding: str = "shared", history: float = 5.0,
         move_time: float = 1.0, resettable: bool = True, title: Optional[str] = None,
         quiet: bool = False) -> LiveView:
    """A live view of `sim` (any :class:`coopsim.Simulation`: one or several robots, with or without a
    world) in the browser; returns the :class:`LiveView`.

    t_end: simulated time (s) the run goes to (None: until closed; the log grows meanwhile). speed: 0 .. 4
    (400 %). frame_rate: frames per second (Hz) the view aims at (the pacer sleeps to it; 40 reaches 30 or
    more). host, port: where the server listens (127.0.0.1 by default, port 0: any free one; give another
    host only on purpose). start: run at once in
    the view's thread (False: call :meth:`LiveView.start`, or drive it with :meth:`LiveView.run_to`).
    collision_boxes, contact_lines, ghosts, labels: what the Display panel shows at first. holding:
    'shared' (robots green while another robot holds the same body) or 'any'. history: seconds shown in the
    plots. move_time: duration (s) of a teach move. resettable: whether the page may reset the run to its
    start (False for a run sequenced from Python). quiet: do not print the URL.
    """
    return LiveView(sim, t_end=t_end, speed=speed, frame_rate=frame_rate, host=host, port=port, start=start,
                    collision_boxes=collision_boxes, contact_lines=contact_lines, ghosts=ghosts, labels=labels,
                    holding=holding, history=history, move_time=move_time, resettable=resettable, title=title,
                    quiet=quiet)
