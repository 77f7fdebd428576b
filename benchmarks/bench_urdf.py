"""Imported real robots: generated vs numeric forward dynamics beside Pinocchio's ABA.

The UR5 and the Panda arm (fingers locked) of the example-robot-data wheel,
loaded by coopsim.Robot.from_urdf and by Pinocchio from the same file. For
each: the cost of coopsim.codegen.compile (cold: sympy + g++, or cached),
then ns per forward-dynamics call from Python (coopsim numeric, coopsim
generated, pin.aba; each a single call with its Python overhead) and ns per
state of coopsim's batch forward dynamics (N states in one call, one
thread: the engine's own cost). The three are timed in turn within each
repeat and each figure is its fastest repeat (on a shared machine the
least disturbed one); ratios within this run. The results' agreement is
checked before timing.

    python benchmarks/bench_urdf.py [--calls 20000] [--repeats 5]
"""
from __future__ import annotations

import argparse
import importlib.metadata
import time

import numpy as np
import pinocchio as pin

import coopsim as cs
from coopsim import codegen


def example_robot_data(relative: str) -> str:
    for f in importlib.metadata.files("example-robot-data"):
        if str(f).endswith("robots/" + relative):
            return str(f.locate())
    raise FileNotFoundError(relative)


ROBOTS = {
    "ur5": (example_robot_data("ur_description/urdf/ur5_robot.urdf"), {}),
    "panda": (example_robot_data("panda_description/urdf/panda.urdf"),
              {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
}


def fastest_ns(fns, per, repeats):
    """ns per unit of each fn (called once per repeat, `per` units per call), timed in turn within
    each repeat; the fastest repeat of each."""
    best = [np.inf] * len(fns)
    for _ in range(repeats):
        for k, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            best[k] = min(best[k], (time.perf_counter() - t0) / per * 1e9)
    return best


def loop(fn, calls):
    def run():
        for _ in range(calls):
            fn()
    return run


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    print(f"{'robot':6} {'what':34} {'ns':>9}")
    for name, (path, locked) in ROBOTS.items():
        num = cs.Robot.from_urdf(path, locked=locked)
        t0 = time.perf_counter()
        gen = codegen.compile(num)
        t_compile = time.perf_counter() - t0
        info = codegen.info(gen)
        model = pin.buildModelFromUrdf(path)
        if locked:
            model = pin.buildReducedModel(model, [model.getJointId(j) for j in locked], pin.neutral(model))
        data = model.createData()
        rng = np.random.default_rng(0)
        n = num.dof
        lim = np.clip(num.q_limits, -np.pi, np.pi)
        q, qd, tau = rng.uniform(lim[:, 0], lim[:, 1]), rng.normal(size=n), rng.normal(size=n) * 5
        # same numbers first (Pinocchio's ABA leaves out the URDF's damping: it goes into tau)
        ref = pin.aba(model, data, q, qd, tau)
        for r in (num, gen):
            err = np.abs(r.forward_dynamics(q, qd, tau + r.friction(qd)) - ref).max() / np.abs(ref).max()
            assert err < 1e-10, (name, r.backend, err)
        print(f"{name:6} {'compile (s; cached if < 1)':34} {t_compile:9.2f}   operations {info['operation_count']}")
        t_num, t_gen, t_pin = fastest_ns([loop(lambda: num.forward_dynamics(q, qd, tau), args.calls),
                                          loop(lambda: gen.forward_dynamics(q, qd, tau), args.calls),
                                          loop(lambda: pin.aba(model, data, q, qd, tau), args.calls)],
                                         args.calls, args.repeats)
        N = 100_000
        Q = rng.uniform(lim[:, 0], lim[:, 1], (N, n))
        QD, T = rng.normal(size=(N, n)), rng.normal(size=(N, n)) * 5
        b_num, b_gen = fastest_ns([lambda: cs.forward_dynamics_batch(num, Q, QD, T, threads=1),
                                   lambda: cs.forward_dynamics_batch(gen, Q, QD, T, threads=1)], N, args.repeats)
        print(f"{name:6} {'FD from Python, numeric':34} {t_num:9.0f}")
        print(f"{name:6} {'FD from Python, generated':34} {t_gen:9.0f}")
        print(f"{name:6} {'pin.aba from Python':34} {t_pin:9.0f}")
        print(f"{name:6} {'FD batch per state, numeric':34} {b_num:9.0f}")
        print(f"{name:6} {'FD batch per state, generated':34} {b_gen:9.0f}")
        print(f"{name:6} ratios: numeric/generated {t_num / t_gen:.2f} (Python), {b_num / b_gen:.2f} (batch); "
              f"generated/pin.aba {t_gen / t_pin:.2f}, numeric/pin.aba {t_num / t_pin:.2f} (Python)")


if __name__ == "__main__":
    main()
