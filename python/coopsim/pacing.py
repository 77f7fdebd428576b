"""Time: run statistics and pacing to the wall clock (the paper's FrameRate and speed control).

:class:`RunStats` is the paper's time supervision window for any run;
:class:`Pacer` runs a simulation at 0 % (pause) to 400 % of real time,
calling a frame callback for live drawing or control. The pacer drives a
simulation through its public calls alone (``time``, ``dt``, ``steps``,
``steps_until``, ``step`` and ``stats``: a :class:`coopsim.Simulation` or
anything that has them).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

__all__ = ["Pacer", "RunStats"]


@dataclass(frozen=True)
class RunStats:
    """Timing of a run (the paper's time supervision window).

    sim_time: simulated time at the end (s); sim_elapsed: simulated time
    covered by this run (s); wall_time: wall-clock duration (s); busy_time:
    wall time spent stepping (s); step_size: dt (s); steps: steps taken;
    steps_per_second: steps / busy_time (the engine's speed);
    real_time_factor: sim_elapsed / wall_time (1 = real time; for a paced
    run, about the speed setting); frames and frame_rate (Hz): frames drawn
    by a paced run and the rate reached (0 for headless runs); frame_rate_asked
    (Hz): the pacer's frame rate, which frame_rate falls below when a frame
    (stepping and drawing) takes longer than 1 / frame_rate_asked (0 for
    headless runs).
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
    frame_rate_asked: float = 0.0

    @staticmethod
    def _make(sim_time, sim_elapsed, wall, busy, dt, steps, frames=0, frame_rate_asked=0.0):
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
            frame_rate_asked=float(frame_rate_asked),
        )

    def __str__(self) -> str:
        return (f"sim time {self.sim_time:.4f} s (+{self.sim_elapsed:.4f} s), wall {self.wall_time:.4f} s, "
                f"step {self.step_size * 1e3:.4g} ms, {self.steps} steps, {self.steps_per_second:,.0f} steps/s, "
                f"real-time factor {self.real_time_factor:.3g}"
                + (f", {self.frames} frames ({self.frame_rate:.1f}/s"
                   + (f" of {self.frame_rate_asked:g}/s asked" if self.frame_rate_asked else "") + ")"
                   if self.frames else ""))



#: what the pacer uses of a simulation
_DRIVEN = ("time", "dt", "steps", "steps_until", "step", "stats")


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
        self._carry = None       # (sim, last frame's clock, simulated time due) of the last run, for keep_clock

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
        """True while simulated time stands still: after pause() (until resume()) or at speed 0, a pause."""
        return self._paused or self._speed == 0.0

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
        return RunStats._make(sim.time, sim.time - t0, self._clock() - w0, busy, sim.dt, sim.steps - s0, frames,
                              self._frame_rate)

    def run(self, sim, t_end: float, *, on_frame: Optional[Callable] = None,
            max_wall_time: Optional[float] = None, keep_clock: bool = False) -> RunStats:
        """Runs `sim` (a coopsim.Simulation, see the module's docstring) up to t_end (s) paced to the wall
        clock; returns the statistics, also left in ``sim.stats``.

        keep_clock: continue the pacing of this pacer's previous run of the same simulation, for a run
        sequenced in short pieces (a task's phases): the wall time since that run's last frame (at most
        max_catch_up) and the simulated time it was due beyond its t_end count in this one, and the run
        returns as soon as it reaches t_end, without waiting for a next frame. Without it, each run
        starts its clock afresh."""
        if not all(hasattr(sim, a) for a in _DRIVEN):
            raise ValueError(f"sim must be a coopsim.Simulation (or have {', '.join(_DRIVEN)}), "
                             f"got {type(sim).__name__}")
        if not isinstance(t_end, (int, float, np.floating, np.integer)) or isinstance(t_end, bool) \
                or not math.isfinite(t_end):
            raise ValueError(f"t_end must be a finite number of seconds, got {t_end!r}")
        if max_wall_time is not None and not (math.isfinite(max_wall_time) and max_wall_time > 0):
            raise ValueError(f"max_wall_time must be > 0 s, got {max_wall_time!r}")
        if on_frame is not None and not callable(on_frame):
            raise ValueError("on_frame must be callable as on_frame(sim, pacer)")
        if (self._speed == 0 or self._paused) and on_frame is None and max_wall_time is None:
            raise ValueError("speed 0 (paused) with no on_frame and no max_wall_time would never finish")
        sim.steps_until(float(t_end))  # checks t_end is not in the past
        self._stop = False
        clock = self._clock
        w0 = clock()
        carry = self._carry if keep_clock and self._carry is not None and self._carry[0] is sim else None
        last = w0 if carry is None else carry[1]
        # the simulated time the wall clock asks for (beyond t_end at the end of a run: kept for keep_clock)
        due = sim.time if carry is None else min(max(carry[2], sim.time), sim.time + self.max_catch_up * self._speed)
        t0, s0, busy, frames = sim.time, sim.steps, 0.0, 0
        self._live = [sim, t0, s0, w0, busy, frames]
        try:
            while not self._stop and sim.steps_until(float(t_end)) > 0:
                start = clock()
                elapsed = min(start - last, self.max_catch_up)
                last = start
                if not self._paused:
                    due = max(due, sim.time) + elapsed * self._speed
                target = min(float(t_end), due)
                n = sim.steps_until(max(target, sim.time))
                if n:
                    b = clock()
                    sim.step(n)
                    busy += clock() - b
                frames += 1
                self._live[4:] = [busy, frames]
                if on_frame is not None and on_frame(sim, self) is False:
                    break
                if max_wall_time is not None and clock() - w0 >= max_wall_time:
                    break
                if keep_clock and sim.steps_until(float(t_end)) == 0:
                    break
                delay = start + 1.0 / self._frame_rate - clock()
                if delay > 0:
                    self._sleep(delay)
        finally:
            self._live[4:] = [busy, frames]
            self._carry = (sim, last, due)
            sim.stats = self.stats
        return sim.stats
