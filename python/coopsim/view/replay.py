"""Browser replay of a simulation: one self-contained HTML file, played in any browser from ``file://``.

    view.replay_html(sim, "out/run.html")            # a finished Simulation: its log, robots and world
    view.replay_html(log, "out/run.html", robots=sim.robots, world=sim.world, fps=30, speed=0.5)

The page shows every robot as its parts (:mod:`coopsim.view.parts`, the
same as the live page's: the SCARAs as the paper draws them, a URDF arm with
its visual meshes, another robot as its boxes) on its link frames
(``robot.frames(q)``), its collision boxes (``robot.shapes(q)``) instead
when the bar's "boxes" box is ticked (``collision_boxes=True``: at first),
the desired pose (the log's ``q_ref``) as a transparent blue ghost of the
moving links' parts, the robots green
while both hold a body (``log[i].holding``; 'any': while they hold something), the world's static
scenery, its free bodies (the bar, in the paper's red) and the floor, with
the colours of :data:`coopsim.view.COLORS`. It has an orbit camera (drag to
turn, right-drag or shift-drag to pan, wheel to zoom), a play/pause button
(or the space bar), a time scrubber (arrow keys step a frame) and a speed
control from 0 to 400 %, as in the paper's viewer, and marks on the
timeline (the log's grasps and releases, any markers given, e.g. a task's
steps). It starts playing, or opens at a time given in its address
(``run.html#t=12.5``). meshcat's own controls are hidden. It needs no server and
no network: the viewer's JavaScript and the data are inside the file.

How it is made. The viewer is meshcat's (MIT licence, kept in the page):
its bundle ``viewer/dist/main.min.js`` from the ``meshcat`` wheel holds
three.js r129, OrbitControls and a msgpack decoder. The scene is a list of
meshcat commands, as meshcat's Python client would send them to its server
(``set_object`` for each box, ``set_transform`` for fixed ones,
``set_property``, and one ``set_animation`` for everything that moves),
each packed with msgpack (meshcat's own ``umsgpack``), base64 in the page
and fed to the viewer's ``handle_command_bytearray``. The animation is
three.js keyframes: per moving box a position track and a quaternion track
at the chosen frame rate (``fps``, default 30), with times and values as
float32 arrays (msgpack extension 0x17, decoded as ``Float32Array``), so a
20 s run of both SCARAs is well under 2 MB, the viewer bundle (0.85 MB)
included. Frames are log rows (the row that held at each multiple of 1/fps),
so a frame shows exactly what the log holds at its time; three.js
interpolates between frames while playing. meshcat's scene root turns the
z-up world into three.js's y-up one; the poses in the commands are z-up.

A small JavaScript hook, ``window.coopsim``, lets scripts and tests drive
the page (all times in the log's seconds, poses in the z-up world):

- ``seek(t)``: shows time t (clamped to the replay) and renders; returns t.
- ``pose(name)``: the (4, 4) pose of a box as nested rows, or null:
  ``robot<i>/<box name>`` (e.g. ``robot0/link2``), ``robot<i>/parts/link<k>``
  (DH frame k) and ``robot<i>/parts/link<k>/<part name>`` (e.g.
  ``robot0/parts/link1/segment1``, the part's pose, without its scale),
  ``ghost<i>/parts/link<k>[/<part name>]``, ``bodies/<name>`` (e.g.
  ``bodies/bar``), ``scenery/<name>``, ``floor``.
- ``color(name)``: the box's colour now, "#rrggbb" (or null).
- ``names()``: all such names. ``time()``, ``play()``, ``pause()``,
  ``playing()``, ``setSpeed(s)`` (0 to 4), ``speed()``, ``boxes(on)`` (the
  collision boxes instead of the parts, or back; returns whether they show; no
  argument: only that); ``t0``, ``t1``,
  ``frames`` (the frame times), ``markers`` ([{t, label}] on the timeline), ``fps``, ``ready`` (true once loaded),
  ``viewer`` (meshcat's ``Viewer``: its ``camera``, ``controls``, ``scene``).
"""
from __future__ import annotations

import base64
import functools
import html
import importlib.resources
import importlib.util
import json
import math
import os
import re
import uuid
from typing import List, Optional

import numpy as np
import umsgpack  # the msgpack meshcat's Python client uses (a dependency of meshcat)

from .. import _checks
from .._core import Robot
from ..log import SimulationLog, _atomic_write, rows_at
from .bodies import COLORS
from .parts import _box_role, mesh_triangles, part_corners, robot_parts
from .world import holding_from_log

__all__ = ["replay_html"]

