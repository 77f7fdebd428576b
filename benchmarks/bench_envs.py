"""Environment steps per second of ``coopsim/DualCarry-v0`` under random actions: one environment, and the vector
environment (``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``) on 1 and 2 threads.

Each step is one control period at 50 Hz (the default): 100 engine steps of 0.2 ms, the controllers and the world
(Bullet: the bar, the stands, the clamps' welds) every 5 engine steps, the observation, the reward and the carry's
checks. Random actions (``action_space.sample()``, seeded) run whole episodes of 180 steps in the bounded action
space (the squeeze 0 to 3 N, offsets of +-1 cm reached over 0.2 s), most ending at the place with the bar a few
mm off (a failure of the place, not of the carry's rules); an episode's reset plans the carry and simulates its
grasp (1 s), as for scripted actions. Two figures per row:

- steps/s: environment steps over the wall time of the whole loop, the resets included (the vector
  environment resets inside its step, Gymnasium's next-step autoreset);
- steps/s without resets (one environment only): the same steps over the time spent inside ``step()``.

The same rows with the scripted carry's actions (``scripted_action``) show the step with the plan's commands.
The targets are read on the random rows. The default 2,880 steps are 16 episodes: one environment runs 16 in a
row, the vector environment of 8 runs 360 steps each (two episodes each, the second's reset inside a step).
Each run also prints the mean wall time of a reset (ms) of the one environment.

"GIL released" is the share of the row's wall time the caller's thread spent in the engine's calls with the GIL
released (``coopsim.gil_released_seconds``; on 1 thread: the engine's part of a step, the rest is Python holding the
GIL, which bounds what a second thread can add; on 2 threads the engine runs on the worker threads, not counted).
"cores" is the process's CPU time over the wall time of the row: the cores the figure had (on a shared machine a
ratio on 2 threads means something only when cores came near 2); "per CPU s" is steps/s over cores, the steps
per second of CPU time (what one core would give if it were the row's alone, contention aside). Each figure is the best of ``--repeats``.

Beside them: robosuite's two-arm tasks, 20-100 environment steps/s with no batched step (robosuite's issue 256),
and the targets of the project's issue 36: 2,000 steps/s on one core, the vector environment at least 1.8x on 2
threads against 1. Printed, never asserted.

    python benchmarks/bench_envs.py [--steps 2880] [--envs 8] [--repeats 2] [--quick]
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")     # numpy's BLAS threads would take a core from the run

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402
import coopsim.envs  # noqa: E402,F401  (registers the environments)
from coopsim.envs import DualCarryEnv  # noqa: E402

ROBOSUITE = (20, 100)           # steps/s, robosuite's two-arm tasks
TARGET_ONE_CORE = 2000.0        # steps/s, one environment on one core
TARGET_VECTOR_2 = 1.8           # the vector environment on 2 threads against 1


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def single(steps: int, seed: int = 0, scripted: bool = False) -> dict:
    """One DualCarryEnv, `steps` random actions (or the scripted carry's), resets when an episode ends."""
    env = DualCarryEnv()
    env.action_space.seed(seed)
    env.reset(seed=seed)
    episodes, in_step, in_reset = 1, 0.0, 0.0
    c0, g0, t0 = _cpu(), cs.gil_released_seconds(), time.perf_counter()
    for _ in range(steps):
        a = env.scripted_action if scripted else env.action_space.sample()
        s = time.perf_counter()
        _, _, term, trunc, _ = env.step(a)
        in_step += time.perf_counter() - s
        if term or trunc:
            s = time.perf_counter()
            env.reset()
            in_reset += time.perf_counter() - s
            episodes += 1
    wall = time.perf_counter() - t0
    gil = (cs.gil_released_seconds() - g0) / wall
    env.close()
    return dict(rate=steps / wall, rate_steps=steps / in_step, cores=(_cpu() - c0) / wall, episodes=episodes,
                reset_ms=1e3 * in_reset / max(1, episodes - 1), released=gil)


def vector(n_envs: int, threads: int, steps: int, seed: int = 0, scripted: bool = False) -> dict:
    """The vector environment of `n_envs` DualCarry environments on `threads` threads, `steps` vector steps of
    random actions (or the scripted carry's)."""
    v = gym.make_vec("coopsim/DualCarry-v0", num_envs=n_envs, vectorization_mode="vector_entry_point",
                     threads=threads)
    v.action_space.seed(seed)
    v.reset(seed=seed)
    episodes = n_envs
    c0, g0, t0 = _cpu(), cs.gil_released_seconds(), time.perf_counter()
    scripted_actions = np.tile(v.unwrapped.envs[0].scripted_action, (n_envs, 1))
    for _ in range(steps):
        _, _, term, trunc, _ = v.step(scripted_actions if scripted else v.action_space.sample())
        episodes += int(np.sum(term | trunc))
    wall = time.perf_counter() - t0
    gil = (cs.gil_released_seconds() - g0) / wall
    v.close()
    return dict(rate=steps * n_envs / wall, cores=(_cpu() - c0) / wall, episodes=episodes, released=gil)


def best(fn, repeats: int) -> dict:
    runs = [fn() for _ in range(repeats)]
    return max(runs, key=lambda r: r["rate"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2880, help="environment steps per row (default 2880)")
    ap.add_argument("--envs", type=int, default=8, help="environments of the vector environment (default 8)")
    ap.add_argument("--repeats", type=int, default=2, help="repeats per row, the best kept (default 2)")
    ap.add_argument("--quick", action="store_true", help="400 steps, one repeat")
    args = ap.parse_args()
    steps, repeats = (400, 1) if args.quick else (args.steps, args.repeats)
    n = args.envs
    warnings.simplefilter("ignore")
    print(f"coopsim/DualCarry-v0, random and scripted actions, 50 Hz control (100 engine steps of 0.2 ms a "
          f"step, the world at 1 kHz); {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}; best of {repeats}")
    vsteps = max(1, steps // n)
    rows = {}
    for policy in ("random", "scripted"):
        sc = policy == "scripted"
        rows[policy] = (best(lambda: single(steps, scripted=sc), repeats),
                        best(lambda: vector(n, 1, vsteps, scripted=sc), repeats),
                        best(lambda: vector(n, 2, vsteps, scripted=sc), repeats))
    print()
    print(f"{'':52s} {'steps/s':>9s} {'cores':>6s} {'episodes':>9s} {'per CPU s':>10s} {'GIL released':>13s}")
    for policy, (one, v1, v2) in rows.items():
        print(f"{f'{policy} actions: one environment':52s} {one['rate']:9.0f} {one['cores']:6.2f} {one['episodes']:9d} "
              f"{one['rate'] / one['cores']:10.0f} {100 * one['released']:12.1f}%")
        print(f"{f'{policy} actions: one environment, time in step() only':52s} {one['rate_steps']:9.0f}")
        print(f"{f'{policy} actions: one environment, a reset (ms)':52s} {one['reset_ms']:9.1f}")
        for threads, v in ((1, v1), (2, v2)):
            label = f"{policy} actions: vector, {n} environments, {threads} thread{'s' if threads > 1 else ''}"
            gil = f"{100 * v['released']:12.1f}%" if threads == 1 else f"{'':13s}"
            per_cpu = v['rate'] / v['cores']
            print(f"{label:52s} {v['rate']:9.0f} {v['cores']:6.2f} {v['episodes']:9d} {per_cpu:10.0f} {gil}")
    print(f"{'robosuite two-arm tasks (their figures)':52s} {f'{ROBOSUITE[0]}-{ROBOSUITE[1]}':>9s}")
    one, v1, v2 = rows["random"]
    print()
    ratio = v2["rate"] / v1["rate"]
    met = lambda ok: "met" if ok else "not met"  # noqa: E731
    print(f"target one core >= {TARGET_ONE_CORE:.0f} steps/s: {one['rate']:.0f} with resets, "
          f"{one['rate_steps']:.0f} in step() ({met(one['rate'] >= TARGET_ONE_CORE)}, "
          f"{met(one['rate_steps'] >= TARGET_ONE_CORE)})")
    print(f"target vector 2 threads / 1 >= {TARGET_VECTOR_2}x: {ratio:.2f}x ({met(ratio >= TARGET_VECTOR_2)}; "
          f"cores {v2['cores']:.2f})")
    sv1, sv2 = rows["scripted"][1:]
    print(f"(scripted actions: vector 2 threads / 1 = {sv2['rate'] / sv1['rate']:.2f}x, cores {sv2['cores']:.2f})")
    print(f"load average at the end: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    per = lambda rate: f"{rate / ROBOSUITE[1]:.2f}x"  # noqa: E731
    print(f"against robosuite's {ROBOSUITE[1]} steps/s, random actions: one environment {per(one['rate'])}, vector "
          f"on 2 threads {per(v2['rate'])}; scripted: {per(rows['scripted'][0]['rate'])}, {per(sv2['rate'])}")

if __name__ == "__main__":
    main()
