"""The dynamics' derivatives (Robot.forward_dynamics_derivatives, Robot.inverse_dynamics_derivatives,
cs.forward_dynamics_derivatives_batch): against central differences of the dynamics they differentiate
(friction viscous and Coulomb, armature, wrenches at the tool and on links), against Pinocchio's
computeRNEADerivatives / computeABADerivatives on the SCARAs' exported URDF and on arms of the
example-robot-data wheel, the batch against the single call, and bad input named in one line."""
from __future__ import annotations

import importlib.metadata
import os
import tempfile

import numpy as np
import pytest

import coopsim as cs
import coopsim.codegen
from conftest import random_fleet, random_state

pin = pytest.importorskip("pinocchio", reason="Pinocchio ('pin' on PyPI) is installed by the test extra")

SCARAS = [cs.robots.scara1(backend="numeric"), cs.robots.scara2(backend="numeric")]


def _rel(x, y):
    """max |x - y| over max |y|: the error relative to the matrix's largest entry."""
    x, y = np.asarray(x), np.asarray(y)
    return np.abs(x - y).max() / np.abs(y).max()


def _central(f, x, h=1e-6):
    """Central differences of f at x, column k = df/dx_k, steps h max(1, |x_k|)."""
    cols = []
    for k in range(len(x)):
        e = np.zeros(len(x))
        e[k] = h * max(1.0, abs(x[k]))
        cols.append((f(x + e) - f(x - e)) / (2 * e[k]))
    return np.array(cols).T


def _with_drives(robot, seed):
    """The robot with armature and Coulomb friction on every joint (its viscous friction kept)."""
    rng = np.random.default_rng(seed)
    n = robot.dof
    return cs.Robot.from_dh(robot.dh, robot.com, robot.masses, robot.inertias, robot.joint_types,
                            friction=robot.friction_coefficients, q_limits=robot.q_limits,
                            armature=rng.uniform(0.01, 0.2, n), coulomb=rng.uniform(0.2, 2.0, n),
                            coulomb_width=rng.uniform(0.2, 1.0, n), tool=robot.tool, name=robot.name + "_drives")


def _states(robot, seed, count):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q, qd, qdd = random_state(robot, rng)
        yield q, 2 * qd, qdd, 5 * rng.normal(size=robot.dof)


def _wrenches(robot):
    """None, a wrench at the tool centre point, and wrenches on two links at points off their frames."""
    n = robot.dof
    return [None, np.array([3.0, -2.0, 5.0, 0.3, -0.2, 0.4]),
            [cs.Wrench(n - 1, [0.05, -0.02, 0.03], [1.0, 2.0, -3.0, 0.1, 0.2, 0.3]),
             cs.Wrench(2, [0.1, 0.0, -0.04], [-2.0, 0.5, 1.0, 0.0, -0.3, 0.2])]]


FD_ROBOTS = SCARAS + [_with_drives(r, 7 + i) for i, r in enumerate(SCARAS)] + random_fleet()[:4]


@pytest.mark.parametrize("robot", FD_ROBOTS, ids=[r.name for r in FD_ROBOTS])
def test_derivatives_equal_central_differences(robot):
    """Both derivatives equal central differences of inverse_dynamics and forward_dynamics to 1e-6
    relative, at random states, with no external wrench, a wrench at the tool and wrenches on links;
    dtau/dqdd is M and dqdd/dtau its inverse."""
    for q, qd, qdd, tau in _states(robot, robot.dof, 3):
        for f_ext in _wrenches(robot):
            dq, dqd, M = robot.inverse_dynamics_derivatives(q, qd, qdd, f_ext)
            assert _rel(dq, _central(lambda x: robot.inverse_dynamics(x, qd, qdd, f_ext), q)) <= 1e-6
            assert _rel(dqd, _central(lambda x: robot.inverse_dynamics(q, x, qdd, f_ext), qd)) <= 1e-6
            assert _rel(M, _central(lambda x: robot.inverse_dynamics(q, qd, x, f_ext), qdd)) <= 1e-6
            np.testing.assert_allclose(M, robot.mass_matrix(q), rtol=0, atol=1e-13 * np.abs(M).max())
            aq, aqd, Minv = robot.forward_dynamics_derivatives(q, qd, tau, f_ext)
            assert _rel(aq, _central(lambda x: robot.forward_dynamics(x, qd, tau, f_ext), q)) <= 1e-6
            assert _rel(aqd, _central(lambda x: robot.forward_dynamics(q, x, tau, f_ext), qd)) <= 1e-6
            assert _rel(Minv, _central(lambda x: robot.forward_dynamics(q, qd, x, f_ext), tau)) <= 1e-6
            np.testing.assert_allclose(Minv @ M, np.eye(robot.dof), atol=1e-10)


