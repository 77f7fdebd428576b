"""The carry on a simulation: the plan's references installed once, the run advanced step by step with the
rules that fail it, and :func:`run`, which returns the scored :class:`CarryResult`."""
from __future__ import annotations

import dataclasses
import time
from typing import Dict, List, Optional, Sequence

import numpy as np

from ..._core import CooperativeController, DivergenceError, IKError, LinkBox, shape_clearances
from ...schedule import AddCooperative, Holding, RemoveCooperative, ScheduleError, SetBodyWrench, SetController, SetReference, Step
from ...simulation import Simulation
from . import scene
from .constants import BACKED_OFF, END, PLACE_TOL, PLACE_TOL_ANGLE, START
from .controllers import CONTROLLERS, Cooperative, Phased, check_options, computed_torque, controller_factory, grip_point
from .disturbances import Disturbances, disturbances
from .pairs import pair as make_pair
from .planning import STEPS, Plan, _pose4, make_plan, random_start
from .scoring import score

__all__ = ["CarryError", "CarryResult", "SEQUENCING", "run"]

SEQUENCING = ("engine", "python")   # run's ways of running the sequence

JAWS = ("/fixed_jaw", "/link6")   # the SCARAs' jaws' boxes in the world (a pair's: "/" + Pair.jaws)
CHUNK = 0.001          # s: while a grasp or release is awaited, and while the bar is held, the run goes in chunks
HELD_CHUNK = 0.05      # of these, checking the grasps between them


class CarryError(RuntimeError):
    """A carry failed: `step` (one of :data:`~.planning.STEPS`), `t` (s), `reason`, and the bodies involved."""

    def __init__(self, step: str, t: float, reason: str, bodies: Sequence[str] = ()):
        super().__init__(f"{step} at t = {t:.4f} s: {reason}")
        self.step, self.t, self.reason, self.bodies = step, float(t), reason, tuple(bodies)


@dataclasses.dataclass
class CarryResult:
    """What :func:`run` returns: the report (plain values, JSON-ready), the simulation, its log, the plan, the
    series behind the figures (None unless scored) and the wall times (kept out of the report)."""

    report: dict
    sim: Simulation
    log: object
    plan: Plan
    series: Optional[dict] = None
    timing: Optional[dict] = None

    @property
    def success(self) -> bool:
        return bool(self.report["success"])


