"""``coopsim/DualCarry-v0``: the dual carry of :mod:`coopsim.tasks.carry` (docs/carry.md) as an environment
whose actions are the cooperative law's commands.

``reset(seed=)`` draws the start stands by the seed (:func:`~coopsim.tasks.carry.planning.random_start`, so the
episode of seed s carries what ``tasks.carry.run(seed=s, controllers="object")`` carries), plans the carry, and
runs its approach and grasp scripted (the carry's own ``_Runner``); the episode starts at the end of the
grasp with the bar held by both clamps under object-level control (:class:`coopsim.ObjectControl`, the
carry's ``"object"`` controllers). Each ``step(action)`` sets the law's commands and advances the engine one
control period (default 50 Hz: 100 engine steps of 0.2 ms, the controllers at 1 kHz, the world at 1 kHz) in
one call, along the plan's lift, carry and place (3.6 s: 180 steps at 50 Hz).

Action: Box (5,) float64, the cooperative law's commands: the bar's offset from its planned path (3,) m
(each within +-``max_offset``, 0.02 m; the law's reference moves to it along a straight line over the period
from the last one: :attr:`coopsim.ObjectControl.offset` with ``offset_ramp`` the period), the squeeze (N,
compression positive, in [-5, 10]) and SCARA #1's load share (its part of the bar's vertical load, [0, 1]).
:attr:`DualCarryEnv.scripted_action` ([0, 0, 0, 0, 0.5]) is the scripted carry's. The commands are set on
the one law of the episode (:class:`coopsim.ObjectControl`'s ``squeeze``, ``load_share``, ``offset``) and
taken at its next update, the start of the period: no law rebuilt, its force integral running on.

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
t = 3.7 s); ``info["push"]`` is the force (3,) N on the bar during the step. A grip offset and a model mass
factor change the plan, sensor noise the force/torque sensors, as in the carry.
"""
from __future__ import annotations

from typing import Optional

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import _checks
from .._core import DivergenceError, World
from ..simulation import Simulation
from ..tasks import scene as _handover_scene
from ..tasks.carry import controllers as _controllers
from ..tasks.carry import planning as _planning
from ..tasks.carry import scene as _scene
from ..tasks.carry.constants import PLACE_TOL, PLACE_TOL_ANGLE, STAND_FRICTION
from ..tasks.carry.disturbances import Disturbances
from ..tasks.carry.disturbances import disturbances as _disturbances
from ..tasks.carry.sequence import CarryError, _Runner
from ._common import DT, Frames, bounded, check_action, check_render_mode, clip, control_period

__all__ = ["DualCarryEnv"]

#: the scripted carry's commands: no offset, no squeeze, half the load each
SCRIPTED = np.array([0.0, 0.0, 0.0, 0.0, 0.5])
SQUEEZE_RANGE = (-5.0, 10.0)      # N
GRIP_SCALE = 0.01                 # m: the task term's scale
SHARE_SCALE = 0.25                # the load share's scale
INTERNAL_SCALE = 5.0              # N: the internal force's scale
#: the simulation's rates (the carry's for the SCARAs): controllers and world every 5 engine steps, a log row
#: every 5 ms (the carry's checks read the grasp events from it)
RATES = dict(dt=DT, world_every=5, control_every=5, log_every=25)


def _quaternion(R) -> np.ndarray:
    """[w, x, y, z] of a rotation matrix (w >= 0)."""
    m = np.asarray(R, float)
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2.0
    x = np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2.0
    y = np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2.0
    z = np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2.0
    x = np.copysign(x, m[2, 1] - m[1, 2])
    y = np.copysign(y, m[0, 2] - m[2, 0])
    z = np.copysign(z, m[1, 0] - m[0, 1])
    return np.array([w, x, y, z])


def _rotation_vector(R) -> np.ndarray:
    """The rotation vector (3,) rad of a rotation matrix."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    angle = float(np.arccos(c))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s = np.sin(angle)
    return v / 2.0 if s < 1e-9 else v * (angle / (2.0 * s))


def _world(start, end, bar_mass: float) -> World:
    """The carry's world (:func:`coopsim.tasks.carry.scene.world`) with a bar of `bar_mass` kg."""
    w = World(floor=True, floor_friction=_handover_scene.FLOOR_FRICTION)
    for name, he, T in _scene.stands(start, end):
        w.add_static_box(name, he, T, friction=STAND_FRICTION)
    w.add_free_box(_scene.BAR, _scene.BAR_HALF_EXTENTS, bar_mass, _scene.bar_pose(*start),
                   friction=_handover_scene.BAR_FRICTION)
    return w


