"""Published robot data goes in as published: links without mass, inertia
tensors that break the triangle inequality (a warning), CoM vectors in the
link frames, rotor inertia (armature) and Coulomb friction, in both
backends and everywhere the dynamics are used."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import coopsim as cs
from conftest import FLEET_SEEDS, random_robot, random_state

# The Puma 560 as the Robotics Toolbox's Puma560 model (standard DH) gives it,
# after Armstrong, Khatib and Burdick (1986) and Corke and Armstrong-Helouvry
# (1994): link 1 has no mass (its CoM sits on its own axis) and an inertia
# about one axis only, which no rigid body has (I1 + I2 < I3; link 3's breaks
# it too); motor inertia
# Jm (kg m^2), gear ratio G and Coulomb friction Tc (N m, motor side, the mean
# of the two directions' magnitudes) per joint.
PUMA_DH = np.array([[0.0, 0.0, 0.0, np.pi / 2], [0.0, 0.0, 0.4318, 0.0], [0.0, 0.15005, 0.0203, -np.pi / 2],
                    [0.0, 0.4318, 0.0, np.pi / 2], [0.0, 0.0, 0.0, -np.pi / 2], [0.0, 0.0, 0.0, 0.0]])
PUMA_MASS = np.array([0.0, 17.4, 4.8, 0.82, 0.34, 0.09])
PUMA_COM = np.array([[0, 0, 0], [-0.3638, 0.006, 0.2275], [-0.0203, -0.0141, 0.070], [0, 0.019, 0], [0, 0, 0],
                     [0, 0, 0.032]])
PUMA_I = np.array([[0, 0.35, 0], [0.13, 0.524, 0.539], [0.066, 0.086, 0.0125], [1.8e-3, 1.3e-3, 1.8e-3],
                   [0.3e-3, 0.4e-3, 0.3e-3], [0.15e-3, 0.15e-3, 0.04e-3]])
PUMA_JM = np.array([200e-6, 200e-6, 200e-6, 33e-6, 33e-6, 33e-6])
PUMA_G = np.array([-62.6111, 107.815, -53.7063, 76.0364, 71.923, 76.686])
PUMA_TC = np.array([0.415, 0.0985, 0.1185, 14.05e-3, 11.88e-3, 7.23e-3])


def puma(**kw):
    inertias = np.array([np.diag(d) for d in PUMA_I])
    return cs.Robot.from_dh(PUMA_DH, PUMA_COM, PUMA_MASS, inertias, "RRRRRR", armature=PUMA_JM * PUMA_G**2,
                            coulomb=PUMA_TC * np.abs(PUMA_G), name="puma560", **kw)


def test_puma560_published_data_goes_in():
    """A zero-mass first link and a tensor breaking the triangle inequality: a warning naming the
    link, not a refusal (an error on request); M stays positive definite and includes J_m G^2."""
    with pytest.warns(cs.InertiaWarning) as rec:
        r = puma()
    # links 1 and 3 break it (link 3: 0.0125 + 0.066 < 0.086 kg m^2)
    assert [str(w.message)[:60] for w in rec] == [
        f"link {i}: inertia tensor breaks the triangle inequality of its" for i in (1, 3)]
    assert r.masses[0] == 0.0 and len(r.inertia_warnings) == 2
    with pytest.raises(ValueError, match="link 1: inertia tensor breaks the triangle inequality"):
        puma(inertia_check="error")
    rng = np.random.default_rng(0)
    for _ in range(20):
        q, qd, qdd = random_state(r, rng)
        M = r.mass_matrix(q)
        assert np.linalg.eigvalsh(M).min() > 0
        # the armature is M's diagonal beyond the rigid bodies' (the same robot without it)
        np.testing.assert_allclose(np.diag(M - rigid_puma().mass_matrix(q)), PUMA_JM * PUMA_G**2, rtol=1e-13)
        tau = r.inverse_dynamics(q, qd, qdd)
        np.testing.assert_allclose(r.forward_dynamics(q, qd, tau), qdd, rtol=1e-9, atol=1e-9)
    # link 1 has no mass: joint 1 moves the rest of the arm and link 1's inertia about its axis only
    # (y of frame 1 = the joint axis z0 turned by alpha_1)
    assert r.mass_matrix(np.zeros(6))[0, 0] > PUMA_I[0, 1]


def rigid_puma():
    inertias = np.array([np.diag(d) for d in PUMA_I])
    return cs.Robot.from_dh(PUMA_DH, PUMA_COM, PUMA_MASS, inertias, "RRRRRR", inertia_check="ignore")


def test_zero_mass_link_with_positive_definite_mass_matrix():
    """A massless, inertia-less middle link works: the next link carries the joint's load."""
    dh = np.array([[0, 0.3, 0, np.pi / 2], [0, 0, 0.4, 0], [0, 0, 0.3, 0]])
    com = np.array([[0, 0, 0], [-0.2, 0, 0], [-0.15, 0, 0]])
    I = np.array([np.zeros((3, 3)), np.diag([0.01, 0.05, 0.05]), np.diag([0.01, 0.03, 0.03])])
    r = cs.Robot.from_dh(dh, com, [0.0, 2.0, 1.0], I, "RRR")
    q = np.array([0.3, -0.4, 0.9])
    assert np.linalg.eigvalsh(r.mass_matrix(q)).min() > 0
    t, Q, QD = cs.integrate(r, q, np.zeros(3), np.zeros(3), dt=1e-3, steps=100)
    assert np.all(np.isfinite(Q))


