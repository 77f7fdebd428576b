"""The dual carry: both SCARAs carry one bar from two stands to two others.

The command line, ``python -m coopsim.tasks.carry`` (``--help`` for the options): runs the carry, writes its
report (JSON and text), figures and animation, and prints the summary and the real-time factor.
"""
from __future__ import annotations

import argparse
import ast
import math
import os
import time

import numpy as np

from ...view.animation import MAX_SPEED
from ..handover.cli import check_out_folder
from .controllers import CONTROLLERS, controller_factory, load_callable
from .pairs import PAIRS
from .disturbances import DISTURBANCES, disturbances
from .report import (FIGURE_FORMATS, SERIES_FORMATS, parquet_missing, summary, sweep_series_table, write_outputs,
                     write_report, write_table)
from .runs import sweep_table
from .sequence import check_controllers, run
from .statistics import format_statistics, sweep_statistics


def parser() -> argparse.ArgumentParser:
    """The command line's parser (its checks of the values are in :func:`parse_args`)."""
    ap = argparse.ArgumentParser(prog="python -m coopsim.tasks.carry", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out/carry", help="folder for the outputs (default out/carry; made if missing)")
    ap.add_argument("--robots", default="scara",
                    help=f"the pair of arms: one of {', '.join(PAIRS)} (default scara, the two SCARAs; ur5: two UR5s "
                         f"with clamps facing each other; panda: two 7-dof Pandas), or a factory of one's own as "
                         f"module:factory or path/to/file.py:factory returning the two clamped robots and their "
                         f"bases")
    ap.add_argument("--seed", type=int, default=None,
                    help="shift and turn the start stands by a seeded draw (>= 0; default: the planned start)")
    ap.add_argument("--disturbance", action="append", default=None, metavar="NAME",
                    help=f"one of {', '.join(DISTURBANCES)}; repeat it or join names with commas to combine them")
    ap.add_argument("--controller", default="ct",
                    help=f"one of {', '.join(CONTROLLERS)} (default ct, the baseline: independent computed torque), "
                         f"or a factory of one's own as module:factory (a module on sys.path) or "
                         f"path/to/file.py:factory, called as the named ones: factory(robots, plan, **options)")
    ap.add_argument("--controller-option", action="append", default=None, metavar="KEY=VALUE",
                    help="a keyword for the controllers' factories (repeat it): the value a Python literal (0.3, "
                         "(5000.0, 20.0), True, None) or else a string; CONTROLLER:KEY=VALUE gives it to that "
                         "controller only (of --controller or --sweep-controllers), KEY=VALUE to every one; each "
                         "checked against the factory's options before anything runs")
    ap.add_argument("--mass-factor", type=float, default=None, metavar="F",
                    help="the bar's mass in the controllers' models over the world's (> 0; as the mass disturbances, "
                         "which it excludes)")
    ap.add_argument("--sweep", type=int, default=0, metavar="N",
                    help="also sweep seeds 0 .. N-1 for every controller of --sweep-controllers and disturbance of "
                         "--sweep-disturbances (threads: --threads), print each score's mean, standard deviation and "
                         "95 %% confidence interval and the success rate with its Wilson interval, and write "
                         "sweep.csv, sweep_statistics.csv and sweep.json")
    ap.add_argument("--sweep-only", action="store_true",
                    help="with --sweep: only the sweep, not the run of --controller first (no figures, no video)")
    ap.add_argument("--sweep-controllers", default=None, metavar="A,B",
                    help="the sweep's controllers, joined by commas (default: --controller)")
    ap.add_argument("--sweep-disturbances", default=None, metavar="A,B",
                    help="the sweep's disturbances, one per run, joined by commas (default: the run's --disturbance, "
                         "combined)")
    ap.add_argument("--threads", type=int, default=2, help="the sweep's threads (>= 1, default 2)")
    ap.add_argument("--format", default="png", choices=FIGURE_FORMATS,
                    help="the figures' file format (default png; svg and pdf are vector graphics)")
    ap.add_argument("--series", default=None, choices=SERIES_FORMATS,
                    help="also write the time series as one table: series.npz or series.parquet (the log, the "
                         "cooperation columns and the carry's own), and with --sweep every run's log and "
                         "cooperation columns in sweep_series.npz or .parquet (npz needs nothing, parquet pyarrow)")
    ap.add_argument("--video", dest="video", action="store_true", default=True, help="write carry.mp4 (default)")
    ap.add_argument("--no-video", dest="video", action="store_false", help="skip the animation")
    ap.add_argument("--speed", type=float, default=1.0,
                    help=f"simulated seconds per video second, > 0 and <= {MAX_SPEED:g} (default 1)")
    return ap


def parse_args(argv=None) -> argparse.Namespace:
    """The arguments, every one checked before anything runs: a bad one is argparse's one-line error (exit 2).
    `disturbance` comes back as the list of names."""
    ap = parser()
    args = ap.parse_args(argv)
    if args.seed is not None and args.seed < 0:
        ap.error(f"argument --seed: must be >= 0, got {args.seed}")
    names = [n.strip() for item in (args.disturbance or []) for n in item.split(",") if n.strip()]
    try:
        disturbances(names, 0.0)
    except ValueError as e:
        ap.error(f"argument --disturbance: {e}")
    args.disturbance = names
    if args.mass_factor is not None:
        if not (args.mass_factor > 0 and math.isfinite(args.mass_factor)):   # also NaN
            ap.error(f"argument --mass-factor: must be finite and > 0, got {args.mass_factor:g}")
        if any(n.startswith("mass") for n in names):
            ap.error("argument --mass-factor: not with a mass disturbance (both set the bar's mass in the models)")
    if args.robots not in PAIRS:
        if ":" not in args.robots:
            ap.error(f"argument --robots: unknown pair {args.robots!r}: choose from {', '.join(PAIRS)} (or name a "
                     f"factory as module:factory or path/to/file.py:factory)")
        try:
            load_callable(args.robots, "robots", "() -> the two robots and their bases")
        except ValueError as e:
            ap.error(f"argument --robots: {e}")
    try:
        controller_factory(args.controller)      # loads it (made with its options below)
    except ValueError as e:
        ap.error(f"argument --controller: {e}")
    if args.sweep < 0:
        ap.error(f"argument --sweep: must be >= 0, got {args.sweep}")
    if args.sweep_only and not args.sweep:
        ap.error("argument --sweep-only: give --sweep N (the seeds) too")
    if args.threads < 1:
        ap.error(f"argument --threads: must be >= 1, got {args.threads}")
    args.sweep_controllers = _list(args.sweep_controllers) or [args.controller]
    for c in args.sweep_controllers:
        try:
            controller_factory(c)
        except ValueError as e:
            ap.error(f"argument --sweep-controllers: {e}")
    _controller_options(ap, args)
    args.sweep_disturbances = _list(args.sweep_disturbances) or [",".join(names) or "none"]
    for d in args.sweep_disturbances:
        if d not in DISTURBANCES and d != ",".join(names):
            ap.error(f"argument --sweep-disturbances: unknown disturbance {d!r}: choose from {', '.join(DISTURBANCES)}")
    if args.mass_factor is not None and any(d.startswith("mass") for d in args.sweep_disturbances):
        ap.error("argument --mass-factor: not with a mass disturbance in the sweep")
    if not (0.0 < args.speed <= MAX_SPEED) or not math.isfinite(args.speed):   # also NaN
        ap.error(f"argument --speed: must be > 0 and <= {MAX_SPEED:g}, got {args.speed:g}")
    if args.series == "parquet" and parquet_missing():
        ap.error(f"argument --series: {parquet_missing()}")
    check_out_folder(ap, args.out)
    return args


def _list(text):
    return [x.strip() for x in (text or "").split(",") if x.strip()]


def option_value(text: str):
    """A --controller-option's value: a Python literal (numbers, strings in quotes, tuples and lists, True,
    False, None) when it reads as one, else the text itself (a string)."""
    try:
        return ast.literal_eval(text.strip())
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        return text


def _controller_options(ap, args) -> None:
    """--controller-option into args.controller_options (every controller's: {key: value}) and
    args.options_by_controller ({controller: {key: value}}), each controller checked with its options."""
    common, scoped = {}, {}
    used = [args.controller] + [c for c in args.sweep_controllers if c != args.controller]
    for item in args.controller_option or []:
        key, eq, value = item.partition("=")
        who, _, key = key.strip().rpartition(":")
        if not eq or not key.isidentifier():
            ap.error(f"argument --controller-option: must be KEY=VALUE or CONTROLLER:KEY=VALUE with KEY a keyword "
                     f"(a Python name), got {item!r}")
        if who and who not in used:
            ap.error(f"argument --controller-option: {item!r} names controller {who!r}, which does not run (the "
                     f"controllers: {', '.join(used)})")
        (scoped.setdefault(who, {}) if who else common)[key] = option_value(value)
    for c in used:
        try:
            check_controllers(c, {**common, **scoped.get(c, {})}, robots=args.robots)
        except ValueError as e:
            ap.error(f"argument --controller-option: {e}")
    args.controller_options = common
    args.options_by_controller = scoped


def run_options(args, controller: str) -> dict:
    """The controller options a controller of the command line runs with (the common ones, its own over
    them)."""
    return {**args.controller_options, **args.options_by_controller.get(controller, {})}


#: the scores whose statistics the command line prints per controller and disturbance (sweep_statistics.csv
#: has all of :data:`~.statistics.SCORES`)
SWEEP_SUMMARY = ("bar_error_rms_mm", "bar_error_max_mm", "squeeze_mean_N", "squeeze_peak_N", "internal_force_max_N",
                 "load_share_deviation", "relative_position_max_mm", "wall_time")


def main(argv=None) -> int:
    """``python -m coopsim.tasks.carry``: runs the carry, writes its outputs, prints the summary, and with
    --sweep the sweep's statistics; exit 0 on success, 1 on a failed carry (with --sweep-only: a failed run of
    the sweep)."""
    args = parse_args(argv)
    paths, ok = [], True
    if not args.sweep_only:
        res = run(seed=args.seed, disturbance=args.disturbance, controllers=args.controller, robots=args.robots,
                  controller_options=run_options(args, args.controller), mass_factor=args.mass_factor)
        rep, wall = res.report, res.timing["run"]
        rep["command_line"] = dict(robots=args.robots, seed=args.seed, disturbance=args.disturbance, controller=args.controller,
                                   controller_options=args.controller_options,
                                   options_by_controller=args.options_by_controller, mass_factor=args.mass_factor,
                                   sweep=args.sweep, sweep_controllers=args.sweep_controllers,
                                   sweep_disturbances=args.sweep_disturbances, threads=args.threads,
                                   video=args.video, speed=args.speed, out=args.out, format=args.format,
                                   series=args.series)
        print(summary(rep))
        print(f"simulated {rep['simulated_time']:.2f} s in {wall:.3f} s of wall time: "
              f"{rep['simulated_time'] / wall:.0f}x real time (scoring {res.timing['scoring']:.3f} s more)")
        paths += write_outputs(res, args.out, video=args.video, speed=args.speed, fmt=args.format,
                               series=args.series, arguments=vars(args))
        ok = bool(rep["success"])
    if args.sweep:
        paths += _sweep(args)
        ok = ok and (not args.sweep_only or _sweep.all_succeeded)
    print("wrote " + ", ".join(paths))
    return 0 if ok else 1


def _sweep(args) -> list:
    """The sweep of the command line: runs it, prints its statistics and failures, writes sweep.csv,
    sweep_statistics.csv, sweep.json and with --series sweep_series.*; returns the paths."""
    t1 = time.perf_counter()
    table = sweep_table(args.sweep_controllers, args.sweep_disturbances, range(args.sweep), threads=args.threads,
                        mass_factor=args.mass_factor, controller_options=args.controller_options or None,
                        robots=args.robots,
                        options_by_controller={c: o for c, o in args.options_by_controller.items()
                                               if c in args.sweep_controllers},
                        keep_logs=args.series is not None)
    success = np.array([v is True or (isinstance(v, (bool, np.bool_)) and bool(v)) for v in table.success])
    _sweep.all_succeeded = bool(success.all())
    print(f"sweep of {len(table)} runs ({len(args.sweep_controllers)} controllers x {len(args.sweep_disturbances)} "
          f"disturbances x {args.sweep} seeds) on {args.threads} threads in {time.perf_counter() - t1:.1f} s: "
          f"success rate {success.mean() * 100:.0f} %; per controller and disturbance, mean +- standard deviation "
          f"and 95 % intervals (all scores in sweep_statistics.csv):")
    stats = sweep_statistics(table)
    print(format_statistics(stats[stats.quantity.isin(("success_rate",) + SWEEP_SUMMARY)]))
    for r in table[~success].itertuples():
        print(f"  {r.controller}, {r.disturbance}, seed {r.seed}: FAILED in {r.step}: {r.reason or r.error}")
    paths = []
    if args.series is not None:
        paths.append(write_table(sweep_series_table(table), os.path.join(args.out, "sweep_series." + args.series),
                                 args.series))
        table = table.drop(columns="log")
    p = os.path.join(args.out, "sweep.csv")
    table.to_csv(p)
    paths.append(p)
    p = os.path.join(args.out, "sweep_statistics.csv")
    stats.to_csv(p, index=False, float_format="%.17g")
    paths.append(p)
    paths.append(write_report(dict(success_rate=float(success.mean()), statistics=stats.to_dict(orient="records"),
                                   runs=table.to_dict(orient="records")),
                              os.path.join(args.out, "sweep.json"), arguments=vars(args), seed=list(range(args.sweep))))
    return paths
