"""The live page's Plots panel: a chosen robot's joints against their references and its tracking error, and
the plots its run has (the sensed force and moment, the task-space or object error, squeeze and load share),
fed from a history of the last seconds taken on the simulation's thread; a mixin of LiveView."""
from __future__ import annotations

import math

import numpy as np

from ..._core import ObjectControl, TaskController
from .common import _PLOT_EVERY
from .drawing import Frame

_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
_PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]


class _PlotsPanel:
    """The Plots panel's plots and their data (a mixin of LiveView)."""

    def _plot_kinds_of(self, i: int) -> tuple:
        """The plots robot i's run has now: 'q' (joints and references) always; 'wrench' (the sensed force and
        moment) when its sensor has something to sense (a world, applied wrenches, a task-space law or a
        cooperative group reading it, sensor noise or filter set) or has read a wrench; 'task' (the task-space
        error) under a task-space law or object-level control; 'coop' (squeeze, load share) while it is in a
        cooperative group with another robot or has held a body with another. Once shown, a plot stays."""
        kinds = {"q"}
        law, own, g = self._driver(i)
        o = self.sim.sensor_options(i)
        if self.sim.world is not None or self.sim.applied(i)["wrenches"] or isinstance(law, TaskController) \
                or g is not None or o.noise_force > 0 or o.noise_moment > 0 or o.time_constant > 0:
            kinds.add("wrench")
        if isinstance(law, (TaskController, ObjectControl)):
            kinds.add("task")
        if self._partner(i) is not None:
            kinds.add("coop")
        seen = self._seen_kinds[i]
        seen |= kinds
        return tuple(k for k in ("q", "wrench", "task", "coop") if k in seen)

    def _partner(self, i: int):
        """The robot i cooperates with now: a member of its cooperative group, else one holding the same body;
        None when neither."""
        g = self._group_of(i)
        if g is not None:
            others = [k for k in g["robots"] if k != i]
            if others:
                return others[0]
        f = self.frame
        if self._world is not None and f is not None and len(self.robots) > 1 and f.holding[i]:
            body = self.sim.holding(i)
            for k in range(len(self.robots)):
                if k != i and body is not None and self.sim.holding(k) == body:
                    return k
        return None

    def _rebuild_plots(self, i: int) -> None:
        """Robot i's plots made anew in the Plots panel (the ones its run has: see _plot_kinds_of)."""
        import viser.uplot as up  # the optional live extra

        for h in self._plot_handles:
            h.remove()
        kinds = self._plot_kinds_of(i)
        self._plot_kinds = kinds
        r, lab = self.robots[i], self.labels[i]
        gui = self.server.gui
        scales = {"x": {"time": False}}
        def line(label, j, **kw):
            return up.Series(label=label, stroke=_PALETTE[j % len(_PALETTE)], points={"show": False},
                             **{"width": 1.5, **kw})
        x = np.zeros(2)
        made = {}

        def plot(key, labels, title, dashed=()):
            series = [up.Series(label="t (s)")] + [line(s, j if not dashed else j // 2,
                                                        **({"dash": [4, 4], "width": 1} if j in dashed else {}))
                                                   for j, s in enumerate(labels)]
            made[key] = gui.add_uplot((x,) * (1 + len(labels)), tuple(series), title=title, scales=scales,
                                      aspect=1.4)

        with self._plots_tab:
            q_labels = [s for j in range(r.dof) for s in (f"q{j + 1}", f"ref{j + 1}")]
            plot("q", q_labels, f"{lab}: q and q_ref (rad, m)", dashed=tuple(range(1, 2 * r.dof, 2)))
            plot("e", [f"e{j + 1}" for j in range(r.dof)], f"{lab}: error q_ref - q (rad, m)")
            if "wrench" in kinds:
                plot("force", ["fx", "fy", "fz"], f"{lab}: sensed force (N, world)")
                plot("moment", ["mx", "my", "mz"], f"{lab}: sensed moment (N m, about the TCP)")
            if "task" in kinds:
                law = self._driver(i)[0]
                what = "object error (m, rad)" if isinstance(law, ObjectControl) else "task-space error (m, rad)"
                plot("task", list(_AXES), f"{lab}: {what}")
            if "coop" in kinds:
                plot("squeeze", ["squeeze"], f"{lab}: squeeze (N)")
                plot("share", ["this robot", "the other"], f"{lab}: load share (of the vertical load)")
        self._plot_q, self._plot_e = made["q"], made["e"]
        self._plot_made = made
        self._plot_handles = list(made.values())
        self._last_plot = -math.inf

    def _pick_plot(self, i: int) -> None:
        with self._lock:
            self._plot_robot = i
            self._rebuild_plots(i)
            self._changes += 1

    # ---- the plots' data ----

    def _extras(self, i: int):
        """(sensed wrench (6,), task-space error (6,) or None, (squeeze, share of i, share of the other) or
        None) of robot i now, on the simulation's thread."""
        wrench = np.asarray(self.sim.sensor(i).ft_world, dtype=float)
        law = self._driver(i)[0]
        task = None
        if isinstance(law, ObjectControl):
            task = np.asarray(law.object_error, dtype=float)
        elif isinstance(law, TaskController):
            task = np.asarray(law.state.error, dtype=float)
        coop = None
        k = self._partner(i)
        if k is not None:
            a, b = min(i, k), max(i, k)
            c = self.sim.cooperation(a, b)
            share = np.asarray(c.load_share, dtype=float)
            coop = np.array([float(c.squeeze), share[0 if i == a else 1], share[1 if i == a else 0]])
        return wrench, task, coop

    def _plots(self, f: Frame, now: float) -> None:
        for i, h in enumerate(self._hist):
            h.append((f.t, f.q[i], f.q_ref[i]) + self._extras(i))
            while h and h[0][0] < f.t - self.history:
                h.popleft()
        if not self._hist or now - self._last_plot < _PLOT_EVERY:
            return
        i = self._plot_robot
        if self._plot_kinds_of(i) != self._plot_kinds:
            self._rebuild_plots(i)
        h = self._hist[i]
        if not h:
            return
        self._last_plot = now
        made = self._plot_made
        t = np.array([x[0] for x in h])
        q = np.array([x[1] for x in h])
        qr = np.array([x[2] for x in h])
        cols = [t]
        for j in range(q.shape[1]):
            cols += [q[:, j], qr[:, j]]
        made["q"].data = tuple(cols)
        made["e"].data = (t,) + tuple((qr - q).T)
        if "force" in made:
            w = np.array([x[3] for x in h])
            made["force"].data = (t,) + tuple(w[:, :3].T)
            made["moment"].data = (t,) + tuple(w[:, 3:].T)
        for key, k, width in (("task", 4, 6), ("squeeze", 5, 1), ("share", 5, 2)):
            if key not in made:
                continue
            rows = [(x[0], x[k]) for x in h if x[k] is not None]     # only where the run had it
            if not rows:
                continue
            tt = np.array([r[0] for r in rows])
            v = np.array([r[1] for r in rows])
            v = v[:, :1] if key == "squeeze" else v[:, 1:3] if key == "share" else v
            made[key].data = (tt,) + tuple(v.T)
