"""The data log of a simulation (the paper's DataManager) and its export.

:class:`SimulationLog` holds the logged time and one :class:`RobotLog` per
robot as numpy arrays; it exports to pandas, CSV and Excel (written
atomically: a failure midway leaves any earlier file intact) and reads them
back. The columns per robot are the engine's log schema
(the engine's ``log_schema()``), defined once in C++, plus the tracking
error ``e`` derived from it for tables.

Units: s, rad or m, N m or N. Arrays are float64, (rows, n) per robot.
"""
from __future__ import annotations

import csv
import errno
import io
import math
import os
import re
import tempfile
import warnings
import zipfile
from typing import Callable, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from . import _checks
from ._core import cooperation_schema as _engine_cooperation_schema
from ._core import log_schema as _engine_log_schema
from .plotting import plot_log

__all__ = ["BODY_COLUMNS", "BodyLog", "QUANTITIES", "RobotLog", "SimulationLog", "cooperation_schema", "log_schema",
           "rows_at"]


def rows_at(t, times) -> np.ndarray:
    """The log row that held at each of `times` (s): the last row at or before it, whose state lasts from
    its time until the next row's. The one rule by which the views find a row for a time (a video frame,
    a replay's keyframe, a contact's beginning or end): the same time shows the same row everywhere.

    t: the log's times (rows,), ascending; two rows may share a time (when the applied inputs change
    between runs: the last of them holds from then on). A time less than 1e-9 of the log's time scale (at
    least 1e-9 s) before a row's counts as at it, so that computed times (t0 + k / fps) meet the rows they
    aim at. Times before the first row give the first row (0), after the last row the last. Returns int
    indices in the shape of `times`. ValueError for a log without rows.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or len(t) == 0:
        raise ValueError(f"t must be a log's times (rows,) with at least one row, got shape {t.shape}")
    eps = 1e-9 * max(1.0, abs(float(t[0])), abs(float(t[-1])))
    return np.clip(np.searchsorted(t, np.asarray(times, dtype=float) + eps, side="right") - 1, 0, len(t) - 1)


def log_schema() -> List[Tuple[str, str]]:
    """The quantities logged per robot, in column order: [(name, description)], one column per joint."""
    return [tuple(x) for x in _engine_log_schema()]


def cooperation_schema() -> List[Tuple[str, int, str]]:
    """The engine's log columns of a pair of robots holding one body, in row order:
    [(name, width, description)] (see :meth:`SimulationLog.cooperation`)."""
    return [tuple(x) for x in _engine_cooperation_schema()]


# where each cooperation quantity lies in a pair's row
_COOPERATION_SLICES = {}
for _name, _width, _ in cooperation_schema():
    _start = sum(s.stop - s.start for s in _COOPERATION_SLICES.values())
    _COOPERATION_SLICES[_name] = slice(_start, _start + _width)
_COOPERATION_WIDTH = sum(s.stop - s.start for s in _COOPERATION_SLICES.values())

#: Quantities stored per robot (the engine's schema), in column order.
STORED: Tuple[str, ...] = tuple(name for name, _ in log_schema())
#: Quantities in tables (CSV, Excel, DataFrame): the stored ones, then the error e = q_ref - q.
QUANTITIES: Tuple[str, ...] = STORED + ("e",)

# the world's extent, m: positions of bodies lie within it
_MAX_DISTANCE = 1e6
# Excel's sheet size (rows include the header)
_EXCEL_MAX_ROWS = 1_048_576


class RobotLog:
    """One robot's log: every array has one row per logged step.

    t (rows,) s, then one (rows, n) array per quantity of the engine's log
    schema (:data:`QUANTITIES`, described by :func:`log_schema`): q, qd, qdd
    (rad, rad/s, rad/s^2, or m... for prismatic joints); tau, the torque
    applied from that row's time to the next step (held, saturated), and
    tau_ext, the joint torque of the applied forces and wrenches over that
    step (N m or N); q_ref, qd_ref, qdd_ref, the reference at that time; error =
    q_ref - q. Beside them (not in the tables): holding and weld (the grasp), and
    ft_world, ft_clamp (rows, 6), the force/torque sensor's reading at the tool
    centre point (N, N m; Simulation.set_sensor). Arrays taken from a simulation are read-only views of its log
    (later steps or a reset do not change them); copy one to modify it.
    """

    __slots__ = ("name", "t", "holding", "weld", "ft_world", "ft_clamp", "joint_types") + STORED

    def __init__(self, name, t, holding=None, weld=None, joint_types=None, ft_world=None, ft_clamp=None, **arrays):
        missing = [k for k in STORED if k not in arrays]
        unknown = [k for k in arrays if k not in STORED]
        if missing or unknown:
            raise ValueError(f"RobotLog needs the arrays {list(STORED)}; missing {missing}, unknown {unknown}")
        self.name = str(name)
        self.t = t
        #: per row, the name of the body held ('' when none), and the weld's force on it and its moment about
        #: the weld's point, midway between the clamp's pads (rows, 6; N, N m, world frame)
        self.holding = np.full(len(t), "", dtype=object) if holding is None else holding
        self.weld = np.zeros((len(t), 6)) if weld is None else weld
        #: per row, the force/torque sensor's reading (rows, 6): force (N) and moment (N m) about the tool
        #: centre point that the robot's end applies to its environment (Simulation.set_sensor), in world
        #: axes (ft_world) and in the sensor frame, the tool frame (ft_clamp); zeros when unknown
        self.ft_world = np.zeros((len(t), 6)) if ft_world is None else ft_world
        self.ft_clamp = np.zeros((len(t), 6)) if ft_clamp is None else ft_clamp
        #: the robot's joint types, e.g. 'RRPRRP' (which joints are in rad, which in m), or None if unknown
        self.joint_types = joint_types
        for k in STORED:
            setattr(self, k, arrays[k])

    def __getstate__(self):
        return {k: getattr(self, k) for k in self.__slots__}

    def __setstate__(self, state):
        self.joint_types = None  # a log pickled before it had them
        rows = len(state["t"])
        self.ft_world = self.ft_clamp = np.zeros((rows, 6))  # nor these
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


class BodyLog:
    """One free body's log: t (rows,) s; position (rows, 3) m; quaternion
    (rows, 4) [w, x, y, z]; velocity (rows, 3) m/s of the centre; angular
    velocity (rows, 3) rad/s; all in the world, sampled at the world's steps
    (with world_every = k, held for k robot steps)."""

    __slots__ = ("name", "t", "data")

    def __init__(self, name, t, data):
        self.name, self.t, self.data = str(name), t, data

    position = property(lambda self: self.data[:, 0:3])
    quaternion = property(lambda self: self.data[:, 3:7])
    velocity = property(lambda self: self.data[:, 7:10])
    angular_velocity = property(lambda self: self.data[:, 10:13])

    def poses(self) -> np.ndarray:
        """World poses (rows, 4, 4)."""
        w, x, y, z = self.quaternion.T
        T = np.zeros((len(self.t), 4, 4))
        T[:, 0] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y), self.position[:, 0]], 1)
        T[:, 1] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x), self.position[:, 1]], 1)
        T[:, 2] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y), self.position[:, 2]], 1)
        T[:, 3, 3] = 1.0
        return T

    def __getstate__(self):
        return {k: getattr(self, k) for k in self.__slots__}

    def __setstate__(self, state):
        for k, v in state.items():
            setattr(self, k, v)

    def __len__(self) -> int:
        return len(self.t)

    def __repr__(self) -> str:
        return f"<BodyLog '{self.name}' {len(self.t)} rows>"


#: Table columns of a free body: position, quaternion, velocity, angular velocity.
BODY_COLUMNS = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
#: Columns of the contact events table.
EVENT_COLUMNS = ("a", "b", "kind", "begin", "end", "peak_force", "max_depth", "steps")


class SimulationLog:
    """The log of a simulation (the paper's DataManager).

    ``log.t`` (rows,) s; ``log[i]`` or ``log.robots[i]`` is robot i's
    :class:`RobotLog`. With a single robot, ``log.q``, ``log.tau`` ... are
    that robot's arrays. With a world: ``log.bodies[name]`` is a free body's
    :class:`BodyLog`; ``log.contacts`` the contact events (a pandas
    DataFrame: a, b, kind, begin, end (s, NaN while ongoing), peak_force (N),
    max_depth (m), steps); ``log.contact_points`` every contact point of
    every world step when the simulation kept them (log_contacts=True).
    Export: :meth:`to_dataframe`, :meth:`to_csv`, :meth:`to_excel` (robots'
    and bodies' columns; Excel adds a 'contacts' sheet); read back with
    :meth:`read_csv`, :meth:`read_excel`.
    """

    def __init__(self, t: np.ndarray, robots: Sequence[RobotLog], *, dt: Optional[float] = None,
                 control_every: Optional[int] = None, log_every: Optional[int] = None,
                 bodies: Optional[Sequence[BodyLog]] = None, contacts=None, contact_points=None, grasps=None,
                 cooperation: Optional[dict] = None):
        self.t = t
        self.robots: List[RobotLog] = list(robots)
        self.bodies = {b.name: b for b in (bodies or [])}
        self.dt = dt
        self.control_every = control_every
        self.log_every = log_every
        self._contacts = contacts
        self._contact_points = contact_points
        self._grasps = grasps
        #: {(a, b): (rows, width) array of cooperation_schema()} for robots a < b (a simulation's log)
        self._cooperation = dict(cooperation or {})

    def check(self, *, poses: bool = False) -> "SimulationLog":
        """Returns the log if it is consistent, else raises ValueError naming what is not: log.t
        (rows,) finite real numbers in time order; per robot every quantity (rows, n) real numbers
        with one n, holding (rows,), weld, ft_world and ft_clamp (rows, 6); per free body (rows, 13) real numbers, and
        with poses=True (the views) finite, positions within 1e6 m and unit quaternions. A
        simulation's log always is; the views and tables check one built or changed by hand."""
        t = _checks.real_array(self.t, "log.t")
        if t.ndim != 1:
            raise ValueError(f"log.t must be (rows,), got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise ValueError("log.t must be finite (no NaN or inf)")
        if np.any(np.diff(t) < 0):
            raise ValueError("log.t must be in time order (non-decreasing)")
        rows = len(t)
        for i, r in enumerate(self.robots):
            if not isinstance(r, RobotLog):
                raise ValueError(f"log.robots[{i}] must be a RobotLog, got {type(r).__name__}")
            n = None
            for k in STORED:
                a = _checks.real_array(getattr(r, k), f"log[{i}].{k}")
                if a.ndim != 2 or a.shape[0] != rows or (n is not None and a.shape[1] != n):
                    want = f"({rows}, {'n' if n is None else n})"
                    raise ValueError(f"wrong shape for log[{i}].{k}: expected {want}, one row per log row, "
                                     f"got {a.shape}")
                n = a.shape[1]
            if np.shape(r.holding) != (rows,):
                raise ValueError(f"wrong shape for log[{i}].holding: expected ({rows},), got {np.shape(r.holding)}")
            for k in ("weld", "ft_world", "ft_clamp"):
                if _checks.real_array(getattr(r, k), f"log[{i}].{k}").shape != (rows, 6):
                    raise ValueError(f"wrong shape for log[{i}].{k}: expected ({rows}, 6), got {np.shape(getattr(r, k))}")
        for name, b in self.bodies.items():
            d = _checks.real_array(b.data, f"log.bodies[{name!r}]")
            if d.shape != (rows, 13):
                raise ValueError(f"wrong shape for log.bodies[{name!r}]: expected ({rows}, 13), got {d.shape}")
            if poses and not (np.all(np.isfinite(d)) and np.all(np.abs(d[:, :3]) <= _MAX_DISTANCE)
                              and np.all(np.abs(d[:, 3:7]) <= 1.0 + 1e-6)
                              and np.all(np.abs(np.linalg.norm(d[:, 3:7], axis=1) - 1.0) <= 1e-6)):
                raise ValueError(f"log.bodies[{name!r}] must hold finite positions within {_MAX_DISTANCE:g} m and "
                                 "unit quaternions")
        return self

    def _pair(self, a, b):
        n = len(self.robots)
        for name, i in (("a", a), ("b", b)):
            if not isinstance(i, (int, np.integer)) or isinstance(i, (bool, np.bool_)) or not 0 <= i < n:
                raise ValueError(f"{name} must be the index of a robot of the log, in [0, {n}), got {i!r}")
        if a >= b:
            raise ValueError(f"a must be less than b (robot a leads, b follows), got a = {a}, b = {b}")
        return int(a), int(b)

    def cooperation(self, a: int = 0, b: int = 1) -> dict:
        """What robots a and b (a < b) do together to a body both hold, per log row, as the engine
        computed it (docs/world-and-grasp.md, "Two holders"). A dict of arrays, one row per log row:

        - t (rows,) s; holding (rows,) bool, both hold one body; body (rows,) its name ('' when not);
        - centre (rows, 3) m: the body's centre of mass c; point_a, point_b (rows, 3) m: the welds' points
          p_a, p_b (world);
        - external (rows, 6) N, N m: the net wrench of both welds on the body about c,
          sum_k W_k h_k with W_k = [[I, 0], [S(p_k - c), I]];
        - internal (rows, 12) N, N m: [f_a; mu_a; f_b; mu_b], the welds' wrenches' part in W's null space,
          each about its own point, taking the external wrench as pins would share it (forces carry all
          they can: :func:`coopsim.grasp.internal_wrenches` with metric="forces");
        - squeeze (rows,) N: the internal force along the line from p_a to p_b, (f_a - f_b) . e / 2,
          > 0 when the clamps push the body together (compression), < 0 when they pull it apart;
        - twist (rows,) N m: the internal moment about that line, (mu_a - mu_b) . e / 2;
        - bending (rows, 2) N m: each weld's moment across the line (magnitude); shear (rows,) N: the
          internal force across the line that balances them (magnitude);
        - load_share (rows, 2): each robot's part of the vertical load, f_k,up / (f_a + f_b)_up;
        - relative_pose_error (rows, 6) m, rad: robot b's clamp frame against where a rigid hold with
          a's since the second weld attached would put it: position (3), rotation vector (3), world axes.

        Rows where they do not hold one body are NaN (holding False). ValueError for robots the log
        lacks, a >= b, or a log without these columns (one read back from a table)."""
        a, b = self._pair(a, b)
        data = self._cooperation.get((a, b))
        if data is None:
            raise ValueError(f"the log has no cooperation columns for robots {a} and {b}: a simulation's log "
                             "has them for every pair; tables (CSV, Excel) do not keep them")
        data = np.asarray(data, dtype=float)
        if data.shape != (len(self.t), _COOPERATION_WIDTH):
            raise ValueError(f"wrong shape for the cooperation columns of robots {a} and {b}: expected "
                             f"({len(self.t)}, {_COOPERATION_WIDTH}), got {data.shape}")
        holding = data[:, 0] >= 0
        out = {"t": self.t, "holding": holding,
               "body": np.where(holding, self.robots[a].holding, "").astype(object)}
        for name, sl in _COOPERATION_SLICES.items():
            if name != "body":
                out[name] = data[:, sl] if sl.stop - sl.start > 1 else data[:, sl.start]
        return out

    def internal_wrench(self, a: int = 0, b: int = 1) -> np.ndarray:
        """Deprecated: (w_a - w_b) / 2 (rows, 6) of robots a and b's weld wrenches (zeros in the rows where
        they do not hold one body), kept for old scripts; it warns (DeprecationWarning).

        This is not the internal wrench. It is the part that cancels on the body only when both welds act
        at one point; each acts between its own clamp's pads, so an uneven split of the weight between
        holders at different distances from the centre of mass shows here although nothing squeezes the
        body. Use :meth:`cooperation` (squeeze, internal, twist, bending, shear)."""
        warnings.warn("SimulationLog.internal_wrench is (w_a - w_b) / 2, not the internal wrench: use "
                      "SimulationLog.cooperation(a, b) (squeeze, internal)", DeprecationWarning, stacklevel=2)
        n = len(self.robots)
        for name, i in (("a", a), ("b", b)):
            if not isinstance(i, (int, np.integer)) or isinstance(i, (bool, np.bool_)) or not -n <= i < n:
                raise ValueError(f"{name} must be the index of a robot of the log, in [0, {n}), got {i!r}")
        ra, rb = self.robots[a], self.robots[b]
        both = (ra.holding != "") & (ra.holding == rb.holding)
        return np.where(both[:, None], (ra.weld - rb.weld) / 2, 0.0)

    @property
    def grasps(self):
        """Grasps and releases as a pandas DataFrame: t (s), robot (index), body, event ('grasp' or
        'release'), reason ('grasp', 'opened', 'slipped', 'released')."""
        import pandas as pd  # pandas' import is heavy: only when a table is asked for

        cols = ("t", "robot", "body", "event", "reason")
        data = self._grasps or {k: [] for k in cols}
        return pd.DataFrame({k: data[k] for k in cols})

    @property
    def contacts(self):
        """The contact events as a pandas DataFrame (one row per contact from begin to end)."""
        import pandas as pd  # pandas' import is heavy: only when a table is asked for

        data = self._contacts or {k: [] for k in EVENT_COLUMNS}
        return pd.DataFrame({k: data[k] for k in EVENT_COLUMNS})

    @property
    def contact_points(self):
        """Every contact point of every world step (log_contacts=True) as a pandas DataFrame, else None."""
        import pandas as pd  # pandas' import is heavy: only when a table is asked for

        return None if self._contact_points is None else pd.DataFrame(self._contact_points)

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
        """Column names: 't', then '<label>.<quantity><joint>' (joints from 1), then
        '<body>.<x|y|z|qw|qx|qy|qz|vx|vy|vz|wx|wy|wz>' per free body."""
        cols = ["t"]
        for label, r in zip(self.labels, self.robots):
            cols += [f"{label}.{qty}{j + 1}" for qty in QUANTITIES for j in range(r.dof)]
        for name in self.bodies:
            cols += [f"{name}.{c}" for c in BODY_COLUMNS]
        return cols

    def to_array(self) -> np.ndarray:
        """All columns as one (rows, columns) float64 array, in :meth:`columns` order."""
        self.check()
        parts = [np.asarray(self.t, dtype=float)[:, None]]
        with np.errstate(invalid="ignore", over="ignore"):  # e of a log holding inf (written by hand) is NaN
            for r in self.robots:
                parts += [np.asarray(getattr(r, "error" if qty == "e" else qty), dtype=float) for qty in QUANTITIES]
        parts += [b.data for b in self.bodies.values()]
        return np.hstack(parts) if parts else np.zeros((0, 1))

    def to_dataframe(self):
        """A pandas DataFrame, one row per logged step, columns as :meth:`columns`."""
        import pandas as pd  # pandas' import is heavy: only when a table is asked for

        return pd.DataFrame(self.to_array(), columns=self.columns())

    @classmethod
    def from_dataframe(cls, df) -> "SimulationLog":
        """Rebuilds a log from :meth:`to_dataframe`'s layout (e.g. read from CSV or Excel)."""
        cols = [str(c) for c in df.columns]
        if not cols or cols[0] != "t":
            raise ValueError("df must start with a 't' column")
        data = np.asarray(df.to_numpy(dtype=np.float64))
        pat = re.compile(r"^(.*)\.(" + "|".join(sorted(QUANTITIES, key=len, reverse=True)) + r")(\d+)$")
        body_pat = re.compile(r"^(.*)\.(" + "|".join(BODY_COLUMNS) + r")$")
        order: List[str] = []
        found = {}
        body_cols: dict = {}
        for k, c in enumerate(cols[1:], start=1):
            m = pat.match(c)
            b = None if m else body_pat.match(c)
            if b:
                body_cols.setdefault(b.group(1), {})[b.group(2)] = k
                continue
            if not m:
                raise ValueError(f"df column {c!r} is not '<robot>.<quantity><joint>' nor '<body>.<x|y|z|qw|...>'")
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
        bodies = []
        for name, cmap in body_cols.items():
            missing = [c for c in BODY_COLUMNS if c not in cmap]
            if missing:
                raise ValueError(f"df lacks {missing} columns for body {name!r}")
            bodies.append(BodyLog(name, t, data[:, [cmap[c] for c in BODY_COLUMNS]].copy()))
        dt = float(t[1] - t[0]) if len(t) > 1 else None
        return cls(t, robots, dt=dt, bodies=bodies)

    # ---- files (written to a temporary file, then renamed over the target) ----

    def to_csv(self, path, *, progress: Optional[Callable[[float], None]] = None) -> str:
        """Writes the table as CSV (full precision: every value as ``%.17g``, an empty field for NaN) to
        path atomically; returns the path. The same file as pandas' ``to_csv(index=False,
        float_format="%.17g")``, written a block of rows at a time with Python's number formatting, about
        five times faster (a 10 MB table of 4000 rows x 148 columns in about 0.3 s on a 2-core machine).
        progress: called with the fraction written (0 .. 1) after each block (about 1 MB) and at the end."""
        _checks.callable_or_none(progress, "progress", "the fraction written (0 .. 1)")
        data = self.to_array()      # checks the log first
        cols = self.columns()

        def write(tmp):
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                _write_csv(f, cols, data, progress)

        return _atomic_write(path, ".csv", write)

    def to_excel(self, path, sheet_name: str = "log", *,
                 progress: Optional[Callable[[float], None]] = None) -> str:
        """Writes the table to an .xlsx workbook atomically, every value at full precision: sheet
        `sheet_name` holds the data (columns as :meth:`columns`), sheet 'info' the step size and
        robots, sheet 'contacts' the contact events when there are any. The workbook is xlsxwriter's, the
        data sheet's rows are written into it a block at a time as text (numbers as ``%.17g``, which read
        back exactly), nothing decimated: about 1 s for 4000 rows x 148 columns (10 MB of CSV) on a 2-core
        machine, against 3 s cell by cell with xlsxwriter, 8 s through pandas and 13 s with openpyxl.
        NaN and inf (a log written by hand) are empty cells.
        progress: called with the fraction of the data rows written (0 .. 1) after each block of rows and
        at the end. Raises ValueError past Excel's row limit."""
        _checks.callable_or_none(progress, "progress", "the fraction written (0 .. 1)")
        if len(self.t) + 1 > _EXCEL_MAX_ROWS:
            raise ValueError(f"the log has {len(self.t)} rows, more than an Excel sheet holds "
                             f"({_EXCEL_MAX_ROWS - 1}): log less often (log_every) or use to_csv")
        import xlsxwriter  # only when writing Excel

        data = self.to_array()
        info = [("dt", _none_str(self.dt)), ("control_every", _none_str(self.control_every)),
                ("log_every", _none_str(self.log_every))]
        info += [(f"robot {i}", f"{lab} ({r.dof} joints)") for i, (lab, r) in enumerate(zip(self.labels, self.robots))]

        def write(tmp):
            book = xlsxwriter.Workbook(tmp, {"constant_memory": True})
            try:
                sheet = book.add_worksheet(sheet_name)     # the header here, the rows added below
                sheet.write_row(0, 0, self.columns())
                sheet = book.add_worksheet("info")
                sheet.write_row(0, 0, ["key", "value"])
                for i, row in enumerate(info, start=1):
                    sheet.write_row(i, 0, row)
                if self._contacts and len(self._contacts["a"]):
                    sheet = book.add_worksheet("contacts")
                    sheet.write_row(0, 0, EVENT_COLUMNS)
                    events = self.contacts
                    for i, row in enumerate(events.itertuples(index=False), start=1):
                        # an ongoing contact has no end: an empty cell
                        sheet.write_row(i, 0, ["" if isinstance(v, float) and v != v else v for v in row])
            finally:
                book.close()
            _add_rows(tmp, "xl/worksheets/sheet1.xml", data, progress)

        return _atomic_write(path, ".xlsx", write)

    @classmethod
    def read_csv(cls, path) -> "SimulationLog":
        """Reads a log written by :meth:`to_csv`."""
        import pandas as pd  # pandas' import is heavy: only when a table is asked for

        # exact decimal -> binary parsing: the default from pandas 3, an option before
        exact = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
        return cls.from_dataframe(pd.read_csv(path, **exact))

    @classmethod
    def read_excel(cls, path, sheet_name: str = "log") -> "SimulationLog":
        """Reads a log written by :meth:`to_excel`."""
        import pandas as pd  # pandas' import is heavy: only when a table is asked for

        return cls.from_dataframe(pd.read_excel(path, sheet_name=sheet_name, engine="openpyxl"))

    def plot(self, robot: int = 0, quantity: str = "q", **kwargs):
        """Joints against time, one panel each, references dashed; see coopsim.plotting.plot_log."""
        return plot_log(self, robot=robot, quantity=quantity, **kwargs)


# values per block of rows written at a time (CSV: about 1 MB of text)
_BLOCK_VALUES = 50_000


def _write_csv(f, cols: List[str], data: np.ndarray, progress) -> None:
    """The table as pandas writes it with float_format="%.17g" (header quoted as the csv module does,
    NaN as an empty field, inf as inf, lines ended by os.linesep), a block of rows at a time."""
    end = os.linesep
    head = io.StringIO()
    csv.writer(head, lineterminator=end).writerow(cols)
    f.write(head.getvalue())
    rows, width = data.shape
    fmt = ",".join(["%.17g"] * width)
    block = max(1, _BLOCK_VALUES // max(1, width))
    for start in range(0, rows, block):
        part = data[start:start + block]
        finite = np.isfinite(part).all(axis=1)
        if finite.all():
            lines = [fmt % tuple(r) for r in part.tolist()]
        else:
            lines = [fmt % tuple(r) if ok else ",".join("" if v != v else "%.17g" % v for v in r)
                     for r, ok in zip(part.tolist(), finite.tolist())]
        lines.append("")
        f.write(end.join(lines))
        if progress is not None:
            progress(min(start + block, rows) / rows)
    if progress is not None and rows == 0:
        progress(1.0)


def _add_rows(book: str, sheet: str, data: np.ndarray, progress) -> None:
    """Adds the rows of `data` (rows, columns) under the header row of the worksheet `sheet` (its part's
    name) of the .xlsx file `book` (rewritten in place): each row as ``<row r="i">`` with one number cell
    ``<c r="A2"><v>%.17g</v></c>`` per finite value (none for NaN or inf: an empty cell), and the sheet's
    dimension to match. progress(fraction) after each block of rows."""
    from xlsxwriter.utility import xl_col_to_name  # only when writing Excel

    rows, width = data.shape
    names = [xl_col_to_name(j) for j in range(width)]
    fmt = '<row r="@">' + "".join(f'<c r="{n}@"><v>%.17g</v></c>' for n in names) + "</row>"
    block = max(1, _BLOCK_VALUES // max(1, width))
    tmp = book + ".rows"
    try:
        _copy_with_rows(book, tmp, sheet, data, fmt, names, block, progress)
        os.replace(tmp, book)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _copy_with_rows(book, tmp, sheet, data, fmt, names, block, progress) -> None:
    rows = len(data)
    with zipfile.ZipFile(book) as zin, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zout:
        for item in zin.infolist():
            if item.filename != sheet:
                zout.writestr(item, zin.read(item.filename))
                continue
            xml = zin.read(sheet).decode("utf-8")
            head, tail = xml.split("</sheetData>", 1)
            head = re.sub(r'<dimension ref="[^"]*"/>', f'<dimension ref="A1:{names[-1]}{rows + 1}"/>', head, count=1)
            with zout.open(sheet, "w", force_zip64=True) as f:
                f.write(head.encode("utf-8"))
                for start in range(0, rows, block):
                    part = data[start:start + block]
                    finite = np.isfinite(part).all(axis=1)
                    out = []
                    for i, (r, ok) in enumerate(zip(part.tolist(), finite.tolist()), start=start + 2):
                        if ok:
                            out.append((fmt % tuple(r)).replace("@", str(i)))
                        else:
                            out.append(f'<row r="{i}">' + "".join(f'<c r="{n}{i}"><v>{v:.17g}</v></c>'
                                                                  for n, v in zip(names, r) if math.isfinite(v))
                                       + "</row>")
                    f.write("".join(out).encode("ascii"))
                    if progress is not None:
                        progress(min(start + block, rows) / rows)
                f.write(("</sheetData>" + tail).encode("utf-8"))
    if progress is not None and rows == 0:
        progress(1.0)


def _none_str(v):
    return "" if v is None else str(v)


def _file_in_the_way(folder: str) -> Optional[str]:
    """The existing ancestor of `folder` (itself included) that is not a folder, or None: a file there
    keeps the folder from being made."""
    while True:
        if os.path.lexists(folder):
            return None if os.path.isdir(folder) else folder
        parent = os.path.dirname(folder)
        if parent == folder:
            return None
        folder = parent


def _atomic_write(path, suffix: str, write: Callable[[str], None]) -> str:
    """Calls write(tmp) on a temporary file beside `path`, then renames it to `path`: a failure midway
    leaves any earlier file intact. The folder is made as needed. A path that cannot name a file is a
    ValueError, a file system error an OSError naming `path` (not the temporary file); a file where a folder of `path` should be is a NotADirectoryError naming that file."""
    if not isinstance(path, (str, os.PathLike)) or not isinstance(os.fspath(path), str):
        raise ValueError(f"path must be a file name (str or path-like), got {path!r}")
    path = os.fspath(path)
    if not path or "\0" in path or path.endswith(("/", os.sep)) or os.path.isdir(path):
        raise ValueError(f"path must name a file, got {path!r}" + (" (a folder)" if path and os.path.isdir(path)
                                                                     else ""))
    folder = os.path.dirname(os.path.abspath(path))
    blocker = _file_in_the_way(folder)
    if blocker is not None:
        raise NotADirectoryError(errno.ENOTDIR, f"cannot write the file: {blocker!r} is a file, not a folder", path)
    tmp = None
    try:
        os.makedirs(folder, exist_ok=True)  # a fresh output folder is made, as the file would be
        # the temporary name stays short: a name near the file system's limit must still work
        fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path)[:64] + ".", suffix=suffix, dir=folder)
        os.close(fd)
        write(tmp)
        # mkstemp makes the file private; give it the usual mode
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except OSError as e:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        if e.errno is None:
            raise
        raise OSError(e.errno, f"cannot write the file: {e.strerror}", path) from e
    except BaseException:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
