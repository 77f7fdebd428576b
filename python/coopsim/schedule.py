"""A task's sequence run by the engine in one call, with the GIL released: :meth:`coopsim.Simulation.run_schedule`.

A schedule is a list of :class:`Step`. Each step makes its changes to the run (its ``actions``:
:class:`SetController`, :class:`SetReference`, :class:`AddCooperative`, :class:`RemoveCooperative`,
:class:`SetBodyWrench`, :class:`Release`), then advances to ``until`` (s, the simulation's clock) in pieces of
``every`` s (0: one piece), checking after each piece, in order:

- the contacts that began since the last look, against ``allowed_contacts`` (when given): one not allowed
  fails the run (kind ``'contact'``);
- ``hold``: each :class:`Holding` true (else ``'hold'``: a clamp let go);
- ``record``: each :class:`Holding` recorded the first time it is true (its time, the robot's joints and the
  body's pose: :attr:`ScheduleResult.records`);
- ``wait``: all true ends the step early (checked at its start too); not all true by ``until`` fails it
  (``'wait'``: a timeout).

At the step's end its ``at_end`` conditions must hold (``'at_end'``). The pieces are those of
:meth:`~coopsim.Simulation.advance_until`: a sequence moved from Python, advancing piece by piece and checking
between pieces, into a schedule gives the same run, stopped at the same time.

A failure raises :class:`ScheduleError` (one line: the step, the time, the reason) with the run stopped where
it failed; an engine error while advancing (a :class:`~coopsim.DivergenceError`, ...) is raised as it is, with
``schedule_step`` (the step's name) set on it. A bad schedule is a ValueError naming the step and the action or
condition, before anything runs.

Example, a grasp awaited for at most 2 s, then a carry with a push, failing on any contact but the bar's with
the jaws::

    from coopsim.schedule import Step, Holding, SetBodyWrench
    sim.run_schedule([
        Step("grasp", until=sim.time + 2.0, every=0.001, wait=[Holding(0, "bar")]),
        Step("push", until=3.0, every=0.05, hold=[Holding(0, "bar")],
             actions=[SetBodyWrench("bar", [5, 0, 0, 0, 0, 0])]),
        Step("carry", until=5.0, every=0.05, hold=[Holding(0, "bar")], actions=[SetBodyWrench("bar", [0] * 6)]),
    ], allowed_contacts=[("bar", "*/fixed_jaw"), ("bar", "*/link6")])
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from . import _checks

__all__ = ["AddCooperative", "Holding", "Release", "RemoveCooperative", "ScheduleError", "ScheduleResult",
           "SetBodyWrench", "SetController", "SetReference", "Step"]


class ScheduleError(RuntimeError):
    """A schedule's run failed: ``step`` (its name), ``index`` (its position, 0-based), ``t`` (s; a contact's:
    when it began), ``kind`` ('contact', 'hold', 'wait', 'at_end'), ``condition`` (the condition's index in the
    step's list, -1 for a contact), ``bodies`` (a contact's two bodies), ``reason`` (one line), and ``result``
    (the :class:`ScheduleResult` up to the failure)."""

    def __init__(self, step: str, index: int, t: float, kind: str, reason: str, condition: int = -1,
                 bodies: Sequence[str] = (), result: Optional["ScheduleResult"] = None):
        super().__init__(f"{step} at t = {t:.4f} s: {reason}")
        self.step, self.index, self.t, self.kind, self.reason = step, index, float(t), kind, reason
        self.condition, self.bodies, self.result = condition, tuple(bodies), result


@dataclasses.dataclass(frozen=True)
class Holding:
    """Robot ``robot`` (index) holds the free body named ``body`` (None: holds nothing)."""
    robot: int
    body: Optional[str] = None


@dataclasses.dataclass(frozen=True)
class SetController:
    """Robot ``robot``'s controller replaced (:meth:`~coopsim.Simulation.set_controller`)."""
    robot: int
    controller: Any


@dataclasses.dataclass(frozen=True)
class SetReference:
    """Robot ``robot``'s reference replaced (:meth:`~coopsim.Simulation.set_reference`): a coopsim.Reference or
    a set-point (n,)."""
    robot: int
    reference: Any


@dataclasses.dataclass(frozen=True)
class AddCooperative:
    """A cooperative group: ``controller`` (a coopsim.CooperativeController) drives ``robots`` (indices)
    (:meth:`~coopsim.Simulation.add_cooperative`)."""
    controller: Any
    robots: Sequence[int]


@dataclasses.dataclass(frozen=True)
class RemoveCooperative:
    """Group ``group`` stops driving (None: the last group this schedule added)."""
    group: Optional[int] = None


@dataclasses.dataclass(frozen=True)
class SetBodyWrench:
    """The wrench (6,) on free body ``body`` (world force N, moment N m; zeros: removed)."""
    body: str
    wrench: Any


@dataclasses.dataclass(frozen=True)
class Release:
    """What robot ``robot`` holds is released now."""
    robot: int


