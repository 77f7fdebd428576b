"""Learning to cooperate: a linear policy trained by augmented random search (ARS v2) on NumPy alone.

Two problems, each a linear policy on (normalised) observations trained by ARS v2 (Mania, Guy and Recht 2018,
"Simple random search provides a competitive approach to reinforcement learning"): states normalised by
the running mean and standard deviation of every state the training has seen, the policy perturbed along
`directions` random directions both ways, the `top` best directions kept, the step scaled by the standard
deviation of their returns. The 2 x directions perturbed episodes and the `eval_episodes` episodes of the
unperturbed policy (the learning curve's point) run side by side in one vector environment
(``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``: the simulations advanced in one engine
call per step on `threads` threads, the GIL released).

- ``reach``: ``coopsim/Reach-v0`` with TCP set-point actions; action = max_offset * clip(M z + b, -1, 1),
  z the normalised target less the TCP (3,), the last three of the observation. From the policy that does
  nothing (M = 0) to one that reaches.
- ``carry``: ``coopsim/DualCarry-v0`` under a push (``disturbance="push"``: 2 N across the bar for 0.2 s in
  the middle of the carry), its squeeze commanded: squeeze = 0.5 N + 0.05 N x (M z + b) within the action
  space, z the normalised swing s - 0.5 N of the measured squeeze s (N, along the bar: the one part of the
  internal force the squeeze command acts on, the same whatever the bar's yaw), the offset and load share
  the scripted carry's. The squeeze is held at 0.5 N because DualCarry-v0 commands compression only (from
  0 N): about a held squeeze the command can both raise and lower it. ARS maximises the environment's
  reward less (swing / 0.1 N)^2 per step over the push and the second after it (the environment's own
  internal-force factor, exp(-|f| / 5 N), weighs the push's 0.2 N at 4 % of a step: too little against the
  grips). From M = 0 (the squeeze held at 0.5 N whatever happens) it learns to lower the command while the
  bar is squeezed and raise it while it is pulled: the swing's peak and its integral over the push, printed
  before and after on the same evaluation starts, fall.

Each iteration's starts are drawn from the seed and shared by all its directions (common random numbers:
`episodes` per direction and way); the normaliser starts from the states of the initial policy's episodes.

Writes into --out: learn_reach.png and learn_carry.png (the mean return of the unperturbed policy over the
evaluation episodes per iteration, its spread: the band from the lowest to the highest, and +- one standard
deviation), learn_to_cooperate.json (the curves). Prints the returns before and after. The same --seed
gives the same curves bit for bit. --quick runs a few iterations of each (about a minute).

    python examples/learn_to_cooperate.py --out out            # both, the default budget (a few minutes)
    python examples/learn_to_cooperate.py --task reach --iterations 30 --directions 8 --seed 1
"""
from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional

import numpy as np

#: the squeeze (N, compression) the carry's policy holds and commands about: DualCarry-v0's squeeze is
#: compression only (its action's range starts at 0 N), so a command that must both raise and lower the
#: squeeze works about a held one
CARRY_SQUEEZE = 0.5
#: the carry's commands with M = 0: no offset, the held squeeze, half the load each (DualCarry-v0's
#: scripted_action but for the squeeze)
CARRY_BASE = np.array([0.0, 0.0, 0.0, CARRY_SQUEEZE, 0.5])
#: the carry policy's output scale: N of squeeze command per unit of M z + b
SQUEEZE_ACTION_SCALE = 0.05
#: the carry's objective: the environment's reward per step less SQUEEZE_PENALTY x (swing / SQUEEZE_PENALTY_SCALE)^2,
#: the swing the squeeze less the one held (a swing of 0.1 N for one step costs a whole step's reward, whose
#: largest value is 1; the push's swings, near 0.2 N, four; the carry's swings outside the push, under 0.05 N,
#: a quarter at most)
SQUEEZE_PENALTY = 1.0
SQUEEZE_PENALTY_SCALE = 0.1
#: control periods (50 Hz) from the push's start over which the swing is penalised and measured: the push's
#: 0.2 s and the second after it
PUSH_WINDOW_STEPS = 60


# ---- the two problems ----

