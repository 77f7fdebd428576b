"""Vector environments: N coopsim environments stepped together, their simulations advanced in one engine
call on a pool of threads with the GIL released (:meth:`coopsim.Simulation.advance_all`).

``gymnasium.make_vec("coopsim/DualCarry-v0", num_envs=N, vectorization_mode="vector_entry_point")`` (and
``"coopsim/Reach-v0"``) make them. Keywords: ``threads`` (the pool's size, 0: every core),
``autoreset_mode`` (``gymnasium.vector.AutoresetMode.NEXT_STEP``, Gymnasium's default, or ``SAME_STEP``),
and the single environment's keywords, each either one value for all or a sequence of N values, one per
environment (e.g. ``bar_mass=[0.1, 0.15, 0.2, 0.25]`` for domain randomisation). ``reset(seed=s)`` seeds the
environments s, s + 1, ...; ``reset(seed=[...])`` one seed each.

A step applies each environment's action (all actions are checked first: a bad one is refused, naming
its index, before any is applied), advances all simulations that end the step at the same time in one
engine call (environments in step with each other: one call; an environment reset at another time than the
others makes a second group), and reads each one's outcome, exactly as the single environment does: the
same seeds and actions give the single environments' episodes bit for bit.

With ``threads`` of 2 or more (or 0) the step runs its environments in a pipeline of chunks: the caller's
thread applies a chunk's actions (Python, holding the GIL) and hands the chunk to the engine's pool
(:meth:`coopsim.Simulation.advance_pool`, a thread less than ``threads``), whose threads advance its
simulations and read them (:meth:`coopsim.Simulation.pair_readout` for the carry) without ever taking the GIL,
while the caller applies the next chunk; the caller then takes each chunk's outcome as it finishes, and runs
queued chunks itself (the GIL released) while none has: as many threads as cores, none waiting for a core while
another runs Python. Each environment goes through the same calls in the same order. With ``threads=1`` the step runs them
in turn on the caller's thread alone (one core).
"""
from __future__ import annotations

import concurrent.futures
import os
from typing import Any, Optional, Sequence

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, iterate

from .. import _checks
from ..simulation import Simulation
from ._common import check_action
from .carry import DualCarryEnv
from .reach import ReachEnv

__all__ = ["CoopsimVectorEnv", "make_carry_vec", "make_reach_vec"]


def _per_env(kwargs: dict, n: int, per_env_keys: Sequence[str]) -> list:
    """The keywords of each of n environments: a key of `per_env_keys` given as a list or tuple (or array)
    of n values gives each its own; any other value goes to all."""
    out = [dict() for _ in range(n)]
    for k, v in kwargs.items():
        if k in per_env_keys and isinstance(v, (list, tuple, np.ndarray)):
            if len(v) != n:
                raise ValueError(f"{k} must be one value or one per environment ({n}), got {len(v)} values")
            for i in range(n):
                out[i][k] = v[i].item() if isinstance(v[i], np.generic) else v[i]
        else:
            for i in range(n):
                out[i][k] = v
    return out


