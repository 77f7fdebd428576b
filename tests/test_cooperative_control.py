"""Cooperative control: one controller driving both SCARAs holding one bar (Simulation.add_cooperative):
object-level control with a commanded load share and squeeze, object impedance to a push, leader-follower,
a law written in Python, and bad input."""
from __future__ import annotations

import numpy as np
import pytest

import coopsim as cs

G = 9.81
BAR_HE, BAR_M = np.array([0.175, 0.01, 0.01]), 0.3
CENTRE, YAW = np.array([0.25, -0.15, 0.20]), np.radians(165)


def robots():
    return cs.robots.scara1(L_base=0.52), cs.robots.scara2(L_base=0.38, base_position=(0.75, 0, 0))


def grip_q(r, p, axis, **kw):
    """Joints (n,) putting the clamp's fixed jaw against the bar at point p of its axis, jaws 3 cm open, the
    bar's axis across the jaws, pointing down."""
    for yaw in np.linspace(-np.pi, np.pi, 721):
        T = cs.clamp_pose(r, p, yaw, **kw)
        if abs(T[:3, 0] @ axis) > 0.99999:
            T[:3, 3] = p + (0.015 - BAR_HE[1] - 2e-4) * T[:3, 1]
            return r.ik(T, opening=0.03)
    raise AssertionError("no clamp yaw along the bar")


def held(kp=400.0, kd=40.0, lift=0.03):
    """Both SCARAs close on a 35 cm, 0.3 kg bar 0.1 m either side of its centre (on a thin pedestal) and lift
    it 3 cm under independent computed torque. Returns the simulation (0.8 s run, both holding)."""
    r1, r2 = robots()
    axis = np.array([np.cos(YAW), np.sin(YAW), 0.0])
    q1 = grip_q(r1, CENTRE + 0.1 * axis, axis, pitch=np.pi / 2)
    q2 = grip_q(r2, CENTRE - 0.1 * axis, axis)
    P = np.eye(4)
    P[:3, :3] = [[np.cos(YAW), -np.sin(YAW), 0], [np.sin(YAW), np.cos(YAW), 0], [0, 0, 1]]
    P[:3, 3] = CENTRE
    w = cs.World(gravity=(0, 0, -G))
    w.add_free_box("bar", BAR_HE, BAR_M, P, friction=0.5)
    top = CENTRE[2] - BAR_HE[2]
    ped = np.eye(4)
    ped[:3, 3] = [CENTRE[0], CENTRE[1], top / 2]
    w.add_static_box("pedestal", [0.004, 0.004, top / 2], ped, friction=0.5)
    sim = cs.Simulation(dt=2e-4, world=w, log_every=10)
    for r, q, z in ((r1, q1, 2), (r2, q2, 3)):
        b = q.copy()
        b[5] = 0.019
        d = b.copy()
        d[z] -= lift
        sim.add_robot(r, cs.ComputedTorque(kp, kd), cs.CubicTrajectory([0, 0.02, 0.12, 0.17, 0.47],
                                                                        np.array([q, q, b, b, d])))
    sim.run(0.8, progress=False)
    assert sim.holding(0) == "bar" and sim.holding(1) == "bar"
    for i in (0, 1):
        sim.set_reference(i, cs.SetPoint(sim.state(i)[0]))
    return sim


def bar_inertia():
    return np.asarray(cs.box_inertia(BAR_M, *(2 * BAR_HE)))


def test_object_control_holds_the_commanded_load_share_and_squeeze(record_property):
    """70 % of the bar's weight on SCARA #1, a 2 N squeeze, the grips symmetric about the centre (so the
    uneven share needs #1's pitch moment): after 2 s the welds' squeeze and shares (the log's cooperation
    columns) equal the commands within 1 %, and the bar sits where the reference puts it (0.1 mm)."""
    sim = held()
    before = sim.log.cooperation(0, 1)
    c = cs.ObjectControl(BAR_M, bar_inertia(), load_share=0.7, squeeze=2.0)
    sim.add_cooperative(c, [0, 1])
    sim.run(2.8, progress=False)
    co = sim.log.cooperation(0, 1)
    assert co["squeeze"][-1] == pytest.approx(2.0, rel=0.01)
    np.testing.assert_allclose(co["load_share"][-1], [0.7, 0.3], rtol=0.01)
    assert np.abs(c.object_error[:3]).max() < 1e-4
    # independent computed torque before: no squeeze commanded, the share the welds' compliance gave
    assert abs(before["squeeze"][-1]) < 0.05 and abs(before["load_share"][-1][0] - 0.7) > 0.05
    record_property("squeeze (N)", float(co["squeeze"][-1]))
    record_property("load share #1", float(co["load_share"][-1][0]))


