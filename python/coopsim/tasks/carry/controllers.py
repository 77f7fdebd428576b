"""The carry's controllers: factories ``(robots, plan) -> per-robot controllers`` that :func:`~.sequence.run`
takes as ``controllers=``.

A factory returns one of three things:

- a list of one :class:`coopsim.Controller` per robot, driving it for the whole run;
- :class:`Phased` controllers: ``free`` ones while the robots do not hold the bar together and ``held``
  ones from the moment both clamps hold it (the end of the grasp) until both have let go (the end of the
  release), installed with :meth:`coopsim.Simulation.set_controller`;
- :class:`Cooperative`: ``free`` per-robot controllers and one :class:`coopsim.CooperativeController`
  (``law``) that drives both robots together from the end of the grasp to the end of the place
  (:meth:`coopsim.Simulation.add_cooperative`); it is removed before the jaws open
  (:meth:`coopsim.Simulation.remove_cooperative`), and the free controllers release the bar and back off.
  The robots' references stay the planned joint trajectories: a law reads them through its members.

A factory reads what it needs from the plan (:class:`~.planning.Plan`): its references, its grips, the bar's
planned path, and ``plan.model_bar_mass``, the bar's mass its model should take (the 'mass' disturbances
scale it). Factories may take keyword options after (robots, plan) (``functools.partial`` or
:func:`run`'s ``controller_options`` set them).

The choices by name are :data:`CONTROLLERS` (the command line's ``--controller``, :func:`~.sequence.run`'s
``controllers="object"``, the sweeps'); :func:`register_controller` adds one. A factory of one's own is also
named as ``"module:factory"`` (a module on sys.path) or ``"path/to/file.py:factory"`` wherever a name is taken
(:func:`controller_factory`): it is imported where the run runs, so it reaches a sweep's worker processes. A cooperative law from the
engine plugs in as ``register_controller(name, cooperative(make_law))``, ``make_law(robots, plan, **options)``
returning the law.

- :func:`computed_torque` (``ct``), the baseline: each arm on its own, :class:`coopsim.ComputedTorque` on its
  reference with the robot alone as its model. The model knows no bar: it is wrong by the bar's whole share
  throughout the hold, and a wrong bar mass ('mass' disturbances) does not reach it.
- :func:`computed_torque_payload` (``ct-payload``): the same, but while both hold the bar each arm's model
  carries its share of the bar, half of ``plan.model_bar_mass``, as a point mass at its grip on the clamp's
  link (with the bar's mass at the two grips 0.10 m either side of its centre its inertia about the vertical
  through the centre is m 0.01 m^2, within 2 % of the bar's m L^2 / 12). Here a bar mass wrong by +-50 % is a
  model wrong by +-50 % of that share.
- :func:`object_control` (``object``): :class:`coopsim.ObjectControl` drives both arms during the hold,
  object-level control with the bar's model mass ``plan.model_bar_mass`` (so the 'mass' disturbances scale
  it) and the inertia of a box of that mass with the bar's size, a commanded load share (0.5: SCARA #1
  carries half of the bar's weight) and squeeze (0 N); the gains :data:`~.constants.OBJECT_GAINS`. The
  bar's reference is SCARA #1's (its planned joint trajectory and its grip); SCARA #2's TCP moves as a
  point of the bar. Free, the baseline.
- :func:`object_impedance` (``object-impedance``): the same object-level control (the same model, load share,
  squeeze and gains), but the bar is an impedance: it yields to a push as a mass-spring-damper around its
  planned path (:class:`coopsim.ObjectControl` with ``impedance``; the values
  :data:`~.constants.OBJECT_IMPEDANCE`: 300 N/m, 1 kg, damping ratio 0.69, so the carry's 2 N push moves it
  about F/K = 6.7 mm and it comes back after), the push estimated from the clamps' sensors and the bar's
  measured acceleration. The model's weight of the bar is part of that estimate: a wrong model mass moves the
  bar by its weight's error over the stiffness. Free, the baseline.
- :func:`leader_follower` (``leader-follower``): :class:`coopsim.LeaderFollower` drives both arms during the
  hold. SCARA #1 leads: task-space computed torque on its own reference, carrying what it feels. SCARA #2
  follows: an impedance over x, y, z and yaw around where the grips put its clamp given the leader's, driven
  by its sensed wrench less its share (``follower_share``, 0.5) of the weight of the bar's model mass
  ``plan.model_bar_mass`` (so the 'mass' disturbances scale it); the values
  :data:`~.constants.LEADER_FOLLOWER`. Free, the baseline.
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import inspect
import os
import sys
import threading
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from ..._core import (ComputedTorque, Controller, CooperativeController, LeaderFollower, ObjectControl, Robot,
                     box_inertia, commandable_directions)
from . import scene
from .constants import LEADER_FOLLOWER, OBJECT_GAINS, OBJECT_IMPEDANCE, OMEGA

__all__ = ["CONTROLLERS", "Cooperative", "Phased", "computed_torque", "computed_torque_payload", "controller_factory",
           "cooperative",
           "leader_follower", "object_control", "object_impedance", "register_controller", "with_point_mass"]


@dataclasses.dataclass
class Phased:
    """Per-robot controllers by phase: `free` (one per robot) outside the dual hold, `held` during it."""

    free: Sequence[Controller]
    held: Sequence[Controller]


@dataclasses.dataclass
class Cooperative:
    """Per-robot controllers `free` (one per robot: outside the dual hold, and the robots' own controllers,
    standing aside, during it) and one cooperative `law` (a :class:`coopsim.CooperativeController`) driving
    both robots from the end of the grasp to the end of the place.

    What the law commands of the bar's sharing (the protocol of docs/carry.md, "What a cooperative law
    commands"; the report's ``commanded``, against which the scores measure it): `load_share`, SCARA #1's part
    of the bar's vertical load (0 .. 1), and `squeeze`, the internal force along the line between the welds
    (N, compression positive). Each given here is what the law commands; each None is read from the law's own
    attribute of that name when it has one (:class:`coopsim.ObjectControl` has both; a Python law may define
    them), else nothing is commanded: the lever rule's share, no squeeze."""

    free: Sequence[Controller]
    law: CooperativeController
    load_share: Optional[float] = None
    squeeze: Optional[float] = None


