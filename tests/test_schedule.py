"""The engine's schedule (Simulation.run_schedule, coopsim.schedule): a sequence of steps, their actions, waits,
checks and records run in one engine call. The carry and the handover run on it to the same results as their
Python sequencing (tests/test_engine_waits.py); here: what each part of a step does, a bad schedule or a bad action
as a one-line ValueError naming the step, a condition that never comes true as a one-line ScheduleError naming the
step, a forbidden contact, a clamp letting go, an engine error with its step, and the run's bookkeeping."""
from __future__ import annotations

import threading

import numpy as np
import pytest

import coopsim as cs
from coopsim.schedule import (AddCooperative, Holding, Release, RemoveCooperative, ScheduleError, SetBodyWrench,
                              SetController, SetReference, Step)
from coopsim.tasks import carry as C
from coopsim.tasks.carry import sequence as carry_sequence

from test_grasp import BOX, PID, Q0, closing, scene


def _grasping(**kw):
    """SCARA #1 closing its jaws on a box on a pedestal (the clamp rule grasps it about 0.13 s in)."""
    r, w = scene(BOX)
    return closing(r, w, **kw)


def test_a_wait_ends_at_the_grasp_and_records_it_where_the_engines_waits_stop():
    sim = _grasping()
    res = sim.run_schedule([Step("close", until=1.0, every=0.001, wait=[Holding(0, "box")],
                                 record=[Holding(0, "box")])])
    g = sim.log.grasps
    assert len(g) == 1 and sim.holding(0) == "box"
    # the step ended after the 1 ms piece of the grasp, as advance_until stops
    t_grasp = float(g.t.iloc[0])
    assert t_grasp <= sim.time < t_grasp + 0.001 + 1e-12
    other = _grasping()
    other.advance_until(1.0, "grasp", every=0.001)
    assert other.time == sim.time
    (t0, t1), = res.times
    assert t0 == 0.0 and t1 == sim.time
    rec, = res.records
    assert (rec.step, rec.condition, rec.t) == (0, 0, sim.time)
    np.testing.assert_array_equal(rec.q, sim.state(0)[0])
    np.testing.assert_array_equal(rec.pose, sim.body_state("box").pose)


def test_a_condition_that_never_comes_true_is_a_one_line_error_naming_the_step():
    sim = _grasping(jaw_ref=0.04)          # the jaw is commanded open: no grasp
    with pytest.raises(ScheduleError) as info:
        sim.run_schedule([Step("approach", until=0.1),
                          Step("grasp", until=0.5, every=0.01, wait=[Holding(0, "box")])])
    e = info.value
    assert "\n" not in str(e)
    assert str(e).startswith("grasp at t = 0.5000 s: robot 0 ('scara1') did not grasp box within 0.4 s: the clamp "
                             "rule's closing, touching failed (angle 0.0 deg, gaps "), str(e)
    assert (e.step, e.index, e.kind, e.condition, e.t) == ("grasp", 1, "wait", 0, sim.time)
    assert e.result.times == [(0.0, 0.1), (0.1, sim.time)]
    assert sim.time == pytest.approx(0.5, abs=1e-12)
    # a condition at a step's end: the same reason, without the timeout
    sim = _grasping(jaw_ref=0.04)
    with pytest.raises(ScheduleError, match=r"^hold on at t = 0.2000 s: robot 0 \('scara1'\) did not grasp box: "):
        sim.run_schedule([Step("hold on", until=0.2, at_end=[Holding(0, "box")])])


