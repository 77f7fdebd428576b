"""Animations of a simulation log: frames at a chosen rate and speed, written as MP4 or GIF.

Frame k shows time t_start + k * speed / fps: joint positions (and the
reference ghost) interpolated linearly between log rows, per-row flags
(holding, colliding boxes, contacts, body poses) taken from the last row at
or before that time. Every frame only moves the scene's one polygon
collection; files are written by blitting it over a background drawn once
(the camera is fixed), straight into ffmpeg (imageio-ffmpeg's bundled
binary) or Pillow.
"""
from __future__ import annotations

import base64
import math
import os
import tempfile
from typing import Callable, Optional

import numpy as np

from .. import _checks
from ..log import _atomic_write, rows_at
from .bodies import Body, _array, _is_simulation, _robot_list
from .geometry import box_corners
from .scene import Scene, _contacts
from .world import (_holding_mode, colliding_from_log, contacts_from_log, holding_from_log, resolve_world,
                    world_bodies)

__all__ = ["Animation", "animate", "ffmpeg_path"]

MAX_SPEED = 4.0
_SUFFIXES = (".mp4", ".gif")


def ffmpeg_path() -> str:
    """The ffmpeg executable bundled with imageio-ffmpeg (``pip install imageio-ffmpeg``).

    Also sets matplotlib's ``rcParams['animation.ffmpeg_path']`` to it when that is still the default
    'ffmpeg', so matplotlib's own writers (``FuncAnimation.save``, ``to_html5_video``) find it too.
    """
    import matplotlib  # matplotlib loads only to draw

    try:
        import imageio_ffmpeg  # only to find or run ffmpeg
    except ImportError:  # pragma: no cover - a declared dependency
        raise RuntimeError("MP4 needs imageio-ffmpeg: pip install imageio-ffmpeg") from None
    exe = imageio_ffmpeg.get_ffmpeg_exe()
    if matplotlib.rcParams["animation.ffmpeg_path"] == "ffmpeg":
        matplotlib.rcParams["animation.ffmpeg_path"] = exe
    return exe


def _suffix(path) -> str:
    if not isinstance(path, (str, os.PathLike)) or not isinstance(os.fspath(path), str):
        raise ValueError(f"path must be a file name ending in .mp4 or .gif, got {path!r}")
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    if suffix not in _SUFFIXES:
        raise ValueError(f"path must end in .mp4 or .gif (the format follows the suffix), got {os.fspath(path)!r}")
    return suffix


class Animation:
    """Frames of a log in a :class:`~coopsim.view.Scene`; made by :func:`animate`.

    times: (frames,) simulated time shown by each frame, s. fps: frames per
    second of the video; speed: simulated seconds per video second.
    scene: the Scene drawn into; fig: its Figure. :meth:`show_frame` puts
    frame k in the scene; :meth:`save` writes MP4 or GIF; in a notebook the
    object displays as an HTML5 video (:meth:`to_html5_video`);
    :attr:`animation` is a matplotlib FuncAnimation of the same frames (for
    interactive windows or matplotlib's own writers).
    """

    def __init__(self, scene: Scene, times: np.ndarray, fps: float, speed: float, frame_args: Callable[[int], dict],
                 label: Optional[Callable[[float], str]]):
        self.scene = scene
        self.fig = scene.fig
        self.times = times
        self.fps = fps
        self.speed = speed
        self._frame_args = frame_args
        self._label = label
        self._anim = None
        self.path: Optional[str] = None

    def __len__(self) -> int:
        return len(self.times)

    @property
    def duration(self) -> float:
        """Length of the video, s (frames / fps)."""
        return len(self.times) / self.fps

    def show_frame(self, k: int) -> list:
        """Puts frame k (0 .. frames-1) in the scene; returns the changed artists (the figure is not drawn)."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k < len(self.times):
            raise ValueError(f"k must be a frame index in [0, {len(self.times)}), got {k!r}")
        args = self._frame_args(int(k))
        if self._label is not None:
            args["label"] = self._label(float(self.times[k]))
        return self.scene.update(**args)

    # ---- rendering ----

    def frames(self):
        """Yields each frame as an (height, width, 4) uint8 RGBA array (a view of the canvas, valid until
        the next frame), drawn with :meth:`Scene.redraw` (the background once, then the moving artists)."""
        fig = self.fig
        if not hasattr(fig.canvas, "buffer_rgba"):
            from matplotlib.backends.backend_agg import FigureCanvasAgg  # matplotlib loads only to draw

            FigureCanvasAgg(fig)
        for k in range(len(self.times)):
            self.show_frame(k)
            self.scene.redraw()
            yield np.asarray(fig.canvas.buffer_rgba())

    def save(self, path, *, quality: Optional[float] = None) -> str:
        """Writes the frames to path: .mp4 (H.264 through imageio-ffmpeg's ffmpeg) or .gif (Pillow).

        quality: MP4 only, 0 (smallest) .. 10 (best), default 7. GIF frame
        delays are whole centiseconds, spread so the total duration is
        frames / fps. Returns the path; raises ValueError for another suffix.
        """
        suffix = _suffix(path)
        path = os.fspath(path)
        if suffix == ".gif" and self.fps > 50:
            raise ValueError(f"fps must be <= 50 for a GIF (browsers slow down shorter frame delays), got {self.fps:g}")
        if quality is not None:
            quality = _checks.number(quality, "quality")
            if not 0 <= quality <= 10:
                raise ValueError(f"quality must be in 0 .. 10, got {quality!r}")

        def write(tmp):
            if suffix == ".mp4":
                self._write_mp4(tmp, 7.0 if quality is None else quality)
            else:
                self._write_gif(tmp)

        # a temporary file in the same folder, then renamed: no half-written video under the name
        self.path = _atomic_write(path, suffix, write)
        return self.path

    def _write_mp4(self, path: str, quality: float) -> None:
        import imageio_ffmpeg  # only to find or run ffmpeg

        ffmpeg_path()
        w, h = self.fig.canvas.get_width_height(physical=True)
        W, H = w + w % 2, h + h % 2           # yuv420p needs even sizes: pad with white
        writer = imageio_ffmpeg.write_frames(path, (W, H), fps=self.fps, codec="libx264", pix_fmt_in="rgb24",
                                             pix_fmt_out="yuv420p", quality=quality, macro_block_size=1,
                                             ffmpeg_log_level="error")
        writer.send(None)
        buf = np.full((H, W, 3), 255, dtype=np.uint8)
        try:
            for frame in self.frames():
                buf[:h, :w] = frame[..., :3]
                writer.send(buf.tobytes())
        finally:
            writer.close()

    def _write_gif(self, path: str) -> None:
        from PIL import Image  # Pillow loads only to write a GIF

        images = []
        for frame in self.frames():
            im = Image.fromarray(np.ascontiguousarray(frame[..., :3]))
            images.append(im.quantize(colors=255, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE))
        # delays in whole centiseconds whose running sum follows k / fps
        ends = np.round(np.arange(1, len(images) + 1) * 100.0 / self.fps).astype(int)
        delays = 10 * np.diff(ends, prepend=0)
        delays = np.maximum(delays, 10)
        images[0].save(path, format="GIF", save_all=True, append_images=images[1:], duration=delays.tolist(),
                       loop=0, optimize=False, disposal=1)

    def to_html5_video(self) -> str:
        """The frames as an HTML ``<video>`` tag with the MP4 embedded (base64), for notebooks."""
        with tempfile.TemporaryDirectory() as d:
            p = self.save(os.path.join(d, "animation.mp4"))
            with open(p, "rb") as f:
                data = base64.b64encode(f.read()).decode("ascii")
        self.path = None
        w, h = self.fig.canvas.get_width_height()
        return (f'<video width="{w}" height="{h}" controls autoplay loop>'
                f'<source type="video/mp4" src="data:video/mp4;base64,{data}"></video>')

    def _repr_html_(self) -> str:
        return self.to_html5_video()

    @property
    def animation(self):
        """A matplotlib ``FuncAnimation`` over the same frames (interval 1000 / fps ms), made on first use."""
        if self._anim is None:
            from matplotlib.animation import FuncAnimation  # matplotlib loads only to draw

            ffmpeg_path()
            self._anim = FuncAnimation(self.fig, self.show_frame, frames=len(self.times), interval=1000.0 / self.fps,
                                       blit=False, repeat=True)
        return self._anim

    def __repr__(self) -> str:
        return (f"<coopsim.view.Animation {len(self.times)} frames at {self.fps:g} fps, speed {self.speed:g} "
                f"(t = {self.times[0]:.4g} .. {self.times[-1]:.4g} s), {self.duration:.3g} s>")


def _interp(t_log: np.ndarray, X: np.ndarray, times: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(times, t_log, X[:, j]) for j in range(X.shape[1])])


def _per_robot_rows(x, n_robots: int, rows: int, what: str, tails: list, dtype=float) -> list:
    """Per robot an array (rows, *tails[i]) or None, from None, one array (one robot) or one per robot."""
    if x is None:
        return [None] * n_robots
    shapes = [(rows,) + tuple(t) for t in tails]
    try:
        whole = np.shape(x)
    except ValueError:          # ragged: one entry per robot
        whole = None
    if n_robots == 1 and (whole == shapes[0] or isinstance(x, np.ndarray)):
        items = [x]
    elif len(set(shapes)) == 1 and whole == (rows, n_robots) + shapes[0][1:]:
        items = [np.asarray(x)[:, i] for i in range(n_robots)]
    else:
        items = list(x) if isinstance(x, (list, tuple, np.ndarray)) else [x]
        if len(items) != n_robots:
            raise ValueError(f"{what} must hold one array per robot ({n_robots}), each "
                             f"{' / '.join(map(str, sorted(set(shapes))))} (one row per log row), got {len(items)} "
                             f"entries")
    out = []
    for i, (a, shape) in enumerate(zip(items, shapes)):
        name = what if n_robots == 1 else f"{what}[{i}]"
        if a is None:
            out.append(None)
            continue
        arr = np.asarray(a)
        if arr.shape != shape:
            raise ValueError(f"wrong shape for {name}: expected {shape}, one row per log row, got {arr.shape}")
        if dtype is bool:
            if arr.dtype != bool and not (np.issubdtype(arr.dtype, np.integer) and np.isin(arr, (0, 1)).all()):
                raise ValueError(f"{name} must be booleans, got dtype {arr.dtype}")
            arr = arr.astype(bool)
        else:
            arr = _array(arr, name)
        out.append(arr)
    return out


def animate(log, robots=None, *, fps: float = 30.0, speed: float = 1.0, path=None, t_start: Optional[float] = None,
            t_end: Optional[float] = None, duration: Optional[float] = None, reference=True, holding=None,
            collision_boxes: bool = False, colliding=None, contacts=None, bodies=None, world=None, label=True,
            ax=None, figsize=(6.4, 4.8), dpi: float = 100.0, quality: Optional[float] = None, inset: bool = False,
            **scene_options) -> Animation:
    """An animation of a simulation log: robots as shaded boxes, at `fps` frames per second and `speed`.

    log: a SimulationLog (``sim.run(...)`` or ``sim.log``) with rows at
    times log.t (s), or a finished Simulation: its log, robots and world
    (``view.animate(sim)``). robots: the simulated robots in log order (a
    list of Robot, one Robot, or the Simulation; default the Simulation's).
    world: a coopsim.World or a Simulation (its world; default the
    Simulation given as log or robots, False for none): its static boxes
    drawn as grey scenery, its free bodies (the bar, named 'bar...', red;
    others purple) at their logged poses (``log.bodies``) in every frame.
    fps: video frames per second (>
    0). speed: simulated seconds per video second, 0 .. 4 (the paper's
    0-400 %; 0 freezes t_start and needs `duration`). Frame k shows the log
    at t_start + k speed / fps (joint positions interpolated between rows),
    up to t_end (default the log's first and last times); duration (s)
    fixes the video's length instead (the last pose is held if the log ends
    first).

    path: None, or a file name ending in .mp4 (H.264, through
    imageio-ffmpeg's bundled ffmpeg) or .gif (Pillow), written before
    returning; quality: MP4 0..10 (default 7). The returned
    :class:`Animation` also displays inline in a notebook (an HTML5 video)
    and has ``.save(path)``, ``.frames()`` and ``.animation`` (a matplotlib
    FuncAnimation).

    What each frame shows, all given per log row (len(log.t) rows):

    - reference: True (default) draws each robot's logged q_ref as a
      transparent blue ghost, False none, or per robot a (rows, n) array
      (None for no ghost of that robot).
    - holding: the robot's moving links are green while it holds. None
      (default) or 'shared': from the log (``log[i].holding``), in the rows
      where the robot holds a body that another robot holds too (the
      paper's convention, its Fig. 18: green while both hold the bar);
      'any': in the rows where it holds anything (one robot carrying a
      body); see :func:`~coopsim.view.holding_from_log`. False: never, True:
      always; or per robot a (rows,) bool array (or None). A (rows, robots)
      array is accepted too. (With collision_boxes=True the boxes show
      their contacts instead.)
    - collision_boxes: colour every box green (free) or red where colliding
      is True; colliding: per robot a (rows, boxes) bool mask in
      robot.boxes order (default: from the log's contact events, see
      :func:`~coopsim.view.colliding_from_log`; all free without them).
    - contacts: a sequence of rows entries, each an (m, 2, 3) array of
      (point, normal) pairs (m) or None: red lines along the normals
      (default with collision_boxes=True: the log's contact points when
      the simulation kept them, log_contacts=True, see
      :func:`~coopsim.view.contacts_from_log`; False: none).
    - bodies: a list of :class:`Body` (the bar, scenery), poses fixed or
      one per row ((rows, 4, 4) or (rows, m, 4, 4)), drawn before the
      world's.
    - label: True for "t = ... s" at the top left and the speed at the
      top right, False for none, or a function of t (s) returning the
      text at the top left.

    - inset: True adds a zoom on the held body (the log's
      ``log[i].holding``) in the upper right: its limits follow the body and
      the clamps holding it, frame by frame; hidden while nothing is held
      (see :func:`~coopsim.view.draw`).

    ax: a 3D Axes to draw into (default a new figsize-inch figure at dpi,
    not managed by pyplot, so a notebook shows only the video).
    scene_options go to the :class:`Scene` (floor, tile, colors, limits,
    elev, azim, zoom, axis, contact_length, edges, cull: see
    :func:`~coopsim.view.draw`); the camera is fixed, so cull defaults to
    True.

    Raises ValueError naming the argument: speed outside 0..4, fps <= 0,
    arrays of the wrong shape, times outside the log, an unknown suffix, a
    world that is not a World or Simulation.
    """
    # ---- arguments ----
    sim = None
    if _is_simulation(log):
        sim = log
        log = sim.log
        if robots is None:
            robots = sim.robots
    elif _is_simulation(robots):
        sim = robots
    wld, _ = resolve_world(sim if world is None else world, "world")
    if robots is None:
        raise ValueError("robots must be given with a log (the simulated robots in log order), or pass the "
                         "Simulation itself")
    robots = _robot_list(robots, allow_empty=wld is not None)
    fps = _checks.number(fps, "fps")
    if not 0 < fps <= 1000:
        raise ValueError(f"fps must be > 0 (and at most 1000) frames per second, got {fps!r}")
    speed = _checks.number(speed, "speed")
    if not 0 <= speed <= MAX_SPEED:
        raise ValueError(f"speed must be between 0 (pause) and {MAX_SPEED:g} (400 %), got {speed!r}")
    if path is not None:
        _suffix(path)
    if not hasattr(log, "t") or not hasattr(log, "robots"):
        raise ValueError(f"log must be a coopsim.SimulationLog, got {type(log).__name__}")
    if hasattr(log, "check"):
        log.check(poses=True)
    t_log = np.asarray(log.t, dtype=float)
    rows = len(t_log)
    if rows == 0:
        raise ValueError("log is empty: run the simulation (with log_every > 0) first")
    if len(log.robots) != len(robots):
        raise ValueError(f"robots must match the log's robots: the log has {len(log.robots)}, got {len(robots)}")
    for i, (rl, r) in enumerate(zip(log.robots, robots)):
        if rl.q.shape[1] != r.dof:
            raise ValueError(f"robots[{i}] has {r.dof} joints but the log's robot {i} ({rl.name}) has {rl.q.shape[1]}")
    t0 = float(t_log[0]) if t_start is None else _checks.number(t_start, "t_start")
    t1 = float(t_log[-1]) if t_end is None else _checks.number(t_end, "t_end")
    eps = 1e-9 * max(1.0, abs(t_log[-1]))
    if not t_log[0] - eps <= t0 <= t_log[-1] + eps:
        raise ValueError(f"t_start must be within the log's times [{t_log[0]:g}, {t_log[-1]:g}] s, got {t0!r}")
    if not t0 <= t1 <= t_log[-1] + eps:
        raise ValueError(f"t_end must be within [t_start, last log time] = [{t0:g}, {t_log[-1]:g}] s, got {t1!r}")
    if duration is not None:
        duration = _checks.number(duration, "duration")
        if duration <= 0:
            raise ValueError(f"duration must be > 0 s, got {duration!r}")
        frames = duration * fps
    elif speed == 0:
        raise ValueError("speed 0 (pause) needs a duration (s) for the video")
    else:
        frames = (t1 - t0) * fps / speed
    if not frames <= 1_000_000:
        raise ValueError(f"{frames:.3g} frames is too many: lower fps, raise speed or shorten t_end - t_start"
                         + (" (or the duration)" if duration is not None else ""))
    n_frames = max(1, int(round(frames))) if duration is not None else int(math.floor(frames + 1e-9)) + 1
    times = np.minimum(t0 + np.arange(n_frames) * (speed / fps), t1)

    n = len(robots)
    Q = [_interp(t_log, np.asarray(rl.q, dtype=float), times) for rl in log.robots]
    if reference is True:
        R = [_interp(t_log, np.asarray(rl.q_ref, dtype=float), times) for rl in log.robots]
    elif reference is False or reference is None:
        R = [None] * n
    else:
        given = _per_robot_rows(reference, n, rows, "reference", [(r.dof,) for r in robots])
        R = [None if g is None else _interp(t_log, g, times) for g in given]
    at = rows_at(t_log, times)
    if holding is None or isinstance(holding, str):
        mode = _holding_mode("shared" if holding is None else holding, "holding")
        holding = holding_from_log(log, mode=mode)
    elif isinstance(holding, (bool, np.bool_)):
        holding = [np.full(rows, bool(holding))] * n
    H = _per_robot_rows(holding, n, rows, "holding", [()] * n, dtype=bool)
    if colliding is not None and not collision_boxes:
        raise ValueError("colliding is shown only with collision_boxes=True")
    if collision_boxes and colliding is None and len(log.contacts):
        colliding = colliding_from_log(log, robots)
    if contacts is False:
        contacts = None
    elif contacts is None and collision_boxes:
        contacts = contacts_from_log(log)
    C = _per_robot_rows(colliding, n, rows, "colliding", [(len(r.boxes),) for r in robots], dtype=bool)
    if contacts is not None:
        if len(contacts) != rows:
            raise ValueError(f"contacts must hold one entry per log row ({rows}), got {len(contacts)}")
        contacts = [None if contacts[k] is None else _contacts(contacts[k], f"contacts[{k}]") for k in sorted(set(at))]
        contacts = dict(zip(sorted(set(at)), contacts))
    if bodies is None:
        bodies = []
    elif isinstance(bodies, Body):
        bodies = [bodies]
    else:
        bodies = list(bodies)
    if wld is not None:
        bodies = bodies + world_bodies(sim if sim is not None and sim.world is wld else wld, log, rows=rows)
    checked_bodies = []
    for j, b in enumerate(bodies):
        if not isinstance(b, Body):
            raise ValueError(f"bodies[{j}] must be a coopsim.view.Body, got {type(b).__name__}")
        checked_bodies.append((b, b._checked(f"bodies[{j}]", rows=rows)))
    if label is True:
        def label_fn(t):
            return f"t = {t:.2f} s"
    elif label is False or label is None:
        label_fn = None
    elif callable(label):
        label_fn = label
    else:
        raise ValueError(f"label must be True, False or a function of t (s), got {label!r}")

    def body_at(b, chk, k):
        h, p, _ = chk
        pose = p if p.ndim == 3 else p[at[k]]
        return Body(b.name, h, pose, b.color, b.alpha, b.scenery, b.tiled)

    held_rows = [np.asarray(rl.holding, dtype=object) for rl in log.robots] if inset else None

    def frame_args(k: int) -> dict:
        r = at[k]
        extra = {} if held_rows is None else dict(held=[str(h[r]) or None for h in held_rows])
        return dict(
            **extra,
            q=[Q[i][k] for i in range(n)],
            reference=[None if R[i] is None else R[i][k] for i in range(n)],
            holding=[False if H[i] is None else bool(H[i][r]) for i in range(n)],
            colliding=[None if C[i] is None else C[i][r] for i in range(n)] if collision_boxes else None,
            contacts=None if contacts is None else contacts[r],
            bodies=[body_at(b, chk, k) for b, chk in checked_bodies],
        )

    # ---- the scene: fixed camera, floor and limits fitted to every frame ----
    if ax is None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # matplotlib loads only to draw
        from matplotlib.figure import Figure  # matplotlib loads only to draw

        dpi = _checks.number(dpi, "dpi")
        w, h = figsize
        fig = Figure(figsize=(w, h), dpi=dpi)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(projection="3d")
        fig.subplots_adjust(0, 0, 1, 1)
    elif getattr(ax, "name", None) != "3d":
        raise ValueError("ax must be a 3D Axes (fig.add_subplot(projection='3d')) or None")
    scene_options.setdefault("cull", True)       # the camera does not move
    if wld is not None:
        scene_options.setdefault("floor", bool(wld.floor))
    if not robots and not checked_bodies:
        raise ValueError("nothing to draw: the log has no robots and the world no bodies")
    scene = Scene(ax, robots, collision_boxes=collision_boxes, inset=inset, **scene_options)
    pts = []
    sample = np.unique(np.linspace(0, n_frames - 1, min(n_frames, 200)).astype(int))
    for k in sample:
        for i, r in enumerate(robots):
            for qq in (Q[i][k], None if R[i] is None else R[i][k]):
                if qq is not None:
                    pts.append(box_corners(*r.shapes(qq)).reshape(-1, 3))
        for b, (hb, p, _) in checked_bodies:
            pts.append(box_corners(p if p.ndim == 3 else p[at[k]], hb).reshape(-1, 3))
    # the camera: robots and bodies seen past each other over a few frames (azim=None)
    few = sample[np.unique(np.linspace(0, len(sample) - 1, min(len(sample), 8)).astype(int))]
    scene.choose_azimuth([[(True, *r.shapes(Q[i][k]), False) for i, r in enumerate(robots)]
                          + [(False, p if p.ndim == 3 else p[at[k]], hb, b.scenery and p.ndim == 3)
                             for b, (hb, p, _) in checked_bodies] for k in few])
    pts = np.concatenate(pts)
    if not np.all(np.abs(pts) <= 1e6):
        raise ValueError("the log puts boxes more than 1e6 m from the origin (q, q_ref or a body's pose)")
    scene.fit(pts)
    if label is True:
        # the part that does not change goes into the background (text costs about 0.1 ms a glyph)
        ax.figure.text(0.98, 0.975, f"speed {100 * speed:.0f} %", va="top", ha="right", fontsize=9)
    anim = Animation(scene, times, fps, speed, frame_args, label_fn)
    anim.show_frame(0)
    if path is not None:
        anim.save(path, quality=quality)
    return anim