def _forward_is_minus_minv_times_inverse(robot, seed, tol):
    """At three states (of seed) with a wrench at the tool: dqdd/dx = -M^-1 dtau/dx, the inverse dynamics'
    derivatives taken at qdd = FD(q, qd, tau), and dqdd/dtau = M^-1, each to tol of its largest entry."""
    f_ext = np.array([1.0, 2.0, -1.0, 0.1, 0.0, 0.2])
    for q, qd, _, tau in _states(robot, seed, 3):
        qdd = robot.forward_dynamics(q, qd, tau, f_ext)
        dq, dqd, M = robot.inverse_dynamics_derivatives(q, qd, qdd, f_ext)
        aq, aqd, Minv = robot.forward_dynamics_derivatives(q, qd, tau, f_ext)
        np.testing.assert_allclose(aq, -np.linalg.solve(M, dq), rtol=0, atol=tol * np.abs(aq).max())
        np.testing.assert_allclose(aqd, -np.linalg.solve(M, dqd), rtol=0, atol=tol * np.abs(aqd).max())
        np.testing.assert_allclose(Minv, np.linalg.inv(M), rtol=0, atol=tol * np.abs(Minv).max())


def test_forward_derivatives_are_minus_minv_times_the_inverse_ones_at_the_forward_acceleration():
    """dqdd/dx = -M^-1 dtau/dx with the inverse dynamics' derivatives taken at qdd = FD(q, qd, tau)."""
    _forward_is_minus_minv_times_inverse(_with_drives(SCARAS[0], 3), 11, 1e-10)


def test_coulomb_derivative_is_the_smooth_models_at_and_away_from_zero_velocity():
    """The Coulomb term F_c tanh(qd / v_c) is smooth: dtau_j/dqd_j has K + F_c / v_c at qd_j = 0 and
    K + F_c / v_c (1 - tanh^2) elsewhere, over what the rigid body alone gives."""
    robot = _with_drives(SCARAS[1], 5)
    bare = cs.Robot.from_dh(robot.dh, robot.com, robot.masses, robot.inertias, robot.joint_types,
                            armature=robot.armature, q_limits=robot.q_limits)
    K, Fc, vc = robot.friction_coefficients, robot.coulomb, robot.coulomb_width
    q, qdd = np.array([0.3, -0.5, 0.1, 0.4, 0.7, 0.02]), np.linspace(-1, 1, 6)
    for qd in (np.zeros(6), np.array([0.0, 0.3, -0.05, 2.0, -1.0, 0.01])):
        dqd = robot.inverse_dynamics_derivatives(q, qd, qdd)[1]
        rigid = bare.inverse_dynamics_derivatives(q, qd, qdd)[1]
        expected = K + Fc / vc * (1 - np.tanh(qd / vc) ** 2)
        np.testing.assert_allclose(np.diag(dqd - rigid), expected, rtol=1e-12)
        np.testing.assert_allclose(dqd - rigid - np.diag(expected), 0, atol=1e-12)


def _generated_variants(which):
    """The built-in SCARA as it comes, with other dimensions, masses, friction, a turned base and a tilted
    gravity, and with armature and Coulomb friction on every joint: (generated, numeric) pairs."""
    factory = getattr(cs.robots, which)
    changed = dict(masses=[4.0, 1.5, 1.1, 0.4, 0.3, 0.08], friction=[0.3, 0.2, 1.0, 0.1, 0.0, 0.5], base_yaw=0.7,
                   gravity=(0.4, -0.3, -9.7), L1=0.42 if which == "scara1" else 0.25)
    drives = _with_drives(factory(backend="numeric"), 13).with_generated(which)
    return [(factory(), factory(backend="numeric")), (factory(**changed), factory(backend="numeric", **changed)),
            (drives, drives.with_backend("numeric"))]


