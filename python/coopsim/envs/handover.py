"""``coopsim/Handover-v0``: the handover of :mod:`coopsim.tasks.handover` (docs/handover.md) with the bar's yaw at the
handover as the agent's one decision.

An episode is one handover cycle of one bar: ``reset(seed=)`` draws the bar's start on the floor from the
seed (:func:`coopsim.tasks.handover.random_bar`, as ``tasks.handover.run(seed=s)`` draws it) and observes it;
``step(action)`` takes the handover yaw and runs the whole cycle with the task's scripted phases (SCARA #2's
pick and carry to the handover, #1's grasp in the air, #2's release, the insertion and the slide down the
tube; :func:`coopsim.tasks.handover.run`, unscored), and the episode ends (a contextual bandit: one step).

The yaw matters: at the task's 285 deg both robots reach the bar's grips clear of each other; far from it
SCARA #2 cannot reach a grip both at the pick and at the handover (the plan fails) or its clamp arrives too
fast to grasp, or the arms meet.

Action: Box (1,) float64, the bar's yaw at the handover (rad) within +-45 deg of the task's
(:data:`coopsim.tasks.handover.HANDOVER_YAW`, 285 deg). :attr:`HandoverEnv.scripted_action` is the task's.

Observation: Box (3,) float64, the bar's start on the floor: x, y (m) and yaw (rad), within the task's
:data:`~coopsim.tasks.handover.REGION`.

Reward: the task's outcome, 1 when the bar ends in the container by the task's rules (no forbidden contact,
the grasps and the release happen, the bar slides down the tube), 0 otherwise. Terminated after the step,
with ``info["success"]`` and on a failure ``info["failure"]`` = {step, t, reason} (the plan's own refusal:
step ``"plan"``). No truncation. No render modes (the task's report and live page show a run:
``tasks.handover.run(live=True)``).
"""
from __future__ import annotations

from typing import Optional

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .._core import IKError
from ..tasks import handover as _handover
from ._common import check_action

__all__ = ["HandoverEnv"]

#: the action's half-range about the task's handover yaw (rad)
YAW_RANGE = np.radians(45.0)


class HandoverEnv(gym.Env):
    """One handover cycle, the handover yaw as the action (see the module's documentation). Keywords:
    those of :func:`coopsim.tasks.handover.run` that set the simulation (dt, log_every, world_every,
    control_every), the container (mouth, slope) or a fault (container_shift, grip1_turn)."""

    metadata = {"render_modes": []}

    def __init__(self, render_mode: Optional[str] = None, **run_options):
        if render_mode is not None:
            raise ValueError(f"render_mode must be None (Handover-v0 draws no frames), got {render_mode!r}")
        allowed = {"dt", "log_every", "world_every", "control_every", "mouth", "slope", "container_shift",
                   "grip1_turn"}
        unknown = sorted(set(run_options) - allowed)
        if unknown:
            raise ValueError(f"unknown keyword(s) of Handover-v0: {', '.join(unknown)} (choose from "
                             f"{', '.join(sorted(allowed))})")
        self.render_mode = None
        self.run_options = run_options
        yaw = _handover.HANDOVER_YAW
        self.action_space = spaces.Box(np.array([yaw - YAW_RANGE]), np.array([yaw + YAW_RANGE]), dtype=np.float64)
        self.scripted_action = np.array([yaw])
        region = _handover.REGION
        self.observation_space = spaces.Box(np.array([region["x"][0], region["y"][0], region["yaw"][0]]),
                                            np.array([region["x"][1], region["y"][1], region["yaw"][1]]),
                                            dtype=np.float64)
        self.result = None
        self._done = True

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        if options:
            raise ValueError(f"Handover-v0's reset takes no options, got {', '.join(map(repr, options))}")
        draw = int(seed) if seed is not None else int(self.np_random.integers(0, 2 ** 31 - 1))
        self.bar = _handover.random_bar(draw)
        self.result = None
        self._done = False
        return self._observe(), dict(seed=draw)

    def _observe(self) -> np.ndarray:
        T = self.bar
        obs = np.array([T[0, 3], T[1, 3], np.arctan2(T[1, 0], T[0, 0])])
        return np.clip(obs, self.observation_space.low, self.observation_space.high)

    def step(self, action):
        if self._done:
            raise RuntimeError("step() after the episode ended: call reset() first")
        a = check_action(action, self.action_space)
        yaw = float(a[0])
        info = dict(handover_yaw=yaw, success=False)
        try:
            self.result = _handover.run([self.bar], handover_yaw=yaw, score=False, **self.run_options)
        except IKError as e:              # the plan refuses: no grip reachable both at the pick and the handover
            info["failure"] = dict(step="plan", t=0.0, reason=str(e).splitlines()[0])
        else:
            cycle = self.result.report["cycles"][0]
            info["success"] = bool(self.result.success)
            info["time"] = float(self.result.report["simulated_time"])
            if not info["success"]:
                info["failure"] = dict(step=cycle.get("failed_step"), t=cycle.get("failed_at"),
                                       reason=cycle.get("reason"))
        self._done = True
        return self._observe(), float(info["success"]), True, False, info
