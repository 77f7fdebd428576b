"""The clamp grasp: the rule, the weld, the release."""
from __future__ import annotations

import numpy as np
import pytest

import coopsim as cs

DT = 2e-4
Q0 = np.array([0.3, 0.5, 0.15, 0.2, np.pi / 2, 0.03])  # SCARA #1, clamp pointing down, 3 cm open
PID = dict(kp=[400, 400, 2000, 20, 20, 500], ki=[0] * 6, kd=[40, 40, 100, 2, 2, 20])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def scene(he, *, centre=None, turn=0.0, shift=0.0, velocity=0.0, gravity=True, friction=0.5, pedestal=True):
    """SCARA #1 with a box between its jaws: half extents `he` along the tool's x (across), y (jaw
    axis) and z (approach), turned by `turn` about the approach, its centre `centre` m from the fixed
    jaw's face along the jaw axis (default: touching it), shifted along the approach by `shift`,
    moving across the jaws at `velocity` m/s."""
    r = cs.robots.scara1(gravity=(0, 0, -9.81 if gravity else 0.0))
    T = r.fk(Q0)
    fixed, _ = r.clamp_faces(Q0)
    P = T.copy()
    P[:3, :3] = T[:3, :3] @ rot_z(turn)
    c = he[1] + 2e-4 if centre is None else centre
    P[:3, 3] = fixed[:3, 3] + fixed[:3, 2] * c + T[:3, 2] * shift
    w = cs.World(gravity=r.gravity_acceleration)
    w.add_free_box("box", he, 0.1, P, friction=friction, velocity=velocity * T[:3, 0])
    if pedestal:  # thin enough for the jaws to close around it
        top = P[2, 3] - he[2]
        ped = np.eye(4)
        ped[:3, 3] = [P[0, 3], P[1, 3], top / 2]
        w.add_static_box("pedestal", [0.004, 0.004, top / 2], ped, friction=friction)
    return r, w


def closing(r, w, jaw_ref=0.019, lift=0.0, t_close=0.1, t_lift=0.3, open_at=None, **kw):
    """The jaw closes to jaw_ref over t_close (or, above the present opening, is commanded open from
    the start), then the quill lifts by `lift` m over t_lift; from open_at (s) the jaw opens to 3 cm."""
    sim = cs.Simulation(dt=DT, world=w, log_every=25, **kw)
    q1 = Q0.copy()
    q1[5] = jaw_ref
    if jaw_ref > Q0[5]:
        sim.add_robot(r, cs.PID(**PID), q1, q0=Q0)
        return sim
    q2 = q1.copy()
    q2[2] -= lift
    t1 = 0.02 + t_close
    times, points = [0.0, 0.02, t1, t1 + 0.05, t1 + 0.05 + t_lift], [Q0, Q0, q1, q1, q2]
    if open_at is not None:
        q3 = q2.copy()
        q3[5] = 0.03
        times += [open_at, open_at + 0.1]
        points += [q2, q3]
    sim.add_robot(r, cs.PID(**PID), cs.CubicTrajectory(times, np.array(points)))
    return sim


