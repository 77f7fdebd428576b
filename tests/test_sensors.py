"""The force/torque sensor at the tool centre point and the joint-torque reading (Simulation.set_sensor,
Simulation.sensor, the log's ft_world and ft_clamp)."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import coopsim as cs
from test_grasp import BOX, DT, PID, Q0, closing, scene

G = 9.81


def still_robot(**sim_kw):
    """SCARA #1 without gravity held by a PID at Q0 and starting there: nothing moves it."""
    r = cs.robots.scara1(gravity=(0, 0, 0))
    sim = cs.Simulation(dt=DT, **sim_kw)
    sim.add_robot(r, cs.PID(**PID), Q0)
    return r, sim


def to_clamp(pose, h):
    """A world wrench (6,) [force; moment] in the axes of `pose` (4, 4)."""
    R = pose[:3, :3]
    return np.concatenate([R.T @ h[:3], R.T @ h[3:]])


# ---- what it reads ----

def test_a_held_bar_at_rest_reads_its_weight_and_lever_moment():
    """SCARA #1 grips an 18 cm bar 5 cm off its centre and lifts it: at rest the clamp carries m g upwards
    and the moment of the weight about the TCP, (c - p) x (m g e_z), in the clamp frame too."""
    r = cs.robots.scara1(gravity=(0, 0, -G))
    T = r.fk(Q0)
    fixed, _ = r.clamp_faces(Q0)
    m, he, off = 0.2, np.array([0.09, 0.01, 0.01]), 0.05  # along the tool's x (across the jaws), y (jaw axis), z
    P = T.copy()
    P[:3, 3] = fixed[:3, 3] + fixed[:3, 2] * (he[1] + 2e-4) + T[:3, 0] * off
    w = cs.World(gravity=r.gravity_acceleration)
    w.add_free_box("bar", he, m, P, friction=0.5)
    top = P[2, 3] - he[2]
    ped = np.eye(4)
    ped[:3, 3] = [P[0, 3], P[1, 3], top / 2]
    w.add_static_box("pedestal", [0.004, 0.004, top / 2], ped, friction=0.5)
    sim = closing(r, w, lift=0.05)
    sim.run(1.5, progress=False)
    assert sim.holding(0) == "bar"
    s = sim.sensor(0)
    q, _ = sim.state(0)
    np.testing.assert_allclose(s.pose, r.fk(q), rtol=0, atol=1e-12)  # the sensor frame is the tool frame
    c, p = sim.body_state("bar").position, s.pose[:3, 3]
    assert np.linalg.norm((c - p)[:2]) > 0.045  # the lever: the bar's centre 5 cm from the TCP
    f = np.array([0.0, 0.0, m * G])
    want = np.concatenate([f, np.cross(c - p, f)])
    np.testing.assert_allclose(s.ft_world, want, rtol=0, atol=1e-3 * m * G)
    assert np.linalg.norm(s.ft_world[3:] - want[3:]) < 1e-3 * np.linalg.norm(want[3:])
    np.testing.assert_allclose(s.ft_clamp, to_clamp(s.pose, want), rtol=0, atol=1e-3 * m * G)
    # an ideal sensor: the reading is the truth (turned into the clamp frame and back), and the log's last
    # row is the reading now
    np.testing.assert_allclose(s.ft_world, s.ft_true_world, rtol=0, atol=1e-15)
    log = sim.log[0]
    np.testing.assert_array_equal(log.ft_world[-1], s.ft_world)
    np.testing.assert_array_equal(log.ft_clamp[-1], s.ft_clamp)
    # before the grasp, with the jaws open and touching nothing, it read zero
    assert np.all(log.ft_world[0] == 0) and np.all(log.ft_clamp[0] == 0)


