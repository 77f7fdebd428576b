"""Plots of simulation logs and trajectories (matplotlib).

Each function draws into new axes unless given some, and returns the
matplotlib Figure; nothing is shown or saved here.
"""
from __future__ import annotations

import numpy as np

__all__ = ["plot_log"]

_LOG_LABELS = {
    "q": ("position", "rad | m"),
    "qd": ("velocity", "rad/s | m/s"),
    "qdd": ("acceleration", "rad/s² | m/s²"),
    "tau": ("torque", "N m | N"),
    "error": ("tracking error", "rad | m"),
}


def plot_log(log, robot: int = 0, quantity: str = "q", joints=None, axes=None, title=None):
    """Joints of one robot against time, one panel per joint.

    log: a SimulationLog (or one robot's RobotLog). quantity: 'q', 'qd'
    (drawn with the reference dashed), 'qdd', 'tau' or 'error'. joints:
    indices (from 0) to draw, default all. axes: a sequence of as many
    matplotlib Axes, default a new figure with one column of panels sharing
    the time axis. Revolute joints are in rad, prismatic ones in m.
    """
    import matplotlib.pyplot as plt

    if quantity not in _LOG_LABELS:
        raise ValueError(f"quantity must be one of {sorted(_LOG_LABELS)}, got {quantity!r}")
    rlog = log.robots[robot] if hasattr(log, "robots") else log
    t = rlog.t
    data = getattr(rlog, quantity)
    ref = {"q": rlog.q_ref, "qd": rlog.qd_ref}.get(quantity)
    n = data.shape[1]
    joints = list(range(n)) if joints is None else [int(j) for j in joints]
    for j in joints:
        if not 0 <= j < n:
            raise ValueError(f"joints must be indices in [0, {n}), got {j}")
    if axes is None:
        fig, axes = plt.subplots(len(joints), 1, sharex=True, squeeze=False,
                                 figsize=(7.0, 1.6 + 1.4 * len(joints)))
        axes = axes[:, 0]
    else:
        axes = list(np.ravel(axes))
        if len(axes) != len(joints):
            raise ValueError(f"axes must hold {len(joints)} Axes, one per joint, got {len(axes)}")
        fig = axes[0].figure
    name, unit = _LOG_LABELS[quantity]
    for ax, j in zip(axes, joints):
        ax.plot(t, data[:, j], "-", color="C0", lw=1.4, label=f"{quantity}{j + 1}")
        if ref is not None:
            ax.plot(t, ref[:, j], "--", color="C1", lw=1.2, label="reference")
        ax.set_ylabel(f"{quantity}{j + 1}")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(title or f"{rlog.name}: {name} ({unit})")
    fig.tight_layout()
    return fig