class _Runner:
    """One carry on one simulation."""

    def __init__(self, plan: Plan, start, dist: Disturbances, factory, *, dt, log_every, world_every,
                 control_every):
        self.plan, self.dist = plan, dist
        self.robots = plan.robots
        self.names = plan.pair.names
        self.jaws = tuple("/" + j for j in plan.pair.jaws)
        self.sim = Simulation(dt=dt, world=scene.world(start, plan.end), log_every=log_every,
                              world_every=world_every, control_every=control_every)
        made = factory(self.robots, plan)
        self.phased = made if isinstance(made, Phased) else None
        self.coop = made if isinstance(made, Cooperative) else None
        free = made.free if isinstance(made, (Phased, Cooperative)) else made
        if len(free) != 2 or (self.phased and len(self.phased.held) != 2):
            raise ValueError(f"controllers must give one controller per robot (2), got {made!r}")
        if self.coop is not None and not isinstance(self.coop.law, CooperativeController):
            raise ValueError(f"a Cooperative's law must be a coopsim.CooperativeController, got {self.coop.law!r}")
        self.group: Optional[int] = None
        self.commanded = commanded_sharing(self.coop, plan)
        for r, c, ref in zip(self.robots, free, plan.references):
            self.sim.add_robot(r, c, ref)
        if dist.sensor_noise is not None:
            for i in range(2):
                self.sim.set_sensor(i, noise_force=dist.sensor_noise[0], noise_moment=dist.sensor_noise[1], seed=i + 1)
        self.step = "approach"
        self.steps: Dict[str, List[float]] = {}
        self.contact_seen = 0
        self.anchors: List[Optional[dict]] = [None, None]   # each weld's point in the clamp's link and in the bar
        self.unexpected: List[dict] = []

    # ---- running ----

    def mark(self, step):
        self.step = step
        self.steps[step] = [self.sim.time, None]

    def done(self):
        self.steps[self.step][1] = self.sim.time

    def run_to(self, t_end, chunk=None, held=False):
        """Advances to t_end (in chunks of `chunk` s), checking contacts and, with `held`, that both clamps
        still hold the bar after each chunk. The engine does the chunks' waiting (Simulation.advance_until):
        it stops after a chunk in which a contact began or, with `held`, a clamp let go (a grasp event), the
        only chunks whose checks can find anything, so the checks see what they would see after every chunk."""
        until = ("grasp", "contact") if held else "contact"
        while self.sim.time < t_end - 1e-12:
            try:
                if chunk is None:
                    self.sim.advance(t_end)
                else:
                    self.sim.advance_until(t_end, until, every=chunk)
            except ValueError:
                # a cooperative law refuses robots that no longer hold one body: a clamp let go
                if self.group is not None and any(self.sim.holding(i) != scene.BAR for i in range(2)):
                    self.check_held()
                raise
            if held:   # first: a clamp that let go explains what the bar then hits
                self.check_held()
            self.check_contacts()

    def check_held(self):
        for i in range(2):
            if self.sim.holding(i) != scene.BAR:
                # the engine's grasp events (no log tables built): robot i's last release, if any
                g = self.sim.grasp_events()
                last = [k for k in range(len(g["t"])) if g["robot"][k] == i and g["event"][k] == "release"]
                why = f" ({g['reason'][last[-1]]} at t = {float(g['t'][last[-1]]):.4f} s)" if last else ""
                raise CarryError(self.step, self.sim.time, f"{self.names[i]} let go of the bar{why}")

    def record_anchor(self, i, t=None, q=None, bar=None):
        """The weld's point (midway between the pads now, just after the grasp; or at time t with robot i's
        joints q and the bar's pose `bar` then) in the clamp's link frame and in the bar's frame: the slip (the
        weld's stretch) is their distance later."""
        if t is None:
            t, q, bar = self.sim.time, self.sim.state(i)[0], self.sim.body_state(scene.BAR).pose
        r = self.robots[i]
        F = r.frames(q)[r.clamp.fixed_link]
        p_link = grip_point(r, q, F)
        p_world = (F @ np.append(p_link, 1.0))[:3]
        self.anchors[i] = dict(t=t, link=p_link, body=np.linalg.solve(bar, np.append(p_world, 1.0))[:3])

    def wait_grasps(self, t_end):
        """Runs to t_end in CHUNK steps, recording each weld's anchor when it appears; CarryError('grasp') if
        either clamp does not hold the bar at t_end, naming the clamp rule's conditions that failed."""
        while self.sim.time < t_end - 1e-12:
            self.sim.advance_until(t_end, ("grasp", "contact"), every=CHUNK)
            self.check_contacts()
            for i in range(2):
                if self.anchors[i] is None and self.sim.holding(i) == scene.BAR:
                    self.record_anchor(i)
        self.check_grasped()

    def check_grasped(self):
        """CarryError('grasp') unless both clamps hold the bar, naming the clamp rule's conditions that failed."""
        for i in range(2):
            if self.sim.holding(i) != scene.BAR:
                c = self.sim.grasp_check(i, scene.BAR)
                failed = [k for k in ("closing", "aligned", "touching", "in_pads", "slow") if not getattr(c, k)]
                detail = (f"angle {np.degrees(c.angle):.1f} deg, gaps {c.gap_fixed * 1e3:.1f} and "
                          f"{c.gap_moving * 1e3:.1f} mm, speed {c.speed:.3f} m/s")
                raise CarryError("grasp", self.sim.time, f"{self.names[i]} did not grasp the bar: the clamp rule's "
                                 f"{', '.join(failed) or 'hold time'} failed ({detail})")

    # ---- contacts ----

    def allowed(self, a: str, b: str, begin: float) -> bool:
        """Whether a contact between bodies a and b beginning at `begin` is expected: the bar with the jaws, with
        the start stands until it is lifted off them, with the end stands from when it comes down onto them."""
        if scene.BAR not in (a, b):
            return False          # robot-robot, robot-scenery, a robot's own links
        other = b if a == scene.BAR else a
        if other.endswith(self.jaws):
            return True
        if other.startswith("start_stand"):
            return begin <= self.plan.steps["lift"][1]
        if other.startswith("end_stand"):
            return begin >= self.plan.steps["place"][0]
        return False              # the floor, a robot's other links

    def check_contacts(self):
        ev = self.sim.contact_events(self.contact_seen)     # the events since the last look
        if not ev:
            return
        for a, b, begin in zip(ev["a"], ev["b"], ev["begin"].tolist()):
            if not self.allowed(a, b, begin):
                raise CarryError(self.step, begin, f"unexpected contact between {a} and {b}", (a, b))
        self.contact_seen += len(ev["a"])

    # ---- the carry ----

    def carry(self):
        plan, sim, S = self.plan, self.sim, self.plan.steps
        self.mark("approach")
        self.run_to(S["approach"][1])
        self.done()
        self.mark("grasp")
        self.wait_grasps(S["grasp"][1])
        if self.phased:
            for i, c in enumerate(self.phased.held):
                sim.set_controller(i, c)
        if self.coop:
            self.group = sim.add_cooperative(self.coop.law, [0, 1])
        self.done()
        self.mark("lift")
        self.run_to(S["lift"][1], HELD_CHUNK, held=True)
        self.done()
        self.mark("carry")
        t0, t1 = S["carry"]
        if self.dist.push is not None:
            force, at, T = self.dist.push
            mid = t0 + at * (t1 - t0)
            self.run_to(mid - T / 2, HELD_CHUNK, held=True)
            sim.set_body_wrench(scene.BAR, np.r_[force, 0.0, 0.0, 0.0])
            self.run_to(mid + T / 2, HELD_CHUNK, held=True)
            sim.set_body_wrench(scene.BAR, np.zeros(6))
        self.run_to(t1, HELD_CHUNK, held=True)
        self.done()
        self.mark("place")
        self.run_to(S["place"][1], HELD_CHUNK, held=True)
        self.done()
        self.mark("release")
        if self.group is not None:     # the bar rests on the end stands: the free controllers open the jaws
            sim.remove_cooperative(self.group)
            self.group = None
            for i, ref in enumerate(self.plan.references):
                sim.set_reference(i, ref)
        self.run_to(S["release"][1], CHUNK)
        for i in range(2):
            if sim.holding(i) is not None:
                raise CarryError("release", sim.time, f"{self.names[i]} did not let go of the bar")
        if self.phased:
            for i, c in enumerate(self.phased.free):
                sim.set_controller(i, c)
        self.done()
        self.mark("back off")
        self.run_to(S["back off"][1])
        self.done()
        self.check_placed()
        self.check_backed_off()

    def contact_rules(self) -> list:
        """:meth:`allowed` as the engine's schedule takes it: the bar with the jaws at any time, with the start
        stands until the lift's end, with the end stands from the place's start."""
        S = self.plan.steps
        return ([(scene.BAR, "*" + j) for j in self.jaws] +
                [(scene.BAR, "start_stand*", None, float(S["lift"][1])),
                 (scene.BAR, "end_stand*", float(S["place"][0]), None)])

    def scheduled(self, steps) -> None:
        """Runs `steps` (coopsim.schedule.Step, the carry's step names) in one engine call, with the checks
        :meth:`run_to` and :meth:`wait_grasps` make between pieces; the runner follows (its steps' times, the
        anchors, the cooperative group, the contacts seen, the step now). A failure is the CarryError the
        Python checks raise, with the same reason; an engine error propagates with the runner's step set."""
        try:
            res = self.sim.run_schedule(steps, allowed_contacts=self.contact_rules(), contacts_seen=self.contact_seen)
        except ScheduleError as e:
            self._follow(steps, e.result)
            if e.kind == "hold":
                self.check_held()              # the release's reason, as the Python check gives it
            elif e.kind == "at_end" and e.step == "grasp":
                self.check_grasped()           # the clamp rule's conditions that failed
            elif e.kind == "at_end" and e.step == "release":
                raise CarryError("release", e.t, f"{self.names[steps[e.index].at_end[e.condition].robot]} did "
                                 f"not let go of the bar") from None
            raise CarryError(e.step, e.t, e.reason, e.bodies) from None
        except Exception as e:
            if getattr(e, "schedule_result", None) is not None:
                self._follow(steps, e.schedule_result)
            raise
        self._follow(steps, res)

    def _follow(self, steps, res) -> None:
        """The runner after a schedule's result `res` (coopsim.schedule.ScheduleResult) of `steps`: its steps'
        times, the step now, the welds' anchors from the records, the cooperative group, the contacts seen."""
        for k, (t0, t1) in enumerate(res.times):
            name = steps[k].name
            if name != self.step or name not in self.steps:
                self.steps[name] = [t0, t1]
            else:
                self.steps[name][1] = t1
            self.step = name
        for rec in res.records:
            i = steps[rec.step].record[rec.condition].robot
            self.record_anchor(i, rec.t, rec.q, rec.pose)
        # the pair's cooperative group, as the simulation keeps it after the schedule's adds and removes
        self.group = next((g["group"] for g in self.sim.cooperatives if g["robots"] == [0, 1]), None)
        self.contact_seen = res.contacts_seen

    def carry_scheduled(self):
        """The carry of :meth:`carry` as one engine schedule: the same steps, actions and checks."""
        S = self.plan.steps
        held = [Holding(0, scene.BAR), Holding(1, scene.BAR)]
        lift = []
        if self.phased:
            lift += [SetController(i, c) for i, c in enumerate(self.phased.held)]
        if self.coop:
            lift.append(AddCooperative(self.coop.law, [0, 1]))
        steps = [Step("approach", S["approach"][1]),
                 Step("grasp", S["grasp"][1], CHUNK, record=held, at_end=held),
                 Step("lift", S["lift"][1], HELD_CHUNK, lift, hold=held)]
        t0, t1 = S["carry"]
        if self.dist.push is not None:
            force, at, T = self.dist.push
            mid = t0 + at * (t1 - t0)
            steps += [Step("carry", mid - T / 2, HELD_CHUNK, hold=held),
                      Step("carry", mid + T / 2, HELD_CHUNK, [SetBodyWrench(scene.BAR, np.r_[force, 0.0, 0.0, 0.0])],
                           hold=held),
                      Step("carry", t1, HELD_CHUNK, [SetBodyWrench(scene.BAR, np.zeros(6))], hold=held)]
        else:
            steps.append(Step("carry", t1, HELD_CHUNK, hold=held))
        steps.append(Step("place", S["place"][1], HELD_CHUNK, hold=held))
        release = []
        if self.coop:     # the bar rests on the end stands: the free controllers open the jaws
            release = [RemoveCooperative()] + [SetReference(i, ref) for i, ref in enumerate(self.plan.references)]
        steps.append(Step("release", S["release"][1], CHUNK, release, at_end=[Holding(0), Holding(1)]))
        back = [SetController(i, c) for i, c in enumerate(self.phased.free)] if self.phased else []
        steps.append(Step("back off", S["back off"][1], 0.0, back))
        self.step = "approach"
        self.scheduled(steps)
        self.check_placed()
        self.check_backed_off()

    def check_placed(self):
        """The bar at rest on the end stands within PLACE_TOL and PLACE_TOL_ANGLE of its planned pose."""
        b = self.sim.body_state(scene.BAR)
        want = self.plan.bar.pose(self.plan.t_end)
        d = float(np.linalg.norm(b.pose[:3, 3] - want[:3, 3]))
        ang = _angle(want[:3, :3].T @ b.pose[:3, :3])
        speed = float(np.linalg.norm(b.velocity))
        self.placed = dict(position_error=d, angle_error=ang, speed=speed)
        if d > PLACE_TOL or ang > PLACE_TOL_ANGLE or speed > 1e-3:
            raise CarryError("place", self.sim.time, f"the bar came to {d * 1e3:.1f} mm and {ang * 1e3:.1f} mrad from "
                             f"its planned pose on the end stands, moving at {speed * 1e3:.2f} mm/s (allowed "
                             f"{PLACE_TOL * 1e3:.0f} mm, {PLACE_TOL_ANGLE * 1e3:.0f} mrad, at rest)")

    def check_backed_off(self):
        """Every collision shape of both robots at least BACKED_OFF m from the bar."""
        from_bar = []
        bar = self.sim.body_state(scene.BAR).pose[None]
        bar_shape = [LinkBox(0, scene.BAR_HALF_EXTENTS, np.eye(4), scene.BAR)]
        for i, r in enumerate(self.robots):
            P, _ = r.shapes(self.sim.state(i)[0])
            from_bar.append(float(shape_clearances(P[None], list(r.boxes), bar, bar_shape)[0][0]))
        self.backed_off = from_bar
        for i, d in enumerate(from_bar):
            if d < BACKED_OFF:
                raise CarryError("back off", self.sim.time, f"{self.names[i]} ended {d * 1e3:.1f} mm from the bar "
                                 f"(at least {BACKED_OFF * 1e3:.0f} mm expected)")


