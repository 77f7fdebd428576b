"""The live page's teach mode (in the Robots panel): joint sliders, a joint target typed in and a gizmo at the
clamp (closed-form IK), each a cubic from where the robot is to the target as its new reference, and the
controls kept in step with what the robot tracks without fighting a user who touches them; a mixin of LiveView."""
from __future__ import annotations

import math
import time

import numpy as np

from ..._core import CubicTrajectory
from ... import _checks
from .common import _rotation, quaternions
from .drawing import Frame

_HOLD_OFF = 2.0        # s of wall time a robot's teach controls are left alone after the user touched one


class _TeachMode:
    """Teach moves and the teach controls kept in step with the robot (a mixin of LiveView)."""

    @staticmethod
    def _check_move_time(value) -> float:
        v = _checks.number(value, "move time", text=True)
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
            target = _checks.numbers(q, r.dof, f"joint target of {self.labels[i]}", text=True)
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