def test_zero_mass_link_that_makes_mass_matrix_singular_raises_naming_the_state():
    """The last link without mass or inertia: nothing resists joint 3, M is singular; forward
    dynamics (and so RK4 and the simulation) raise a ValueError that names q."""
    dh = np.array([[0, 0.3, 0, np.pi / 2], [0, 0, 0.4, 0], [0, 0, 0.3, 0]])
    com = np.array([[0, 0, 0], [-0.2, 0, 0], [-0.15, 0, 0]])
    I = np.array([np.diag([0.01, 0.01, 0.01]), np.diag([0.01, 0.05, 0.05]), np.zeros((3, 3))])
    r = cs.Robot.from_dh(dh, com, [1.0, 2.0, 0.0], I, "RRR")
    q = np.array([0.25, -0.5, 0.75])
    M = r.mass_matrix(q)  # evaluating M itself is fine: it is what it is
    assert np.all(M[2] == 0)
    msg = r"mass matrix is not positive definite at q = \[0.25, -0.5, 0.75\]"
    with pytest.raises(ValueError, match=msg):
        r.forward_dynamics(q, np.zeros(3), np.zeros(3))
    with pytest.raises(cs.DivergenceError, match=msg):  # the integrator names step and time too
        cs.integrate(r, q, np.zeros(3), np.zeros(3), dt=1e-3, steps=10)
    # a prismatic joint carrying nothing: the same
    r2 = cs.Robot.from_dh(dh, com, [1.0, 2.0, 0.0], I, "RRP")
    with pytest.raises(ValueError, match="not positive definite at q"):
        r2.forward_dynamics(q, np.zeros(3), np.zeros(3))


# ------------------------------------------------------------------ CoM vectors

@pytest.mark.parametrize("seed", list(FLEET_SEEDS)[:20])
def test_com_vectors_equal_com_table(seed):
    """A robot given as CoM vectors and link-frame inertias equals the same robot given as the
    paper's CoM table, to 1e-13 (the CoM frames' positions equal, their orientation is free)."""
    r = random_robot(seed, mixed=True)
    v = cs.Robot.from_dh(r.dh, r.com_positions, r.masses, r.link_inertias, r.joint_types,
                         friction=r.friction_coefficients, base_position=r.base_position, base_yaw=r.base_yaw)
    np.testing.assert_allclose(v.com_positions, r.com_positions, rtol=0, atol=1e-15)
    np.testing.assert_allclose(v.link_inertias, r.link_inertias, rtol=0, atol=1e-15)
    rng = np.random.default_rng(seed)
    for _ in range(5):
        q, qd, qdd = random_state(r, rng)
        np.testing.assert_allclose(v.com_frames(q)[:, :3, 3], r.com_frames(q)[:, :3, 3], rtol=0, atol=1e-13)
        for f, args in (("mass_matrix", (q,)), ("gravity", (q,)), ("coriolis", (q, qd)),
                        ("coriolis_matrix", (q, qd)), ("inverse_dynamics", (q, qd, qdd))):
            x, y = getattr(v, f)(*args), getattr(r, f)(*args)
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-13 * max(1.0, np.abs(y).max()), err_msg=f)