@pytest.mark.parametrize("which", ["scara1", "scara2"])
def test_generated_derivatives_equal_the_recursive_ones(which):
    """The generated SCARAs take their derivatives from the symbolic model (emitted C++,
    GeneratedDynamics::derivatives): equal to the recursive algorithm's to 1e-12 relative, both calls,
    with other parameters, armature and Coulomb friction, and with wrenches at the tool and on links (whose
    term is the recursive one's). Not the same arithmetic: the two differ in the last bits somewhere."""
    last_bits = False
    for gen, num in _generated_variants(which):
        assert gen.backend == "generated" and num.backend == "numeric"
        assert cs.codegen.info(gen)["derivatives"] is True
        for q, qd, qdd, tau in _states(gen, 2, 4):
            for f_ext in _wrenches(gen):
                pairs = [(gen.forward_dynamics_derivatives(q, qd, tau, f_ext),
                          num.forward_dynamics_derivatives(q, qd, tau, f_ext)),
                         (gen.inverse_dynamics_derivatives(q, qd, qdd, f_ext),
                          num.inverse_dynamics_derivatives(q, qd, qdd, f_ext))]
                for ours, theirs in pairs:
                    for a, b in zip(ours, theirs):
                        assert _rel(a, b) <= 1e-12
                        last_bits |= not np.array_equal(a, b)
    assert last_bits


def test_generated_forward_derivatives_are_taken_at_forward_dynamics_acceleration():
    """The generated path takes qdd from forward_dynamics' own computation (the generated dynamics and
    LDL^T): its forward derivatives equal -M^-1 times its inverse ones at that qdd."""
    _forward_is_minus_minv_times_inverse(_generated_variants("scara2")[2][0], 5, 1e-11)


# ---- out= and the arguments read in place ----

@pytest.mark.parametrize("backend", ["generated", "numeric"])
def test_out_receives_the_results_in_place(backend):
    """out= (three float64 (n, n) arrays) gets the same values as new arrays, and the call returns them."""
    r = cs.robots.scara1(backend=backend)
    for q, qd, qdd, tau in _states(r, 3, 2):
        for call, x in ((r.forward_dynamics_derivatives, tau), (r.inverse_dynamics_derivatives, qdd)):
            fresh = call(q, qd, x)
            out = tuple(np.full((6, 6), np.nan) for _ in range(3))
            got = call(q, qd, x, out=out)
            assert got is out or all(g is o for g, o in zip(got, out))
            for a, b in zip(out, fresh):
                np.testing.assert_array_equal(a, b)
            block = np.empty((3, 6, 6))
            got = call(q, qd, x, None, out=list(block))  # views of one block, as a list
            np.testing.assert_array_equal(block, np.array(fresh))
            assert isinstance(got, tuple) and len(got) == 3


def test_arguments_of_any_layout_give_the_same_results():
    """float64 C-contiguous arrays are read in place; lists, other dtypes, strided and byte-swapped arrays are
    converted: the same results, bit for bit."""
    r = cs.robots.scara2()
    q, qd, _, tau = next(_states(r, 8, 1))
    ref = r.forward_dynamics_derivatives(q, qd, tau)
    wide = np.zeros((6, 2))
    wide[:, 0] = qd
    for args in ([list(q), list(qd), list(tau)], [q.astype(">f8"), wide[:, 0], tau],
                 [q, qd, np.asfortranarray(tau)], [q.astype(np.longdouble), qd, tau]):
        for a, b in zip(r.forward_dynamics_derivatives(*args), ref):
            np.testing.assert_array_equal(a, b)
    readonly = q.copy()
    readonly.flags.writeable = False
    for a, b in zip(r.forward_dynamics_derivatives(readonly, qd, tau), ref):
        np.testing.assert_array_equal(a, b)