@pytest.mark.parametrize("squeeze,share", [(-1.0, 0.5), (5.0, 0.3)])
def test_other_commands_are_met_too(squeeze, share):
    sim = held()
    sim.add_cooperative(cs.ObjectControl(BAR_M, bar_inertia(), load_share=share, squeeze=squeeze), [0, 1])
    sim.run(2.3, progress=False)
    co = sim.log.cooperation(0, 1)
    assert co["squeeze"][-1] == pytest.approx(squeeze, rel=0.01)
    assert co["load_share"][-1][0] == pytest.approx(share, rel=0.01)


def zeta_from_overshoot(x):
    """Damping ratio of a second-order step response from its first overshoot over the final value."""
    os_ = x.max() / x[-1] - 1
    return -np.log(os_) / np.sqrt(np.pi ** 2 + np.log(os_) ** 2)


def test_object_impedance_gives_the_commanded_second_order_response_to_a_push(record_property):
    """The held bar as a mass-spring-damper (K 100 N/m, M 1 kg, zeta 0.4; the motion loop at 50 rad/s, five
    times faster): a 1 N step push on its centre, across its axis and level, moves it F/K (2 %) with the
    commanded damping ratio (5 %); the push estimated from the sensors is the push (1 %)."""
    sim = held()
    K, M, zeta = 100.0, 1.0, 0.4
    c = cs.ObjectControl(BAR_M, bar_inertia(), kp=2500.0, kd=100.0, impedance=(K, 2 * zeta * np.sqrt(K * M), M))
    sim.add_cooperative(c, [0, 1])
    sim.run(1.8, progress=False)
    assert np.abs(c.compliant_offset).max() < 1e-6  # at rest, unpushed: on the reference
    y = np.array([-np.sin(YAW), np.cos(YAW), 0.0])  # across the bar, horizontal
    start = sim.body_state("bar").position
    sim.set_body_wrench("bar", np.concatenate([y, np.zeros(3)]))
    x = []
    for k in range(1, 801):
        sim.run(1.8 + 0.005 * k, progress=False)
        x.append((sim.body_state("bar").position - start) @ y)
    x = np.array(x)
    assert sim.holding(0) == "bar" and sim.holding(1) == "bar"
    assert x[-1] == pytest.approx(1.0 / K, rel=0.02)
    z = zeta_from_overshoot(x)
    record_property("steady displacement / (F/K)", float(x[-1] * K))
    record_property("damping ratio", float(z))
    assert z == pytest.approx(zeta, rel=0.05)
    np.testing.assert_allclose(c.push_estimate[:3], y, atol=0.01)


def test_leader_follower_keeps_the_clamps_together_while_the_leader_moves(record_property):
    """SCARA #1 leads the held bar 4.5 cm (quintic, 1 s); SCARA #2 follows as an impedance on its sensed
    wrench (K 300 N/m). The clamps' relative pose error (the log's cooperation columns, against the pose at the
    second weld) stays within 0.05 mm and 0.5 mrad, the squeeze within 0.1 N, and the follower carries its half
    of the weight (share 0.5 within 1 %)."""
    sim = held()
    r1 = sim.robots[0]
    q, _ = sim.state(0)
    T0 = r1.fk(q)
    T1 = T0.copy()
    T1[:2, 3] += [0.04, -0.02]
    t0 = sim.time
    sim.set_reference(0, cs.plan_cartesian(r1, [T0, T0, T1, T1], [t0, t0 + 0.2, t0 + 1.2, t0 + 1.7], q_start=q,
                                           opening=q[5], intermediate=12, time_law="quintic", spline=True))
    lf = cs.LeaderFollower(300.0, 30.0, 1.0, object_mass=BAR_M)
    sim.add_cooperative(lf, [0, 1])
    sim.run(t0 + 1.7, progress=False)
    assert sim.holding(0) == "bar" and sim.holding(1) == "bar"
    co = sim.log.cooperation(0, 1)
    k = sim.log.t > t0
    rpe = co["relative_pose_error"][k]
    np.testing.assert_allclose(sim.body_state("bar").position[:2] - CENTRE[:2], [0.04, -0.02], atol=5e-4)
    record_property("relative position error (mm)", float(np.abs(rpe[:, :3]).max() * 1e3))
    record_property("relative rotation error (mrad)", float(np.abs(rpe[:, 3:]).max() * 1e3))
    assert np.abs(rpe[:, :3]).max() < 5e-5 and np.abs(rpe[:, 3:]).max() < 5e-4
    assert np.abs(co["squeeze"][k]).max() < 0.1
    assert co["load_share"][k][-1][0] == pytest.approx(0.5, rel=0.01)


