"""Generated dynamics (coopsim.codegen) against the numeric algorithms, textbook
models, and the committed files.

Tolerances: generated vs numeric 1e-10 relative, per state and quantity, in
the max norm: |generated - numeric|_inf <= 1e-10 * |numeric|_inf (plus 1e-12
absolute for quantities that vanish, e.g. C at qd = 0). RK4 trajectories
over 1 s: 1e-9 (positions) and 1e-8 (velocities) relative, round-off grown
over 5000 steps. Textbook models: the symbolic difference must simplify to
exactly 0.
"""
from __future__ import annotations

import difflib
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import coopsim as cs
from coopsim import codegen
from coopsim.codegen.builtin import check_generated

REL = 1e-10
ABS = 1e-12
N_STATES = 1000
REPO = Path(__file__).resolve().parents[1]


def _close(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.max(np.abs(a - b)) <= REL * np.max(np.abs(b)) + ABS


def _compare(gen, num, n_states=N_STATES, seed=0):
    """Every generated quantity equals the numeric one on random states."""
    assert gen.backend == "generated" and num.backend == "numeric"
    rng = np.random.default_rng(seed)
    n = gen.dof
    lim = num.q_limits
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi)
    bad = []
    for s in range(n_states):
        q = rng.uniform(lo, hi)
        qd, qdd, tau = rng.normal(size=n) * 2, rng.normal(size=n), rng.normal(size=n) * 5
        checks = {
            "M": (gen.mass_matrix(q), num.mass_matrix(q)),
            "C": (gen.coriolis(q, qd), num.coriolis(q, qd)),
            "C_matrix": (gen.coriolis_matrix(q, qd), num.coriolis_matrix(q, qd)),
            "G": (gen.gravity(q), num.gravity(q)),
            "friction": (gen.friction(qd), num.friction(qd)),
            "forward": (gen.forward_dynamics(q, qd, tau), num.forward_dynamics(q, qd, tau)),
            "inverse": (gen.inverse_dynamics(q, qd, qdd), num.inverse_dynamics(q, qd, qdd)),
        }
        bad += [(s, k) for k, (a, b) in checks.items() if not _close(a, b)]
    assert not bad, f"generated != numeric at (state, quantity): {bad[:10]}"


CHANGED = dict(
    scara1=dict(L_base=0.5, L1=0.42, L2=0.19, L4=0.07, L5=0.11, quill_length=0.35, jaw_length=0.05,
                width=0.08, masses=[4.0, 1.5, 1.1, 0.4, 0.3, 0.08], friction=[0.3, 0.2, 1.0, 0.1, 0.0, 0.5]),
    scara2=dict(L_base=0.35, L1=0.25, L2=0.14, L3=0.2, L5=0.09, quill_length=0.25, jaw_thickness=0.015,
                height=0.05, masses=[2.5, 1.0, 0.9, 0.7, 0.2, 0.06], friction=[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]),
)


@pytest.mark.parametrize("changed", [False, True], ids=["default", "changed"])
@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_builtin_generated_equals_numeric(name, changed):
    factory = getattr(cs.robots, name)
    # changed: other dimensions and masses, a turned base and a tilted gravity
    # (gravity in frame 0 then has x and y components)
    kw = dict(CHANGED[name], base_yaw=0.7, gravity=(0.4, -0.3, -9.7)) if changed else {}
    gen, num = factory(**kw), factory(backend="numeric", **kw)
    assert gen.has_generated and cs._core.generated_info(gen)["name"] == name
    _compare(gen, num)


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_integration_generated_equals_numeric(name):
    """One second of RK4 (0.2 ms steps, end stops on) gives the same trajectory on both backends."""
    factory = getattr(cs.robots, name)
    gen, num = factory(), factory(backend="numeric")
    q0 = np.array([0.3, -0.5, 0.1, 0.4, 0.2, 0.02]) if name == "scara1" else \
        np.array([0.3, -0.5, 0.4, 0.1, 0.2, 0.02])
    qd0 = np.array([0.5, -0.3, 0.0, 1.0, -0.5, 0.0])
    tau = np.array([0.5, -0.2, 1.0, 0.01, 0.02, 0.1])
    _, Qg, QDg = cs.integrate(gen, q0, qd0, tau, dt=2e-4, steps=5000, record_every=500)
    _, Qn, QDn = cs.integrate(num, q0, qd0, tau, dt=2e-4, steps=5000, record_every=500)
    assert np.max(np.abs(Qg - Qn)) <= 1e-9 * np.max(np.abs(Qn))
    assert np.max(np.abs(QDg - QDn)) <= 1e-8 * np.max(np.abs(QDn))