def _kinetic_energy_from_links(r, q, qd, com, inertia):
    """sum 1/2 m |v_c|^2 + 1/2 w^T (R I R^T) w from the CoM vectors and link-frame inertias
    directly (point Jacobians of the DH frames), independent of the CoM rows."""
    F = r.frames(q)
    T = 0.0
    for i in range(r.dof):
        J = r.jacobian(q, link=i + 1, point=com[i])
        v, w = J[:3] @ qd, J[3:] @ qd
        R = F[i + 1][:3, :3]
        T += 0.5 * r.masses[i] * v @ v + 0.5 * w @ (R @ inertia[i] @ R.T) @ w
    return T


@pytest.mark.parametrize("types", ["RRR", "RPR", "PRP"])
def test_com_vectors_on_joint_axes(types):
    """CoMs on their own joint axis (x, y of the CoM zero in the frame before the joint turns) and
    elsewhere: the CoM rows chosen put every CoM where the vector says, and the kinetic and
    potential energies equal those computed from the vectors directly, to 1e-13."""
    dh = np.array([[0.2, 0.1, 0.3, np.pi / 2], [-0.4, 0.05, 0.25, -0.7], [0.3, 0.0, 0.2, 0.0]])
    # link 1: CoM on axis z0 (x = -a, y cos(alpha) - z sin(alpha) = 0); link 2 general; link 3 on
    # axis z2 with alpha = 0
    com = np.array([[-0.3, 0.0, 0.0], [0.05, -0.1, 0.07], [-0.2, 0.0, 0.12]])
    rng = np.random.default_rng(1)
    from conftest import random_inertia
    masses = np.array([1.5, 2.0, 0.7])
    I = np.array([random_inertia(rng, m) for m in masses])
    r = cs.Robot.from_dh(dh, com, masses, I, types, gravity=(0.3, -1.0, -9.81))
    np.testing.assert_array_equal(r.com[[0, 2], 2], [0.0, 0.0])  # a_c = 0: on the axis
    np.testing.assert_allclose(r.com_positions, com, rtol=0, atol=1e-16)
    np.testing.assert_allclose(r.link_inertias, I, rtol=0, atol=1e-16)
    for _ in range(10):
        q, qd, _ = random_state(r, rng)
        F = r.frames(q)
        c = np.array([F[i + 1][:3, :3] @ com[i] + F[i + 1][:3, 3] for i in range(3)])
        np.testing.assert_allclose(r.com_frames(q)[:, :3, 3], c, rtol=0, atol=1e-15)
        Tk, V = r.energy(q, qd)
        np.testing.assert_allclose(Tk, _kinetic_energy_from_links(r, q, qd, com, I), rtol=1e-13)
        np.testing.assert_allclose(V, -np.sum(masses * (c @ r.gravity_acceleration)), rtol=1e-13)