# the truth table, at the moment the jaws meet the body: everything right but one condition
BOX = np.array([0.05, 0.015, 0.01])  # 3 cm wide: both faces touch at the 3 cm opening
CUBE = 0.015 / (np.cos(np.pi / 6) + np.sin(np.pi / 6))  # half side: turned 30 deg it still spans 3 cm
CASES = {
    "all conditions": (dict(he=BOX), {}, None),
    "one jaw touching": (dict(he=np.array([0.05, 0.01, 0.01])), dict(jaw_ref=0.025), "touching"),
    "turned 30 deg about the approach": (dict(he=np.full(3, CUBE), turn=np.pi / 6, centre=0.015 + 2e-4), {},
                                         "aligned"),
    "wider than the opening": (dict(he=np.array([0.05, 0.017, 0.01]), centre=0.015), {}, "touching"),
    "outside the pads": (dict(he=BOX, shift=0.025), {}, "in_pads"),
    "standing out 5 mm beyond the tips": (dict(he=BOX, shift=0.015), {}, None),
    "moving at 0.2 m/s": (dict(he=BOX, velocity=0.2, friction=0.0), {}, "slow"),
    "jaw commanded open": (dict(he=BOX), dict(jaw_ref=0.04), "closing"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_clamp_rule_as_a_truth_table(case):
    scene_kw, sim_kw, broken = CASES[case]
    r, w = scene(**scene_kw)
    sim = closing(r, w, **sim_kw)
    check = sim.grasp_check(0, "box")
    names = ("closing", "aligned", "touching", "in_pads", "slow")
    assert {n: getattr(check, n) for n in names} == {n: n != broken for n in names}, check
    assert check.ok == (broken is None)


def test_the_grasp_happens_through_the_rule_and_never_snaps():
    r, w = scene(BOX * [1, 2 / 3, 1])  # 2 cm wide against the fixed jaw: the moving jaw closes on it
    sim = closing(r, w)
    p0 = sim.body_state("box").pose
    sim.run(0.2, progress=False)
    g = sim.log.grasps
    assert sim.holding(0) == "box" and list(g["event"]) == ["grasp"] and 0.02 < g["t"][0] < 0.2
    # attached where it was: the body has not jumped
    assert np.abs(sim.body_state("box").pose - p0).max() < 2e-3
    # without the rule nothing is held
    r, w = scene(BOX * [1, 2 / 3, 1])
    sim = closing(r, w, grasp=False)
    sim.run(0.2, progress=False)
    assert sim.holding(0) is None and len(sim.log.grasps) == 0


def test_a_grasp_leaves_resting_contacts_whole():
    # the grasp changes which pairs collide (the held body and its clamp): only the held body's pairs are
    # made again, and a body made again while it rests keeps its contact (contacts settle 1e-11 m deep)
    r, w = scene(BOX * [1, 2 / 3, 1])
    w.add_free_box("bar", [0.175, 0.01, 0.01], 0.15, position=[-0.3, -0.3, 0.01], friction=0.5)
    sim = closing(r, w)
    sim.run(0.3, progress=False)
    assert sim.holding(0) == "box"
    events = sim.log.contacts
    for pair in (("floor", "bar"), ("box", "pedestal")):
        e = events[(events["a"] == pair[0]) & (events["b"] == pair[1])]
        assert len(e) == 1 and np.isnan(e["end"].iloc[0]) and e["steps"].iloc[0] == 1501, e
    bar = [c for c in sim.contacts() if c.b == "bar"]
    assert sum(c.force for c in bar)[2] == pytest.approx(-0.15 * 9.81, rel=1e-9)


@pytest.mark.parametrize("case", ["one jaw touching", "jaw commanded open", "moving at 0.2 m/s"])
def test_no_grasp_when_a_condition_stays_false(case):
    scene_kw, sim_kw, _ = CASES[case]
    r, w = scene(**scene_kw)
    sim = closing(r, w, **sim_kw)
    sim.run(0.2, progress=False)
    assert sim.holding(0) is None and len(sim.log.grasps) == 0


def test_a_lifted_body_weighs_m_g_on_the_weld_and_loads_the_robot():
    r, w = scene(BOX * [1, 2 / 3, 1])
    sim = closing(r, w, lift=0.05)
    sim.run(1.5, progress=False)
    assert sim.holding(0) == "box"
    assert sim.body_state("box").position[2] > sim.world.body("box")["pose"][2, 3] + 0.045  # carried up
    F = sim.weld_wrench(0)
    assert F[2] == pytest.approx(0.1 * 9.81, rel=1e-6)
    assert np.abs(F[:2]).max() < 1e-6 * 0.981
    # the robot feels it: the clamp link carries the weld's reaction, J^T (-F) at the weld's point, midway
    # between the pads; the box is gripped about its centre, which stands in for that point here
    q, _ = sim.state(0)
    link = r.clamp.fixed_link
    c = sim.body_state("box").position
    tau = r.external_torques(q, [cs.Wrench(link, np.linalg.solve(r.frames(q)[link], [*c, 1.0])[:3], -F)])
    tau_ext = sim.applied(0)["tau_ext"]
    np.testing.assert_allclose(tau_ext[:5], tau[:5], rtol=1e-3, atol=1e-4)  # joint 6 also feels the jaw stop
    # the log: what each row held and the weld's wrench over it
    log = sim.log
    held = log[0].holding
    k = int(np.flatnonzero(held == "box")[0])
    assert set(held[:k]) == {""} and set(held[k:]) == {"box"}
    assert log.grasps["t"][0] == pytest.approx(log.t[k], abs=25 * DT)
    np.testing.assert_allclose(log[0].weld[-1], F, rtol=1e-6, atol=1e-9)


def test_release_gives_the_body_the_clamps_rigid_twist():
    r, w = scene(BOX * [1, 2 / 3, 1], gravity=False, pedestal=False)
    sim = closing(r, w)
    sim.run(0.2, progress=False)
    assert sim.holding(0) == "box"
    sim.set_applied(0, forces=np.array([2.0, -1.0, 0.0, 0.5, 0.0, 0.0]))  # swing the arm
    sim.run(0.3, progress=False)
    q, qd = sim.state(0)
    assert np.abs(qd).max() > 0.05
    sim.release(0)
    assert sim.holding(0) is None
    st = sim.body_state("box")
    link = r.clamp.fixed_link
    p = np.linalg.solve(r.frames(q)[link], [*st.position, 1.0])[:3]
    twist = r.jacobian(q, link, p) @ qd
    np.testing.assert_allclose(st.velocity, twist[:3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(st.angular_velocity, twist[3:], rtol=0, atol=1e-9)
    g = sim.log.grasps
    assert list(g["event"]) == ["grasp", "release"] and g["reason"].iloc[-1] == "released"


def test_opening_the_jaw_releases_and_the_body_falls():
    r, w = scene(BOX * [1, 2 / 3, 1])
    sim = closing(r, w, lift=0.05, open_at=0.8)
    sim.run(0.75, progress=False)
    assert sim.holding(0) == "box"
    z_held = sim.body_state("box").position[2]
    sim.run(1.5, progress=False)
    g = sim.log.grasps
    assert sim.holding(0) is None and list(g["event"]) == ["grasp", "release"], g
    assert g["reason"].iloc[-1] == "opened" and 0.9 < g["t"].iloc[-1] < 1.0  # opened at 0.8, let go over 0.1 s
    assert sim.body_state("box").position[2] < z_held - 0.04  # back down on the pedestal


# ---- two holders ----

def gripper(x, name):
    """A gantry gripper over (x, 0): joint 1 lifts its hand (prismatic, vertical), joint 2 opens its
    jaw along -y (prismatic); the jaws hang 3 cm under the hand, the fixed one's face in the plane y = 0."""
    dh = [[0.0, 0.0, 0.0, np.pi / 2], [0.0, 0.0, 0.0, 0.0]]
    com = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]
    inertias = [cs.box_inertia(1.0, 0.04, 0.04, 0.04), cs.box_inertia(0.05, 0.02, 0.02, 0.005)]
    # frame 1: x1 = x0, y1 up, z1 = -y0 (the jaw axis); the jaw runs down, along -y1
    face = np.eye(4)
    face[:3, :3] = [[0, 1, 0], [-1, 0, 0], [0, 0, 1]]
    face[:3, 3] = [0, -0.03, 0]

    def at(y, z):
        T = np.eye(4)
        T[1, 3], T[2, 3] = y, z
        return T

    boxes = [cs.LinkBox(1, [0.02, 0.02, 0.02], np.eye(4), "hand"),
             cs.LinkBox(1, [0.01, 0.02, 0.0025], at(-0.03, -0.0025), "fixed_jaw"),
             cs.LinkBox(2, [0.01, 0.02, 0.0025], at(-0.03, 0.0025), "moving_jaw")]
    return cs.Robot.from_dh(dh, com, [1.0, 0.05], inertias, joint_types="PP", q_limits=[[-1, 1], [0, 0.05]],
                            base_position=(x, 0.0, 0.0), name=name, boxes=boxes,
                            clamp=cs.Clamp(1, face, 2, 0.04, 0.02))


BAR = np.array([0.2, 0.015, 0.01])  # along x, 3 cm across the jaws
G_BAR = 0.2 * 9.81


def two_holders(xa, xb, close_b=0.0, open_a=None, t_end=1.0, **kw):
    """A bar held at its centre's height 0.17 m by grippers at xa and xb; b closes at close_b (s), a
    opens at open_a (s)."""
    w = cs.World(floor=False)
    P = np.eye(4)
    P[:3, 3] = [0.0, -0.015, 0.17]
    w.add_free_box("bar", BAR, 0.2, P, friction=0.5)
    sim = cs.Simulation(dt=DT, world=w, log_every=50, **kw)
    for x, name, t_close, t_open in ((xa, "a", 0.0, open_a), (xb, "b", close_b, None)):
        g = gripper(x, name)
        q_open, q_shut = np.array([0.2, 0.035 if t_close > 0 else 0.03]), np.array([0.2, 0.029])
        times, points = [0.0, t_close + 1e-3 if t_close > 0 else 0.02, t_close + 0.06], [q_open, q_open, q_shut]
        if t_open is not None:  # open, then move the hand 5 cm up, clear of the bar
            times += [t_open, t_open + 0.05, t_open + 0.25, t_open + 0.45]
            points += [q_shut, np.array([0.2, 0.04]), np.array([0.2, 0.04]), np.array([0.25, 0.04])]
        q0 = q_shut.copy()
        q0[1] = 0.035 if t_close > 0 else 0.03
        sim.add_robot(g, cs.PID([4000.0, 200.0], [0.0, 0.0], [200.0, 4.0]), cs.CubicTrajectory(times, np.array(points)),
                      q0=q0)
    return sim


def test_two_holders_share_the_weight():
    sim = two_holders(-0.1, 0.1)
    sim.run(1.0, progress=False)
    assert sim.holding(0) == "bar" and sim.holding(1) == "bar"
    fa, fb = sim.weld_wrench(0), sim.weld_wrench(1)
    assert fa[2] + fb[2] == pytest.approx(G_BAR, rel=1e-6)
    assert fa[2] == pytest.approx(G_BAR / 2, rel=1e-4) and fb[2] == pytest.approx(G_BAR / 2, rel=1e-4)
    # the internal force: what the two wrenches cancel on the bar, small for a symmetric hold
    assert abs(fa[0] + fb[0]) < 1e-6 and abs(fa[1] + fb[1]) < 1e-6


def test_a_second_holder_takes_no_load_at_first_and_all_of_it_after_a_handover():
    sim = two_holders(-0.1, 0.12, close_b=0.3, open_a=0.7)
    sim.run(0.25, progress=False)
    assert sim.holding(0) == "bar" and sim.holding(1) is None
    history = []
    while sim.time < 2.0 - 1e-9:
        sim.step(1)
        history.append((sim.time, sim.holding(0), sim.holding(1), sim.weld_wrench(0)[2], sim.weld_wrench(1)[2]))
    t, ha, hb, fa, fb = map(np.array, zip(*history))
    k = int(np.flatnonzero(hb == "bar")[0])  # b's first held step
    assert abs(fb[k]) < 0.01 * G_BAR  # no jump when b attaches
    # from b's attach on, through a's release (its weld fading out as its jaw opens), no force jumps
    after = t > t[k]
    assert np.abs(np.diff(fb[after])).max() < 0.01 * G_BAR and np.abs(np.diff(fa[after])).max() < 0.01 * G_BAR
    g = sim.log.grasps
    assert list(zip(g["robot"], g["event"])) == [(0, "grasp"), (1, "grasp"), (0, "release")]
    assert sim.holding(0) is None and sim.holding(1) == "bar"
    assert fb[-1] == pytest.approx(G_BAR, rel=1e-6)


def payload_robot(r, X, mass, he):
    """SCARA #1 with a box of `mass` and half extents `he` lumped into its clamp link 5 at the pose
    X (4, 4) in frame 5: the exact oracle of a held body at rest. Link 5's CoM row is rewritten
    to the composite centre of mass (frame 5 sits at Tx(L5) of frame 4 with alpha 0) and its
    inertia to the composite's about it, in that CoM frame."""
    m5, I5 = r.masses[4], r.inertias[4]
    L5 = r.dh[4, 2]
    C5 = r.com[4]
    A_com5 = cs.dh_transform(*C5)  # link 5's CoM frame in frame 4 (q5 = 0)
    A5 = cs.dh_transform(*r.dh[4])  # frame 5 in frame 4
    c_link = A_com5[:3, 3]
    c_box = (A5 @ X)[:3, 3]
    m = m5 + mass
    c = (m5 * c_link + mass * c_box) / m

    def shifted(I, R, mass_, at):
        d = at - c
        return R @ I @ R.T + mass_ * (d @ d * np.eye(3) - np.outer(d, d))

    I_box = cs.box_inertia(mass, *(2 * np.asarray(he)))
    I4 = shifted(I5, A_com5[:3, :3], m5, c_link) + shifted(I_box, (A5 @ X)[:3, :3], mass, c_box)
    theta = np.arctan2(c[1], c[0])
    row = [theta, c[2], np.hypot(c[0], c[1]), 0.0]
    Rc = cs.dh_transform(*row)[:3, :3]
    com, masses, inertias = r.com.copy(), r.masses.copy(), r.inertias.copy()
    com[4], masses[4], inertias[4] = row, m, Rc.T @ I4 @ Rc
    return cs.Robot.from_dh(r.dh, com, masses, inertias, joint_types=r.joint_types,
                            friction=r.friction_coefficients, q_limits=r.q_limits, tau_limits=r.tau_limits,
                            gravity=r.gravity_acceleration, base_position=r.base_position, base_yaw=r.base_yaw,
                            tool=r.tool)


def test_holding_still_costs_the_torques_of_the_body_lumped_into_the_clamp_link():
    he = BOX * [1, 2 / 3, 1]
    r, w = scene(he)
    sim = closing(r, w, lift=0.05)
    sim.run(1.5, progress=False)
    assert sim.holding(0) == "box"
    q, qd = sim.state(0)
    assert np.abs(qd).max() < 1e-4  # at rest
    link = r.clamp.fixed_link
    X = np.linalg.solve(r.frames(q)[link], sim.body_state("box").pose)
    oracle = payload_robot(r, X, 0.1, he)
    # gravity torques of robot + payload = the robot's own, minus what the weld brings in
    tau_ext = sim.applied(0)["tau_ext"]
    expected = oracle.gravity(q) - r.gravity(q)
    assert expected[2] == pytest.approx(-0.1 * 9.81, rel=1e-9)  # the quill (down is +d3) carries the box
    # joints 1-5 (joint 6, the jaw, also feels the stop at the body's width); within the weld's sag
    np.testing.assert_allclose(-tau_ext[:5], expected[:5], rtol=0, atol=1e-4 * np.abs(oracle.gravity(q)).max())


def test_a_held_body_swinging_without_friction_or_gains_never_gains_energy():
    # no gravity, no friction, zero gains: the arm swings with the box welded to its clamp. The weld is
    # a spring-damper between them (it can only take energy out, through its damping of the small
    # relative motion), so the total kinetic energy of robot and box never grows and falls only a little
    r = cs.robots.scara1(gravity=(0, 0, 0), friction=np.zeros(6))
    fixed, _ = r.clamp_faces(Q0)
    P = r.fk(Q0)
    P[:3, 3] = fixed[:3, 3] + fixed[:3, 2] * BOX[1]  # 3 cm wide: both faces touch
    qd0 = np.array([0.5, -0.8, 0.0, 1.0, 0.0, 0.0])
    twist = r.jacobian(Q0, 5, np.linalg.solve(r.frames(Q0)[5], P[:, 3])[:3]) @ qd0  # moving with the clamp
    w = cs.World(floor=False, gravity=(0, 0, 0))
    w.add_free_box("box", BOX, 0.1, P, friction=0.5, velocity=twist[:3], angular_velocity=twist[3:])
    sim = cs.Simulation(dt=DT, world=w, log_every=10)
    q_ref = Q0.copy()
    q_ref[5] = 0.029  # commanded closed: the rule holds at once
    sim.add_robot(r, cs.PID(0.0, 0.0, 0.0, gravity_compensation=False), q_ref, q0=Q0, qd0=qd0)
    log = sim.run(2.0, progress=False)
    assert set(log[0].holding[1:]) == {"box"}
    box = log.bodies["box"]
    R = box.poses()[:, :3, :3]
    I = np.einsum("rij,jk,rlk->ril", R, cs.box_inertia(0.1, *(2 * BOX)), R)
    e_box = 0.05 * (box.velocity ** 2).sum(1) + 0.5 * np.einsum("ri,rij,rj->r", box.angular_velocity, I,
                                                               box.angular_velocity)
    e = e_box + np.array([sum(r.energy(q, qd)) for q, qd in zip(log.q, log.qd)])
    assert e.max() <= e[0] * (1 + 1e-9)
    assert e[-1] > 0.8 * e[0]  # measured 0.937


def test_grasp_matrix_load_split_and_internal_wrenches():
    from coopsim import grasp

    pts, c = np.array([[-0.1, 0.0, 0.0], [0.15, 0.0, 0.0]]), np.zeros(3)
    G = grasp.grasp_matrix(pts, c)
    w = np.array([0.0, 0.0, 1.962, 0.0, 0.05, 0.0])  # lift a bar's weight and a pitch moment
    f = grasp.load_split(w, pts, c)
    np.testing.assert_allclose(G @ f.reshape(-1), w, atol=1e-14)  # the shares make the net wrench
    squeeze = np.array([[5.0, 0, 0, 0, 0, 0], [-5.0, 0, 0, 0, 0, 0]])
    g = grasp.load_split(w, pts, c, internal=squeeze)
    np.testing.assert_allclose(G @ g.reshape(-1), w, atol=1e-12)  # an internal part leaves it unchanged
    np.testing.assert_allclose(grasp.internal_wrenches(g, pts, c), g - f, atol=1e-12)
    np.testing.assert_allclose(grasp.internal_wrenches(g, pts, c).sum(axis=0)[:3], 0, atol=1e-12)
    # a symmetric grasp shares a pure force equally
    sym = grasp.load_split([0, 0, 2.0, 0, 0, 0], [[-0.1, 0, 0], [0.1, 0, 0]], c)
    np.testing.assert_allclose(sym[:, 2], [1.0, 1.0], rtol=1e-12)
    with pytest.raises(ValueError, match="points"):
        grasp.grasp_matrix(np.zeros((2, 2)), c)


@pytest.mark.parametrize("call, match", [
    # numpy's "could not convert string to float: 'a'" before, naming nothing
    (lambda g: g.grasp_matrix(["ab", "cd"], np.zeros(3)), "points must be an array of real numbers"),
    # complex numbers were cast to their real part with numpy's ComplexWarning
    (lambda g: g.load_split(np.ones(6) * 1j, np.zeros((1, 3)), np.zeros(3)), "wrench must be an array of real"),
    # NaN in the internal part or the wrenches came back as NaN shares
    (lambda g: g.load_split(np.ones(6), np.zeros((1, 3)), np.zeros(3), internal=np.full((1, 6), np.nan)),
     r"internal must be finite and within \+-1e\+12 N, N m"),
    (lambda g: g.internal_wrenches(np.full((1, 6), np.inf), np.zeros((1, 3)), np.zeros(3)), "wrenches must be finite"),
    # points far enough to overflow the pseudo-inverse
    (lambda g: g.load_split(np.ones(6), [[0, 0, 1e200]], np.zeros(3)), r"points must be finite and within \+-1e\+06 m"),
    (lambda g: g.load_split(np.ones(6), np.zeros((2, 3)), np.zeros(3), internal=np.zeros((3, 6))),
     r"wrong shape for internal: expected \(2, 6\)"),
])
def test_load_sharing_bad_input_names_the_argument(call, match):
    from coopsim import grasp

    with pytest.raises(ValueError, match=match):
        call(grasp)


def test_the_deprecated_half_difference_is_the_internal_wrench_only_for_welds_at_one_point():
    sim = two_holders(-0.1, 0.1)
    log = sim.run(1.0, progress=False)
    with pytest.warns(DeprecationWarning, match="not the internal wrench"):
        iw = log.internal_wrench(0, 1)
    both = (log[0].holding == "bar") & (log[1].holding == "bar")
    assert both.any() and np.all(iw[~both] == 0)
    np.testing.assert_allclose(iw[-1], (log[0].weld[-1] - log[1].weld[-1]) / 2)
    # it is the grasp module's internal part (either metric) for two welds at one point, here the bar's
    # centre; the welds' own points lie between each gripper's pads (SimulationLog.cooperation has them)
    c = sim.body_state("bar").position
    for metric in ("euclidean", "forces"):
        internal = cs.grasp.internal_wrenches(np.array([log[0].weld[-1], log[1].weld[-1]]), [c, c], c, metric=metric)
        np.testing.assert_allclose(internal[0], iw[-1], atol=1e-12)
    assert np.abs(iw[-1][:3]).max() < 1e-3  # symmetric and at rest: the weight splits evenly


def test_pressing_a_held_body_on_scenery_passes_the_scenery_force_to_the_robot():
    # grasp the box on its pedestal, then push down 2 mm into it: the pedestal's force on the box
    # reaches the robot through the weld, J^T (F_pedestal + m g) at the box's centre
    r, w = scene(BOX * [1, 2 / 3, 1])
    sim = cs.Simulation(dt=DT, world=w, log_every=25)
    q1 = Q0.copy()
    q1[5] = 0.019
    q2 = q1.copy()
    q2[2] += 0.002  # the quill 2 mm further down
    traj = cs.CubicTrajectory([0.0, 0.02, 0.12, 0.2, 0.4], np.array([Q0, Q0, q1, q1, q2]))
    sim.add_robot(r, cs.PID(**PID), traj)
    sim.run(1.0, progress=False)
    assert sim.holding(0) == "box"
    on_box = sum(-c.force if c.b == "box" else c.force for c in sim.contacts()
                 if "pedestal" in (c.a, c.b) and "box" in (c.a, c.b))
    assert on_box[2] > 3.0  # pressed well beyond its weight (0.98 N): measured 4.9 N
    F = sim.weld_wrench(0)
    np.testing.assert_allclose(F[:3], -(on_box + [0, 0, -0.1 * 9.81]), rtol=1e-3, atol=1e-3)  # the box at rest
    q, _ = sim.state(0)
    link = r.clamp.fixed_link
    c = sim.body_state("box").position
    tau = r.external_torques(q, [cs.Wrench(link, np.linalg.solve(r.frames(q)[link], [*c, 1.0])[:3],
                                           np.r_[on_box + [0, 0, -0.1 * 9.81], -F[3:]])])
    np.testing.assert_allclose(sim.applied(0)["tau_ext"][:5], tau[:5], rtol=1e-2, atol=1e-3)


def test_an_asymmetric_point_grasp_follows_the_lever_rule():
    # point welds (forces only) at -0.05 and +0.15 m from the bar's centre: 0.75 / 0.25 of its weight
    sim = two_holders(-0.05, 0.15, grasp_options=dict(weld_moment=False))
    sim.run(1.0, progress=False)
    assert sim.holding(0) == "bar" and sim.holding(1) == "bar"
    fa, fb = sim.weld_wrench(0), sim.weld_wrench(1)
    assert np.all(fa[3:] == 0) and np.all(fb[3:] == 0)
    assert fa[2] + fb[2] == pytest.approx(G_BAR, rel=1e-6)
    assert fa[2] / G_BAR == pytest.approx(0.75, abs=1e-4) and fb[2] / G_BAR == pytest.approx(0.25, abs=1e-4)
    # 6-DOF welds at the same places share it by their compliance instead (measured 0.62/0.38)
    sim = two_holders(-0.05, 0.15)
    sim.run(1.0, progress=False)
    fa6 = sim.weld_wrench(0)[2] / G_BAR
    assert 0.5 < fa6 < 0.75 and sim.weld_wrench(0)[2] + sim.weld_wrench(1)[2] == pytest.approx(G_BAR, rel=1e-6)


def test_a_pick_and_move_with_the_weld_follows_the_payload_oracle_within_the_welds_sag():
    # grasp the box, lift it, swing the arm; then the same motion by the robot with the box lumped into its
    # clamp link (the exact oracle), both under one control law (PID with the oracle's gravity model).
    # The weld differs from the rigid payload only by its compliance: the clamp link's paths differ by at
    # most the sag F / k of the weld at the peak force F, with k = m_red omega^2, omega = 0.2 / dt, and
    # m_red the reduced mass of box and robot at the weld's point in its most compliant direction
    he = BOX * [1, 2 / 3, 1]
    gains = dict(kp=[400, 400, 2000, 20, 20, 500], ki=[0] * 6, kd=[40, 40, 100, 2, 2, 20])
    q1 = Q0.copy()
    q1[5] = 0.019
    lifted = q1.copy()
    lifted[2] -= 0.05
    swung = lifted + [0.3, -0.2, 0, 0, 0, 0]
    r, w = scene(he)
    grasp_only = cs.Simulation(dt=DT, world=w)
    grasp_only.add_robot(r, cs.PID(**gains), cs.CubicTrajectory([0, 0.02, 0.12], np.array([Q0, Q0, q1])))
    grasp_only.run(0.15, progress=False)
    q = grasp_only.state(0)[0]
    X = np.linalg.solve(r.frames(q)[5], grasp_only.body_state("box").pose)
    oracle = payload_robot(r, X, 0.1, he)

    r, w = scene(he)
    welded = cs.Simulation(dt=DT, world=w)
    welded.add_robot(r, cs.PID(**gains, model=oracle),
                     cs.CubicTrajectory([0, 0.02, 0.12, 0.2, 0.4, 0.9, 1.3], np.array([Q0, Q0, q1, q1, lifted, swung,
                                                                                      swung])))
    welded.run(0.4, progress=False)
    assert welded.holding(0) == "box"
    q_start, qd_start = welded.state(0)
    rigid = cs.Simulation(dt=DT)
    rigid.add_robot(oracle, cs.PID(**gains), cs.CubicTrajectory([0, 0.5, 0.9], np.array([lifted, swung, swung])),
                    q0=q_start, qd0=qd_start)
    lw, lr = welded.run(1.3, progress=False), rigid.run(0.9, progress=False)
    k = lw.t >= 0.4 - 1e-9
    Qw, Qr = lw.q[k][:len(lr.t)], lr.q
    assert np.abs(Qw[-1] - swung)[:5].max() < 1e-3  # it did move
    # the bound: the weld's sag at its peak force
    F = np.linalg.norm(lw[0].weld[k][:, :3], axis=1).max()
    link = r.clamp.fixed_link
    c = np.linalg.solve(r.frames(q_start)[link], [*welded.body_state("box").position, 1.0])[:3]
    J = r.jacobian(q_start, link, c)[:3]
    robot_inv = np.linalg.eigvalsh(J @ np.linalg.solve(r.mass_matrix(q_start), J.T)).max()
    m_red = 1.0 / (1.0 / 0.1 + robot_inv)
    sag = F / (m_red * (0.2 / DT) ** 2)
    diff = max(np.linalg.norm(r.frames(a)[link][:3, 3] - r.frames(b)[link][:3, 3]) for a, b in zip(Qw[::10], Qr[::10]))
    assert diff <= sag, (diff, sag)
    assert np.abs(Qw - Qr)[:, :5].max() < sag / 0.1  # joints: the sag over a lever of at least 10 cm
