"""The simulation: robots with controllers and references, stepped in C++.

The state lives in the engine (``coopsim._core.SimulationCore``): the robots
(immutable copies), q and qd, the held torques, the applied forces and
wrenches, the log and the tracking metrics. :class:`Simulation` is a thin
wrapper over it that adds what a user handles in Python: a progress bar,
run statistics, pacing to the wall clock (:mod:`coopsim.pacing`), the log as
numpy arrays (:mod:`coopsim.log`) and pickling of its description.

Units: s, rad or m, N m or N. Arrays are float64.
"""
from __future__ import annotations

import ast
import inspect
import re
import time
from collections.abc import Mapping
from contextlib import contextmanager
from typing import Callable, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _core
from . import _checks
from . import schedule as _schedule
from ._core import ComputedTorque, Controller, DivergenceError, PID, Robot, SimulationBusyError, World
from .log import BodyLog, RobotLog, SimulationLog
from .pacing import Pacer, RunStats

#: the engine's defaults of the options (its SimulationOptions, the one place they are written), which the
#: signature below shows; grasp_options=None takes the engine's defaults of the grasp options
_DEFAULTS = _core.simulation_defaults()

__all__ = ["ComputedTorque", "Controller", "DivergenceError", "PID", "Simulation", "SimulationBusyError",
           "gil_released_seconds"]

# by default a headless run of at least this many steps shows a progress bar
# once it has lasted _PROGRESS_DELAY s of wall time
_PROGRESS_MIN_STEPS = 10_000
_PROGRESS_DELAY = 1.0
# Simulation.advance_until's events: the engine's flags (Simulation::Until)
_UNTIL = {"grasp": 1, "contact": 2}


