"""The task's sequence and rules: each phase of a cycle planned from the state the previous one left and run
on the simulation, grasps and releases through the clamp rule, a cycle failing on a forbidden contact, a grasp
or release that does not happen or a bar that does not slide down the tube; :func:`run` runs the cycles."""
from __future__ import annotations

import dataclasses
import itertools
import math
import time
from typing import Dict, List, Optional, Sequence

import numpy as np

from ..._core import ComputedTorque, CubicTrajectory, DivergenceError, IKError
from ...planning import plan_cartesian, rotz
from ...schedule import Holding, ScheduleError, Step
from ...simulation import Simulation
from ... import view
from ...view.live import Restart
from .. import scene
from .constants import (BACK_OFF, BEFORE_MOUTH, BESIDE, BRANCH, CLEAR_ABOVE, CLOSE_SPEED, DEG, GRASP_TIMEOUT, GRIP1,
                        INSERT_BRANCH, INSERT_DEPTH, MAX_CYCLES, OMEGA, OPEN, RELEASE_FADE, RETREAT2, SLIDE_BACK, SLIDE_MIN,
                        SQUEEZE, TIMES)
from .planning import Planner, _grip_down, _pose, _yaw_pitch, default_bars, random_bar
from .scoring import score_cycles
from .summary import summary


_WAIT_CHUNK = 0.01   # s: a wait for a grasp or release looks for it after every such chunk


class TaskError(RuntimeError):
    """A cycle of the task failed: `step` (name), `t` (s), `reason`, and the bodies involved."""

    def __init__(self, step: str, t: float, reason: str, bodies: Sequence[str] = ()):
        super().__init__(f"{step} at t = {t:.4f} s: {reason}")
        self.step, self.t, self.reason, self.bodies = step, t, reason, tuple(bodies)


@dataclasses.dataclass
class TaskResult:
    """What :func:`run` returns: the report (a dict of plain values, JSON-ready), the simulation and its log."""

    report: dict
    sim: Simulation
    log: object
    series: Optional[dict] = None  # t (rows,), clearance_robots, clearance_container (m), tool_error (rows, 2) m,
    #                                 weld_force (rows, 2) N; over the dual hold (NaN elsewhere, log.cooperation):
    #                                 squeeze (rows,) N, internal_force (rows,) N, internal_moment (rows,) N m,
    #                                 load_share (rows, 2), relative_pose_error (rows, 6) m, rad
    timing: Optional[dict] = None  # wall seconds of the run (planning and simulation) and of the scoring; kept out of
    #                                the report, which is the same bit for bit for the same input
    live: Optional[object] = None  # the coopsim.view.LiveView of a run with live=..., or None

    @property
    def success(self) -> bool:
        return bool(self.report["success"])



def _times(t0: float, durations) -> list:
    """[t0, t0 + d0, t0 + (d0 + d1), ...] (s): what ``[t0] + list(t0 + np.cumsum(durations))`` gives, bit for bit
    (the running sum first, then t0 added), on Python floats (a few values: numpy's calls cost more than the
    sums)."""
    return [t0] + [t0 + c for c in itertools.accumulate(float(d) for d in durations)]


