"""The dual carry: two arms (the two SCARAs by default; two UR5s, two Pandas or a pair of one's own with
``run(robots=...)``, :mod:`.pairs`) grasp one bar at two points, lift it together, carry it along a path in their
common workspace (a translation, a turn, a change of height), set it down on two other stands, let go and
back off.

The bar (the handover's: 0.35 x 0.02 x 0.02 m, 0.15 kg) lies on two stands; SCARA #1 grips it 0.10 m from
its centre on the +x side of the bar's own axis, #2 0.10 m on the other side. One planned path of the bar
(:class:`~.planning.BarPath`) gives both clamps' references (:func:`~.planning.make_plan`), so they agree on
the bar they carry; grasps and releases happen only through the clamp rule. The arms are driven by
controllers that a factory ``(robots, plan) -> controllers`` makes, chosen by name from
:data:`~.controllers.CONTROLLERS` (:mod:`.controllers`: the baseline ``ct``, independent computed torque;
``ct-payload``; ``object``, object-level control of both arms by one cooperative law while they hold the bar;
``leader-follower``, SCARA #1 leading and #2 following as an impedance; ``object-impedance``, object-level
control whose bar yields to a push as a mass-spring-damper);
the run (:func:`run`) fails naming its step (approach, grasp, lift, carry,
place, release, back off) and reason, and is scored from its log (:mod:`.scoring`): the bar's pose against
its planned path, the welds' wrenches and stretch (slip), the joint torques, tracking, clearances, the force
sensors, and what the clamps do to the bar together (squeeze, internal wrench, load share, relative pose error:
the log's cooperation columns). Disturbances (:mod:`.disturbances`): the bar's mass wrong in the controllers' models, a push on
the bar mid-carry, a clamp gripping 5 mm off its planned point, noisy force sensors; a seed shifts and turns
the start stands (:func:`~.planning.random_start`).

The modules: :mod:`.constants` (the values, checked in tests/test_carry.py), :mod:`.scene` (the World),
:mod:`.pairs` (the arms: 'scara', 'ur5', 'panda' or one's own, placed, with what the plan and the baseline need),
:mod:`.planning`, :mod:`.controllers`, :mod:`.disturbances`, :mod:`.sequence` (the run and its rules),
:mod:`.scoring`, :mod:`.report` (text, JSON, series and figures), :mod:`.runs` (sweeps: :func:`sweep_table`
over controllers x disturbances x seeds through :func:`coopsim.sweep`), :mod:`.statistics` (a sweep's means,
deviations and intervals: :func:`sweep_statistics`) and :mod:`.cli`.

Command line: ``python -m coopsim.tasks.carry --out out/carry`` (``--help`` for the options).
"""
from .constants import END, START  # noqa: F401
from .controllers import (CONTROLLERS, Cooperative, Phased, computed_torque, computed_torque_payload,  # noqa: F401
                          cooperative, leader_follower, object_control, object_impedance,
                          register_controller)
from .disturbances import DISTURBANCES, Disturbances  # noqa: F401
from .pairs import PAIRS, Pair, pair  # noqa: F401
from .planning import STEPS, BarPath, Plan, clearances, make_plan, random_start  # noqa: F401
from .report import report_figures, summary, write_outputs  # noqa: F401
from .runs import CarryRun, sweep, sweep_table
from .statistics import sweep_statistics  # noqa: F401
from .sequence import CarryError, CarryResult, run

__all__ = ["CONTROLLERS", "DISTURBANCES", "PAIRS", "STEPS", "CarryError", "CarryResult", "CarryRun", "Cooperative",
           "Disturbances", "Pair", "Phased", "clearances", "make_plan", "pair", "register_controller", "run", "sweep", "sweep_statistics",
           "sweep_table"]
