"""The tasks' sequences handed to the engine (Simulation.run_schedule, Simulation.advance_until): the engine advances
in the callers' chunks and checks between them, so a carry and a handover run to the same results as when Python
advanced chunk by chunk and looked between chunks (same reports, same logs, bit for bit); bad
arguments are one-line ValueErrors; and the engine's count of the time a thread spends in it with the GIL released
(coopsim.gil_released_seconds), which benchmarks/bench_scaling.py divides by a run's wall time."""
from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

import coopsim as cs

from coopsim.tasks import carry as C
from coopsim.tasks import handover as H
from coopsim.tasks.carry import sequence as carry_sequence
from coopsim.tasks.handover import sequence as handover_sequence


# ---- the callers' loops as they were: Python advances chunk by chunk and looks between chunks ----

def _carry_run_to(self, t_end, chunk=None, held=False):
    while self.sim.time < t_end - 1e-12:
        t = t_end if chunk is None else min(t_end, self.sim.time + chunk)
        try:
            self.sim.advance(t)
        except ValueError:
            if self.group is not None and any(self.sim.holding(i) != C.scene.BAR for i in range(2)):
                self.check_held()
            raise
        if held:
            self.check_held()
        self.check_contacts()


def _carry_wait_grasps(self, t_end):
    while self.sim.time < t_end - 1e-12:
        self.sim.advance(min(t_end, self.sim.time + carry_sequence.CHUNK))
        self.check_contacts()
        for i in range(2):
            if self.anchors[i] is None and self.sim.holding(i) == C.scene.BAR:
                self.record_anchor(i)
    real_wait = _real["wait_grasps"]
    real_wait(self, t_end)      # at t_end already: only its checks of the grasps run


def _handover_wait_for(self, condition, timeout, what):
    t_end = self.sim.time + timeout
    while self.sim.holding(condition.robot) != condition.body:
        if self.sim.time >= t_end - 1e-12:
            raise handover_sequence.TaskError(self.step, self.sim.time, what)
        self.run_to(min(self.sim.time + 0.01, t_end))


def _handover_run_to(self, t_end):
    if t_end > self.t_limit:
        raise handover_sequence.TaskError(self.step, self.sim.time, f"the task would run past its time limit of "
                                          f"{self.t_limit} s")
    self.sim.advance(t_end)
    self.check_contacts()


_real = dict(wait_grasps=carry_sequence._Runner.wait_grasps)


@pytest.fixture
def python_chunks(monkeypatch):
    """Runs the tasks with the loops above (Python chunk by chunk) in place of the engine's waits."""
    def use():
        monkeypatch.setattr(carry_sequence._Runner, "run_to", _carry_run_to)
        monkeypatch.setattr(carry_sequence._Runner, "wait_grasps", _carry_wait_grasps)
        monkeypatch.setattr(handover_sequence._Runner, "wait_for", _handover_wait_for)
        monkeypatch.setattr(handover_sequence._Runner, "run_to", _handover_run_to)
    return use


class Calls:
    """Counts the simulations' stepping calls (Simulation._timed) while active."""

    def __enter__(self):
        self.n, real = 0, cs.Simulation._timed
        self.real = real

        def counted(sim, call, *args):
            self.n += 1
            return real(sim, call, *args)
        cs.Simulation._timed = counted
        return self

    def __exit__(self, *exc):
        cs.Simulation._timed = self.real


def _same(a, b, path="report"):
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{path}[{k}]")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=path)
    elif isinstance(a, float) and np.isnan(a):
        assert np.isnan(b), path
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


def _same_log(a, b):
    assert a.time == b.time and a.steps == b.steps
    la, lb = a.log, b.log
    np.testing.assert_array_equal(la.t, lb.t)
    for ra, rb in zip(la.robots, lb.robots):
        for qty in ("q", "qd", "tau", "weld"):
            np.testing.assert_array_equal(getattr(ra, qty), getattr(rb, qty), err_msg=qty)
    ga, gb = la.grasps, lb.grasps
    assert ga.equals(gb)
    assert la.contacts.equals(lb.contacts)


_TEAR = C.Disturbances(push=((0.0, 0.0, -60.0), 0.5, 0.2), names=("push",))   # tears the bar out of a clamp

CARRIES = {
    "computed torque, scored": dict(seed=0, score_run=True),
    "a clamp torn open under computed torque": dict(seed=1, disturbance=_TEAR, score_run=True),
    "a clamp torn open under object control": dict(seed=1, disturbance=_TEAR, controllers="object", score_run=True),
    "phased computed torque with the payload": dict(seed=4, controllers="ct-payload", disturbance="push",
                                                    score_run=True),
    "object control under a push": dict(seed=2, controllers="object", disturbance="push", score_run=True),
    "a clamp that never closes": dict(seed=0, jaws_close=(True, False), score_run=True),
    "leader-follower": dict(seed=3, controllers="leader-follower", score_run=False),
}


@pytest.mark.parametrize("case", list(CARRIES))
def test_the_carry_with_the_engines_waits_equals_the_carry_chunk_by_chunk(case, python_chunks):
    kw = CARRIES[case]
    with Calls() as engine_calls:
        engine = C.run(**kw)
    python_chunks()
    with Calls() as python_calls:
        python = C.run(**kw, sequencing="python")
    _same(engine.report, python.report)
    _same_log(engine.sim, python.sim)
    if kw.get("score_run"):
        _same(engine.series, python.series, "series")
    # the engine's waits made a handful of calls where Python made one per chunk
    assert python_calls.n > 20 * engine_calls.n, (python_calls.n, engine_calls.n)


