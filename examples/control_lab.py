"""Control lab on SCARA #1: PID against computed torque (paper sections 9, 11.3, 11.4).

One cubic joint trajectory, three controllers: PID with gravity
compensation, computed torque with the robot's own model, and computed
torque with a model whose masses are 20 % too large. Prints their RMS
tracking errors, runs the PID case paced at 200 % of real time, then sweeps
a 4 x 4 grid of PID gains in one batch call. Writes into --out:
control_lab_pid.png (joints against the dashed reference),
control_lab_errors.png (tracking error norms of the three controllers, the
revolute joints (rad) and the prismatic ones (m) apart),
control_lab_sweep.png (RMS error over the gain grid), and the
computed-torque log as control_lab_ct.csv and control_lab_ct.xlsx.
"""
from __future__ import annotations

import argparse
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402
from coopsim.plotting import plot_log  # noqa: E402


def trajectory(robot):
    """Four via-points spread over each joint's range, 1 s apart."""
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    return cs.CubicTrajectory([0.0, 1.0, 2.0, 3.0], np.array([mid + f * span for f in (-0.1, 0.15, -0.2, 0.05)]))


def pid_gains(robot, traj, w):
    """kp = J w^2, kd = 2 J w, ki = kp w / 10 with J the largest diagonal inertia on the path."""
    J = np.max([np.diag(robot.mass_matrix(traj.evaluate(t)[0])) for t in np.linspace(0, 3, 31)], axis=0)
    J = np.maximum(J, 0.01)
    return J * w * w, J * w ** 3 / 10, 2 * J * w


def overall_rms(sim):
    """RMS tracking error (rad) over the steps and the revolute joints (the prismatic ones, in m, apart)."""
    revolute = [j for j, c in enumerate(sim.robots[0].joint_types) if c == "R"]
    return float(np.sqrt(np.mean(sim.metrics()[0].rms_error[revolute] ** 2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out", help="folder for figures and files")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    robot = cs.robots.scara1()
    traj = trajectory(robot)
    wrong = cs.robots.scara1(masses=robot.masses * 1.2)
    controllers = {
        "PID + gravity compensation": cs.PID(*pid_gains(robot, traj, 50.0)),
        "computed torque, exact model": cs.ComputedTorque(900.0, 60.0),
        "computed torque, masses x 1.2": cs.ComputedTorque(900.0, 60.0, model=wrong),
    }
    sims = {}
    print(f"{'controller':<32} {'RMS e (rad)':>11} {'max |e| (rad)':>13}  {'real-time x':>11}")
    revolute = [j for j, c in enumerate(robot.joint_types) if c == "R"]
    prismatic = [j for j, c in enumerate(robot.joint_types) if c == "P"]
    for name, ctrl in controllers.items():
        sim = cs.Simulation(dt=2e-4)
        sim.add_robot(robot, ctrl, traj)
        sim.run(3.5)
        m = sim.metrics()[0]
        sims[name] = sim
        print(f"{name:<32} {overall_rms(sim):>11.2e} {m.max_abs_error[revolute].max():>13.2e}  "
              f"{sim.stats.real_time_factor:>11.0f}")

    pid_log = sims["PID + gravity compensation"].log
    fig = plot_log(pid_log, title="SCARA #1 under PID: joints (solid) and reference (dashed)",
                   joint_types=robot.joint_types)
    fig.savefig(os.path.join(args.out, "control_lab_pid.png"), dpi=90)
    plt.close(fig)

    fig, (ax_r, ax_p) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for name, sim in sims.items():
        log = sim.log
        ax_r.semilogy(log.t, np.linalg.norm(log.error[:, revolute], axis=1) + 1e-12, label=name)
        ax_p.semilogy(log.t, np.linalg.norm(log.error[:, prismatic], axis=1) + 1e-12, label=name)
    ax_p.set_xlabel("t (s)")
    ax_r.set_ylabel("|q_ref - q|, revolute (rad)")
    ax_p.set_ylabel("|q_ref - q|, prismatic (m)")
    ax_r.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    for ax in (ax_r, ax_p):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "control_lab_errors.png"), dpi=90)
    plt.close(fig)

    # export: every 50th row of the computed-torque log
    ct = cs.Simulation(dt=2e-4, log_every=50)
    ct.add_robot(robot, cs.ComputedTorque(900.0, 60.0), traj)
    log = ct.run(3.5)
    log.to_csv(os.path.join(args.out, "control_lab_ct.csv"))
    log.to_excel(os.path.join(args.out, "control_lab_ct.xlsx"))
    print(f"wrote {len(log)} rows x {len(log.columns())} columns to control_lab_ct.csv / .xlsx")

    # paced at 200 %: half a second of wall time for a second of motion
    paced = cs.Simulation(dt=2e-4)
    paced.add_robot(robot, cs.PID(*pid_gains(robot, traj, 50.0)), traj)
    stats = paced.run_paced(1.0, speed=2.0, frame_rate=60.0)
    print(f"paced at 200 %: {stats}")

    # a 4 x 4 grid of PID bandwidths and damping, one batch call on every core
    bandwidths = np.array([20.0, 30.0, 45.0, 70.0])
    damping = np.array([0.5, 1.0, 1.5, 2.0])
    grid = []
    for w in bandwidths:
        for z in damping:
            kp, ki, kd = pid_gains(robot, traj, w)
            sim = cs.Simulation(dt=2e-4, log_every=0)
            sim.add_robot(robot, cs.PID(kp, ki, kd * z), traj)
            grid.append(sim)
    metrics = cs.run_batch(grid, 3.5, output="metrics", errors="return")
    rms = np.array([np.sqrt(np.mean(m[0]["rms_error"][revolute] ** 2)) if isinstance(m, list) else np.nan
                    for m in metrics]).reshape(len(bandwidths), len(damping))
    i, j = np.unravel_index(np.nanargmin(rms), rms.shape)
    print(f"gain sweep: best RMS {rms[i, j]:.2e} rad (revolute joints) at bandwidth {bandwidths[i]:g} rad/s, kd x {damping[j]:g}")
    fig, ax = plt.subplots(figsize=(5, 4))
    im = ax.imshow(np.log10(rms), origin="lower", cmap="viridis")
    ax.set_xticks(range(len(damping)), [f"{z:g}" for z in damping])
    ax.set_yticks(range(len(bandwidths)), [f"{w:g}" for w in bandwidths])
    ax.set_xlabel("kd factor")
    ax.set_ylabel("bandwidth (rad/s)")
    fig.colorbar(im, label="log10 RMS error of θ1, θ2, θ4, θ5 (rad)")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "control_lab_sweep.png"), dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    main()