@pytest.mark.parametrize("types", ["RRR", "RPR", "PRP"])
def test_com_vectors_equal_hand_written_table_with_coms_on_axes(types):
    """The paper's CoM table written by hand, two of its CoMs on their joint axes (a_c = 0) and one
    anywhere, its vectors and link-frame inertias computed here with dh_transform; the robot given
    the vectors equals the robot given the table to 1e-13."""
    dh = np.array([[0.2, 0.1, 0.3, np.pi / 2], [-0.4, 0.05, 0.25, -0.7], [0.3, 0.0, 0.2, 0.0]])
    table = np.array([[0.2, 0.1, 0.0, np.pi / 2],     # on axis z0: the CoM frame is frame 1 slid back by a
                      [0.1, 0.08, 0.1, 0.3],           # anywhere
                      [0.3, 0.12, 0.0, 0.0]])          # on axis z2
    rng = np.random.default_rng(8)
    from conftest import random_inertia
    masses = np.array([1.5, 2.0, 0.7])
    I_com = np.array([random_inertia(rng, m) for m in masses])  # in the CoM frames
    vec, I_link = [], []
    for i in range(3):
        # frame i -> CoM frame, q in the same slot of both rows (q = 0 here: the transform is constant)
        X = np.linalg.inv(cs.dh_transform(*dh[i])) @ cs.dh_transform(*table[i])
        vec.append(X[:3, 3])
        I_link.append(X[:3, :3] @ I_com[i] @ X[:3, :3].T)
    a = cs.Robot.from_dh(dh, table, masses, I_com, types)
    b = cs.Robot.from_dh(dh, np.array(vec), masses, np.array(I_link), types)
    for _ in range(10):
        q, qd, qdd = random_state(a, rng)
        for f, args in (("mass_matrix", (q,)), ("gravity", (q,)), ("coriolis", (q, qd)),
                        ("inverse_dynamics", (q, qd, qdd))):
            x, y = getattr(b, f)(*args), getattr(a, f)(*args)
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-13 * max(1.0, np.abs(y).max()), err_msg=f)
        np.testing.assert_allclose(b.com_frames(q)[:, :3, 3], a.com_frames(q)[:, :3, 3], rtol=0, atol=1e-15)


def test_com_vectors_bad_shape():
    with pytest.raises(ValueError, match="wrong shape for com"):
        cs.Robot.from_dh(np.zeros((2, 4)), np.zeros((2, 2)), [1, 1], np.array([np.eye(3)] * 2) * 0.01, "RR")
    with pytest.raises(ValueError, match="com must be finite"):
        cs.Robot.from_dh(np.zeros((2, 4)), np.full((2, 3), np.nan), [1, 1], np.array([np.eye(3)] * 2) * 0.01, "RR")


# ----------------------------------------------------- armature and Coulomb friction

def _loaded(r, armature, coulomb, width=0.05):
    return cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, r.joint_types, friction=r.friction_coefficients,
                            q_limits=r.q_limits, tau_limits=r.tau_limits, name=r.name, armature=armature,
                            coulomb=coulomb, coulomb_width=width, boxes=r.boxes, clamp=r.clamp, tool=r.tool,
                            base_position=r.base_position, base_yaw=r.base_yaw)


ARMATURE = np.array([0.05, 0.03, 0.8, 0.004, 0.002, 0.3])
COULOMB = np.array([1.5, 0.8, 6.0, 0.1, 0.05, 2.0])


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_armature_and_coulomb_in_both_backends(name):
    """The generated code reads armature, F_c and v_c at run time: the same numbers as the
    numeric backend; M gains the armature on its diagonal, the torques F_c tanh(qd / v_c)."""
    base = getattr(cs.robots, name)(backend="numeric")
    num = _loaded(base, ARMATURE, COULOMB)
    gen = num.with_generated(name)
    assert gen.backend == "generated"
    rng = np.random.default_rng(3)
    for _ in range(20):
        q, qd, qdd = random_state(num, rng)
        tau = rng.normal(size=6) * 5
        np.testing.assert_allclose(num.mass_matrix(q) - base.mass_matrix(q), np.diag(ARMATURE), rtol=0, atol=1e-14)
        fr = num.friction_coefficients * qd + COULOMB * np.tanh(qd / 0.05)
        np.testing.assert_allclose(num.friction(qd), fr, rtol=1e-15, atol=0)
        np.testing.assert_allclose(num.inverse_dynamics(q, qd, qdd),
                                   base.inverse_dynamics(q, qd, qdd) + ARMATURE * qdd + COULOMB * np.tanh(qd / 0.05),
                                   rtol=0, atol=1e-12)
        for f, args in (("mass_matrix", (q,)), ("inverse_dynamics", (q, qd, qdd)),
                        ("forward_dynamics", (q, qd, tau))):
            x, y = getattr(gen, f)(*args), getattr(num, f)(*args)
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-10 * max(1.0, np.abs(y).max()), err_msg=f)
    # the parameter vector carries them (19 per link)
    p = gen.parameter_vector.reshape(-1)[:19 * 6].reshape(6, 19)
    np.testing.assert_array_equal(p[:, 16], ARMATURE)
    np.testing.assert_array_equal(p[:, 17], COULOMB)
    np.testing.assert_array_equal(p[:, 18], 0.05)