def test_bad_out_is_named_in_one_line_and_nothing_is_written():
    r = cs.robots.scara1()
    z = np.zeros(6)
    good = np.empty((6, 6))
    ro = np.zeros((6, 6))
    ro.flags.writeable = False
    bad = [np.empty((3, 6, 6)), (good, good), (good, good, good), (good, np.empty((6, 5)), np.empty((6, 6))),
           (np.empty((6, 6), np.float32), np.empty((6, 6)), np.empty((6, 6))),
           (np.empty((6, 6), order="F"), np.empty((6, 6)), np.empty((6, 6))),
           (ro, np.empty((6, 6)), np.empty((6, 6))), "abc", (1, 2, 3)]
    for out in bad:
        for call in (r.forward_dynamics_derivatives, r.inverse_dynamics_derivatives):
            with pytest.raises(ValueError) as e:
                call(z, z, z, out=out)
            _one_line(e, "out must be", "(6, 6)")
    assert not ro.any()
    # a result that is not finite: refused before anything is written
    for robot in (r, r.with_backend("numeric")):
        out = tuple(np.zeros((6, 6)) for _ in range(3))
        with pytest.raises(ValueError) as e:
            robot.inverse_dynamics_derivatives(r.q_limits.mean(axis=1), np.full(6, 1e200), z, out=out)
        _one_line(e, "inverse_dynamics_derivatives: result is not finite")
        assert not any(o.any() for o in out)


# ---- Pinocchio ----

def _example_robot_data(relative: str) -> str:
    """Path of a file shipped in the example-robot-data wheel (PyPI)."""
    for f in importlib.metadata.files("example-robot-data"):
        if str(f).endswith("robots/" + relative):
            return str(f.locate())
    raise FileNotFoundError(relative)


ARMS = {  # URDF in example-robot-data, joints locked
    "ur5": ("ur_description/urdf/ur5_robot.urdf", {}),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", {}),
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "z1": ("z1_description/urdf/z1.urdf", {}),
    "so100": ("so_arm_description/urdf/so100.urdf", {}),
}


def _pinocchio_pair(which):
    """(coopsim robot, Pinocchio model) of one robot, friction and armature alike on both sides:
    armature set in Pinocchio's model; friction (which Pinocchio's algorithms leave out) added to its
    results by the test."""
    if which in ARMS:
        rel, locked = ARMS[which]
        path = _example_robot_data(rel)
        robot = cs.Robot.from_urdf(path, locked=locked)
        model = pin.buildModelFromUrdf(path)
        if locked:
            model = pin.buildReducedModel(model, [model.getJointId(j) for j in locked], pin.neutral(model))
    else:
        robot = _with_drives(getattr(cs.robots, which)(backend="numeric"), 1)
        with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
            f.write(robot.to_urdf())
        try:
            model = pin.buildModelFromUrdf(f.name)
        finally:
            os.unlink(f.name)
    assert model.nq == model.nv == robot.dof
    model.armature[:] = robot.armature
    return robot, model


def _sym(A):
    return np.triu(A) + np.triu(A, 1).T


@pytest.mark.parametrize("which", ["scara1", "scara2"] + list(ARMS))
def test_derivatives_equal_pinocchio(which):
    """Against Pinocchio's computeRNEADerivatives and computeABADerivatives on the same URDF (the
    SCARAs exported with armature and Coulomb friction, the arms as shipped): 1e-10 relative."""
    robot, model = _pinocchio_pair(which)
    data = model.createData()
    n = robot.dof
    lim = np.clip(robot.q_limits, -np.pi, np.pi)
    rng = np.random.default_rng(len(which))
    for _ in range(10):
        q = rng.uniform(lim[:, 0], lim[:, 1])
        qd, qdd, tau = 2 * rng.normal(size=n), rng.normal(size=n), 5 * rng.normal(size=n)
        # friction's derivative, diagonal: viscous plus Coulomb (tanh)
        t = np.tanh(qd / robot.coulomb_width)
        D = np.diag(robot.friction_coefficients + robot.coulomb / robot.coulomb_width * (1 - t * t))
        dq, dqd, M = robot.inverse_dynamics_derivatives(q, qd, qdd)
        pin.computeRNEADerivatives(model, data, q, qd, qdd)
        assert _rel(dq, data.dtau_dq) <= 1e-10
        assert _rel(dqd, data.dtau_dv + D) <= 1e-10
        assert _rel(M, _sym(data.M)) <= 1e-10
        aq, aqd, Minv = robot.forward_dynamics_derivatives(q, qd, tau)
        pin.computeABADerivatives(model, data, q, qd, tau - robot.friction(qd))
        Minv_pin = _sym(data.Minv)
        assert _rel(aq, data.ddq_dq) <= 1e-10
        assert _rel(aqd, data.ddq_dv - Minv_pin @ D) <= 1e-10
        assert _rel(Minv, Minv_pin) <= 1e-10


# ---- the batch ----

