"""The dual carry headless (coopsim.tasks.carry, 7.1 s simulated): the real-time factor of the run (planning
included, unscored) and of the run with its scoring under each controller of coopsim.tasks.carry.CONTROLLERS, for
each pair of arms (coopsim.tasks.carry.PAIRS: the two SCARAs, two UR5s, two Pandas, each at its own rates: the
SCARAs' robots at 5 kHz, the UR5s' and Pandas' at 1 kHz, the world and the controllers at 1 kHz for all), with the
CPU time's factor beside the wall time's (on a shared machine the wall time counts the others' load); then a
sweep of every controller x 4 disturbances x 5 seeds on 2 threads with the SCARAs (coopsim.sweep: wall time, runs
per second, the table's means per controller and disturbance).

Targets: >= 50x real time for the SCARAs' run under each controller (the handover's target), >= 25x for the
UR5s' and the Pandas'.

    python benchmarks/bench_carry.py [--quick] [--pairs scara,ur5,panda] [--no-sweep]
"""
from __future__ import annotations

import argparse
import os
import time

# numpy's OpenBLAS threads spin after each call and take a core from the run being timed
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from coopsim.tasks import carry as C  # noqa: E402

TARGET_RTF = {"scara": 50.0, "ur5": 25.0, "panda": 25.0}
DISTURBANCES = ("none", "mass+50", "push", "grip-offset")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one repeat, 2 seeds in the sweep")
    ap.add_argument("--pairs", default=",".join(C.PAIRS), help="the pairs of arms, joined by commas (default all)")
    ap.add_argument("--no-sweep", action="store_true", help="only the runs, no sweep")
    args = ap.parse_args()
    repeats, seeds = (1, 2) if args.quick else (5, 5)
    controllers = list(C.CONTROLLERS)
    pairs = [p.strip() for p in args.pairs.split(",") if p.strip()]
    width = max(len(c) for c in controllers + ["controller"]) + 2
    print(f"{'pair':<7}{'controller':<{width}}{'simulated s':>12}{'run s':>9}{'x real time':>13}{'CPU s':>8}"
          f"{'x real time':>13}{'+ scoring s':>13}{'x real time':>13}")
    for pair in pairs:
        C.pair(pair)                  # the arms read once (their meshes' hulls), outside the timings
        for name in controllers:
            best, best_cpu, best_scored = None, None, None
            for _ in range(repeats):
                t, c = time.perf_counter(), time.process_time()
                res = C.run(robots=pair, controllers=name, score_run=False)
                w, cpu = time.perf_counter() - t, time.process_time() - c
                best = w if best is None else min(best, w)
                best_cpu = cpu if best_cpu is None else min(best_cpu, cpu)
                t = time.perf_counter()
                scored = C.run(robots=pair, controllers=name)
                w = time.perf_counter() - t
                best_scored = w if best_scored is None else min(best_scored, w)
            assert res.success and scored.success, C.summary(scored.report)
            st = res.report["simulated_time"]
            target = TARGET_RTF.get(pair, 25.0)
            flag = "" if st / best >= target else f"  (below the {target:.0f}x target)"
            print(f"{pair:<7}{name:<{width}}{st:>12.2f}{best:>9.3f}{st / best:>12.1f}x{best_cpu:>8.3f}"
                  f"{st / best_cpu:>12.1f}x{best_scored:>13.3f}{st / best_scored:>12.1f}x{flag}", flush=True)
    if args.no_sweep:
        return
    t = time.perf_counter()
    table = C.sweep_table(controllers, DISTURBANCES, range(seeds), threads=2)
    w = time.perf_counter() - t
    n = len(table)
    print(f"sweep of {n} runs ({len(controllers)} controllers x {len(DISTURBANCES)} disturbances x {seeds} seeds), "
          f"scored, on 2 threads: {w:.1f} s wall, {n / w:.1f} runs/s, {table.simulated_time.sum() / w:.0f}x real "
          f"time overall, success rate {table.success.astype(bool).mean() * 100:.0f} %")
    cols = ["success", "bar_error_rms_mm", "squeeze_rms_N", "squeeze_max_N", "internal_force_rms_N",
            "internal_force_max_N", "load_share_deviation", "relative_position_max_mm"]
    print(table.groupby(["controller", "disturbance"], sort=False)[cols].mean().to_string(
        float_format=lambda x: f"{x:.3f}"))
    for r in table[~table.success.astype(bool)].itertuples():
        print(f"  {r.controller}, {r.disturbance}, seed {r.seed}: {r.step}: {r.reason or r.error}")


if __name__ == "__main__":
    main()