def test_coulomb_friction_never_adds_energy():
    """SCARA #1 with armature and Coulomb friction only (viscous K = 0), released under gravity
    with zero torque: its power qd . F_c tanh(qd / v_c) is >= 0, and the energy (with the rotors'
    kinetic energy, 1/2 qd^T M qd) never increases beyond round-off while it falls."""
    base = cs.robots.scara1(backend="numeric", friction=np.zeros(6))
    r = _loaded(base, ARMATURE, COULOMB * 0.2, width=0.05)
    rng = np.random.default_rng(5)
    for _ in range(100):
        qd = rng.normal(size=6) * rng.choice([1e-3, 1e-1, 10])
        assert qd @ r.friction(qd) >= 0
    q0 = np.array([0.3, -0.6, 0.05, 0.4, 1.2, 0.02])
    qd0 = np.array([2.0, -1.5, 0.2, 3.0, -2.0, 0.05])
    t, Q, QD = cs.integrate(r, q0, qd0, np.zeros(6), dt=2e-4, steps=5000, end_stops=False, record_every=5)
    E = np.array([sum(r.energy(q, qd)) for q, qd in zip(Q, QD)])
    assert np.diff(E).max() <= 1e-12 * np.abs(E).max()
    assert E[-1] < E[0] - 0.1


def test_computed_torque_uses_armature_and_coulomb_of_its_model():
    """A simulation whose controller's model is the plant (armature and Coulomb friction included)
    tracks a trajectory within the torque hold's error (the same SCARA without them, its own
    model: 2.3e-4 rad at most); given the model without them, the error is over 100 times that."""
    r = _loaded(cs.robots.scara1(backend="numeric"), ARMATURE, COULOMB)
    q0 = np.array([0.2, 0.4, 0.05, 0.1, np.pi / 2, 0.02])
    traj = cs.CubicTrajectory([0.0, 0.5], np.array([q0, q0 + [0.5, -0.3, 0.03, 0.4, 0.0, 0.01]]))
    sim = cs.Simulation(dt=2e-4, log_every=10)
    sim.add_robot(r, cs.ComputedTorque(kp=400.0, kd=40.0), traj)
    log = sim.run(0.5)
    err = np.abs(log[0].q - log[0].q_ref).max()
    assert err < 1e-4
    # without the model's armature and Coulomb friction the error is orders larger
    sim2 = cs.Simulation(dt=2e-4, log_every=10)
    wrong = cs.robots.scara1(backend="numeric")
    sim2.add_robot(r, cs.ComputedTorque(kp=400.0, kd=40.0, model=wrong), traj)
    log2 = sim2.run(0.5)
    assert np.abs(log2[0].q - log2[0].q_ref).max() > 100 * err


def test_armature_coulomb_bad_input():
    r = cs.robots.scara1(backend="numeric")
    with pytest.raises(ValueError, match="link 2: armature must be finite and >= 0"):
        _loaded(r, [0, -1, 0, 0, 0, 0], 0.0)
    with pytest.raises(ValueError, match="link 1: Coulomb friction must be finite and >= 0"):
        _loaded(r, 0.0, [-1, 0, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="Coulomb friction width must be finite and > 0"):
        _loaded(r, 0.0, 1.0, width=0.0)
    with pytest.raises(ValueError, match="wrong shape for armature"):
        _loaded(r, [1.0, 2.0], 0.0)
    with pytest.raises(ValueError, match="coulomb must be finite"):
        _loaded(r, 0.0, np.nan)


def test_pickle_keeps_armature_coulomb_and_base_orientation():
    import pickle
    R = cs.dh_transform(0.0, 0.0, 0.0, 0.4)[:3, :3]
    r = _loaded(cs.robots.scara1(), ARMATURE, COULOMB).with_base_orientation(R)
    p = pickle.loads(pickle.dumps(r))
    for k in ("armature", "coulomb", "coulomb_width", "base_orientation", "base"):
        np.testing.assert_array_equal(getattr(p, k), getattr(r, k), err_msg=k)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pickle.loads(pickle.dumps(puma(inertia_check="ignore")))  # no warning when unpickled
