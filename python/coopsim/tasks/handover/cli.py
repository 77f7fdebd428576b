"""The cooperative task (paper section 11.5, Figs. 17-18): two SCARAs hand a bar over and drop it into an
inclined container.

The command line, ``python -m coopsim.tasks.handover`` (``--help`` for the options): runs the task, writes
its report, data, plots, video and browser replay, and prints the summary.
"""
from __future__ import annotations

import argparse
import math
import os
import time

from ... import view
from ...view.animation import MAX_SPEED
from .constants import MAX_CYCLES
from .report import FIGURE_FORMATS, plot_report, step_markers, summary, write_report
from .runs import sweep
from .sequence import run


def parser() -> argparse.ArgumentParser:
    """The command line's parser (its checks of the values are in :func:`parse_args`)."""
    ap = argparse.ArgumentParser(prog="python -m coopsim.tasks.handover", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out", help="folder for the outputs (default out/; made if missing)")
    ap.add_argument("--cycles", type=int, default=None,
                    help=f"bars moved, one per cycle, 1 .. {MAX_CYCLES} (default {MAX_CYCLES}; the container takes "
                         f"{MAX_CYCLES})")
    ap.add_argument("--seed", type=int, default=None,
                    help="one bar drawn from the stated region with this seed (>= 0): one cycle")
    ap.add_argument("--sweep", type=int, default=0, metavar="N",
                    help="also run seeds 0 .. N-1 and print a row per seed and the rate")
    ap.add_argument("--threads", type=int, default=2, help="threads for the sweep (>= 1, default 2)")
    ap.add_argument("--no-video", action="store_true", help="skip the animation (MP4) and the browser replay")
    ap.add_argument("--format", default="png", choices=FIGURE_FORMATS,
                    help="the figures' file format (default png; svg and pdf are vector graphics)")
    ap.add_argument("--speed", type=float, default=None,
                    help=f"simulated seconds per wall second, > 0 and <= {MAX_SPEED:g}: the video's (default 2) and, "
                         f"with --live, the page's, the run starting at once (1 = 100 %%)")
    ap.add_argument("--live", action="store_true",
                    help="run in a live page in the browser (coopsim.view.live, 127.0.0.1): it waits paused at t = 0 "
                         "for its Start (or starts at once at --speed); after the run it shows the summary and keeps "
                         "serving (downloads, Reset runs the task again) until Ctrl-C or the page is closed (--hold s)")
    ap.add_argument("--port", type=int, default=0, help="--live: the page's port (default any free one)")
    ap.add_argument("--hold", type=float, default=None,
                    help="--live: seconds the page stays after the run (default: until Ctrl-C or the page closed in a "
                         "terminal, else 0)")
    return ap


def parse_args(argv=None) -> argparse.Namespace:
    """The arguments, every one checked before anything runs: a bad one is argparse's one-line error (exit 2).
    `cycles` comes back as the number of cycles the run makes (1 with a seed)."""
    ap = parser()
    args = ap.parse_args(argv)
    if args.seed is not None:
        if args.seed < 0:
            ap.error(f"argument --seed: must be >= 0, got {args.seed}")
        if args.cycles not in (None, 1):
            ap.error(f"argument --cycles: --seed draws one bar, so one cycle; got --cycles {args.cycles} "
                     f"(leave out --seed for {args.cycles} lined-up bars)")
        args.cycles = 1
    elif args.cycles is None:
        args.cycles = MAX_CYCLES
    if not 1 <= args.cycles <= MAX_CYCLES:
        ap.error(f"argument --cycles: must be 1 .. {MAX_CYCLES} (the container takes {MAX_CYCLES} bars: the ones "
                 f"that slid out pile up at its lower mouth and the next stays in the tube), got {args.cycles}")
    if args.sweep < 0:
        ap.error(f"argument --sweep: must be >= 0, got {args.sweep}")
    if args.threads < 1:
        ap.error(f"argument --threads: must be >= 1, got {args.threads}")
    if args.speed is not None and not (0.0 < args.speed <= MAX_SPEED):   # also NaN
        ap.error(f"argument --speed: must be > 0 and <= {MAX_SPEED:g} (400 %), got {args.speed:g}")
    check_out_folder(ap, args.out)
    if not 0 <= args.port <= 65535:
        ap.error(f"argument --port: must be 0 (any free port) .. 65535, got {args.port}")
    if args.hold is not None and not (args.hold >= 0 and math.isfinite(args.hold)):
        ap.error(f"argument --hold: must be a finite number of seconds >= 0, got {args.hold:g}")
    return args


def check_out_folder(ap: argparse.ArgumentParser, out: str) -> None:
    """--out: a folder, made if missing, writable; else the parser's one-line error (exit 2)."""
    if os.path.exists(out) and not os.path.isdir(out):
        ap.error(f"argument --out: {out!r} exists and is not a folder")
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as e:
        ap.error(f"argument --out: cannot make the folder {out!r}: {e.strerror}")
    if not os.access(out, os.W_OK | os.X_OK):
        ap.error(f"argument --out: the folder {out!r} is not writable")


def sweep_table(sw: dict) -> str:
    """The sweep's rows, one per seed: the bar's start, the outcome, the simulated time and a failure's step
    and reason."""
    lines = [f"{'seed':>5} {'x (m)':>7} {'y (m)':>7} {'yaw (deg)':>9}  {'result':<7} {'t (s)':>6}  failure"]
    for r in sw["runs"]:
        x, y, yaw = r["bar"]
        why = "" if r["success"] else f"{r['step']}: {r['reason']}"
        lines.append(f"{r['seed']:>5} {x:>7.3f} {y:>7.3f} {math.degrees(yaw):>9.1f}  "
                     f"{'success' if r['success'] else 'FAILED':<7} {r['simulated_time']:>6.2f}  {why}")
    return "\n".join(lines)


INTERRUPTED = 130   # the exit status of a run stopped by Ctrl-C (128 + SIGINT), as a shell reports it


def main(argv=None) -> int:
    """``python -m coopsim.tasks.handover``: runs the task, writes its outputs, prints the summary. Ctrl-C
    during the run writes the log and a report marked interrupted (one line, no traceback, exit 130); during
    the outputs it stops them with one line; while the live page is held it closes the page."""
    args = parse_args(argv)
    live = None
    if args.live:
        live = dict(port=args.port, speed=args.speed, paused=False) if args.speed is not None else \
            dict(port=args.port, paused=True)
    try:
        res = run(seed=args.seed, live=live, on_interrupt="report") if args.seed is not None else \
            run(cycles=args.cycles, live=live, on_interrupt="report")
    except KeyboardInterrupt:      # before the run began (planning, the page's set-up)
        print("interrupted (Ctrl-C) before the run began: nothing written", flush=True)
        return INTERRUPTED
    try:
        if res.report.get("interrupted"):
            return _interrupted(args, res)
        if res.live is not None:
            res.live.say(f"The run is over: writing its outputs to {args.out} (the page answers when they are "
                         f"written)")
        try:
            return _outputs(args, res)
        except KeyboardInterrupt:
            print("interrupted (Ctrl-C) while writing the outputs: the files written so far are in "
                  f"{args.out}", flush=True)
            return INTERRUPTED
    finally:
        if res.live is not None:
            if res.report.get("interrupted"):
                res.live.close()           # Ctrl-C ends the session
            else:
                res.live.say(f"The run is over and its outputs are in {args.out}: the page stays until Ctrl-C in "
                             f"the terminal or every page is closed")
                res.live.hold(args.hold)


def _interrupted(args, res) -> int:
    """A run stopped by Ctrl-C: its report (marked interrupted) and its log, in one line."""
    rep = res.report
    rep["command_line"] = _command_line(args)
    paths = [write_report(rep, os.path.join(args.out, "report.json"), arguments=vars(args)),
             res.log.to_csv(os.path.join(args.out, "task.csv"))]
    step = rep["cycles"][-1]["failed_step"] if rep["cycles"] else "start"
    print(f"interrupted (Ctrl-C) at t = {rep['simulated_time']:.3f} s in {step}: wrote {', '.join(paths)}", flush=True)
    return INTERRUPTED


def _command_line(args) -> dict:
    # speed: the video's (and with --live the page's) as used, the default 2 when not given
    return dict(cycles=args.cycles, seed=args.seed, sweep=args.sweep, threads=args.threads, video=not args.no_video,
                speed=2.0 if args.speed is None else args.speed, live=args.live, out=args.out, format=args.format)


def _outputs(args, res) -> int:
    rep, wall = res.report, res.timing["run"]
    # what was asked for: the run's own inputs are in the report already (seed, cycles_planned, ...)
    rep["command_line"] = _command_line(args)
    print(summary(rep))
    print(f"simulated {rep['simulated_time']:.2f} s in {wall:.2f} s of wall time: {rep['simulated_time'] / wall:.1f}x "
          f"real time (scoring {res.timing['scoring']:.2f} s more)")
    paths = [write_report(rep, os.path.join(args.out, "report.json"), arguments=vars(args)),
             res.log.to_csv(os.path.join(args.out, "task.csv")),
             res.log.to_excel(os.path.join(args.out, "task.xlsx"))]
    paths += plot_report(res, args.out, args.format)
    if not args.no_video:
        paths.append(view.replay_html(res.sim, os.path.join(args.out, "task_replay.html"),
                                      title="coopsim: the cooperative bar handover", markers=step_markers(rep)))
        anim = view.animate(res.sim, speed=2.0 if args.speed is None else args.speed, fps=20, path=os.path.join(args.out, "task.mp4"), inset=True)
        paths.append(anim.path)
    if args.sweep:
        t1 = time.perf_counter()
        sw = sweep(range(args.sweep), threads=args.threads)
        print(f"sweep of {args.sweep} seeds in {time.perf_counter() - t1:.1f} s:")
        print(sweep_table(sw))
        print(f"success rate {sw['success_rate'] * 100:.0f} % ({len(sw['runs']) - len(sw['failures'])} of "
              f"{len(sw['runs'])})")
        paths.append(write_report(sw, os.path.join(args.out, "sweep.json"), arguments=vars(args),
                                  seed=list(range(args.sweep))))
    print("wrote " + ", ".join(paths))
    return 0 if rep["success"] else 1