class Simulation:
    """One or more robots, each with a controller and a reference, stepped at a fixed dt.

    dt: step size (s, default 0.2 ms, the paper's). integrator: 'rk4'
    (default) or 'euler' (semi-implicit). control_every: the controllers
    run every k-th step and their torque is held in between (zero-order
    hold); the log shows the held torque. log_every: log every n-th step
    (0: no log; tracking metrics still cover every step). end_stops: joints
    beyond their limits meet the robot's spring-damper stops. max_speed
    (rad/s or m/s) and max_position (rad or m): a state beyond them, or a
    non-finite one, stops the run with :class:`DivergenceError` (naming
    step, time, robot and state); the log keeps every row up to the last
    good step.

    Each robot carries applied inputs, set between steps and kept until
    changed (:meth:`set_applied`): joint forces and link wrenches, whose
    joint torque is held over each step like the controller's torque and
    logged as ``tau_ext``.

    world: a :class:`coopsim.World` (floor, scenery, free bodies), owned by
    this simulation alone. Every robot brings its boxes into it as
    kinematic bodies; each step runs controllers, then the world (free
    bodies advance under gravity and contacts), then the robots with the
    contacts' wrenches mapped by J^T into their tau_ext (contact_forces;
    False: contacts are reported only). world_every: the world steps every
    k-th robot step with its contacts and their torques held in between
    (a k times cheaper world; contacts then act k steps late at most, and a
    link may sink about k times deeper before its contact pushes back).
    log_contacts: keep every contact point of every world step (else only
    the contact events: begin, end, peak force, deepest penetration).

    grasp: every robot with a clamp grasps free bodies by the clamp rule
    and holds them by a soft weld (see :meth:`holding`, :meth:`release`);
    grasp_options overrides its thresholds: hold_time (s, 2e-3), gap (m,
    5e-4), penetration (m, 1e-3), angle (rad, 10 deg), speed (m/s, 0.05),
    angular_speed (rad/s, 0.5), open_margin (m, 1e-3), slip (m, 5e-3),
    weld_omega_dt (0.2), release_time (s, 0.1: opening lets go by fading the
    weld out over it, so the load passes on without a jump), weld_moment
    (True; False: point welds that carry forces only).

    Arguments of the wrong type raise TypeError, values out of range
    ValueError naming the argument (checked once, in the engine).

    The description (options, robots, controllers, references, initial
    states) pickles; the state, applied inputs and log do not, so an
    unpickled simulation starts at t = 0.

    One driver at a time: the engine holds the run for the thread advancing or changing it. A call
    that advances (:meth:`step`, :meth:`run`, :meth:`advance`, :meth:`run_paced`) or changes the
    simulation (:meth:`reset`, ``set_*``, ``add_*``, :meth:`release`, ...) from another thread while
    one runs it raises :class:`SimulationBusyError` at once, naming the holder; a driver that runs
    it for a while (the live view) holds it across its calls with :meth:`driving`. Reads
    (:attr:`time`, :meth:`state`, :attr:`log`, :meth:`metrics`, ...) are not guarded: from another
    thread they may see a step half done. :meth:`sensor`, :meth:`grasp_check` and
    :meth:`cooperation` compute on the engine's scratch and count as changes.
    """

    def __init__(self, dt: float = _DEFAULTS["dt"], *, world: Optional[World] = None,
                 integrator: str = _DEFAULTS["integrator"], control_every: int = _DEFAULTS["control_every"],
                 log_every: int = _DEFAULTS["log_every"], end_stops: bool = _DEFAULTS["end_stops"],
                 max_speed: float = _DEFAULTS["max_speed"], max_position: float = _DEFAULTS["max_position"],
                 world_every: int = _DEFAULTS["world_every"], contact_forces: bool = _DEFAULTS["contact_forces"],
                 log_contacts: bool = _DEFAULTS["log_contacts"], grasp: bool = _DEFAULTS["grasp"],
                 grasp_options: Optional[dict] = None):
        if world is not None and not isinstance(world, World):
            raise ValueError(f"world must be a coopsim.World or None, got {type(world).__name__}")
        grasp_options = _grasp_options(grasp_options)
        self._core = _core.SimulationCore(dt=dt, control_every=control_every, log_every=log_every,
                                          end_stops=end_stops, max_speed=max_speed, max_position=max_position,
                                          integrator=integrator, world=world, world_every=world_every,
                                          contact_forces=contact_forces, log_contacts=log_contacts, grasp=grasp,
                                          grasp_options=grasp_options)
        self.stats: Optional[RunStats] = None

    # ---- model and data ----

    @classmethod
    def from_model(cls, model) -> "Simulation":
        """A new run of `model` (from :meth:`model`) at t = 0, with data of its own: each controller and
        cooperative law copied (built-in ones in C++, Python subclasses by ``copy.deepcopy``), a world of its
        own built from the model's description, its own log. The same model gives the same run to
        round-off; the runs step independently (e.g. on threads with :func:`coopsim.run_batch`)."""
        if not isinstance(model, _core.SimulationModel):
            raise ValueError(f"model must be a coopsim.SimulationModel (from Simulation.model()), "
                             f"got {type(model).__name__}")
        sim = cls.__new__(cls)
        sim._core = _core.SimulationCore.from_model(model)
        sim.stats = None
        groups = {}
        for k in range(sim._core.cooperative_count):
            controller, robots, active = sim._core.cooperative_group(k)
            if active:
                groups[k] = (controller, tuple(robots))
        if groups:
            sim.__dict__["_groups"] = groups
        return sim

    def replicate(self, n: int) -> List["Simulation"]:
        """`n` new runs of this simulation's model (:meth:`model`, :meth:`from_model`), sharing it: for
        sweeps and batches of one description (seeds, disturbances and inputs set on each run after)."""
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f"n must be an int >= 0, got {n!r}")
        model = self.model()
        return [Simulation.from_model(model) for _ in range(n)]

    # ---- building ----

    def add_robot(self, robot: Robot, controller: Controller, reference, *, q0=None, qd0=None) -> int:
        """Adds `robot` driven by `controller` towards `reference`; returns its index.

        robot: a coopsim.Robot (immutable: the simulation runs exactly this
        model, backend included). reference: a coopsim.Reference (e.g.
        CubicTrajectory, or a Python subclass) or a set-point array (n,) held
        at all times (kept as a coopsim.SetPoint). q0, qd0 (n,): the initial
        state, by default the reference's q and qd at t = 0. Each robot needs
        its own controller instance (controllers keep state). With a world,
        a start that puts a link box beyond 1e6 m of the origin is a
        ValueError naming the box.
        """
        if not isinstance(robot, Robot):
            raise ValueError(f"robot must be a coopsim.Robot, got {type(robot).__name__}")
        if not isinstance(controller, Controller):
            raise ValueError(f"controller must be a coopsim.Controller (PID, ComputedTorque or a subclass), "
                             f"got {type(controller).__name__}")
        return self._core.add_robot(robot, controller, reference, q0, qd0)

    def add_cooperative(self, controller, robots) -> int:
        """Drives robots `robots` (indices) together with a coopsim.CooperativeController (ObjectControl,
        LeaderFollower or a subclass) from the next controller update on; their own controllers stand aside
        until remove_cooperative. A robot belongs to one group at most. Returns the group's index."""
        if not isinstance(controller, _core.CooperativeController):
            raise ValueError(f"controller must be a coopsim.CooperativeController, got {type(controller).__name__}")
        idx = [_index(i, self.robot_count) for i in robots]
        k = self._core.add_cooperative(controller, idx)
        self.__dict__.setdefault("_groups", {})[k] = (controller, tuple(idx))
        return k

    def remove_cooperative(self, group: int) -> None:
        """Group `group` stops driving; its robots' own controllers are reset and drive again."""
        self._core.remove_cooperative(int(group))
        self.__dict__.get("_groups", {}).pop(int(group), None)

    @property
    def cooperatives(self) -> List[dict]:
        """The cooperative groups driving now (added by :meth:`add_cooperative`, not removed), in the order
        of their indices: each {'group': index, 'controller': the CooperativeController, 'robots': [indices]}."""
        groups = sorted(self.__dict__.get("_groups", {}).items())
        return [dict(group=k, controller=c, robots=list(r)) for k, (c, r) in groups]

    # ---- description ----

    @staticmethod
    def defaults() -> dict:
        """The options' defaults, the engine's: {name: value}, grasp_options a dict of its own."""
        return _core.simulation_defaults()

    @staticmethod
    def sensor_defaults() -> "_core.SensorOptions":
        """The engine's defaults of a robot's force/torque sensor (see :meth:`set_sensor`): noise_force (N),
        noise_moment (N m), time_constant (s), seed."""
        return _core.sensor_defaults()

    @property
    def options(self) -> dict:
        """The constructor's keyword arguments but the world."""
        c = self._core
        return dict(dt=c.dt, integrator=c.integrator, control_every=c.control_every, log_every=c.log_every,
                    end_stops=c.end_stops, max_speed=c.max_speed, max_position=c.max_position,
                    world_every=c.world_every, contact_forces=c.contact_forces, log_contacts=c.log_contacts,
                    grasp=c.grasp, grasp_options=c.grasp_options())

    @property
    def robots(self) -> List[Robot]:
        """The robots as simulated (equal to the ones added: robots are immutable)."""
        return [self._core.robot(i) for i in range(self.robot_count)]

    @property
    def controllers(self) -> List[Controller]:
        return [self._core.controller(i) for i in range(self.robot_count)]

    @property
    def references(self) -> list:
        """Each robot's reference (a coopsim.Reference; set-points as coopsim.SetPoint)."""
        return [self._core.reference(i) for i in range(self.robot_count)]

    def __getstate__(self):
        c = self._core
        entries = [(c.robot(i), c.controller(i), c.reference(i), *c.initial_state(i)) for i in range(self.robot_count)]
        # the world as built (a fresh copy of its bodies, at their initial states)
        sensors = [c.sensor_options(i) for i in range(self.robot_count)]
        return {"options": self.options, "world": c.world, "entries": entries, "sensors": sensors}

    def __setstate__(self, state):
        self.__init__(world=state.get("world"), **state["options"])
        for robot, controller, reference, q0, qd0 in state["entries"]:
            self.add_robot(robot, controller, reference, q0=q0, qd0=qd0)
        for i, options in enumerate(state.get("sensors", [])):  # SensorOptions (dicts in older pickles)
            if not isinstance(options, Mapping):
                options = {k: getattr(options, k) for k in _core.SensorOptions.fields}
            self.set_sensor(i, **options)

    def __repr__(self) -> str:
        names = ", ".join(f"{r.name}/{type(c).__name__}" for r, c in zip(self.robots, self.controllers))
        return f"<coopsim.Simulation dt={self.dt:g} s, t={self.time:.6g} s, {names or 'no robots'}>"

    # ---- one driver at a time ----

    @contextmanager
    def driving(self, label: str) -> Iterator["Simulation"]:
        """Holds the run for the calling thread for the block: ``with sim.driving("the live view at
        http://127.0.0.1:8080"): ...``.

        Inside it this thread may step and change the simulation as usual (and nest other holds);
        every other thread's call that advances or changes it (:meth:`step`, :meth:`run`,
        :meth:`advance`, :meth:`reset`, ``set_*`` ...) raises :class:`SimulationBusyError` naming
        `label`, until the block ends, normally or by an exception. Reads (:attr:`time`,
        :meth:`state`, :attr:`log` ...) stay open to everyone and are not guarded. label: a
        non-empty str naming the driver to the others. Raises SimulationBusyError at once when
        another thread holds the run. Yields this simulation.
        """
        if not isinstance(label, str) or not label:
            raise ValueError(f"label must be a non-empty str naming the driver, got {label!r}")
        hold = self._core.hold(label)
        try:
            yield self
        finally:
            hold.release()

    @property
    def driver(self) -> Optional[Tuple[str, int]]:
        """(label, thread) of the driver holding the run now (thread: its ``threading.get_ident()``;
        label 'another thread' for a call holding it for its own duration), or None. A snapshot."""
        return self._core.holder

    # ---- state ----

    @property
    def t(self) -> float:
        """Simulated time now, s (the same as :attr:`time`)."""
        return self._core.time

    def state(self, robot: int = 0):
        """(q, qd) of a robot now, each (n,)."""
        return self._core.state(_index(robot, self.robot_count))

    def torque(self, robot: int = 0) -> np.ndarray:
        """The torque held on a robot now, (n,) (saturated)."""
        return self._core.torque(_index(robot, self.robot_count))

    def set_applied(self, robot: int = 0, *, forces=None, wrenches=None) -> None:
        """Sets a robot's applied inputs, kept until changed (MuJoCo's qfrc_applied / xfrc_applied).

        forces: (n,) joint forces, N m or N, added to the torque. wrenches:
        a coopsim.Wrench or a list of them (force and moment in world
        coordinates at a point of a link), replacing the ones set before;
        [] removes them. None leaves that input as it is. Their joint torque
        tau_ext = forces + sum J^T w is evaluated at each step's state and
        held over the step; it is logged as ``tau_ext``. A change takes
        effect from the next step; if this time's row is already logged, the
        next run logs a second row at the same time with the new inputs.
        """
        self._core.set_applied(_index(robot, self.robot_count), forces, wrenches)

    def set_reference(self, robot: int, reference) -> None:
        """Replaces a robot's reference: a coopsim.Reference (e.g. a CubicTrajectory with times in
        the simulation's clock, s) or a set-point (n,) held from now on.

        It acts from the next controller update: at once before the first step or after
        :meth:`reset`; between runs, the torque already held over the step at the present time
        stays and the new reference drives the next step on. Plan it to start at :attr:`time` with
        the present reference's q and qd for a smooth switch (a task sequenced phase by phase does
        this between ``run`` calls). The pickled description keeps the latest reference.
        """
        self._core.set_reference(_index(robot, self.robot_count), reference)

    def set_robot(self, robot: int, new: Robot) -> None:
        """Replaces a robot by `new` (a coopsim.Robot with the same joint types and the same boxes on
        the same links, e.g. ``cs.robots.scara1(L1=0.35)``: other link lengths, base height and the
        masses that follow them), during a run as before it.

        q and qd stay; the torque held over the present step stays (saturated at the new robot's
        limits) and the new robot's dynamics act from the next step. The controller is reset now
        when the run is under way: a PID's integral restarts at zero; a controller without a model
        of its own (``model=None``: the simulated robot) computes with the new robot; an explicit
        model stays. With a world, the robot's link bodies take the new sizes and their poses at q
        and its self-collision exclusions are recomputed (:meth:`excluded_pairs`); the other bodies
        keep their states. ValueError naming what is wrong: other joints or boxes, a robot that
        holds a body (release it first), another gravity than the world's. :meth:`reset` keeps the
        new robot, as the pickled description does.
        """
        if not isinstance(new, Robot):
            raise ValueError(f"robot must be a coopsim.Robot, got {type(new).__name__}")
        self._core.set_robot(_index(robot, self.robot_count), new)

    def set_controller(self, robot: int, controller: Controller) -> None:
        """Replaces a robot's controller by `controller` (a coopsim.Controller: PID, ComputedTorque
        or a subclass), keeping the robot's state, e.g. to change gains during a run.

        Checked as :meth:`add_robot`'s controller: its gains sized for the robot's joints, its model
        (if any) of the robot's dof, and not driving another robot of this simulation (ValueError
        naming what is wrong). The new controller is reset now, so a PID's integral restarts at
        zero and its velocity estimate at the measured velocity; it computes from the next
        controller update on: at once before the first step or after :meth:`reset`; between runs,
        the torque already held over the step at the present time stays and the new controller
        drives the next step on. The pickled description keeps the latest controller.
        """
        if not isinstance(controller, Controller):
            raise ValueError(f"controller must be a coopsim.Controller (PID, ComputedTorque or a subclass), "
                             f"got {type(controller).__name__}")
        self._core.set_controller(_index(robot, self.robot_count), controller)

    def applied(self, robot: int = 0) -> dict:
        """A robot's applied inputs now: {'forces': (n,), 'wrenches': [Wrench], 'tau_ext': (n,)}."""
        i = _index(robot, self.robot_count)
        forces, wrenches = self._core.applied(i)
        return {"forces": forces, "wrenches": list(wrenches), "tau_ext": self.tau_ext(i)}

    def clear_applied(self, robot: int = 0) -> None:
        """Removes a robot's applied forces and wrenches."""
        i = _index(robot, self.robot_count)
        self._core.set_applied(i, np.zeros(self._core.robot(i).dof), [])

    def tau_ext(self, robot: int = 0) -> np.ndarray:
        """The joint torque of a robot's applied inputs (forces and wrenches), held over the next step, (n,)
        N m or N (the same as ``applied(robot)['tau_ext']``)."""
        return self._core.tau_ext(_index(robot, self.robot_count))

    def link_state(self, robot: int, box: int) -> "_core.BodyState":
        """The pose and twist the world holds for a robot's link box (``robot.boxes[box]``), as set at the
        last world step: pose (4, 4), position (3,) m, quaternion (4,) [w, x, y, z], velocity (3,) m/s,
        angular_velocity (3,) rad/s. Needs a world."""
        i = _index(robot, self.robot_count)
        k = self._core.robot(i).boxes
        if not isinstance(box, (int, np.integer)) or isinstance(box, bool) or not 0 <= box < len(k):
            raise ValueError(f"box must be an index in [0, {len(k)}) of robot {i}'s boxes, got {box!r}")
        return self._core.link_body_state(i, int(box))

    def holding(self, robot: int = 0) -> Optional[str]:
        """The name of the free body a robot holds now, or None."""
        return self._core.holding(_index(robot, self.robot_count))

    def release(self, robot: int = 0) -> None:
        """Releases what a robot holds, now: the body leaves with the clamp's rigid twist."""
        self._core.release(_index(robot, self.robot_count))

    def grasp_check(self, robot: int, body: str) -> "_core.GraspCheck":
        """The clamp rule's conditions for a robot and a free body in the present state: closing,
        aligned, touching, in_pads, slow and ok (all of them), with the measures behind them: angle
        (rad), gap_fixed and gap_moving (m, < 0 penetrating), speed (m/s), angular_speed (rad/s),
        width (m)."""
        return self._core.grasp_check(_index(robot, self.robot_count), body)

    def weld_wrench(self, robot: int = 0) -> np.ndarray:
        """The weld's force (N) and moment (N m) on the body a robot holds, (6,), world frame."""
        return self._core.weld_wrench(_index(robot, self.robot_count))

    def cooperation(self, a: int = 0, b: int = 1) -> "_core.HeldCooperation":
        """What robots a and b (a < b) do together to a body both hold, now: the log's row at this time
        (:meth:`SimulationLog.cooperation` for the quantities and units, one row: centre, point_a,
        point_b (3,), external (6,), internal (12,), squeeze, twist, shear (floats), bending,
        load_share (2,), relative_pose_error (6,)), with holding (bool) and body (its name, or None).
        When they do not hold one body: holding False and zeros."""
        n = self.robot_count
        return self._core.cooperation(_index(a, n), _index(b, n))

    # ---- sensors ----

    def set_sensor(self, robot: int = 0, *, noise_force: Optional[float] = None,
                   noise_moment: Optional[float] = None, time_constant: Optional[float] = None,
                   seed: Optional[int] = None) -> None:
        """Configures a robot's force/torque sensor (every robot has one; by default ideal: no noise,
        no filter). An argument left None keeps its present value.

        The sensor sits at the tool centre point (TCP; for a clamp, between the jaws) and reads the
        wrench the robot's end (the clamp's links, or the tool's link and beyond) applies to its
        environment: the weld's wrench on a held body, minus every contact force and moment on the
        end's boxes, minus the applied link wrenches on it (applied joint forces are not sensed);
        not the end's own weight or inertia. [force N; moment N m about the TCP]. A held body at
        rest reads its weight carried: force m g upwards, moment (c - p_tcp) x force.

        noise_force (N), noise_moment (N m): standard deviations of the Gaussian noise added to each
        force and moment component in the sensor frame (>= 0). time_constant (s, >= 0; 0: none): a
        first-order low-pass filter after the noise, y_k = y_(k-1) + a (x_k - y_(k-1)) with
        a = 1 - exp(-dt / time_constant) at every step (its step response at time T after the step
        is 1 - exp(-(T + dt) / time_constant)). seed (int >= 0): the noise generator restarts from
        it now and at :meth:`reset`, so a seed repeats its noise. ValueError names a negative or
        non-finite option. The new options act from the next step.
        """
        i = _index(robot, self.robot_count)
        o = self._core.sensor_options(i)
        given = dict(noise_force=noise_force, noise_moment=noise_moment, time_constant=time_constant, seed=seed)
        self._core.set_sensor(i, **{k: getattr(o, k) if given[k] is None else given[k] for k in given})

    def sensor_options(self, robot: int = 0) -> "_core.SensorOptions":
        """A robot's sensor options: noise_force (N), noise_moment (N m), time_constant (s), seed."""
        return self._core.sensor_options(_index(robot, self.robot_count))

    def sensor(self, robot: int = 0) -> "_core.SensorReading":
        """A robot's sensors at the present time (the log's row at this time), numpy arrays:

        ft_world (6,): the force/torque reading [fx, fy, fz, mx, my, mz] (N, N m; moment about the
        TCP) in world axes; ft_clamp (6,): the same in the sensor frame (the tool frame, ``pose``);
        ft_true_world, ft_true_clamp (6,): the true wrench, without noise or filter; pose (4, 4):
        the sensor frame in the world; tau (n,): the motors' torque held over the step (N m or N);
        tau_ext (n,): the joint torque the environment puts on the joints over the step: contacts,
        welds (J^T of their wrenches), the jaw's stop on a held body, applied forces and wrenches.
        See :meth:`set_sensor` for what the wrench is. All zero before the first step.
        """
        return self._core.sensor(_index(robot, self.robot_count))

    def excluded_pairs(self, robot: int = 0) -> List[tuple]:
        """Names of the box pairs of a robot that never collide in the world: boxes of one
        link or of adjacent links (the base column is link 0), and pairs touching at every
        one of 200 random poses within the joint limits."""
        r = self._core.robot(_index(robot, self.robot_count))
        names = [b.name for b in r.boxes]
        return [(names[i], names[j]) for i, j in _core.SimulationCore.excluded_pairs(r)]

    def reset(self) -> None:
        """Back to t = 0 and the initial states (the world's bodies too); clears the log, metrics,
        contacts, applied inputs and statistics. Controllers are reset at the next step."""
        self._core.reset()
        self.stats = None

    # ---- running ----

    def step(self, n: int = 1) -> float:
        """Advances n steps (GIL released); returns the new time (s)."""
        self._timed(self._core.advance, n)
        return self.time

    def run(self, t_end: float, *, progress: Optional[bool] = None) -> SimulationLog:
        """Runs headless, as fast as the machine allows, up to time t_end (s); returns the log.

        The loop is C++ with the GIL released (Python controllers or
        references take it for their own calls). progress: True shows a
        tqdm bar, False never; None (default) shows one on a run of 10 000
        steps or more once it has lasted a second. Ctrl-C stops the run
        between chunks with the log kept. Statistics go to :attr:`stats`.
        """
        total = self._core.steps_until(t_end)
        bar = None
        if progress or (progress is None and total >= _PROGRESS_MIN_STEPS):
            from tqdm import tqdm  # only when a bar is shown: tqdm's import is not free

            bar = tqdm(total=total, unit="step", unit_scale=True, delay=0.0 if progress else _PROGRESS_DELAY,
                       desc="simulating", leave=False)
        try:
            self._run(t_end, None if bar is None else (lambda done, tot: bar.update(done - bar.n)))
        finally:
            if bar is not None:
                bar.close()
        return self.log

    def advance(self, t_end: float) -> float:
        """Runs headless up to time t_end (s) as :meth:`run` does, without a progress bar and without
        building the log's arrays; returns the new time (s).

        For a caller that advances in many short pieces and reads the state between them (a task
        sequenced phase by phase, a wait for a grasp): the engine keeps logging as configured, and
        :attr:`log` gives every row whenever it is read. Statistics go to :attr:`stats`.
        """
        self._run(t_end, None)
        return self.time

    def advance_until(self, t_end: float, until: Union[str, Sequence[str]] = ("grasp", "contact"), *,
                      every: Optional[float] = None) -> Optional[str]:
        """Advances toward time t_end (s) as :meth:`advance` does, in one engine call with the GIL
        released, and stops early after an event of `until`: 'grasp' (a grasp or a release: a row of
        :attr:`SimulationLog.grasps` appeared), 'contact' (a contact began between two bodies of the
        world: an entry of :meth:`contact_events` appeared), or both (a sequence).

        The engine looks for the events after every `every` s of steps counted from now (None: every
        step; rounded down to whole steps, at least one), as a caller advancing in pieces of `every`
        and looking between them would; it stops at the end of the first piece with one, so handing
        such a wait to the engine gives the same run, stopped at the same time. Returns 'grasp',
        'contact' or 'grasp+contact' (what the last piece had), or None when t_end was reached.
        ValueError naming the argument for an unknown event, a non-positive or non-finite `every`,
        or a t_end before now.
        """
        names = (until,) if isinstance(until, str) else tuple(until)
        flags = 0
        for name in names:
            if name not in _UNTIL:
                raise ValueError(f"until must name events of {', '.join(map(repr, _UNTIL))}, got {name!r}")
            flags |= _UNTIL[name]
        if not names:
            raise ValueError("until must name at least one event ('grasp', 'contact')")
        found = self._timed(self._core.run_until, t_end, flags, self.dt if every is None else every)
        return "+".join(n for n, f in _UNTIL.items() if found & f) or None

    def run_schedule(self, steps, *, allowed_contacts=None, contacts_seen: int = 0):
        """Runs a schedule (:mod:`coopsim.schedule`: a list of :class:`~coopsim.schedule.Step`) in one engine call
        with the GIL released: each step's actions, then its advance in pieces with its checks and waits.

        allowed_contacts: None (contacts not checked) or the contacts allowed, each (a, b) or (a, b, from, to):
        body names or patterns ('name', 'prefix*', '*suffix', '*'), either way round, beginning within [from,
        to] s (None: unbounded); a contact that begins and matches none fails the run. contacts_seen: the
        contact events already looked at (a previous schedule's :attr:`~coopsim.schedule.ScheduleResult.contacts_seen`):
        those before it are not checked.

        Returns a :class:`~coopsim.schedule.ScheduleResult`. Raises :class:`~coopsim.schedule.ScheduleError`
        (one line naming the step, the time and the reason) for a failed check, a wait that timed out or a
        condition false at a step's end, with the run stopped there; an engine error while advancing as it is,
        with ``schedule_step`` (the step's name) and ``schedule_result`` (the
        :class:`~coopsim.schedule.ScheduleResult` up to it) on it; ValueError, before anything runs, naming the step and the
        action or condition for a bad schedule (a robot or body out of range, a missing controller, a time
        before the previous one), and naming the step, its time and the action for one the simulation refuses
        when it comes. Statistics go to :attr:`stats`.
        """
        plain, rules = _schedule.plain(steps, allowed_contacts)
        seen = _checks.integer(contacts_seen, "contacts_seen", 0, 2 ** 62)
        out = self._timed(_core.run_schedule, self._core, plain, allowed_contacts is not None, rules, seen)
        groups = self.__dict__.setdefault("_groups", {})
        added, mine = iter(out.groups), []
        for st in plain[:len(out.times)]:      # the groups the schedule added and removed, as the calls do
            for a in st[3]:
                if a[0] == "add_cooperative":
                    k = next(added, None)
                    if k is not None:
                        groups[k] = (a[1], tuple(int(i) for i in a[2]))
                        mine.append(k)
                elif a[0] == "remove_cooperative":
                    groups.pop(a[1] if a[1] is not None else (mine[-1] if mine else None), None)
        result = _schedule.ScheduleResult([tuple(t) for t in out.times], list(out.groups),
                                          [_schedule.Record(r.step, r.condition, r.t, r.q, r.pose) for r in out.records],
                                          int(out.contacts_seen))
        if out.failed_step < 0:
            return result
        name = plain[out.failed_step][0]
        if out.kind == "error":
            e = out.error
            e.schedule_step, e.schedule_result = name, result
            raise e
        raise _schedule.ScheduleError(name, out.failed_step, out.t, out.kind, out.reason, out.condition, out.bodies,
                                      result)

    @staticmethod
    def advance_all(sims: Sequence["Simulation"], t_end: float, threads: int = 0) -> list:
        """Advances each of `sims` up to time t_end (s) as :meth:`advance` does, all in one engine call on
        a pool of `threads` threads (0: every core) with the GIL released; the simulations must not share
        controller instances. Returns per simulation the exception that stopped it (e.g. a
        DivergenceError), or None. Each one's :attr:`stats` give the wall time of its own run (the runs
        overlap on the threads). :func:`coopsim.run_batch` checks the arguments and gathers the results.
        """
        marks = [(s.time, s.steps) for s in sims]
        errors, seconds = _core.run_batch([s._core for s in sims], float(t_end), int(threads))
        _batch_stats(sims, seconds, marks)
        return list(errors)

    @staticmethod
    def advance_pool(threads: int) -> "AdvancePool":
        """A pool of `threads` engine threads to which chunks of simulations are handed one at a time
        (:class:`AdvancePool`): what a pipeline of chunks uses when its caller's thread has Python to run
        between them (the vector environments')."""
        return AdvancePool(threads)

    @staticmethod
    def pair_readout(sims: Sequence["Simulation"], a: int, b: int, body: str) -> np.ndarray:
        """Robots `a` < `b` and free body `body` (its name) of each of `sims` now, in one engine call with the
        GIL released: an (len(sims), 72 + 2 (na + nb)) float64 array, one row per simulation (na, nb: the robots'
        joints, the same in every simulation). A row: time s; 1.0 when a and b hold one body (else 0); 1.0 when
        a holds `body`, 1.0 when b does; the counts of contact events and of grasp events so far; then for a and
        for b: q (n), qd (n), the TCP's position (3) m and quaternion [w, x, y, z] (4, w >= 0), its twist J qd
        (6) m/s, rad/s and the force/torque sensor in world axes (6) N, N m (:meth:`sensor`'s ``ft_world``);
        the body's position (3) m, quaternion (4), velocity (3) m/s, angular velocity (3) rad/s
        (:meth:`body_state`); the pair's internal wrench (12) N, N m, squeeze (1) N and load shares (2), as
        :meth:`cooperation` gives them (zeros unless a and b hold one body). What a learning environment
        reads after each step (:mod:`coopsim.envs`): a dozen calls' quantities in one. ValueError naming the
        argument for robots that are not 0 <= a < b < robot_count, a simulation without a world, an unknown
        body."""
        return _core.pair_readout([s._core for s in sims], a, b, body)

    def _run(self, t_end: float, callback) -> None:
        self._timed(self._core.run, t_end, callback)

    def _timed(self, call, *args):
        """call(*args) and what it returns, its run's statistics to :attr:`stats` (also when it fails,
        but for a SimulationBusyError: that run is another thread's, and so are the statistics)."""
        t0, s0, w0 = self.time, self.steps, time.perf_counter()
        try:
            out = call(*args)
        except SimulationBusyError:
            raise
        except BaseException:
            self._record(t0, s0, w0)
            raise
        self._record(t0, s0, w0)
        return out

    def _record(self, t0: float, s0: int, w0: float) -> None:
        w = time.perf_counter() - w0
        self.stats = RunStats._make(self.time, self.time - t0, w, w, self.dt, self.steps - s0)

    def run_paced(self, t_end: float, *, speed: float = 1.0, frame_rate: float = 60.0,
                  on_frame: Optional[Callable] = None, max_wall_time: Optional[float] = None,
                  pacer: Optional[Pacer] = None) -> RunStats:
        """Runs up to t_end (s) paced to the wall clock at `speed` x real time (0 .. 4; 2.0 = 200 %).

        Every frame (frame_rate per second) the simulation advances by the
        wall time since the last frame times the speed, then calls
        on_frame(sim, pacer) for live drawing or control; it may change
        pacer.speed, pause()/resume() or stop(), or return False to stop.
        Pass your own `pacer` to keep control from outside. Returns (and
        stores in :attr:`stats`) the run's statistics. The run holds the
        simulation (:meth:`driving`): other threads' steps and changes raise
        SimulationBusyError until it ends.
        """
        if pacer is None:
            pacer = Pacer(speed=speed, frame_rate=frame_rate)
        with self.driving("a paced run (Simulation.run_paced)"):
            return pacer.run(self, t_end, on_frame=on_frame, max_wall_time=max_wall_time)

    # ---- results ----

    @property
    def log(self) -> SimulationLog:
        """The log up to now: read-only views, without copying, that later steps do not change."""
        return self.log_snapshot()

    def log_arrays(self, robot: int = 0) -> dict:
        """Robot `robot`'s log so far without building a :class:`SimulationLog`, in O(1) whatever the run's
        length: {'t': (rows,) s, and one (rows, n) array per quantity of the log schema}, read-only views
        (no copy) that later steps do not change. For a reader of a running simulation that needs a few
        rows (a live page's table: ``a['q'][-8:]``)."""
        c = self._core
        out = {"t": c.log_t()}
        out.update(c.log(_index(robot, self.robot_count)))
        return out

    def body_log(self, name: str) -> BodyLog:
        """Free body `name`'s log so far, as :attr:`log`'s ``bodies[name]`` (read-only views, no copy), without
        the rest of the log. ValueError naming the bodies for a name that is not a free body of the world."""
        c = self._core
        names = c.free_body_names()
        if name not in names:
            raise ValueError(f"name must be a free body of the world ({', '.join(map(repr, names)) or 'none'}), "
                             f"got {name!r}")
        return BodyLog(name, c.log_t(), c.body_log()[names.index(name)])

    def reference(self, robot: int = 0):
        """Robot `robot`'s reference (:attr:`references`' entry, without making the others')."""
        return self._core.reference(_index(robot, self.robot_count))

    def log_snapshot(self, *, contact_points: bool = True) -> SimulationLog:
        """The log up to now, as :attr:`log`; contact_points=False leaves out every contact point of every
        world step (the one part copied, in time growing with the run: the tables do not hold them), so the
        log is taken in about constant time (e.g. between chunks of a live run, to write it elsewhere)."""
        c = self._core
        t = c.log_t()
        names = np.array((c.world.body_names if c.world is not None else []) + [""], dtype=object)
        robots = []
        for i in range(self.robot_count):
            g = c.grasp_log(i)
            held = names[g[:, 0].astype(int)]  # -1 (none) picks the trailing ""
            ft = c.sensor_log(i)
            robots.append(RobotLog(c.robot(i).name, t, holding=held, weld=g[:, 1:], ft_world=ft[:, :6],
                                   ft_clamp=ft[:, 6:], joint_types=c.robot(i).joint_types, **c.log(i)))
        bodies = [BodyLog(name, t, data) for name, data in zip(c.free_body_names(), c.body_log())]
        pairs = {(a, b): c.cooperation_log(a, b) for b in range(self.robot_count) for a in range(b)}
        return SimulationLog(t, robots, dt=self.dt, control_every=self.control_every, log_every=self.log_every,
                             cooperation=pairs,
                             bodies=bodies, contacts=c.contact_events() if c.world is not None else None,
                             grasps=c.grasp_events() if c.world is not None else None,
                             contact_points=c.contact_log() if contact_points and c.log_contacts and c.world is not None
                             else None)

    def metrics(self) -> List["_core.TrackingMetrics"]:
        """Per robot, tracking metrics over every step so far (whatever log_every):
        name, steps, rms_error (n,), max_abs_error (n,), max_abs_tau (n,)."""
        return [self._core.metrics(i) for i in range(self.robot_count)]


    def set_profiling(self, on: bool = True) -> None:
        """Switches the engine's step profiler on (its timers cost a little) or off; :meth:`profile` reads it."""
        if not isinstance(on, (bool, np.bool_)):
            raise ValueError(f"on must be True or False, got {on!r}")
        self._core.set_profiling(bool(on))


