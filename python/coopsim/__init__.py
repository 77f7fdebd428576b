"""coopsim: simulation and control of serial manipulators, alone and cooperating.

The engine is C++ (Eigen, Bullet) in the compiled module ``coopsim._core``;
this package re-exports it and adds robot definitions, planning, plotting,
views, and the cooperative task (:mod:`coopsim.tasks.handover`). SI units and radians throughout; arrays are numpy float64.
"""
from . import _core
from ._arguments import install as _install_short_type_errors
from ._core import (
    Clamp,
    CubicTrajectory,
    IKError,
    InertiaWarning,
    LinearModel,
    LinkBox,
    Reference,
    Robot,
    SetPoint,
    StateFeedback,
    Tool,
    World,
    Wrench,
    box_clearances,
    box_distance,
    box_distances,
    shape_clearances,
    shape_distance,
    box_inertia,
    cooperation_wrenches,
    dh_transform,
    euler_step,
    forward_dynamics_batch,
    forward_dynamics_derivatives_batch,
    integrate,
    linearize,
    rk4_step,
)
from . import analysis, grasp, robots
from .urdf import from_urdf, to_urdf
from .mjcf import from_mjcf
from .planning import clamp_pose, plan_cartesian
from .simulation import ComputedTorque, Controller, DivergenceError, PID, Simulation, SimulationBusyError, gil_released_seconds
from ._core import (
    CooperativeController,
    CoopMember,
    LeaderFollower,
    ObjectControl,
    TASK_AXES,
    HybridForce,
    Impedance,
    Payload,
    TaskController,
    TaskState,
    commandable_directions,
    task_axes,
)
from .log import BodyLog, RobotLog, SimulationLog
from .pacing import Pacer, RunStats
from .batch import run_batch, simulate
from . import sweeps
from .sweeps import sweep
from .tasks import TaskRun
from .hold_model import HoldModel, linearize_hold  # noqa: E402  two arms holding one body, linearised
from . import view

Robot.to_urdf = to_urdf
Robot.from_urdf = staticmethod(from_urdf)
Robot.from_mjcf = staticmethod(from_mjcf)
# a wrong argument type in any compiled call: one short TypeError naming the argument (coopsim._arguments)
_install_short_type_errors(_core)


def build_info() -> dict:
    """How the compiled engine was built: optimised (bool; timings count only from an optimised build) and
    sanitizers (str: the sanitizers compiled in, e.g. 'address,undefined'; '' for none)."""
    return {"optimised": bool(_core.build_optimised), "sanitizers": str(_core.build_sanitizers)}


__version__ = "0.1.0"

__all__ = [
    "Clamp",
    "CubicTrajectory",
    "IKError",
    "InertiaWarning",
    "LinearModel",
    "LinkBox",
    "Reference",
    "Robot",
    "SetPoint",
    "StateFeedback",
    "Tool",
    "World",
    "Wrench",
    "box_clearances",
    "box_distance",
    "box_distances",
    "shape_clearances",
    "shape_distance",
    "box_inertia",
    "build_info",
    "cooperation_wrenches",
    "clamp_pose",
    "plan_cartesian",
    "planning",
    "dh_transform",
    "euler_step",
    "forward_dynamics_batch",
    "forward_dynamics_derivatives_batch",
    "integrate",
    "linearize",
    "rk4_step",
    "analysis",
    "grasp",
    "robots",
    "from_urdf",
    "from_mjcf",
    "to_urdf",
    "view",
    "CooperativeController", "CoopMember", "LeaderFollower", "ObjectControl",
    "TASK_AXES", "HybridForce", "Impedance", "Payload", "TaskController", "TaskState", "commandable_directions", "task_axes",  # noqa: E501
    "BodyLog", "ComputedTorque", "Controller", "DivergenceError", "PID", "Pacer", "RobotLog", "RunStats", "Simulation", "SimulationBusyError", "SimulationLog", "gil_released_seconds", "run_batch", "simulate",  # noqa: E501
    "sweep", "sweeps", "TaskRun", "HoldModel", "linearize_hold",
]
