"""Shared fixtures: the built-in robots and random serial robots."""
from __future__ import annotations

import gc
import sys
import threading

import numpy as np
import pytest
from hypothesis import settings

import coopsim as cs

# The property-based tests (hypothesis) draw the same examples every run and keep no example
# database, so that the suite's verdict depends on the code alone. To explore new examples instead:
#   python3 -m pytest --hypothesis-profile=explore tests/test_bad_input.py tests/test_fuzz_world.py
# (random examples, as many per test as the repeatable run; a failure prints how to reproduce it).
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False, database=None, print_blob=True)
settings.load_profile("repeatable")


def random_inertia(rng: np.random.Generator, mass: float) -> np.ndarray:
    """A physically valid inertia tensor (kg m^2): random box-like principal
    moments (triangle inequality holds) in a random orientation."""
    dims = rng.uniform(0.02, 0.4, 3)
    principal = np.diag(cs.box_inertia(mass, *dims))
    A = rng.normal(size=(3, 3))
    Q, _ = np.linalg.qr(A)
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    I = Q @ np.diag(principal) @ Q.T
    return 0.5 * (I + I.T)


def random_robot(seed: int, dof: int | None = None, friction: bool = True, mixed: bool = False,
                 **kw) -> cs.Robot:
    """A random serial robot: R/P joints drawn 0.7/0.3, random DH and CoM rows,
    masses in [0.2, 5] kg, random valid inertias, random base placement.
    mixed=True: 2 to 7 joints (unless dof is given, >= 2) with at least one
    R and one P joint; mixed=False keeps the robots other tests rely on."""
    rng = np.random.default_rng(seed)
    if mixed:
        n = int(rng.integers(2, 8)) if dof is None else dof
        if n < 2:
            raise ValueError("a mixed R/P robot needs dof >= 2")
        types = list(rng.choice(["R", "P"], size=n, p=[0.7, 0.3]))
        # an all-R or all-P draw gets one joint of the other kind, at a random place
        if len(set(types)) == 1:
            i = int(rng.integers(n))
            types[i] = "P" if types[i] == "R" else "R"
        types = "".join(types)
    else:
        n = int(rng.integers(1, 8)) if dof is None else dof
        types = "".join(rng.choice(["R", "P"], size=n, p=[0.7, 0.3]))
    dh = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.3, 0.3, n),
                          rng.uniform(-0.4, 0.4, n), rng.uniform(-np.pi, np.pi, n)])
    com = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.2, 0.2, n),
                           rng.uniform(-0.2, 0.2, n), rng.uniform(-np.pi, np.pi, n)])
    masses = rng.uniform(0.2, 5.0, n)
    inertias = np.array([random_inertia(rng, m) for m in masses])
    K = rng.uniform(0.0, 2.0, n) if friction else np.zeros(n)
    return cs.Robot.from_dh(dh, com, masses, inertias, joint_types=types, friction=K,
                            base_position=rng.uniform(-1, 1, 3), base_yaw=float(rng.uniform(-3, 3)),
                            name=f"random{seed}", **kw)


#: the random fleet of the dynamics and energy tests: each robot has 2 to 7
#: joints, both R and P
FLEET_SEEDS = range(60)


def random_fleet(**kw) -> list[cs.Robot]:
    return [random_robot(s, mixed=True, **kw) for s in FLEET_SEEDS]


def random_state(robot: cs.Robot, rng: np.random.Generator):
    """Random (q, qd, qdd) inside the joint limits where they are finite."""
    n = robot.dof
    lim = robot.q_limits
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi)
    q = rng.uniform(lo, hi)
    return q, rng.normal(size=n), rng.normal(size=n)


ROBOT_FACTORIES = {
    "scara1": lambda: cs.robots.scara1(backend="numeric"),
    "scara2": lambda: cs.robots.scara2(backend="numeric"),
}


@pytest.fixture(params=sorted(ROBOT_FACTORIES))
def scara(request) -> cs.Robot:
    return ROBOT_FACTORIES[request.param]()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def python_ran_during(call, attempts: int = 20) -> int:
    """Whether call() releases the GIL: calls it (up to `attempts` times)
    while another Python thread waits to run. Returns how many calls it took
    until that thread ran during one (1 unless the machine is busy), or 0 if it
    never did: call() holds the GIL throughout.

    The switch interval is raised far beyond the calls' length meanwhile, so
    the interpreter never takes the GIL from this thread to hand it over: the
    other thread can only run when this one releases the GIL, which the Python
    code here does not do between setting `go` and reading `ran`. So a call
    that holds the GIL gives 0 whatever the timing, and no amount of load can
    make it look released. One that releases it lets the other thread run as
    soon as the OS schedules it; on a loaded machine that may come only after
    the call has taken the GIL back, so the call is repeated, each time a new
    chance. There is no wall-time limit to miss."""
    if not getattr(sys, "_is_gil_enabled", lambda: True)():
        pytest.skip("no GIL in this interpreter")
    go, ran, stop = threading.Event(), threading.Event(), threading.Event()

    def other():
        go.wait()
        ran.set()
        stop.wait()  # blocks, so hands the GIL back

    interval, gc_was_enabled = sys.getswitchinterval(), gc.isenabled()
    gc.disable()  # a finalizer run by the collector may release the GIL
    sys.setswitchinterval(100.0)
    th = threading.Thread(target=other)
    try:
        th.start()
        go.set()
        for calls in range(1, attempts + 1):
            call()
            if ran.is_set():
                return calls
        return 0
    finally:
        sys.setswitchinterval(interval)
        if gc_was_enabled:
            gc.enable()
        stop.set()
        th.join()
