"""One driver at a time: the engine holds a simulation's run for the thread advancing or changing
it, and every other thread's step or change fails at once with SimulationBusyError naming the
holder (implicitly for one call, or across a block with ``sim.driving(label)``)."""
from __future__ import annotations

import re
import threading

import numpy as np
import pytest

import coopsim as cs
from coopsim.tasks import scene as task_scene

# generous bound on any wait for another thread (s): a condition, never a timing assertion
WAIT = 120.0
Q0 = ([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03], [0.4, -0.5, -0.5, 0.0, 0.0, 0.02])
LIVE = "the live view at http://127.0.0.1:8080"


class Gate(cs.Reference):
    """A set-point whose first evaluation after arm() waits (GIL released) until open() is called:
    the thread stepping the simulation is then inside the engine, holding the run."""

    dof = 6
    t_start = 0.0
    t_end = 0.0

    def __init__(self, q):
        super().__init__()
        self.q = np.array(q, dtype=float)
        self.opened = threading.Event()
        self.armed = False
        self.waiting = False
        self.concurrent = 0  # evaluations by another thread while the first waited inside the engine

    def arm(self):
        self.opened.clear()
        self.armed = True
        self.concurrent = 0

    def open(self):
        self.opened.set()

    def evaluate(self, t):
        if self.waiting:  # the thread that holds the gate is blocked in it: this is another thread
            self.concurrent += 1
        elif self.armed:
            self.armed = False
            self.waiting = True
            self.opened.wait(WAIT)  # the GIL is released while waiting
            self.waiting = False
        return self.q, np.zeros(6), np.zeros(6)


def task_sim(gate: bool = False, **kw):
    """Both SCARAs of the cooperative task in its world (floor, container, three bars), computed torque
    towards set-points; with gate, SCARA #2's set-point is a Gate (returned too)."""
    bars = [task_scene.bar_pose(0.95, 0.30 + 0.07 * k) for k in range(3)]
    sim = cs.Simulation(dt=2e-4, world=task_scene.world(bars), log_every=10, **kw)
    g = None
    for i, (r, q0) in enumerate(zip(task_scene.scaras(), Q0)):
        ref = np.array(q0, dtype=float)
        if gate and i == 1:
            ref = g = Gate(q0)
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), ref, q0=np.array(q0, dtype=float))
    return (sim, g) if gate else sim


def in_thread(fn):
    """fn() on another thread: (result, exception)."""
    out = {}

    def body():
        try:
            out["result"] = fn()
        except BaseException as e:  # noqa: BLE001 - handed back to the test
            out["error"] = e

    t = threading.Thread(target=body)
    t.start()
    t.join(WAIT)
    assert not t.is_alive(), "the other thread did not finish"
    return out.get("result"), out.get("error")


def busy_message(label, thread):
    return (f"this simulation is being run by '{label}' (thread {thread}); one driver at a time: "
            f"pause or close it first")


def test_the_error_is_a_runtime_error_of_the_package():
    from coopsim.simulation import SimulationBusyError

    assert cs.SimulationBusyError is SimulationBusyError
    assert issubclass(cs.SimulationBusyError, RuntimeError)
    assert "SimulationBusyError" in cs.__all__