#: what Simulation takes from the engine's SimulationCore as it is: same name, same arguments, the engine's
#: docstring (from its headers); written here once instead of a method that only forwards
FORWARDED: Tuple[str, ...] = (
    "dt", "integrator", "control_every", "log_every", "world", "robot_count", "time", "steps", "diverged",
    "log_rows", "steps_until", "contacts", "contact_events", "body_state", "set_body_wrench", "body_wrench",
    "profile", "model", "grasp_events")


def _signature(doc: str) -> Optional[inspect.Signature]:
    """The signature a pybind11 docstring's first line shows, self first (None if it cannot be read)."""
    m = re.match(r"^\w+\((.*)\) ->", doc or "")
    if not m:
        return None
    params = [inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)]
    depth, part, parts = 0, "", []
    for ch in m.group(1):
        depth += ch in "([" and 1 or ch in ")]" and -1 or 0
        if ch == "," and depth == 0:
            parts.append(part)
            part = ""
        else:
            part += ch
    parts.append(part)
    for text in parts[1:]:
        name, _, default = text.strip().partition("=")
        name = name.split(":")[0].strip()
        try:
            value = ast.literal_eval(default.strip()) if default else inspect.Parameter.empty
        except (ValueError, SyntaxError):
            value = default.strip()
        params.append(inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=value))
    return inspect.Signature(params)