@dataclass
class Problem:
    """What ARS needs of an environment: its id and keywords, the features (n, f) of a batch of observations,
    and the action (n, a) of a batch of policy outputs u (n, a)."""

    name: str
    env_id: str
    env_kwargs: dict
    n_features: int
    n_actions: int
    features: Callable[[object], np.ndarray]
    action: Callable[[np.ndarray], np.ndarray]
    #: ARS's step size and exploration noise (in the units of M)
    step: float
    noise: float
    defaults: dict = field(default_factory=dict)
    #: a quantity (n,) of a batch of observations whose peak and integral over each episode are recorded, its name
    measure: Optional[Callable[[object], np.ndarray]] = None
    measure_name: str = ""
    #: what ARS maximises per step, (obs, rewards (n,), window (n,) bool) -> (n,): None for the environment's reward
    objective: Optional[Callable[[object, np.ndarray, np.ndarray], np.ndarray]] = None
    #: the steps from the start of a push (info["push"] not zero) over which the measure is taken and `window`
    #: is True (0: every step of the episode)
    window_steps: int = 0
    #: s: the control period (the measure's integral is its sum times this)
    period: float = 0.02


def reach_problem() -> Problem:
    max_offset = 0.05

    def features(obs):          # the target less the TCP (3,) m
        return np.asarray(obs, float)[:, -3:]

    def action(u):
        return max_offset * np.clip(u, -1.0, 1.0)

    return Problem("reach", "coopsim/Reach-v0", dict(action="setpoint", max_offset=max_offset), 3, 3,
                   features, action, step=0.5, noise=0.5,
                   defaults=dict(iterations=12, directions=8, top=4, episodes=2, eval_episodes=8))


def carry_problem(low: Optional[np.ndarray] = None, high: Optional[np.ndarray] = None,
                  squeeze_penalty: Optional[float] = None) -> Problem:
    """The pushed dual carry, its squeeze commanded about the held CARRY_SQUEEZE: feature the swing s - 0.5 N (1,),
    action squeeze = 0.5 N + SQUEEZE_ACTION_SCALE x (M z + b) within the action space (low, high: its bounds,
    DualCarry-v0's), the offset and load share the scripted carry's; ARS maximises the environment's reward
    less squeeze_penalty (default SQUEEZE_PENALTY) x |s - 0.5 N| per step; the measure is |s - 0.5 N| (N)."""
    env_space = gym_space("coopsim/DualCarry-v0")
    low = env_space.low if low is None else np.asarray(low, float)
    high = env_space.high if high is None else np.asarray(high, float)
    penalty = SQUEEZE_PENALTY if squeeze_penalty is None else float(squeeze_penalty)

    def swing(obs):              # (n,) N: the squeeze less the one held, signed
        return np.asarray(obs["squeeze"], float).reshape(-1) - CARRY_SQUEEZE

    def features(obs):           # the swing (n, 1) N: along the bar, whatever its yaw
        return swing(obs)[:, None]

    def action(u):               # the squeeze's command; the offset and the load share the scripted carry's
        a = np.repeat(CARRY_BASE[None], len(u), axis=0)
        a[:, 3] += SQUEEZE_ACTION_SCALE * u[:, 0]
        return np.clip(a, low, high)

    def measure(obs):            # N: the swing's size
        return np.abs(swing(obs))

    def objective(obs, rewards, window):  # the environment's reward less the push's swing's penalty
        return rewards - penalty * window * (swing(obs) / SQUEEZE_PENALTY_SCALE) ** 2

    return Problem("carry", "coopsim/DualCarry-v0", dict(disturbance="push"), 1, 1, features, action,
                   step=0.1, noise=0.2, defaults=dict(iterations=8, directions=4, top=2, episodes=1, eval_episodes=4),
                   measure=measure, measure_name="squeeze swing |s - 0.5 N| (N) over the push and the second after it",
                   objective=objective,
                   period=0.02, window_steps=PUSH_WINDOW_STEPS)


def gym_space(env_id: str):
    """The action space of one environment of env_id (its bounds as the environment declares them now)."""
    import gymnasium as gym

    import coopsim.envs  # noqa: F401  (registers the environments)

    env = gym.make(env_id)
    try:
        return env.action_space
    finally:
        env.close()


PROBLEMS = {"reach": reach_problem, "carry": carry_problem}


# ---- ARS v2 ----

