"""Plots of simulation logs and trajectories (matplotlib).

Each function draws into new axes unless given some, and returns the
matplotlib Figure; nothing is shown or saved here.
"""
from __future__ import annotations

import numpy as np

__all__ = ["plot_log", "plot_trajectory", "plot_tool_path"]

_LOG_LABELS = {
    "q": ("position", "rad | m"),
    "qd": ("velocity", "rad/s | m/s"),
    "qdd": ("acceleration", "rad/s² | m/s²"),
    "tau": ("torque", "N m | N"),
    "error": ("tracking error", "rad | m"),
}


def plot_log(log, robot: int = 0, quantity: str = "q", joints=None, axes=None, title=None, joint_types=None,
             label=None, color=None, reference: bool = True):
    """Joints of one robot against time, one panel per joint.

    log: a SimulationLog (or one robot's RobotLog). quantity: 'q', 'qd'
    (drawn with the reference dashed), 'qdd', 'tau' or 'error'. joints:
    indices (from 0) to draw, default all. axes: a sequence of as many
    matplotlib Axes, default a new figure with one column of panels sharing
    the time axis; pass the axes of an earlier call (``fig.axes``) to
    overlay another run. label: this run's name in the legends (e.g. the
    controller), default none; color: its line colour (any matplotlib
    colour), default 'C0' with the reference in 'C1' (with a color, the
    reference is dashed in the same colour). reference: draw q_ref / qd_ref.
    Each panel is one joint, its y axis named with the joint and its unit:
    revolute joints θ1, ... in rad (rad/s, rad/s², N m), prismatic ones d3,
    ... in m (m/s, m/s², N). The joint types come from the log (a
    simulation's log carries its robot's ``joint_types``); joint_types
    (e.g. "RRPRRP") overrides them, and a log that has none (one read from
    CSV) names the joints q1, q2, ... "(rad or m)". Legends stand to the
    right of the panels, off the data; tick labels show whole values (no
    offset such as "+3e-1" hiding them).
    Returns the Figure.
    """
    import matplotlib.pyplot as plt  # matplotlib loads only to draw

    if quantity not in _LOG_LABELS:
        raise ValueError(f"quantity must be one of {sorted(_LOG_LABELS)}, got {quantity!r}")
    rlog = log.robots[robot] if hasattr(log, "robots") else log
    if joint_types is None:
        joint_types = getattr(rlog, "joint_types", None)
    t = rlog.t
    data = getattr(rlog, quantity)
    ref = {"q": rlog.q_ref, "qd": rlog.qd_ref}.get(quantity) if reference else None
    n = data.shape[1]
    joints = list(range(n)) if joints is None else [int(j) for j in joints]
    for j in joints:
        if not 0 <= j < n:
            raise ValueError(f"joints must be indices in [0, {n}), got {j}")
    if color is not None:
        from matplotlib.colors import is_color_like  # matplotlib loads only to draw

        if not is_color_like(color):
            raise ValueError(f"color must be a matplotlib colour, got {color!r}")
    new_figure = axes is None
    if new_figure:
        fig, axes = plt.subplots(len(joints), 1, sharex=True, squeeze=False,
                                 figsize=(7.0, 1.6 + 1.4 * len(joints)))
        axes = axes[:, 0]
    else:
        axes = list(np.ravel(axes))
        if len(axes) != len(joints):
            raise ValueError(f"axes must hold {len(joints)} Axes, one per joint, got {len(axes)}")
        fig = axes[0].figure
    name, unit = _LOG_LABELS[quantity]
    names, units = _joint_labels(n, joint_types)
    prefix = "" if label is None else f"{label}: "
    for ax, j in zip(axes, joints):
        shown = names[j] if joint_types is not None else f"{quantity}{j + 1}"
        ax.plot(t, data[:, j], "-", color=color or "C0", lw=1.4, label=f"{prefix}{shown}")
        if ref is not None:
            ax.plot(t, ref[:, j], "--", color=color or "C1", lw=1.2, label=f"{prefix}{shown} reference")
        if joint_types is None:
            per = {"q": "", "qd": "/s", "qdd": "/s²"}.get(quantity)
            ax.set_ylabel(f"{quantity}{j + 1} " + (f"(rad{per} or m{per})" if per is not None else
                                                   "(N m or N)" if quantity == "tau" else "(rad or m)"))
        else:
            ax.set_ylabel(f"{'' if quantity == 'q' else quantity + ' '}{names[j]} "
                          f"({unit.split(' | ')[0 if units[j] == 'rad' else 1]})")
        _plain_ticks(ax)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="x-small", borderaxespad=0.0)
    axes[-1].set_xlabel("t (s)")
    if new_figure or title is not None:
        fig.suptitle(title or f"{rlog.name}: {name}")
    if new_figure:
        fig.tight_layout()
    return fig


def _plain_ticks(ax, axis: str = "y") -> None:
    """Tick labels with their whole values: no offset ("+3e-1") and a ×10ⁿ factor only for tiny or huge values."""
    from matplotlib.ticker import ScalarFormatter  # matplotlib loads only to draw

    fmt = ScalarFormatter(useOffset=False, useMathText=True)
    fmt.set_powerlimits((-4, 5))
    (ax.yaxis if axis == "y" else ax.xaxis).set_major_formatter(fmt)


def _joint_labels(n, joint_types):
    if joint_types is None:
        return [f"q{j + 1}" for j in range(n)], [""] * n
    if len(joint_types) != n:
        raise ValueError(f"joint_types must have {n} letters, got {joint_types!r}")
    names = [("θ" if c in "Rr" else "d") + str(j + 1) for j, c in enumerate(joint_types)]
    return names, ["rad" if c in "Rr" else "m" for c in joint_types]