def test_two_threads_racing_to_advance_one_simulation_one_runs_the_other_is_refused():
    """Both threads call step(n) at once, 20 times in a row on the task's world: the first in holds the
    run (the gate keeps it inside the engine until the other has tried), the other gets
    SimulationBusyError naming the holder's thread, and the time is what one driver advanced."""
    sim, gate = task_sim(gate=True)
    n = 50
    for rep in range(20):
        sim.reset()
        gate.arm()
        barrier = threading.Barrier(2)
        outcomes = {}

        def driver(name):
            barrier.wait(WAIT)
            try:
                sim.step(n)
                outcomes[name] = ("ran", threading.get_ident())
            except cs.SimulationBusyError as e:
                outcomes[name] = (e, threading.get_ident())
            finally:
                gate.open()  # whoever is done lets the other through

        threads = [threading.Thread(target=driver, args=(k,)) for k in (0, 1)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(WAIT)
        assert not any(t.is_alive() for t in threads), f"repetition {rep}: a driver never finished"
        ran = [k for k, (o, _) in outcomes.items() if o == "ran"]
        refused = [k for k, (o, _) in outcomes.items() if isinstance(o, cs.SimulationBusyError)]
        assert len(ran) == 1 and len(refused) == 1, f"repetition {rep}: {outcomes}"
        assert gate.concurrent == 0, f"repetition {rep}: two threads stepped at once"
        e, _ = outcomes[refused[0]]
        winner = outcomes[ran[0]][1]
        assert e.holder == "another thread" and e.thread == winner
        assert str(e) == busy_message("another thread", winner)
        assert sim.steps == n and sim.time == pytest.approx(n * sim.dt, rel=1e-12)
        assert sim.driver is None  # given back when the call returned
        assert np.isfinite(sim.state(0)[0]).all() and np.isfinite(sim.state(1)[0]).all()


def test_a_free_race_of_two_threads_never_runs_both_at_once():
    """Without a gate, two threads call advance(t) on the task's world at once, 20 times in a row:
    either one ran and the other was refused (they met), and the time is one driver's; or the
    second came after the first had finished and advanced no further (advance goes to a time). Never
    a crash, never another time."""
    sim = task_sim()
    t_end = 0.02
    met = 0
    for rep in range(20):
        sim.reset()
        barrier = threading.Barrier(2)
        errors = [None, None]

        def driver(k):
            barrier.wait(WAIT)
            try:
                sim.advance(t_end)
            except cs.SimulationBusyError as e:
                errors[k] = e

        threads = [threading.Thread(target=driver, args=(k,)) for k in (0, 1)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(WAIT)
        assert not any(t.is_alive() for t in threads)
        refused = [e for e in errors if e is not None]
        assert len(refused) <= 1, f"repetition {rep}: both refused: {refused}"
        met += len(refused)
        pattern = re.escape(busy_message("another thread", "THREAD")).replace("THREAD", r"\d+")
        for e in refused:
            assert e.holder == "another thread" and re.fullmatch(pattern, str(e)), str(e)
        assert sim.steps == round(t_end / sim.dt), f"repetition {rep}: {sim.steps} steps"
    print(f"the drivers met in {met} of 20 races")


def test_driving_holds_the_run_for_its_block_and_refuses_other_threads():
    sim = task_sim()
    me = threading.get_ident()
    assert sim.driver is None
    with sim.driving(LIVE) as s:
        assert s is sim
        assert sim.driver == (LIVE, me)
        # the holder steps and changes it as usual
        sim.step(5)
        sim.set_applied(0, forces=np.zeros(6))
        assert sim.steps == 5
        for what, call in (("step", lambda: sim.step(5)), ("advance", lambda: sim.advance(0.01)),
                           ("run", lambda: sim.run(0.01, progress=False)), ("reset", sim.reset)):
            _, e = in_thread(call)
            assert isinstance(e, cs.SimulationBusyError), what
            assert e.holder == LIVE and e.thread == me
            assert str(e) == busy_message(LIVE, me), what
        # nothing moved: the refused calls did nothing
        assert sim.steps == 5
        # reads are open to the others
        (t, state), e = in_thread(lambda: (sim.time, sim.state(1)))
        assert e is None and t == pytest.approx(5 * sim.dt) and np.isfinite(state[0]).all()
        # a second driver is refused too
        _, e = in_thread(lambda: sim.driving("a second view").__enter__())
        assert isinstance(e, cs.SimulationBusyError) and e.holder == LIVE
    assert sim.driver is None
    # released: another thread drives now
    _, e = in_thread(lambda: sim.step(5))
    assert e is None and sim.steps == 10


def test_every_change_from_another_thread_is_refused_while_driven():
    """Each mutator of the facade, called from another thread while the run is held, raises
    SimulationBusyError and leaves the simulation as it was."""
    sim = task_sim()
    robot0 = sim.robots[0]
    controller0 = sim.controllers[0]
    sim.step(2)
    calls = {
        "set_applied": lambda: sim.set_applied(0, forces=np.ones(6)),
        "set_reference": lambda: sim.set_reference(0, np.zeros(6)),
        "set_controller": lambda: sim.set_controller(0, cs.ComputedTorque(100.0, 20.0)),
        "set_robot": lambda: sim.set_robot(0, robot0),
        "set_sensor": lambda: sim.set_sensor(0, noise_force=1.0),
        "set_body_wrench": lambda: sim.set_body_wrench(task_scene.bar_names(3)[0], np.ones(6)),
        "release": lambda: sim.release(1),
        "set_profiling": lambda: sim.set_profiling(True),
        "sensor": lambda: sim.sensor(0),
        "grasp_check": lambda: sim.grasp_check(1, task_scene.bar_names(3)[0]),
        "cooperation": lambda: sim.cooperation(0, 1),
        "run_paced": lambda: sim.run_paced(sim.time + 0.01, speed=4.0),
        "reset": sim.reset,
    }
    before = (sim.steps, sim.sensor_options(0), sim.body_wrench(task_scene.bar_names(3)[0]).copy())
    with sim.driving(LIVE):
        for name, call in calls.items():
            _, e = in_thread(call)
            assert isinstance(e, cs.SimulationBusyError), f"{name}: {e!r}"
            assert e.holder == LIVE, name
    after = (sim.steps, sim.sensor_options(0), sim.body_wrench(task_scene.bar_names(3)[0]))
    assert after[0] == before[0] and after[1] == before[1]
    np.testing.assert_array_equal(after[2], before[2])
    np.testing.assert_array_equal(sim.applied(0)["forces"], np.zeros(6))
    np.testing.assert_array_equal(sim.references[0].evaluate(0.0)[0], Q0[0])
    assert sim.controllers[0] is controller0


def test_adding_a_robot_from_another_thread_is_refused_while_driven():
    sim = cs.Simulation()
    r = cs.robots.scara1()
    with sim.driving(LIVE):
        _, e = in_thread(lambda: sim.add_robot(r, cs.ComputedTorque(100.0, 20.0), np.zeros(6)))
        assert isinstance(e, cs.SimulationBusyError) and e.holder == LIVE
        assert sim.robot_count == 0
        sim.add_robot(r, cs.ComputedTorque(100.0, 20.0), np.zeros(6))  # the holder may
    assert sim.robot_count == 1


def test_the_hold_is_released_after_an_exception_in_the_block():
    sim = task_sim()
    with pytest.raises(KeyError):
        with sim.driving(LIVE):
            sim.step(3)
            raise KeyError("in the block")
    assert sim.driver is None
    _, e = in_thread(lambda: sim.step(3))
    assert e is None and sim.steps == 6


def test_the_hold_is_released_after_an_engine_error_in_the_block():
    sim = task_sim()
    with pytest.raises(ValueError, match="t_end"):
        with sim.driving(LIVE):
            sim.advance(-1.0)
    assert sim.driver is None
    _, e = in_thread(lambda: sim.step(1))
    assert e is None


def test_holds_nest_on_one_thread_and_the_outer_label_stays():
    sim = task_sim()
    me = threading.get_ident()
    with sim.driving(LIVE):
        with sim.driving("a nested driver"):
            assert sim.driver == (LIVE, me)
            sim.step(1)
        # the inner block gave back its own hold only
        assert sim.driver == (LIVE, me)
        _, e = in_thread(lambda: sim.step(1))
        assert isinstance(e, cs.SimulationBusyError) and e.holder == LIVE
    assert sim.driver is None


def test_a_driver_on_another_thread_refuses_this_thread():
    """The live view's case: its thread drives; the notebook's advance gets the error while it runs,
    and runs once the driver has let go."""
    sim = task_sim()
    holding, done = threading.Event(), threading.Event()
    ident = {}

    def view_thread():
        with sim.driving(LIVE):
            ident["t"] = threading.get_ident()
            sim.step(4)
            holding.set()
            done.wait(WAIT)

    t = threading.Thread(target=view_thread)
    t.start()
    try:
        assert holding.wait(WAIT)
        with pytest.raises(cs.SimulationBusyError, match=re.escape(busy_message(LIVE, ident["t"]))):
            sim.advance(1.0)
        with pytest.raises(cs.SimulationBusyError):
            sim.reset()
        with pytest.raises(cs.SimulationBusyError):
            with sim.driving("the notebook"):
                pass
        assert sim.steps == 4
        assert sim.stats is not None and sim.stats.steps == 4  # the driver's statistics, not the refused call's
    finally:
        done.set()
        t.join(WAIT)
    sim.advance(0.002)
    assert sim.steps == 10


def test_a_held_simulation_in_a_batch_reports_the_busy_error():
    sims = [task_sim(), task_sim()]
    holding, done = threading.Event(), threading.Event()

    def driver():
        with sims[1].driving(LIVE):
            holding.set()
            done.wait(WAIT)

    t = threading.Thread(target=driver)
    t.start()
    try:
        assert holding.wait(WAIT)
        errors = cs.Simulation.advance_all(sims, 0.004, threads=2)
    finally:
        done.set()
        t.join(WAIT)
    assert errors[0] is None and sims[0].steps == 20
    assert isinstance(errors[1], cs.SimulationBusyError) and errors[1].holder == LIVE and sims[1].steps == 0


@pytest.mark.parametrize("label", ["", None, 3])
def test_driving_needs_a_label(label):
    sim = task_sim()
    with pytest.raises(ValueError, match="label must be a non-empty str"):
        with sim.driving(label):
            pass
    assert sim.driver is None
