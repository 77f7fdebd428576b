"""The cooperative task headless (coopsim.tasks.handover, 3 cycles of the default scene): simulated time,
wall time and real-time factor of the run alone (robots integrated at 5 kHz, controllers and world at 1 kHz;
then the controllers, and the world too, at every 0.2 ms step) and with its scoring, the time per step split into
controllers, world (Bullet, the grasp included), grasp, contact mapping and robots (RK4) from the
simulation's own profiler, and the seeded sweep of 20 bars on 2 threads.

Targets: >= 100x real time for the task with its scoring, three cycles, warm, on one core (the paper ran it at
1x); the sweep of 20 seeds in under a minute. Where a step's instructions go: docs/speed-and-comparisons.md
("The handover's step, profiled"); wall figures need a quiet machine (load below 1).

    python benchmarks/bench_task.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import time

# numpy's OpenBLAS threads spin after each call and take a core from the run being timed
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from coopsim.tasks import handover as H  # noqa: E402

TARGET_RTF = 100.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one cycle, 4 seeds")
    args = ap.parse_args()
    cycles, seeds = (1, 4) if args.quick else (3, 20)
    print(f"{'run':<34}{'simulated s':>12}{'wall s':>9}{'x real time':>13}")
    for label, kw in (("task (control, world at 1 kHz)", dict(score=False)),
                      ("controllers every step (5 kHz)", dict(score=False, control_every=1)),
                      ("controllers and world every step", dict(score=False, control_every=1, world_every=1)),
                      ("task + scoring", dict(score=True))):
        best = None
        for _ in range(3):
            t = time.perf_counter()
            res = H.run(cycles=cycles, **kw)
            w = time.perf_counter() - t
            best = w if best is None else min(best, w)
        assert res.success, H.summary(res.report)
        st = res.report["simulated_time"]
        print(f"{label:<34}{st:>12.2f}{best:>9.3f}{st / best:>12.1f}x")
        if kw.get("score"):
            print(f"target: task + scoring >= {TARGET_RTF:g}x real time: "
                  f"{'met' if st / best >= TARGET_RTF else 'NOT met'} on this machine in this run "
                  f"(load {os.getloadavg()[0]:.2f})")
    # the per-step split, from the engine's profiler in a separate run (the timers cost a little)
    runner = H._Runner(H.default_bars(1), dt=2e-4, log_every=25, world_every=5, control_every=5, mouth=None,
                       slope=None, handover_yaw=None, t_limit=120.0)
    runner.sim.set_profiling(True)
    runner.cycle(0)
    p, n = runner.sim.profile(), runner.sim.steps
    part = lambda k: getattr(p, k) if hasattr(p, k) else p[k]  # noqa: E731  (the profile's fields, or its keys)
    split = ", ".join(f"{k} {part(k) / n * 1e6:.2f}" for k in ("controllers", "world", "grasp", "contacts", "robots"))
    print(f"per step (us), defaults: {split} (grasp within world)")
    t = time.perf_counter()
    sw = H.sweep(range(seeds), threads=2)
    w = time.perf_counter() - t
    print(f"sweep of {seeds} seeds on 2 threads: {w:.1f} s wall, success rate {sw['success_rate'] * 100:.0f} %"
          f" (target: 20 seeds under 60 s)")
    for f in sw["failures"]:
        print(f"  seed {f['seed']}: {f['step']}: {f['reason']}")


if __name__ == "__main__":
    main()
