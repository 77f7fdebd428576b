"""The live page's panels: the tabs Run, Display, Robots, Plots and Data built, each panel with one message line
that the next message replaces, and the Display panel's switches. The panels' jobs are their own mixins: the
Run panel's state, speed and time supervision (run_panel), what drives each robot and its settings and
dimensions (robots_panel), the teach mode (teach), the plots (plots_panel), the Data panel (data); their
requests are checked there and applied on the simulation's thread."""
from __future__ import annotations

import threading
from typing import Callable

import numpy as np

from .common import _DIMENSION_FIELDS
from .plots_panel import _PlotsPanel
from .robots_panel import _RobotsPanel
from .run_panel import _RunPanel
from .teach import _TeachMode

_PANEL_NAMES = ("run", "display", "robots", "plots", "data")
#: the tabs' titles, in the page's order (what the page's readiness waits for: serving.announce_readiness)
TAB_TITLES = ("Run", "Display", "Robots", "Plots", "Data")


class _Panels(_RunPanel, _RobotsPanel, _TeachMode, _PlotsPanel):
    """The panels of a LiveView (a mixin: the view holds the server, the simulation and the queue): the tabs
    built here, each panel's message line, the Display panel; the Run panel's state and supervision
    (:mod:`~coopsim.view.live.run_panel`), what drives each robot (:mod:`~coopsim.view.live.robots_panel`),
    the teach mode (:mod:`~coopsim.view.live.teach`) and the plots (:mod:`~coopsim.view.live.plots_panel`)
    from their mixins."""

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
        self._speed_pending = 0          # speed requests waiting for the simulation's thread (under _speed_lock)
        self._speed_lock = threading.Lock()
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
            self._speed_known = self.pacer.speed_percent
            self._speed.on_update(lambda e: None if self._syncing else
                                  self._set_speed_percent(e.target.value, from_slider=True))
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