HANDOVERS = {
    "three bars, scored": dict(cycles=3, score=True),
    "a forbidden contact (a steeper tube)": dict(cycles=1, slope=np.radians(35), score=True),
}


@pytest.mark.parametrize("case", list(HANDOVERS))
def test_the_handover_with_the_engines_waits_equals_the_handover_chunk_by_chunk(case, python_chunks):
    kw = HANDOVERS[case]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # the steeper tube's run warns of its failure
        with Calls() as engine_calls:
            engine = H.run(**kw)
        python_chunks()
        with Calls() as python_calls:
            python = H.run(**kw)
    _same(engine.report, python.report)
    assert python_calls.n > engine_calls.n + 20, (python_calls.n, engine_calls.n)
    _same_log(engine.sim, python.sim)
    if case.startswith("a forbidden"):
        assert "forbidden contact" in engine.report["cycles"][0]["reason"]


def test_the_carry_is_one_engine_call():
    """Counted: the carry's sequence is one engine call (its schedule), not one per phase and event (17 with the
    engine's waits alone) or per chunk (1574 chunk by chunk)."""
    with Calls() as calls:
        r = C.run(seed=0, score_run=False)
    assert r.success and calls.n == 1
    with Calls() as calls:
        r = C.run(seed=0, score_run=False, sequencing="python")
    events = len(r.log.grasps) + len(r.log.contacts)
    assert r.success and 1 < calls.n <= 10 + events, (calls.n, events)


# ---- advance_until itself ----



def test_advance_until_stops_after_the_chunk_of_the_event_and_equals_chunks():
    """A simulation advanced by advance_until(every=chunk) stops at the end of the chunk in which the first grasp
    happened, and a twin advanced chunk by chunk in Python sees that grasp first after the same chunk."""
    def carry_sim():
        res = C.run(seed=0, score_run=False)     # a carry's scene and references, run again from t = 0
        sim = res.sim
        sim.reset()
        return sim
    a, b = carry_sim(), carry_sim()
    chunk = 0.001
    t_end = 3.0
    found = a.advance_until(t_end, "grasp", every=chunk)
    assert found == "grasp"
    g = a.log.grasps
    assert len(g) >= 1 and a.time < t_end
    t_event = float(g.t.iloc[0])
    assert t_event <= a.time < t_event + chunk + 1e-12
    while len(b.log.grasps) == 0:
        b.advance(min(t_end, b.time + chunk))
    assert b.time == a.time and b.steps == a.steps
    np.testing.assert_array_equal(a.state(0)[0], b.state(0)[0])
    # reaching t_end without an event: None
    c = carry_sim()
    assert c.advance_until(0.5, ("grasp", "contact"), every=0.05) in (None, "contact")


@pytest.mark.parametrize("kw, match", [
    (dict(until="slip"), "until must name events of 'grasp', 'contact', got 'slip'"),
    (dict(until=()), "until must name at least one event"),
    (dict(until="grasp", every=0.0), "every must be a finite time > 0 s, got 0.0"),
    (dict(until="grasp", every=float("nan")), "every must be a finite time > 0 s"),
])
def test_advance_until_refuses_bad_arguments_in_one_line(kw, match):
    sim = cs.Simulation(dt=1e-3)
    sim.add_robot(cs.robots.scara1(), cs.ComputedTorque(900.0, 60.0), np.zeros(6))
    until = kw.pop("until")
    with pytest.raises(ValueError, match=match) as e:
        sim.advance_until(0.1, until, **kw)
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="before the current time"):
        sim.advance(0.05)
        sim.advance_until(0.01, "grasp")


def test_advance_until_without_a_world_runs_to_the_end():
    sim = cs.Simulation(dt=1e-3)
    sim.add_robot(cs.robots.scara1(), cs.ComputedTorque(900.0, 60.0), np.zeros(6))
    assert sim.advance_until(0.2, ("grasp", "contact"), every=0.01) is None
    assert sim.steps == 200


# ---- the engine's count of the time with the GIL released ----

class Sleepy(cs.Controller):
    """A controller in Python that holds the GIL for a while at each update (busy, not sleeping: a sleep would
    release it)."""

    def __init__(self):
        super().__init__()
        self.held = 0.0

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < 2e-4:
            pass
        self.held += time.perf_counter() - t0
        return np.zeros(len(q))


def test_the_gil_released_count_grows_inside_the_engine_and_pauses_in_python_callbacks():
    sim = cs.Simulation(dt=1e-3)
    sim.add_robot(cs.robots.scara1(), cs.ComputedTorque(900.0, 60.0), np.zeros(6))
    c0, w0 = cs.gil_released_seconds(), time.perf_counter()
    sim.advance(2.0)
    released, wall = cs.gil_released_seconds() - c0, time.perf_counter() - w0
    assert 0.0 < released <= wall
    # a Python controller holds the GIL inside the engine's call: that time is not counted as released
    slow = cs.Simulation(dt=1e-3)
    ctrl = Sleepy()
    slow.add_robot(cs.robots.scara1(), ctrl, np.zeros(6))
    c0, w0 = cs.gil_released_seconds(), time.perf_counter()
    slow.advance(0.2)
    released, wall = cs.gil_released_seconds() - c0, time.perf_counter() - w0
    assert ctrl.held > 0.0
    assert 0.0 <= released <= wall - ctrl.held
    # outside the engine the count stands still
    c0 = cs.gil_released_seconds()
    sum(range(100000))
    assert cs.gil_released_seconds() == c0
