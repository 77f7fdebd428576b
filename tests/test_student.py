"""What a student trips over: each fix shown."""
from __future__ import annotations

import numpy as np

import coopsim as cs


def test_the_readme_round_trip_gives_back_the_accelerations():
    # the README's first block: the same wrench in eq. (1) and eq. (2)
    r = cs.robots.scara1(L1=0.32)
    q, qd = np.zeros(6), np.zeros(6)
    F = np.array([0, 0, -5.0, 0, 0, 0])
    tau = r.inverse_dynamics(q, qd, np.ones(6), f_ext=F)
    np.testing.assert_allclose(r.forward_dynamics(q, qd, tau, f_ext=F), np.ones(6), rtol=1e-12)
    assert not np.allclose(r.forward_dynamics(q, qd, tau), np.ones(6))  # what tripped the student
    with open(__file__.replace("tests/test_student.py", "README.md"), encoding="utf-8") as f:
        assert "qdd = r.forward_dynamics(q, qd, tau, f_ext=F)" in f.read()


def test_a_frame_callback_gets_the_simulation_and_its_pacer_and_sim_t_exists():
    r = cs.robots.scara1()
    sim = cs.Simulation()
    sim.add_robot(r, cs.PID(50.0, 0.0, 5.0), np.full(6, 0.02))
    seen = []

    def on_frame(s, pacer):
        seen.append((s.t, s.time, pacer.speed))
        return len(seen) < 3

    clock = iter(np.arange(0.0, 10.0, 0.01))
    pacer = cs.Pacer(speed=1.0, frame_rate=100.0, clock=lambda: next(clock), sleep=lambda s: None)
    sim.run_paced(1.0, on_frame=on_frame, pacer=pacer)
    assert len(seen) == 3 and all(a == b for a, b, _ in seen) and seen[-1][0] > 0


def test_the_pid_says_it_compensates_gravity():
    assert "gravity_compensation=True" in repr(cs.PID(1.0, 0.0, 0.1))
    assert "gravity_compensation=False" in repr(cs.PID(1.0, 0.0, 0.1, gravity_compensation=False))
    r = cs.robots.scara1()
    sim = cs.Simulation()
    q = np.full(6, 0.02)
    sim.add_robot(r, cs.PID(0.0, 0.0, 0.0), q)
    sim.step(1)
    np.testing.assert_allclose(sim.log.tau[0], np.clip(r.gravity(q), -r.tau_limits, r.tau_limits), rtol=1e-12)


def test_an_output_folder_is_made_for_the_log(tmp_path):
    sim = cs.Simulation()
    sim.add_robot(cs.robots.scara1(), cs.PID(50.0, 0.0, 5.0), np.full(6, 0.02))
    log = sim.run(0.01, progress=False)
    path = log.to_csv(tmp_path / "out" / "run.csv")
    assert cs.SimulationLog.read_csv(path).t.shape == log.t.shape


def test_what_the_package_says_of_the_task_is_there():
    import importlib
    import os

    assert ":mod:`coopsim.tasks.handover`" in cs.__doc__
    assert callable(importlib.import_module("coopsim.tasks.handover").run)
    # no file of the project points to design notes that are not part of it
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    notes = ("shared/design", "task.md", "world.md", "robots.md", "performance.md", "architecture.md")
    for top in ("python", "notebooks", "benchmarks", "examples", "scripts", "docs", "README.md", "CHANGELOG.md"):
        for folder, _, files in os.walk(os.path.join(repo, top)) if not top.endswith(".md") else [(repo, [], [top])]:
            for name in files:
                if name.endswith((".py", ".pyi", ".ipynb", ".md", ".sh")):
                    with open(os.path.join(folder, name), encoding="utf-8") as f:
                        text = f.read()
                    assert not [n for n in notes if n in text], os.path.join(folder, name)


def test_planning_errors_name_the_argument_and_what_is_wrong():
    import pytest

    r = cs.robots.scara2()
    with pytest.raises(ValueError, match=r"position must be finite \(got \[nan, 0.0, 0.2\]\)"):
        cs.clamp_pose(r, [np.nan, 0, 0.2])
    with pytest.raises(ValueError, match=r"wrong shape for position"):
        cs.clamp_pose(r, [0, 0.2])
    with pytest.raises(ValueError, match=r"wrong shape for poses\[1\]: expected \(4, 4\), got \(3, 3\)"):
        cs.plan_cartesian(r, [np.eye(4), np.eye(3)], [0, 1])