class _Runner(Planner):
    """The task on one simulation: plans and runs the phases of every cycle (scored by
    :func:`~coopsim.tasks.handover.scoring.score`)."""

    def __init__(self, bars, *, dt, log_every, world_every, control_every, mouth, slope, handover_yaw, t_limit,
                 container_shift=None, grip1_turn=0.0):
        Planner.__init__(self, handover_yaw)
        self.bars = [np.asarray(b, float) for b in bars]
        self.names = scene.bar_names(len(self.bars))
        self.mouth = scene.CONTAINER["mouth"] if mouth is None else np.asarray(mouth, float)
        self.slope = scene.CONTAINER["slope"] if slope is None else float(slope)
        self.axes = scene.container_axes(self.slope)
        placed = self.mouth if container_shift is None else self.mouth + np.asarray(container_shift, float)
        self.walls = scene.container_walls(placed, self.slope)
        self.grip1_turn = float(grip1_turn)
        w = scene.world(self.bars, mouth=placed, slope=self.slope)
        self.sim = Simulation(dt=dt, world=w, log_every=log_every, world_every=world_every,
                              control_every=control_every)
        self.t_limit = t_limit
        self.live = None     # a coopsim.view.LiveView that runs the phases paced, or None (headless)
        # start: #1 waiting above its handover grip, #2 above its first pick
        self.q1_wait = self._ik(0, self._wait1_pose(), OPEN)
        for k, T in enumerate(self.bars):   # every bar pickable where it lies: checked before the run
            self.step = f"planning the pick of {self.names[k]}"
            self.pick_grip(T)
        self.q2_home = self._ik(1, self._above(*self.pick_grip(self.bars[0])), OPEN)
        self.sim.add_robot(self.r1, ComputedTorque(OMEGA[0] ** 2, 2.0 * OMEGA[0]), self.q1_wait)
        self.sim.add_robot(self.r2, ComputedTorque(OMEGA[1] ** 2, 2.0 * OMEGA[1]), self.q2_home)
        self.restart()

    def restart(self) -> None:
        """The task's own state at its start (the simulation's is its reset's: t = 0, the robots and bars
        where they began)."""
        self.cycles: List[dict] = []
        self.step = "start"
        self.contact_seen = 0
        self.state = {name: "floor" for name in self.names}   # floor -> grasped -> held (lifted) -> released
        self.label: Dict[str, np.ndarray] = {}   # the task's frame of each bar in its body frame
        self.outcome: Dict[str, str] = {}
        self._rules = None       # (the bars' states, contact_rules for them)

    # ---- running ----

    def q_ref(self, i) -> np.ndarray:
        return self.sim.reference(i).evaluate(self.sim.time)[0]

    def move_joints(self, i, points, durations):
        """Robot i through joint points (each (6,)) from its present reference, at rest at each."""
        q0 = self.q_ref(i)
        t0 = self.sim.time
        times = _times(t0, durations)
        self.sim.set_reference(i, CubicTrajectory(times, np.vstack([q0] + [np.asarray(p, float) for p in points])))
        return times[-1]

    def move_line(self, i, poses, durations, opening, intermediate=4, branch=None):
        """Robot i's tool along straight lines through `poses` from its present pose (opening: jaw, m)."""
        r = (self.r1, self.r2)[i]
        q0 = self.q_ref(i)
        t0 = self.sim.time
        times = _times(t0, durations)
        P = [r.fk(q0)] + [self._reachable(i, T) for T in poses]
        op = [q0[5]] + [opening] * len(poses)
        try:
            traj, info = plan_cartesian(r, P, times, opening=op, q_start=q0, intermediate=intermediate, info=True,
                                        branch=BRANCH[i] if branch is None else branch)
        except IKError as e:
            raise IKError(f"{('SCARA #1', 'SCARA #2')[i]}, {self.step}: {e}") from None
        Q = info["q_points"]
        Q[0] = q0
        self.sim.set_reference(i, CubicTrajectory(info["times"], Q))
        return times[-1]

    def jaw(self, i, opening, duration):
        q = self.q_ref(i).copy()
        q[5] = opening
        return self.move_joints(i, [q], [duration])

    def bar(self, name) -> np.ndarray:
        """A bar's pose now in the task's frame for it (see pick_grip), (4, 4)."""
        return self.sim.body_state(name).pose @ self.label.get(name, np.eye(4))

    def close(self, i):
        """Robot i's jaw closes fast to 2 mm over the bar's width, then slowly (CLOSE_SPEED) on to SQUEEZE:
        the moving jaw meets the bar at a speed the clamp rule takes as 'moving with the clamp'."""
        q = self.q_ref(i)
        near = q.copy()
        near[5] = 2.0 * scene.BAR_HALF_EXTENTS[1] + 0.002
        shut = q.copy()
        shut[5] = SQUEEZE
        return self.move_joints(i, [near, shut], [TIMES["close"], (near[5] - SQUEEZE) / CLOSE_SPEED])

    def run_to(self, t_end):
        if t_end > self.t_limit:
            raise TaskError(self.step, self.sim.time, f"the task would run past its time limit of {self.t_limit} s")
        # advance, not run: phases end hundreds of times per cycle, and a log of the whole run built at
        # each end would cost more than the steps
        if self.live is not None:
            # paced, with the page live (coopsim.view.live); the page's Reset raises view.live.Restart: the
            # task starts over (run)
            self.live.run_to(t_end, restart=True)
            self.check_contacts()
        else:      # one engine step, its contacts checked there
            self.scheduled(Step(self.step, t_end))

    def scheduled(self, step: Step) -> None:
        """Runs one engine schedule's `step` with the contacts checked against :meth:`contact_rules`; a
        forbidden contact or a wait that times out is the TaskError the Python checks raise."""
        try:
            res = self.sim.run_schedule([step], allowed_contacts=self.contact_rules(), contacts_seen=self.contact_seen)
        except ScheduleError as e:
            self.contact_seen = e.result.contacts_seen
            if e.kind == "contact":
                raise TaskError(e.step, e.t, f"forbidden contact between {e.bodies[0]} and {e.bodies[1]}",
                                e.bodies) from None
            raise TaskError(e.step, e.t, "") from None      # a wait's timeout: its caller says why
        self.contact_seen = res.contacts_seen

    def wait_for(self, condition: Holding, timeout, what):
        """Runs in 10 ms chunks until `condition` (robot i holds a bar, or nothing) holds, at most `timeout` s;
        TaskError with `what` if not. Headless, one engine schedule's wait step does the chunks' waiting and the
        contacts' checks; in a live page (or past the time limit) Python advances chunk by chunk."""
        t_end = self.sim.time + timeout
        if self.live is None and t_end <= self.t_limit:
            try:
                self.scheduled(Step(self.step, t_end, _WAIT_CHUNK, wait=[condition]))
            except TaskError as e:
                if e.reason:
                    raise
                raise TaskError(self.step, self.sim.time, what) from None
            return
        while self.sim.holding(condition.robot) != condition.body:
            if self.sim.time >= t_end - 1e-12:
                raise TaskError(self.step, self.sim.time, what)
            self.run_to(min(self.sim.time + _WAIT_CHUNK, t_end))

    def wait_grasp(self, i, name):
        """Runs until robot i holds `name` (GRASP_TIMEOUT s at most); else TaskError naming the clamp
        rule's conditions that failed at the end."""
        try:
            self.wait_for(Holding(i, name), GRASP_TIMEOUT, "")
        except TaskError as e:
            if e.reason:   # something else went wrong while waiting (a forbidden contact): that is the reason
                raise
            c = self.sim.grasp_check(i, name)
            failed = [k for k in ("closing", "aligned", "touching", "in_pads", "slow") if not getattr(c, k)]
            detail = (f"angle {c.angle / DEG:.1f} deg, gaps {c.gap_fixed * 1e3:.1f} and "
                      f"{c.gap_moving * 1e3:.1f} mm, speed {c.speed:.3f} m/s")
            raise TaskError(self.step, self.sim.time, f"SCARA #{i + 1} did not grasp {name}: the clamp rule's "
                            f"{', '.join(failed) or 'hold time'} failed ({detail})") from None

    # ---- contacts ----

    def allowed(self, a: str, b: str) -> bool:
        """Whether a contact between bodies a and b is allowed now."""
        for x, y in ((a, b), (b, a)):
            if x in self.state:
                st = self.state[x]
                if y in self.state:   # bar on bar: both already dropped
                    return st == "released" and self.state[y] == "released"
                if y.endswith("/fixed_jaw") or y.endswith("/link6"):
                    return True
                if y == "floor":
                    return st in ("floor", "grasped", "released")
                if y.startswith("container"):
                    return st == "released"
                return False
        return False

    def contact_rules(self) -> list:
        """:meth:`allowed` now, as the engine's schedule takes it: each bar with the jaws; with the floor on it,
        grasped or released; with the container and the other released bars once released."""
        key = tuple(self.state[x] for x in self.names)
        if self._rules is not None and self._rules[0] == key:
            return self._rules[1]
        rules = []
        released = [x for x in self.names if self.state[x] == "released"]
        for x in self.names:
            st = self.state[x]
            rules += [(x, "*/fixed_jaw"), (x, "*/link6")]
            if st in ("floor", "grasped", "released"):
                rules.append((x, "floor"))
            if st == "released":
                rules.append((x, "container*"))
                rules += [(x, y) for y in released if y > x]
        self._rules = (key, rules)
        return rules

    def check_contacts(self):
        ev = self.sim.contact_events(self.contact_seen)     # the events since the last look
        if not ev:
            return
        for a, b, begin in zip(ev["a"], ev["b"], ev["begin"].tolist()):
            if not self.allowed(a, b):
                raise TaskError(self.step, begin, f"forbidden contact between {a} and {b}", (a, b))
        self.contact_seen += len(ev["a"])

    # ---- one cycle ----

    def cycle(self, k):
        name, sim = self.names[k], self.sim
        steps: Dict[str, list] = {}

        def mark(step):
            self.step = step
            steps[step] = [sim.time, None]

        def done():
            steps[self.step][1] = sim.time

        T = TIMES
        # 1. #2 above the bar, down to it, closes: the clamp rule grasps
        mark("pick")
        bar0, G = self.pick_grip(sim.body_state(name).pose)
        self.label[name] = np.linalg.solve(sim.body_state(name).pose, bar0)
        grip = bar0 @ G
        above = grip.copy()
        above[2, 3] += CLEAR_ABOVE
        q_above = self._ik(1, above, OPEN, q_near=self.q_ref(1))
        t = self.move_joints(1, [q_above], [T["approach"]])
        self.run_to(t)
        self.run_to(self.move_line(1, [grip], [T["descend"]], OPEN))
        self.close(1)
        self.wait_grasp(1, name)
        self.state[name] = "grasped"   # still on the floor until lifted
        done()
        # 2. lift, carry under #1's open clamp
        mark("carry")
        G2 = np.linalg.solve(self.r2.fk(sim.state(1)[0]), self.bar(name))   # bar in #2's tool
        lifted = self.bar(name)
        lifted[2, 3] += CLEAR_ABOVE
        hand = self._handover_bar()
        pre = hand.copy()
        pre[:3, 3] += np.array([0.10, -0.10, 0.0])
        self.run_to(self.move_line(1, [lifted @ np.linalg.inv(G2)], [T["lift"]], SQUEEZE))
        self.state[name] = "held"
        q_pre = self._ik(1, pre @ np.linalg.inv(G2), SQUEEZE, q_near=self.q_ref(1))
        self.run_to(self.move_joints(1, [q_pre], [T["carry"]]))
        self.run_to(self.move_line(1, [hand @ np.linalg.inv(G2)], [T["enter"]], SQUEEZE))
        self.run_to(sim.time + T["settle"])
        done()
        # 3. #1 descends onto the bar as it is held and closes: both hold
        mark("grasp by #1")
        held = self.bar(name)
        g1 = held @ _grip_down(GRIP1, 0.0) @ _pose(rotz(self.grip1_turn), np.zeros(3))
        self.run_to(self.move_line(0, [g1], [T["descend"]], OPEN))
        self.close(0)
        self.wait_grasp(0, name)
        self.run_to(sim.time + T["settle"])
        done()
        # 4. #2 opens and leaves
        mark("release by #2")
        self.jaw(1, OPEN, T["open"])
        self.wait_for(Holding(1), GRASP_TIMEOUT, "SCARA #2 did not let go")
        up = self.r2.fk(self.q_ref(1))
        up[2, 3] += RETREAT2
        self.run_to(self.move_line(1, [up], [T["retreat"]], OPEN))
        nxt = self.names[k + 1] if k + 1 < len(self.names) else None
        home = self._above(*self.pick_grip(sim.body_state(nxt).pose if nxt else self.bars[0]))
        self.run_to(self.move_joints(1, [self._ik(1, home, OPEN, q_near=self.q_ref(1))], [T["home"]]))
        done()
        # 5. #1 turns the bar onto the container's axis, beside it, then slides onto it
        mark("to container")
        G1 = np.linalg.solve(self.r1.fk(sim.state(0)[0]), self.bar(name))
        a = self.axes[:, 0]
        R_axis = _yaw_pitch(math.atan2(a[1], a[0]), self.slope)
        lead = scene.BAR_HALF_EXTENTS[0]
        on_axis = _pose(R_axis, self.mouth - a * (lead + BEFORE_MOUTH))
        beside = on_axis.copy()
        beside[:3, 3] += np.array([BESIDE, 0.0, 0.0])
        lifted = self.bar(name)
        lifted[2, 3] += 0.06
        self.run_to(self.move_line(0, [lifted @ np.linalg.inv(G1)], [T["lift"]], SQUEEZE))
        q_beside = self._ik(0, beside @ np.linalg.inv(G1), SQUEEZE, q_near=self.q_ref(0), branch=INSERT_BRANCH)
        self.run_to(self.move_joints(0, [q_beside], [T["to_container"]]))
        self.run_to(self.move_line(0, [on_axis @ np.linalg.inv(G1)], [T["slide_on"]], SQUEEZE, branch=INSERT_BRANCH))
        done()
        # 6. insert along the axis
        mark("insert")
        inside = on_axis.copy()
        inside[:3, 3] += a * (BEFORE_MOUTH + INSERT_DEPTH)
        self.run_to(self.move_line(0, [inside @ np.linalg.inv(G1)], [T["insert"]], SQUEEZE, intermediate=8,
                                   branch=INSERT_BRANCH))
        done()
        # 7. open, back off along the approach, return
        mark("release")
        self.jaw(0, OPEN, T["open"])
        self.wait_for(Holding(0), GRASP_TIMEOUT, "SCARA #1 did not let go")
        self.state[name] = "released"
        T1 = self.r1.fk(self.q_ref(0))
        T1[:3, 3] -= T1[:3, 2] * BACK_OFF
        self.run_to(self.move_line(0, [T1], [T["back_off"]], OPEN, branch=INSERT_BRANCH))
        done()
        mark("return")
        t_release = sim.time
        self.run_to(self.move_joints(0, [self.q1_wait], [T["home"]]))
        done()
        self.step = "slide"
        self.check_slide(name, steps["release"][0])
        return steps

    def check_slide(self, name, t_release):
        """The bar, since its release (once the weld has faded out), slid down the tube: its centre within the tube's section while in it,
        never moving back up the axis faster than SLIDE_BACK m/s, at least SLIDE_MIN m further down, and
        now inside the tube or out of its lower mouth."""
        b = self.sim.body_log(name)
        k = b.t >= t_release + RELEASE_FADE
        rel = b.position[k] - self.mouth
        a = self.axes[:, 0]
        s = rel @ a
        lateral = np.linalg.norm(rel - s[:, None] * a, axis=1)
        v = b.velocity[k] @ a
        L = scene.CONTAINER["length"]
        inside = (s >= 0.0) & (s <= L)
        t = b.t[k]
        if np.any(lateral[inside] > scene.CONTAINER["inner"] / 2):
            j = int(np.argmax(inside & (lateral > scene.CONTAINER["inner"] / 2)))
            raise TaskError("slide", float(t[j]), f"{name} left the tube's section: its centre {lateral[j] * 1e3:.1f} mm "
                            f"off the axis")
        if np.any(v[inside] < -SLIDE_BACK):
            j = int(np.argmax(inside & (v < -SLIDE_BACK)))
            raise TaskError("slide", float(t[j]), f"{name} moved back up the tube at {-v[j]:.3f} m/s")
        if s[-1] - s[0] < SLIDE_MIN:
            raise TaskError("slide", float(t[-1]), f"{name} did not slide down the tube: it moved "
                            f"{(s[-1] - s[0]) * 1e3:.1f} mm along the axis")
        if s[-1] < 0.0:
            raise TaskError("slide", float(t[-1]), f"{name} ended above the tube's upper mouth")
        self.outcome[name] = "inside the container" if s[-1] <= L else "out of the lower mouth"