def commanded_sharing(coop: Optional[Cooperative], plan: Plan) -> dict:
    """What the controllers command of the bar's sharing while both hold it (the protocol of docs/carry.md,
    "What a cooperative law commands"): dict(load_share=(2,) SCARA #1's and #2's parts of the vertical load,
    squeeze N (compression positive), source). Each of load_share and squeeze is the
    :class:`~.controllers.Cooperative`'s when it declares one, else the law's attribute of that name when it has
    one (:class:`coopsim.ObjectControl`; a Python law's attribute or property), else not commanded: the share
    the lever rule gives two pins at the planned grips (each carries the other's distance from the centre over
    their distance), no squeeze. source: 'controller' when the controllers command either, else 'lever rule'.
    ValueError naming what is wrong for a declared share outside [0, 1] or a value that is not a finite number."""
    law = coop.law if coop is not None else None

    def declared(name):
        v = getattr(coop, name, None)
        if v is None and law is not None:
            v = getattr(law, name, None)
        if v is None:
            return None
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"the cooperative law's {name} must be a number, got {v!r}") from None
        if not np.isfinite(v) or (name == "load_share" and not 0.0 <= v <= 1.0):
            raise ValueError(f"the cooperative law's {name} must be {'in [0, 1]' if name == 'load_share' else 'finite'}"
                             f", got {v!r}")
        return v

    share, squeeze = (declared("load_share"), declared("squeeze")) if coop is not None else (None, None)
    if share is None:
        s = [float(G[0, 3]) for G in plan.grips]     # the grips' positions along the bar from its centre (m)
        share_used = abs(s[1]) / (abs(s[0]) + abs(s[1]))
    else:
        share_used = share
    source = "controller" if share is not None or squeeze is not None else "lever rule"
    return dict(load_share=[share_used, 1.0 - share_used], squeeze=0.0 if squeeze is None else squeeze, source=source)