def test_batch_equals_the_single_call_on_one_and_on_several_threads():
    robot = _with_drives(SCARAS[0], 9)
    rng = np.random.default_rng(4)
    N = 300
    lim = robot.q_limits
    Q = rng.uniform(lim[:, 0], lim[:, 1], size=(N, 6))
    QD, TAU = rng.normal(size=(N, 6)), 5 * rng.normal(size=(N, 6))
    one = cs.forward_dynamics_derivatives_batch(robot, Q, QD, TAU, threads=1)
    many = cs.forward_dynamics_derivatives_batch(robot, Q, QD, TAU, threads=3)
    assert all(x.shape == (N, 6, 6) for x in one)
    for a, b in zip(one, many):
        np.testing.assert_array_equal(a, b)
    for i in (0, 151, N - 1):
        for a, b in zip(one, robot.forward_dynamics_derivatives(Q[i], QD[i], TAU[i])):
            np.testing.assert_array_equal(a[i], b)
    empty = cs.forward_dynamics_derivatives_batch(robot, np.zeros((0, 6)), np.zeros((0, 6)), np.zeros((0, 6)))
    assert all(x.shape == (0, 6, 6) for x in empty)


def test_batch_writes_into_the_callers_arrays_when_given_out():
    """out=: the results land in the caller's three (N, n, n) arrays (a tuple is returned as given, a list as
    a tuple of its arrays), equal bit for bit to new arrays' results; a second call overwrites them."""
    robot = SCARAS[1]
    rng = np.random.default_rng(8)
    N = 70  # a chunk of 64 and six more
    Q, QD, TAU = rng.uniform(-1, 1, size=(N, 6)), rng.normal(size=(N, 6)), rng.normal(size=(N, 6))
    fresh = cs.forward_dynamics_derivatives_batch(robot, Q, QD, TAU)
    block = np.full((3, N, 6, 6), np.nan)
    out = tuple(block)
    got = cs.forward_dynamics_derivatives_batch(robot, Q, QD, TAU, threads=2, out=out)
    assert got is out
    for a, b in zip(fresh, block):
        np.testing.assert_array_equal(a, b)
    lst = [np.empty((N, 6, 6)) for _ in range(3)]
    got = cs.forward_dynamics_derivatives_batch(robot, Q[::-1], QD[::-1], TAU[::-1], threads=1, out=lst)
    assert isinstance(got, tuple) and all(g is x for g, x in zip(got, lst))
    for a, b in zip(fresh, lst):
        np.testing.assert_array_equal(a[::-1], b)


@pytest.mark.parametrize("which", ["scara1", "scara2"])
def test_generated_batch_takes_four_states_at_once_as_the_single_call_takes_one(which):
    """The generated robots' batch evaluates four states at once (one per lane of a vector), the rest and
    the leftover states one by one: every row equals the single call's result (to rounding of another
    instruction order) and the recursive algorithm's to 1e-12, on one and two threads; a bad state inside a
    group of four is named by its own row."""
    for gen, num in _generated_variants(which):
        rng = np.random.default_rng(21)
        N = 11  # two groups of four and three states alone
        lim = np.clip(gen.q_limits, -np.pi, np.pi)
        Q = rng.uniform(lim[:, 0], lim[:, 1], size=(N, 6))
        QD, TAU = 2 * rng.normal(size=(N, 6)), 5 * rng.normal(size=(N, 6))
        one = cs.forward_dynamics_derivatives_batch(gen, Q, QD, TAU, threads=1)
        two = cs.forward_dynamics_derivatives_batch(gen, Q, QD, TAU, threads=2)
        rec = cs.forward_dynamics_derivatives_batch(num, Q, QD, TAU, threads=1)
        for a, b, c in zip(one, two, rec):
            np.testing.assert_array_equal(a, b)
            assert _rel(a, c) <= 1e-12
        for i in range(N):
            for a, b in zip(one, gen.forward_dynamics_derivatives(Q[i], QD[i], TAU[i])):
                assert np.abs(a[i] - b).max() <= 1e-14 * np.abs(b).max()


# ---- bad input ----

def _one_line(excinfo, *words):
    text = str(excinfo.value)
    assert "\n" not in text
    for w in words:
        assert w in text, (w, text)


