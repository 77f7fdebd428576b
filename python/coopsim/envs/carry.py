"""``coopsim/DualCarry-v0``: the dual carry of :mod:`coopsim.tasks.carry` (docs/carry.md) as an environment
whose actions are the cooperative law's commands.

``reset(seed=)`` draws the start stands by the seed (:func:`~coopsim.tasks.carry.planning.random_start`, so the
episode of seed s carries what ``tasks.carry.run(seed=s, controllers="object")`` carries), plans the carry, and
starts at the approach's end: the plan's clock begins there (every planned time 1 s earlier than the carry's),
the arms at rest at the approach's end with the jaws open around the bar, the bar at rest on its start stands.
Only the grasp is simulated, scripted (the carry's own ``_Runner``: the jaws close, the clamp rule welds the
bar, 0.3 s of settling): 1 s of simulated time instead of the carry's 2 s (the approach moves the arms in free
space and touches nothing, and it ends at rest). The episode starts at the end of the grasp with the bar held
by both clamps under object-level control (:class:`coopsim.ObjectControl`, the carry's ``"object"``
controllers). Each ``step(action)`` sets the law's commands and advances the engine one control period
(default 50 Hz: 100 engine steps of 0.2 ms, the controllers at 1 kHz, the world at 1 kHz) in one call, along
the plan's lift, carry and place (3.6 s: 180 steps at 50 Hz).

Action: Box (5,) float64, the cooperative law's commands: the bar's offset from its planned path (3,) m
(each within +-``max_offset``, default 0.01 m), the squeeze (N, compression positive, in [0, 3]) and SCARA
#1's load share (its part of the bar's vertical load, [0, 1]). The offset is a target the law's reference
reaches along a straight line over 0.2 s from where it is (:attr:`coopsim.ObjectControl.offset` with
``offset_ramp`` 0.2 s, :data:`OFFSET_RAMP`): the bar's reference moves at most 2 max_offset / 0.2 s (0.1 m/s
at 1 cm). :attr:`DualCarryEnv.scripted_action` ([0, 0, 0, 0, 0.5]) is the scripted carry's. The commands are
set on the one law of the episode (:class:`coopsim.ObjectControl`'s ``squeeze``, ``load_share``,
``offset``) and taken at its next update, the start of the period: no law rebuilt, its force integral running
on.

Why these bounds (measured, docs/envs.md "The action space"): the clamps hold the bar by soft welds that let go
when stretched beyond 5 mm (the grasp's ``slip``). A squeeze stretches both welds along the bar, about 0.5 mm
per N held (1.6 mm at 3 N), and a pull (a negative squeeze) draws the jaws off the bar; an offset that jumps
by centimetres within one 20 ms period asks the bar for metres per second and the welds for the force to
accelerate it. With the squeeze in [-5, 10] N and offsets of +-2 cm reached within a period, random
actions let go of the bar within 1 to 7 steps; within [0, 3] N and +-1 cm reached over 0.2 s, 8 random
episodes of 8 ran their 180 steps with the welds stretched at most 3.5 mm, while a policy can still squeeze,
shift the load and move the bar by a centimetre.

Observation: a Dict (``gymnasium.wrappers.FlattenObservation`` flattens it): q, qd (2, 6) of both arms;
clamp_pose (2, 7): each TCP's position (m) and quaternion [w, x, y, z]; clamp_twist (2, 6): each TCP's
velocity (m/s) and angular velocity (rad/s); wrench (2, 6): each clamp's force/torque sensor in world axes
(N, N m, what its end applies to the bar); bar_pose (7,), bar_twist (6,); bar_error (6,): the plan's bar pose
less the bar's (position m, rotation vector rad); internal (12,): the internal wrench of the hold
(:meth:`coopsim.Simulation.cooperation`), squeeze (1,) N, load_share (2,); phase (1,): the fraction of the
held part of the plan gone by. Each within +-1e4 (clipped).

Reward per step, in [0, 1]: each arm i earns task_i * share_i, task_i = exp(-|its TCP - its planned grip|
/ 1 cm) and share_i = exp(-((its load share - 1/2) / 0.25)^2) (1 while the bar's vertical load is under a
fifth of its weight: on the stands); the step's reward is the smaller of the two arms' times
exp(-|internal force| / 5 N), the squeeze and internal-force penalty. One arm carrying the bar, or
an arm off its grip, earns the episode little.

Terminated: at the end of the place (``info["success"]`` when the bar is within 5 mm and 0.05 rad of its
planned pose, moving slower than 1 cm/s), or at a failure of the carry's rules (an unexpected contact, a
clamp letting go, a divergence) with ``info["failure"]`` (its step, time and reason) and reward 0; a start
whose scripted approach or grasp failed (a bar too heavy for the clamps) says so in reset's ``info["failure"]``
and ends at the first step so.

Disturbances: ``disturbance=`` takes what ``tasks.carry.run(disturbance=)`` takes (None, a name of
:data:`coopsim.tasks.carry.disturbances.DISTURBANCES` such as ``"push"``, several names, or a
:class:`~coopsim.tasks.carry.disturbances.Disturbances`), made for each episode's start as the carry makes it.
The push (2 N horizontal on the bar's centre, across its start axis, 0.2 s in the middle of the carry) acts
over the control periods that start within its window (at 50 Hz exactly its 0.2 s: ten periods from
t = 2.7 s on the episode's clock); ``info["push"]`` is the force (3,) N on the bar during the step. A grip
offset and a model mass factor change the plan, sensor noise the force/torque sensors, as in the carry.
"""
from __future__ import annotations