class Normaliser:
    """The running mean and variance of the states seen (Welford's update, batched), as ARS v2 keeps them."""

    def __init__(self, n: int):
        self.count = 0
        self.mean = np.zeros(n)
        self.m2 = np.zeros(n)

    def update(self, x: np.ndarray):
        x = np.asarray(x, float).reshape(-1, self.mean.size)
        if len(x) == 0:
            return
        n_b = len(x)
        mean_b = x.mean(axis=0)
        m2_b = ((x - mean_b) ** 2).sum(axis=0)
        n = self.count + n_b
        delta = mean_b - self.mean
        self.mean = self.mean + delta * n_b / n
        self.m2 = self.m2 + m2_b + delta ** 2 * self.count * n_b / n
        self.count = n

    @property
    def std(self) -> np.ndarray:
        if self.count < 2:
            return np.ones_like(self.mean)
        sd = np.sqrt(self.m2 / (self.count - 1))
        return np.where(sd < 1e-8, 1.0, sd)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return (x - self.mean) / self.std


def rollouts(venv, problem: Problem, weights: np.ndarray, norm: Normaliser, seeds: List[int]) -> dict:
    """One episode per environment of `venv` from reset(seed=seeds), environment i acting with the linear policy
    weights[i] ((a, f + 1): M and the bias) on the states normalised by `norm` (frozen during the episodes).
    Returns a dict: 'returns' (n,) of problem.objective (the environment's reward without one), 'env_returns'
    (n,) of the environment's reward, 'lengths' (n,), 'seen' the features seen (m, f), and of problem.measure
    (zeros without one) 'peak' (n,), its largest value over each episode, and 'integral' (n,), its sum over
    the episode's steps times problem.period (unit s)."""
    n = venv.num_envs
    obs, _ = venv.reset(seed=list(seeds))
    returns, env_returns = np.zeros(n), np.zeros(n)
    lengths = np.zeros(n, dtype=int)
    active = np.ones(n, dtype=bool)
    peak, integral = np.zeros(n), np.zeros(n)
    since = np.full(n, -1)            # steps since the push started (-1: not yet)
    seen = []
    while active.any():
        x = problem.features(obs)
        seen.append(x[active])
        z = np.concatenate([norm(x), np.ones((n, 1))], axis=1)
        u = np.einsum("naf,nf->na", weights, z)
        obs, rewards, terminated, truncated, infos = venv.step(problem.action(u))
        if problem.window_steps > 0:
            pushed = np.any(np.asarray(infos.get("push", np.zeros((n, 3))), float) != 0.0, axis=1)
            since = np.where(since >= 0, since + 1, np.where(pushed, 0, -1))
            window = (since >= 0) & (since < problem.window_steps)
        else:
            window = np.ones(n, dtype=bool)
        objective = rewards if problem.objective is None else problem.objective(obs, rewards, window)
        returns[active] += objective[active]
        env_returns[active] += rewards[active]
        if problem.measure is not None:
            m = np.where(window, problem.measure(obs), 0.0)
            peak[active] = np.maximum(peak[active], m[active])
            integral[active] += problem.period * m[active]
        lengths[active] += 1
        active &= ~(terminated | truncated)     # an ended environment resets at its next step: not counted
    return dict(returns=returns, env_returns=env_returns, lengths=lengths, seen=np.concatenate(seen), peak=peak,
                integral=integral)


def ars_update(M: np.ndarray, deltas: np.ndarray, r_plus: np.ndarray, r_minus: np.ndarray, top: int,
               step: float) -> np.ndarray:
    """ARS v2's step: M (a, f + 1) plus step / (top x sigma) x sum over the `top` directions whose better way
    returned most of (r_plus - r_minus) x delta; deltas (d, a, f + 1), r_plus and r_minus (d,) the returns of
    M + noise x delta and M - noise x delta, sigma the standard deviation of the 2 x top returns kept (1 when
    they are all equal). Ties keep the earlier direction."""
    best = np.argsort(-np.maximum(r_plus, r_minus), kind="stable")[:top]
    sigma = np.std(np.concatenate([r_plus[best], r_minus[best]]))
    sigma = sigma if sigma > 1e-12 else 1.0
    return M + step / (top * sigma) * np.einsum("k,kaf->af", r_plus[best] - r_minus[best], deltas[best])