@dataclasses.dataclass
class Step:
    """One step of a schedule (see the module's text): ``name`` (named in failures), ``until`` (s, the
    simulation's clock: where the step ends; a wait's timeout), ``every`` (s, the checks' pieces; 0: the step
    in one piece), ``actions`` (done at its start, in order) and the conditions ``hold``, ``wait``, ``at_end``
    and ``record`` (lists of :class:`Holding`)."""
    name: str
    until: float
    every: float = 0.0
    actions: Sequence[Any] = ()
    hold: Sequence[Holding] = ()
    wait: Sequence[Holding] = ()
    at_end: Sequence[Holding] = ()
    record: Sequence[Holding] = ()


class Record(NamedTuple):
    """A record condition come true: ``step`` (index), ``condition`` (its index in the step's ``record``), ``t``
    (s), ``q`` (the robot's joints then, (n,)), ``pose`` (the body's pose then, (4, 4); identity for nothing)."""
    step: int
    condition: int
    t: float
    q: np.ndarray
    pose: np.ndarray


@dataclasses.dataclass
class ScheduleResult:
    """What :meth:`~coopsim.Simulation.run_schedule` returns: ``times`` (each step reached: (start, end) s),
    ``groups`` (the index of each cooperative group added, in order), ``records`` (:class:`Record`),
    ``contacts_seen`` (the contact events looked at: the next schedule's ``contacts_seen``)."""
    times: List[Tuple[float, float]]
    groups: List[int]
    records: List[Record]
    contacts_seen: int


_ACTIONS = {SetController: ("set_controller", "robot", "controller"),
            SetReference: ("set_reference", "robot", "reference"),
            AddCooperative: ("add_cooperative", "controller", "robots"),
            RemoveCooperative: ("remove_cooperative", "group"),
            SetBodyWrench: ("set_body_wrench", "body", "wrench"),
            Release: ("release", "robot")}


def _where(k: int, step) -> str:
    return f"schedule step {k + 1} ({getattr(step, 'name', step)!r})"


def _conditions(items, where: str) -> list:
    out = []
    for j, c in enumerate(items):
        if not isinstance(c, Holding):
            raise ValueError(f"{where} condition {j + 1} must be a coopsim.schedule.Holding, got {c!r}")
        robot = c.robot
        _checks.integer(robot, f"{where} condition {j + 1}: robot", 0, 2 ** 31 - 1)
        if c.body is not None and not isinstance(c.body, str):
            raise ValueError(f"{where} condition {j + 1}: body must be a name or None, got {c.body!r}")
        out.append((int(robot), c.body))
    return out


def _time(x, what) -> float:
    """A step's time (s): a finite float as it is (the common case, without building the message), else checked."""
    return x if type(x) is float and math.isfinite(x) else _checks.number(x, what(), unit="s")


def plain(steps: Sequence[Step], allowed_contacts) -> tuple:
    """The engine's form of a schedule: (steps as tuples, the allowed contacts as (a, b, from, to)); ValueError
    naming the step and the item for what is not a step, an action or a condition."""
    if isinstance(steps, Step):
        steps = [steps]
    out = []
    for k, st in enumerate(steps):
        if not isinstance(st, Step):
            raise ValueError(f"{_where(k, st)} must be a coopsim.schedule.Step, got {type(st).__name__}")
        if not isinstance(st.name, str) or not st.name:
            raise ValueError(f"{_where(k, st)}: name must be a non-empty str")
        acts = []
        for j, a in enumerate(st.actions):
            spec = _ACTIONS.get(type(a))
            if spec is None:
                raise ValueError(f"{_where(k, st)}, action {j + 1}: not an action (SetController, SetReference, "
                                 f"AddCooperative, RemoveCooperative, SetBodyWrench, Release), got {a!r}")
            acts.append((spec[0],) + tuple(getattr(a, f) for f in spec[1:]))
        every = _time(st.every, lambda: f"{_where(k, st)}: every")
        if every < 0.0:
            _checks.positive(every, f"{_where(k, st)}: every", zero=True, unit="s")
        cond = [_conditions(c, f"{_where(k, st)}, {n}") if c else []
                for c, n in ((st.hold, "hold"), (st.wait, "wait"), (st.at_end, "at_end"), (st.record, "record"))]
        out.append((st.name, _time(st.until, lambda: f"{_where(k, st)}: until"), every, acts, *cond))
    rules = []
    for j, r in enumerate(allowed_contacts or ()):
        if type(r) is tuple and len(r) == 2 and type(r[0]) is str and type(r[1]) is str:
            rules.append((r[0], r[1], -math.inf, math.inf))       # the common case: two names or patterns
            continue
        r = tuple(r)
        if len(r) not in (2, 3, 4) or not all(isinstance(x, str) for x in r[:2]):
            raise ValueError(f"allowed contact {j + 1} must be (a, b) or (a, b, from, to) with body names or "
                             f"patterns ('name', 'prefix*', '*suffix', '*'), got {r!r}")
        lo = -math.inf if len(r) < 3 or r[2] is None else _checks.number(r[2], f"allowed contact {j + 1}: from", unit="s")
        hi = math.inf if len(r) < 4 or r[3] is None else _checks.number(r[3], f"allowed contact {j + 1}: to", unit="s")
        rules.append((r[0], r[1], lo, hi))
    return out, rules
