"""Cartesian planning for SCARA #1: clamp poses with times -> inverse
kinematics -> cubic joint trajectory (paper sections 6 and 7).

The tool passes through every given pose; between them it follows the
joints' cubics, not a straight line, unless straight-line intermediate poses
are inserted: the more of them, the closer the path (the paper's remark that
precision grows with the number of points). Writes into --out:
plan_trajectory_joints.png (q, q̇, q̈ of the plan) and
plan_trajectory_path.png (tool path, top view, for several point counts).
"""
from __future__ import annotations

import argparse
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402
from coopsim.plotting import plot_tool_path, plot_trajectory  # noqa: E402


def line_deviation(robot, traj, poses, times, samples=400):
    """Largest distance (m) of the TCP from the straight segments between the poses."""
    worst = 0.0
    for k in range(len(times) - 1):
        t = np.linspace(times[k], times[k + 1], samples)
        q, _, _ = traj.evaluate(t)
        p = np.array([robot.fk(qi)[:3, 3] for qi in q])
        a, b = poses[k][:3, 3], poses[k + 1][:3, 3]
        d = b - a
        rel = p - a
        off = rel - np.outer(rel @ d / (d @ d), d)
        worst = max(worst, np.linalg.norm(off, axis=1).max())
    return worst


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="out", help="output folder")
    ap.add_argument("--points", type=int, default=10, help="intermediate poses per segment for the main plan")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)

    robot = cs.robots.scara1()
    # clamp poses: TCP position (m), yaw about the vertical, pitch (0 horizontal, pi/2 down)
    poses = np.array([
        cs.clamp_pose(robot, [0.40, 0.10, 0.20], yaw=0.3, pitch=1.2),
        cs.clamp_pose(robot, [0.38, -0.22, 0.10], yaw=-0.6, pitch=0.5),
        cs.clamp_pose(robot, [0.22, 0.36, 0.25], yaw=1.4, pitch=0.1),
        cs.clamp_pose(robot, [0.30, 0.20, 0.05], yaw=0.2, pitch=1.5),
    ])
    times = np.array([0.0, 1.5, 3.5, 5.0])
    opening = [0.03, 0.03, 0.01, 0.01]  # jaw opening d6 (m) at each pose

    traj, info = cs.plan_cartesian(robot, poses, times, opening=opening, intermediate=args.points, info=True)
    q_at, _, _ = traj.evaluate(times)
    err = max(np.abs(robot.fk(q) - T).max() for q, T in zip(q_at, poses))
    print(f"SCARA #1 plan: {traj}, elbow branch {info['branch']:+d}; "
          f"largest pose error at the given poses {err:.2e}")
    print("intermediate poses per segment -> largest distance of the tool from the straight path:")
    plans = {}
    for k in (0, 2, 5, args.points, 3 * args.points):
        plans[k] = cs.plan_cartesian(robot, poses, times, opening=opening, intermediate=k)
        print(f"  {k:3d}: {line_deviation(robot, plans[k], poses, times) * 1e3:8.3f} mm")

    fig = plot_trajectory(traj, robot, margin=0.5,
                          title=f"SCARA #1: cubic joint trajectory through 4 clamp poses, {args.points} "
                                f"straight-line points per segment")
    path = os.path.join(args.out, "plan_trajectory_joints.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    for c, k in enumerate(sorted(plans)):
        plot_tool_path(robot, plans[k], poses=poses if c == 0 else None, ax=ax, label=f"{k} intermediate poses",
                       color=f"C{c}")
    ax.set_title("SCARA #1 tool path (top view)")
    path2 = os.path.join(args.out, "plan_trajectory_path.png")
    fig.savefig(path2, dpi=110)
    plt.close(fig)

    # SCARA #2, placed opposite, through the same kind of plan
    robot2 = cs.robots.scara2(base_position=(0.75, 0.0, 0.0), base_yaw=np.pi)
    poses2 = np.array([cs.clamp_pose(robot2, p, yaw=y) for p, y in
                       (([0.45, 0.10, 0.20], 0.3), ([0.50, -0.20, 0.15], -0.5), ([0.35, 0.05, 0.30], 1.0))])
    traj2 = cs.plan_cartesian(robot2, poses2, [0.0, 1.0, 2.0], opening=0.02, spline=True, intermediate=4)
    q2, _, _ = traj2.evaluate(np.array([0.0, 1.0, 2.0]))
    err2 = max(np.abs(robot2.fk(q) - T).max() for q, T in zip(q2, poses2))
    print(f"SCARA #2 plan (C2 spline): {traj2}; largest pose error at the given poses {err2:.2e}")
    print(f"wrote {path} and {path2}")


if __name__ == "__main__":
    main()
