"""Generated dynamics (coopsim.codegen) against the numeric algorithms, textbook
models, and the committed files.

Tolerances: generated vs numeric 1e-10 relative, per state and quantity, in
the max norm: |generated - numeric|_inf <= 1e-10 * |numeric|_inf (plus 1e-12
absolute for quantities that vanish, e.g. C at qd = 0). Friction is the
generated h = C qd + G + K qd (inverse dynamics at qdd = 0) minus the
generated C and G, against K qd, to the same tolerance. RK4 trajectories
over 1 s: 1e-9 (positions) and 1e-8 (velocities) relative, round-off grown
over 5000 steps. Textbook models: the symbolic difference must simplify to
exactly 0. Emitted code: the cse operation count at most half of the count
without cse, per function.
"""
from __future__ import annotations

import difflib
import hashlib
import os
import pickle
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import coopsim as cs
from coopsim import codegen
from coopsim.codegen.builtin import check_generated
from coopsim.codegen.compile import structure_key
from coopsim.codegen.files import runtime_source

REL = 1e-10
ABS = 1e-12
N_STATES = 1000
REPO = Path(__file__).resolve().parents[1]


def _close(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.max(np.abs(a - b)) <= REL * np.max(np.abs(b)) + ABS


def _mismatches(gen, num, n_states=N_STATES, seed=0):
    """[(state, quantity)] where a generated quantity differs from the numeric one."""
    assert gen.backend == "generated" and num.backend == "numeric"
    rng = np.random.default_rng(seed)
    n = gen.dof
    lim = num.q_limits
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi)
    K = num.friction_coefficients
    bad = []
    for s in range(n_states):
        q = rng.uniform(lo, hi)
        qd, qdd, tau = rng.normal(size=n) * 2, rng.normal(size=n), rng.normal(size=n) * 5
        C, G = gen.coriolis(q, qd), gen.gravity(q)
        checks = {
            "M": (gen.mass_matrix(q), num.mass_matrix(q)),
            "C": (C, num.coriolis(q, qd)),
            "C_matrix": (gen.coriolis_matrix(q, qd), num.coriolis_matrix(q, qd)),
            "G": (G, num.gravity(q)),
            # the generated friction: h = C qd + G + K qd + F_c tanh(qd / v_c) of the generated
            # dynamics (inverse dynamics at qdd = 0) less the generated C and G
            "friction": (gen.inverse_dynamics(q, qd, np.zeros(n)) - C - G,
                         K * qd + num.coulomb * np.tanh(qd / num.coulomb_width)),
            "forward": (gen.forward_dynamics(q, qd, tau), num.forward_dynamics(q, qd, tau)),
            "inverse": (gen.inverse_dynamics(q, qd, qdd), num.inverse_dynamics(q, qd, qdd)),
        }
        # the derivatives (generated where the code carries them, else the recursive algorithm's)
        for label, (a, b) in (("forward derivatives", (gen.forward_dynamics_derivatives(q, qd, tau),
                                                       num.forward_dynamics_derivatives(q, qd, tau))),
                              ("inverse derivatives", (gen.inverse_dynamics_derivatives(q, qd, qdd),
                                                       num.inverse_dynamics_derivatives(q, qd, qdd)))):
            for k, (x, y) in enumerate(zip(a, b)):
                checks[f"{label} {k}"] = (x, y)
        bad += [(s, k) for k, (a, b) in checks.items() if not _close(a, b)]
    return bad


def _compare(gen, num, n_states=N_STATES, seed=0):
    """Every generated quantity equals the numeric one on random states."""
    bad = _mismatches(gen, num, n_states, seed)
    assert not bad, f"generated != numeric at (state, quantity): {bad[:10]}"


