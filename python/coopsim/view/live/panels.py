"""The live page's panels: Run (state, speed, start, pause, step, reset, the time supervision, the run's
outcome), Display, Robots (what drives each robot: its controller or its cooperative group's law, the editable
gains and stiffnesses, dimensions, teach mode kept in step with the robot), Plots (joints, sensed wrench,
task-space error, squeeze and load share when the run has them) and Data; each panel with one message line
that the next message replaces; their requests checked here and applied on the simulation's thread."""
from __future__ import annotations

import contextlib
import math
import time
from typing import Callable

import numpy as np

from ..._core import (PID, ComputedTorque, CooperativeController, CubicTrajectory, HybridForce, Impedance,
                      ObjectControl, TaskController)
from ...robots import scara1, scara2
from .drawing import Frame
from .common import (_DIMENSION_FIELDS, _PLOT_EVERY, _WINDOW, _items, _number, _numbers, _rotation,
                     quaternions)

_PANEL_NAMES = ("run", "display", "robots", "plots", "data")
_HOLD_OFF = 2.0        # s of wall time a robot's teach controls are left alone after the user touched one
_DASH = "–"            # shown where there is nothing to measure (never "nan")
_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
_PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]

# the editable settings of each controller kind: (name, field label, where the constructor takes it: an index
# into its positional arguments, or None for a keyword)
_SETTINGS = {
    PID: (("kp", "kp", None), ("ki", "ki", None), ("kd", "kd", None)),
    ComputedTorque: (("kp", "kp (1/s²)", None), ("kd", "kd (1/s)", None)),
    Impedance: (("stiffness", "stiffness (N/m, N m/rad)", 0), ("damping", "damping (N s/m, N m s/rad)", 1),
                ("mass", "mass (kg, kg m²)", 2)),
    HybridForce: (("force", "force (N, N m)", 1), ("kp_force", "kp_force", None), ("ki_force", "ki_force (1/s)", None),
                  ("kv", "kv (1/s)", None), ("kp", "kp (1/s²)", None), ("kd", "kd (1/s)", None)),
}


def _fmt(a) -> str:
    return ", ".join(f"{x:.4g}" for x in np.atleast_1d(a))


def _kind(c):
    """The built-in controller class of c whose settings the page edits (PID, ComputedTorque, Impedance,
    HybridForce), or None (a Python controller, or another law)."""
    t = type(c)
    return t if t in _SETTINGS else None


def _is_python(c) -> bool:
    return type(c).__module__ != PID.__module__      # a class of the engine's module, or one written in Python


