"""The force/torque sensors' cost per step: the cooperative task (coopsim.tasks.handover, one cycle, its
defaults) with the sensors as they are by default (ideal, nothing configured) and with both robots' sensors
noisy and filtered; and two SCARAs without a world, stepped in C++, sensors off, noisy and filtered, and
noisy with an applied wrench on the clamp (the sensor's kinematics every step). ns per step and the ratio
to the unconfigured run; best of 5.

    python benchmarks/bench_sensors.py
"""
from __future__ import annotations

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402
from coopsim.tasks import handover as H  # noqa: E402

REPEATS = 5
NOISY = dict(noise_force=0.2, noise_moment=0.01, time_constant=0.005, seed=1)


def best(f):
    out = None
    for _ in range(REPEATS):
        t = time.perf_counter()
        steps = f()
        w = (time.perf_counter() - t) / steps
        out = w if out is None else min(out, w)
    return out


def task(sensors: bool):
    runner = H._Runner(H.default_bars(1), dt=2e-4, log_every=25, world_every=5, control_every=5, mouth=None,
                       slope=None, handover_yaw=None, t_limit=120.0)
    if sensors:
        for i in range(runner.sim.robot_count):
            runner.sim.set_sensor(i, **NOISY)
    runner.cycle(0)
    return runner.sim.steps


def free(mode: str, t_end: float = 2.0):
    sim = cs.Simulation(dt=2e-4, log_every=1)
    for r, q in ((cs.robots.scara1(), [0.3, 0.5, 0.15, 0.2, np.pi / 2, 0.03]),
                 (cs.robots.scara2(), [0.3, 0.5, 0.2, 0.15, 0.2, 0.03])):
        i = sim.add_robot(r, cs.ComputedTorque(kp=[100.0] * 6, kd=[20.0] * 6), np.array(q))
        if mode != "off":
            sim.set_sensor(i, **NOISY)
        if mode == "wrench":
            sim.set_applied(i, wrenches=np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0]))
    sim.run(t_end, progress=False)
    return sim.steps


def main():
    rows = [("task, sensors unconfigured", lambda: task(False)), ("task, both sensors noisy + filtered", lambda: task(True)),
            ("2 SCARAs, no world, sensors off", lambda: free("off")),
            ("2 SCARAs, noisy + filtered", lambda: free("noisy")),
            ("2 SCARAs, noisy + filtered + wrench", lambda: free("wrench"))]
    print(f"{'run':<40}{'ns/step':>10}{'ratio':>8}")
    base = {}
    for label, f in rows:
        ns = best(f) * 1e9
        key = label.split(",")[0]
        base.setdefault(key, ns)
        print(f"{label:<40}{ns:>10.0f}{ns / base[key]:>8.3f}")


if __name__ == "__main__":
    main()
