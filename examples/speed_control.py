"""Speed control and live drawing (the paper's FrameRate, section 11.4).

SCARA #1 follows a cubic trajectory under computed torque while a Pacer
ties simulated time to the wall clock. A per-frame callback redraws the arm
(top view, desired pose as a faint ghost) and, like the paper's speed
control, changes the speed on the way: 100 % for the first half second of
simulated time, then 400 %, then a pause of 0.3 s of wall time, then 200 %
to the end. It prints the time supervision figures (simulated time, wall
time, step size, steps per second, real-time factor) twice a second of wall
time. Writes into --out: speed_control_frames.png (snapshots of the live
drawing) and speed_control_time.png (simulated against wall time).
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out", help="folder for the figures")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    robot = cs.robots.scara1()
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    traj = cs.CubicTrajectory([0.0, 1.0, 2.0, 3.0], np.array([mid + f * span for f in (-0.2, 0.2, -0.25, 0.1)]))
    sim = cs.Simulation(dt=2e-4, log_every=10)
    sim.add_robot(robot, cs.ComputedTorque(900.0, 60.0), traj)

    # the live view: arm and ghost of the desired pose, top view
    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    reach = 0.6
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ghost, = ax.plot([], [], "o-", color="tab:blue", alpha=0.3, lw=6, label="desired")
    arm, = ax.plot([], [], "o-", color="tab:green", lw=3, label="robot")
    label = ax.set_title("")
    ax.legend(loc="lower left", fontsize="small")
    snapshots = []
    trace = []  # (wall, simulated) per frame
    state = {"paused_at": None, "printed": 0.0, "t0": time.perf_counter()}

    def top_view(q):
        p = robot.frames(q)[:, :2, 3]
        return p[:, 0], p[:, 1]

    def on_frame(s, pacer):
        wall = time.perf_counter() - state["t0"]
        trace.append((wall, s.time))
        # speed schedule: 100 %, then 400 %, a pause, then 200 %
        if s.time >= 0.5 and pacer.speed == 1.0 and state["paused_at"] is None:
            pacer.speed_percent = 400
        if s.time >= 1.5 and state["paused_at"] is None:
            pacer.pause()
            state["paused_at"] = wall
        if pacer.paused and wall - state["paused_at"] >= 0.3:
            pacer.speed = 2.0
            pacer.resume()
        # live drawing
        q, _ = s.state()
        arm.set_data(*top_view(q))
        ghost.set_data(*top_view(traj.evaluate(s.time)[0]))
        label.set_text(f"t = {s.time:.2f} s   speed {0 if pacer.paused else pacer.speed_percent:.0f} %")
        fig.canvas.draw()
        if len(trace) % 15 == 1 and len(snapshots) < 6:
            snapshots.append(np.asarray(fig.canvas.buffer_rgba()).copy())
        if wall - state["printed"] >= 0.5:
            state["printed"] = wall
            print(pacer.stats)

    stats = sim.run_paced(3.5, speed=1.0, frame_rate=30.0, on_frame=on_frame)
    print("done:", stats)
    plt.close(fig)

    fig, axes = plt.subplots(2, 3, figsize=(10, 7))
    for a, img in zip(axes.ravel(), snapshots):
        a.imshow(img)
        a.axis("off")
    for a in axes.ravel()[len(snapshots):]:
        a.axis("off")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "speed_control_frames.png"), dpi=80)
    plt.close(fig)

    w, t = np.array(trace).T
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(w, t, ".-", ms=3)
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("simulated time (s)")
    ax.set_title("100 % -> 400 % -> pause -> 200 %")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "speed_control_time.png"), dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    main()