def _forward(name: str):
    """Simulation's attribute `name`: the engine's property or method of that name on self._core."""
    engine = getattr(_core.SimulationCore, name)
    if isinstance(engine, property):
        return property(lambda self: getattr(self._core, name), doc=engine.__doc__)

    def method(self, *args, **kwargs):
        return getattr(self._core, name)(*args, **kwargs)

    method.__name__, method.__qualname__, method.__doc__ = name, f"Simulation.{name}", engine.__doc__
    signature = _signature(engine.__doc__)
    if signature is not None:
        method.__signature__ = signature
    return method


for _name in FORWARDED:
    setattr(Simulation, _name, _forward(_name))


def _grasp_options(options) -> dict:
    """grasp_options as a dict of option names; the engine checks the values (and the names)."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(f"grasp_options must be a dict {{option: value}} or None, got {type(options).__name__}")
    for key, value in options.items():
        if not isinstance(key, str):
            raise ValueError(f"grasp_options: option names are str, got {key!r}")
        if key == "weld_moment" and not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"grasp_options: weld_moment must be True or False, got {value!r}")
    return dict(options)


def _index(i, n):
    if not isinstance(i, (int, np.integer)) or isinstance(i, bool) or not -n <= i < n:
        raise ValueError(f"robot must be an index in [0, {n}), got {i!r}")
    return int(i) % n


def gil_released_seconds() -> float:
    """Wall seconds (s) the calling thread has spent inside the engine's calls with the GIL released, since it
    started: a running total, so take its growth over what you measure. Every engine call that releases the
    GIL counts (a simulation's stepping, :func:`coopsim.run_batch`, the batch dynamics, IK, the clearances);
    a Python controller, reference, cooperative law or progress callback that takes the GIL back inside such
    a call pauses the count while it holds it. Threads the engine starts itself (the pools of run_batch and
    the batch functions) are not counted; the calling thread's call is. ``benchmarks/bench_scaling.py``
    divides its growth over a task run by the run's wall time."""
    return _core.gil_released_seconds()


def _batch_stats(sims, seconds, marks) -> None:
    """Each of `sims`' :attr:`~Simulation.stats` after a batch advanced it: its run's wall time (s, the runs
    overlapping on the threads) and what it covered since its (time, steps) mark taken before."""
    for s, w, (t0, k0) in zip(sims, seconds, marks):
        s.stats = RunStats._make(s.time, s.time - t0, w, w, s.dt, s.steps - k0)


class AdvancePool:
    """`threads` engine threads (1 to 4096) that advance chunks of simulations handed to them one at a time, in
    the order given, each idle thread taking the next chunk; their threads never take the GIL. ``submit(sims,
    t_end, readout=None)`` queues a chunk: each simulation advanced to its own end time (s; :meth:`Simulation.advance`'s
    rules, the simulations distinct and not sharing controllers), then, with ``readout=(a, b, body)``, read by
    :meth:`Simulation.pair_readout`; it returns an :class:`AdvanceJob` at once. The caller may run Python (the
    next chunk's commands) while the pool advances the last ones, then collect each job's result. Made by
    :meth:`Simulation.advance_pool`; the engine's threads stop when the pool is collected."""

    def __init__(self, threads: int):
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or not 1 <= threads <= 4096:
            raise ValueError(f"threads must be an integer from 1 to 4096, got {threads!r}")
        self._core = _core.AdvancePool(int(threads))

    @property
    def threads(self) -> int:
        """The pool's engine threads."""
        return self._core.threads

    def run_one(self) -> bool:
        """Runs the chunk queued first on the caller's thread, as the pool's threads do (the GIL released), and
        returns True; False when none is queued. A caller with nothing else to do helps its pool so instead of
        waiting: its thread becomes one more engine thread (a pipeline of N cores: N - 1 pool threads and the
        caller, never more threads than cores)."""
        return self._core.run_one()

    def submit(self, sims: Sequence[Simulation], t_end: Sequence[float],
               readout: Optional[Tuple[int, int, str]] = None) -> "AdvanceJob":
        """Queues sims, each to advance to its t_end (s), then their readout when `readout` = (a, b, body) is
        given; returns the :class:`AdvanceJob`. ValueError when t_end does not hold one finite time per
        simulation (the rest of the checks come with the job's result)."""
        sims = list(sims)
        a, b, body = readout if readout is not None else (0, 0, "")
        marks = [(s.time, s.steps) for s in sims]
        job = self._core.submit([s._core for s in sims], [float(t) for t in t_end], int(a), int(b), str(body))
        return AdvanceJob(job, sims, marks)


class AdvanceJob:
    """A chunk handed to an :class:`AdvancePool`; :meth:`result` waits for it. It keeps its simulations alive
    until the engine is done with them, even if dropped uncollected."""

    def __init__(self, job, sims, marks):
        self._job, self._sims, self._marks = job, sims, marks

    def done(self) -> bool:
        """Whether the pool has advanced (and read) the chunk, without waiting."""
        return self._job.done()

    def result(self):
        """(errors, rows) once the pool has advanced (and read) the chunk, waiting with the GIL released: per
        simulation the exception that stopped it or None (as :meth:`Simulation.advance_all`), and the readout's
        rows (len(sims), width) or None. Sets each simulation's :attr:`~Simulation.stats`. Raises the chunk's own
        error (ValueError: a simulation repeated, controllers shared, robots or body not there to read)."""
        errors, seconds, rows = self._job.result()
        _batch_stats(self._sims, seconds, self._marks)
        return errors, rows

    def __del__(self):
        try:
            self._job.result()
        except Exception:
            pass