import bisect
import dataclasses
import math
from typing import Optional

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import _checks
from .._core import CubicTrajectory, DivergenceError, World
from ..simulation import Simulation
from ..tasks import scene as _handover_scene
from ..tasks.carry import controllers as _controllers
from ..tasks.carry import planning as _planning
from ..tasks.carry import scene as _scene
from ..tasks.carry.constants import PLACE_TOL, PLACE_TOL_ANGLE, STAND_FRICTION
from ..tasks.carry.disturbances import Disturbances
from ..tasks.carry.disturbances import disturbances as _disturbances
from ..tasks.carry.sequence import CarryError, _Runner
from ._common import BOUND, DT, Frames, bounded, check_action, check_render_mode, clip, control_period

__all__ = ["DualCarryEnv"]

#: the scripted carry's commands: no offset, no squeeze, half the load each
SCRIPTED = np.array([0.0, 0.0, 0.0, 0.0, 0.5])
SQUEEZE_RANGE = (0.0, 3.0)        # N: compression only, at most 3 N (see the module's documentation)
OFFSET_RAMP = 0.2                 # s: an offset's action is reached over this time (a rate limit)
GRIP_SCALE = 0.01                 # m: the task term's scale
SHARE_SCALE = 0.25                # the load share's scale
INTERNAL_SCALE = 5.0              # N: the internal force's scale
#: the simulation's rates (the carry's for the SCARAs): controllers and world every 5 engine steps, a log row
#: every 5 ms (the carry's checks read the grasp events from it)
RATES = dict(dt=DT, world_every=5, control_every=5, log_every=25)


def _shifted(trajectory: CubicTrajectory, t_cut: float) -> CubicTrajectory:
    """`trajectory` from its knot at t_cut (s) on, its times less t_cut: the same cubic pieces."""
    times = np.asarray(trajectory.times)
    keep = times >= t_cut - 1e-12
    if not np.any(np.abs(times - t_cut) < 1e-12):
        raise ValueError(f"the plan's references have no knot at t = {t_cut} s")
    return CubicTrajectory(times[keep] - t_cut, np.asarray(trajectory.q_points)[keep],
                           np.asarray(trajectory.qd_points)[keep])


