"""The live page's Robots panel, what drives each robot: its controller or its cooperative group's law as a
line with its settings and units, the fields of the settings the page edits (PID, computed torque, impedance,
hybrid force) and a new law of the same kind when they are set, the built-in SCARAs' dimensions and their
rebuild; a mixin of LiveView (:class:`~coopsim.view.live.panels._Panels` builds the panel, the teach mode is
:mod:`~coopsim.view.live.teach`'s)."""
from __future__ import annotations

import contextlib

import numpy as np

from ..._core import (PID, ComputedTorque, CooperativeController, HybridForce, Impedance, ObjectControl,
                      TaskController)
from ...robots import scara1, scara2
from ... import _checks

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


class _RobotsPanel:
    """What drives each robot, its editable settings and dimensions (a mixin of LiveView)."""

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
                items = _checks.items(text)
                if not items:
                    raise ValueError(f"{name} of {self.labels[i]} must be 1 or {self.robots[i].dof} numbers, got none")
                values[name] = np.array([_checks.number(t, f"{name}[{j}] of {self.labels[i]}", text=True)
                                         for j, t in enumerate(items)])
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
                new_dims[key] = _checks.number(text, f"{key} of {self.labels[i]}", text=True)
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

    def _robot_index(self, i) -> int:
        n = len(self.robots)
        if not isinstance(i, (int, np.integer)) or isinstance(i, bool) or not 0 <= i < n:
            raise ValueError(f"robot must be an index in [0, {n}), got {i!r}")
        return int(i)