def _plain(x):
    """Tuples as lists, numpy scalars as floats, all the way down: the report holds JSON's values."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in x]
    return x.item() if isinstance(x, np.generic) else x


def _angle(R) -> float:
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


def _factory(controllers, name, options):
    """(the factory, its name in the report) of run's `controllers` (a name of CONTROLLERS, 'module:factory' or
    a factory) with `options` (keywords for the factory, or None)."""
    if isinstance(controllers, str):
        name, controllers = name or controllers, controller_factory(controllers)
    if not callable(controllers):
        raise ValueError(f"controllers must be a name ({', '.join(CONTROLLERS)}) or a factory (robots, plan) -> "
                         f"controllers, got {controllers!r}")
    if name is None:
        inner = getattr(controllers, "func", controllers)       # a functools.partial: its function's name
        name = getattr(inner, "__name__", type(controllers).__name__)
    if options is None:
        return controllers, name
    if not isinstance(options, dict) or not all(isinstance(k, str) for k in options):
        raise ValueError(f"controller_options must be a dict of keywords for the controllers' factory, got {options!r}")
    check_options(controllers, options, f"controller {name!r}")
    return (lambda robots, plan: controllers(robots, plan, **options)), name


def check_controllers(controllers, options: Optional[dict] = None, robots=None) -> None:
    """Makes the controllers of `controllers` (as :func:`run` takes it) with `options` for the planned carry,
    and drops them: the ValueError (one line) :func:`run` would raise for an unknown controller, a factory that
    does not load, an option the factory does not take or a value it refuses, without running anything (the
    command line checks its arguments so; about 10 ms for the SCARAs). robots: the pair (as run takes it)."""
    factory, _ = _factory(controllers, None, options)
    plan = make_plan(START, END, robots=robots)
    try:
        made = factory(plan.robots, plan)
    except TypeError as e:        # a factory of one's own called with keywords it does not take
        raise ValueError(f"controller {controllers!r}: {e}") from None
    if made is None:
        raise ValueError(f"controller {controllers!r}: its factory returned None, not the robots' controllers")


def run(*, seed: Optional[int] = None, start=None, end=None, disturbance=None, controllers=computed_torque,
        controller_name: Optional[str] = None, controller_options: Optional[dict] = None, mass_factor: Optional[float] = None, jaws_close=(True, True),
        robots=None, dt: Optional[float] = None, log_every: Optional[int] = None, world_every: Optional[int] = None,
        control_every: Optional[int] = None, score_run: bool = True, sequencing: str = "engine") -> CarryResult:
    """Runs the dual carry and scores it.

    seed: the start stands shifted and turned by a seeded draw (:func:`~.planning.random_start`; None: the
    planned START). start, end: the bar's (x, y, z, yaw) on the start and end stands (m, rad; default START
    and END; start and seed exclude each other). disturbance: None, a name of
    :data:`~.disturbances.DISTURBANCES`, several (a list, or names joined by commas) or a
    :class:`~.disturbances.Disturbances`. controllers: a name of :data:`~.controllers.CONTROLLERS` ('ct',
    'ct-payload', 'object', 'leader-follower', 'object-impedance'), a factory of one's own named 'module:factory' or
    'path/to/file.py:factory' (:func:`~.controllers.controller_factory`), or a factory (robots, plan) -> one controller
    per robot, :class:`~.controllers.Phased` or :class:`~.controllers.Cooperative` ones (default the baseline,
    :func:`~.controllers.computed_torque`); controller_options: keywords for the factory (e.g. ``squeeze``,
    ``load_share`` and gains for 'object', ``stiffness`` for 'leader-follower' and 'object-impedance');
    controller_name: its name in the report (default the name given, or the factory's __name__). mass_factor:
    the bar's mass in the controllers' models over the world's (> 0), instead of a 'mass' disturbance's.
    jaws_close: (2,) flags, False: that clamp's jaw is never commanded to close (a forced failure). robots: the
    pair of arms (:func:`~.pairs.pair`): 'scara' (default: the handover's two SCARAs), 'ur5' (two UR5s of
    example-robot-data with clamps, facing each other), 'panda' (two 7-dof Pandas), a
    :class:`~.pairs.Pair`, or a factory ``() -> ((robot #1, robot #2), ((position, yaw), (position, yaw)))`` of
    two clamped robots and their bases. dt (s), log_every, world_every, control_every: the simulation's (None:
    the pair's, Pair.simulation; the SCARAs' robots integrated at 5 kHz, the controllers and the world at 1 kHz;
    the UR5s' and Pandas' robots, controllers and world all at 1 kHz; a log row every 5 ms). score_run: compute
    the scores (:func:`~.scoring.score`). sequencing: 'engine' (default: the steps, their actions, waits and
    checks run as one engine schedule with the GIL released, :meth:`coopsim.Simulation.run_schedule`) or
    'python' (the same sequence advanced piece by piece from Python, checking between pieces: the same run and
    report, the GIL held between the pieces).

    A run fails, naming its step (approach, grasp, lift, carry, place, release, back off), time and reason, on
    an unexpected contact (robot-robot, a robot with a stand or the floor or its own links, the bar with
    anything but the jaws, the start stands before it is lifted and the end stands once it comes down), a
    grasp that does not happen by the end of the grasp step, a clamp letting go while carrying (its weld
    stretched beyond 5 mm), a release that does not happen, the bar not at rest on the end stands within
    PLACE_TOL and PLACE_TOL_ANGLE of its planned pose, or a robot left within BACKED_OFF of the bar.

    Returns a :class:`CarryResult`. Raises ValueError for bad arguments and IKError (naming the robot and the
    step) for a plan out of reach, both before anything runs.
    """
    if seed is not None and start is not None:
        raise ValueError("give start or seed, not both: seed draws the start")
    if sequencing not in SEQUENCING:
        raise ValueError(f"sequencing must be one of {', '.join(map(repr, SEQUENCING))}, got {sequencing!r}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    start = random_start(int(seed)) if seed is not None else (START if start is None else start)
    end = END if end is None else end
    factory, name = _factory(controllers, controller_name, controller_options)
    pair = make_pair(robots)
    rates = dict(pair.simulation)
    dt = float(rates.get("dt", 2e-4)) if dt is None else dt
    world_every = int(rates.get("world_every", 5)) if world_every is None else world_every
    control_every = int(rates.get("control_every", 5)) if control_every is None else control_every
    if log_every is None:
        log_every = max(1, int(round(5e-3 / dt))) if isinstance(dt, (int, float)) and dt > 0 else 25
    start, end = _pose4(start, "start"), _pose4(end, "end")
    dist = disturbances(disturbance, start[3])        # the push is across the bar: its direction needs the yaw
    if mass_factor is not None:
        if dist.mass_factor != 1.0:
            raise ValueError(f"mass_factor {mass_factor!r} and the disturbance's mass factor {dist.mass_factor} both "
                             f"given: give one of them")
        dist = dataclasses.replace(dist, mass_factor=mass_factor)
    plan = make_plan(start, end, robots=pair, grip_offsets=dist.grip_offset, close=tuple(jaws_close),
                     mass_factor=dist.mass_factor)
    runner = _Runner(plan, plan.start, dist, factory, dt=dt, log_every=log_every, world_every=world_every,
                     control_every=control_every)
    failure = None
    t_wall = time.perf_counter()
    try:
        runner.carry() if sequencing == "python" else runner.carry_scheduled()
    except CarryError as e:
        failure = dict(step=e.step, t=e.t, reason=e.reason, bodies=list(e.bodies))
    except (IKError, DivergenceError) as e:
        failure = dict(step=runner.step, t=runner.sim.time, reason=f"{type(e).__name__}: {e}", bodies=[])
    if runner.step in runner.steps and runner.steps[runner.step][1] is None:
        runner.steps[runner.step][1] = runner.sim.time
    t_run = time.perf_counter() - t_wall
    report = dict(success=failure is None, failure=failure, steps=runner.steps,
                  planned_steps={k: list(v) for k, v in plan.steps.items()},
                  simulated_time=runner.sim.time, seed=seed, start=list(plan.start), end=list(plan.end),
                  robots=pair.name, robot_names=list(pair.names),
                  controller=name, controller_options=_plain(dict(controller_options or {})),
                  commanded=runner.commanded, disturbance=_plain(dataclasses.asdict(dist)), jaws_close=list(plan.close),
                  dt=dt, log_every=log_every, world_every=world_every, control_every=control_every,
                  placed=getattr(runner, "placed", None), backed_off=getattr(runner, "backed_off", None))
    series = None
    log = runner.sim.log
    if score_run:
        series = score(runner, report, log)
    timing = dict(run=t_run, scoring=time.perf_counter() - t_wall - t_run)
    return CarryResult(report, runner.sim, log, plan, series, timing)
