"""The live page's panels: Run (speed, pause, step, reset, the time supervision), Display, Robots (controllers,
gains, dimensions, teach mode), Plots and Data; their requests checked here and applied on the simulation's
thread."""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..._core import PID, ComputedTorque, CubicTrajectory
from ...robots import scara1, scara2
from .drawing import Frame
from .common import (_DIMENSION_FIELDS, _PLOT_EVERY, _WINDOW, _items, _number, _numbers, _rotation,
                     quaternions)


class _Panels:
    """The panels of a LiveView (a mixin: the view holds the server, the simulation and the queue)."""

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

    def _pick_plot(self, i: int) -> None:
        with self._lock:
            self._plot_robot = i
            self._plot_q.remove()
            self._plot_e.remove()
            self._plot_q, self._plot_e = self._make_plots(i)
            self._last_plot = -math.inf
            self._changes += 1

    def _refusing(self, fn: Callable[[], None]) -> None:
        try:
            fn()
        except ValueError as e:
            self._say(f"Refused: {e}")

    def _say(self, text: str) -> None:
        self.message = text
        self._msg.content = f"**{text}**" if text else ""

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