_GROUP = "coopsim"            # meshcat path of everything drawn here
_FLOOR_THICKNESS = 0.01       # m, the floor slab under z = 0 (drawn)
_STILL = 1e-7                 # m (and rad): a box that moves less than this over the replay is drawn fixed
_DISCRETE = 2300              # THREE.InterpolateDiscrete: a colour switches at its key, no blend
_LOOP_ONCE = 2200             # THREE.LoopOnce: a seek to the end shows the end (LoopRepeat would wrap to 0)


# ---- the page's template, meshcat's bundle and client ----

@functools.lru_cache(maxsize=1)
def _template() -> str:
    """The page (replay_template.html, package data beside this module) with @NAME@ where values go."""
    return importlib.resources.files(__package__).joinpath("replay_template.html").read_text(encoding="utf-8")


@functools.lru_cache(maxsize=1)
def _meshcat_assets():
    """(viewer JavaScript, licence text, meshcat version) from the installed meshcat wheel.

    The package is found, not imported: importing meshcat loads its ZMQ server and IPython machinery,
    none of which a file needs."""
    from importlib.metadata import PackageNotFoundError, version  # its import costs 50 ms: only for a page
    spec = importlib.util.find_spec("meshcat")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("coopsim.view.replay_html needs the meshcat package for its viewer bundle "
                          "(pip install meshcat; scripts/setup.sh installs it)")
    root = list(spec.submodule_search_locations)[0]
    dist = os.path.join(root, "viewer", "dist")
    js_path = os.path.join(dist, "main.min.js")
    if not os.path.isfile(js_path):   # pragma: no cover
        raise ImportError(f"meshcat's viewer bundle is missing from this installation: {js_path}")
    with open(js_path, encoding="utf-8") as f:
        js = f.read()
    if "</script" in js.lower():   # pragma: no cover - none in meshcat 0.3.2
        js = re.sub(r"</(script)", r"<\\/\1", js, flags=re.I)
    notices = []
    for p in (os.path.join(root, "viewer", "LICENSE"), os.path.join(dist, "main.min.js.LICENSE.txt")):
        if os.path.isfile(p):
            with open(p, encoding="utf-8") as f:
                notices.append(f.read().strip())
    if not notices:   # pragma: no cover
        notices.append("MeshCat viewer: MIT License, Copyright (c) 2018 Robin Deits. "
                       "three.js: MIT License, Copyright 2010-2021 Three.js Authors.")
    try:
        mc_version = version("meshcat")
    except PackageNotFoundError:   # pragma: no cover
        mc_version = "?"
    return js, "\n\n".join(notices), mc_version


def _pack(cmd: dict) -> str:
    return base64.b64encode(umsgpack.packb(cmd)).decode("ascii")


def _f32(a: np.ndarray):
    """A float32 array as msgpack extension 0x17, which meshcat's decoder turns into a Float32Array."""
    return umsgpack.Ext(0x17, np.ascontiguousarray(a, dtype="<f4").tobytes())


def _hex(color) -> int:
    from matplotlib.colors import to_rgb  # matplotlib loads only to draw

    try:
        r, g, b = to_rgb(color)
    except (ValueError, TypeError):
        raise ValueError(f"not a matplotlib colour: {color!r}") from None
    return (int(round(r * 255)) << 16) | (int(round(g * 255)) << 8) | int(round(b * 255))


# three.js JSON (ObjectLoader, format 4.5) of a set_object command, as meshcat.geometry lowers a Mesh of a
# Box with a MeshLambertMaterial, or LineSegments of a PointsGeometry with a LineBasicMaterial

def _object_json(kind: str, geometry: dict, material: dict) -> dict:
    gid, mid, oid = (str(uuid.uuid4()) for _ in range(3))
    return {"metadata": {"version": 4.5, "type": "Object"},
            "geometries": [dict(geometry, uuid=gid)],
            "materials": [dict(material, uuid=mid)],
            "object": {"uuid": oid, "type": kind, "name": "box", "geometry": gid, "material": mid,
                       "matrix": [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0]}}


def _material(kind: str, color: int, opacity: float) -> dict:
    transparent = opacity < 1.0
    m = {"type": kind, "color": int(color), "side": 2, "transparent": transparent, "opacity": float(opacity),
         "vertexColors": 0}
    if transparent:
        m["depthWrite"] = False         # a ghost hides nothing behind it
    return m


def _box_object(half, color: int, opacity: float = 1.0) -> dict:
    """A box of the given half extents, Lambert-shaded."""
    w, h, d = (float(2 * x) for x in half)
    return _object_json("Mesh", {"type": "BoxGeometry", "width": w, "height": h, "depth": d},
                        _material("MeshLambertMaterial", color, opacity))


_CYLINDER_SIDES = 32
# three.js's cylinder stands along its y: turned so that it stands along the part's z
_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])