class DualCarryEnv(gym.Env):
    """The dual carry with the cooperative law's commands as actions (see the module's documentation).

    control_rate: Hz (default 50). bar_mass: the world's bar (kg, default the carry's 0.15; the controllers'
    model keeps the planned 0.15: a mass to randomise over; ``reset(options={"bar_mass": m})`` for one
    episode). max_offset: m, the bound of the offset's action (0.02). disturbance: what the carry's
    ``disturbance=`` takes (None, ``"push"``, names, a Disturbances; see the module's documentation).
    render_mode: None or 'rgb_array' (frames of :func:`coopsim.view.draw`)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, *, control_rate: float = 50.0, bar_mass: Optional[float] = None, max_offset: float = 0.02,
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
        self._layout = [(name, shape, int(np.prod(shape))) for name, shape in self._layout]
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
        plan = _planning.make_plan(start, _planning.END, grip_offsets=dist.grip_offset, mass_factor=dist.mass_factor)
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
            runner.mark("approach")
            runner.run_to(S["approach"][1])
            runner.done()
            runner.mark("grasp")
            runner.wait_grasps(S["grasp"][1])
            runner.coop.law.offset_ramp = self.period     # the offset's action ramps over a period
            runner.group = self.sim.add_cooperative(runner.coop.law, [0, 1])
            runner.done()
            runner.mark("lift")
        except (CarryError, DivergenceError) as e:    # not seen with the planned carry: said in info
            self._failure = self._failure_info(e)
        self.t0, self.t_end = self.sim.time, float(S["place"][1])
        self.k = 0
        self.commands = SCRIPTED.copy()
        self._done = False       # a failed start ends the episode at its first step

    # ---- one step: apply, advance (here or by the vector environment), read ----

    def _apply(self, action) -> float:
        """Checks and applies `action` (the law's commands); returns the time (s) to advance to."""
        a = check_action(action, self.action_space)
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
        self.commands = a.copy()
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

    def _checked(self, error: Optional[BaseException]):
        """The carry's checks after an advance (as ``_Runner.run_to``'s): the failure (dict) or None."""
        runner = self.runner
        try:
            if error is not None:
                if isinstance(error, ValueError) and any(self.sim.holding(i) != _scene.BAR for i in range(2)):
                    runner.check_held()
                raise error
            runner.check_held()
            runner.check_contacts()
        except (CarryError, DivergenceError, ValueError) as e:
            return self._failure_info(e)
        return None

    def _phase_marks(self):
        S, t, runner = self.plan.steps, self.sim.time, self.runner
        for step, nxt in (("lift", "carry"), ("carry", "place")):
            if runner.step == step and t >= S[step][1] - 1e-9:
                runner.done()
                runner.mark(nxt)

    def _observe(self) -> dict:
        sim, plan = self.sim, self.plan
        parts = []
        poses, twists, wrenches, qs, qds = [], [], [], [], []
        for i, r in enumerate(plan.robots):
            q, qd = sim.state(i)
            T = r.fk(q)
            qs.append(q)
            qds.append(qd)
            poses += [T[:3, 3], _quaternion(T[:3, :3])]
            twists.append(r.tool_jacobian(q) @ qd)
            wrenches.append(sim.sensor(i).ft_world)
        b = sim.body_state(_scene.BAR)
        want = self._planned_bar = plan.bar.pose(sim.time)
        c = sim.cooperation(0, 1)
        held = bool(c.holding)
        phase = (sim.time - self.t0) / max(self.t_end - self.t0, 1e-12)
        parts = qs + qds + poses + twists + wrenches + [
            b.pose[:3, 3], _quaternion(b.pose[:3, :3]), b.velocity, b.angular_velocity,
            want[:3, 3] - b.pose[:3, 3], _rotation_vector(want[:3, :3] @ b.pose[:3, :3].T),
            np.asarray(c.internal, float) if held else np.zeros(12), [c.squeeze if held else 0.0],
            np.asarray(c.load_share, float) if held else np.zeros(2), [min(1.0, max(0.0, phase))]]
        flat = clip(np.concatenate(parts))
        out, k = {}, 0
        for name, shape, n in self._layout:
            out[name] = flat[k:k + n].reshape(shape)
            k += n
        return out

    def _terms(self, obs) -> dict:
        """The reward's terms: each arm's task and share terms and the internal-force factor."""
        plan = self.plan
        bar = self._planned_bar
        task, share = np.empty(2), np.ones(2)
        for i in range(2):
            planned = (bar @ plan.grips[i])[:3, 3]
            task[i] = np.exp(-np.linalg.norm(obs["clamp_pose"][i, :3] - planned) / GRIP_SCALE)
        up = obs["wrench"][:, 2]
        if np.sum(up) > 0.2 * self.episode_bar_mass * 9.81 and np.all(obs["load_share"] != 0.0):
            share = np.exp(-((obs["load_share"] - 0.5) / SHARE_SCALE) ** 2)
        internal = float(np.linalg.norm(obs["internal"][:3]))
        return dict(task=task, share=share, arms=task * share, internal=internal,
                    internal_factor=float(np.exp(-internal / INTERNAL_SCALE)))

    def _outcome(self, error: Optional[BaseException] = None):
        failure = self._failure if self._failure is not None else self._checked(error)
        obs = self._observe()
        info = dict(time=self.sim.time, step=self.runner.step, commands=self.commands.copy(),
                    success=False, bar_mass=self.episode_bar_mass, push=self._push_now.copy())
        if failure is not None:
            self._done = True
            info["failure"] = failure
            return obs, 0.0, True, False, info
        self._phase_marks()
        terms = self._terms(obs)
        info["reward_terms"] = terms
        reward = float(np.min(terms["arms"]) * terms["internal_factor"])
        terminated = self.sim.time >= self.t_end - 1e-9
        if terminated:
            self.runner.done()
            b = self.sim.body_state(_scene.BAR)
            d = float(np.linalg.norm(obs["bar_error"][:3]))
            ang = float(np.linalg.norm(obs["bar_error"][3:]))
            speed = float(np.linalg.norm(b.velocity))
            info["placed"] = dict(position_error=d, angle_error=ang, speed=speed)
            info["success"] = bool(d <= PLACE_TOL and ang <= PLACE_TOL_ANGLE and speed <= 0.01)
            if not info["success"]:
                info["failure"] = dict(step="place", t=self.sim.time, reason=(
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