@pytest.mark.parametrize("kind", ["scenery pressed by the tips", "free box squeezed by the jaws"])
def test_contacts_on_the_jaws_are_sensed_without_a_weld(kind):
    """No grasp, no weld: the clamp pointing down pushes its jaws' tips 3 mm into a static box (penalty
    forces), or closes its jaws hard on a free box on a pedestal (Bullet's solver forces). The reading is
    minus the sum of the contact forces on the clamp's boxes, about the TCP (summed here from
    sim.contacts()), and its J^T is the joints' tau_ext: for joints 1..5, below the clamp,
    tau_ext = J(5, p_tcp)^T (-h) (a wrench on the moving jaw moves joints 1..5 as the same wrench at the
    same point of link 5 would)."""
    r = cs.robots.scara1(gravity=(0, 0, -G))
    if kind.startswith("scenery"):
        fixed, moving = r.clamp_faces(Q0)
        tip = 0.5 * (fixed[:3, 3] + moving[:3, 3]) + fixed[:3, 0] * r.clamp.jaw_length / 2  # jaw tips' middle
        assert fixed[2, 0] < -0.99  # the jaws point down
        w = cs.World(gravity=r.gravity_acceleration)
        he = np.array([0.04, 0.04, 0.01])
        P = np.eye(4)
        P[:3, 3] = [tip[0], tip[1], tip[2] - he[2]]
        w.add_static_box("box", he, P, friction=0.5)
        q1 = Q0.copy()
        q1[2] += 0.003  # the quill (positive down) commanded 3 mm lower: the PID presses
        sim = cs.Simulation(dt=DT, world=w, grasp=False, log_every=50)
        sim.add_robot(r, cs.PID(**PID), q1, q0=Q0)
    else:
        r, w = scene(BOX * [1, 2 / 3, 1], friction=1.0)
        sim = closing(r, w, jaw_ref=0.01, grasp=False)
    sim.run(0.3, progress=False)
    clamp = {f"{r.name}/{b.name}" for b in r.boxes if b.link >= r.clamp.fixed_link}

    def on_the_clamp():
        """The newtons on the clamp's boxes now, and minus their wrench about the TCP."""
        p = sim.sensor(0).pose[:3, 3]
        h, pushed = np.zeros(6), 0.0
        for c in sim.contacts():
            for name, point, force in ((c.a, c.point_a, c.force), (c.b, c.point_b, -c.force)):
                if name in clamp:
                    pushed += np.linalg.norm(force)
                    h -= np.concatenate([force, np.cross(point - p, force)])
        return pushed, h

    pushed, h = on_the_clamp()
    # the jaws closing hard on the free box chatter (its contacts come and go from one world step to the
    # next, which step depending on round-off): the reading is checked at the first step from 0.3 s on
    # with the jaws pushed
    t_stop = sim.time + 0.2
    while pushed <= 1.0 and sim.time < t_stop:
        sim.advance(sim.time + DT)
        pushed, h = on_the_clamp()
    assert sim.holding(0) is None
    s = sim.sensor(0)
    p = s.pose[:3, 3]
    assert pushed > 1.0  # newtons on the jaws
    if kind.startswith("scenery"):
        assert h[2] < -5.0  # pressing down with several newtons
    np.testing.assert_allclose(s.ft_true_world, h, rtol=0, atol=1e-9 * pushed)
    np.testing.assert_allclose(s.ft_world, s.ft_true_world, rtol=0, atol=1e-12 * pushed)
    q, _ = sim.state(0)
    link = r.clamp.fixed_link
    J = r.jacobian(q, link, np.linalg.solve(r.frames(q)[link], [*p, 1.0])[:3])
    np.testing.assert_allclose(s.tau_ext[:link], (J.T @ -s.ft_true_world)[:link], rtol=0,
                               atol=1e-9 * pushed)