def _part_object(part, color: int, opacity: float = 1.0, shrink: float = 0.0) -> dict:
    """A part (coopsim.view.parts.Part) in its node's frame (the part's pose): a box, a cylinder or a mesh's
    triangles, Lambert-shaded; the shape's scale in the mesh's own matrix, so that the node's pose stays
    rigid. shrink (m): a box or cylinder that much smaller on each side (ghosts)."""
    scale = np.asarray(part.scale, float)
    if part.shape != "mesh":
        scale = np.maximum(scale - 2 * shrink, 0.5 * scale)
    M = np.eye(4)
    if part.shape == "box":
        geometry = {"type": "BoxGeometry", "width": float(scale[0]), "height": float(scale[1]),
                    "depth": float(scale[2])}
    elif part.shape == "cylinder":
        geometry = {"type": "CylinderGeometry", "radiusTop": 0.5, "radiusBottom": 0.5, "height": 1.0,
                    "radialSegments": _CYLINDER_SIDES}
        M = _Y_TO_Z @ np.diag([scale[0], scale[2], scale[1], 1.0])
    else:
        v, f = mesh_triangles(part.mesh)
        geometry = {"type": "BufferGeometry",
                    "data": {"attributes": {"position": {"itemSize": 3, "type": "Float32Array", "array": _f32(v.reshape(-1)),
                                                         "normalized": False}},
                             "index": {"itemSize": 1, "type": "Uint32Array", "normalized": False,
                                       "array": umsgpack.Ext(0x16, np.ascontiguousarray(f, "<u4").tobytes())}}}
        M = np.diag([*scale, 1.0])
    obj = _object_json("Mesh", geometry, _material("MeshLambertMaterial", color, opacity))
    obj["object"]["matrix"] = [float(x) for x in M.T.reshape(-1)]
    return obj


def _lines_object(segments: np.ndarray, color: int, opacity: float) -> dict:
    """Line segments between consecutive pairs of points (m, 3)."""
    pos = {"itemSize": 3, "type": "Float32Array", "array": _f32(np.asarray(segments, float).reshape(-1)),
           "normalized": False}
    return _object_json("LineSegments", {"type": "BufferGeometry", "data": {"attributes": {"position": pos}}},
                        _material("LineBasicMaterial", color, opacity))


def _set_object(path: str, obj: dict) -> dict:
    return {"type": "set_object", "path": path, "object": obj}


def _set_transform(path: str, T: np.ndarray) -> dict:
    return {"type": "set_transform", "path": path, "matrix": _f32(np.asarray(T, float).T.reshape(-1))}


def _set_property(path: str, key: str, value) -> dict:
    return {"type": "set_property", "path": path, "property": key, "value": value}


# ---- poses ----

