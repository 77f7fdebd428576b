"""``coopsim/Reach-v0``: one SCARA #1 brings its tool centre point (TCP) to a target position.

The target is drawn from the seed inside the workspace: a joint configuration drawn uniformly within the
joint limits (the wrist and jaw at their start), its TCP position by forward kinematics, so it is reachable.
The robot starts at rest at :data:`Q0`. Each step applies the action and advances the engine one control
period (default 50 Hz: 100 engine steps of 0.2 ms) in one call (``Simulation.advance``).

Actions (chosen at construction):

- ``action="torque"`` (default): joint torques (6,) N m / N, the Box of the actuator limits
  (``robot.tau_limits``), held over the period; no controller (not even gravity compensation).
- ``action="setpoint"``: a TCP position offset (3,) m from where the TCP is now, each within
  +-``max_offset``; the joint set-point whose TCP is there (closed-form IK near the present q, the tool's
  orientation kept) is tracked by :class:`coopsim.ComputedTorque` (omega 30 rad/s on the arm joints, 60 on the
  wrist and jaw). A set-point out of reach keeps the last one (``info["ik_failed"]``).

Observation: Box (21,) float64 (within +-1e4, clipped): q (6,), qd (6,), the TCP's position (3,) m, the target (3,) m and the target
less the TCP (3,) m. Reward per step: -(distance to the target, m) - torque_penalty * mean((tau / tau_max)^2).
Terminated (success) when the TCP is within ``tolerance`` (1 cm) of the target moving slower than
``max_speed`` (0.05 m/s); truncated at ``time_limit`` (s). ``info``: distance (m), speed (m/s), success, time
(s). A run that diverges (DivergenceError) terminates with ``info["failure"]``.
"""
from __future__ import annotations

from typing import Optional

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import _checks
from .. import robots as _robots
from ..view import Body, live
from .._core import ComputedTorque, DivergenceError, IKError, PID
from ..simulation import Simulation
from ._common import DT, Frames, bounded, check_action, check_render_mode, clip, control_period

__all__ = ["Q0", "ReachEnv"]

#: the start: the arm bent, the TCP 0.12 m above its lowest, the clamp pointing down, the jaw half open
Q0 = np.array([0.0, 1.2, 0.12, 0.0, np.pi / 2, 0.025])
#: the ComputedTorque gains of action="setpoint": omega (rad/s) per joint, kp = omega^2, kd = 2 omega
OMEGA = np.array([30.0, 30.0, 30.0, 60.0, 60.0, 60.0])
ACTIONS = ("torque", "setpoint")


