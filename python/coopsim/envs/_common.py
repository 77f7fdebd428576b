"""What the environments share: the action check, the control period over the engine's steps, RGB frames
from the matplotlib view."""
from __future__ import annotations

from typing import Optional

import numpy as np
from gymnasium import spaces

from .. import _checks, view

#: the engine's step (s): 0.2 ms, 5 kHz
DT = 2e-4
#: the bound of the observations' unbounded quantities (m, rad, m/s, rad/s, N, N m): finite, so that
#: Gymnasium's checks and wrappers see a bounded space; a state beyond it is clipped to it
BOUND = 1e4


def bounded(shape, low: float = -BOUND, high: float = BOUND) -> spaces.Box:
    """A float64 Box of `shape` within [low, high]."""
    return spaces.Box(low, high, shape=shape, dtype=np.float64)


def clip(x: np.ndarray, low: float = -BOUND, high: float = BOUND) -> np.ndarray:
    """`x` as float64 within [low, high], NaN as 0 (a run that diverged)."""
    x = np.minimum(np.maximum(np.asarray(x, np.float64), low), high)     # NaN stays NaN here
    if not (x == x).all():
        x[np.isnan(x)] = 0.0
    return x


def control_period(control_rate, dt: float = DT) -> float:
    """The control period (s) of `control_rate` (Hz, > 0, at most 1 / dt; a whole number of engine steps of
    `dt` s per period, rounded): ValueError naming control_rate otherwise."""
    rate = _checks.number(control_rate, "control_rate", 0.0, 1.0 / dt, lo_open=True, unit="Hz")
    return max(1, int(round(1.0 / (rate * dt)))) * dt


def check_action(action, space: spaces.Box, name: str = "action") -> np.ndarray:
    """`action` as a float64 array of the Box `space`'s shape, or a one-line ValueError naming `name` and what
    is wrong: not numbers, the wrong shape, NaN or infinite entries, entries outside [low, high]."""
    if type(action) is np.ndarray and action.dtype == np.float64 and action.shape == space.shape \
            and ((action >= space.low) & (action <= space.high)).all():
        return action.copy()       # the common case, checked in one pass (NaN fails the comparisons)
    a = np.asarray(action)
    if a.dtype.kind not in "biuf":
        raise ValueError(f"{name} must be an array of numbers of shape {space.shape}, got {action!r}")
    a = a.astype(np.float64)
    if a.shape != space.shape:
        raise ValueError(f"{name} must have shape {space.shape}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {np.array2string(a, precision=4, separator=', ')}")
    low, high = space.low.astype(np.float64), space.high.astype(np.float64)
    # a float32 space's bounds are the float64 ones rounded: allow that rounding
    tol = 1e-6 * np.maximum(1.0, np.abs(high - low))
    bad = (a < low - tol) | (a > high + tol)
    if np.any(bad):
        k = int(np.flatnonzero(bad.ravel())[0])
        raise ValueError(f"{name} must lie in its space's bounds: entry {k} is {a.ravel()[k]:.6g}, outside "
                         f"[{low.ravel()[k]:.6g}, {high.ravel()[k]:.6g}]")
    return np.clip(a, low, high)


def check_render_mode(render_mode: Optional[str], modes) -> Optional[str]:
    if render_mode is not None:
        _checks.one_of(render_mode, "render_mode", modes)
    return render_mode


class Frames:
    """RGB frames (H, W, 3) uint8 of a simulation now through :func:`coopsim.view.draw` (its robots, its world
    and extra bodies, e.g. a target) on an off-screen Agg figure, whatever matplotlib's backend is."""

    def __init__(self, width: int = 480, height: int = 360, **draw_options):
        self.size = (int(width), int(height))
        self.options = draw_options
        self.fig = None

    def frame(self, sim, bodies=None, label: Optional[str] = None) -> np.ndarray:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        if self.fig is None:
            dpi = 100.0
            self.fig = Figure(figsize=(self.size[0] / dpi, self.size[1] / dpi), dpi=dpi)
            FigureCanvasAgg(self.fig)
        self.fig.clear()
        ax = self.fig.add_subplot(projection="3d")
        self.fig.subplots_adjust(0, 0, 1, 1)
        view.draw(ax, sim, bodies=bodies, label=label, **self.options)
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[:, :, :3].copy()

    def close(self):
        self.fig = None