def _from_grasp(plan: _planning.Plan) -> _planning.Plan:
    """The plan from the approach's end on, its clock started there (every time less the approach's
    duration): the arms start at rest at the approach's end, the jaws open around the bar, the bar at rest
    on its stands; the grasp, lift, carry, place, release and back off as planned, 1 s earlier."""
    cut = float(plan.steps["approach"][1])
    steps = {name: (float(a) - cut, float(b) - cut) for name, (a, b) in plan.steps.items()}
    bar = dataclasses.replace(plan.bar, times=np.asarray(plan.bar.times, float) - cut)
    knots = [(np.asarray(t, float) - cut, q) for t, q in plan.knots]
    return dataclasses.replace(plan, bar=bar, steps=steps, t_end=float(plan.t_end) - cut, knots=knots,
                               references=[_shifted(r, cut) for r in plan.references])


def _world(start, end, bar_mass: float) -> World:
    """The carry's world (:func:`coopsim.tasks.carry.scene.world`) with a bar of `bar_mass` kg."""
    w = World(floor=True, floor_friction=_handover_scene.FLOOR_FRICTION)
    for name, he, T in _scene.stands(start, end):
        w.add_static_box(name, he, T, friction=STAND_FRICTION)
    w.add_free_box(_scene.BAR, _scene.BAR_HALF_EXTENTS, bar_mass, _scene.bar_pose(*start),
                   friction=_handover_scene.BAR_FRICTION)
    return w


def _row_index(n: int = 6) -> np.ndarray:
    """Where each entry of the observation's flat vector (97,) is in a row of :meth:`Simulation.pair_readout`
    of two robots of n joints and the bar (bar_error and phase, which a row has not, point at entry 0 and
    are written after)."""
    a, b = 6, 6 + 2 * n + 19                           # each robot's part: q, qd, TCP pose (7), twist, wrench
    arms = lambda at, m: list(range(a + at, a + at + m)) + list(range(b + at, b + at + m))  # noqa: E731
    body = b + 2 * n + 19                              # the bar (13), then the pair's internal, squeeze, shares
    return np.array(arms(0, n) + arms(n, n) + arms(2 * n, 7) + arms(2 * n + 7, 6) + arms(2 * n + 13, 6)
                    + list(range(body, body + 13)) + [0] * 6 + list(range(body + 13, body + 28)) + [0])


_ROW_INDEX = _row_index()
_BAR = 68                   # the bar's pose in a row of Simulation.pair_readout (SCARAs of 6 joints)
#: where each part of the observation begins in its flat vector
_FLAT = dict(zip(("q", "qd", "clamp_pose", "clamp_twist", "wrench", "bar_pose", "bar_twist", "bar_error",
                  "internal", "squeeze", "load_share", "phase"),
                 np.cumsum([0, 12, 12, 14, 12, 12, 7, 6, 6, 12, 1, 2]).tolist()))
_ERROR = _FLAT["bar_error"]