def _gains(i, plan=None):
    """Robot i's baseline gains (kp, kd) (n,): the pair's of the plan (the SCARAs' OMEGA without one)."""
    pair = getattr(plan, "pair", None)
    w = OMEGA[i] if pair is None else pair.omega[i]
    return w ** 2, 2.0 * w


def computed_torque(robots: Sequence[Robot], plan) -> List[Controller]:
    """The baseline: independent computed torque per arm (kp = omega^2, kd = 2 omega from the pair's gains,
    ``plan.pair.omega``: the SCARAs' :data:`~.constants.OMEGA`), each with the robot alone as its model."""
    return [ComputedTorque(*_gains(i, plan)) for i in range(len(robots))]


def with_point_mass(robot: Robot, link: int, point, mass: float) -> Robot:
    """A copy of `robot` whose link `link` (1..n) also carries a point mass `mass` (kg) at `point` (3,) m in
    that link's DH frame: the link's mass, centre of mass and inertia (about the new centre, DH axes) combined
    by the parallel-axis rule. Its dynamics are the numeric ones (the generated code is the bare robot's)."""
    n = robot.dof
    if not 1 <= link <= n:
        raise ValueError(f"link must be 1 .. {n}, got {link}")
    if not (mass >= 0.0 and np.isfinite(mass)):
        raise ValueError(f"mass must be finite and >= 0 kg, got {mass!r}")
    p = np.asarray(point, float)
    masses, com, inertia = robot.masses.copy(), robot.com_positions.copy(), robot.link_inertias.copy()
    k = link - 1
    m0, c0 = masses[k], com[k]
    m = m0 + mass
    c = (m0 * c0 + mass * p) / m

    def shift(mm, d):
        return mm * (d @ d * np.eye(3) - np.outer(d, d))

    inertia[k] = inertia[k] + shift(m0, c0 - c) + shift(mass, p - c)
    masses[k], com[k] = m, c
    return Robot.from_dh(robot.dh, com, masses, inertia, robot.joint_types,
                         friction=robot.friction_coefficients, q_limits=robot.q_limits, tau_limits=robot.tau_limits,
                         gravity=robot.gravity_acceleration, base_position=robot.base_position,
                         base_yaw=robot.base_yaw, tool=robot.tool, name=robot.name,
                         end_stop_frequency=robot.end_stop_frequency,
                         end_stop_damping_ratio=robot.end_stop_damping_ratio, boxes=robot.boxes, clamp=robot.clamp,
                         dimensions=robot.dimensions, armature=robot.armature, coulomb=robot.coulomb,
                         coulomb_width=robot.coulomb_width, base_orientation=robot.base_orientation)


def grip_point(robot: Robot, q, frame=None) -> np.ndarray:
    """The point midway between the clamp's pads' centres at q (where a weld holds), in the DH frame of the
    clamp's link: (3,) m. frame: that link's pose (4, 4) at q when the caller has it."""
    faces = robot.clamp_faces(q)
    mid = (faces[0, :3, 3] + faces[1, :3, 3]) / 2.0
    F = robot.frames(q)[robot.clamp.fixed_link] if frame is None else frame
    return np.linalg.solve(F, np.append(mid, 1.0))[:3]