def test_the_joint_torque_reading_is_tau_and_the_jacobian_transpose_of_the_external_wrenches():
    """tau is the motors' held torque; tau_ext the applied forces plus J^T of the applied wrenches
    (robot.jacobian at their points). A wrench on link 3 is below the clamp: the F/T sensor does not see
    it; one on the clamp's link reads minus itself about the TCP."""
    r, sim = still_robot()
    sim.run(0.01, progress=False)
    f = np.array([0.3, -0.2, 1.0, 0.05, 0.0, 0.01])
    w3 = cs.Wrench(3, [0.01, 0.02, -0.03], [1.0, -2.0, 0.5, 0.1, 0.2, -0.3])
    w5 = cs.Wrench(5, [0.02, 0.0, 0.01], [-0.5, 1.5, 2.0, 0.05, -0.1, 0.2])
    sim.set_applied(0, forces=f, wrenches=[w3])
    q, _ = sim.state(0)
    s = sim.sensor(0)
    want = f + r.jacobian(q, 3, w3.point).T @ w3.wrench
    np.testing.assert_allclose(s.tau_ext, want, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(s.tau, sim.torque(0))
    assert np.all(s.ft_world == 0) and np.all(s.ft_true_clamp == 0)
    sim.set_applied(0, wrenches=[w3, w5])
    s = sim.sensor(0)
    want += r.jacobian(q, 5, w5.point).T @ w5.wrench
    np.testing.assert_allclose(s.tau_ext, want, rtol=1e-12, atol=1e-12)
    at = (r.frames(q)[5] @ [*w5.point, 1.0])[:3]
    p = s.pose[:3, 3]
    h = -np.concatenate([w5.wrench[:3], w5.wrench[3:] + np.cross(at - p, w5.wrench[:3])])
    np.testing.assert_allclose(s.ft_world, h, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.ft_clamp, to_clamp(r.fk(q), h), rtol=0, atol=1e-12)
    # the log's row at this time holds the same
    sim.step(1)
    log = sim.log[0]
    np.testing.assert_allclose(log.tau_ext[-2], want, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(log.ft_world[-2], h, rtol=0, atol=1e-12)


# ---- noise and filter ----

def test_the_noise_has_its_standard_deviation_and_repeats_with_its_seed():
    """Nothing acts on the clamp: the reading is the noise alone. Over N = 10001 rows the sample standard
    deviation of a Gaussian is within 5 % of sigma (its own deviation is sigma / sqrt(2 N) = 0.7 %), the
    mean within 5 sigma / sqrt(N), and the components are uncorrelated (|r| < 5 / sqrt(N))."""
    sf, sm = 0.5, 0.02

    def noisy(seed):
        _, sim = still_robot()
        sim.set_sensor(0, noise_force=sf, noise_moment=sm, seed=seed)
        return sim, sim.run(2.0, progress=False)[0]

    sim, log = noisy(7)
    x = log.ft_clamp
    n = len(x)
    assert n == 10001
    sigma = np.array([sf] * 3 + [sm] * 3)
    np.testing.assert_allclose(x.std(axis=0), sigma, rtol=0.05)
    assert np.all(np.abs(x.mean(axis=0)) < 5 * sigma / np.sqrt(n))
    corr = np.corrcoef(x.T)
    assert np.abs(corr - np.eye(6)).max() < 5 / np.sqrt(n)
    # the world reading is the same vector in world axes
    R = sim.sensor(0).pose[:3, :3]
    np.testing.assert_allclose(log.ft_world[:, :3], x[:, :3] @ R.T, rtol=0, atol=1e-12)
    np.testing.assert_allclose(log.ft_world[:, 3:], x[:, 3:] @ R.T, rtol=0, atol=1e-12)
    # the same seed, the same noise (a new simulation, or after reset); another seed, other noise
    np.testing.assert_array_equal(noisy(7)[1].ft_clamp, x)
    sim.reset()
    np.testing.assert_array_equal(sim.run(2.0, progress=False)[0].ft_clamp, x)
    assert not np.any(noisy(8)[1].ft_clamp == x)


def test_the_filter_follows_its_closed_form_and_reaches_1_minus_1_over_e_at_its_time_constant():
    """At t0 a wrench w is applied at the TCP together with the joint forces -J^T w: the robot feels
    nothing and stays put, the sensor reads a step to -w. With a = 1 - exp(-dt / tau) the reading m steps
    after t0 is -w (1 - (1 - a)^(m + 1)) = -w (1 - exp(-(m + 1) dt / tau)); at t0 + tau it is 1 - 1/e of
    the step within dt / tau."""
    tau = 0.01
    r, sim = still_robot()
    sim.set_sensor(0, time_constant=tau)
    t0 = 0.01
    sim.run(t0, progress=False)
    q, _ = sim.state(0)
    w = np.array([3.0, -1.0, 2.0, 0.2, -0.1, 0.3])
    sim.set_applied(0, forces=-r.tool_jacobian(q).T @ w, wrenches=w)
    log = sim.run(t0 + 5 * tau, progress=False)[0]
    assert np.abs(sim.state(0)[0] - Q0).max() < 1e-12 and np.abs(sim.tau_ext(0)).max() < 1e-12
    k0 = int(np.flatnonzero(log.t >= t0 - 1e-12)[1])  # the second row at t0: the one with the wrench
    assert log.t[k0] == pytest.approx(t0) and np.all(log.ft_world[:k0] == 0)
    m = np.arange(len(log.t) - k0)
    a = 1 - np.exp(-DT / tau)
    want = -w[None, :] * (1 - (1 - a) ** (m + 1))[:, None]
    np.testing.assert_allclose(log.ft_world[k0:], want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sim.sensor(0).ft_true_world, -w, rtol=0, atol=1e-12)
    i = int(round(tau / DT))  # the row at t0 + tau
    assert abs(log.ft_world[k0 + i, 0] / -w[0] - (1 - np.exp(-1))) < DT / tau


def test_filtered_noise_has_the_standard_deviation_of_the_filter():
    """White noise of deviation sigma through the filter: a stationary AR(1) of deviation
    sigma sqrt(a / (2 - a)). With tau = 5 dt the correlation lasts about 5 steps: over 40001 rows the
    sample deviation is within 5 %."""
    sf, tau = 1.0, 5 * DT
    _, sim = still_robot()
    sim.set_sensor(0, noise_force=sf, time_constant=tau, seed=3)
    x = sim.run(8.0, progress=False)[0].ft_clamp[1000:]
    a = 1 - np.exp(-DT / tau)
    np.testing.assert_allclose(x[:, :3].std(axis=0), sf * np.sqrt(a / (2 - a)), rtol=0.05)
    assert np.all(x[:, 3:] == 0)


# ---- its configuration ----

def test_sensor_options_their_defaults_checks_and_pickling():
    _, sim = still_robot()
    o = sim.sensor_options(0)
    assert o == cs.Simulation.sensor_defaults()
    assert (o.noise_force, o.noise_moment, o.time_constant, o.seed) == (0.0, 0.0, 0.0, 0)
    s = sim.sensor(0)
    assert set(type(s).fields) == {"ft_world", "ft_clamp", "ft_true_world", "ft_true_clamp", "pose", "tau", "tau_ext"}
    assert all(np.all(getattr(s, k) == 0) for k in type(s).fields if k != "pose") and s.ft_world.shape == (6,)
    sim.set_sensor(0, noise_force=0.1, seed=4)
    sim.set_sensor(0, time_constant=0.02)  # the others kept
    o = sim.sensor_options(0)
    assert (o.noise_force, o.noise_moment, o.time_constant, o.seed) == (0.1, 0.0, 0.02, 4)
    for name, value, msg in [("noise_force", -1.0, r"sensor: noise_force must be finite and >= 0 N, got -1"),
                             ("noise_moment", np.nan, r"sensor: noise_moment must be finite and >= 0 N m, got nan"),
                             ("time_constant", -0.1, r"sensor: time_constant must be finite and >= 0 s, got -0\.1"),
                             ("time_constant", np.inf, r"sensor: time_constant must be finite and >= 0 s, got inf"),
                             ("seed", -3, r"sensor: seed must be >= 0, got -3")]:
        with pytest.raises(ValueError, match=msg):
            sim.set_sensor(0, **{name: value})
    assert sim.sensor_options(0).noise_force == 0.1  # a refused change changes nothing
    with pytest.raises(TypeError):
        sim.set_sensor(0, noise_force="loud")
    with pytest.raises((ValueError, IndexError)):
        sim.set_sensor(1, noise_force=0.1)
    again = pickle.loads(pickle.dumps(sim))
    assert again.sensor_options(0) == sim.sensor_options(0)


def test_an_ideal_sensor_reads_the_same_off_the_log_rows():
    """An ideal sensor (no noise, no filter) is read only at the log's rows and when asked: asked between
    rows, and at the rows, it reads what a sensor read at every step does."""
    w5 = cs.Wrench(5, [0.02, 0.0, 0.01], [-0.5, 1.5, 2.0, 0.05, -0.1, 0.2])
    out = []
    for log_every in (1, 7):
        r = cs.robots.scara1(gravity=(0, 0, -G))
        sim = cs.Simulation(dt=DT, log_every=log_every)
        sim.add_robot(r, cs.PID(**PID), Q0)  # it sags under gravity: the TCP moves, the moment about it too
        sim.set_applied(0, wrenches=[w5])
        sim.step(10)
        out.append((sim.sensor(0), sim.log[0].ft_world))
    (a, log_a), (b, log_b) = out
    assert np.any(a.ft_world != 0)
    for k in type(a).fields:
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    np.testing.assert_array_equal(log_a[::7], log_b)
