"""Both SCARAs released from a pose with zero joint torque.

Gravity pulls each quill down onto its end stop and tips SCARA #1's clamp;
the horizontal joints swing from the coupling and settle under friction.
Writes the joint positions as a plot (PNG) and as data (CSV) into --out.
"""
from __future__ import annotations

import argparse
import os
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402

JOINTS = {
    "scara1": ["θ1 (rad)", "θ2 (rad)", "d3 (m)", "θ4 (rad)", "θ5 (rad)", "d6 (m)"],
    "scara2": ["θ1 (rad)", "θ2 (rad)", "θ3 (rad)", "d4 (m)", "θ5 (rad)", "d6 (m)"],
}


def simulate(t_end: float, dt: float):
    robots = {
        "scara1": cs.robots.scara1(),
        "scara2": cs.robots.scara2(base_position=(0.75, 0.0, 0.0)),
    }
    start = {
        "scara1": (np.array([0.4, 1.2, 0.05, 0.3, 0.8, 0.02]), np.array([2.0, -1.0, 0.0, 0.0, 0.0, 0.0])),
        "scara2": (np.array([2.5, -1.0, 0.8, 0.05, 0.5, 0.02]), np.array([-1.5, 2.0, 0.0, 0.0, 0.0, 0.0])),
    }
    steps = int(round(t_end / dt))
    out = {}
    for name, robot in robots.items():
        q0, qd0 = start[name]
        t0 = time.perf_counter()
        t, Q, QD = cs.integrate(robot, q0, qd0, np.zeros(robot.dof), dt=dt, steps=steps, record_every=25)
        wall = time.perf_counter() - t0
        out[name] = (robot, t, Q, QD, wall)
        print(f"{name}: backend {robot.backend}, {steps} RK4 steps of {dt * 1e3:.1f} ms in {wall * 1e3:.1f} ms "
              f"({t_end / wall:.0f}x real time)")
    return out


def plot(results, path):
    fig, axes = plt.subplots(6, 2, figsize=(11, 12), sharex=True)
    for col, (name, (robot, t, Q, _, _)) in enumerate(results.items()):
        lim = robot.q_limits
        for j in range(robot.dof):
            ax = axes[j, col]
            ax.plot(t, Q[:, j], color="tab:green" if col == 0 else "tab:blue")
            for v in lim[j]:
                ax.axhline(v, color="0.6", ls=":", lw=0.8)
            lo, hi = Q[:, j].min(), Q[:, j].max()
            pad = 0.1 * max(hi - lo, 1e-3)
            ax.set_ylim(lo - pad, hi + pad)
            ax.set_ylabel(JOINTS[name][j])
            ax.grid(alpha=0.3)
        axes[0, col].set_title(f"SCARA #{name[-1]}: zero torque under gravity")
        axes[-1, col].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def save_csv(results, path):
    cols, data = ["t"], None
    for name, (robot, t, Q, QD, _) in results.items():
        data = t[:, None] if data is None else data
        cols += [f"{name}_q{j + 1}" for j in range(robot.dof)] + [f"{name}_qd{j + 1}" for j in range(robot.dof)]
        data = np.hstack([data, Q, QD])
    tmp = path + ".tmp"
    np.savetxt(tmp, data, delimiter=",", header=",".join(cols), comments="")
    os.replace(tmp, path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="out", help="output folder")
    ap.add_argument("--t-end", type=float, default=3.0, help="simulated time (s)")
    ap.add_argument("--dt", type=float, default=2e-4, help="RK4 step (s)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    results = simulate(args.t_end, args.dt)
    png = os.path.join(args.out, "gravity_demo.png")
    csv = os.path.join(args.out, "gravity_demo.csv")
    plot(results, png)
    save_csv(results, csv)
    print(f"wrote {png} and {csv}")


if __name__ == "__main__":
    main()