def _unit_label(units, joints, order: int) -> str:
    """'rad', 'm' or 'rad or m' (unknown types) with /s or /s² for derivative `order`."""
    per = "" if order == 0 else "/s" if order == 1 else "/s²"
    kinds = sorted({units[j] for j in joints}, key=lambda u: u != "rad")
    if kinds == [""]:
        return f"rad{per} or m{per}"
    return " | ".join(k + per for k in kinds)


def plot_trajectory(trajectory, robot=None, t=None, samples: int = 600, joints=None, axes=None, title=None,
                    knots: bool = True, margin: float = 0.0):
    """Position, velocity and acceleration of a joint trajectory against time.

    trajectory: a Reference, e.g. CubicTrajectory. robot: optional Robot (or
    a joint-type string such as 'RRPRRP') to name the joints θi / di and give
    units. t: (N,) times (s), default `samples` evenly spaced over the
    trajectory, extended by `margin` s on each side to show the held ends.
    joints: indices (from 0) to draw, default all. axes: three matplotlib
    Axes (q, qd, qdd), default a new figure. knots: mark the via-points of a
    CubicTrajectory. Revolute joints in rad, rad/s, rad/s² on the left y
    axes (solid), prismatic ones in m, m/s, m/s² on twin axes at the right
    (dashed), so that no axis mixes units; without joint types every joint
    shares one axis "(rad or m)". Returns the Figure (its axes: the three
    given or made, then the twins).
    """
    import matplotlib.pyplot as plt  # matplotlib loads only to draw

    n = trajectory.dof
    joint_types = robot if isinstance(robot, str) or robot is None else robot.joint_types
    names, units = _joint_labels(n, joint_types)
    joints = list(range(n)) if joints is None else [int(j) for j in joints]
    for j in joints:
        if not 0 <= j < n:
            raise ValueError(f"joints must be indices in [0, {n}), got {j}")
    if t is None:
        if int(samples) < 2:
            raise ValueError(f"samples must be >= 2, got {samples}")
        t = np.linspace(trajectory.t_start - margin, trajectory.t_end + margin, int(samples))
    t = np.asarray(t, dtype=float)
    q, qd, qdd = trajectory.evaluate(t)
    if axes is None:
        fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8.0, 8.0))
    else:
        axes = list(np.ravel(axes))
        if len(axes) != 3:
            raise ValueError(f"axes must hold 3 Axes (q, qd, qdd), got {len(axes)}")
        fig = axes[0].figure
    has_knots = knots and hasattr(trajectory, "q_points")
    # one kind of joint per y axis: revolute (rad) on the left, prismatic (m) on a twin axis at the right
    kinds = [[j for j in joints if units[j] == u] for u in ("rad", "m", "")]
    kinds = [g for g in kinds if g]
    handles = []
    for k, (ax, data, what) in enumerate(zip(axes, (q, qd, qdd), ("position", "velocity", "acceleration"))):
        for g, group in enumerate(kinds):
            gax = ax if g == 0 else ax.twinx()
            for j in group:
                c = f"C{joints.index(j) % 10}"
                unit = units[j] + ("" if k == 0 else "/s" if k == 1 else "/s²") if units[j] else ""
                line, = gax.plot(t, data[:, j], color=c, lw=1.4, ls="-" if g == 0 else "--",
                                 label=names[j] + (f" ({unit})" if unit else ""))
                if k == 0:
                    handles.append(line)
                if has_knots and k < 2:
                    pts = trajectory.q_points if k == 0 else trajectory.qd_points
                    gax.plot(trajectory.times, pts[:, j], "o", color=c, ms=3.5)
            side = "" if len(kinds) == 1 else (", solid" if g == 0 else ", dashed")
            gax.set_ylabel(f"{what} ({_unit_label(units, group, k)}{side})")
            _plain_ticks(gax)
        ax.grid(True, alpha=0.3)
    axes[0].legend(handles=handles, loc="lower left", bbox_to_anchor=(0.0, 1.02), ncol=min(len(handles), 6),
                   fontsize="small", borderaxespad=0.0)
    axes[-1].set_xlabel("t (s)")
    if has_knots:
        for ax in axes:
            for tk in trajectory.times:
                ax.axvline(tk, color="0.75", lw=0.6, zorder=0)
    fig.suptitle(title or f"joint trajectory: q, q̇, q̈ ({len(t)} samples)")
    fig.tight_layout()
    return fig


def plot_tool_path(robot, trajectory, poses=None, samples: int = 400, ax=None, label=None, color=None):
    """Top view (x, y) of the tool centre point along a joint trajectory.

    robot: the Robot whose fk gives the TCP; trajectory: a Reference for it.
    poses: optional (N, 4, 4) target poses, drawn as points joined by
    straight dashed lines (the intended path). ax: a matplotlib Axes, default
    a new figure. Returns the Figure.
    """
    import matplotlib.pyplot as plt  # matplotlib loads only to draw

    if int(samples) < 2:
        raise ValueError(f"samples must be >= 2, got {samples}")
    t = np.linspace(trajectory.t_start, trajectory.t_end, int(samples))
    q, _, _ = trajectory.evaluate(t)
    p = np.array([robot.fk(qi)[:3, 3] for qi in q])
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.0, 6.0))
    fig = ax.figure
    ax.plot(p[:, 0], p[:, 1], "-", lw=1.5, color=color, label=label or "tool path")
    if poses is not None:
        P = np.asarray(poses, dtype=float)
        ax.plot(P[:, 0, 3], P[:, 1, 3], "k--o", lw=0.8, ms=4, label="target poses")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig
