"""Simulation loop, data log, time control and batch runs.

The stepping is C++ (``coopsim._core.SimulationCore``): RK4 at a fixed step
(default 0.2 ms), the controllers updated every ``control_every`` steps with
the torque held in between (zero-order hold) and saturated at the actuator
limits, the log written into storage reserved before each run. This module
adds what a user handles in Python:

- :class:`Simulation`: robots with controllers and references; ``run``
  (headless, as fast as possible, progress bar on long runs), ``step``,
  ``run_paced`` (wall-clock pacing from 0 % to 400 % of real time), picklable
  description;
- :class:`SimulationLog` / :class:`RobotLog`: the paper's DataManager as numpy
  arrays, with pandas, CSV and Excel export (atomic writes) and a plot;
- :class:`Pacer`: the paper's FrameRate and speed control;
- :func:`run_batch` and :func:`simulate`: many independent runs on threads, or
  through any ``concurrent.futures`` executor.

Units: s, rad or m, N m or N. Arrays are float64; per-robot arrays are
(rows, n) with one row per logged step.
"""
from __future__ import annotations

import math
import os
import re
import tempfile
import time
from dataclasses import dataclass
from typing import Callable, Iterator, List, Optional, Sequence

import numpy as np

from . import _core
from ._core import ComputedTorque, Controller, DivergenceError, PID, Robot

__all__ = [
    "ComputedTorque",
    "Controller",
    "DivergenceError",
    "PID",
    "Pacer",
    "RobotLog",
    "RunStats",
    "Simulation",
    "SimulationLog",
    "run_batch",
    "simulate",
]

#: Logged quantities per robot, in column order.
QUANTITIES = ("q", "qd", "qdd", "tau", "q_ref", "qd_ref", "e")

# by default a headless run of at least this many steps shows a progress bar
# once it has lasted _PROGRESS_DELAY s of wall time
_PROGRESS_MIN_STEPS = 10_000
_PROGRESS_DELAY = 1.0
_INT_MAX = 2**31 - 1  # the engine's int and long counters
_LONG_MAX = 2**63 - 1
# Excel's sheet size (rows include the header)
_EXCEL_MAX_ROWS = 1_048_576


# ---------------------------------------------------------------------------
# statistics


@dataclass(frozen=True)
class RunStats:
    """Timing of a run (the paper's time supervision window).

    sim_time: simulated time at the end (s); sim_elapsed: simulated time
    covered by this run (s); wall_time: wall-clock duration (s); busy_time:
    wall time spent stepping (s); step_size: dt (s); steps: steps taken;
    steps_per_second: steps / busy_time (the engine's speed);
    real_time_factor: sim_elapsed / wall_time (1 = real time; for a paced
    run, about the speed setting); frames and frame_rate (Hz): frames drawn
    by a paced run (0 for headless runs).
    """

    sim_time: float
    sim_elapsed: float
    wall_time: float
    busy_time: float
    step_size: float
    steps: int
    steps_per_second: float
    real_time_factor: float
    frames: int = 0
    frame_rate: float = 0.0

    @staticmethod
    def _make(sim_time, sim_elapsed, wall, busy, dt, steps, frames=0):
        return RunStats(
            sim_time=float(sim_time),
            sim_elapsed=float(sim_elapsed),
            wall_time=float(wall),
            busy_time=float(busy),
            step_size=float(dt),
            steps=int(steps),
            steps_per_second=steps / busy if busy > 0 else math.inf if steps else 0.0,
            real_time_factor=sim_elapsed / wall if wall > 0 else math.inf if sim_elapsed else 0.0,
            frames=int(frames),
            frame_rate=frames / wall if wall > 0 else 0.0,
        )

    def __str__(self) -> str:
        return (f"sim time {self.sim_time:.4f} s (+{self.sim_elapsed:.4f} s), wall {self.wall_time:.4f} s, "
                f"step {self.step_size * 1e3:.4g} ms, {self.steps} steps, {self.steps_per_second:,.0f} steps/s, "
                f"real-time factor {self.real_time_factor:.3g}"
                + (f", {self.frames} frames ({self.frame_rate:.1f}/s)" if self.frames else ""))


# ---------------------------------------------------------------------------
# logs


class RobotLog:
    """One robot's log: every array has one row per logged step.

    t (rows,) s; q, qd, qdd (rows, n) rad, rad/s, rad/s^2 (m... for prismatic
    joints); tau (rows, n) N m or N, the torque applied from that row's time
    to the next step (held, saturated); q_ref, qd_ref (rows, n) the reference
    at that time; error = q_ref - q. Arrays taken from a simulation are
    read-only views of its log (later steps or a reset do not change them);
    copy one to modify it.
    """

    __slots__ = ("name", "t", "q", "qd", "qdd", "tau", "q_ref", "qd_ref")

    def __init__(self, name, t, q, qd, qdd, tau, q_ref, qd_ref):
        self.name = str(name)
        self.t = t
        self.q, self.qd, self.qdd, self.tau = q, qd, qdd, tau
        self.q_ref, self.qd_ref = q_ref, qd_ref

    def __getstate__(self):
        return {k: getattr(self, k) for k in self.__slots__}

    def __setstate__(self, state):
        for k, v in state.items():
            setattr(self, k, v)

    @property
    def dof(self) -> int:
        return self.q.shape[1]

    @property
    def error(self) -> np.ndarray:
        """Tracking error q_ref - q, (rows, n)."""
        return self.q_ref - self.q

    e = error

    @property
    def qd_error(self) -> np.ndarray:
        """Velocity error qd_ref - qd, (rows, n)."""
        return self.qd_ref - self.qd

    def rms_error(self) -> np.ndarray:
        """Root-mean-square tracking error per joint over the logged rows, (n,)."""
        if len(self.t) == 0:
            return np.zeros(self.dof)
        return np.sqrt(np.mean(self.error ** 2, axis=0))

    def __len__(self) -> int:
        return len(self.t)

    def __repr__(self) -> str:
        return f"<RobotLog '{self.name}' {len(self.t)} rows x {self.dof} joints>"


class SimulationLog:
    """The log of a simulation (the paper's DataManager).

    ``log.t`` (rows,) s; ``log[i]`` or ``log.robots[i]`` is robot i's
    :class:`RobotLog`. With a single robot, ``log.q``, ``log.tau`` ... are
    that robot's arrays. Export: :meth:`to_dataframe`, :meth:`to_csv`,
    :meth:`to_excel`; read back with :meth:`read_csv`, :meth:`read_excel`.
    """

    def __init__(self, t: np.ndarray, robots: Sequence[RobotLog], *, dt: Optional[float] = None,
                 control_every: Optional[int] = None, log_every: Optional[int] = None):
        self.t = t
        self.robots: List[RobotLog] = list(robots)
        self.dt = dt
        self.control_every = control_every
        self.log_every = log_every

    # single-robot shortcuts
    def __getattr__(self, name):
        if name.startswith("_") or name not in (*QUANTITIES, "error", "qd_error", "rms_error", "dof", "name"):
            raise AttributeError(name)
        robots = self.__dict__.get("robots", [])
        if len(robots) != 1:
            raise AttributeError(f"the log holds {len(robots)} robots: use log[i].{name}")
        return getattr(robots[0], name)

    def __getitem__(self, i: int) -> RobotLog:
        return self.robots[i]

    def __iter__(self) -> Iterator[RobotLog]:
        return iter(self.robots)

    def __len__(self) -> int:
        return len(self.t)

    def __repr__(self) -> str:
        return (f"<SimulationLog {len(self.t)} rows, robots: "
                f"{', '.join(r.name for r in self.robots) or 'none'}>")

    @property
    def labels(self) -> List[str]:
        """Column prefixes: robot names, made unique with _<index> when repeated."""
        names = [r.name for r in self.robots]
        return [n if names.count(n) == 1 else f"{n}_{i}" for i, n in enumerate(names)]

    # ---- tables ----

    def columns(self) -> List[str]:
        """Column names: 't', then '<label>.<quantity><joint>' (joints from 1)."""
        cols = ["t"]
        for label, r in zip(self.labels, self.robots):
            cols += [f"{label}.{qty}{j + 1}" for qty in QUANTITIES for j in range(r.dof)]
        return cols

    def to_array(self) -> np.ndarray:
        """All columns as one (rows, columns) float64 array, in :meth:`columns` order."""
        parts = [self.t[:, None]]
        for r in self.robots:
            parts += [getattr(r, "error" if qty == "e" else qty) for qty in QUANTITIES]
        return np.hstack(parts) if parts else np.zeros((0, 1))

    def to_dataframe(self):
        """A pandas DataFrame, one row per logged step, columns as :meth:`columns`."""
        import pandas as pd

        return pd.DataFrame(self.to_array(), columns=self.columns())

    @classmethod
    def from_dataframe(cls, df) -> "SimulationLog":
        """Rebuilds a log from :meth:`to_dataframe`'s layout (e.g. read from CSV or Excel)."""
        cols = [str(c) for c in df.columns]
        if not cols or cols[0] != "t":
            raise ValueError("df must start with a 't' column")
        data = np.asarray(df.to_numpy(dtype=np.float64))
        pat = re.compile(r"^(.*)\.(q|qd|qdd|tau|q_ref|qd_ref|e)(\d+)$")
        order: List[str] = []
        found = {}
        for k, c in enumerate(cols[1:], start=1):
            m = pat.match(c)
            if not m:
                raise ValueError(f"df column {c!r} is not '<robot>.<quantity><joint>'")
            label, qty, j = m.group(1), m.group(2), int(m.group(3))
            if label not in found:
                order.append(label)
                found[label] = {}
            found[label].setdefault(qty, {})[j] = k
        t = data[:, 0].copy()
        robots = []
        for label in order:
            q = found[label]
            missing = [x for x in QUANTITIES if x not in q]
            if missing:
                raise ValueError(f"df lacks {missing} columns for robot {label!r}")
            n = len(q["q"])
            arrays = {}
            for qty in QUANTITIES[:-1]:
                idx = [q[qty].get(j + 1) for j in range(n)]
                if None in idx or len(q[qty]) != n:
                    raise ValueError(f"df columns of {label}.{qty} are not joints 1..{n}")
                arrays[qty] = data[:, idx].copy()
            robots.append(RobotLog(label, t, **arrays))
        dt = float(t[1] - t[0]) if len(t) > 1 else None
        return cls(t, robots, dt=dt)

    # ---- files (written to a temporary file, then renamed over the target) ----

    def to_csv(self, path) -> str:
        """Writes the table as CSV (full precision) to path atomically; returns the path."""
        df = self.to_dataframe()
        return _atomic_write(path, ".csv", lambda tmp: df.to_csv(tmp, index=False, float_format="%.17g"))

    def to_excel(self, path, sheet_name: str = "log") -> str:
        """Writes the table to an .xlsx workbook (openpyxl) atomically: sheet `sheet_name` holds the
        data, sheet 'info' the step size and robots. Raises ValueError past Excel's row limit."""
        if len(self.t) + 1 > _EXCEL_MAX_ROWS:
            raise ValueError(f"the log has {len(self.t)} rows, more than an Excel sheet holds "
                             f"({_EXCEL_MAX_ROWS - 1}): log less often (log_every) or use to_csv")
        import pandas as pd

        df = self.to_dataframe()
        info = pd.DataFrame({
            "key": ["dt", "control_every", "log_every"] + [f"robot {i}" for i in range(len(self.robots))],
            "value": [_none_str(self.dt), _none_str(self.control_every), _none_str(self.log_every)]
            + [f"{lab} ({r.dof} joints)" for lab, r in zip(self.labels, self.robots)],
        })

        def write(tmp):
            with pd.ExcelWriter(tmp, engine="openpyxl") as xw:
                df.to_excel(xw, sheet_name=sheet_name, index=False)
                info.to_excel(xw, sheet_name="info", index=False)

        return _atomic_write(path, ".xlsx", write)

    @classmethod
    def read_csv(cls, path) -> "SimulationLog":
        """Reads a log written by :meth:`to_csv`."""
        import pandas as pd

        # exact decimal -> binary parsing: the default from pandas 3, an option before
        exact = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
        return cls.from_dataframe(pd.read_csv(path, **exact))

    @classmethod
    def read_excel(cls, path, sheet_name: str = "log") -> "SimulationLog":
        """Reads a log written by :meth:`to_excel`."""
        import pandas as pd

        return cls.from_dataframe(pd.read_excel(path, sheet_name=sheet_name, engine="openpyxl"))

    def plot(self, robot: int = 0, quantity: str = "q", **kwargs):
        """Joints against time, one panel each, references dashed; see coopsim.plotting.plot_log."""
        from .plotting import plot_log

        return plot_log(self, robot=robot, quantity=quantity, **kwargs)


def _none_str(v):
    return "" if v is None else str(v)


def _atomic_write(path, suffix: str, write: Callable[[str], None]) -> str:
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=suffix, dir=folder)
    os.close(fd)
    try:
        write(tmp)
        # mkstemp makes the file private; give it the usual mode
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


# ---------------------------------------------------------------------------
# the simulation


class Simulation:
    """One or more robots, each with a controller and a reference, stepped by RK4.

    dt: step size (s, default 0.2 ms, the paper's). control_every: the
    controllers run every k-th step and their torque is held in between
    (zero-order hold); the log shows the held torque. log_every: log every
    n-th step (0: no log; tracking metrics still cover every step).
    end_stops: joints beyond their limits meet the robot's spring-damper
    stops. max_speed (rad/s or m/s) and max_position (rad or m): a state
    beyond them, or a non-finite one, stops the run with
    :class:`DivergenceError` (naming step, time, robot and state); the log
    keeps every row up to the last good step.

    The description (options, robots, controllers, references, initial
    states) pickles; the state and log do not, so an unpickled simulation
    starts at t = 0.
    """

    def __init__(self, dt: float = 2e-4, *, control_every: int = 1, log_every: int = 1, end_stops: bool = True,
                 max_speed: float = 1e4, max_position: float = 1e6):
        for name, v in (("dt", dt), ("max_speed", max_speed), ("max_position", max_position)):
            if not isinstance(v, (int, float, np.floating, np.integer)) or isinstance(v, bool):
                raise ValueError(f"{name} must be a number, got {v!r}")
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be finite and > 0, got {v!r}")
        for name, v, lo in (("control_every", control_every, 1), ("log_every", log_every, 0)):
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or not lo <= v <= _INT_MAX:
                raise ValueError(f"{name} must be an integer in {lo} .. {_INT_MAX}, got {v!r}")
        self._options = dict(dt=float(dt), control_every=int(control_every), log_every=int(log_every),
                             end_stops=bool(end_stops), max_speed=float(max_speed),
                             max_position=float(max_position))
        self._core = _core.SimulationCore(**self._options)
        self._entries: list = []
        self.stats: Optional[RunStats] = None

    # ---- building ----

    def add_robot(self, robot: Robot, controller: Controller, reference, *, q0=None, qd0=None) -> int:
        """Adds `robot` (copied) driven by `controller` towards `reference`; returns its index.

        reference: a coopsim.Reference (e.g. CubicTrajectory, or a Python
        subclass) or a set-point array (n,) held at all times. q0, qd0 (n,):
        the initial state, by default the reference's q and qd at t = 0.
        Each robot needs its own controller instance (controllers keep state).
        """
        if not isinstance(robot, Robot):
            raise ValueError(f"robot must be a coopsim.Robot, got {type(robot).__name__}")
        if not isinstance(controller, Controller):
            raise ValueError(f"controller must be a coopsim.Controller (PID, ComputedTorque or a subclass), "
                             f"got {type(controller).__name__}")
        i = self._core.add_robot(robot, controller, reference, q0, qd0)
        keep = lambda a: None if a is None else np.array(a, dtype=np.float64)  # noqa: E731
        self._entries.append((robot, controller, reference if isinstance(reference, _core.Reference)
                              else keep(reference), keep(q0), keep(qd0)))
        return i

    # ---- description ----

    @property
    def dt(self) -> float:
        """Step size, s."""
        return self._options["dt"]

    @property
    def control_every(self) -> int:
        return self._options["control_every"]

    @property
    def log_every(self) -> int:
        return self._options["log_every"]

    @property
    def options(self) -> dict:
        """The constructor's keyword arguments."""
        return dict(self._options)

    @property
    def robots(self) -> List[Robot]:
        return [e[0] for e in self._entries]

    @property
    def controllers(self) -> List[Controller]:
        return [e[1] for e in self._entries]

    @property
    def references(self) -> list:
        return [e[2] for e in self._entries]

    @property
    def robot_count(self) -> int:
        return len(self._entries)

    def __getstate__(self):
        return {"options": self._options, "entries": self._entries}

    def __setstate__(self, state):
        self.__init__(**state["options"])
        for robot, controller, reference, q0, qd0 in state["entries"]:
            self.add_robot(robot, controller, reference, q0=q0, qd0=qd0)

    def __repr__(self) -> str:
        names = ", ".join(f"{r.name}/{type(c).__name__}" for r, c, *_ in self._entries) or "no robots"
        return f"<coopsim.Simulation dt={self.dt:g} s, t={self.time:.6g} s, {names}>"

    # ---- state ----

    @property
    def time(self) -> float:
        """Simulated time now, s."""
        return self._core.time

    @property
    def steps(self) -> int:
        """Steps taken since t = 0."""
        return self._core.steps

    @property
    def diverged(self) -> bool:
        return self._core.diverged

    def state(self, robot: int = 0):
        """(q, qd) of a robot now, each (n,)."""
        return self._core.state(_index(robot, self.robot_count))

    def torque(self, robot: int = 0) -> np.ndarray:
        """The torque held on a robot now, (n,) (saturated)."""
        return self._core.torque(_index(robot, self.robot_count))

    def reset(self) -> None:
        """Back to t = 0 and the initial states; clears the log, metrics and statistics.
        Controllers are reset at the next step."""
        self._core.reset()
        self.stats = None

    # ---- running ----

    def step(self, n: int = 1) -> float:
        """Advances n steps (GIL released); returns the new time (s)."""
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or not 0 <= n <= _LONG_MAX:
            raise ValueError(f"n must be an integer in 0 .. {_LONG_MAX}, got {n!r}")
        t0, s0, w0 = self.time, self.steps, time.perf_counter()
        try:
            self._core.advance(int(n))
        finally:
            w = time.perf_counter() - w0
            self.stats = RunStats._make(self.time, self.time - t0, w, w, self.dt, self.steps - s0)
        return self.time

    def run(self, t_end: float, *, progress: Optional[bool] = None) -> SimulationLog:
        """Runs headless, as fast as the machine allows, up to time t_end (s); returns the log.

        The loop is C++ with the GIL released (Python controllers or
        references take it for their own calls). progress: True shows a
        tqdm bar, False never; None (default) shows one on a run of 10 000
        steps or more once it has lasted a second. Ctrl-C stops the run
        between chunks with the log kept. Statistics go to :attr:`stats`.
        """
        if not isinstance(t_end, (int, float, np.floating, np.integer)) or isinstance(t_end, bool) \
                or not math.isfinite(t_end):
            raise ValueError(f"t_end must be a finite number of seconds, got {t_end!r}")
        total = self._core.steps_until(float(t_end))
        bar = None
        if progress or (progress is None and total >= _PROGRESS_MIN_STEPS):
            from tqdm import tqdm

            bar = tqdm(total=total, unit="step", unit_scale=True, delay=0.0 if progress else _PROGRESS_DELAY,
                       desc="simulating", leave=False)
        cb = None if bar is None else (lambda done, tot: bar.update(done - bar.n))
        t0, s0, w0 = self.time, self.steps, time.perf_counter()
        try:
            self._core.run(float(t_end), cb)
        finally:
            if bar is not None:
                bar.close()
            w = time.perf_counter() - w0
            self.stats = RunStats._make(self.time, self.time - t0, w, w, self.dt, self.steps - s0)
        return self.log

    def run_paced(self, t_end: float, *, speed: float = 1.0, frame_rate: float = 60.0,
                  on_frame: Optional[Callable] = None, max_wall_time: Optional[float] = None,
                  pacer: Optional["Pacer"] = None) -> RunStats:
        """Runs up to t_end (s) paced to the wall clock at `speed` x real time (0 .. 4; 2.0 = 200 %).

        Every frame (frame_rate per second) the simulation advances by the
        wall time since the last frame times the speed, then calls
        on_frame(sim, pacer) for live drawing or control; it may change
        pacer.speed, pause()/resume() or stop(), or return False to stop.
        Pass your own `pacer` to keep control from outside. Returns (and
        stores in :attr:`stats`) the run's statistics.
        """
        if pacer is None:
            pacer = Pacer(speed=speed, frame_rate=frame_rate)
        return pacer.run(self, t_end, on_frame=on_frame, max_wall_time=max_wall_time)

    # ---- results ----

    @property
    def log(self) -> SimulationLog:
        """The log up to now: read-only views, without copying, that later steps do not change."""
        t = self._core.log_t()
        robots = []
        for i, (robot, *_rest) in enumerate(self._entries):
            robots.append(RobotLog(robot.name, t, **self._core.log(i)))
        return SimulationLog(t, robots, dt=self.dt, control_every=self.control_every, log_every=self.log_every)

    def metrics(self) -> List[dict]:
        """Per robot, tracking metrics over every step so far (whatever log_every):
        name, steps, rms_error (n,), max_abs_error (n,), max_abs_tau (n,)."""
        out = []
        for i, (robot, *_rest) in enumerate(self._entries):
            m = self._core.metrics(i)
            m["name"] = robot.name
            out.append(m)
        return out


def _index(i, n):
    if not isinstance(i, (int, np.integer)) or isinstance(i, bool) or not -n <= i < n:
        raise ValueError(f"robot must be an index in [0, {n}), got {i!r}")
    return int(i) % n


# ---------------------------------------------------------------------------
# time control


class Pacer:
    """Paces a simulation to wall-clock time: the paper's FrameRate and speed control.

    speed: simulated seconds per wall second, 0 (pause) to 4 (400 %).
    frame_rate: frames per second (Hz); each frame advances the simulation by
    the wall time since the previous frame times the speed (at most
    max_catch_up s of wall time, so a stall does not become a burst), calls
    the frame callback, then sleeps until the next frame. pause() holds the
    simulated time still while frames go on; resume() continues at the speed
    set. clock and sleep can be replaced (e.g. for tests).
    """

    MAX_SPEED = 4.0

    def __init__(self, speed: float = 1.0, frame_rate: float = 60.0, *, max_catch_up: float = 0.25,
                 clock: Callable[[], float] = time.perf_counter, sleep: Callable[[float], None] = time.sleep):
        self.speed = speed
        self.frame_rate = frame_rate
        if not (isinstance(max_catch_up, (int, float)) and math.isfinite(max_catch_up) and max_catch_up > 0):
            raise ValueError(f"max_catch_up must be > 0 s, got {max_catch_up!r}")
        self.max_catch_up = float(max_catch_up)
        self._clock, self._sleep = clock, sleep
        self._paused = False
        self._stop = False
        self._live = None

    @property
    def speed(self) -> float:
        """Simulated seconds per wall second, 0 .. 4."""
        return self._speed

    @speed.setter
    def speed(self, v: float) -> None:
        if not isinstance(v, (int, float, np.floating, np.integer)) or isinstance(v, bool) \
                or not math.isfinite(v) or not 0.0 <= v <= self.MAX_SPEED:
            raise ValueError(f"speed must be between 0 (pause) and {self.MAX_SPEED:g} (400 %), got {v!r}")
        self._speed = float(v)

    @property
    def speed_percent(self) -> float:
        """The speed in percent of real time (0 .. 400)."""
        return 100.0 * self._speed

    @speed_percent.setter
    def speed_percent(self, v: float) -> None:
        if not isinstance(v, (int, float, np.floating, np.integer)) or isinstance(v, bool):
            raise ValueError(f"speed_percent must be a number from 0 to 400, got {v!r}")
        self.speed = v / 100.0

    @property
    def frame_rate(self) -> float:
        return self._frame_rate

    @frame_rate.setter
    def frame_rate(self, v: float) -> None:
        if not isinstance(v, (int, float, np.floating, np.integer)) or isinstance(v, bool) \
                or not math.isfinite(v) or not 0 < v <= 10_000:
            raise ValueError(f"frame_rate must be in (0, 10000] Hz, got {v!r}")
        self._frame_rate = float(v)

    @property
    def paused(self) -> bool:
        return self._paused

    def pause(self) -> None:
        """Holds simulated time still; frames continue."""
        self._paused = True

    def resume(self) -> None:
        self._paused = False

    def stop(self) -> None:
        """Ends the current run after this frame."""
        self._stop = True

    @property
    def stats(self) -> Optional[RunStats]:
        """Statistics of the run in progress (or the last one)."""
        if self._live is None:
            return None
        sim, t0, s0, w0, busy, frames = self._live
        return RunStats._make(sim.time, sim.time - t0, self._clock() - w0, busy, sim.dt, sim.steps - s0, frames)

    def run(self, sim: Simulation, t_end: float, *, on_frame: Optional[Callable] = None,
            max_wall_time: Optional[float] = None) -> RunStats:
        """Runs `sim` up to t_end (s) paced to the wall clock; returns the statistics."""
        if not isinstance(sim, Simulation):
            raise ValueError(f"sim must be a coopsim.Simulation, got {type(sim).__name__}")
        if not isinstance(t_end, (int, float, np.floating, np.integer)) or isinstance(t_end, bool) \
                or not math.isfinite(t_end):
            raise ValueError(f"t_end must be a finite number of seconds, got {t_end!r}")
        if max_wall_time is not None and not (math.isfinite(max_wall_time) and max_wall_time > 0):
            raise ValueError(f"max_wall_time must be > 0 s, got {max_wall_time!r}")
        if on_frame is not None and not callable(on_frame):
            raise ValueError("on_frame must be callable as on_frame(sim, pacer)")
        if (self._speed == 0 or self._paused) and on_frame is None and max_wall_time is None:
            raise ValueError("speed 0 (paused) with no on_frame and no max_wall_time would never finish")
        core = sim._core
        core.steps_until(float(t_end))  # checks t_end is not in the past
        self._stop = False
        clock = self._clock
        w0 = clock()
        last = w0
        target = sim.time
        t0, s0, busy, frames = sim.time, sim.steps, 0.0, 0
        self._live = [sim, t0, s0, w0, busy, frames]
        try:
            while not self._stop and core.steps_until(float(t_end)) > 0:
                start = clock()
                elapsed = min(start - last, self.max_catch_up)
                last = start
                if not self._paused:
                    target = min(float(t_end), max(target, sim.time) + elapsed * self._speed)
                n = core.steps_until(max(target, sim.time))
                if n:
                    b = clock()
                    core.advance(n)
                    busy += clock() - b
                frames += 1
                self._live[4:] = [busy, frames]
                if on_frame is not None and on_frame(sim, self) is False:
                    break
                if max_wall_time is not None and clock() - w0 >= max_wall_time:
                    break
                delay = start + 1.0 / self._frame_rate - clock()
                if delay > 0:
                    self._sleep(delay)
        finally:
            self._live[4:] = [busy, frames]
            sim.stats = self.stats
        return sim.stats


