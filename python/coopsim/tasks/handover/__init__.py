"""The cooperative task (paper section 11.5, Figs. 17-18): two SCARAs hand a bar over and drop it into an
inclined container.

SCARA #2 picks a bar from the floor and carries it under SCARA #1's open clamp; #1 grasps it in the air
(both hold it), #2 lets go, #1 turns the bar onto the container's axis, inserts it, opens and backs
off; the bar slides down the tube by gravity. Both robots return and the next bar follows.

Python sequences the phases; every step runs in the engine. Each phase plans both robots' motions from
the state the previous phase left (the bar's pose in a clamp is measured after each grasp, so a grip
that settled a millimetre off is carried into the plan), installs them with
:meth:`Simulation.set_reference`, and advances the simulation with :meth:`Simulation.advance`; grasps
and releases happen only through the clamp rule (closing the jaws on the bar, opening them). Motions are the
existing closed-form IK and cubic joint trajectories (:func:`coopsim.planning.plan_cartesian` for the
straight tool lines).

A cycle fails, with its step, time and reason, on a forbidden contact (robot-robot, robot-container,
a robot's own links, or a bar touching anything but the jaws, the floor before pick-up, the container
and the floor after release), a grasp that does not happen, a release that does not happen, or a bar
that does not slide down the tube. The run stops at the first failure. :func:`run` returns a
:class:`TaskResult` whose ``report`` holds, per cycle: durations per step, tracking errors (joint and
tool), minimum clearances robot-robot and robot-container, peak weld forces, and over the dual hold the
engine's ``log.cooperation(0, 1)``: the peak squeeze along the line between the grips (N, > 0 pushing the
bar together), the peak internal force and moment, and the clamps' largest relative pose error since #1's
grasp (#1 grasps a bar #2 holds still, so its weld starts unstretched and #2 carries the bar as a
cantilever until it opens: no squeeze, but an internal shear, #1's lever-rule share, against two pins),
every contact and grasp event, and success or the step and reason.

Scene values: :mod:`coopsim.tasks.scene`. Planning values (m, rad, s) are the constants of
:mod:`~coopsim.tasks.handover.constants` (checked against the robots' kinematics in tests/test_task.py): the handover bar centre (0.25, 0.25, 0.20), yaw 285 deg, #1 gripping
0.075 m on one side of the centre and #2 0.125 m on the other; #2 picks the bar 0.125 m from its
centre with the tool centre point 0.015 m above the bar's centre; #1 inserts at a clamp pitch of
65 deg, arriving 0.10 m beside the axis, sliding onto it and pushing 0.20 m in, then backing off
0.06 m along its approach.

The package's modules, one per job: :mod:`.constants` (the planning values), :mod:`.planning` (where the
clamps go: grips, poses, inverse kinematics), :mod:`.sequence` (the phases of a cycle on the simulation and
the rules that fail it: :func:`run`), :mod:`.scoring` (the per-cycle scores from the log), :mod:`.report`
(the JSON report, the summary and the plots), :mod:`.runs` (the task as a sweep item, :class:`TaskRun`, and
over many seeds, :func:`sweep`) and :mod:`.cli` (the command line).

Command line: ``python -m coopsim.tasks.handover --out out/`` (``--help`` for the options).
"""
# the package's names, as the module it was: the constants, the planning helpers, the run and its outputs
from .constants import (  # noqa: F401
    BACK_OFF, BEFORE_MOUTH, BESIDE, BRANCH, CLEAR_ABOVE, CLOSE_SPEED, DEG, FIXED_GAP,
    GRASP_TIMEOUT, GRIP1, GRIP2, HANDOVER_CENTRE, HANDOVER_YAW, INSERT_BRANCH, INSERT_DEPTH, INSERT_PITCH,
    LINE_SPACING, OMEGA, OPEN, PICK_HEIGHT, REGION, RELEASE_FADE, RETREAT2, SLIDE_BACK, SLIDE_MIN, SQUEEZE, TIMES)
from .planning import _grip_down, bar_on_floor, default_bars, random_bar  # noqa: F401
from .report import _jsonable, plot_report, report_figures, summary, write_report  # noqa: F401
from .runs import TaskRun, sweep
from .scoring import clearances  # noqa: F401
from .sequence import TaskError, TaskResult, _Runner, run  # noqa: F401

__all__ = ["REGION", "TaskResult", "TaskError", "TaskRun", "default_bars", "random_bar", "run", "sweep"]