def test_backend_default_report_and_switch():
    r = cs.robots.scara1()
    assert r.backend == "generated"
    q, qd = np.full(6, 0.3), np.full(6, -0.4)
    c_gen = r.coriolis(q, qd)
    r.set_backend("numeric")
    assert r.backend == "numeric"
    assert _close(r.coriolis(q, qd), c_gen)
    r.set_backend("generated")
    assert r.backend == "generated"
    assert cs.robots.scara2(backend="numeric").backend == "numeric"
    assert sorted(cs._core.builtin_generated_names()) == ["scara1", "scara2"]
    with pytest.raises(ValueError, match="backend"):
        r.set_backend("fast")


def test_generated_files_header_and_operation_count():
    for name in ("scara1", "scara2"):
        for ext in ("hpp", "cpp"):
            first = (REPO / "cpp" / "generated" / f"{name}_dynamics.{ext}").read_text().splitlines()[0]
            assert first.startswith("// Generated by `python -m coopsim.codegen` (coopsim.codegen "
                                    f"{codegen.GENERATOR_VERSION}, sympy {sp.__version__}) - do not edit.")
            ops = int(first.rsplit("Operation count: ", 1)[1].rstrip("."))
            assert ops == cs._core.generated_info(getattr(cs.robots, name)())["operation_count"] > 0
    text = (REPO / "cpp" / "generated" / "scara1_dynamics.cpp").read_text()
    assert "pow(" not in text
    # sin and cos of each revolute joint once per function (5 functions)
    assert text.count("std::cos(q[1])") == text.count("std::sin(q[1])") == 5


def test_generated_files_do_not_drift():
    """Regenerates into memory and diffs with cpp/generated (update: python -m coopsim.codegen)."""
    diff = check_generated(REPO / "cpp" / "generated")
    assert diff == "", "cpp/generated differs from the generator; run `python -m coopsim.codegen`:\n" + diff


@pytest.mark.slow
def test_generation_independent_of_hash_seed():
    """Byte-identical output in a fresh interpreter with another string-hash seed."""
    env = dict(os.environ, PYTHONHASHSEED="12345")
    res = subprocess.run([sys.executable, "-m", "coopsim.codegen", "--check", "--out", str(REPO / "cpp" / "generated")],
                         env=env, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]


def test_command_writes_identical_files(tmp_path):
    """The documented command writes byte-identical files into another folder."""
    from coopsim.codegen.__main__ import main

    assert main(["--out", str(tmp_path)]) == 0
    written = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    committed = {p.name: p.read_bytes() for p in (REPO / "cpp" / "generated").iterdir()}
    assert set(written) == set(committed)
    diff = "".join(
        line for name in sorted(written) if written[name] != committed[name]
        for line in difflib.unified_diff(committed[name].decode().splitlines(True),
                                         written[name].decode().splitlines(True), f"committed/{name}",
                                         f"regenerated/{name}", n=1))
    assert diff == "", "regenerated files differ (run `python -m coopsim.codegen`):\n" + diff[:20000]
    (tmp_path / "scara1_dynamics.cpp").write_bytes(written["scara1_dynamics.cpp"] + b" ")
    assert main(["--out", str(tmp_path), "--check"]) == 1


# ---- textbook models: exact symbolic agreement ----

