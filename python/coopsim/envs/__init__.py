"""Gymnasium environments of coopsim (the ``gym`` extra: ``pip install coopsim[gym]``).

Importing this module registers them with Gymnasium (Gymnasium 1.x loads no plugins by entry point, so
``import coopsim.envs`` first, or name the module in the id: ``gym.make("coopsim.envs:coopsim/Reach-v0")``):

- ``coopsim/Reach-v0`` (:class:`~coopsim.envs.reach.ReachEnv`): one SCARA #1 brings its TCP to a seeded
  target; joint torques or TCP set-points as actions.
- ``coopsim/DualCarry-v0`` (:class:`~coopsim.envs.carry.DualCarryEnv`): the dual carry of
  :mod:`coopsim.tasks.carry` from the grasp on, the cooperative law's commands as actions.
- ``coopsim/Handover-v0`` (:class:`~coopsim.envs.handover.HandoverEnv`): one cycle of the handover of
  :mod:`coopsim.tasks.handover`, scripted, the bar's yaw at the handover as the one action; reward the outcome.

``coopsim.envs.dual_carry_parallel()`` (:mod:`coopsim.envs.parallel`, PettingZoo) is the dual carry with one
agent per arm. Reach-v0 and DualCarry-v0 have a vector entry point (:mod:`coopsim.envs.vector`):
``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")`` steps N simulations in one
engine call on threads. See docs/envs.md.
"""
from __future__ import annotations

import gymnasium as gym

from .carry import DualCarryEnv
from .handover import HandoverEnv
from .parallel import DualCarryParallelEnv, dual_carry_parallel
from .reach import ReachEnv
from .vector import CoopsimVectorEnv

__all__ = ["CoopsimVectorEnv", "DualCarryEnv", "DualCarryParallelEnv", "ENV_IDS", "HandoverEnv", "ReachEnv",
           "dual_carry_parallel"]

#: the registered ids
ENV_IDS = ("coopsim/Reach-v0", "coopsim/DualCarry-v0", "coopsim/Handover-v0")

_ENTRIES = {
    "coopsim/Reach-v0": ("coopsim.envs.reach:ReachEnv", "coopsim.envs.vector:make_reach_vec"),
    "coopsim/DualCarry-v0": ("coopsim.envs.carry:DualCarryEnv", "coopsim.envs.vector:make_carry_vec"),
    "coopsim/Handover-v0": ("coopsim.envs.handover:HandoverEnv", None),     # one step: Gymnasium's vectors
}

for _id, (_entry, _vector) in _ENTRIES.items():
    if _id not in gym.registry:
        gym.register(_id, entry_point=_entry, vector_entry_point=_vector, disable_env_checker=False)