def run(bars=None, *, cycles: Optional[int] = None, seed: Optional[int] = None, dt: float = 2e-4,
        log_every: int = 25, world_every: int = 5, control_every: int = 5, mouth=None, slope=None,
        handover_yaw=None, t_limit: float = 120.0, score: bool = True, container_shift=None,
        grip1_turn: float = 0.0, live=None, on_interrupt: str = "raise") -> TaskResult:
    """Runs the task and scores it.

    bars: list of (4, 4) start poses of the bars on the floor (default: :func:`default_bars` of
    `cycles`, 3), or None with `seed`: one bar drawn from :data:`REGION`. cycles: how many bars to
    move (default: all). dt (s), log_every, world_every, control_every: the simulation's (by default
    the robots are integrated at 5 kHz, the paper's 0.2 ms, and the controllers, with their torques held
    in between, and the world with its contacts run at 1 kHz, a servo rate; with the controllers at
    every step the scores agree to 0.01 mm, see benchmarks/bench_task.py). mouth (3,) m, slope (rad): the
    container (default scene.CONTAINER). handover_yaw (rad): the bar's yaw at the handover. t_limit:
    simulated seconds after which a cycle fails. score: compute the per-cycle scores (clearances,
    tracking errors, forces, events; a little slower than the run itself).

    Faults, to see failures reported: container_shift (3,) m moves the container in the world by that
    much while the plan still aims at the container where it should be; grip1_turn (rad) turns SCARA
    #1's clamp about its approach when it comes down on the bar at the handover.

    live: run in a live page (:func:`coopsim.view.live`, paced, 100 % by default): True, or a dict of
    its options (speed, port, host, paused=True to wait at t = 0 for the page's Start, ...); the view is
    ``result.live`` (close it, or :meth:`~coopsim.view.LiveView.hold` it to keep serving the page). The
    page's Reset starts the task over; after the run the page shows the summary (or the failed cycle's step,
    time and reason) and its Reset runs the task again in the page (:meth:`~coopsim.view.LiveView.serve`).

    on_interrupt: 'raise' (Ctrl-C propagates as KeyboardInterrupt) or 'report': Ctrl-C ends the run where it
    is and the result's report says so (``report["interrupted"]``, the cycle cut short with the step and
    time), its log kept up to there.

    The report records every input that changes the run: the seed (None when the bars were given or
    defaulted), the bars' poses and the keywords above.

    Returns a :class:`TaskResult`. Raises ValueError for cycles outside 1 .. MAX_CYCLES (3: the container
    takes three bars, see :data:`~coopsim.tasks.handover.constants.MAX_CYCLES`), a seed with bars or with
    more than one cycle; coopsim.IKError, naming the bar and what is out of reach,
    when a bar cannot be picked where it lies (checked before the run starts).
    """
    if seed is not None and bars is not None:
        raise ValueError("give bars or seed, not both: seed draws the one bar")
    if seed is not None and cycles not in (None, 1):
        raise ValueError(f"seed draws one bar, so one cycle: cycles must be 1 (or None) with a seed, got {cycles}")
    if cycles is not None and bars is None and not 0 < int(cycles) <= MAX_CYCLES:
        raise ValueError(f"cycles must be 1 .. {MAX_CYCLES} (the container takes {MAX_CYCLES} bars: the ones that "
                         f"slid out pile up at its lower mouth, the next stays in the tube), got {cycles}")
    if bars is None:
        bars = [random_bar(seed)] if seed is not None else default_bars(3 if cycles is None else cycles)
    cycles = len(bars) if cycles is None else int(cycles)
    if not 0 < cycles <= len(bars):
        raise ValueError(f"cycles must be 1 .. {len(bars)} (one per bar), got {cycles}")
    if cycles > MAX_CYCLES:
        raise ValueError(f"cycles must be 1 .. {MAX_CYCLES} (the container takes {MAX_CYCLES} bars: the ones that "
                         f"slid out pile up at its lower mouth, the next stays in the tube), got {cycles}")
    if on_interrupt not in ("raise", "report"):
        raise ValueError(f"on_interrupt must be 'raise' or 'report', got {on_interrupt!r}")
    runner = _Runner(bars, dt=dt, log_every=log_every, world_every=world_every, control_every=control_every,
                     mouth=mouth, slope=slope, handover_yaw=handover_yaw, t_limit=t_limit,
                     container_shift=container_shift, grip1_turn=grip1_turn)
    inputs = dict(seed=seed, dt=dt, log_every=log_every, world_every=world_every, control_every=control_every,
                  t_limit=t_limit, container_shift=container_shift, grip1_turn=grip1_turn)

    def once() -> TaskResult:
        return _run_cycles(runner, cycles, score, on_interrupt, inputs)

    if not live:
        return once()
    options = dict(speed=1.0, title="coopsim: the cooperative bar handover")
    options.update(live if isinstance(live, dict) else {})
    runner.live = view.live(runner.sim, start=False, resettable=True, **options)
    while True:
        try:
            result = once()
            break
        except Restart:      # the page's Reset: the task starts over, in the page
            runner.restart()

    def rerun() -> None:              # the page's Reset after the run: the task again (LiveView.serve)
        runner.restart()
        again = once().report
        _show_outcome(runner.live, again)
        if again.get("interrupted"):      # Ctrl-C during it ends the session, as during the first run
            raise KeyboardInterrupt

    _show_outcome(runner.live, result.report)
    runner.live.rerun = rerun
    return result


