"""Drawing speed of coopsim.view: ms per animation frame and time to write a 20 s run as MP4 and GIF.

Both SCARAs follow cubic trajectories for 20 s under computed torque
(logged every 5 ms). Rows:

- ms per frame of ``Animation.frames()`` (scene update + blitted draw,
  640 x 480), for SCARA #1 alone, SCARA #2 alone and both, with the
  reference ghosts; and the same with a full ``canvas.draw()`` per frame,
  and with matplotlib's axes shown (axis=True), for comparison;
- ms of ``Scene.update`` alone (the numpy and engine part of a frame);
- wall time to write the whole 20 s log at 30 fps (601 frames) as MP4
  (imageio-ffmpeg's ffmpeg, H.264) and as GIF (Pillow), and the file sizes;
- the same for the cooperative task itself (coopsim.tasks.handover: both
  SCARAs, the container, the bars, the grasps), its first 20 s as MP4, GIF
  and the browser replay (HTML).

Each figure is the median over repeats. Target: a 20 s log at 30 fps to MP4
in well under a minute on two cores.

    python benchmarks/bench_view.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402
from coopsim import view  # noqa: E402

T_END = 20.0


def trajectory(robot, duration, phase):
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    times = np.linspace(0.0, duration, 9)
    pts = np.array([mid + 0.2 * np.sin(phase + 1.3 * k) * span for k in range(len(times))])
    return cs.CubicTrajectory(times, pts)


def run(robots, t_end):
    sim = cs.Simulation(dt=2e-4, log_every=25)
    for i, r in enumerate(robots):
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), trajectory(r, t_end, phase=1.7 * i))
    return sim.run(t_end, progress=False), sim.robots


def run_task_scene(t_end):
    """The cooperative task itself (coopsim.tasks.handover, logged every 5 ms), enough cycles to cover t_end s:
    both SCARAs, the container, the bars, the grasps (robots coloured while they hold)."""
    from coopsim.tasks import handover

    res = handover.run(cycles=max(1, min(3, int(t_end // 16.0) + 1)), score=False)
    assert res.success, handover.summary(res.report)
    return res.sim


def median_ms_per_frame(make_anim, frames, repeats, full=False):
    out = []
    for _ in range(repeats):
        anim = make_anim()
        n = min(frames, len(anim))
        t0 = time.perf_counter()
        if full:
            for k in range(n):
                anim.show_frame(k)
                anim.fig.canvas.draw()
        else:
            it = anim.frames()
            for _ in range(n):
                next(it)
            it.close()
        out.append((time.perf_counter() - t0) / n * 1e3)
    return statistics.median(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames and repeats, a 4 s log for the files")
    args = ap.parse_args()
    frames, repeats = (30, 1) if args.quick else (120, 3)
    t_files = 4.0 if args.quick else T_END

    r1 = cs.robots.scara1()
    r2 = cs.robots.scara2(base_position=(0.75, 0.0, 0.0), base_yaw=np.pi)
    print(f"coopsim.view, 640 x 480 frames, matplotlib {matplotlib.__version__}; median of {repeats} over "
          f"{frames} frames")
    print(f"{'scene':<28} {'blitted (ms/frame)':>19} {'full draw':>10} {'axes shown':>11} {'update only':>12}")
    logs = {}
    for name, robots in (("SCARA #1", [r1]), ("SCARA #2", [r2]), ("both SCARAs", [r1, r2])):
        log, sims_robots = run(robots, T_END)
        logs[name] = (log, sims_robots)

        def make(axis=False):
            return view.animate(log, sims_robots, fps=30, axis=axis)

        blit = median_ms_per_frame(make, frames, repeats)
        full = median_ms_per_frame(make, frames, repeats, full=True)
        axes = median_ms_per_frame(lambda: make(axis=True), frames, repeats, full=True)
        anim = make()
        t0 = time.perf_counter()
        n = min(frames, len(anim))
        for k in range(n):
            anim.show_frame(k)
        upd = (time.perf_counter() - t0) / n * 1e3
        print(f"{name + ' + ghosts':<28} {blit:>19.2f} {full:>10.2f} {axes:>11.2f} {upd:>12.2f}")

    task = run_task_scene(T_END)
    blit = median_ms_per_frame(lambda: view.animate(task, fps=30), frames, repeats)
    full = median_ms_per_frame(lambda: view.animate(task, fps=30), frames, repeats, full=True)
    print(f"{'the task (world) + ghosts':<28} {blit:>19.2f} {full:>10.2f}")
    with tempfile.TemporaryDirectory() as d:
        for suffix in (".mp4", ".gif", ".html"):
            path = os.path.join(d, "task" + suffix)
            t0 = time.perf_counter()
            if suffix == ".html":
                view.replay_html(task, path, t_end=t_files)
                n = int(t_files * 30) + 1
            else:
                n = len(view.animate(task, fps=30, t_end=t_files, path=path))
            wall = time.perf_counter() - t0
            print(f"the task, {t_files:g} s at 30 fps -> {suffix[1:].upper()}: {n} frames in {wall:.2f} s, "
                  f"{os.path.getsize(path) / 1e6:.2f} MB")

    log, robots = logs["both SCARAs"]
    with tempfile.TemporaryDirectory() as d:
        for suffix in (".mp4", ".gif"):
            path = os.path.join(d, "run" + suffix)
            t0 = time.perf_counter()
            anim = view.animate(log, robots, fps=30, t_end=t_files, path=path)
            wall = time.perf_counter() - t0
            print(f"both SCARAs, {t_files:g} s log at 30 fps -> {suffix[1:].upper()}: {len(anim)} frames in "
                  f"{wall:.2f} s ({wall / len(anim) * 1e3:.1f} ms/frame), {os.path.getsize(path) / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
