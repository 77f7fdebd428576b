"""The dual carry with one agent per arm: a PettingZoo ``ParallelEnv`` (:func:`dual_carry_parallel`).

The episode is :class:`~coopsim.envs.carry.DualCarryEnv`'s (the same seeds, scripted approach and grasp,
control periods, terminations and failures); its two agents, ``"scara_1"`` and ``"scara_2"`` (SCARA #1 and
#2, the law's clamps 0 and 1), each send their share of the cooperative law's commands and earn their own
arm's reward term.

Action of each agent: Box (5,) float64: [offset (3,) m, squeeze part N, load claim]: the bar's offset is the
mean of the two agents' offsets (each within +-``max_offset``), the squeeze the sum of their parts (each in
[0, 1.5] N: the single environment's [0, 3] when both agree), and SCARA #1's load share its claim over
the two claims (each in [0, 1]; 1/2 when both claim nothing). :attr:`DualCarryParallelEnv.scripted_action`
([0, 0, 0, 0, 0.5] each) is the scripted carry's.

Observation of each agent: a Dict of its own arm (q, qd (6,); clamp_pose (7,): its TCP's position m and
quaternion [w, x, y, z]; clamp_twist (6,); wrench (6,): its clamp's sensed wrench, world axes) and of the
bar they share (bar_pose (7,), bar_twist (6,), bar_error (6,), internal (12,), squeeze (1,) N), its own
load share (1,) and the phase (1,): the single environment's observation split by arm.

Reward of each agent: its arm's term of the single environment's reward, ``info["reward_terms"]["arms"][i]``
times the internal-force factor, in [0, 1] (its TCP on its planned grip, its load share near a half, the
bar not squeezed): an agent whose partner drops its share of the load loses too. The single environment's
reward is the smaller of the two.

All agents end together (terminated at the place or a failure, as the single environment); ``agents`` is
then empty until reset. ``reset(options=)`` takes the single environment's ``bar_mass``; other keys are
ignored (PettingZoo's API test passes one of its own).
"""
from __future__ import annotations

import functools
from typing import Optional

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from ._common import bounded, check_action
from .carry import SQUEEZE_RANGE, DualCarryEnv

__all__ = ["AGENTS", "DualCarryParallelEnv", "dual_carry_parallel"]

#: the agents: SCARA #1 (clamp 0 of the law) and SCARA #2
AGENTS = ("scara_1", "scara_2")
#: the parts of an agent's observation taken from its own arm's row of the single environment's
_OWN = ("q", "qd", "clamp_pose", "clamp_twist", "wrench", "load_share")
_SHARED = ("bar_pose", "bar_twist", "bar_error", "internal", "squeeze", "phase")


class DualCarryParallelEnv(ParallelEnv):
    """The dual carry, one agent per arm (see the module's documentation). Keywords: those of
    :class:`~coopsim.envs.carry.DualCarryEnv` (control_rate Hz, bar_mass kg, max_offset m, render_mode)."""

    metadata = {"name": "coopsim_dual_carry_v0", "render_modes": ["rgb_array"], "render_fps": 50,
                "is_parallelizable": True}

    def __init__(self, **kwargs):
        self.env = DualCarryEnv(**kwargs)
        self.render_mode = self.env.render_mode
        self.metadata = dict(self.metadata, render_fps=self.env.metadata["render_fps"])
        self.possible_agents = list(AGENTS)
        self.agents: list = []
        m = self.env.max_offset
        lo, hi = SQUEEZE_RANGE
        self._action_space = spaces.Box(np.array([-m, -m, -m, lo / 2.0, 0.0]), np.array([m, m, m, hi / 2.0, 1.0]),
                                        dtype=np.float64)
        single = self.env.observation_space.spaces
        parts = {name: bounded(single[name].shape[1:]) for name in _OWN}      # its own arm's row
        parts["load_share"] = bounded((1,))
        parts.update({name: single[name] for name in _SHARED})
        self._observation_space = spaces.Dict(parts)
        self.scripted_action = np.array([0.0, 0.0, 0.0, 0.0, 0.5])

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent):
        self._check_agent(agent)
        return self._observation_space

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent):
        self._check_agent(agent)
        return self._action_space

    def _check_agent(self, agent):
        if agent not in self.possible_agents:
            raise ValueError(f"agent must be one of {', '.join(map(repr, self.possible_agents))}, got {agent!r}")

    # ---- the split and the merge ----

    def commands(self, actions: dict) -> np.ndarray:
        """The single environment's action (5,) of the agents' actions (a dict of both agents' (5,) arrays):
        the mean offset, the summed squeeze, SCARA #1's claim over both claims. ValueError naming the agent
        for an action missing or outside its space."""
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict of each agent's action, got {type(actions).__name__}")
        extra = sorted(set(actions) - set(self.agents))
        if extra:
            raise ValueError(f"actions holds agents not in the episode: {', '.join(map(repr, extra))} "
                             f"(live: {self.agents})")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"actions must hold an action of each live agent, missing {', '.join(map(repr, missing))}")
        a = [check_action(actions[name], self._action_space, f"actions[{name!r}]") for name in AGENTS]
        claims = a[0][4] + a[1][4]
        share = 0.5 if claims == 0.0 else a[0][4] / claims
        return np.r_[(a[0][:3] + a[1][:3]) / 2.0, a[0][3] + a[1][3], share]

    def _split(self, obs: dict) -> dict:
        out = {}
        for i, name in enumerate(AGENTS):
            o = {k: np.array(obs[k][i]) for k in _OWN}
            o["load_share"] = np.array(obs["load_share"][i:i + 1])
            o.update({k: np.array(obs[k]) for k in _SHARED})
            out[name] = o
        return out

    # ---- PettingZoo ----

    def reset(self, seed: Optional[int] = None, options: Optional[dict] = None):
        known = {k: v for k, v in (options or {}).items() if k == "bar_mass"}
        obs, info = self.env.reset(seed=seed, options=known or None)
        self.agents = list(AGENTS)
        return self._split(obs), {name: dict(info) for name in self.agents}

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("step() after the episode ended: call reset() first")
        obs, reward, terminated, truncated, info = self.env.step(self.commands(actions))
        terms = info.get("reward_terms")
        rewards, infos = {}, {}
        for i, name in enumerate(self.agents):
            rewards[name] = 0.0 if terms is None else float(terms["arms"][i] * terms["internal_factor"])
            infos[name] = dict(info)
        out = self._split(obs)
        done = dict.fromkeys(self.agents, bool(terminated))
        cut = dict.fromkeys(self.agents, bool(truncated))
        if terminated or truncated:
            self.agents = []
        return out, rewards, done, cut, infos

    def render(self):
        return self.env.render()

    def close(self):
        self.env.close()

    def state(self) -> np.ndarray:
        """The whole episode's state: the single environment's observation flattened (its parts in order)."""
        obs = self.env._observe()
        return np.concatenate([np.ravel(obs[name]) for name, _, _ in self.env._layout])


def dual_carry_parallel(**kwargs) -> DualCarryParallelEnv:
    """The dual carry as a PettingZoo ``ParallelEnv`` of one agent per arm (:class:`DualCarryParallelEnv`;
    keywords: control_rate Hz, bar_mass kg, max_offset m, render_mode)."""
    return DualCarryParallelEnv(**kwargs)