class CoopsimVectorEnv(VectorEnv):
    """N environments of `env_class` (a coopsim environment: ReachEnv, DualCarryEnv) stepped together; see the
    module's documentation. num_envs >= 1; threads: the engine's pool (0: every core); autoreset_mode:
    NEXT_STEP or SAME_STEP; per_env_keys: the keywords that may be given one per environment."""

    def __init__(self, env_class, num_envs: int, *, threads: int = 0,
                 autoreset_mode=AutoresetMode.NEXT_STEP, per_env_keys: Sequence[str] = (), **kwargs):
        num_envs = _checks.integer(num_envs, "num_envs", 1, 1 << 20)
        threads = _checks.integer(threads, "threads", 0, 4096)
        try:
            mode = autoreset_mode if isinstance(autoreset_mode, AutoresetMode) else AutoresetMode(autoreset_mode)
        except ValueError:
            mode = None
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(f"autoreset_mode must be AutoresetMode.NEXT_STEP or SAME_STEP, got {autoreset_mode!r}")
        kwargs.pop("max_episode_steps", None)     # the environments end their episodes themselves
        self.num_envs = int(num_envs)
        self.threads = int(threads)
        self.autoreset_mode = mode
        self.envs = [env_class(**kw) for kw in _per_env(kwargs, self.num_envs, per_env_keys)]
        first = self.envs[0]
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = dict(first.metadata, autoreset_mode=mode)
        self.render_mode = first.render_mode
        self._env_obs: list = [None] * self.num_envs
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._executor: Optional[concurrent.futures.ThreadPoolExecutor] = None
        self._advance_pool = None

    # ---- Gymnasium ----

    def reset(self, *, seed=None, options: Optional[dict] = None):
        n = self.num_envs
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed must be None, an int or one per environment ({n}), got {len(seeds)} seeds")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(n, dtype=bool)
        else:
            mask = np.asarray(mask)
            if mask.shape != (n,) or mask.dtype != np.bool_:
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},), got {mask!r}")
        infos: dict = {}
        indices = [i for i in range(n) if mask[i]]

        def one(i):                  # each environment's reset (its grasp in the engine, the GIL released)
            return self.envs[i].reset(seed=seeds[i], options=options or None)
        parallel = self.threads != 1 and len(indices) > 1
        for i, (obs, info) in zip(indices, list(self._pool().map(one, indices) if parallel else map(one, indices))):
            self._env_obs[i] = obs
            self._autoreset[i] = False
            infos = self._add_info(infos, info, i)
        return self._batched(), infos

    def step(self, actions):
        n = self.num_envs
        resetting = self._autoreset.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP \
            else np.zeros(n, dtype=bool)
        space = self.action_space
        checked = (type(actions) is np.ndarray and actions.dtype == np.float64 and actions.shape == space.shape
                   and bool(((actions >= space.low) & (actions <= space.high)).all()))
        if checked:                  # the common case: all in their space, checked in one pass; rows of a copy
            acts = list(actions.copy())
        else:
            acts = list(iterate(space, actions)) if not isinstance(actions, (list, tuple)) else list(actions)
            if len(acts) != n:
                raise ValueError(f"actions must hold one action per environment ({n}), got {len(acts)}")
            for i in range(n):       # every action checked before any is applied
                if not resetting[i]:
                    check_action(acts[i], self.single_action_space, f"actions[{i}]")
        rewards = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        results: list = [None] * n
        errors: dict = {}
        rows: dict = {}              # each environment's readout after its advance (a class that reads at once)
        readout = getattr(type(self.envs[0]), "_readout_args", None)   # pair_readout's (a, b, body), or None

        parallel = self.threads != 1 and n > 1
        ended: list = []             # SAME_STEP: the environments whose episode ended this step

        def apply(part):             # Python: each environment's commands (holds the GIL)
            t_next = {}
            for i in part:
                if not resetting[i]:
                    t_next[i] = self.envs[i]._apply(acts[i], checked)
            return t_next

        def engine(part, t_next):    # the engine: the part's simulations in one call per end time, then
            for t in sorted(set(t_next.values())):     # their readouts in one more (the GIL released)
                group = [i for i in t_next if t_next[i] == t]
                got = Simulation.advance_all([self.envs[i].sim for i in group], t, self.threads)
                errors.update(zip(group, got))
            live = [i for i in part if not resetting[i]]
            if live and readout is not None:
                rows.update(zip(live, Simulation.pair_readout([self.envs[i].sim for i in live], *readout)))

        def outcome(part):           # Python: each environment's observation, reward and checks
            for i in part:
                if resetting[i]:
                    continue
                got = self.envs[i]._outcome(errors[i], rows[i]) if readout else self.envs[i]._outcome(errors[i])
                self._env_obs[i], rewards[i], terminated[i], truncated[i], results[i] = got
                if self.autoreset_mode == AutoresetMode.SAME_STEP and (terminated[i] or truncated[i]):
                    ended.append(i)

        def reset(indices):          # each environment's reset (its grasp in the engine, the GIL released)
            def one(i):
                return self.envs[i].reset()
            done = self._pool().map(one, indices) if parallel and len(indices) > 1 else map(one, indices)
            for i, got in zip(indices, list(done)):
                if resetting[i]:
                    results[i] = got[1]
                    self._env_obs[i] = got[0]
                else:            # SAME_STEP: the final observation and info kept in this step's info
                    results[i] = ({"final_obs": self._env_obs[i], "final_info": results[i]}, got[1])
                    self._env_obs[i] = got[0]

        # the resets first, side by side on the pool when there is one (episodes of equal length end together)
        reset([i for i in range(n) if resetting[i]])
        if not parallel:
            whole = range(n)
            engine(whole, apply(whole))
            outcome(whole)
        else:
            # chunks in a pipeline: the caller's thread applies each chunk's actions and hands the chunk to the
            # engine's pool (its threads advance and read it without ever taking the GIL); then, until every
            # chunk's outcome is taken, it takes the outcome of a chunk that is done, or else runs the next queued
            # chunk itself (the GIL released), or else waits for the first one not done. The pool has a thread
            # less than the workers: with the caller, as many threads as cores, none waiting for a core while
            # another runs Python. Each environment goes through the same calls in the same order as on one thread
            pool = self._engine_pool()
            count = min(n, 4 * self._workers())
            chunks = [range(k * n // count, (k + 1) * n // count) for k in range(count)]
            jobs = []
            for chunk in chunks:
                t_next = apply(chunk)
                live = [i for i in chunk if i in t_next]
                jobs.append((live, pool.submit([self.envs[i].sim for i in live], [t_next[i] for i in live],
                                               readout) if live else None))
            pending = list(range(count))
            while pending:
                ready = [k for k in pending if jobs[k][1] is None or jobs[k][1].done()]
                if not ready:
                    if pool.run_one():
                        continue
                    ready = pending[:1]             # (its result() waits, the GIL released)
                for k in ready:
                    live, job = jobs[k]
                    if job is not None:
                        got, read = job.result()
                        errors.update(zip(live, got))
                        if readout is not None:
                            rows.update(zip(live, read))
                    outcome(chunks[k])
                    pending.remove(k)
        reset(ended)
        entries = []                 # each environment's infos in the order Gymnasium's _add_info takes them
        for i in range(n):
            entries.extend((i, x) for x in (results[i] if isinstance(results[i], tuple) else (results[i],)))
        self._autoreset = terminated | truncated
        return self._batched(), rewards, terminated, truncated, self._gathered(entries)

    def _pool(self):
        """The Python worker threads (`threads` of them, 0: every core, at least 2): they run the resets of one
        step, or of reset(), side by side (a step's chunks go to the engine's pool, :meth:`_engine_pool`)."""
        if self._executor is None:
            self._executor = concurrent.futures.ThreadPoolExecutor(self._workers(),
                                                                   thread_name_prefix="coopsim-vector")
        return self._executor

    def _engine_pool(self):
        """The engine's threads that advance and read a step's chunks in the pipeline: one less than the workers
        (the caller's thread runs chunks too, :meth:`coopsim.AdvancePool.run_one`)."""
        if self._advance_pool is None:
            self._advance_pool = Simulation.advance_pool(self._workers() - 1)
        return self._advance_pool

    def _workers(self) -> int:
        return max(2, self.threads or (os.cpu_count() or 2))

    def _gathered(self, entries) -> dict:
        """The vector's info from (environment index, info dict) pairs: what Gymnasium's ``_add_info`` gives
        when called on each pair in turn (each key's (N, ...) array, its dtype from the first value, and its
        ``_key`` mask; dicts within, recursively; ``final_obs`` an object array), built key by key in one pass
        over the environments instead of one call per environment."""
        n, out = self.num_envs, {}
        keys: dict = {}
        for _, info in entries:
            keys.update(dict.fromkeys(info))
        for key in keys:
            items = [(i, info[key]) for i, info in entries if key in info]
            first = items[0][1]
            if key != "final_obs" and isinstance(first, dict):
                array = self._gathered(items)
            else:
                kind = type(first)
                if key != "final_obs" and (kind in (int, float, bool) or issubclass(kind, np.number)):
                    array = np.zeros(n, dtype=kind)
                elif key != "final_obs" and isinstance(first, np.ndarray):
                    array = np.zeros((n, *first.shape), dtype=first.dtype)
                else:
                    array = np.full(n, None, dtype=object)
                for i, value in items:
                    array[i] = value
            mask = np.zeros(n, dtype=np.bool_)
            mask[[i for i, _ in items]] = True
            out[key], out["_" + key] = array, mask
        return out

    def _batched(self):
        """The environments' observations batched, new arrays (each key's (N, ...) for a Dict space): one
        np.stack per key, what gymnasium's concatenate and a copy give."""
        obs = self._env_obs
        if isinstance(obs[0], dict):
            flats = [getattr(env, "_obs_flat", None) for env in self.envs]
            layout = getattr(self.envs[0], "_layout", None)
            if layout is not None and all(f is not None and o[layout[0][0]].base is f for o, f in zip(obs, flats)):
                # each observation's parts are views of one flat array (the carry's): one stack, views of it
                whole, n = np.stack(flats), self.num_envs
                return {name: whole[:, k:k + size].reshape(n, *shape) for name, shape, k, size in layout}
            return {k: np.stack([o[k] for o in obs]) for k in self.single_observation_space.spaces}
        return np.stack(obs)

    def render(self):
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs: Any) -> None:
        if self._executor is not None:
            self._executor.shutdown()
            self._executor = None
        self._advance_pool = None      # its engine threads stop when it is collected
        for env in self.envs:
            env.close()

    @property
    def sims(self) -> list:
        """The environments' simulations now (:class:`coopsim.Simulation`)."""
        return [env.sim for env in self.envs]


def make_reach_vec(num_envs: int = 1, **kwargs) -> CoopsimVectorEnv:
    """``coopsim/Reach-v0``'s vector entry point: a :class:`CoopsimVectorEnv` of ReachEnv (per environment:
    action, control_rate, time_limit, tolerance, max_speed, torque_penalty, max_offset may be sequences)."""
    return CoopsimVectorEnv(ReachEnv, num_envs, per_env_keys=("time_limit", "tolerance", "max_speed",
                                                                "torque_penalty", "max_offset"), **kwargs)


def make_carry_vec(num_envs: int = 1, **kwargs) -> CoopsimVectorEnv:
    """``coopsim/DualCarry-v0``'s vector entry point: a :class:`CoopsimVectorEnv` of DualCarryEnv (per
    environment: bar_mass may be a sequence, kg)."""
    return CoopsimVectorEnv(DualCarryEnv, num_envs, per_env_keys=("bar_mass",), **kwargs)
