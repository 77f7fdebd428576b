"""The live page's Run panel: the run's state ('waiting', 'running', 'paused', 'finished', 'failed') and its
state line, the speed in percent, Start, Pause and Resume with their messages, and the time supervision
(simulated and wall time, set and achieved speed, step time mean and max, frames per second); a mixin of
LiveView (:class:`~coopsim.view.live.panels._Panels` builds the panel)."""
from __future__ import annotations

import math

from ... import _checks
from .common import _PLOT_EVERY, _WINDOW
from .drawing import Frame

_DASH = "–"            # shown where there is nothing to measure (never "nan")


class _RunPanel:
    """The Run panel's state, speed and time supervision (a mixin of LiveView)."""

    def _set_speed_percent(self, value, from_slider: bool = False) -> None:
        """Sets the pacer's speed in percent of real time (0 .. 400; a number or its text), applied on the
        simulation's thread. Refused in percent with a message in the Run panel: text, NaN, beyond 0 .. 400 %.
        from_slider: the page's slider asked (it shows the value already; the view does not set it back)."""
        try:
            if isinstance(value, bool):
                raise ValueError(f"speed must be a number of percent from 0 to 400, got {value!r}")
            v = _checks.number(value, "speed (%)", text=True)
            if not 0.0 <= v <= 100.0 * self.pacer.MAX_SPEED:
                raise ValueError(f"speed must be 0 .. {100 * self.pacer.MAX_SPEED:g} %, got {v:g} %")
        except ValueError as e:
            self._say(f"Refused: {e}", "run")
            return

        def go():
            with self._speed_lock:
                self._speed_pending -= 1
            self.pacer.speed_percent = v
            self._speed_known = v  # what the page shows or has asked for
            if not from_slider:
                self._sync_speed()
            why = " (nothing moves at 0 %)" if v == 0 else " (paused: Resume to go on)" if self.pacer.paused else ""
            self._say(f"Speed {v:g} %{why}", "run")
        # while a request waits for the simulation's thread, the slider is not set back to the pacer's speed
        with self._speed_lock:
            self._speed_pending += 1
        self.submit(go)

    def _sync_speed(self) -> None:
        self._syncing = True
        try:
            self._speed_known = self.pacer.speed_percent
            self._speed.value = round(self.pacer.speed_percent)
        finally:
            self._syncing = False

    def _start_pressed(self) -> None:
        self.resume()
        self._say("Started" if self.pacer.speed > 0 else
                  "Started, but the speed is 0 %: nothing moves until the speed is raised", "run")

    def _pause_pressed(self) -> None:
        self.pause()
        self._say("Paused: Resume to go on", "run")

    def _resume_pressed(self) -> None:
        """The Resume button: resumes the run; at speed 0 says why nothing moves; after the end, that it is over."""
        state = self.run_state
        self.resume()
        if state in ("finished", "failed"):
            self._say(f"The run has {'finished' if state == 'finished' else 'stopped'}: nothing left to resume"
                      + (" (Reset to start runs it again)" if self.resettable else ""), "run")
        elif self.pacer.speed == 0:
            self._say("Resumed, but the speed is 0 %: nothing moves until the speed is raised", "run")
        else:
            self._say(f"Running at {self.pacer.speed_percent:.0f} %", "run")

    def _state_text(self) -> str:
        """The Run panel's state line: waiting for Start, running at a speed, paused (and why), finished, failed."""
        state = self.run_state
        if state == "waiting":
            return "**State**: waiting for Start"
        if state == "running":
            return f"**State**: running at {self.pacer.speed_percent:.0f} %"
        if state == "paused":
            why = "speed 0 %" if self.pacer.speed == 0 else "Resume to go on"
            return f"**State**: paused at t = {self.sim.time:.4f} s ({why})"
        if state == "finished":
            return f"**State**: finished at t = {self.sim.time:.4f} s"
        if state == "failed":
            e = self.error
            return "**State**: failed" + (f" at t = {self.sim.time:.4f} s: {type(e).__name__}" if e else "")
        return f"**State**: {state}"

    # ---- the time supervision ----

    def _supervise(self, f: Frame, now: float) -> None:
        st = self.pacer.stats
        busy, steps = (st.busy_time, st.steps) if st is not None else (0.0, 0)
        self._stats.append((now, f.t, busy, steps))
        while len(self._stats) > 2 and now - self._stats[0][0] > _WINDOW:
            self._stats.popleft()
        s = list(self._stats)
        wall = s[-1][0] - s[0][0]
        fps = (len(s) - 1) / wall if wall > 0 else 0.0
        achieved = max(0.0, (s[-1][1] - s[0][1]) / wall) if wall > 0 else 0.0
        per = [(b1 - b0) / (n1 - n0) for (_, _, b0, n0), (_, _, b1, n1) in zip(s, s[1:]) if n1 > n0]
        dn = sum(n1 - n0 for (_, _, _, n0), (_, _, _, n1) in zip(s, s[1:]) if n1 > n0)
        db = sum(b1 - b0 for (_, _, b0, n0), (_, _, b1, n1) in zip(s, s[1:]) if n1 > n0)
        mean = db / dn if dn else None             # nothing stepped in the window (paused): nothing to measure
        top = max(per) if per else None
        wall_total = st.wall_time if st is not None else 0.0
        us = lambda x: _DASH if x is None else f"{x * 1e6:.2f}"        # noqa: E731
        state = self.run_state
        self._state_md.content = self._state_text()
        self._time.content = (
            f"| | |\n|---|---|\n| Simulated time | {f.t:.4f} s |\n| Wall time (this run) | {wall_total:.2f} s |\n"
            f"| Speed set | {self.pacer.speed_percent:.0f} % |\n| Speed achieved | {100 * achieved:.0f} % |\n"
            f"| Step size | {self._dt * 1e3:.4g} ms |\n"
            f"| Step time mean / max | {us(mean)} / {us(top)} µs |\n"
            f"| Frames per second | {fps:.1f} |\n| Steps | {f.steps} |")
        if self._start.visible != (state == "waiting"):
            self._start.visible = state == "waiting"
        self.stats = dict(t=f.t, wall=wall_total, speed_set=self.pacer.speed_percent, speed_achieved=100 * achieved,
                          step_mean=mean, step_max=top, fps=fps, steps=f.steps, state=state)
        # the slider follows the pacer when the pacer's speed changed by another way than the slider; it is
        # not compared with the slider's value, which the page may be changing now (its request not yet
        # counted as pending): set back, the page's slider would jump away from where the user put it
        if self.pacer.speed_percent != getattr(self, "_speed_known", self.pacer.speed_percent) and \
                not self._syncing and not self._speed_pending:
            self._sync_speed()
        if now - getattr(self, "_last_drivers", -math.inf) >= _PLOT_EVERY:
            self._last_drivers = now
            self._refresh_drivers()
            self._follow(f)