def computed_torque_payload(robots: Sequence[Robot], plan) -> Phased:
    """Computed torque whose models carry the bar during the dual hold: free, the baseline; held, each
    robot's model with half of ``plan.model_bar_mass`` at its grip (:func:`with_point_mass` on the clamp's
    link, at the point between the pads of ``plan.q_grasp``)."""
    held = []
    for i, r in enumerate(robots):
        model = with_point_mass(r, r.clamp.fixed_link, grip_point(r, plan.q_grasp[i]), plan.model_bar_mass / 2.0)
        held.append(ComputedTorque(*_gains(i, plan), model=model))
    return Phased(free=computed_torque(robots, plan), held=held)


def check_options(fn: Callable, options: dict, what: str, skip: int = 2) -> None:
    """Unless `fn` takes every keyword of `options` (after its first `skip` parameters, robots and plan): a
    ValueError naming the unknown ones and those it takes (``fn(**options)`` would be a bare TypeError)."""
    try:
        params = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):  # no signature to read (a builtin): the call says what is wrong
        return
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return
    taken = [p.name for p in params[skip:] if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    unknown = sorted(set(options) - set(taken))
    if unknown:
        raise ValueError(f"unknown option(s) of {what}: {', '.join(unknown)} "
                         f"({'choose from ' + ', '.join(taken) if taken else 'it takes none'})")


def _declared(value, options: dict) -> Optional[float]:
    """A declared command (load_share or squeeze of :func:`cooperative`): None, a number, or a function of the
    law's options giving one."""
    if value is None:
        return None
    return float(value(**options) if callable(value) else value)


def cooperative(make_law: Callable[..., CooperativeController], load_share=None, squeeze=None
                ) -> Callable[..., Cooperative]:
    """A factory of :class:`Cooperative` controllers from ``make_law(robots, plan, **options)`` -> a
    :class:`coopsim.CooperativeController`: the law drives both arms during the dual hold, the baseline
    (:func:`computed_torque`) outside it. Its name is the law maker's.

    What the law commands, for a law that does not show it as its own ``load_share`` / ``squeeze`` attributes
    (the protocol of docs/carry.md, "What a cooperative law commands"): `load_share`, SCARA #1's part of the
    bar's vertical load (0 .. 1), and `squeeze` (N, compression positive), each None (read from the law, else
    none commanded), a number, or a function ``(**options) -> number`` of the law's options (a squeeze
    command that is an option of the law: ``squeeze=lambda squeeze=0.0, **_: squeeze``)."""

    if not callable(make_law):
        raise ValueError(f"make_law must be callable (robots, plan, **options) -> a CooperativeController, "
                         f"got {make_law!r}")
    for value, what, unit in ((load_share, "load_share", "SCARA #1's share"), (squeeze, "squeeze", "N")):
        if value is not None and not callable(value) and (isinstance(value, bool) or
                                                          not isinstance(value, (int, float, np.number))):
            raise ValueError(f"{what} must be None, a number ({unit}) or callable (**options) -> one, got {value!r}")

    def factory(robots: Sequence[Robot], plan, **options) -> Cooperative:
        check_options(make_law, options, f"the cooperative law {getattr(make_law, '__name__', '')!r}")
        law = make_law(robots, plan, **options)
        return Cooperative(free=computed_torque(robots, plan), law=law,
                           load_share=_declared(load_share, options),
                           squeeze=_declared(squeeze, options))

    factory.__name__ = getattr(make_law, "__name__", "cooperative")
    factory.__doc__ = make_law.__doc__
    return factory


def bar_model(plan):
    """The bar as the controllers' models take it: (mass kg, inertia (3, 3) kg m^2 about its centre in its own
    frame): ``plan.model_bar_mass`` and a solid box of that mass with the bar's size."""
    m = plan.model_bar_mass
    return m, np.asarray(box_inertia(m, *(2.0 * scene.BAR_HALF_EXTENTS)))


def _object_control_law(robots: Sequence[Robot], plan, *, load_share: float = 0.5, squeeze: float = 0.0,
                        **gains) -> ObjectControl:
    """Object-level control (:class:`coopsim.ObjectControl`) with the bar's model (:func:`bar_model`): SCARA
    #1 carries `load_share` of its weight, the clamps squeeze it with `squeeze` N (compression positive); gains
    (kp 1/s^2, kd 1/s, kp_force, ki_force 1/s, integral_limit N) default to :data:`~.constants.OBJECT_GAINS`, with
    the pair's own over them (``plan.pair.object_gains``: the UR5s' and Pandas' ki_force 0)."""
    return _object_law("object control", plan, load_share, squeeze, gains, None)


def _object_impedance_law(robots: Sequence[Robot], plan, *, load_share: float = 0.5, squeeze: float = 0.0,
                          **options) -> ObjectControl:
    """Object impedance: :func:`object control <_object_control_law>` whose bar yields to a push as a
    mass-spring-damper around its reference (:class:`coopsim.ObjectControl` with ``impedance``). Options: those of
    object control, and stiffness (N/m, N m/rad), damping (N s/m, N m s/rad), mass (kg, kg m^2) (scalars or (6,)
    over x, y, z, rx, ry, rz) and accel_filter (s), defaulting to :data:`~.constants.OBJECT_IMPEDANCE`."""
    return _object_law("object impedance", plan, load_share, squeeze, options, OBJECT_IMPEDANCE)


def _object_law(what, plan, load_share, squeeze, options, impedance) -> ObjectControl:
    """ObjectControl with the bar's model, OBJECT_GAINS updated from `options`, and with `impedance` (a dict of
    stiffness, damping, mass, accel_filter updated from `options`) or without (None)."""
    known = list(OBJECT_GAINS) + list(impedance or ())
    unknown = set(options) - set(known)
    if unknown:
        raise ValueError(f"unknown option(s) of {what}: {', '.join(sorted(unknown))} (choose from "
                         f"load_share, squeeze, {', '.join(known)})")
    m, inertia = bar_model(plan)
    pair_gains = getattr(getattr(plan, "pair", None), "object_gains", None) or {}
    gains = {**OBJECT_GAINS, **pair_gains, **{k: v for k, v in options.items() if k in OBJECT_GAINS}}
    if impedance is not None:
        o = {**impedance, **{k: v for k, v in options.items() if k in impedance}}
        gains.update(impedance=(o["stiffness"], o["damping"], o["mass"]), accel_filter=o["accel_filter"])
    return ObjectControl(m, inertia, load_share=load_share, squeeze=squeeze, **gains)


_object_control_law.__name__ = "object_control"
#: ``object``: :class:`coopsim.ObjectControl` during the dual hold (options: load_share, squeeze and the gains
#: of :data:`~.constants.OBJECT_GAINS`), the baseline outside it
object_control = cooperative(_object_control_law)
_object_impedance_law.__name__ = "object_impedance"
#: ``object-impedance``: :class:`coopsim.ObjectControl` with the bar's impedance
#: (:data:`~.constants.OBJECT_IMPEDANCE`) during the dual hold (options: those of ``object`` and of
#: OBJECT_IMPEDANCE), the baseline outside it
object_impedance = cooperative(_object_impedance_law)


def _leader_follower_law(robots: Sequence[Robot], plan, **options) -> LeaderFollower:
    """Leader-follower control (:class:`coopsim.LeaderFollower`): SCARA #1 leads on its reference, SCARA #2
    follows as an impedance around where the grips put it, less `follower_share` of the weight of the bar's
    model mass ``plan.model_bar_mass``. Options (stiffness N/m and N m/rad, damping N s/m and N m s/rad, mass kg
    and kg m^2: scalars or (4,) over x, y, z, yaw; kp 1/s^2, kd 1/s: the leader's; follower_share) default to
    :data:`~.constants.LEADER_FOLLOWER`."""
    unknown = set(options) - set(LEADER_FOLLOWER)
    if unknown:
        raise ValueError(f"unknown option(s) of leader-follower: {', '.join(sorted(unknown))} (choose from "
                         f"{', '.join(LEADER_FOLLOWER)})")
    o = {**LEADER_FOLLOWER, **options}
    directions = _common_directions(robots)
    k, d, m = (_per_direction(o.pop(key), directions) for key in ("stiffness", "damping", "mass"))
    return LeaderFollower(k, d, m, object_mass=plan.model_bar_mass, **o)


def _common_directions(robots: Sequence[Robot]) -> List[str]:
    """The task directions both robots command (:func:`coopsim.commandable_directions`), in the engine's order."""
    a, b = (set(commandable_directions(r)) for r in robots)
    return [x for x in commandable_directions(robots[0]) if x in b and x in a]


def _per_direction(value, directions: List[str]):
    """A value of LEADER_FOLLOWER's form, over x, y, z, yaw (the SCARAs' directions), as one per direction the
    robots command: the translations' for x, y, z, the yaw's for every rotation. A scalar, or values for exactly
    the directions commanded, stay as they are (the engine checks them)."""
    v = np.asarray(value, float)
    if v.ndim == 0 or v.shape != (4,) or len(directions) == 4:
        return value
    return np.array([v[3] if x in ("roll", "pitch", "yaw") else v["xyz".index(x)] for x in directions])


def _leader_share(*, follower_share: float = LEADER_FOLLOWER["follower_share"], **_) -> float:
    return 1.0 - follower_share


_leader_follower_law.__name__ = "leader_follower"
#: ``leader-follower``: :class:`coopsim.LeaderFollower` during the dual hold (options: those of
#: :data:`~.constants.LEADER_FOLLOWER`), the baseline outside it; it commands SCARA #1 1 - follower_share of the
#: bar's weight
leader_follower = cooperative(_leader_follower_law, _leader_share)

#: the controller factories by name (the command line's ``--controller``, ``run(controllers=NAME)``, sweeps)
CONTROLLERS: Dict[str, Callable] = {"ct": computed_torque, "ct-payload": computed_torque_payload,
                                    "object": object_control, "leader-follower": leader_follower,
                                    "object-impedance": object_impedance}


def register_controller(name: str, factory: Callable) -> None:
    """Adds `factory` to :data:`CONTROLLERS` as `name` (a new name: ValueError for one taken)."""
    if not isinstance(name, str) or not name or name != name.strip() or "," in name:
        raise ValueError(f"name must be a non-empty string without commas or surrounding spaces, got {name!r}")
    if name in CONTROLLERS:
        raise ValueError(f"a controller named {name!r} exists: choose another name")
    if not callable(factory):
        raise ValueError(f"factory must be callable (robots, plan, **options) -> controllers, got {factory!r}")
    CONTROLLERS[name] = factory


def controller_factory(spec: str) -> Callable:
    """The factory a controller's name stands for: a name of :data:`CONTROLLERS`, or ``"module:factory"``
    (``module`` imported from sys.path, ``factory`` an attribute of it, dotted for one inside a class or
    object) or ``"path/to/file.py:factory"`` (the file imported as a module of its own, once per path). The
    factory is called as the named ones are: ``factory(robots, plan, **options)``. ValueError, one line, for an
    unknown name, a module that does not import (with its error), or a factory it lacks or that is not
    callable."""
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"controllers must be a name ({', '.join(CONTROLLERS)}) or 'module:factory', got {spec!r}")
    if spec in CONTROLLERS:
        return CONTROLLERS[spec]
    if ":" not in spec:
        raise ValueError(f"unknown controller {spec!r}: choose from {', '.join(CONTROLLERS)} (or name a factory of "
                         f"your own as module:factory or path/to/file.py:factory)")
    return load_callable(spec, "controller", "(robots, plan, **options) -> controllers")


