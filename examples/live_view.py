"""Live view of a paced run (the paper's real-time window), in the browser.

Both SCARAs follow cubic joint trajectories under a slow PID while the
simulation runs paced to the wall clock (speed 1 = real time, up to 4 = 400 %)
and ``coopsim.view.live`` serves the page on 127.0.0.1: the robots, their
desired poses as transparent blue ghosts, the panels (speed, pause, one step,
reset, time supervision, display, teach moves, plots, the log to download).
Open the printed URL; after the run the page stays until Ctrl-C (or --hold
seconds). --out DIR also writes the run's joint plot as a PNG.

--matplotlib: the matplotlib window instead (no page): every frame the
on_frame callback moves the robots of a ``coopsim.view`` scene (SCARA #2 green
in the second half as if it held something) and redraws only the boxes; with
--out DIR every frame as DIR/live_view_NNNN.png; --frames N stops after N
frames. The label and the statistics printed at the end give the frame rate
reached against the one asked for (--fps).
"""
from __future__ import annotations

import argparse
import os

import matplotlib.pyplot as plt
import numpy as np

import coopsim as cs
from coopsim import view


def plan(robot, fractions, t_end):
    """A cubic trajectory through the middle of the joint ranges moved by the given fractions of each range."""
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    times = np.linspace(0.0, t_end, len(fractions))
    return cs.CubicTrajectory(times, np.array([mid + np.asarray(f) * span for f in fractions]))


def pid_gains(robot, ref, w):
    """PID gains kp = J w^2, ki = kp w / 10, kd = 2 J w from each joint's largest inertia J on the path."""
    ts = np.linspace(ref.t_start, ref.t_end, 21)
    J = np.maximum(np.max([np.diag(robot.mass_matrix(ref.evaluate(t)[0])) for t in ts], axis=0), 0.01)
    return J * w ** 2, J * w ** 3 / 10, 2 * J * w


def build(T):
    """Both SCARAs on cubic trajectories through their joint ranges, under a slow PID."""
    r1 = cs.robots.scara1()
    r2 = cs.robots.scara2(base_position=(0.75, 0.0, 0.0), base_yaw=np.pi)
    refs = [plan(r1, [[-0.25, 0.2, -0.3, 0, 0.1, -0.4], [0.0, -0.15, 0.2, 0.2, -0.2, 0.4],
                      [0.2, 0.1, -0.1, -0.2, 0.2, -0.2]], T),
            plan(r2, [[0.15, -0.2, 0.1, -0.3, 0, -0.4], [-0.1, 0.2, -0.15, 0.2, 0.3, 0.4],
                      [0.1, 0.05, 0.2, -0.1, -0.2, 0.0]], T)]
    sim = cs.Simulation(dt=2e-4, log_every=25)   # a row every 5 ms: the page's table, plots and downloads
    for robot, ref in zip((r1, r2), refs):
        # a slow PID (bandwidth 12 rad/s), so that the robots lag behind their ghosts
        sim.add_robot(robot, cs.PID(*pid_gains(robot, ref, 12.0)), ref)
    return sim, (r1, r2), refs


def browser(args, sim):
    """The live page: runs to --t-end paced, then serves the page until Ctrl-C or --hold seconds."""
    v = view.live(sim, t_end=args.t_end, speed=args.speed, frame_rate=args.fps, title="coopsim: live view")
    try:
        v.wait()
        print(f"run done: t = {sim.time:.3f} s, {v.frames} frames sent")
        if args.out:
            fig = sim.log.plot(robot=0)
            fig = getattr(fig, "figure", fig)
            path = os.path.join(args.out, "live_view_q.png")
            fig.savefig(path, dpi=80)
            print(f"wrote {path}")
        v.hold(args.hold)
    except KeyboardInterrupt:
        pass
    finally:
        v.close()


def window(args, sim, robots, refs):
    """The matplotlib window (the fallback without a browser)."""
    r1, r2 = robots
    T = args.t_end
    plt.ion()
    fig = plt.figure(figsize=(6.4, 4.8))
    ax = fig.add_subplot(projection="3d")
    fig.subplots_adjust(0, 0, 1, 1)
    # fix the view over the whole run: floor and limits from the references' poses
    samples = np.linspace(0.0, T, 25)
    scene = view.Scene(ax, [r1, r2], cull=True)
    scene.fit(np.concatenate([view.box_corners(*r.shapes(q)).reshape(-1, 3)
                              for r, ref in zip((r1, r2), refs) for q in ref.evaluate(samples)[0]]))
    plt.show(block=False)
    written = []

    def on_frame(s, pacer):
        t = s.time
        q = [s.state(i)[0] for i in range(2)]
        q_ref = [ref.evaluate(t)[0] for ref in refs]
        st = pacer.stats   # the frame rate reached so far against the one asked for (drawing may be slower)
        scene.update(q, reference=q_ref, holding=[False, t >= T / 2],
                     label=f"t = {t:.2f} s   speed {pacer.speed_percent:.0f} %   {st.frames} frames, "
                           f"{st.frame_rate:.0f} of {pacer.frame_rate:g} fps")
        scene.redraw()
        fig.canvas.flush_events()
        if args.out:
            path = os.path.join(args.out, f"live_view_{len(written):04d}.png")
            plt.imsave(path, np.asarray(fig.canvas.buffer_rgba()))
            written.append(path)
        if args.frames and pacer.stats.frames >= args.frames:
            return False
        return None

    stats = sim.run_paced(T, speed=args.speed, frame_rate=args.fps, on_frame=on_frame)
    print(stats)
    if stats.frame_rate < 0.9 * args.fps:
        print(f"drew {stats.frame_rate:.1f} frames per second of the {args.fps:g} asked for: a frame (stepping and "
              f"drawing) took {1e3 / stats.frame_rate:.0f} ms on average")
    if written:
        print(f"wrote {len(written)} frames: {written[0]} ... {written[-1]}")
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="folder for the PNGs (default: write none)")
    ap.add_argument("--matplotlib", action="store_true", help="the matplotlib window instead of the browser page")
    ap.add_argument("--frames", type=int, default=0, help="--matplotlib: stop after this many frames (0: all)")
    ap.add_argument("--hold", type=float, default=None,
                    help="seconds the page stays after the run (default: until Ctrl-C in a terminal, else 0)")
    ap.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall second, 0 .. 4")
    ap.add_argument("--t-end", type=float, default=3.0, help="simulated time to run, s")
    ap.add_argument("--fps", type=float, default=30.0, help="frames per second drawn")
    args = ap.parse_args()
    if args.frames < 0:
        ap.error("--frames must be >= 0")
    if args.out:
        os.makedirs(args.out, exist_ok=True)
    sim, robots, refs = build(args.t_end)
    if args.matplotlib:
        window(args, sim, robots, refs)
    else:
        browser(args, sim)


if __name__ == "__main__":
    main()