@pytest.mark.parametrize("call,match", [
    (lambda: cs.LeaderFollower(-1.0, 1.0, 1.0, object_mass=BAR_M), "stiffness must be >= 0"),
    (lambda: cs.LeaderFollower(1.0, 1.0, 0.0, object_mass=BAR_M), "mass must be > 0"),
    (lambda: cs.LeaderFollower(1.0, 1.0, 1.0, object_mass=float("nan")), "object_mass must be finite"),
    (lambda: cs.LeaderFollower(1.0, 1.0, 1.0, object_mass=BAR_M, follower_share=-0.1), "follower_share must be in"),
    (lambda: cs.LeaderFollower(1.0, 1.0, 1.0, object_mass=BAR_M, kp=float("inf")), "kp must be finite"),
])
def test_bad_leader_follower_input_is_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


class PythonIndependent(cs.CooperativeController):
    """Two computed-torque controllers run from one cooperative law in Python."""

    def __init__(self, robots, kp, kd):
        super().__init__()
        self.ct = [cs.ComputedTorque(kp, kd) for _ in robots]
        self.robots = robots

    def reset(self, robots, period):
        for c, r in zip(self.ct, robots):
            c.reset(r, period)

    def compute(self, t, members):
        return [c.compute(t, m.q, m.qd, m.q_ref, m.qd_ref, m.qdd_ref) for c, m in zip(self.ct, members)]


def test_a_cooperative_law_in_python_drives_both_robots_as_its_parts_would():
    """A Python cooperative law made of two computed-torque controllers gives the same run, bit for bit, as
    the two controllers driving their robots on their own; its members see what each clamp holds."""
    logs = []
    for coop in (False, True):
        sim = held()
        if coop:
            law = PythonIndependent(sim.robots, 400.0, 40.0)
            sim.add_cooperative(law, [0, 1])
        else:
            for i in (0, 1):
                sim.set_controller(i, cs.ComputedTorque(400.0, 40.0))
        sim.run(1.0, progress=False)
        logs.append(sim.log)
    for i in (0, 1):
        np.testing.assert_array_equal(logs[0][i].tau, logs[1][i].tau)
        np.testing.assert_array_equal(logs[0][i].q, logs[1][i].q)


def test_removing_the_group_gives_the_robots_back_to_their_controllers():
    sim = held()
    k = sim.add_cooperative(cs.ObjectControl(BAR_M, bar_inertia()), [0, 1])
    sim.run(1.0, progress=False)
    sim.remove_cooperative(k)
    sim.run(1.2, progress=False)
    assert sim.holding(0) == "bar" and sim.holding(1) == "bar"


@pytest.mark.parametrize("kw,match", [
    (dict(load_share=1.5), "load_share must be in"),
    (dict(kp=float("nan")), "kp must be finite"),
    (dict(kd=-1.0), "kd must be finite and >= 0"),
    (dict(squeeze=float("inf")), "squeeze must be finite"),
    (dict(impedance=(1.0, 1.0, 0.0)), "impedance mass must be finite and > 0"),
    (dict(impedance=(-1.0, 1.0, 1.0)), "stiffness must be finite and >= 0"),
    (dict(impedance=(1.0, 1.0)), r"impedance must be \(stiffness, damping, mass\)"),
])
def test_bad_object_control_input_is_named(kw, match):
    with pytest.raises(ValueError, match=match):
        cs.ObjectControl(BAR_M, bar_inertia(), **kw)
    with pytest.raises(ValueError, match="mass"):
        cs.ObjectControl(0.0, bar_inertia())


def test_robots_that_do_not_hold_one_body_are_refused():
    r1, r2 = robots()
    sim = cs.Simulation(dt=2e-4)
    sim.add_robot(r1, cs.ComputedTorque(400.0, 40.0), np.array([0.3, 0.5, 0.1, 0.2, 1.5, 0.03]))
    sim.add_robot(r2, cs.ComputedTorque(400.0, 40.0), np.array([2.9, 0.7, 0.7, 0.1, -1.6, 0.03]))
    with pytest.raises(ValueError, match="drives two robots"):
        sim.add_cooperative(cs.ObjectControl(BAR_M, bar_inertia()), [0])
    with pytest.raises(ValueError, match="twice"):
        sim.add_cooperative(cs.ObjectControl(BAR_M, bar_inertia()), [0, 0])
    sim.add_cooperative(cs.ObjectControl(BAR_M, bar_inertia()), [0, 1])
    with pytest.raises(ValueError, match="do not hold the same body"):
        sim.run(0.01, progress=False)
    with pytest.raises(ValueError, match="already driven"):
        sim.add_cooperative(cs.ObjectControl(BAR_M, bar_inertia()), [1, 0])