def load_callable(spec: str, what: str, call: str) -> Callable:
    """The callable ``"module:name"`` or ``"path/to/file.py:name"`` stands for (as :func:`controller_factory`
    finds a factory); ValueError naming `what` (e.g. 'controller') and what it is called as (`call`) for one
    that does not import, is missing or is not callable."""
    where, attr = (x.strip() for x in spec.rsplit(":", 1))
    if not where or not attr:
        raise ValueError(f"{what} {spec!r}: give it as module:factory or path/to/file.py:factory")
    try:
        module = _load_file(where) if where.endswith(".py") or os.sep in where or "/" in where \
            else importlib.import_module(where)
    except Exception as e:  # noqa: BLE001 - the module's own error, in one line
        raise ValueError(f"{what} {spec!r}: cannot import {where!r}: {type(e).__name__}: "
                         f"{str(e).splitlines()[0] if str(e) else ''}") from None
    obj = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"{what} {spec!r}: {where!r} has no {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ValueError(f"{what} {spec!r}: {attr!r} is not callable {call}, it is {type(obj).__name__}")
    return obj


def _load_file(path: str):
    """The module of a Python file (imported once per absolute path, kept in sys.modules under a name made
    from the path, so that what it defines pickles within this process)."""
    full = os.path.abspath(path)
    if not os.path.isfile(full):
        raise FileNotFoundError(f"no file {path!r}")
    name = "coopsim_user_" + os.path.splitext(os.path.basename(full))[0].replace("-", "_") + "_" + \
        hashlib.sha1(full.encode()).hexdigest()[:8]
    with _LOADING:            # a sweep's threads load it once
        if name in sys.modules:
            return sys.modules[name]
        spec = importlib.util.spec_from_file_location(name, full)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[name]
            raise
        return module


_LOADING = threading.Lock()
