"""A long run: 10^7 steps of both SCARAs in the task's world, SCARA #2 holding a bar and swinging it,
SCARA #1 moving on its own: memory flat, the grasp held within its slip limit, every state finite."""
from __future__ import annotations

import os

import numpy as np
import pytest

import coopsim as cs
from coopsim.tasks import handover as H

#: 10^7 steps; against the engine built with sanitizers (scripts/test_sanitized.sh), where a step
#: costs several times as much, 2 10^5: the same code instrumented (the length is the plain build's test)
STEPS = 200_000 if cs.build_info()["sanitizers"] else 10_000_000


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def swing(q_a, q_b, t0, period, cycles):
    """A reference going from q_a to q_b and back, `cycles` times, starting at t0 (s)."""
    from coopsim import CubicTrajectory

    times = t0 + np.arange(2 * cycles + 1) * period / 2
    points = np.array([q_a if k % 2 == 0 else q_b for k in range(2 * cycles + 1)])
    return CubicTrajectory(times, points)


@pytest.mark.slow
def test_ten_million_steps_with_a_held_bar_keep_memory_flat_and_the_grasp():
    R = H._Runner(H.default_bars(1), dt=2e-4, log_every=0, world_every=5, control_every=5, mouth=None, slope=None,
                  handover_yaw=None, t_limit=1e9)
    sim, name = R.sim, "bar"
    R.step = "pick"
    bar, G = R.pick_grip(sim.body_state(name).pose)
    R.run_to(R.move_joints(1, [R._ik(1, R._above(bar, G), H.OPEN)], [1.5]))
    R.run_to(R.move_line(1, [bar @ G], [0.6], H.OPEN))
    R.close(1)
    R.wait_grasp(1, name)
    up = R.r2.fk(R.q_ref(1))
    up[2, 3] += 0.08
    R.run_to(R.move_line(1, [up], [0.6], H.SQUEEZE))
    assert sim.holding(1) == name
    # from here on: #2 swings the bar, #1 swings its arm, for the rest of 10^7 steps
    t0 = sim.time
    total = STEPS * sim.dt
    q2, q1 = R.q_ref(1), R.q_ref(0)
    sim.set_reference(1, swing(q2, q2 + [0.25, -0.2, -0.2, -0.03, 0.5, 0.0], t0, 2.0, int(total / 2) + 2))
    sim.set_reference(0, swing(q1, q1 + [0.3, -0.3, -0.05, 0.6, -0.3, 0.0], t0, 3.0, int(total / 3) + 2))
    sim.run(t0 + 20.0, progress=False)                 # warm up: every buffer at its working size
    grasps = len(sim.log.grasps)
    X = np.linalg.solve(R.r2.fk(sim.state(1)[0]), sim.body_state(name).pose)   # the bar in #2's tool frame
    before = rss_bytes()
    sim.step(STEPS - sim.steps)
    after = rss_bytes()
    assert sim.steps == STEPS
    assert after - before < 8 * 2 ** 20, (before, after)     # flat: under 8 MB over 10^7 steps
    assert sim.holding(1) == name and len(sim.log.grasps) == grasps   # never slipped nor let go
    for i in range(2):
        q, qd = sim.state(i)
        assert np.all(np.isfinite(q)) and np.all(np.isfinite(qd))
    assert np.all(np.isfinite(sim.body_state(name).pose))
    # the bar stayed where the weld holds it: within the grasp's slip limit (5 mm) of where it sat in the clamp
    drift = sim.body_state(name).pose[:3, 3] - (R.r2.fk(sim.state(1)[0]) @ X)[:3, 3]
    assert np.linalg.norm(drift) < 5e-3