def _zero(expr):
    return sp.simplify(sp.expand_trig(expr)) == 0


def test_pendulum_textbook():
    s = codegen.Structure("pendulum", "R", [(0.0, 0.0, 0.0, 0.0)])
    m = codegen.derive(s)
    q, qd = m.q[0], m.qd[0]
    mass, lc, Izz, gy = sp.Symbol("m_1", real=True), sp.Symbol("ac_1", real=True), \
        sp.Symbol("Izz_1", real=True), sp.Symbol("g_y", real=True)
    g = sp.Symbol("g", positive=True)
    sub = {gy: -g, sp.Symbol("g_x", real=True): 0, sp.Symbol("g_z", real=True): 0}
    assert _zero(m.in_trig(m.M[0, 0]) - (mass * lc**2 + Izz))
    assert m.C[0] == 0 and m.C_matrix[0, 0] == 0
    assert _zero(m.in_trig(m.G[0]).subs(sub) - mass * g * lc * sp.cos(q))
    assert m.friction[0] == sp.Symbol("K_1", real=True) * qd


def test_two_link_planar_arm_textbook():
    """Spong, Hutchinson, Vidyasagar, Robot Modeling and Control, sec. 7.4.1 (gravity along -y)."""
    s = codegen.Structure("planar2", "RR", [(0.0, 0.0, 0.0, 0.0)] * 2)
    m = codegen.derive(s)
    q1, q2 = m.q
    qd1, qd2 = m.qd
    S = lambda name: sp.Symbol(name, real=True)  # noqa: E731
    m1, m2, l1, lc1, lc2, I1, I2 = (S(k) for k in ("m_1", "m_2", "a_1", "ac_1", "ac_2", "Izz_1", "Izz_2"))
    g = sp.Symbol("g", positive=True)
    sub = {S("g_y"): -g, S("g_x"): 0, S("g_z"): 0}
    M = sp.Matrix([[m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * sp.cos(q2)) + I1 + I2,
                    m2 * (lc2**2 + l1 * lc2 * sp.cos(q2)) + I2],
                   [m2 * (lc2**2 + l1 * lc2 * sp.cos(q2)) + I2, m2 * lc2**2 + I2]])
    h = -m2 * l1 * lc2 * sp.sin(q2)
    C = sp.Matrix([[h * qd2, h * qd2 + h * qd1], [-h * qd1, 0]])
    G = sp.Matrix([(m1 * lc1 + m2 * l1) * g * sp.cos(q1) + m2 * lc2 * g * sp.cos(q1 + q2),
                   m2 * lc2 * g * sp.cos(q1 + q2)])
    for i in range(2):
        assert _zero(m.in_trig(m.G[i]).subs(sub) - G[i])
        assert _zero(m.in_trig(m.C[i]) - (C * sp.Matrix([qd1, qd2]))[i])
        for j in range(2):
            assert _zero(m.in_trig(m.M[i, j]) - M[i, j])
            assert _zero(m.in_trig(m.C_matrix[i, j]) - C[i, j])


def test_symbolic_model_properties_scara2():
    """C = C_matrix qd, and Mdot - 2 C is skew, symbolically (SCARA #2)."""
    m = codegen.derive(cs.robots.scara2())
    n = m.n
    qd = sp.Matrix(m.qd)
    assert (m.C_matrix * qd - m.C).expand() == sp.zeros(n, 1)
    Mdot = sum((m.dM[k] * m.qd[k] for k in range(n)), sp.zeros(n, n))
    N = m.explicit(Mdot) - 2 * m.C_matrix
    assert (N + N.T).expand() == sp.zeros(n, n)
    shown = m.matrices()
    assert set(shown) == {"M", "C", "C_matrix", "G", "friction"}
    assert shown["M"].shape == (n, n) and shown["G"].shape == (n, 1)
    assert "\\cos" in sp.latex(shown["M"][0, 0]) and not shown["M"].free_symbols & set(m.trig)


# ---- run-time robots ----