CHANGED = dict(
    scara1=dict(L_base=0.5, L1=0.42, L2=0.19, L4=0.07, L5=0.11, quill_length=0.35, jaw_length=0.05,
                width=0.08, masses=[4.0, 1.5, 1.1, 0.4, 0.3, 0.08], friction=[0.3, 0.2, 1.0, 0.1, 0.0, 0.5]),
    scara2=dict(L_base=0.35, L1=0.25, L2=0.14, L3=0.2, L5=0.09, quill_length=0.35, jaw_thickness=0.015,
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
    assert gen.has_generated and cs.codegen.info(gen)["name"] == name
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
    # robots are immutable: a backend is chosen by a copy, the original keeps its own
    num = r.with_backend("numeric")
    assert num.backend == "numeric" and r.backend == "generated"
    assert _close(num.coriolis(q, qd), c_gen)
    assert num.with_backend("generated").backend == "generated"
    assert cs.robots.scara2(backend="numeric").backend == "numeric"
    assert sorted(cs.codegen.builtin_names()) == ["scara1", "scara2"]
    with pytest.raises(ValueError, match="backend"):
        r.with_backend("fast")
    assert not hasattr(r, "set_backend")


HEADER = (f"// Generated by `python -m coopsim.codegen` (coopsim.codegen {codegen.GENERATOR_VERSION}, "
          f"sympy {sp.__version__}) - do not edit. Operation count: ")
EMITTED = ("mass_matrix", "coriolis", "coriolis_matrix", "gravity", "dynamics")
_FUNCTION = re.compile(r"^(?:static inline __attribute__\(\(always_inline\)\) )?(?:void|bool) (\w+)\([^\n]*\) \{\n(.*?)\n\}$",
                       re.M | re.S)
#: the templates on the state's scalar type (double, or four states in a vector's lanes) the entry points call
TEMPLATES = ("dynamics_t", "derivatives_t", "forward_derivatives_t")
_TRIG = re.compile(r"sin_cos\(([^,]*), (s_\d+), (c_\d+)\)")


def _functions(text):
    """{function name: body} of the emitted functions (those of GeneratedDynamics, solve and the templates)."""
    return dict(_FUNCTION.findall(text))


def _check_emitted(text, structure, prefix):
    """Format of one emitted .cpp: header line, no pow, per function sin and cos (together) only of
    revolute joints (argument q[i] plus the structure's DH theta), each at most once and, in
    dynamics, each exactly once; no std::sin/std::cos outside sin_cos; the parameter polynomials
    computed by constants (each k[j] written once) and only read by the others; every cse
    temporary defined once and used."""
    assert text.startswith(HEADER), text.splitlines()[0]
    assert "pow(" not in text
    assert text.count("std::sin(") == text.count("std::cos(") == 1  # the fallback in sin_cos only
    funcs = _functions(text)
    # the derivatives where the generator emits them (the collected form), with the forward ones; the
    # dynamics' body in a template that the entry point (and the forward derivatives) call
    deriv = {prefix + f for f in ("derivatives", "forward_derivatives", "forward_derivatives4")} | set(TEMPLATES[1:])
    # with dynamics_level where gravity's horizontal components have terms: the entry point takes it when they
    # are zero (p's gravity along z)
    level = {"dynamics_level"} & set(funcs)
    assert set(funcs) - deriv == {prefix + f for f in EMITTED + ("solve", "constants")} | {"dynamics_t"} | level
    g = 19 * structure.dof
    assert funcs[prefix + "dynamics"].strip() == (
        f"if (p[{g}] == 0.0 && p[{g + 1}] == 0.0)\n    dynamics_level(p, q, qd, M, h);\n  else\n    "
        if level else "") + "dynamics_t(p, q, qd, M, h);"
    if prefix + "derivatives" in funcs:
        assert deriv <= set(funcs)
        assert text.count("static inline double coulomb_slope(") == 1
        assert "coulomb_slope(" in funcs["derivatives_t"]
    written = re.findall(r"^  k\[(\d+)\] = ", funcs[prefix + "constants"], re.M)
    assert [int(j) for j in written] == list(range(len(written)))
    base = 19 * structure.dof + 3
    revolute = [i for i, c in enumerate(structure.joint_types) if c == "R"]
    for fname, body in funcs.items():
        calls = {}
        for arg, sn, cn in _TRIG.findall(body):
            m = re.fullmatch(r"q\[(\d+)\](?: \+ (\S+))?", arg)
            assert m, f"{fname}: sin_cos({arg}) is not of a joint angle"
            i = int(m[1])
            assert (sn, cn) == (f"s_{i + 1}", f"c_{i + 1}"), f"{fname}: sin_cos({arg}) into {sn}, {cn}"
            assert i in revolute, f"{fname}: sin_cos of prismatic joint {i}"
            assert float(m[2] or 0.0) == structure.angles[i][0], f"{fname}: sin_cos({arg}): wrong offset"
            calls[i] = calls.get(i, 0) + 1
        assert all(c == 1 for c in calls.values()), f"{fname}: sin/cos computed more than once: {calls}"
        if fname == "dynamics_t":
            assert set(calls) == set(revolute), (fname, sorted(calls))
        if fname not in (prefix + "constants", prefix + "solve"):
            # kappa_j is read from p[base + j], never recomputed
            for j, at in re.findall(r"^  const double kappa_(\d+) = p\[(\d+)\];$", body, re.M):
                assert int(at) == base + int(j) and int(j) < len(written), (fname, j, at)
            assert not re.search(r"^  const double (a\d+|kappa_\d+) = (?!p\[\d+\];$)", body, re.M), fname
        temps = re.findall(r"^  const (?:double|T) ((?:x|y|a)\d+) = ", body, re.M)
        assert len(set(temps)) == len(temps), f"{fname}: a temporary defined twice"
        dead = [x for x in temps if len(re.findall(rf"\b{x}\b", body)) < 2]
        assert not dead, f"{fname}: temporaries never used: {dead}"


def test_generated_files_header_and_format():
    for name in ("scara1", "scara2"):
        s = codegen.structure_of(getattr(cs.robots, name)(backend="numeric"))
        texts = {ext: (REPO / "cpp" / "generated" / f"{name}_dynamics.{ext}").read_text() for ext in ("hpp", "cpp")}
        for ext, text in texts.items():
            first = text.splitlines()[0]
            assert first.startswith(HEADER)
            ops = int(first.rsplit("Operation count: ", 1)[1].rstrip("."))
            assert ops == cs.codegen.info(getattr(cs.robots, name)())["operation_count"] > 0
            assert "pow(" not in text
        _check_emitted(texts["cpp"], s, f"{name}_")
        assert f"{name}_derivatives" in _functions(texts["cpp"])
        assert f"d.derivatives = &{name}_derivatives;" in texts["cpp"]
    registry = (REPO / "cpp" / "generated" / "registry.cpp").read_text()
    assert registry.startswith(HEADER + "n/a.") and "pow(" not in registry


@pytest.fixture(scope="module")
def scara_models():
    """Symbolic models of both SCARAs (lazy; derived once for the tests that share them)."""
    return {name: codegen.derive(getattr(cs.robots, name)(backend="numeric")) for name in ("scara1", "scara2")}


def _operations_without_cse(model):
    """{function: operations} of the five emitted functions without cse: every output (each of
    the n x n matrix entries) and every parameter polynomial it uses (Horner form, as emitted)
    counted in full, from the model's collected forms."""
    n = model.n
    h = [model.C_kappa[k] + model.G_kappa[k] + model.friction[k] for k in range(n)]
    outputs = dict(mass_matrix=list(model.M_kappa), coriolis=list(model.C_kappa),
                   coriolis_matrix=list(model.C_matrix_kappa), gravity=list(model.G_kappa),
                   dynamics=list(model.M_kappa) + h)
    out = {}
    for f, exprs in outputs.items():
        used = set().union(*(sp.sympify(e).free_symbols for e in exprs))
        out[f] = sum(int(sp.count_ops(e)) for e in exprs) + sum(
            int(sp.count_ops(sp.horner(e))) for k, e in model.kappa.items() if k in used)
    return out


@pytest.mark.slow  # emits both SCARAs' code again
def test_emitted_code_uses_cse(scara_models):
    """Every emitted function of both SCARAs has cse temporaries, and its operation count (as
    written in the file, after cse) is at most half the count without cse."""
    for name, model in scara_models.items():
        assert model.form == "collected"
        text = (REPO / "cpp" / "generated" / f"{name}_dynamics.cpp").read_text()
        line = next(ln for ln in text.splitlines() if "Operations per function (after cse" in ln)
        with_cse = {k: int(v) for k, v in re.findall(r"(\w+) (\d+)", line.split("counted once): ")[1])}
        without = _operations_without_cse(model)
        bodies = _functions(text)
        for f in EMITTED:
            body = bodies["dynamics_t" if f == "dynamics" else f"{name}_{f}"]
            assert re.search(r"^  const (?:double|T) x\d+ = ", body, re.M), (name, f)
            assert with_cse[f] <= 0.5 * without[f], (name, f, with_cse[f], without[f])


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


@pytest.mark.slow  # writes both SCARAs' files again (test_generated_files_do_not_drift checks them in memory)
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


def test_the_command_refuses_an_out_that_is_not_a_folder(tmp_path, capsys):
    from coopsim.codegen.__main__ import main

    with pytest.raises(SystemExit) as e:
        main(["--out", str(tmp_path / "missing")])
    assert e.value.code == 2 and "is not a folder" in capsys.readouterr().err
    assert not (tmp_path / "missing").exists()


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
    Ia, K, Fc, vc = (sp.Symbol(f"{k}_1", real=True) for k in ("Ia", "K", "Fc", "vc"))
    # the rotor's reflected inertia (armature) adds to the link's
    assert _zero(m.in_trig(m.M[0, 0]) - (mass * lc**2 + Izz + Ia))
    assert m.C[0] == 0 and m.C_matrix[0, 0] == 0
    assert _zero(m.in_trig(m.G[0]).subs(sub) - mass * g * lc * sp.cos(q))
    assert m.friction[0] == K * qd + Fc * sp.tanh(qd / vc)


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
            rotor = S(f"Ia_{i + 1}") if i == j else 0  # the rotors' armature on the diagonal
            assert _zero(m.in_trig(m.M[i, j]) - M[i, j] - rotor)
            assert _zero(m.in_trig(m.C_matrix[i, j]) - C[i, j])


def test_symbolic_model_properties_scara2(scara_models):
    """C = C_matrix qd, and Mdot - 2 C is skew, symbolically (SCARA #2)."""
    m = scara_models["scara2"]
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
    assert out is not r and out.backend == "generated" and r.backend == "numeric"  # a copy; r is immutable
    r = out
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


def _arm2(joint_types="RR", alpha=np.pi / 2, scale=1.0):
    """A small 2-DOF robot (builds in well under a second); `alpha` is the first DH alpha."""
    dh = [[0.0, 0.3 * scale, 0.1, alpha], [0.2, 0.1, 0.25 * scale, 0.0]]
    com = [[0.0, 0.1, 0.05, 0.0], [0.2, 0.05, 0.1 * scale, 0.3]]
    masses = np.array([1.0, 0.5]) * scale
    inertias = [cs.box_inertia(m, 0.1, 0.05, 0.2) for m in masses]
    q_limits = [[-3, 3] if c == "R" else [-0.3, 0.3] for c in joint_types]
    return cs.Robot.from_dh(dh, com, masses, inertias, joint_types=joint_types, friction=[0.3, 0.7],
                            q_limits=q_limits, gravity=(0.3, -0.2, -9.81), name="arm2")


@pytest.mark.slow  # g++ builds several libraries
def test_compile_cache_key_is_the_structure(tmp_path):
    """The build is keyed by the structure: another joint type or alpha gives another key and
    library; other lengths, masses or name reuse the build."""
    cxx = "g++"
    key = structure_key(codegen.structure_of(_arm2(), name="robot"), cxx)
    assert structure_key(codegen.structure_of(_arm2(scale=1.3), name="robot"), cxx) == key
    assert structure_key(codegen.structure_of(_arm2(), name="other"), cxx) == key
    assert structure_key(codegen.structure_of(_arm2().with_base([0.5, 0, 0], 1.0), name="robot"), cxx) == key
    assert structure_key(codegen.structure_of(_arm2(), name="robot"), "clang++") != key
    for other in (_arm2(joint_types="RP"), _arm2(joint_types="PR"), _arm2(alpha=-np.pi / 2), _arm2(alpha=np.pi)):
        assert structure_key(codegen.structure_of(other, name="robot"), cxx) != key

    def build(robot):
        r = codegen.compile(robot, cache=tmp_path)
        return cs.codegen.info(r)["name"], r

    name, r = build(_arm2())
    assert name.startswith("gen_") and sorted(p.name for p in tmp_path.glob("*.so")) == [f"coopsim_{name}.so"]
    _compare(r, _arm2(), n_states=200)
    mtime = (tmp_path / f"coopsim_{name}.so").stat().st_mtime_ns
    names = {name}
    for kw in (dict(joint_types="RP"), dict(alpha=-np.pi / 2)):
        other, r = build(_arm2(**kw))
        assert other not in names
        names.add(other)
        assert {p.name for p in tmp_path.glob("*.so")} == {f"coopsim_{n}.so" for n in names}
        _compare(r, _arm2(**kw), n_states=200)
    rescaled, r = build(_arm2(scale=1.3))
    assert rescaled == name and len(list(tmp_path.glob("*.so"))) == 3
    assert (tmp_path / f"coopsim_{name}.so").stat().st_mtime_ns == mtime
    _compare(r, _arm2(scale=1.3), n_states=200)


def test_compile_rebuilds_a_damaged_cache_and_keys_the_compiler_version(tmp_path, monkeypatch):
    import importlib

    compile_module = importlib.import_module("coopsim.codegen.compile")  # the module, not the function

    cxx = compile_module._compiler()
    ident = compile_module._compiler_id(cxx)
    key = structure_key(codegen.structure_of(_arm2(), name="robot"), ident)
    lib = tmp_path / f"coopsim_gen_{key}.so"
    lib.write_bytes(b"")  # a library left truncated, as by a full disk
    r = codegen.compile(_arm2(), cache=tmp_path)
    assert lib.stat().st_size > 0 and cs.codegen.info(r)["name"] == f"gen_{key}"
    _compare(r, _arm2(), n_states=50)
    # the key holds the compiler's version line, not only its path
    assert ident.startswith(cxx) and len(ident) > len(cxx) + 3
    with monkeypatch.context() as m:
        m.setattr(compile_module, "_compiler_id", lambda c: c + " 99.0")
        s = codegen.structure_of(_arm2(), name="robot")
        assert structure_key(s, compile_module._compiler_id(cxx)) != structure_key(s, ident)


def test_derive_takes_any_robot_name():
    robot = cs.Robot.from_dh(_arm2().dh, _arm2().com, _arm2().masses, _arm2().inertias, joint_types="RR",
                             name="my-arm 2")
    model = codegen.derive(robot)
    assert model.M.shape == (2, 2)


def test_friction_check_detects_wrong_friction(tmp_path):
    """The friction comparison of _compare fails on generated code whose h drops or doubles K qd
    (mutated builds of a small robot); M, C, G and the inverse dynamics' derivatives stay equal to the
    numeric ones."""
    cxx = os.environ.get("CXX") or "g++"
    for label, factor in (("dropped", "0.0"), ("doubled", "2.0")):
        s = codegen.structure_of(_arm2(), name=f"test_friction_{label}")
        text, _ = runtime_source(s)
        funcs = _functions(text)
        # the bodies coopsim_gen_dynamics calls: dynamics_t, and dynamics_level for gravity along z (the test's)
        bodies = [funcs["dynamics_t"]] + ([funcs["dynamics_level"]] if "dynamics_level" in funcs else [])
        for k in range(s.dof):
            term = f"p[{19 * k + 15}]*qd[{k}]"
            # K qd only in h of dynamics (once in each body)
            assert text.count(term) == len(bodies) and all(b.count(term) == 1 for b in bodies), term
        for body in bodies:
            mutated = body
            for k in range(s.dof):
                term = f"p[{19 * k + 15}]*qd[{k}]"
                mutated = mutated.replace(term, f"{factor}*{term}")
            text = text.replace(body, mutated)
        src, lib = tmp_path / f"{s.name}.cpp", tmp_path / f"{s.name}.so"
        src.write_text(text)
        res = subprocess.run([cxx, "-O2", "-std=c++17", "-shared", "-fPIC", "-o", str(lib), str(src)],
                             capture_output=True, text=True)
        assert res.returncode == 0, res.stderr[-2000:]
        assert cs.codegen.load(lib) == s.name
        r = _arm2().with_generated(s.name)
        bad = {k for _, k in _mismatches(r, _arm2(), n_states=20)}
        # the forward derivatives are taken at the forward dynamics' qdd: dqdd/dq follows the wrong h
        assert bad == {"friction", "inverse", "forward", "forward derivatives 0"}, (label, bad)


def test_gravity_along_z_and_any_gravity_both_equal_the_numeric_dynamics():
    """The generated dynamics take dynamics_level when gravity in frame 0 is along its z axis (both SCARAs on the
    floor) and dynamics_t otherwise (a base tilted, gravity with horizontal components): both give M, C, G, the
    friction and the forward and inverse dynamics of the recursive algorithms, on random states."""
    for name in ("scara1", "scara2"):
        gen, num = getattr(cs.robots, name)(), getattr(cs.robots, name)(backend="numeric")
        assert gen.parameter_vector[-3:-1].tolist() == [0.0, 0.0]      # the level path
        assert _mismatches(gen, num) == []
        for g in ([0.8, -0.5, -9.76], [0.0, 1e-3, -9.81], [2.0, 0.0, -9.6]):   # the general path, each component
            assert _mismatches(gen.with_gravity(g), num.with_gravity(g)) == [], (name, g)


def _arm6(scale=1.0):
    """A 6-DOF RPRRRP arm: alpha in {0, +-pi/2, pi}, DH theta offsets (a general one on revolute
    joint 3, pi/2 on prismatic joint 6), CoM frames turned, full inertia tensors."""
    from conftest import random_inertia

    h = np.pi / 2
    dh = [[0.0, 0.4, 0.05, h], [0.3, 0.0, 0.35 * scale, 0.0], [-0.4, 0.1, 0.0, -h], [0.0, 0.3 * scale, 0.0, h],
          [0.0, 0.0, 0.0, -h], [h, 0.1, 0.02, np.pi]]
    com = [[0.0, 0.2, 0.02, 0.0], [0.3, 0.05, 0.15 * scale, h], [-0.15, -0.1, 0.01, 0.0],
           [0.0, 0.15 * scale, 0.01, -h], [0.0, 0.01, 0.0, 0.0], [h, 0.03, 0.01, 0.0]]
    masses = np.array([5.0, 3.0, 1.5, 0.8, 0.4, 0.1]) * scale
    rng = np.random.default_rng(6)
    inertias = np.array([random_inertia(rng, m) for m in masses])
    return cs.Robot.from_dh(dh, com, masses, inertias, joint_types="RPRRRP", friction=[0.5, 0.4, 2.0, 0.1, 0.05, 1.0],
                            q_limits=[[-3, 3], [-0.2, 0.3], [-3, 3], [-3, 3], [-3, 3], [0.0, 0.05]],
                            gravity=(0.3, -0.4, -9.81), base_position=(0.1, -0.2, 0.3), base_yaw=0.5, name="arm6")


@pytest.mark.slow
def test_compile_six_dof_robot(tmp_path):
    """A 6-DOF robot compiled at run time equals the numeric dynamics on 1000 states; its source
    (kept in the cache) has the emitted format. Cold: 10-20 s on 2 cores (PUMA-like 6R arm of
    benchmarks/bench_codegen.py: about 19 s; general angles: 1.5-2 min)."""
    r = codegen.compile(_arm6(), cache=tmp_path)
    assert r.backend == "generated"
    _compare(r, _arm6())
    name = cs.codegen.info(r)["name"]
    _check_emitted((tmp_path / f"coopsim_{name}.cpp").read_text(), codegen.structure_of(r), "coopsim_gen_")
    r2 = codegen.compile(_arm6(scale=1.2), cache=tmp_path)
    assert cs.codegen.info(r2)["name"] == name and len(list(tmp_path.glob("*.so"))) == 1
    _compare(r2, _arm6(scale=1.2), n_states=200, seed=1)


def test_compiled_code_carries_the_derivatives_where_they_are_tractable(tmp_path):
    """codegen.compile emits the dynamics' derivatives in the collected form (a small RR arm) and leaves
    them out in the Jacobian form (the 4-DOF arm with general angles), where the recursive algorithm
    gives them; either way they equal the numeric robot's to 1e-12 relative."""
    from conftest import random_state

    for make, carries in ((_arm2, True), (_runtime_robot, False)):
        num = make()
        gen = codegen.compile(num, cache=tmp_path)
        assert cs.codegen.info(gen)["derivatives"] is carries
        name = cs.codegen.info(gen)["name"]
        assert ("coopsim_gen_derivatives(" in (tmp_path / f"coopsim_{name}.cpp").read_text()) is carries
        rng = np.random.default_rng(3)
        for _ in range(20):
            q, qd, qdd = random_state(num, rng)
            tau = 3 * rng.normal(size=num.dof)
            for a, b in ((gen.forward_dynamics_derivatives(q, qd, tau), num.forward_dynamics_derivatives(q, qd, tau)),
                         (gen.inverse_dynamics_derivatives(q, qd, qdd), num.inverse_dynamics_derivatives(q, qd, qdd))):
                for x, y in zip(a, b):
                    assert np.abs(x - y).max() <= 1e-12 * np.abs(y).max()


def test_compile_bad_input(tmp_path):
    with pytest.raises(ValueError, match="robot"):
        codegen.compile("arm", cache=tmp_path)
    with pytest.raises(ValueError, match="joint_types"):
        codegen.Structure("x", "RQ", [(0, 0, 0, 0)] * 2)
    with pytest.raises(ValueError, match="angles"):
        codegen.Structure("x", "RR", [(0, 0, 0, 0)])
    with pytest.raises(ValueError, match="path"):
        cs.codegen.load(tmp_path / "missing.so")


def test_structure_mismatch_is_refused():
    r = cs.robots.scara1(backend="numeric")
    with pytest.raises(ValueError, match="joint types|joints"):
        r.with_base([0, 0, 0], 0.0).with_generated("scara2")


def test_compile_loads_only_the_library_it_built_and_no_name_reaches_the_code(tmp_path):
    """Code generation compiles user input: a hostile robot name never reaches the C++ (the library is named
    by its structure key); a cached library replaced by another one (foreign, or damaged) is built anew, not
    loaded; the engine refuses a library others may write, or one in a folder others may write to."""
    import shutil
    import stat

    hostile = '"); system("touch pwned"); //\n#include </etc/passwd>'
    a = _arm2()
    arm = cs.Robot.from_dh(a.dh, a.com, a.masses, a.inertias, joint_types="RR", friction=[0.3, 0.7],
                           q_limits=a.q_limits, gravity=(0.3, -0.2, -9.81), name=hostile)
    r = codegen.compile(arm, cache=tmp_path)
    assert r.name == hostile and not (tmp_path / "pwned").exists()
    for src in tmp_path.glob("*.cpp"):
        text = src.read_text()
        assert "system" not in text and "pwned" not in text and "passwd" not in text
    _compare(r, arm, n_states=20)
    lib = next(tmp_path.glob("coopsim_gen_*.so"))
    assert (tmp_path / (lib.name + ".sha256")).read_text().strip() == hashlib.sha256(lib.read_bytes()).hexdigest()
    # a foreign library in its place (another structure's build, which would load): rebuilt, not loaded
    other = codegen.compile(_arm2(joint_types="RP"), cache=tmp_path)
    other_lib = tmp_path / f"coopsim_{cs.codegen.info(other)['name']}.so"
    lib.unlink()   # (not written over in place: this process has it mapped)
    shutil.copy(other_lib, lib)
    r = codegen.compile(arm, cache=tmp_path)
    assert cs.codegen.info(r)["joint_types"] == "RR"
    _compare(r, arm, n_states=20)
    assert hashlib.sha256(lib.read_bytes()).hexdigest() != hashlib.sha256(other_lib.read_bytes()).hexdigest()
    # the engine's own check, before loading: writable by others, or in a folder others may write to
    lib.chmod(lib.stat().st_mode | stat.S_IWOTH)
    with pytest.raises(ValueError, match="refusing to load .*: other users may write to it"):
        cs.codegen.load(lib)
    lib.chmod(lib.stat().st_mode & ~stat.S_IWOTH)
    open_dir = tmp_path / "open"
    open_dir.mkdir()
    shutil.copy(lib, open_dir / lib.name)
    open_dir.chmod(0o777)
    with pytest.raises(ValueError, match="its folder .* may be written to by other users"):
        cs.codegen.load(open_dir / lib.name)
    open_dir.chmod(0o777 | stat.S_ISVTX)   # sticky, like /tmp: others cannot replace what is ours
    assert cs.codegen.load(open_dir / lib.name).startswith("gen_")


def _cpu_runs_x86_64_v3():
    try:
        flags = Path("/proc/cpuinfo").read_text().split()
    except OSError:
        return False
    return all(f in flags for f in ("avx2", "fma", "bmi2", "movbe"))


@pytest.mark.parametrize("arch", ["default", "x86-64-v3"])
def test_sin_cos_of_generated_code_within_two_ulp(tmp_path, arch):
    """The generated code's sin_cos against mpmath (200 bits): within 2 ulp of sin and cos for
    |x| < 1e5 (joint angles, angles near multiples of pi/2, large angles), an absolute error below
    1e-26 where the value itself is that small (x a multiple of pi/2 to round-off), and
    std::sin/std::cos beyond (large, inf, nan). glibc's own sin is within 1 ulp. Both targets the
    generated functions are compiled for (x86-64-v3 contracts to FMA)."""
    if arch != "default" and not (_cpu_runs_x86_64_v3() and os.uname().machine == "x86_64"):
        pytest.skip(f"this CPU does not run {arch}")
    import ctypes

    import mpmath

    from coopsim.codegen.emit import SIN_COS

    src = tmp_path / "sin_cos.cpp"
    src.write_text("#include <cmath>\nextern \"C\" {\n" + SIN_COS +
                   "void many(const double* x, double* s, double* c, long n) {\n"
                   "  for (long i = 0; i < n; ++i) sin_cos(x[i], s[i], c[i]);\n}\n}\n")
    lib_path = tmp_path / "sin_cos.so"
    march = [] if arch == "default" else [f"-march={arch}"]
    subprocess.run(["g++", "-O2", *march, "-shared", "-fPIC", "-Wall", "-Wextra", "-Werror", str(src), "-o",
                    str(lib_path)], check=True)
    lib = ctypes.CDLL(str(lib_path))
    rng = np.random.default_rng(7)
    half_pi = np.pi / 2 * np.arange(-300, 301)
    x = np.concatenate([rng.uniform(-4, 4, 1500), rng.uniform(-100, 100, 500), rng.uniform(-1e5, 1e5, 300),
                        half_pi, half_pi + rng.normal(0, 1e-8, half_pi.size), np.pi / 4 * np.arange(-9, 10),
                        [0.0, -0.0, 5e-324, 1e-300, 1e-8, 99999.99, -99999.99, 1e5, 3e7, -1e300]])
    s, c = np.empty_like(x), np.empty_like(x)
    ptr = ctypes.POINTER(ctypes.c_double)
    lib.many(x.ctypes.data_as(ptr), s.ctypes.data_as(ptr), c.ctypes.data_as(ptr), ctypes.c_long(x.size))
    mpmath.mp.prec = 200
    worst = 0.0
    for xi, si, ci in zip(x, s, c):
        for got, exact in ((si, mpmath.sin(mpmath.mpf(xi))), (ci, mpmath.cos(mpmath.mpf(xi)))):
            err = abs(mpmath.mpf(got) - exact)
            if abs(exact) < 1e-10:
                assert err < 1e-26, (xi, got, exact)
            else:
                ulps = float(err / np.spacing(abs(float(exact))))
                assert ulps <= 2.0, (xi, got, float(exact), ulps)
                worst = max(worst, ulps)
    assert worst > 0.5  # the comparison compared something
    odd = np.array([np.inf, -np.inf, np.nan])
    so, co = np.empty(3), np.empty(3)
    lib.many(odd.ctypes.data_as(ptr), so.ctypes.data_as(ptr), co.ctypes.data_as(ptr), ctypes.c_long(3))
    assert np.isnan(so).all() and np.isnan(co).all()