def test_a_step_too_large_for_the_end_stops_is_warned_about_and_named_in_the_error():
    import pytest

    arm = cs.robots.scara1()
    q0 = np.array([0.3, 0.5, 0.24, 0.2, 1.0, 0.02])  # the quill near its lower stop
    with pytest.warns(RuntimeWarning, match=r"omega \* dt = 2.5 at dt = 0.005 s.*use dt <= 0.002 s"):
        cs.integrate(arm, q0, np.zeros(6), np.zeros(6), dt=5e-3, steps=10)
    with pytest.warns(RuntimeWarning, match="end stops"):
        cs.rk4_step(arm, q0, np.zeros(6), np.zeros(6), dt=5e-3)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cs.integrate(arm, q0, np.zeros(6), np.zeros(6), dt=1e-3, steps=10)  # omega dt = 0.5: quiet
        cs.integrate(arm, q0, np.zeros(6), np.zeros(6), dt=5e-3, steps=10, end_stops=False)  # no stops: quiet
    sim = cs.Simulation(dt=5e-3)
    with pytest.warns(RuntimeWarning, match="end stops"):
        sim.add_robot(arm, cs.PID(0.0, 0.0, 0.0), q0)


def test_a_numeric_cartesian_plan_keeps_its_branch_or_refuses_the_flip():
    # issue: plan_cartesian(..., method="numeric") flipped the elbow mid-line and the tool drew a loop.
    # Random lines of SCARA #1: every plan that succeeds moves its arm joints in small steps between knots;
    # where the line leaves the first knot's branch, the plan refuses, naming the pose and why
    import pytest

    r = cs.robots.scara1()
    rng = np.random.default_rng(1)
    refused = planned = 0
    for trial in range(30):
        q0, q1 = rng.uniform(r.q_limits[:, 0], r.q_limits[:, 1], (2, 6))
        q0[4] = q1[4] = np.pi / 2
        A, B = r.fk(q0), r.fk(q1)
        B[:3, :3] = A[:3, :3]
        try:
            _, info = cs.plan_cartesian(r, [A, B], [0, 1], method="numeric", intermediate=10, q_start=q0, info=True)
        except cs.IKError as e:
            refused += "to keep its branch" in str(e)
            continue
        planned += 1
        assert np.abs(np.diff(info["q_points"][:, :2], axis=0)).max() < 1.0
        assert trial != 4, "trial 4 leaves its branch mid-line: it must be refused"
    assert planned >= 10 and refused >= 4
    # the flip itself, on request: trial 4 again with keep_branch=False jumps by more than 4 rad in theta2
    rng = np.random.default_rng(1)
    for trial in range(5):
        q0, q1 = rng.uniform(r.q_limits[:, 0], r.q_limits[:, 1], (2, 6))
    q0[4] = q1[4] = np.pi / 2
    A, B = r.fk(q0), r.fk(q1)
    B[:3, :3] = A[:3, :3]
    with pytest.raises(cs.IKError, match=r"the straight-line pose at t = .* s: .*to keep its branch"):
        cs.plan_cartesian(r, [A, B], [0, 1], method="numeric", intermediate=10, q_start=q0)
    _, info = cs.plan_cartesian(r, [A, B], [0, 1], method="numeric", intermediate=10, q_start=q0, info=True,
                                keep_branch=False)
    assert np.abs(np.diff(info["q_points"][:, 1])).max() > 4.0


def test_a_time_law_along_a_cartesian_line_gives_the_tool_a_smooth_speed():
    # issue: along a straight line with evenly spaced knots the tool's speed overshoots at the ends.
    # With time_law='cubic' or 'quintic' the tool's speed follows L s'(tau) / T within 1 % of its peak
    import pytest

    r = cs.robots.scara1()
    q0 = np.array([0.3, 1.2, 0.1, 0.0, np.pi / 2, 0.02])
    A, B = r.fk(q0), r.fk(q0 + [0.5, 0.3, 0.05, 0, 0, 0])
    B[:3, :3] = A[:3, :3]
    L, T = np.linalg.norm(B[:3, 3] - A[:3, 3]), 2.0
    t = np.linspace(0.0, T, 2001)
    tau = t / T
    laws = {"uniform": np.full_like(t, L / T), "cubic": L / T * 6 * tau * (1 - tau),
            "quintic": L / T * 30 * tau ** 2 * (1 - tau) ** 2}
    for law, want in laws.items():
        traj = cs.plan_cartesian(r, [A, B], [0.0, T], intermediate=20, time_law=law, q_start=q0)
        P = np.array([r.fk(traj.evaluate(x)[0])[:3, 3] for x in t])
        v = np.linalg.norm(np.gradient(P, t, axis=0), axis=1)
        if law == "uniform":
            assert v.max() > 1.3 * want.max()          # the overshoot of evenly spaced knots from rest
        else:
            assert np.abs(v - want).max() < 0.01 * want.max(), law
        np.testing.assert_allclose(r.fk(traj.evaluate(T)[0]), B, atol=1e-9)
    with pytest.raises(ValueError, match="time_law must be one of 'uniform', 'cubic', 'quintic', got 'trapezoid'"):
        cs.plan_cartesian(r, [A, B], [0.0, T], time_law="trapezoid")