class _Panels:
    """The panels of a LiveView (a mixin: the view holds the server, the simulation and the queue)."""

    def _build_panels(self) -> None:
        gui = self.server.gui
        # the panel docked beside the scene (not over it); no share button: the page never leaves this host
        gui.configure_theme(control_width="medium", show_share_button=False)
        gui.main_panel.dock_right()
        tabs = gui.add_tab_group(order=1)
        n = len(self.robots)
        names = tuple(f"{i}: {lab}" for i, lab in enumerate(self.labels)) or ("none",)
        self._msgs = {}
        self._syncing = False            # True while the view itself sets a control's value
        self._touched = {}               # robot -> wall time the user last touched its teach controls
        self._dragging = set()           # robots whose gizmo the user is dragging
        self._taught = {}                # robot -> (the reference a teach move set, its target (n,))
        self._shown_target = {}          # robot -> the target its controls show
        self._driver_key = [None] * n    # what drives each robot, as last shown
        self._gain_fields = [dict() for _ in range(n)]
        self._gain_button = [None] * n
        self._folders = []
        self._plot_handles = []
        self._plot_kinds = ()
        self._seen_kinds = [set() for _ in range(n)]

        with tabs.add_tab("Run"):
            self._msgs["run"] = self._msg = gui.add_markdown("")
            self._state_md = gui.add_markdown("")
            self._start = gui.add_button("Start", visible=self.run_state == "waiting")
            self._start.on_click(lambda e: self._start_pressed())
            self._speed = gui.add_slider("Speed (%)", min=0, max=400, step=1,
                                         initial_value=round(self.pacer.speed_percent))
            self._speed.on_update(lambda e: None if self._syncing else self.set_speed_percent(e.target.value))
            pause, resume = gui.add_button("Pause"), gui.add_button("Resume")
            pause.on_click(lambda e: self._pause_pressed())
            resume.on_click(lambda e: self._resume_pressed())
            step = gui.add_button("One step")
            step.on_click(lambda e: self.one_step())
            reset = gui.add_button("Reset to start", disabled=not self.resettable)
            reset.on_click(lambda e: self.reset())
            self._time = gui.add_markdown("")
            self._outcome_md = gui.add_markdown("")

        with tabs.add_tab("Display"):
            self._msgs["display"] = gui.add_markdown("")
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
            self._msgs["robots"] = gui.add_markdown("")
            for i, r in enumerate(self.robots):
                folder = gui.add_folder(f"{i}: {self.labels[i]}", expand_by_default=(i == 0))
                self._folders.append(folder)
                with folder:
                    text = self._controller_text(i)
                    self._controller_md.append(gui.add_markdown(text))
                    self._driver_key[i] = (text, type(self.sim.controllers[i]))
                    self._make_gain_fields(i, inside=True)
                    sliders = []
                    q_ref = self.sim.references[i].evaluate(self.sim.time)[0]
                    for j in range(r.dof):
                        lo, hi = (float(x) for x in r.q_limits[j])
                        unit = "rad" if r.joint_types[j] == "R" else "m"
                        s = gui.add_slider(f"q{j + 1} ({unit})", min=lo, max=hi, step=(hi - lo) / 1000,
                                           initial_value=float(np.clip(q_ref[j], lo, hi)))
                        s.on_update(lambda e, i=i: self._slider_moved(i, e))
                        sliders.append(s)
                    target = gui.add_text("Joint target", initial_value=", ".join(f"{x:.4g}" for x in q_ref))
                    target.on_update(lambda e, i=i: self._touch(i))
                    go = gui.add_button("Move to joint target")
                    go.on_click(lambda e, i=i, target=target: self.teach_joints(i, target.value, client=e.client))
                    move = gui.add_text("Move time (s)", initial_value=f"{self._move_time:g}")
                    move.on_update(lambda e: self._refusing(lambda: self.set_move_time(e.target.value), "robots"))
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
                    self._shown_target[i] = np.array(q_ref, dtype=float)

        with tabs.add_tab("Plots") as plots_tab:
            self._plots_tab = plots_tab
            self._msgs["plots"] = gui.add_markdown("")
            if n:
                pick = gui.add_dropdown("Robot", names, initial_value=names[0])
                pick.on_update(lambda e: self._pick_plot(names.index(e.target.value)))
        if n:
            self._rebuild_plots(0)
        with tabs.add_tab("Data"):
            self._msgs["data"] = gui.add_markdown("")
            if n:
                pick = gui.add_dropdown("Robot", names, initial_value=names[0])
                pick.on_update(lambda e: self._pick_table(names.index(e.target.value)))
            self._table = gui.add_markdown("")
            csv_btn, xls_btn = gui.add_button("Download CSV"), gui.add_button("Download Excel")
            csv_btn.on_click(lambda e: self.download("csv", e.client))
            xls_btn.on_click(lambda e: self.download("xlsx", e.client))
            self._download_line = gui.add_markdown("")      # the download's progress (data.py)

    # ---- the Run panel ----

    @property
    def run_state(self) -> str:
        """Where the run stands: 'waiting', 'running', 'paused', 'finished' or 'failed' (the session's own
        run_state, where it has one, comes first: this is its minimal form, from the pacer, the end and the
        error)."""
        if self.error is not None:
            return "failed"
        if self._finished.is_set():
            return "finished"
        if getattr(self, "_waiting", False):
            return "waiting"
        return "paused" if self.pacer.paused else "running"

    def _set_speed_percent(self, value) -> None:
        """Sets the pacer's speed in percent of real time (0 .. 400; a number or its text), applied on the
        simulation's thread. Refused in percent with a message in the Run panel: text, NaN, beyond 0 .. 400 %."""
        try:
            if isinstance(value, bool):
                raise ValueError(f"speed must be a number of percent from 0 to 400, got {value!r}")
            v = _number(value, "speed (%)")
            if not 0.0 <= v <= 100.0 * self.pacer.MAX_SPEED:
                raise ValueError(f"speed must be 0 .. {100 * self.pacer.MAX_SPEED:g} %, got {v:g} %")
        except ValueError as e:
            self._say(f"Refused: {e}", "run")
            return

        def go():
            self.pacer.speed_percent = v
            self._sync_speed()
            why = " (nothing moves at 0 %)" if v == 0 else " (paused: Resume to go on)" if self.pacer.paused else ""
            self._say(f"Speed {v:g} %{why}", "run")
        self.submit(go)

    def _sync_speed(self) -> None:
        self._syncing = True
        try:
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

    # ---- what drives each robot ----

    def _group_of(self, i: int):
        """The cooperative group driving robot i now ({'group', 'controller', 'robots'}), or None."""
        for g in getattr(self.sim, "cooperatives", ()):
            if i in g["robots"]:
                return g
        return None

    def _driver(self, i: int):
        """(the law driving robot i, its own controller, its group or None)."""
        own = self.sim.controllers[i]
        g = self._group_of(i)
        return (own if g is None else g["controller"]), own, g

    def _controller_text(self, i: int) -> str:
        law, own, g = self._driver(i)
        if g is not None:
            members = ", ".join(self.labels[k] for k in g["robots"])
            return (f"**Driven by** cooperative group {g['group']}: {self._law_text(law)} on {members}  \n"
                    f"_(its own controller, {type(own).__name__}, stands aside until the group is removed: "
                    f"gains set here act then)_")
        return f"**Controller** {self._law_text(own)}" + (
            f"  \n_(1 or {self.robots[i].dof} values, from the next control step)_" if _kind(own) in (PID, ComputedTorque)
            else "  \n_(scalars or one per direction, from the next control step)_" if _kind(own) else "")

    @staticmethod
    def _law_text(c) -> str:
        """A controller or cooperative law by name with its settings and units."""
        name = type(c).__name__
        if _is_python(c):
            base = "a task-space law" if isinstance(c, TaskController) else \
                "a cooperative law" if isinstance(c, CooperativeController) else "a controller"
            return f"{name} (written in Python, {base}: its settings are its own)"
        if isinstance(c, PID):
            return f"PID: kp [{_fmt(c.kp)}], ki [{_fmt(c.ki)}], kd [{_fmt(c.kd)}]"
        if isinstance(c, ComputedTorque):
            return f"Computed torque: kp [{_fmt(c.kp)}] 1/s², kd [{_fmt(c.kd)}] 1/s"
        if isinstance(c, TaskController):
            along = ", ".join(c.commanded or c.directions or ()) or "every commandable direction"
            if isinstance(c, Impedance):
                return (f"Impedance (task space) along {along}: stiffness [{_fmt(c.stiffness)}] N/m or N m/rad, "
                        f"damping [{_fmt(c.damping)}] N s/m or N m s/rad, mass [{_fmt(c.mass)}] kg or kg m²")
            if isinstance(c, HybridForce):
                return (f"Hybrid force (task space): force [{_fmt(c.force)}] N along "
                        f"{', '.join(c.force_directions)}, kp_force [{_fmt(c.kp_force)}], ki_force "
                        f"[{_fmt(c.ki_force)}] 1/s, kv [{_fmt(c.kv)}] 1/s; position kp [{_fmt(c.kp)}] 1/s², "
                        f"kd [{_fmt(c.kd)}] 1/s")
            return f"{name} (task space, along {along})"
        if isinstance(c, ObjectControl):
            return (f"ObjectControl (object-level): load share {c.load_share:.3g}, squeeze {c.squeeze:.4g} N")
        fields = [(a, u) for a, u in (("kp", "1/s²"), ("kd", "1/s"), ("stiffness", ""), ("damping", ""),
                                      ("mass", ""), ("object_mass", "kg"), ("follower_share", ""))
                  if hasattr(c, a)]
        parts = []
        for a, u in fields:
            try:
                parts.append(f"{a} [{_fmt(getattr(c, a))}]" + (f" {u}" if u else ""))
            except Exception:       # pragma: no cover - a property that cannot be read now
                pass
        return f"{name}" + (": " + ", ".join(parts) if parts else "")

    def _make_gain_fields(self, i: int, inside: bool = False) -> None:
        """Robot i's fields for its own controller's settings (if the page can edit its kind), placed under its
        controller's line; the previous ones removed. inside: called within the robot's folder's block."""
        gui = self.server.gui
        for f in self._gain_fields[i].values():
            f.remove()
        if self._gain_button[i] is not None:
            self._gain_button[i].remove()
        self._gain_fields[i], self._gain_button[i] = {}, None
        labels = self._gain_labels(i)
        if not labels:
            return
        base = self._controller_md[i].order
        with (contextlib.nullcontext() if inside else self._folders[i]):
            fields = {name: gui.add_text(label, initial_value=self._gain_text(i, name), order=base + 0.001 * (k + 1))
                      for k, (name, label) in enumerate(labels)}
            apply = gui.add_button("Set gains", order=base + 0.001 * (len(labels) + 1))
        apply.on_click(lambda e, i=i, fields=fields: self.set_gains(
            i, **{name: f.value for name, f in fields.items()}))
        self._gain_fields[i], self._gain_button[i] = fields, apply

    def _gain_labels(self, i: int) -> tuple:
        """(setting name, field label) of robot i's own controller: PID kp, ki, kd; ComputedTorque kp, kd;
        Impedance stiffness, damping, mass; HybridForce force and its gains; else none."""
        k = _kind(self.sim.controllers[i])
        return tuple((name, label) for name, label, _ in _SETTINGS[k]) if k else ()

    def _gain_text(self, i: int, name: str) -> str:
        """Robot i's setting `name` as a field's text: the shortest that reads back as the same floats (a field
        set unchanged gives the same value)."""
        return ", ".join(repr(float(x)) for x in np.atleast_1d(getattr(self.sim.controllers[i], name)))

    def _refresh_drivers(self) -> None:
        """On the simulation's thread: each robot's controller line anew when what drives it changed (a
        cooperative group added or removed, a controller replaced), its fields remade for another kind of
        controller or filled with the new values."""
        for i in range(len(self.robots)):
            text = self._controller_text(i)
            kind = type(self.sim.controllers[i])
            old = self._driver_key[i]
            if old is not None and old == (text, kind):
                continue
            self._driver_key[i] = (text, kind)
            self._controller_md[i].content = text
            if old is None or old[1] is not kind:
                self._make_gain_fields(i)
            else:
                for name, f in self._gain_fields[i].items():
                    f.value = self._gain_text(i, name)

    def set_gains(self, i: int, **gains) -> None:
        """Replaces robot i's controller by one of the same kind with the given settings, the others kept: PID
        kp, ki, kd; ComputedTorque kp (1/s²), kd (1/s); Impedance stiffness (N/m, N m/rad), damping (N s/m,
        N m s/rad), mass (kg, kg m²); HybridForce force (N, N m), kp_force, ki_force (1/s), kv (1/s), kp (1/s²),
        kd (1/s); each numbers or a text "a, b, ...". The laws have no setters: a new law of the same kind is
        built with the other settings kept (directions, feedback, jaw and null-space gains, payload, model,
        filters) and put in through ``Simulation.set_controller`` on the simulation's thread: it acts from the
        next control step (a PID's integral restarting at zero). A robot driven by a cooperative group gets the
        new controller as its own, which acts when the group is removed (the message says so). Refused with a
        message in the Robots panel: text, NaN, a negative gain, a wrong count (the constructor's and
        set_controller's checks), a Python controller."""
        try:
            i = self._robot_index(i)
            allowed = [name for name, _ in self._gain_labels(i)]
            if not allowed:
                raise ValueError(f"{self.labels[i]}'s controller, {type(self.sim.controllers[i]).__name__}, "
                                 "has no settings editable here")
            values = {}
            for name, text in gains.items():
                if name not in allowed:
                    raise ValueError(f"gain must be one of {allowed} for {self.labels[i]}, got {name!r}")
                items = _items(text)
                if not items:
                    raise ValueError(f"{name} of {self.labels[i]} must be 1 or {self.robots[i].dof} numbers, got none")
                values[name] = np.array([_number(t, f"{name}[{j}] of {self.labels[i]}") for j, t in enumerate(items)])
        except ValueError as e:
            self._say(f"Refused: {e}", "robots")
            return

        def go():
            try:
                c = self.sim.controllers[i]
                new = self._rebuilt(c, values)
                self.sim.set_controller(i, new)
            except ValueError as e:
                self._say(f"Refused: {e}", "robots")
                return
            self._driver_key[i] = (None, type(new))     # the line and the fields' values anew
            self._refresh_drivers()
            g = self._group_of(i)
            after = f" (its own controller: acts when cooperative group {g['group']} is removed)" if g else ""
            self._say(f"{self.labels[i]}: new {type(new).__name__} settings "
                      + "; ".join(f"{k} [{self._gain_text(i, k)}]" for k in values) + after, "robots")
        self.submit(go)

    @staticmethod
    def _rebuilt(c, values: dict):
        """A new controller of c's kind with `values` ({setting: array}) and every other setting of c."""
        if isinstance(c, PID):
            g = {name: values.get(name, getattr(c, name)) for name in ("kp", "ki", "kd")}
            return PID(g["kp"], g["ki"], g["kd"], gravity_compensation=c.gravity_compensation,
                       derivative_filter=c.derivative_filter, integral_limit=c.integral_limit, model=c.model)
        if isinstance(c, ComputedTorque):
            g = {name: values.get(name, getattr(c, name)) for name in ("kp", "kd")}
            return ComputedTorque(g["kp"], g["kd"], model=c.model)
        args, kw = c.__getstate__()          # the constructor's arguments (as pickling rebuilds it)
        args = list(args)
        for name, _, pos in _SETTINGS[type(c)]:
            if name in values:
                if pos is None:
                    kw[name] = values[name]
                else:
                    args[pos] = values[name]
        return type(c)(*args, **kw)

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
            self._say(f"Refused: {e}", "robots")
            return

        def go():
            try:
                self.sim.set_robot(i, new)
            except ValueError as e:
                self._say(f"Refused: {e}", "robots")
                return
            self.robots[i] = self.sim.robots[i]
            self._rescale()
            self._dimensions_md[i].content = self._dimensions_text(i)
            self._say(f"{self.labels[i]}: rebuilt with " + ", ".join(f"{k} {float(v):.4g} m" for k, v in dims.items()),
                      "robots")
        self.submit(go)

    # ---- the Plots panel ----

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
                or g is not None or o["noise_force"] > 0 or o["noise_moment"] > 0 or o["time_constant"] > 0:
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

    def _refusing(self, fn: Callable[[], None], panel: str = "robots") -> None:
        try:
            fn()
        except ValueError as e:
            self._say(f"Refused: {e}", panel)

    def _say(self, text: str, panel: str = "run") -> None:
        """Shows `text` in the message line of `panel` ('run', 'display', 'robots', 'plots', 'data'), replacing
        the line's previous message (a refusal goes when a later request of that panel succeeds); "" clears it.
        The last message of any panel is also :attr:`message`."""
        msgs = getattr(self, "_msgs", None)
        if msgs is not None and panel not in msgs:
            raise ValueError(f"panel must be one of {list(msgs)}, got {panel!r}")
        self.message = text
        if msgs is not None:
            msgs[panel].content = f"**{text}**" if text else ""

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
        self._say(f"Move time {self._move_time:g} s", "robots")

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
            self._say(f"Refused: {e}", "robots")
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
            self._say(f"Refused: {e}", "robots")
            return

        def go():
            try:
                q = self.robots[i].ik(T, q_near=self.sim.state(i)[0])
            except ValueError as e:        # IKError is a ValueError: out of reach
                self._say(f"Refused: {e}", "robots")
                return
            self._move(i, q)
        self.submit(go)

    def _robot_index(self, i) -> int:
        n = len(self.robots)
        if not isinstance(i, (int, np.integer)) or isinstance(i, bool) or not 0 <= i < n:
            raise ValueError(f"robot must be an index in [0, {n}), got {i!r}")
        return int(i)

    def _move(self, i: int, target: np.ndarray) -> None:
        """On the simulation's thread: robot i's new reference, a cubic from its state now to target; its
        sliders, joint target and gizmo show the target at once."""
        q, qd = self.sim.state(i)
        t = self.sim.time
        ref = CubicTrajectory([t, t + self._move_time], np.vstack([q, target]),
                              np.vstack([qd, np.zeros_like(qd)]))
        self.sim.set_reference(i, ref)
        self._taught[i] = (ref, np.array(target, dtype=float))
        self._show_target(i, self._taught[i][1], force=True)
        self._say(f"{self.labels[i]}: moving to [{', '.join(f'{x:.4g}' for x in target)}] "
                  f"in {self._move_time:g} s", "robots")

    # ---- the teach controls kept in step with the robot ----

    def _touch(self, i: int) -> None:
        if not self._syncing:
            self._touched[i] = time.monotonic()

    def _slider_moved(self, i: int, e) -> None:
        if self._syncing:
            return
        self._touch(i)
        self.teach_joints(i, [x.value for x in self._teach[i][0]], client=e.client)

    def _tracked(self, i: int, f: Frame) -> np.ndarray:
        """What robot i's controls show: the target of the teach move it is on, else what it tracks now
        (its reference at the frame's time)."""
        taught = self._taught.get(i)
        if taught is not None:
            ref = self.sim.references[i]
            if ref is taught[0] or (isinstance(ref, CubicTrajectory) and ref.t_start == taught[0].t_start
                                    and np.array_equal(ref.q_points[-1], taught[1])):
                return taught[1]
            del self._taught[i]
        return np.asarray(f.q_ref[i], dtype=float)

    def _show_target(self, i: int, target: np.ndarray, force: bool = False) -> None:
        """Robot i's sliders, joint target and gizmo set to `target` (n,), unless the user touched them in the
        last _HOLD_OFF s or drags the gizmo (not fighting a user), or they show it already."""
        if i >= len(self._teach):
            return
        if not force and (i in self._dragging or time.monotonic() - self._touched.get(i, -math.inf) < _HOLD_OFF):
            return
        shown = self._shown_target.get(i)
        if shown is not None and shown.shape == target.shape and np.allclose(shown, target, rtol=0, atol=1e-9):
            return
        self._shown_target[i] = np.array(target, dtype=float)
        sliders, field = self._teach[i]
        r = self.robots[i]
        self._syncing = True
        try:
            for j, s in enumerate(sliders):
                lo, hi = (float(x) for x in r.q_limits[j])
                s.value = float(np.clip(target[j], lo, hi))
            field.value = ", ".join(f"{x:.4g}" for x in target)
            g = self._gizmos.get(i)
            if g is not None and i not in self._dragging:
                T = np.asarray(r.fk(target))
                g.wxyz = quaternions(T[:3, :3])[0]
                g.position = T[:3, 3]
        finally:
            self._syncing = False

    def _follow(self, f: Frame) -> None:
        """On the simulation's thread: every robot's teach controls in step with what it tracks."""
        for i in range(len(self.robots)):
            self._show_target(i, self._tracked(i, f))

    def _toggle_gizmo(self, i: int, on: bool) -> None:
        if not on:
            g = self._gizmos.pop(i, None)
            if g is not None:
                g.remove()
            self._dragging.discard(i)
            return
        target = self._shown_target.get(i)
        T = np.asarray(self.robots[i].fk(target if target is not None else self.frame.q[i]))   # what it tracks
        g = self.server.scene.add_transform_controls(f"/gizmo{i}", scale=0.15, wxyz=quaternions(T[:3, :3])[0],
                                                     position=T[:3, 3], depth_test=False)

        def moved(e, i=i):
            if e.phase == "start":
                self._dragging.add(i)
            elif e.phase == "end":
                self._dragging.discard(i)
                self._touched[i] = time.monotonic()
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
        if round(self.pacer.speed_percent) != self._speed.value and not self._syncing:
            self._sync_speed()
        if now - getattr(self, "_last_drivers", -math.inf) >= _PLOT_EVERY:
            self._last_drivers = now
            self._refresh_drivers()
            self._follow(f)

    # ---- the plots' data ----

    def _extras(self, i: int):
        """(sensed wrench (6,), task-space error (6,) or None, (squeeze, share of i, share of the other) or
        None) of robot i now, on the simulation's thread."""
        wrench = np.asarray(self.sim.sensor(i)["ft_world"], dtype=float)
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
            share = np.asarray(c["load_share"], dtype=float)
            coop = np.array([float(c["squeeze"]), share[0 if i == a else 1], share[1 if i == a else 0]])
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