def _runtime_robot(scale=1.0):
    """A 4-DOF RPRR robot with general angles (not multiples of 15 degrees), offsets
    in the CoM table and full inertia tensors."""
    from conftest import random_inertia

    rng = np.random.default_rng(7)
    dh = [[0.3, 0.4 * scale, 0.1, np.pi / 2], [0.0, 0.1, 0.05 * scale, -np.pi / 2],
          [-0.2, 0.0, 0.3 * scale, 0.25], [1.1, 0.05, 0.2, 0.0]]
    com = [[0.3, 0.2, 0.05, 0.1], [0.5, -0.1 * scale, 0.0, 0.0], [-0.2, 0.01, 0.15, -0.3],
           [0.9, 0.02, 0.1 * scale, np.pi / 3]]
    masses = np.array([2.0, 1.5, 1.0, 0.5]) * scale
    inertias = np.array([random_inertia(rng, mm) for mm in masses])
    return cs.Robot.from_dh(dh, com, masses, inertias, joint_types="RPRR", friction=[0.5, 1.0, 0.2, 0.1],
                            q_limits=[[-3, 3], [-0.3, 0.3], [-3, 3], [-3, 3]], gravity=(0.5, 0.2, -9.81),
                            base_position=(0.1, 0.2, 0.3), base_yaw=0.4, name="arm4")


@pytest.mark.slow
def test_compile_runtime_robot(tmp_path):
    r = _runtime_robot()
    assert r.backend == "numeric"
    out = codegen.compile(r, cache=tmp_path)
    assert out is r and r.backend == "generated"
    _compare(r, _runtime_robot())
    libs = sorted(tmp_path.glob("*.so"))
    assert len(libs) == 1
    mtime = libs[0].stat().st_mtime_ns
    # other lengths and masses, same structure: the cached library is reused
    r2 = codegen.compile(_runtime_robot(scale=1.3), cache=tmp_path)
    assert sorted(tmp_path.glob("*.so")) == libs and libs[0].stat().st_mtime_ns == mtime
    _compare(r2, _runtime_robot(scale=1.3), n_states=200, seed=1)
    # a pickled copy finds the loaded code again, in this process and in a
    # fresh one that looks in the same cache
    r3 = pickle.loads(pickle.dumps(r2))
    assert r3.backend == "generated"
    q = np.array([0.1, 0.05, -0.3, 0.7])
    assert _close(r3.mass_matrix(q), r2.mass_matrix(q))
    (tmp_path / "robot.pkl").write_bytes(pickle.dumps(r2))
    code = ("import pickle, sys, numpy as np, coopsim\n"
            "r = pickle.loads(open(sys.argv[1], 'rb').read())\n"
            "print(r.backend, *r.mass_matrix(np.array([0.1, 0.05, -0.3, 0.7])).ravel())\n")
    env = dict(os.environ, COOPSIM_CACHE_DIR=str(tmp_path))
    res = subprocess.run([sys.executable, "-c", code, str(tmp_path / "robot.pkl")], env=env, capture_output=True,
                         text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    backend, *values = res.stdout.split()
    assert backend == "generated"
    assert _close(np.array(values, dtype=float), r2.mass_matrix(q).ravel())


def test_compile_bad_input(tmp_path):
    with pytest.raises(ValueError, match="robot"):
        codegen.compile("arm", cache=tmp_path)
    with pytest.raises(ValueError, match="joint_types"):
        codegen.Structure("x", "RQ", [(0, 0, 0, 0)] * 2)
    with pytest.raises(ValueError, match="angles"):
        codegen.Structure("x", "RR", [(0, 0, 0, 0)])
    with pytest.raises(ValueError, match="path"):
        cs._core.load_generated_library(str(tmp_path / "missing.so"))


def test_structure_mismatch_is_refused():
    r = cs.robots.scara1(backend="numeric")
    with pytest.raises(ValueError, match="joint types|joints"):
        cs._core.attach_builtin_generated(r.with_base([0, 0, 0], 0.0), "scara2")
