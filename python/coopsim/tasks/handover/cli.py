"""The cooperative task (paper section 11.5, Figs. 17-18): two SCARAs hand a bar over and drop it into an
inclined container.

The command line, ``python -m coopsim.tasks.handover`` (``--help`` for the options): runs the task, writes
its report, data, plots, video and browser replay, and prints the summary.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from ... import view
from .report import plot_report, summary, write_report
from .runs import sweep
from .sequence import run


def main(argv=None) -> int:
    """``python -m coopsim.tasks.handover``: runs the task, writes its outputs, prints the summary."""
    ap = argparse.ArgumentParser(prog="python -m coopsim.tasks.handover", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out", help="folder for the outputs (default out/)")
    ap.add_argument("--cycles", type=int, default=3, help="bars moved, one per cycle (default 3)")
    ap.add_argument("--seed", type=int, default=None, help="one bar drawn from the stated region with this seed")
    ap.add_argument("--sweep", type=int, default=0, metavar="N", help="also run seeds 0 .. N-1 and report the rate")
    ap.add_argument("--threads", type=int, default=2, help="threads for the sweep (default 2)")
    ap.add_argument("--no-video", action="store_true", help="skip the animation (MP4) and the browser replay")
    ap.add_argument("--speed", type=float, default=2.0, help="simulated seconds per video second (default 2)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    res = run(seed=args.seed) if args.seed is not None else run(cycles=args.cycles)
    rep, wall = res.report, res.timing["run"]
    print(summary(rep))
    print(f"simulated {rep['simulated_time']:.2f} s in {wall:.2f} s of wall time: {rep['simulated_time'] / wall:.1f}x "
          f"real time (scoring {res.timing['scoring']:.2f} s more)")
    paths = [write_report(rep, os.path.join(args.out, "report.json")),
             res.log.to_csv(os.path.join(args.out, "task.csv")),
             res.log.to_excel(os.path.join(args.out, "task.xlsx"))]
    paths += plot_report(res, args.out)
    if not args.no_video:
        paths.append(view.replay_html(res.sim, os.path.join(args.out, "task_replay.html"),
                                      title="coopsim: the cooperative bar handover"))
        anim = view.animate(res.sim, speed=args.speed, fps=20, path=os.path.join(args.out, "task.mp4"))
        paths.append(anim.path)
    if args.sweep:
        t1 = time.perf_counter()
        sw = sweep(range(args.sweep), threads=args.threads)
        print(f"sweep of {args.sweep} seeds in {time.perf_counter() - t1:.1f} s: success rate "
              f"{sw['success_rate'] * 100:.0f} %")
        for f in sw["failures"]:
            print(f"  seed {f['seed']} (bar at {np.round(f['bar'], 3).tolist()}): {f['step']}: {f['reason']}")
        paths.append(write_report(sw, os.path.join(args.out, "sweep.json")))
    print("wrote " + ", ".join(paths))
    return 0 if rep["success"] else 1

