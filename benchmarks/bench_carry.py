"""The dual carry headless (coopsim.tasks.carry, 7.1 s simulated): the real-time factor of the run (planning
included, unscored) and of the run with its scoring under each controller of coopsim.tasks.carry.CONTROLLERS,
then a sweep of every controller x 4 disturbances x 5 seeds on 2 threads (coopsim.sweep: wall time, runs per
second, the table's means per controller and disturbance).

Target: >= 50x real time for the run under each controller (the handover's target).

    python benchmarks/bench_carry.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import time

# numpy's OpenBLAS threads spin after each call and take a core from the run being timed
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from coopsim.tasks import carry as C  # noqa: E402

TARGET_RTF = 50.0
DISTURBANCES = ("none", "mass+50", "push", "grip-offset")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one repeat, 2 seeds in the sweep")
    args = ap.parse_args()
    repeats, seeds = (1, 2) if args.quick else (5, 5)
    controllers = list(C.CONTROLLERS)
    width = max(len(c) for c in controllers + ["controller"]) + 2
    print(f"{'controller':<{width}}{'simulated s':>12}{'run s':>9}{'x real time':>13}{'+ scoring s':>13}{'x real time':>13}")
    for name in controllers:
        best, best_scored = None, None
        for _ in range(repeats):
            t = time.perf_counter()
            res = C.run(controllers=name, score_run=False)
            w = time.perf_counter() - t
            best = w if best is None else min(best, w)
            t = time.perf_counter()
            scored = C.run(controllers=name)
            w = time.perf_counter() - t
            best_scored = w if best_scored is None else min(best_scored, w)
        assert res.success and scored.success, C.summary(scored.report)
        st = res.report["simulated_time"]
        flag = "" if st / best >= TARGET_RTF else f"  (below the {TARGET_RTF:.0f}x target)"
        print(f"{name:<{width}}{st:>12.2f}{best:>9.3f}{st / best:>12.1f}x{best_scored:>13.3f}{st / best_scored:>12.1f}x{flag}")
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