# ---------------------------------------------------------------------------
# batch runs


def _output(sim: Simulation, output: str):
    if output == "log":
        return sim.log
    if output == "metrics":
        return sim.metrics()
    return None


def _check_output(output):
    if output not in ("log", "metrics", "none"):
        raise ValueError(f"output must be 'log', 'metrics' or 'none', got {output!r}")


def run_batch(sims: Sequence[Simulation], t_end: float, *, threads: Optional[int] = None, output: str = "log",
              errors: str = "raise") -> list:
    """Runs many independent simulations up to t_end (s) in one call, on threads.

    The stepping is C++ on a pool of `threads` threads (None: every core)
    with the GIL released. Results, in the order of `sims`: their logs
    (output='log'), their per-robot metrics ('metrics', see
    Simulation.metrics) or None ('none'). A run that fails (e.g. diverges)
    does not stop the others: errors='raise' raises the first failure after
    all have finished, errors='return' puts the exception in its place.
    The simulations must not share controller instances. Each keeps its own
    state and log afterwards, exactly as if run one by one; its ``stats``
    give the wall time of its own run (runs overlap on the threads, so the
    batch takes less than their sum).
    """
    sims = list(sims)
    for i, s in enumerate(sims):
        if not isinstance(s, Simulation):
            raise ValueError(f"sims[{i}] must be a coopsim.Simulation, got {type(s).__name__}")
    _check_output(output)
    if errors not in ("raise", "return"):
        raise ValueError(f"errors must be 'raise' or 'return', got {errors!r}")
    if threads is None:
        threads = 0
    if not isinstance(threads, (int, np.integer)) or isinstance(threads, bool) or threads < 0:
        raise ValueError(f"threads must be an integer >= 1 (or None for every core), got {threads!r}")
    if not isinstance(t_end, (int, float, np.floating, np.integer)) or not math.isfinite(t_end):
        raise ValueError(f"t_end must be a finite number of seconds, got {t_end!r}")
    for i, s in enumerate(sims):
        if not s.robot_count:
            raise ValueError(f"sims[{i}] has no robot")
        s._core.steps_until(float(t_end))  # t_end in the past -> ValueError now, not per thread
    marks = [(s.time, s.steps) for s in sims]
    errs, seconds = _core.run_batch([s._core for s in sims], float(t_end), int(threads))
    results = []
    first = None
    for i, (s, e, (t0, k0)) in enumerate(zip(sims, errs, marks)):
        # each run's own wall time: the runs overlap on the threads
        s.stats = RunStats._make(s.time, s.time - t0, seconds[i], seconds[i], s.dt, s.steps - k0)
        if e is not None:
            if first is None:
                first = (i, e)
            results.append(e)
        else:
            results.append(_output(s, output))
    if first is not None and errors == "raise":
        i, e = first
        if hasattr(e, "add_note"):
            e.add_note(f"raised by sims[{i}] of the batch")
        raise e
    return results


def simulate(sim: Simulation, t_end: float, output: str = "log"):
    """Runs `sim` headless up to t_end (s) and returns its log, metrics or None (see run_batch).

    A module-level function, so a sweep can go through any
    concurrent.futures executor: ``pool.map(functools.partial(simulate,
    t_end=2.0), sims)`` pickles each simulation's description to a worker
    and its log back.
    """
    _check_output(output)
    if not isinstance(sim, Simulation):
        raise ValueError(f"sim must be a coopsim.Simulation, got {type(sim).__name__}")
    sim.run(t_end, progress=False)
    return _output(sim, output)