def test_a_clamp_letting_go_fails_the_step_that_holds_it_with_the_release():
    opened = Q0.copy()
    opened[5] = 0.045
    sim = _grasping()
    sim.run_schedule([Step("grasp", until=0.3, every=0.001, wait=[Holding(0, "box")])])
    with pytest.raises(ScheduleError, match=r"^carry at t = 0\.\d+ s: robot 0 \('scara1'\) let go of box "
                                            r"\(opened at t = 0\.\d{4} s\)$") as info:
        sim.run_schedule([Step("carry", until=0.6, every=0.05, hold=[Holding(0, "box")]),
                          Step("carry", until=1.0, every=0.05, hold=[Holding(0, "box")],
                               actions=[SetReference(0, opened)])])
    e = info.value
    assert e.kind == "hold" and e.index == 1 and sim.holding(0) is None
    # it stopped after the 50 ms piece in which the jaw let go
    released = float(sim.log.grasps.t.iloc[-1])
    assert 0.6 < released <= sim.time < released + 0.05 + 1e-9
    # a release awaited: holding nothing
    sim = _grasping()
    sim.run_schedule([Step("grasp", until=0.3, every=0.001, wait=[Holding(0, "box")]),
                      Step("open", until=1.0, every=0.001, actions=[SetReference(0, opened)], wait=[Holding(0)])])
    assert sim.holding(0) is None and sim.time < 0.5
    assert float(sim.log.grasps.t.iloc[-1]) <= sim.time < float(sim.log.grasps.t.iloc[-1]) + 0.001 + 1e-9


def test_contacts_are_checked_against_the_allowed_ones_with_patterns_and_times():
    """The box on its pedestal touches it from the first world step, and the jaws from the grasp on."""
    sim = _grasping()
    with pytest.raises(ScheduleError) as info:
        sim.run_schedule([Step("close", until=0.3, every=0.01)], allowed_contacts=[])
    e = info.value
    assert e.kind == "contact" and set(e.bodies) == {"box", "pedestal"} and e.t == 0.0
    assert str(e) == "close at t = 0.0000 s: unexpected contact between " + " and ".join(e.bodies)
    assert sim.time == pytest.approx(0.01)          # after the first 10 ms piece
    allowed = [("box", "pedestal"), ("box", "*/fixed_jaw"), ("*/link6", "box")]
    sim = _grasping()
    res = sim.run_schedule([Step("close", until=0.3, every=0.01)], allowed_contacts=allowed)
    ev = sim.contact_events()
    assert res.contacts_seen == len(ev["a"]) >= 2
    # a window that opens after the jaws touched (from the start): their contact is not allowed
    sim = _grasping()
    with pytest.raises(ScheduleError, match="unexpected contact between") as info:
        sim.run_schedule([Step("close", until=0.3, every=0.01)],
                         allowed_contacts=[("box", "ped*"), ("box", "scara1/*", 0.1, None)])
    assert info.value.t < 0.1 and any(b.startswith("scara1/") for b in info.value.bodies)
    sim = _grasping()
    sim.run_schedule([Step("close", until=0.3, every=0.01)],
                     allowed_contacts=[("box", "ped*"), ("box", "scara1/*", 0.0, 0.01)])
    # without allowed_contacts nothing is checked; contacts_seen skips the events already looked at
    sim = _grasping()
    seen = sim.run_schedule([Step("close", until=0.3)]).contacts_seen
    assert seen == 0
    n = len(sim.contact_events()["a"])
    sim.run_schedule([Step("more", until=0.4)], allowed_contacts=[], contacts_seen=n)


