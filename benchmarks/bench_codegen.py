"""Code generation costs: time to regenerate cpp/generated (both SCARAs), operation
counts of the emitted functions, and the time coopsim.codegen.compile takes for a
6-DOF robot defined at run time (generation + g++ build, cold cache), plus its
generated vs numeric forward dynamics from Python.

    python benchmarks/bench_codegen.py [--skip-compile]

Targets: regenerating both robots <= 60 s.
"""
from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

import coopsim as cs
from coopsim import codegen
from coopsim.codegen.builtin import builtin_structures, generate_files
from coopsim.codegen.emit import emit_functions, emit_solve


def puma_like():
    """A 6R arm with the PUMA 560's joint structure (alpha = +-pi/2), illustrative values."""
    h = np.pi / 2
    dh = [[0, 0.67, 0, h], [0, 0, 0.43, 0], [0, 0.15, 0.02, -h], [0, 0.43, 0, h], [0, 0, 0, -h], [0, 0.06, 0, 0]]
    com = [[0, 0.5, 0, 0], [0, 0.1, 0.2, 0], [0, 0.1, 0.01, 0], [0, 0.3, 0, 0], [0, 0, 0, 0], [0, 0.05, 0, 0]]
    masses = [10.0, 17.4, 4.8, 0.82, 0.34, 0.09]
    inertias = [cs.box_inertia(m, 0.1, 0.1, 0.2) for m in masses]
    return cs.Robot.from_dh(dh, com, masses, inertias, joint_types="RRRRRR", friction=[0.1] * 6, name="puma")


def per_call_ns(fn, calls=20000, repeats=5):
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        out.append((time.perf_counter() - t0) / calls * 1e9)
    return float(np.median(out))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-compile", action="store_true", help="leave out the 6-DOF compile")
    args = ap.parse_args()

    t0 = time.perf_counter()
    structures = builtin_structures()
    files = generate_files(structures)
    t_gen = time.perf_counter() - t0
    print(f"regenerate cpp/generated (scara1 + scara2, {len(files)} files): {t_gen:.1f} s  (target <= 60 s)")
    for s in structures:
        model = codegen.SymbolicModel(s)
        ops = {f.name: f.operations for f in emit_functions(model)}
        ops["solve"] = emit_solve(model)[1]
        print(f"  {s.name} operations: " + ", ".join(f"{k} {v}" for k, v in ops.items()))

    if args.skip_compile:
        return
    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        r = codegen.compile(puma_like(), cache=cache, verbose=True)    # a copy with the code attached
        t_cold = time.perf_counter() - t0
        warm = []
        for _ in range(7):     # a new robot of the same structure each time: the cached library loads
            robot = puma_like()
            t0 = time.perf_counter()
            codegen.compile(robot, cache=cache)
            warm.append(time.perf_counter() - t0)
        info = codegen.info(r)
        print(f"compile 6-DOF robot (RRRRRR): cold {t_cold:.1f} s, cached {np.median(warm) * 1e3:.1f} ms "
              f"(median of 7; {min(warm) * 1e3:.1f} to {max(warm) * 1e3:.1f} ms), "
              f"operation count {info['operation_count']}")
        num = puma_like()
        rng = np.random.default_rng(0)
        q, qd, tau = rng.normal(size=6), rng.normal(size=6), rng.normal(size=6)
        t_g = per_call_ns(lambda: r.forward_dynamics(q, qd, tau))
        t_n = per_call_ns(lambda: num.forward_dynamics(q, qd, tau))
        print(f"  forward_dynamics from Python: generated {t_g:.0f} ns, numeric {t_n:.0f} ns, "
              f"ratio {t_n / t_g:.2f}")


if __name__ == "__main__":
    main()