def _show_outcome(v, report: dict) -> None:
    """The task's summary in its live page: finished, or failed with the cycle's step, time and reason."""
    ok = report["success"]
    v.finish(summary(report), ok=ok)
    if not ok:
        bad = next(c for c in report["cycles"] if not c["success"])
        v.say(f"Cycle {bad['cycle']} ({bad['bar']}) failed in {bad['failed_step']} at t = {bad['failed_at']:.3f} s: "
               f"{bad['reason']}")


def _run_cycles(runner: _Runner, cycles: int, score: bool, on_interrupt: str, inputs: dict) -> TaskResult:
    """The task's cycles on the runner's simulation from where it stands, scored; the TaskResult."""
    results = []
    interrupted = False
    t_wall = time.perf_counter()
    for k in range(cycles):
        t0 = runner.sim.time
        c = dict(cycle=k, bar=runner.names[k], success=True, t_start=t0)
        results.append(c)
        try:
            c["steps"] = runner.cycle(k)
            c["t_end"] = runner.sim.time
        except TaskError as e:
            c.update(success=False, t_end=runner.sim.time, failed_step=e.step, failed_at=e.t, reason=e.reason,
                     bodies=list(e.bodies))
            break
        except (IKError, DivergenceError) as e:
            c.update(success=False, t_end=runner.sim.time, failed_step=runner.step, failed_at=runner.sim.time,
                     reason=f"{type(e).__name__}: {e}", bodies=[])
            break
        except KeyboardInterrupt:
            if on_interrupt != "report":
                raise
            interrupted = True
            c.update(success=False, t_end=runner.sim.time, failed_step=runner.step, failed_at=runner.sim.time,
                     reason="interrupted (Ctrl-C)", bodies=[])
            break
    t_run = time.perf_counter() - t_wall
    series = score_cycles(runner, results) if score and not interrupted else None
    timing = dict(run=t_run, scoring=time.perf_counter() - t_wall - t_run)
    shift = inputs["container_shift"]
    report = dict(success=len(results) == cycles and all(c["success"] for c in results), cycles_planned=cycles,
                  cycles=results, bars=[np.round(b, 12).tolist() for b in runner.bars[:cycles]],
                  simulated_time=runner.sim.time, seed=inputs["seed"], dt=inputs["dt"], log_every=inputs["log_every"],
                  world_every=inputs["world_every"], control_every=inputs["control_every"],
                  t_limit=inputs["t_limit"], mouth=runner.mouth.tolist(), slope=runner.slope,
                  handover_yaw=runner.handover_yaw,
                  container_shift=None if shift is None else np.asarray(shift, float).tolist(),
                  grip1_turn=float(inputs["grip1_turn"]))
    if interrupted:
        report["interrupted"] = True
    return TaskResult(report, runner.sim, runner.sim.log, series, timing, runner.live)