def test_actions_change_the_run_at_their_steps_start_as_the_calls_do():
    r = cs.robots.scara1()
    q1 = Q0.copy()
    q1[0] += 0.2

    def make():
        w = cs.World(gravity=r.gravity_acceleration)
        w.add_free_box("cube", [0.02, 0.02, 0.02], 0.1, position=[0.5, 0.0, 0.3])
        sim = cs.Simulation(dt=2e-4, world=w, log_every=25)
        sim.add_robot(r, cs.PID(**PID), Q0)
        return sim

    a = make()
    ct = cs.ComputedTorque(400.0, 40.0)
    a.run_schedule([Step("still", until=0.1),
                    Step("move", until=0.3, actions=[SetReference(0, q1), SetController(0, ct),
                                                     SetBodyWrench("cube", [0, 0, 0.981, 0, 0, 0])]),
                    Step("drop", until=0.4, actions=[SetBodyWrench("cube", np.zeros(6)), Release(0)])])
    b = make()
    b.advance(0.1)
    b.set_reference(0, q1)
    b.set_controller(0, cs.ComputedTorque(400.0, 40.0))
    b.set_body_wrench("cube", [0, 0, 0.981, 0, 0, 0])
    b.advance(0.3)
    b.set_body_wrench("cube", np.zeros(6))
    b.release(0)
    b.advance(0.4)
    np.testing.assert_array_equal(a.log.robots[0].q, b.log.robots[0].q)
    np.testing.assert_array_equal(a.body_log("cube").position, b.body_log("cube").position)
    # the cube's weight balanced by the wrench over "move" only: its fall's speed steady there, not before
    z = a.body_log("cube")
    k = (z.t > 0.1) & (z.t <= 0.3)
    assert np.ptp(z.velocity[k, 2]) < 1e-6 and np.ptp(z.velocity[z.t <= 0.1, 2]) > 0.5


def test_a_cooperative_group_added_and_removed_by_the_schedule():
    """The carry's law installed at the lift and removed at the release by the carry's schedule: the simulation's
    cooperatives follow (a carry failed while carrying keeps its group; one that ended has none)."""
    res = C.run(controllers="object", score_run=False)
    assert res.success and res.sim.cooperatives == []
    d = C.Disturbances(push=((0.0, 0.0, -60.0), 0.5, 0.2), names=("push",))
    res = C.run(disturbance=d, controllers="object", score_run=False)
    assert res.report["failure"]["step"] == "carry"
    sim = res.sim
    assert [g["robots"] for g in sim.cooperatives] == [[0, 1]]
    with pytest.raises(ValueError, match=r"^schedule step 1 \('b'\), action 1 \(remove_cooperative\): no group to "
                                         r"remove \(the schedule added none before it\)$"):
        sim.run_schedule([Step("b", until=sim.time + 0.01, actions=[RemoveCooperative()])])
    with pytest.raises(ValueError, match=r"^schedule step 1 \('b'\), action 1 \(remove_cooperative\): group 3 out "
                                         r"of range$"):
        sim.run_schedule([Step("b", until=sim.time + 0.01, actions=[RemoveCooperative(3)])])
    sim.run_schedule([Step("b", until=sim.time, actions=[RemoveCooperative(sim.cooperatives[0]["group"])])])
    assert sim.cooperatives == []