def ars(problem: Problem, *, iterations: int, directions: int, top: int, eval_episodes: int, episodes: int = 1,
        seed: int = 0, threads: int = 2, step: Optional[float] = None, noise: Optional[float] = None,
        verbose: bool = True) -> dict:
    """Trains problem's linear policy by ARS v2 for `iterations` iterations of `directions` directions (each
    both ways, each way's return the mean of `episodes` episodes from starts drawn for the iteration and
    shared by all directions), keeping the `top` best, the curve's point the mean return of `eval_episodes`
    episodes of the unperturbed policy on fixed seeds, ARS maximising problem.objective's return (the
    environment's without one). Returns the curve: 'mean', 'std', 'min', 'max' of the evaluation's returns
    (iterations + 1,) (the last after the last update); per evaluation and episode 'returns' (the objective's),
    'env_returns' (the environment's reward), 'peak' and 'integral' of problem.measure (rollouts'); the
    weights (a, f + 1) and the normaliser, wall times (s)."""
    import gymnasium as gym

    import coopsim.envs  # noqa: F401  (registers the environments)

    if not (1 <= top <= directions):
        raise ValueError(f"top must be between 1 and directions ({directions}), got {top}")
    step = problem.step if step is None else float(step)
    noise = problem.noise if noise is None else float(noise)
    rng = np.random.default_rng(seed)
    n_train = 2 * directions * episodes
    n = n_train + eval_episodes
    venv = gym.make_vec(problem.env_id, num_envs=n, vectorization_mode="vector_entry_point", threads=threads,
                        **problem.env_kwargs)
    shape = (problem.n_actions, problem.n_features + 1)
    M = np.zeros(shape)
    norm = Normaliser(problem.n_features)
    eval_seeds = [1_000_000 + k for k in range(eval_episodes)]
    curve: Dict[str, list] = dict(mean=[], std=[], min=[], max=[], returns=[], env_returns=[], peak=[], integral=[],
                                  wall=[])

    def record(r):
        curve["returns"].append(r.tolist())
        for k, f in (("mean", np.mean), ("std", np.std), ("min", np.min), ("max", np.max)):
            curve[k].append(float(f(r)))

    t_start = time.perf_counter()
    try:
        # the normaliser starts from the states of the initial policy's episodes (on the evaluation's starts and
        # the first iteration's), so that the first update and the next ones see states on one scale
        warm = rollouts(venv, problem, np.repeat(M[None], n, axis=0), norm,
                        [int(s) for s in np.random.default_rng([seed, 1]).integers(0, 2 ** 31 - 1, size=n_train)]
                        + eval_seeds)
        norm.update(warm["seen"])
        for it in range(iterations + 1):
            t0 = time.perf_counter()
            deltas = rng.standard_normal((directions,) + shape)
            starts = rng.integers(0, 2 ** 31 - 1, size=episodes).tolist()
            # environment (way, direction, episode): + then -, each direction on the iteration's starts
            perturbed = np.concatenate([M + noise * deltas, M - noise * deltas])
            weights = np.concatenate([np.repeat(perturbed, episodes, axis=0), np.repeat(M[None], eval_episodes, 0)])
            seeds = starts * (2 * directions) + eval_seeds
            if it == iterations:          # the last point: the final policy evaluated alone
                weights, seeds = weights[n_train:], eval_seeds
                venv.close()
                venv = gym.make_vec(problem.env_id, num_envs=eval_episodes, vectorization_mode="vector_entry_point",
                                    threads=threads, **problem.env_kwargs)
            out = rollouts(venv, problem, weights, norm, seeds)
            returns, seen = out["returns"], out["seen"]
            record(returns[-eval_episodes:])
            for k in ("env_returns", "peak", "integral"):
                curve[k].append(out[k][-eval_episodes:].tolist())
            if it < iterations:
                r = returns[:n_train].reshape(2, directions, episodes).mean(axis=2)
                M = ars_update(M, deltas, r[0], r[1], top, step)
                norm.update(seen)         # every state of the iteration's episodes
            curve["wall"].append(time.perf_counter() - t0)
            if verbose:
                print(f"  {problem.name} iteration {it:3d}: mean return {curve['mean'][-1]:9.3f} "
                      f"(min {curve['min'][-1]:9.3f}, max {curve['max'][-1]:9.3f}), {curve['wall'][-1]:.1f} s",
                      flush=True)
    finally:
        venv.close()
    curve.update(weights=M.tolist(), normaliser=dict(mean=norm.mean.tolist(), std=norm.std.tolist()),
                 total_wall=time.perf_counter() - t_start,
                 settings=dict(iterations=iterations, directions=directions, top=top, episodes=episodes,
                               eval_episodes=eval_episodes,
                               seed=seed, threads=threads, step=step, noise=noise, env_kwargs=problem.env_kwargs))
    return curve