class ReachEnv(gym.Env):
    """One SCARA #1 reaching a seeded target (see the module's documentation for the spaces and the reward).

    action: 'torque' or 'setpoint'. control_rate: Hz (default 50; a whole number of 0.2 ms steps per
    period). time_limit: s of simulated time before truncation (default 4). tolerance: m (0.01),
    max_speed: m/s (0.05): success. torque_penalty: the weight of the torque term (1e-3). max_offset: m, the
    set-point's reach per step (0.05). render_mode: None, 'rgb_array' (frames from :func:`coopsim.view.draw`)
    or 'human' (the live page, :func:`coopsim.view.live`, paced at real time; needs the ``live`` extra).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 50}

    def __init__(self, *, action: str = "torque", control_rate: float = 50.0, time_limit: float = 4.0,
                 tolerance: float = 0.01, max_speed: float = 0.05, torque_penalty: float = 1e-3,
                 max_offset: float = 0.05, render_mode: Optional[str] = None):
        _checks.one_of(action, "action", ACTIONS)
        time_limit = _checks.positive(time_limit, "time_limit", unit="s")
        tolerance = _checks.positive(tolerance, "tolerance", unit="m")
        max_speed = _checks.positive(max_speed, "max_speed", unit="m/s")
        max_offset = _checks.positive(max_offset, "max_offset", unit="m")
        torque_penalty = _checks.positive(torque_penalty, "torque_penalty", zero=True)
        self.render_mode = check_render_mode(render_mode, self.metadata["render_modes"])
        self.mode = action
        self.period = control_period(control_rate)
        self.metadata = dict(self.metadata, render_fps=int(round(1.0 / self.period)))
        self.time_limit, self.tolerance, self.max_speed = float(time_limit), float(tolerance), float(max_speed)
        self.torque_penalty, self.max_offset = float(torque_penalty), float(max_offset)
        self.robot = _robots.scara1()
        self.tau_max = np.asarray(self.robot.tau_limits, float)
        n = self.robot.dof
        if action == "torque":
            self.action_space = spaces.Box(-self.tau_max, self.tau_max, dtype=np.float64)
            controller = PID(np.zeros(n), np.zeros(n), np.zeros(n), gravity_compensation=False)
        else:
            self.action_space = spaces.Box(-self.max_offset, self.max_offset, shape=(3,), dtype=np.float64)
            controller = ComputedTorque(OMEGA ** 2, 2.0 * OMEGA)
        self.observation_space = bounded((2 * n + 9,))
        self.sim = Simulation(dt=DT, log_every=0)
        self.sim.add_robot(self.robot, controller, Q0.copy(), q0=Q0.copy())
        self.target = self.robot.fk(Q0)[:3, 3].copy()
        self.setpoint = Q0.copy()
        self._frames = None
        self._live = None
        self._done = True

    # ---- the steps: apply, advance, read (the vector environment advances in between) ----

    def _draw_target(self):
        q = self.np_random.uniform(self.robot.q_limits[:, 0], self.robot.q_limits[:, 1])
        q[3:] = Q0[3:]
        return self.robot.fk(q)[:3, 3].copy()

    def _reset_sim(self, seed=None):
        """Resets the simulation and draws the target (the seed through Gymnasium's np_random)."""
        super().reset(seed=seed)
        self.sim.reset()
        self.setpoint = Q0.copy()
        if self.mode == "setpoint":
            self.sim.set_reference(0, self.setpoint.copy())
        else:
            self.sim.set_applied(0, forces=np.zeros(self.robot.dof))
        self.target = self._draw_target()
        self._done = False
        self._tau = np.zeros(self.robot.dof)

    def _apply(self, action, checked: bool = False) -> float:
        """Checks and applies `action` (`checked`: a float64 array of the space already checked, the
        environment's own); returns the time (s) the engine is to advance to."""
        a = action if checked else check_action(action, self.action_space)
        self._ik_failed = False
        if self.mode == "torque":
            self.sim.set_applied(0, forces=a)
            self._tau = a
        else:
            q = self.sim.state(0)[0]
            pose = self.robot.fk(q)
            pose[:3, 3] += a
            try:
                self.setpoint = np.asarray(self.robot.ik(pose, q_near=q, opening=Q0[-1]), float)
            except (IKError, ValueError):
                self._ik_failed = True
            self.sim.set_reference(0, self.setpoint.copy())
        return self._t_next()

    def _t_next(self) -> float:
        k = int(round(self.sim.time / self.period))
        return (k + 1) * self.period

    def _observe(self):
        q, qd = self.sim.state(0)
        tcp = self.robot.fk(q)[:3, 3]
        return clip(np.concatenate([q, qd, tcp, self.target, self.target - tcp])), tcp, q, qd

    def _outcome(self, error: Optional[BaseException] = None):
        """(observation, reward, terminated, truncated, info) after the engine advanced (error: what stopped
        it, or None)."""
        obs, tcp, q, qd = self._observe()
        if self.mode == "setpoint":
            self._tau = self.sim.torque(0)
        d = float(np.linalg.norm(self.target - tcp))
        speed = float(np.linalg.norm(self.robot.tool_jacobian(q)[:3] @ qd)) if error is None else float("nan")
        effort = float(np.mean((np.asarray(self._tau) / self.tau_max) ** 2))
        info = dict(distance=d, speed=speed, time=self.sim.time, success=False)
        if self.mode == "setpoint":
            info["ik_failed"] = self._ik_failed
        if error is not None:
            info["failure"] = f"{type(error).__name__}: {str(error).splitlines()[0]}"
            self._done = True
            return obs, -d if np.isfinite(d) else -1.0, True, False, info
        success = d < self.tolerance and speed < self.max_speed
        info["success"] = success
        reward = -d - self.torque_penalty * effort
        truncated = not success and self.sim.time >= self.time_limit - 1e-9
        self._done = success or truncated
        return obs, float(reward), bool(success), bool(truncated), info

    # ---- Gymnasium ----

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        self._reset_sim(seed)
        obs, tcp, _, _ = self._observe()
        return obs, dict(distance=float(np.linalg.norm(self.target - tcp)), time=0.0, success=False)

    def step(self, action):
        if self._done:
            raise RuntimeError("step() after the episode ended: call reset() first")
        t = self._apply(action)
        error = None
        try:
            if self.render_mode == "human":
                self._human().run_to(t)
            else:
                self.sim.advance(t)
        except DivergenceError as e:
            error = e
        return self._outcome(error)

    def render(self):
        if self.render_mode == "rgb_array":
            if self._frames is None:
                self._frames = Frames()
            T = np.eye(4)
            T[:3, 3] = self.target
            target = Body("target", np.full(3, 0.01), T, color="tab:blue")
            return self._frames.frame(self.sim, bodies=[target], label=f"t = {self.sim.time:.2f} s")
        if self.render_mode == "human":
            self._human()
        return None

    def _human(self):
        if self._live is None:
            self._live = live(self.sim, start=False, resettable=False, title="coopsim/Reach-v0")
            print(f"coopsim/Reach-v0: {self._live.url}")
        return self._live

    def close(self):
        if self._live is not None:
            self._live.close()
            self._live = None
        if self._frames is not None:
            self._frames.close()
            self._frames = None
