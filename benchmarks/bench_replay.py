"""Browser replay (coopsim.view.replay_html): time to write a 20 s run of both SCARAs and the file's size.

Both SCARAs of the task's scene (coopsim.tasks.scene: floor, container,
bar) follow cubic trajectories for 20 s under computed torque, logged
every 5 ms. Rows: wall time to write the HTML page (median of repeats)
and its size, at 30 fps (the default) and 60 fps, and the same with the
ghosts off; then, if Debian's chromium and Playwright are installed, the
time for headless Chromium to open the page until it is ready and the
time per seek-and-render.

    python benchmarks/bench_replay.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
import time

import numpy as np

import coopsim as cs
from coopsim import view
from coopsim.tasks import scene
from bench_view import trajectory  # the two SCARAs' sine-like cubics (this folder is on sys.path)

T_END = 20.0


def run(t_end):
    sim = cs.Simulation(dt=2e-4, world=scene.world(), log_every=25)
    for i, r in enumerate(scene.scaras()):
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), trajectory(r, t_end, phase=1.7 * i))
    sim.run(t_end, progress=False)
    return sim


def browser_figures(path, seeks):
    """(s to open until ready, ms per seek with a render) in headless Chromium, or None without it."""
    chromium = shutil.which("chromium")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return None
    if chromium is None:
        return None
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=chromium, args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
        page = b.new_page(viewport={"width": 1000, "height": 700})
        t0 = time.perf_counter()
        page.goto("file://" + os.path.abspath(path))
        page.wait_for_function("window.coopsim && window.coopsim.ready", timeout=60000)
        opened = time.perf_counter() - t0
        ms = page.evaluate("""(n) => { const c = window.coopsim, t = performance.now();
            for (let i = 0; i < n; i++) c.seek(c.t0 + (c.t1 - c.t0) * i / n);
            return (performance.now() - t) / n; }""", seeks)
        b.close()
    return opened, ms


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a 4 s run, one repeat")
    args = ap.parse_args()
    t_end, repeats = (4.0, 1) if args.quick else (T_END, 5)
    t0 = time.perf_counter()
    sim = run(t_end)
    print(f"coopsim.view.replay_html: both SCARAs in the task's scene, {t_end:g} s logged every 5 ms "
          f"({len(sim.log.t)} rows; simulated in {time.perf_counter() - t0:.1f} s); median of {repeats}")
    print(f"{'page':<32} {'frames':>7} {'write (s)':>10} {'size (MB)':>10}")
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "run.html")
        for label, kw in (("30 fps (default)", dict(fps=30)), ("60 fps", dict(fps=60)),
                          ("30 fps, no ghosts", dict(fps=30, reference=False))):
            walls = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                view.replay_html(sim, path, **kw)
                walls.append(time.perf_counter() - t0)
            frames = int(np.floor(t_end * kw["fps"] + 1e-9)) + 1
            print(f"{label:<32} {frames:>7} {statistics.median(walls):>10.3f} {os.path.getsize(path) / 1e6:>10.2f}")
        view.replay_html(sim, path)
        figures = browser_figures(path, seeks=20 if args.quick else 100)
        if figures is None:
            print("headless Chromium: not installed (Debian's chromium and playwright), skipped")
        else:
            print(f"headless Chromium (SwiftShader, 1000 x 700): opens the 30 fps page in {figures[0]:.2f} s, "
                  f"{figures[1]:.1f} ms per seek with a render")


if __name__ == "__main__":
    main()