def plot(curve: dict, title: str, path: str):
    """The learning curve: the evaluation's mean return per iteration, +- one standard deviation, and the band
    from its lowest to its highest return."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    it = np.arange(len(curve["mean"]))
    mean, std = np.array(curve["mean"]), np.array(curve["std"])
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=100)
    ax.fill_between(it, curve["min"], curve["max"], color="tab:blue", alpha=0.15, label="lowest to highest")
    ax.fill_between(it, mean - std, mean + std, color="tab:blue", alpha=0.3, label="mean +- 1 std")
    ax.plot(it, mean, "o-", color="tab:blue", label=f"mean of {len(curve['returns'][0])} evaluation episodes")
    ax.set_xlabel("iteration (the last point: after the last update)")
    ax.set_ylabel("return")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", choices=["reach", "carry", "both"], default="both")
    ap.add_argument("--iterations", type=int, default=None, help="ARS iterations (default: the task's)")
    ap.add_argument("--directions", type=int, default=None, help="random directions per iteration")
    ap.add_argument("--top", type=int, default=None, help="the best directions kept (default: half)")
    ap.add_argument("--episodes", type=int, default=None, help="episodes per direction and way (shared starts)")
    ap.add_argument("--eval-episodes", type=int, default=None, help="episodes of the curve's points")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2, help="the engine's threads (0: every core)")
    ap.add_argument("--quick", action="store_true", help="a few iterations of each, to see it run")
    ap.add_argument("--out", default="out", help="folder for the figures and the curves (JSON)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    tasks = ["reach", "carry"] if args.task == "both" else [args.task]
    quick = dict(reach=dict(iterations=3, directions=8, top=4, episodes=2, eval_episodes=8),
                 carry=dict(iterations=1, directions=2, top=1, episodes=1, eval_episodes=2))
    results = {}
    for name in tasks:
        problem = PROBLEMS[name]()
        budget = dict(quick[name] if args.quick else problem.defaults)
        for k in ("iterations", "directions", "top", "episodes", "eval_episodes"):
            if getattr(args, k) is not None:
                budget[k] = getattr(args, k)
        if args.directions is not None and args.top is None:
            budget["top"] = max(1, budget["directions"] // 2)
        print(f"{name}: {problem.env_id} {problem.env_kwargs}, ARS v2, {budget}, seed {args.seed}", flush=True)
        curve = ars(problem, seed=args.seed, threads=args.threads, **budget)
        results[name] = curve
        title = (f"{problem.env_id}{' under a push' if name == 'carry' else ''}: ARS v2, {budget['directions']} "
                 f"directions (top {budget['top']}), seed {args.seed}")
        path = os.path.join(args.out, f"learn_{name}.png")
        plot(curve, title, path)
        print(f"{name}: mean return before {curve['mean'][0]:.3f} (min {curve['min'][0]:.3f}), after "
              f"{curve['mean'][-1]:.3f} (min {curve['min'][-1]:.3f}) over {budget['eval_episodes']} episodes; "
              f"{curve['total_wall']:.1f} s; {path}", flush=True)
        if problem.measure is not None:
            p0, p1 = np.mean(curve["peak"][0]), np.mean(curve["peak"][-1])
            i0, i1 = np.mean(curve["integral"][0]), np.mean(curve["integral"][-1])
            e0, e1 = np.mean(curve["env_returns"][0]), np.mean(curve["env_returns"][-1])
            print(f"{name}: {problem.measure_name} over the evaluation episodes (mean): peak before {p0:.4f}, after "
                  f"{p1:.4f} ({100 * (p1 / p0 - 1):+.0f} %); integral (N s) before {i0:.4f}, after {i1:.4f} "
                  f"({100 * (i1 / i0 - 1):+.0f} %); the environment's return before {e0:.3f}, after {e1:.3f}",
                  flush=True)
    with open(os.path.join(args.out, "learn_to_cooperate.json"), "w") as f:
        json.dump(results, f, indent=1)
    return results


if __name__ == "__main__":
    main()