class DualCarryEnv(gym.Env):
    """The dual carry with the cooperative law's commands as actions (see the module's documentation).

    control_rate: Hz (default 50). bar_mass: the world's bar (kg, default the carry's 0.15; the controllers'
    model keeps the planned 0.15: a mass to randomise over; ``reset(options={"bar_mass": m})`` for one
    episode). max_offset: m, the bound of the offset's action (0.01; larger offsets reach it over the same
    0.2 s, faster). disturbance: what the carry's
    ``disturbance=`` takes (None, ``"push"``, names, a Disturbances; see the module's documentation).
    render_mode: None or 'rgb_array' (frames of :func:`coopsim.view.draw`)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, *, control_rate: float = 50.0, bar_mass: Optional[float] = None, max_offset: float = 0.01,
                 disturbance=None, render_mode: Optional[str] = None):
        self.render_mode = check_render_mode(render_mode, self.metadata["render_modes"])
        self.period = control_period(control_rate)
        self.metadata = dict(self.metadata, render_fps=int(round(1.0 / self.period)))
        self.bar_mass = _scene.BAR_MASS if bar_mass is None else _checks.positive(bar_mass, "bar_mass", unit="kg")
        self.max_offset = _checks.positive(max_offset, "max_offset", unit="m")
        if not (disturbance is None or isinstance(disturbance, (str, list, tuple, Disturbances))):
            raise ValueError(f"disturbance must be None, a disturbance's name, a list of names or a Disturbances, "
                             f"got {disturbance!r}")
        _disturbances(disturbance, 0.0)           # an unknown name is refused here, not at reset
        self.disturbance = disturbance
        m = self.max_offset
        self.action_space = spaces.Box(np.array([-m, -m, -m, SQUEEZE_RANGE[0], 0.0]),
                                       np.array([m, m, m, SQUEEZE_RANGE[1], 1.0]), dtype=np.float64)
        self.scripted_action = SCRIPTED.copy()
        box = lambda *shape: bounded(shape)  # noqa: E731
        self.observation_space = spaces.Dict(dict(
            q=box(2, 6), qd=box(2, 6), clamp_pose=box(2, 7), clamp_twist=box(2, 6), wrench=box(2, 6),
            bar_pose=box(7), bar_twist=box(6), bar_error=box(6), internal=box(12), squeeze=box(1),
            load_share=box(2), phase=spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float64)))
        #: the order of the observation's parts in _observe's flat vector
        self._layout = [("q", (2, 6)), ("qd", (2, 6)), ("clamp_pose", (2, 7)), ("clamp_twist", (2, 6)),
                        ("wrench", (2, 6)), ("bar_pose", (7,)), ("bar_twist", (6,)), ("bar_error", (6,)),
                        ("internal", (12,)), ("squeeze", (1,)), ("load_share", (2,)), ("phase", (1,))]
        self._layout = [(name, shape, _FLAT[name], int(np.prod(shape))) for name, shape in self._layout]
        self.runner: Optional[_Runner] = None
        self.sim: Optional[Simulation] = None
        self._frames = None
        self._done = True

    # ---- the episode's start: the carry's approach and grasp, scripted ----

    def _reset_sim(self, seed=None, options=None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - {"bar_mass"})
        if unknown:
            raise ValueError(f"options may hold bar_mass only, got {', '.join(map(repr, unknown))}")
        mass = self.bar_mass if options.get("bar_mass") is None else _checks.positive(options["bar_mass"], "bar_mass", unit="kg")
        draw = int(seed) if seed is not None else int(self.np_random.integers(0, 2 ** 31 - 1))
        start = _planning.random_start(draw)
        dist = _disturbances(self.disturbance, start[3])     # the push is across the bar: made for the start
        plan = _from_grasp(_planning.make_plan(start, _planning.END, grip_offsets=dist.grip_offset,
                                               mass_factor=dist.mass_factor))
        factory = _controllers.object_control
        runner = _Runner(plan, plan.start, dist, factory, **RATES)
        if mass != _scene.BAR_MASS:        # the same run in a world whose bar weighs `mass`
            made = factory(plan.robots, plan)
            sim = Simulation(dt=RATES["dt"], world=_world(plan.start, plan.end, mass), log_every=RATES["log_every"],
                             world_every=RATES["world_every"], control_every=RATES["control_every"])
            for r, c, ref in zip(plan.robots, made.free, plan.references):
                sim.add_robot(r, c, ref)
            if dist.sensor_noise is not None:       # as the carry's runner sets them
                for i in range(2):
                    sim.set_sensor(i, noise_force=dist.sensor_noise[0], noise_moment=dist.sensor_noise[1], seed=i + 1)
            runner.sim, runner.coop = sim, made
        self.runner, self.sim, self.plan, self.dist = runner, runner.sim, plan, dist
        self._push_window = None
        self._push_now = np.zeros(3)
        if dist.push is not None:       # the push's window (s), in the middle of the carry as the carry puts it
            force, at, T = dist.push
            c0, c1 = plan.steps["carry"]
            mid = float(c0) + at * (float(c1) - float(c0))
            self._push_window = (mid - T / 2.0, mid + T / 2.0, np.asarray(force, float))
        self.episode_bar_mass = mass
        S = plan.steps
        self._failure = None
        try:
            # the episode's clock starts at the approach's end (the plan shifted by _from_grasp): the arms at
            # rest there, the jaws open around the bar at rest on its stands; only the grasp is simulated
            runner.mark("grasp")
            runner.wait_grasps(S["grasp"][1])
            runner.coop.law.offset_ramp = OFFSET_RAMP     # the offset's action: a target reached over 0.2 s
            runner.group = self.sim.add_cooperative(runner.coop.law, [0, 1])
            runner.done()
            runner.mark("lift")
        except (CarryError, DivergenceError) as e:    # not seen with the planned carry: said in info
            self._failure = self._failure_info(e)
        self.t0, self.t_end = self.sim.time, float(S["place"][1])
        self._bar_path = (list(map(float, plan.bar.times)), plan.bar)
        self._grips = [np.asarray(G, float)[:3, 3].tolist() for G in plan.grips]    # (2, 3) m, in the bar's frame
        self._waypoints = np.asarray(plan.bar.waypoints, float).tolist()
        self.k = 0
        self.commands = SCRIPTED.copy()
        self._done = False       # a failed start ends the episode at its first step

    # ---- one step: apply, advance (here or by the vector environment), read ----

    def _apply(self, action, checked: bool = False) -> float:
        """Checks and applies `action` (the law's commands; `checked`: a float64 array of the space already
        checked, the environment's own); returns the time (s) to advance to."""
        a = action if checked else check_action(action, self.action_space)
        sim = self.sim
        if self._failure is not None:      # the approach or grasp failed: nothing to advance
            return sim.time
        t_next = min(self.t_end, self.t0 + (self.k + 1) * self.period)
        if abs(t_next - self.t_end) < 1e-9:
            t_next = self.t_end
        # the law's commands, taken at its next update (the one at the period's start): one law all the
        # episode, its force integral running on; the offset ramps over the period from the last one
        law = self.runner.coop.law
        law.squeeze = float(a[3])
        law.load_share = float(a[4])
        law.offset = a[:3]
        self.commands = a
        if self._push_window is not None:   # on over the periods that start within the push's window
            lo, hi, force = self._push_window
            t = sim.time
            push = force if lo - 1e-9 <= t < hi - 1e-9 else np.zeros(3)
            if np.any(push != self._push_now):
                sim.set_body_wrench(_scene.BAR, np.r_[push, 0.0, 0.0, 0.0])
                self._push_now = push
        self.k += 1
        return t_next

    def _failure_info(self, e) -> dict:
        if isinstance(e, CarryError):
            return dict(step=e.step, t=e.t, reason=e.reason)
        return dict(step=self.runner.step, t=self.sim.time, reason=f"{type(e).__name__}: {str(e).splitlines()[0]}")

    def _checked(self, error: Optional[BaseException], row: np.ndarray):
        """The carry's checks after an advance (as ``_Runner.run_to``'s), on the step's readout `row`
        (:meth:`Simulation.pair_readout`): the failure (dict) or None. The runner's own checks run only when
        the row shows what they look for: a clamp that no longer holds the bar, new contact events."""
        runner = self.runner
        try:
            if error is not None:
                if isinstance(error, ValueError) and any(self.sim.holding(i) != _scene.BAR for i in range(2)):
                    runner.check_held()
                raise error
            if row[2] != 1.0 or row[3] != 1.0:
                runner.check_held()
            if row[4] > runner.contact_seen:
                runner.check_contacts()
        except (CarryError, DivergenceError, ValueError) as e:
            return self._failure_info(e)
        return None

    def _phase_marks(self, t: float):
        S, runner = self.plan.steps, self.runner
        for step, nxt in (("lift", "carry"), ("carry", "place")):
            if runner.step == step and t >= S[step][1] - 1e-9:
                runner.done()
                runner.mark(nxt)

    def _planned_bar(self, t: float):
        """The plan's bar pose at t (s), as :meth:`BarPath.pose` gives it: (yaw rad, position (3,) m)."""
        times, path = self._bar_path
        k = min(max(bisect.bisect_right(times, t) - 1, 0), len(times) - 2)
        u = min(1.0, max(0.0, (t - times[k]) / (times[k + 1] - times[k])))
        u = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
        a, b = self._waypoints[k], self._waypoints[k + 1]
        x = [a[j] + u * (b[j] - a[j]) for j in range(4)]
        return x[3], x[:3]

    _readout_args = (0, 1, _scene.BAR)   # the robots and the body of each step's readout (Simulation.pair_readout)

    def _readout(self) -> np.ndarray:
        """The simulation's readout now (:meth:`Simulation.pair_readout` of both arms and the bar): one row."""
        return Simulation.pair_readout([self.sim], *self._readout_args)[0]

    def _observe(self, row: Optional[np.ndarray] = None) -> dict:
        """The observation (the Dict's parts: views of one flat float64 array) from the readout `row` (None:
        read now). Keeps the plan's bar pose at the row's time and the flat values (Python floats) for the
        reward."""
        if row is None:
            row = self._readout()
        t = float(row[0])
        yaw, p = self._planned_bar(t)
        flat = row[_ROW_INDEX]
        # the bar's error: the plan's position less the bar's, and the rotation vector of the plan's yaw times
        # the bar's rotation transposed, from their quaternions (q_plan q_bar*, w >= 0)
        px, py, pz, bw, bx, by, bz = row[_BAR:_BAR + 7].tolist()
        ch, sh = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
        w, vx, vy, vz = ch * bw + sh * bz, sh * by - ch * bx, -ch * by - sh * bx, sh * bw - ch * bz
        if w < 0.0:
            w, vx, vy, vz = -w, -vx, -vy, -vz
        nv = math.sqrt(vx * vx + vy * vy + vz * vz)
        f = 2.0 if nv < 1e-300 else 2.0 * math.atan2(nv, w) / nv
        flat[_ERROR:_ERROR + 6] = (p[0] - px, p[1] - py, p[2] - pz, f * vx, f * vy, f * vz)
        flat[-1] = min(1.0, max(0.0, (t - self.t0) / max(self.t_end - self.t0, 1e-12)))
        if not flat.dot(flat) <= BOUND * BOUND:    # |x_i| <= |x| <= BOUND, and False for NaN or inf
            flat = clip(flat)           # a state beyond the bound or not finite (a run that diverged): clipped
        values = flat.tolist()
        self._planned = (math.cos(yaw), math.sin(yaw), p)
        self._flat = values
        self._obs_flat = flat           # the observation's parts are views of it (the vector env stacks it)
        return {name: flat[k:k + n] if len(shape) == 1 else flat[k:k + n].reshape(shape)
                for name, shape, k, n in self._layout}

    def _terms(self) -> dict:
        """The reward's terms from the last observation: each arm's task and share terms and the internal-force
        factor."""
        c, s, p = self._planned
        f = self._flat
        ls0, ls1 = f[_FLAT["load_share"]], f[_FLAT["load_share"] + 1]
        task = []
        for k, (g0, g1, g2) in zip((_FLAT["clamp_pose"], _FLAT["clamp_pose"] + 7), self._grips):   # m
            d0 = f[k] - (p[0] + c * g0 - s * g1)
            d1 = f[k + 1] - (p[1] + s * g0 + c * g1)
            d2 = f[k + 2] - (p[2] + g2)
            task.append(math.exp(-math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / GRIP_SCALE))
        up = f[_FLAT["wrench"] + 2] + f[_FLAT["wrench"] + 8]
        if up > 0.2 * self.episode_bar_mass * 9.81 and ls0 != 0.0 and ls1 != 0.0:
            share = [math.exp(-(((x - 0.5) / SHARE_SCALE) ** 2)) for x in (ls0, ls1)]
        else:
            share = [1.0, 1.0]
        k = _FLAT["internal"]
        internal = math.sqrt(f[k] ** 2 + f[k + 1] ** 2 + f[k + 2] ** 2)
        arms = [task[0] * share[0], task[1] * share[1]]
        return dict(task=np.array(task), share=np.array(share), arms=np.array(arms), internal=internal,
                    internal_factor=math.exp(-internal / INTERNAL_SCALE))

    def _outcome(self, error: Optional[BaseException] = None, row: Optional[np.ndarray] = None):
        """The step's observation, reward, termination, truncation and info after an advance that raised
        `error` (or None), from the readout `row` (None: read now; the vector environment reads its
        environments' rows in one call)."""
        if row is None:
            row = self._readout()
        failure = self._failure if self._failure is not None else self._checked(error, row)
        obs = self._observe(row)
        t = float(row[0])
        info = dict(time=t, step=self.runner.step, commands=self.commands.copy(),
                    success=False, bar_mass=self.episode_bar_mass, push=self._push_now.copy())
        if failure is not None:
            self._done = True
            info["failure"] = failure
            return obs, 0.0, True, False, info
        self._phase_marks(t)
        terms = self._terms()
        info["reward_terms"] = terms
        reward = float(min(terms["arms"][0], terms["arms"][1]) * terms["internal_factor"])
        terminated = t >= self.t_end - 1e-9
        if terminated:
            self.runner.done()
            e = obs["bar_error"].tolist()
            d = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2)
            ang = math.sqrt(e[3] ** 2 + e[4] ** 2 + e[5] ** 2)
            v = row[_BAR + 7:_BAR + 10].tolist()
            speed = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
            info["placed"] = dict(position_error=d, angle_error=ang, speed=speed)
            info["success"] = bool(d <= PLACE_TOL and ang <= PLACE_TOL_ANGLE and speed <= 0.01)
            if not info["success"]:
                info["failure"] = dict(step="place", t=t, reason=(
                    f"the bar came to {d * 1e3:.1f} mm and {ang * 1e3:.1f} mrad from its planned pose, moving at "
                    f"{speed * 1e3:.1f} mm/s (allowed {PLACE_TOL * 1e3:.0f} mm, {PLACE_TOL_ANGLE * 1e3:.0f} mrad, "
                    f"10 mm/s)"))
            self._done = True
        return obs, reward, bool(terminated), False, info

    # ---- Gymnasium ----

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        self._reset_sim(seed, options)
        obs = self._observe()
        info = dict(time=self.sim.time, step=self.runner.step, success=False, bar_mass=self.episode_bar_mass,
                    start=tuple(float(x) for x in self.plan.start), disturbance=self.dist.names)
        if self._failure is not None:
            info["failure"] = self._failure
        return obs, info

    def step(self, action):
        if self._done:
            raise RuntimeError("step() after the episode ended: call reset() first")
        t = self._apply(action)
        error = None
        try:
            self.sim.advance(t)
        except (ValueError, DivergenceError) as e:
            error = e
        return self._outcome(error)

    def render(self):
        if self.render_mode == "rgb_array" and self.sim is not None:
            if self._frames is None:
                self._frames = Frames(elev=30, azim=-60, zoom=1.6, names=False)   # the carry report's camera
            return self._frames.frame(self.sim, label=f"t = {self.sim.time:.2f} s ({self.runner.step})")
        return None

    def close(self):
        if self._frames is not None:
            self._frames.close()
            self._frames = None
