"""Dynamics speed: ns per call from C++ (native binary) and from Python.

Rows, for both SCARAs and both backends (numeric recursive algorithms and
generated closed-form code): mass matrix, C + G, forward dynamics, inverse
dynamics, one RK4 step; from Python also the batch forward dynamics
(N = 100 000 states in one call, GIL released) on 1 and 2 threads, and
Pinocchio's ``aba`` on the same robot (loaded from our URDF) when Pinocchio
is installed. Each figure is the median over repeats; ratios are taken
within this run.

    python benchmarks/bench_dynamics.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import coopsim as cs

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGETS = {  # ns per call: the project's targets
    ("generated", "forward_dynamics", "C++"): 250.0,
    ("numeric", "forward_dynamics", "C++"): 1000.0,
    ("any", "rk4_step", "C++"): 1200.0,
    ("any", "batch_fd_2threads", "Python"): 400.0,
}


def write_tables(robots, path):
    with open(path, "w") as f:
        f.write(f"{len(robots)}\n")
        for r in robots:
            f.write(f"{r.name} {r.dof} {r.joint_types}\n")
            for i in range(r.dof):
                row = [*r.dh[i], *r.com[i], r.masses[i], *r.inertias[i].ravel(), r.friction_coefficients[i],
                       *r.q_limits[i], r.tau_limits[i]]
                f.write(" ".join(repr(float(v)) for v in row) + "\n")
            t = r.tool
            f.write(" ".join(repr(float(v)) for v in [*r.gravity_acceleration, *r.base_position, r.base_yaw]) + "\n")
            f.write(f"{t.link} " + " ".join(repr(float(v)) for v in t.offset.ravel()) +
                    f" {t.second_link} " + " ".join(repr(float(v)) for v in t.second_point) + "\n")


def build_native():
    build = os.path.join(ROOT, "build", "bench")
    subprocess.run(["cmake", "-S", ROOT, "-B", build, "-DCMAKE_BUILD_TYPE=Release", "-DCOOPSIM_BUILD_PYTHON=OFF",
                    "-DCOOPSIM_BUILD_BENCHMARKS=ON"], check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", build, "--target", "coopsim_bench", "-j2"], check=True,
                   stdout=subprocess.DEVNULL)
    return os.path.join(build, "coopsim_bench")


def native_rows(robots, calls, repeats):
    exe = build_native()
    with tempfile.TemporaryDirectory() as d:
        tables = os.path.join(d, "robots.txt")
        write_tables(robots, tables)
        out = subprocess.run([exe, tables, str(calls), str(repeats)], check=True, capture_output=True,
                             text=True).stdout
    rows = {}
    for line in out.splitlines():
        if line.startswith("#"):
            print(line)
            continue
        name, backend, what, ns = line.split()
        rows[(name, backend, what)] = float(ns)
    return rows


def median_ns(fn, calls, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        times.append((time.perf_counter() - t0) / calls * 1e9)
    return float(np.median(times))


def python_rows(robot, calls, repeats):
    rng = np.random.default_rng(0)
    lim = robot.q_limits
    q = rng.uniform(lim[:, 0], lim[:, 1])
    qd, qdd, tau = rng.normal(size=6), rng.normal(size=6), rng.normal(size=6)
    rows = {
        "mass_matrix": median_ns(lambda: robot.mass_matrix(q), calls, repeats),
        "coriolis_plus_gravity": median_ns(lambda: (robot.coriolis(q, qd), robot.gravity(q)), calls, repeats),
        "forward_dynamics": median_ns(lambda: robot.forward_dynamics(q, qd, tau), calls, repeats),
        "inverse_dynamics": median_ns(lambda: robot.inverse_dynamics(q, qd, qdd), calls, repeats),
        "rk4_step": median_ns(lambda: cs.rk4_step(robot, q, qd, tau), calls, repeats),
    }
    N = 100_000
    Q = rng.uniform(lim[:, 0], lim[:, 1], (N, 6))
    QD, TAU = rng.normal(size=(N, 6)), rng.normal(size=(N, 6))
    for threads in (1, 2):
        rows[f"batch_fd_{threads}thread{'s' if threads > 1 else ''}"] = median_ns(
            lambda: cs.forward_dynamics_batch(robot, Q, QD, TAU, threads=threads), 1, max(3, repeats // 2)) / N
    return rows


def pinocchio_aba(robot, calls, repeats):
    try:
        import pinocchio as pin
    except ImportError:
        return None
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(robot.to_urdf())
    try:
        model = pin.buildModelFromUrdf(f.name)
    finally:
        os.unlink(f.name)
    data = model.createData()
    rng = np.random.default_rng(0)
    lim = robot.q_limits
    q = rng.uniform(lim[:, 0], lim[:, 1])
    qd, tau = rng.normal(size=6), rng.normal(size=6)
    # same physics (friction aside): check before timing
    ours = robot.forward_dynamics(q, qd, tau + robot.friction(qd))
    theirs = pin.aba(model, data, q, qd, tau)
    assert np.allclose(ours, theirs, rtol=1e-9, atol=1e-9), (ours, theirs)
    return median_ns(lambda: pin.aba(model, data, q, qd, tau), calls, repeats)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer calls and repeats")
    args = ap.parse_args(argv)
    calls, repeats = (2000, 3) if args.quick else (20000, 7)
    print(f"coopsim {cs.__version__}, build optimised: {cs.build_info()['optimised']}")
    if not cs.build_info()["optimised"]:
        print("figures from a debug build do not count")
    robots = [cs.robots.scara1(backend="numeric"), cs.robots.scara2(backend="numeric")]
    native = native_rows(robots, calls, repeats)
    what = ["mass_matrix", "coriolis_plus_gravity", "forward_dynamics", "inverse_dynamics", "rk4_step"]
    print(f"\n{'robot':8} {'what':24} {'from':7} {'numeric ns':>11} {'generated ns':>13} {'num/gen':>8}")
    for r in robots:
        gen = getattr(cs.robots, r.name)().has_generated   # its generated dynamics are in the engine
        py = {"numeric": python_rows(r, calls // 4, repeats)}
        if gen:
            rg = getattr(cs.robots, r.name)(backend="generated")
            py["generated"] = python_rows(rg, calls // 4, repeats)
        for w in what:
            n_ns = native[(r.name, "numeric", w)]
            g_ns = native.get((r.name, "generated", w))
            ratio = f"{n_ns / g_ns:8.2f}" if g_ns else "       -"
            print(f"{r.name:8} {w:24} {'C++':7} {n_ns:11.1f} {g_ns if g_ns else float('nan'):13.1f} {ratio}")
        for w in list(py["numeric"]):
            n_ns = py["numeric"][w]
            g_ns = py.get("generated", {}).get(w)
            ratio = f"{n_ns / g_ns:8.2f}" if g_ns else "       -"
            print(f"{r.name:8} {w:24} {'Python':7} {n_ns:11.1f} {g_ns if g_ns else float('nan'):13.1f} {ratio}")
        aba = pinocchio_aba(r, calls // 4, repeats)
        if aba is not None:
            best = min(py["numeric"]["forward_dynamics"], py.get("generated", py["numeric"])["forward_dynamics"])
            print(f"{r.name:8} {'pinocchio aba':24} {'Python':7} {aba:11.1f} {'':13} "
                  f"ours/pin {best / aba:.2f}")
        fd_gen = native.get((r.name, "generated", "forward_dynamics"))
        checks = [("numeric forward dynamics from C++ <= 1000 ns", native[(r.name, "numeric", "forward_dynamics")],
                   1000.0)]
        if fd_gen:
            checks.append(("generated forward dynamics from C++ <= 250 ns", fd_gen, 250.0))
        best_rk4 = min(v for (n, b, w), v in native.items() if n == r.name and w == "rk4_step")
        checks.append(("one RK4 step from C++ <= 1200 ns", best_rk4, 1200.0))
        best_batch = min(p["batch_fd_2threads"] for p in py.values())
        checks.append(("batch forward dynamics from Python <= 400 ns/state", best_batch, 400.0))
        for label, value, target in checks:
            print(f"  target {label}: {value:.0f} ns -> {'met' if value <= target else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
