"""Speed of the live view (coopsim.view.live) on the cooperative task's scene.

The scene: both SCARAs (coopsim.tasks.scene.scaras) in the task's world (floor, the container's four
walls, three bars), each robot following a cubic through its joint ranges under computed torque,
dt = 0.2 ms, the world every step. Rows:

- ms per frame of the view: the snapshot (state, references, ``Robot.shapes`` of q and q_ref in one
  call per robot, the parts' poses at q and q_ref from ``Robot.frames``, holding, contacts, bodies) and
  the send (the scene's batched meshes: the robots' parts and their ghosts, one per shape; the
  supervision panel, plots), with no page and with a headless Chromium page connected;
- frames per second: sent by the view during a paced run, and drawn by the page in headless
  Chromium (software WebGL, swiftshader: a lower bound for a desktop browser), counted with
  requestAnimationFrame;
- the real-time factor reached at 400 % pacing with the view attached (40 frames per second aimed at
  to a connected page) and without it (the pacer alone), and the headless run's own speed.

Each figure is the median over repeats.

The long run (the default): the same scene with every contact point logged (log_contacts=True), the
live view paced at 100 % for --minutes of wall time (5 by default; no browser needed: the Data panel's
table updates every 0.5 s with or without a page). Printed: the speed achieved per 30 s and per minute
(simulated over wall time, from the frames the view drew), the table's update cost (median and max per
minute, rows read), what one rebuild of the whole log (Simulation.log, as the table once did) costs at the
end, and the time from request to sent of a CSV and of an Excel download of the log at the end, with
their sizes, while the run goes on.

    python benchmarks/bench_live.py [--minutes 5] [--log-every 200]     # the long run
    python benchmarks/bench_live.py --frames [--quick]                  # the per-frame figures
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import time

import numpy as np

import coopsim as cs
from coopsim import view
from coopsim.tasks import scene as task_scene

from bench_view import trajectory   # the same cubics through the joint ranges


def task_sim(t_end=60.0, log_every=25, log_contacts=False):
    bars = [task_scene.bar_pose(0.95, 0.30 + 0.07 * k) for k in range(3)]
    sim = cs.Simulation(dt=2e-4, world=task_scene.world(bars), log_every=log_every, log_contacts=log_contacts)
    for i, r in enumerate(task_scene.scaras()):
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), trajectory(r, t_end, phase=1.7 * i))
    return sim


def per_frame(v, repeats):
    snap, send = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f = v._snapshot()
        t1 = time.perf_counter()
        v._changes += 1          # a new frame for the view (the state stands still here): everything is sent
        v._draw(f)
        t2 = time.perf_counter()
        snap.append(t1 - t0)
        send.append(t2 - t1)
    return 1e3 * statistics.median(snap), 1e3 * statistics.median(send)


def browser_page(url):
    from playwright.sync_api import sync_playwright

    pw = sync_playwright().start()
    b = pw.chromium.launch(executable_path=shutil.which("chromium"),
                           args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
    page = b.new_page(viewport={"width": 1000, "height": 620})
    page.goto(url)
    page.get_by_role("tab", name="Run").wait_for(timeout=120_000)
    return pw, b, page


def page_fps(page, seconds):
    return page.evaluate("""(ms) => new Promise(done => {
        let n = 0; const t0 = performance.now();
        function tick(t) { n++; if (t - t0 < ms) requestAnimationFrame(tick); else done(1000 * n / (t - t0)); }
        requestAnimationFrame(tick); })""", 1000 * seconds)


def long_run(minutes, log_every):
    """The live view paced at 100 % for `minutes` of wall time with every contact point logged."""
    wall_total = 60.0 * minutes
    sim = task_sim(t_end=wall_total + 60.0, log_every=log_every, log_contacts=True)
    v = view.live(sim, start=False, quiet=True, speed=1.0)
    table = []                      # (wall s, seconds per update, rows read)
    text = v._table_text

    def timed():
        t0 = time.perf_counter()
        out = text()
        table.append((t0, time.perf_counter() - t0, v.table_rows_read))
        return out
    v._table_text = timed           # what the view's drawing calls every 0.5 s
    print(f"long run: {sim.robot_count} robots in the task's world, every contact point logged, log every "
          f"{log_every} steps ({log_every * sim.dt * 1e3:.0f} ms), paced at 100 % for {minutes:g} min of wall time")
    samples = []                    # (wall s, simulated s) of the frames drawn
    loads = []                      # the machine's load average (1 min) at the end of each minute
    start = time.perf_counter()
    v.start()
    while time.perf_counter() - start < wall_total:
        time.sleep(0.25)
        f = v.frame
        if f is not None:
            samples.append((time.perf_counter() - start, f.t))
        if time.perf_counter() - start >= 60.0 * (len(loads) + 1):
            loads.append(os.getloadavg()[0])
    w = np.array(samples)

    def speeds(window):
        out = []
        for k in range(int(round(wall_total / window))):
            a, b = np.searchsorted(w[:, 0], [k * window, (k + 1) * window])
            b = min(b, len(w) - 1)
            if b > a:
                out.append(100 * (w[b, 1] - w[a, 1]) / (w[b, 0] - w[a, 0]))
        return out
    per30, per60 = speeds(30.0), speeds(60.0)
    print("speed achieved per 30 s:  " + " ".join(f"{x:.1f}" for x in per30) + " %")
    print("speed achieved per min:   " + " ".join(f"{x:.1f}" for x in per60) + " %")
    print(f"machine's load average:   " + " ".join(f"{x:.1f}" for x in loads) + f" (1 min, at each minute's end; "
          f"{os.cpu_count()} cores)")
    worst = min(per30) if per30 else float("nan")
    print(f"whole run:                {100 * (w[-1, 1] - w[0, 1]) / (w[-1, 0] - w[0, 0]):.1f} % "
          f"(slowest 30 s {worst:.1f} %: {'within' if abs(worst - 100) <= 5 else 'NOT within'} 5 % of the set 100 %)")
    tab = np.array(table)
    for k in range(int(round(wall_total / 60.0))):
        m = (tab[:, 0] - start >= 60 * k) & (tab[:, 0] - start < 60 * (k + 1))
        if m.any():
            print(f"table update, minute {k + 1}:   median {1e3 * np.median(tab[m, 1]):.3f} ms, max "
                  f"{1e3 * tab[m, 1].max():.3f} ms over {m.sum()} updates, at most {int(tab[m, 2].max())} rows read")
    rows = v.call(lambda: sim.log_rows)
    t0 = time.perf_counter()
    v.call(lambda: sim.log)
    rebuild = time.perf_counter() - t0
    print(f"at the end: {rows} rows, t = {sim.time:.1f} s; one rebuild of the whole log (Simulation.log with the "
          f"contact points, as the table did before) {rebuild:.2f} s")
    for kind in ("csv", "xlsx"):
        t0 = time.perf_counter()
        v.download(kind)
        while v.download_state not in ("sent", "failed"):
            time.sleep(0.01)
        took = time.perf_counter() - t0
        print(f"download {kind:4s} (the run going on): {took:.2f} s from request to sent: {v.download_text}")
    v.close()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats, shorter runs (with --frames)")
    ap.add_argument("--frames", action="store_true", help="the per-frame figures instead of the long run")
    ap.add_argument("--minutes", type=float, default=5.0, help="wall time of the long run (default 5)")
    ap.add_argument("--log-every", type=int, default=200, help="steps between log rows in the long run "
                    "(default 200: 40 ms, a 20 MB CSV after 5 minutes)")
    args = ap.parse_args()
    if not args.frames:
        if args.minutes <= 0 or args.log_every < 1:
            ap.error("--minutes must be > 0 and --log-every >= 1")
        long_run(args.minutes, args.log_every)
        return
    repeats, sim_seconds = (50, 2.0) if args.quick else (200, 6.0)

    sim = task_sim()
    sim.run(0.5, progress=False)
    v = view.live(sim, start=False, quiet=True, collision_boxes=False, contact_lines=True)
    boxes = sum(len(r.boxes) for r in sim.robots)
    parts = sum(len(p) for p in getattr(v, "_parts", []))
    print(f"scene: {sim.robot_count} robots, {boxes} link boxes, {parts} parts drawn, world bodies "
          f"{sim.world.body_names}")
    s0, d0 = per_frame(v, repeats)
    print(f"frame without a page:      snapshot {s0:.3f} ms + send {d0:.3f} ms = {s0 + d0:.3f} ms")
    have_browser = shutil.which("chromium") is not None
    pw = b = page = None
    if have_browser:
        pw, b, page = browser_page(v.url)
        s1, d1 = per_frame(v, repeats)
        print(f"frame with a page:         snapshot {s1:.3f} ms + send {d1:.3f} ms = {s1 + d1:.3f} ms")
    v.close()
    if page is not None:
        b.close()
        pw.stop()

    # the real-time factor at 400 % with and without the view
    sim = task_sim()
    t0 = sim.time
    stats = sim.run_paced(t0 + sim_seconds, speed=4.0, frame_rate=40.0)
    rtf_alone = stats.real_time_factor
    print(f"paced 400 %, no view:      real-time factor {rtf_alone:.3f} ({stats.frames} frames, "
          f"{stats.steps_per_second:,.0f} steps/s while stepping)")
    sim = task_sim()
    v = view.live(sim, start=False, quiet=True, speed=4.0, resettable=False)
    if have_browser:
        pw, b, page = browser_page(v.url)
    # the run in this thread, the page only drawing meanwhile (Playwright's calls from a second thread would
    # compete with the run for the interpreter)
    w0 = time.perf_counter()
    v.run_to(sim_seconds)
    wall = time.perf_counter() - w0
    rtf_view = sim_seconds / wall
    print(f"paced 400 %, view + page:  real-time factor {rtf_view:.3f} "
          f"({v.frames} frames sent, {v.frames / wall:.1f} per second)")
    print(f"ratio view / no view:      {rtf_view / rtf_alone:.3f}")
    if page is not None:
        # the page's own drawing rate while the view runs on in its thread
        v.start(sim.time + sim_seconds)
        time.sleep(0.5)
        print(f"page in headless Chromium: {page_fps(page, 2.0):.1f} frames per second drawn (software WebGL), "
              f"the view sending {v.stats.get('fps', 0.0):.1f} per second")
    v.close()
    if page is not None:
        b.close()
        pw.stop()
    sim = task_sim()
    w0 = time.perf_counter()
    sim.run(sim_seconds, progress=False)
    w = time.perf_counter() - w0
    print(f"headless, unpaced:         {sim_seconds / w:.1f}x real time")


if __name__ == "__main__":
    main()