def _quaternions(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions [x, y, z, w] (three.js order)."""
    R = np.asarray(R, float)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    q = np.empty(R.shape[:-2] + (4,))
    # Shepperd: divide by the largest of 4w^2, 4x^2, 4y^2, 4z^2
    cand = np.stack([tr, m00, m11, m22], axis=-1)
    k = np.argmax(cand, axis=-1)
    for case in range(4):
        sel = k == case
        if not np.any(sel):
            continue
        r = R[sel]
        if case == 0:
            t = np.sqrt(1.0 + r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]) * 2
            v = np.stack([(r[:, 2, 1] - r[:, 1, 2]) / t, (r[:, 0, 2] - r[:, 2, 0]) / t,
                          (r[:, 1, 0] - r[:, 0, 1]) / t, 0.25 * t], axis=-1)
        elif case == 1:
            t = np.sqrt(1.0 + r[:, 0, 0] - r[:, 1, 1] - r[:, 2, 2]) * 2
            v = np.stack([0.25 * t, (r[:, 0, 1] + r[:, 1, 0]) / t, (r[:, 0, 2] + r[:, 2, 0]) / t,
                          (r[:, 2, 1] - r[:, 1, 2]) / t], axis=-1)
        elif case == 2:
            t = np.sqrt(1.0 - r[:, 0, 0] + r[:, 1, 1] - r[:, 2, 2]) * 2
            v = np.stack([(r[:, 0, 1] + r[:, 1, 0]) / t, 0.25 * t, (r[:, 1, 2] + r[:, 2, 1]) / t,
                          (r[:, 0, 2] - r[:, 2, 0]) / t], axis=-1)
        else:
            t = np.sqrt(1.0 - r[:, 0, 0] - r[:, 1, 1] + r[:, 2, 2]) * 2
            v = np.stack([(r[:, 0, 2] + r[:, 2, 0]) / t, (r[:, 1, 2] + r[:, 2, 1]) / t, 0.25 * t,
                          (r[:, 1, 0] - r[:, 0, 1]) / t], axis=-1)
        q[sel] = v
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q


def _continuous(q: np.ndarray) -> np.ndarray:
    """(frames, 4) quaternions with signs flipped so that neighbours have a positive dot product."""
    q = q.copy()
    for k in range(1, len(q)):
        if np.dot(q[k], q[k - 1]) < 0:
            q[k] = -q[k]
    return q


def _tracks(times: np.ndarray, poses: np.ndarray) -> list:
    """Position and quaternion keyframe tracks of one box, (frames, 4, 4) poses at the given clip times."""
    pos = poses[:, :3, 3]
    quat = _continuous(_quaternions(poses[:, :3, :3]))
    t = _f32(times)
    return [{"name": ".position", "type": "vector", "times": t, "values": _f32(pos.reshape(-1))},
            {"name": ".quaternion", "type": "quaternion", "times": t, "values": _f32(quat.reshape(-1))}]


def _color_track(times: np.ndarray, colors: np.ndarray) -> dict:
    """A discrete colour track: (frames,) 0xRRGGBB, keyed where the colour changes (and at the end)."""
    keep = np.flatnonzero(np.r_[True, colors[1:] != colors[:-1]])
    keep = np.unique(np.append(keep, len(colors) - 1))
    rgb = np.stack([(colors[keep] >> 16) & 255, (colors[keep] >> 8) & 255, colors[keep] & 255], axis=-1) / 255.0
    return {"name": "box.material.color", "type": "color", "interpolation": _DISCRETE, "times": _f32(times[keep]),
            "values": _f32(rgb.reshape(-1))}


_MAX_FRAMES = 1e6  # keyframes of a replay, as animate's frames
_MAX_DISTANCE = 1e6  # m: boxes drawn lie within the world's extent


def _frame_rows(t: np.ndarray, fps: float, t0: float, t1: float) -> np.ndarray:
    """Indices of the log rows shown, among the rows within [t0, t1]: the row that held at each frame's time,
    the first of them + k / fps (:func:`coopsim.log.rows_at`), and the last row in it."""
    lo = int(np.searchsorted(t, t0 - 1e-12, side="left"))
    hi = int(np.searchsorted(t, t1 + 1e-12, side="right")) - 1
    if hi < lo:
        raise ValueError(f"no log row between t_start = {t0:g} s and t_end = {t1:g} s")
    seg = t[lo:hi + 1]
    frames = (seg[-1] - seg[0]) * fps
    if not frames <= _MAX_FRAMES:
        raise ValueError(f"{frames:.3g} frames is too many (at most {_MAX_FRAMES:g}): lower fps or replay a part "
                         "of the log (t_start, t_end)")
    n = int(math.floor(frames + 1e-9)) + 1
    j = rows_at(seg, seg[0] + np.arange(n) / fps)
    return np.unique(np.append(j, len(seg) - 1)) + lo


def _safe(name: str) -> str:
    return str(name).replace("/", "_").strip() or "_"


# ---- arguments ----

def _unpack_sources(log, robots, world):
    """(log, robots, world) from a SimulationLog or a Simulation."""
    if not isinstance(log, SimulationLog) and hasattr(log, "log") and hasattr(log, "robots"):   # a Simulation
        sim = log
        log = sim.log
        if robots is None:
            robots = sim.robots
        if world is None:
            world = getattr(sim, "world", None)
    if not isinstance(log, SimulationLog):
        raise ValueError(f"log must be a coopsim SimulationLog or a finished Simulation, got {type(log).__name__}")
    log.check(poses=True)
    if robots is None:
        robots = []
        if len(log.robots):
            raise ValueError("robots must be given with a log (the robots it was run with), or pass the Simulation")
    if isinstance(robots, Robot):
        robots = [robots]
    robots = list(robots)
    if not all(isinstance(r, Robot) for r in robots):
        raise ValueError("robots must be a coopsim.Robot or a sequence of them")
    if len(robots) != len(log.robots):
        raise ValueError(f"the log has {len(log.robots)} robot(s), got {len(robots)} robot(s)")
    for i, (r, rl) in enumerate(zip(robots, log.robots)):
        if r.dof != rl.dof:
            raise ValueError(f"robots[{i}] has {r.dof} joints, the log's robot {i} ({rl.name}) {rl.dof}")
    return log, robots, world


def _holding(holding, log, rows: int) -> list:
    """Per robot a (rows,) bool array (or None): whether it holds something in each log row."""
    n = len(log.robots)
    if holding is False:
        return [None] * n
    if holding is None or holding is True or isinstance(holding, str):
        # the views' rule: by default green while another robot holds the same body too (the paper's
        # dual hold), 'any' while the robot holds anything
        mode = holding if isinstance(holding, str) else "shared"
        if any(len(getattr(rl, "holding", ())) != rows for rl in log.robots):
            return [None] * n
        return list(holding_from_log(log, mode=mode))
    items = list(holding) if isinstance(holding, (list, tuple)) else None
    if items is None or len(items) != n:
        raise ValueError(f"holding must be None, False or one (rows,) bool array (or None) per robot ({n}), "
                         f"got {type(holding).__name__}")
    out = []
    for i, h in enumerate(items):
        if h is None:
            out.append(None)
            continue
        a = np.asarray(h)
        if a.shape != (rows,) or not (a.dtype == bool or np.isin(a, (0, 1)).all()):
            raise ValueError(f"holding[{i}] must be a ({rows},) bool array, one flag per log row, got shape {a.shape}")
        out.append(a.astype(bool))
    return out


def _world_bodies(world) -> list:
    """The world's bodies as dicts (name, kind, half_extents, pose); [] without a world."""
    if world is None:
        return []
    try:
        names = list(world.body_names)
    except AttributeError:
        raise ValueError(f"world must be a coopsim.World, got {type(world).__name__}") from None
    return [world.body(n) for n in names]


# ---- the page ----

def _markers(markers, log, t0: float, t1: float) -> list:
    """The timeline's marks, [{t, label}] sorted by time within t0 .. t1: `markers` ((t, label) pairs) and, with
    a log, its grasps and releases ('scara2 grasps bar', 'scara2 releases bar (opened)')."""
    out = []
    if markers is not None:
        try:
            pairs = [(m[0], m[1]) for m in markers]
        except (TypeError, IndexError, KeyError):
            raise ValueError("markers must be (t, label) pairs") from None
        for t, label in pairs:
            out.append({"t": _checks.number(t, "a marker's t"), "label": str(label)})
    g = log.grasps if log is not None and hasattr(log, "grasps") else None
    if g is not None and len(g):
        names = [rl.name for rl in log.robots]
        for t, i, body, ev, why in zip(g["t"], g["robot"], g["body"], g["event"], g["reason"]):
            who = names[int(i)] if 0 <= int(i) < len(names) else f"robot {int(i)}"
            verb = "grasps" if ev == "grasp" else "releases"
            out.append({"t": float(t), "label": f"{who} {verb} {body}" + ("" if ev == "grasp" else f" ({why})")})
    return sorted((m for m in out if t0 - 1e-9 <= m["t"] <= t1 + 1e-9), key=lambda m: m["t"])


def replay_html(log, path, *, robots=None, world=None, fps: float = 30.0, speed: float = 1.0,
                t_start: Optional[float] = None, t_end: Optional[float] = None, reference: bool = True,
                floor: bool = True, title: Optional[str] = None, autoplay: bool = True, collision_boxes: bool = False,
                holding=None, colors=None, ghost_margin: float = 0.002, elev: float = 30.0,
                azim: float = -45.0, zoom: float = 1.0, markers=None, events: bool = True) -> str:
    """Write a replay of a simulation log as one self-contained HTML file; returns its path.

    log: a :class:`~coopsim.log.SimulationLog`, or a finished
    :class:`~coopsim.Simulation` (its log, robots and world are used unless
    given). robots: the robots the log was run with (``sim.robots``), one
    per robot in the log. world: the simulation's :class:`~coopsim.World`
    (``sim.world``): its static boxes are drawn as scenery and its free
    bodies (sizes from the world, poses from ``log.bodies``) in the body
    colour; needed when the log has free bodies.

    fps: frames per second of the replay's keyframes (> 0; each frame is
    the log row that held at its time, :func:`coopsim.log.rows_at`, as in
    :func:`~coopsim.view.animate`, so a log coarser than 1/fps keeps all its
    rows). speed: the speed the page starts at, 0 to 4 (400 %). t_start,
    t_end: the part of the log to replay (s; default all). reference: draw
    the desired pose (``q_ref``) as a transparent blue ghost of the moving
    links' parts (robots whose reference is not finite, or beyond 1e6 m, get
    none). collision_boxes: show the collision boxes instead of the parts
    when the page opens (its "boxes" box swaps them). floor: draw the floor (z = 0) when
    the world has one (or there is no world). holding: a robot's moving
    boxes and parts are green while it holds: None (default) or 'shared' from the log
    while another robot holds the same body too (the paper's dual hold,
    :func:`~coopsim.view.holding_from_log`), 'any' while it holds anything,
    False never, or per robot a (rows,) bool array (or None). title: the
    page's title.
    autoplay: start playing when opened (default); the page's address can
    open it at a time instead, paused: ``run.html#t=12.5`` (``#t=12.5&play``
    plays from there). markers: (t, label) pairs (s, text) marked on the
    timeline, e.g. a task's steps; events: also mark the log's grasps and
    releases (default). A mark shows its label on hover and seeks there when
    clicked. colors: one colour per robot for
    its links (matplotlib colours; default :data:`COLORS`). ghost_margin:
    the ghost's boxes and cylinders are this much smaller on each side (m),
    so that a robot on its reference hides its ghost. elev, azim: the camera's elevation and
    azimuth (degrees, as matplotlib's view_init) looking at the middle of
    the robots (their boxes and parts over the replay, and the scenery: free bodies
    that wander off do not pull the camera away); zoom: > 1 brings it
    closer.

    The file (about 0.9 MB plus 36 bytes per moving box or link frame and
    frame; a robot's mesh files add 24 bytes per triangle, 6 MB for the
    UR5 of example-robot-data) needs no network or server; see the module's docstring for the page's
    controls and its ``window.coopsim`` hook.
    """
    log, robots, world = _unpack_sources(log, robots, world)
    fps = _checks.number(fps, "fps", 0.0, 1000.0, lo_open=True)
    speed = _checks.number(speed, "speed", 0.0, 4.0)
    ghost_margin = _checks.number(ghost_margin, "ghost_margin", 0.0, 0.1)
    elev = _checks.number(elev, "elev", -90.0, 90.0)
    azim = _checks.number(azim, "azim")
    zoom = _checks.number(zoom, "zoom", 0.0, 100.0, lo_open=True)
    if path is None or not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file name, got {path!r}")
    path = os.fspath(path)

    t_log = np.asarray(log.t, dtype=float)
    if t_log.ndim != 1 or len(t_log) == 0:
        raise ValueError("the log has no rows: run the simulation first")
    t0 = float(t_log[0]) if t_start is None else _checks.number(t_start, "t_start")
    t1 = float(t_log[-1]) if t_end is None else _checks.number(t_end, "t_end")
    if t1 < t0:
        raise ValueError(f"t_end ({t1:g} s) must not be before t_start ({t0:g} s)")
    rows = _frame_rows(t_log, fps, t0, t1)
    times = t_log[rows]
    t0, t1 = float(times[0]), float(times[-1])
    clip_t = times - t0

    n = len(robots)
    if colors is None:
        colors = [None] * n
    elif isinstance(colors, str) or (isinstance(colors, tuple) and len(colors) in (3, 4)
                                      and all(isinstance(c, (int, float)) for c in colors)):
        colors = [colors] * n
    else:
        colors = list(colors)
        if len(colors) != n:
            raise ValueError(f"colors must hold one colour per robot ({n}), got {len(colors)}")

    cmds: List[dict] = []
    names: List[str] = []
    animations: List[dict] = []
    bounds: List[np.ndarray] = []          # points the camera frames: the robots and the scenery
    others: List[np.ndarray] = []          # points framed only when there are none of those (free bodies)

    def add_box(name, half, color, opacity, poses, colors_per_frame=None, obj=None):
        """poses: (4, 4) fixed, or (frames, 4, 4) moving; colors_per_frame: None, or (frames,) 0xRRGGBB; obj:
        the object (default None: a box of the half extents), False to place a node without one (a link frame)."""
        p = f"/{_GROUP}/{name}"
        if obj is not False:
            cmds.append(_set_object(p, _box_object(half, color, opacity) if obj is None else obj))
        poses = np.asarray(poses, float)
        first = poses if poses.ndim == 2 else poses[0]
        cmds.append(_set_transform(p, first))
        tracks = []
        # still bodies (a bar resting on the floor creeps by 1e-10 m) get one pose: 0.1 um is below float32 here
        if poses.ndim == 3 and len(poses) > 1 and np.ptp(poses, axis=0).max() > _STILL:
            tracks += _tracks(clip_t, poses)
        if colors_per_frame is not None and len(set(colors_per_frame)) > 1:
            tracks.append(_color_track(clip_t, np.asarray(colors_per_frame)))
        if tracks:
            animations.append({"path": p, "clip": {"fps": 1, "name": "default", "tracks": tracks}})
        names.append(name)

    def add_parts(prefix, robot, parts, q, colors, held=None, opacity=1.0, shrink=0.0, moving_only=False):
        """The parts fixed to their link frames: a node per link frame (prefix/parts/link<k>, at the robot's
        DH frame k over the frames), each part a node under it at its fixed pose; held: None or (frames,)
        bool, the parts of moving links green then."""
        F = np.stack([np.asarray(robot.frames(x)) for x in q])              # (frames, n + 1, 4, 4)
        if not np.all(np.abs(F[..., :3, 3]) <= _MAX_DISTANCE):
            return False
        if prefix.startswith("robot") and parts:                           # the camera frames the parts too
            links = np.array([p.link for p in parts])
            W = np.einsum("fkij,kjl->fkil", F[:, links], np.array([p.pose for p in parts]))
            bounds.append(part_corners(parts, W))
        for k in sorted({p.link for p in parts if p.link != 0 or not moving_only}):
            add_box(f"{prefix}/parts/link{k}", None, 0, 1.0, F[0, k] if k == 0 else F[:, k], obj=False)
            for p, col in zip(parts, colors):
                if p.link == k:
                    per_frame = None if held is None or k == 0 else np.where(held, green, col)
                    add_box(f"{prefix}/parts/link{k}/{_safe(p.name)}", None, col, opacity, p.pose, per_frame,
                            obj=_part_object(p, col, opacity, shrink))
        return True

    # robots (green while they hold something) and ghosts
    c = COLORS
    held_rows = _holding(holding, log, len(t_log))
    green = _hex(c["holding"])
    boxes_shown = bool(collision_boxes)
    box_names, part_roots = [], []
    for i, (r, rl) in enumerate(zip(robots, log.robots)):
        q = np.asarray(rl.q, float)[rows]
        k = len(r.boxes)
        shapes = [r.shapes(qq) for qq in q]
        P = np.stack([s[0] for s in shapes])             # (frames, k, 4, 4)
        if not np.all(np.abs(P[..., :3, 3]) <= _MAX_DISTANCE):
            raise ValueError(f"log[{i}].q puts robot {i}'s boxes more than {_MAX_DISTANCE:g} m from the origin")
        H = shapes[0][1]
        role = {"robot": _hex(c["robots"][i % len(c["robots"])] if colors[i] is None else colors[i]),
                "base": _hex(c["base"]), "jaw": _hex(c["jaw"])}
        used = set()
        names_i = []
        for j, b in enumerate(r.boxes):
            nm = _safe(b.name or f"box{j}")
            if nm in used:
                nm = f"{nm}_{j}"
            used.add(nm)
            names_i.append(nm)
            col = role[_box_role(r, b)]
            held = None if held_rows[i] is None or b.link == 0 else np.where(held_rows[i][rows], green, col)
            add_box(f"robot{i}/{nm}", H[j], col, 1.0, P[0, j] if b.link == 0 else P[:, j], held)
            box_names.append(f"robot{i}/{nm}")
            if not boxes_shown:
                cmds.append(_set_property(f"/{_GROUP}/robot{i}/{nm}", "visible", False))
        # the robot's look: its parts on its link frames (coopsim.view.parts), hidden while the boxes show
        parts = robot_parts(r)
        add_parts(f"robot{i}", r, parts, q, [role[p.color] for p in parts],
                  None if held_rows[i] is None else held_rows[i][rows])
        part_roots.append(f"robot{i}/parts")
        if boxes_shown:
            cmds.append(_set_property(f"/{_GROUP}/robot{i}/parts", "visible", False))
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
        pts = np.einsum("fkab,kcb->fkca", P[:, :, :3, :3], corners[None] * H[:, None, :]) + P[:, :, None, :3, 3]
        bounds.append(pts.reshape(-1, 3))
        if reference:
            # the desired pose: the parts of the moving links, ghost_margin smaller (a robot on its reference hides
            # its ghost); none for a reference that is not finite or lies beyond _MAX_DISTANCE
            qr = np.asarray(rl.q_ref, float)[rows]
            if qr.shape == q.shape and np.all(np.isfinite(qr)):
                moving = [p for p in parts if p.link != 0]
                add_parts(f"ghost{i}", r, moving, qr, [_hex(c["ghost"])] * len(moving), opacity=float(c.get(
                    "ghost_alpha", 0.3)), shrink=ghost_margin, moving_only=True)

    # the world: scenery, free bodies
    bodies = _world_bodies(world)
    has_floor = world is None
    free_logged = dict(getattr(log, "bodies", {}) or {})
    for b in bodies:
        kind, name = b["kind"], b["name"]
        if kind == "floor":
            has_floor = True
        elif kind == "static":
            add_box(f"scenery/{_safe(name)}", b["half_extents"], _hex(c["scenery"]), 1.0, b["pose"])
            T = np.asarray(b["pose"], float)
            bounds.append((T[:3, :3] @ (np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                                   for sz in (-1, 1)]) * b["half_extents"]).T).T + T[:3, 3])
        elif kind == "free":
            bl = free_logged.pop(name, None)
            if bl is None:
                poses = np.asarray(b["pose"], float)
            else:
                poses = np.asarray(bl.poses(), float)[rows_at(bl.t, times)]
            bar = str(name).startswith("bar")             # the bar red, other free bodies in their colour
            add_box(f"bodies/{_safe(name)}", b["half_extents"], _hex(c["body"] if bar else c["free_body"]), 1.0,
                    poses)
            pp = poses.reshape(-1, 4, 4)[:, :3, 3]
            others.append(pp)
    if free_logged:
        raise ValueError(f"the log has free bodies ({', '.join(sorted(free_logged))}) that the world does not: "
                         "pass world=sim.world (their sizes), or the Simulation itself")

    allpts = np.concatenate(bounds) if bounds else np.concatenate(others) if others else np.zeros((1, 3))
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    # the camera looks at the middle of what moves and the scenery, from elev / azim, just far enough to
    # have all of it in meshcat's 75 deg vertical view (and in the horizontal one of a 4:3 or wider window)
    centre = (lo + hi) / 2
    e, a = math.radians(elev), math.radians(azim)
    back = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])    # centre -> camera
    right = np.cross(-back, [0.0, 0.0, 1.0])
    right = right / np.linalg.norm(right) if np.linalg.norm(right) > 1e-9 else np.array([1.0, 0.0, 0.0])
    up = np.cross(right, -back)
    rel = allpts - centre
    tv = math.tan(math.radians(75.0 / 2))
    need = rel @ back + np.maximum(np.abs(rel @ up) / tv, np.abs(rel @ right) / (4 / 3 * tv))
    dist = max(0.2, 1.08 * float(need.max())) / zoom
    d = dist * back

    # the floor: a slab whose top is z = 0, tiled by grid lines every 0.1 m
    if floor and has_floor:
        tile = 0.1
        x0, x1 = math.floor((lo[0] - 0.15) / tile) * tile, math.ceil((hi[0] + 0.15) / tile) * tile
        y0, y1 = math.floor((lo[1] - 0.15) / tile) * tile, math.ceil((hi[1] + 0.15) / tile) * tile
        T = np.eye(4)
        T[:3, 3] = [(x0 + x1) / 2, (y0 + y1) / 2, -_FLOOR_THICKNESS / 2]
        fc = c["floor"][0] if isinstance(c["floor"], (list, tuple)) else c["floor"]
        add_box("floor", [(x1 - x0) / 2, (y1 - y0) / 2, _FLOOR_THICKNESS / 2], _hex(fc), 1.0, T)
        segs = []
        for x in np.arange(x0, x1 + 1e-9, tile):
            segs += [[x, y0, 0.0005], [x, y1, 0.0005]]
        for y in np.arange(y0, y1 + 1e-9, tile):
            segs += [[x0, y, 0.0005], [x1, y, 0.0005]]
        cmds.append(_set_object(f"/{_GROUP}/floor_grid", _lines_object(np.array(segs), _hex("#8a9099"), 0.6)))

    # viewer set-up: no default grid and axes, a light background, the camera on the scene
    cmds += [_set_property("/Grid", "visible", False), _set_property("/Axes", "visible", False),
             _set_property("/Background", "top_color", [0.97, 0.98, 1.0]),
             _set_property("/Background", "bottom_color", [0.74, 0.78, 0.84])]
    if animations:
        cmds.append({"type": "set_animation", "animations": animations,
                     "options": {"play": True, "repetitions": 1, "loopMode": _LOOP_ONCE, "clampWhenFinished": True}})

    js, notices, mc_version = _meshcat_assets()
    robot_names = ", ".join(rl.name for rl in log.robots) or "no robots"
    if title is None:
        title = f"coopsim replay: {robot_names}"
    meta = {"t0": t0, "t1": t1, "fps": fps, "speed": speed, "autoplay": bool(autoplay), "names": names,
            "boxes": box_names, "parts": part_roots, "collision_boxes": boxes_shown,
            "markers": _markers(markers, log if events else None, t0, t1),
            "frames": [float(x) for x in times], "group": _GROUP,
            "camera": {"position": [float(x) for x in centre + d], "target": [float(x) for x in centre]}}
    values = {"TITLE": html.escape(str(title)), "NOTICES": html.escape(notices).replace("--", "- -"),
              "NOTICES_TEXT": html.escape(notices), "MESHCAT_VERSION": html.escape(str(mc_version)),
              "COMMANDS": json.dumps([_pack(x) for x in cmds]), "META": json.dumps(meta).replace("</", "<\\/"),
              "MESHCAT_JS": js}
    page = re.sub(r"@([A-Z_]+)@", lambda m: values[m.group(1)], _template())     # one pass: no value is rescanned

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(page)

    return _atomic_write(path, ".html", write)  # no half-written page under the name