def test_bad_input_is_named_in_one_line():
    r = SCARAS[0]
    z = np.zeros(6)
    cases = [
        (lambda: r.forward_dynamics_derivatives(np.zeros(5), z, z), ("q", "(6,)", "(5,)")),
        (lambda: r.forward_dynamics_derivatives(z, np.zeros((6, 1)), z), ("qd", "(6,)")),
        (lambda: r.forward_dynamics_derivatives(z, z, [0, 0, np.nan, 0, 0, 0]), ("tau", "finite")),
        (lambda: r.forward_dynamics_derivatives(z, z, z, np.zeros(5)), ("f_ext", "(6,)")),
        (lambda: r.inverse_dynamics_derivatives([np.inf] + [0] * 5, z, z), ("q", "finite")),
        (lambda: r.inverse_dynamics_derivatives(z, z, np.zeros(7)), ("qdd", "(6,)")),
        (lambda: r.inverse_dynamics_derivatives(z, z, z, np.full(6, np.nan)), ("f_ext", "finite")),
        (lambda: cs.forward_dynamics_derivatives_batch(r, np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((2, 6))),
         ("tau", "(3, 6)", "(2, 6)")),
        (lambda: cs.forward_dynamics_derivatives_batch(r, np.zeros((3, 5)), np.zeros((3, 5)), np.zeros((3, 5))),
         ("q", "(N, 6)")),
        (lambda: cs.forward_dynamics_derivatives_batch(r, np.full((2, 6), np.nan), np.zeros((2, 6)),
                                                       np.zeros((2, 6))), ("q", "finite")),
        (lambda: cs.forward_dynamics_derivatives_batch(r, np.zeros((2, 6)), np.zeros((2, 6)), np.zeros((2, 6)),
                                                       threads=-1), ("threads",)),
        (lambda: cs.forward_dynamics_derivatives_batch(r, np.zeros((2, 6)), np.zeros((2, 6)), np.zeros((2, 6)),
                                                       out=tuple(np.empty((3, 3, 6, 6)))),
         ("out", "(2, 6, 6)", "float64 (3, 6, 6)")),
        (lambda: cs.forward_dynamics_derivatives_batch(r, np.zeros((2, 6)), np.zeros((2, 6)), np.zeros((2, 6)),
                                                       out=(np.empty((2, 6, 6)),) * 3), ("out", "distinct")),
        (lambda: cs.forward_dynamics_derivatives_batch(r, np.zeros((2, 6)), np.zeros((2, 6)), np.zeros((2, 6)),
                                                       out=np.empty((3, 2, 6, 6))), ("out", "(3, 2, 6, 6)")),
    ]
    for call, words in cases:
        with pytest.raises(ValueError) as e:
            call()
        _one_line(e, *words)
    with pytest.raises(ValueError) as e:
        r.forward_dynamics_derivatives(z, z, z, cs.Wrench(9, [0, 0, 0], np.ones(6)))
    _one_line(e, "link")


def test_a_mass_matrix_not_positive_definite_is_named_as_forward_dynamics_names_it():
    """A joint that moves no mass: forward_dynamics_derivatives raises forward_dynamics' error, naming q."""
    r = SCARAS[0]
    masses, inertias = r.masses.copy(), r.inertias.copy()
    masses[5], inertias[5] = 0.0, 0.0  # the moving jaw (prismatic): nothing moves along d6
    bad = cs.Robot.from_dh(r.dh, r.com, masses, inertias, r.joint_types)
    z = np.zeros(6)
    with pytest.raises(ValueError) as fd:
        bad.forward_dynamics(z, z, z)
    with pytest.raises(ValueError) as e:
        bad.forward_dynamics_derivatives(z, z, z)
    assert str(e.value) == str(fd.value)
    _one_line(e, "q = [", "positive definite")
    with pytest.raises(ValueError) as e:
        Z = np.zeros((200, 6))
        cs.forward_dynamics_derivatives_batch(bad, Z, Z, Z, threads=2)
    assert str(e.value) == "state 0 (row of q, qd, tau): " + str(fd.value)
    # one state of a sound robot out of range (the quill 1e200 m out: M overflows): its row, the first
    Q = np.tile(r.q_limits.mean(axis=1), (200, 1))
    Q[[137, 190], 2] = 1e200
    with pytest.raises(ValueError) as e:
        cs.forward_dynamics_derivatives_batch(r, Q, Z, Z, threads=2)
    assert str(e.value).startswith("state 137 (row of q, qd, tau): forward_dynamics: the mass matrix or the forces "
                                   "overflow")