BAD = {
    "a robot out of range": ([Step("lift", 0.1, actions=[SetController(5, "ct")])],
                             r"^schedule step 1 \('lift'\), action 1 \(set_controller\): robot 5 out of range "
                             r"\(0 \.\. 0\)$"),
    "a controller that is not one": ([Step("lift", 0.1, actions=[SetController(0, "ct")])],
                                     r"^schedule step 1 \('lift'\), action 1 \(set_controller\): an argument of the "
                                     r"wrong type in \('set_controller', 0, 'ct'\)$"),
    "not an action": ([Step("lift", 0.1, actions=["open"])],
                      r"^schedule step 1 \('lift'\), action 1: not an action"),
    "a time going back": ([Step("a", 0.2), Step("b", 0.1)],
                          r"^schedule step 2 \('b'\): until 0\.1 s is before the previous step's end \(0\.2 s\)$"),
    "an unknown body": ([Step("a", 0.1, wait=[Holding(0, "cup")])],
                        r"^schedule step 1 \('a'\), wait: no body named 'cup' in the world$"),
    "a reference of other joints": ([Step("a", 0.1, actions=[SetReference(0, np.zeros(4))])],
                                    r"^schedule step 1 \('a'\), action 1 \(set_reference\): wrong shape for reference: expected \(6,\), got \(4,\)$"),
    "a negative piece": ([Step("a", 0.1, every=-0.01)], r"^schedule step 1 \('a'\): every must be finite and >= 0 s, got -0\.01$"),
    "a nameless step": ([Step("", 0.1)], r"^schedule step 1 \(''\): name must be a non-empty str$"),
    "a bad contact rule": ([Step("a", 0.1)], r"^allowed contact 1 must be \(a, b\) or \(a, b, from, to\)"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_schedule_is_a_one_line_value_error_naming_the_step_before_anything_runs(case):
    steps, match = BAD[case]
    sim = _grasping()
    if case == "a robot out of range":
        steps = [Step("lift", 0.1, actions=[SetController(5, cs.ComputedTorque(1.0, 1.0))])]
    kw = dict(allowed_contacts=[("box",)]) if case == "a bad contact rule" else {}
    with pytest.raises(ValueError, match=match) as info:
        sim.run_schedule(steps, **kw)
    assert "\n" not in str(info.value)
    assert sim.time == 0.0 and sim.steps == 0


def test_an_action_the_simulation_refuses_names_the_step_and_its_time_and_stops_there():
    r, w = scene(BOX)
    sim = cs.Simulation(dt=2e-4, world=w, log_every=25)
    a, b = cs.PID(**PID), cs.PID(**PID)
    sim.add_robot(r, a, Q0)
    sim.add_robot(r, b, Q0)
    with pytest.raises(ValueError) as info:
        sim.run_schedule([Step("still", 0.1), Step("swap", 0.2, actions=[SetController(1, a)])])
    assert str(info.value).startswith("schedule step 2 ('swap') at t = 0.1000 s, action 1 (set_controller): "
                                      "controller is already driving robot 0"), str(info.value)
    assert "\n" not in str(info.value)
    assert sim.time == pytest.approx(0.1)


class Exploding(cs.Controller):
    """A controller whose torque goes non-finite at 0.05 s: the run diverges."""

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        return np.full(6, np.nan if t >= 0.05 else 0.0)


def test_an_engine_error_is_raised_as_it_is_with_its_step():
    sim = _grasping()
    with pytest.raises((cs.DivergenceError, ValueError)) as info:
        sim.run_schedule([Step("still", 0.02), Step("boom", 0.2, actions=[SetController(0, Exploding())])])
    e = info.value
    assert e.schedule_step == "boom"
    assert e.schedule_result.times[0] == (0.0, 0.02) and len(e.schedule_result.times) == 2
    assert sim.time < 0.06


def test_a_schedule_runs_with_the_gil_released():
    """A Python thread counts while the carry's schedule runs: it gets the interpreter inside the engine call."""
    plan = C.make_plan(C.START, C.END)
    counts = []
    stop = threading.Event()

    def count():
        n = 0
        while not stop.is_set():
            n += 1
        counts.append(n)

    res = C.run(score_run=False)        # warm
    t = threading.Thread(target=count)
    c0 = cs.gil_released_seconds()
    t.start()
    res = C.run(score_run=False)
    stop.set()
    t.join()
    assert res.success and counts[0] > 0
    assert cs.gil_released_seconds() > c0
    del plan


def test_ctrl_c_stops_a_schedule_between_pieces_with_the_log_kept():
    """A KeyboardInterrupt while the engine runs a schedule on the main thread stops it within 4096 steps, the
    state and the log consistent (every row up to the time it stopped), and the run goes on from there."""
    import _thread

    sim = cs.Simulation(dt=2e-4, log_every=25)
    sim.add_robot(cs.robots.scara1(), cs.ComputedTorque(400.0, 40.0), Q0)
    timer = threading.Timer(0.02, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            sim.run_schedule([Step("long", until=600.0)])
    finally:
        timer.cancel()
    assert 0.0 < sim.time < 600.0 and sim.steps % 4096 == 0
    assert len(sim.log.t) == sim.steps // 25 + 1 and sim.log.t[-1] == pytest.approx((sim.steps // 25) * 25 * 2e-4)
    t = sim.time
    sim.run_schedule([Step("on", until=t + 0.01)])
    assert sim.time == pytest.approx(t + 0.01)
