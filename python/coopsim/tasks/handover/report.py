"""The task's outputs: the report as JSON, a summary of a few lines per cycle, and the plots of a run."""
from __future__ import annotations

import json
import os
from typing import List, Optional

import numpy as np

from ...log import _atomic_write
from ... import view
from ...stamp import stamp
from ...plotting import plot_log
from .sequence import TaskResult
from .summary import summary  # noqa: F401  (the summary, here beside the other outputs)


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


#: the figures' file formats (the command lines' --format)
FIGURE_FORMATS = ("png", "svg", "pdf")


def write_report(report: dict, path, *, arguments: Optional[dict] = None, seed=None) -> str:
    """The report as JSON, written atomically (a temporary file renamed into place), with its ``stamp``
    (:func:`coopsim.stamp.stamp`: coopsim's version, the git commit, the build, Python, numpy, the machine,
    `seed` (default the report's own ``seed``) and `arguments`, every argument of the command line or call);
    the handover's, the carry's and the sweeps' reports are all written here. Returns the path."""
    out = dict(report)
    out["stamp"] = stamp(seed=report.get("seed") if seed is None else seed, arguments=arguments)

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(_jsonable(out), f, indent=1)

    return _atomic_write(path, ".json", write)


def save_figures(figs: dict, out_dir, fmt: str = "png", dpi: int = 90) -> List[str]:
    """Saves figures {name.png: Figure} into out_dir as `fmt` (png, svg or pdf: the name's suffix replaced),
    closing each; returns the paths."""
    import matplotlib.pyplot as plt  # matplotlib loads only to draw

    if fmt not in FIGURE_FORMATS:
        raise ValueError(f"fmt must be one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    os.makedirs(out_dir, exist_ok=True)
    paths = []
    for name, fig in figs.items():
        p = os.path.join(out_dir, os.path.splitext(name)[0] + "." + fmt)
        fig.savefig(p, dpi=dpi, format=fmt)
        plt.close(fig)
        paths.append(p)
    return paths


def step_markers(report: dict) -> List[tuple]:
    """The task's steps as (t, label) pairs (s, text), for a replay's timeline
    (:func:`coopsim.view.replay_html`'s markers): each step's start per cycle, and a failure where it happened."""
    out = []
    for c in report["cycles"]:
        for step, (t_begin, _) in (c.get("steps") or {}).items():
            out.append((float(t_begin), f"cycle {c['cycle']} ({c['bar']}): {step}"))
        if not c["success"]:
            out.append((float(c["failed_at"]), f"cycle {c['cycle']} ({c['bar']}) FAILED in {c['failed_step']}: "
                                                 f"{c['reason']}"))
    return sorted(out, key=lambda m: m[0])


def report_figures(result: TaskResult) -> dict:
    """The figures of a run's report, {file name: matplotlib Figure}: the joints with their references (one
    per robot, ``joints_<robot>.png``), the tracking errors (``tracking.png``) and the clearances with the
    grasp forces with the dual hold's internal force, squeeze and the clamps' relative position error
    (``clearance_forces.png``), all over time; and the scene halfway through the first insertion
    (``insertion.png``, :func:`insertion_figure`). Every y axis names its quantity and unit, one
    unit per axis (revolute joints in rad, prismatic ones in m); legends stand beside the panels."""
    import matplotlib.pyplot as plt  # matplotlib's import is heavy: only when plotting

    log, series, figs = result.log, result.series, {}
    for i, rl in enumerate(log.robots):
        fig, axes = plt.subplots(rl.dof, 1, figsize=(10, 1.6 * rl.dof), sharex=True)
        plot_log(log, robot=i, quantity="q", axes=axes, title=f"{rl.name}: joints (solid) and references (dashed)")
        fig.tight_layout()
        figs[f"joints_{rl.name}.png"] = fig
    cycles = [(c["t_start"], c.get("t_end", c["t_start"])) for c in result.report["cycles"]]

    def finish(fig, axes, title, name):
        """Legends beside the panels, the cycles' bounds and a title on a figure of panels over time."""
        for ax in axes:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize="small")
            for t0, _ in cycles[1:]:
                ax.axvline(t0, color="0.6", lw=0.8, ls=":")
        fig.suptitle(title)
        fig.tight_layout()
        figs[name] = fig

    fig, axes = plt.subplots(3, 1, figsize=(10, 6.5), sharex=True)
    for i, rl in enumerate(log.robots):
        axes[0].plot(series["t"], series["tool_error"][:, i] * 1e3, label=rl.name)
        types = rl.joint_types or ""
        for ax, kind in ((axes[1], "R"), (axes[2], "P")):
            cols = [j for j, c in enumerate(types) if c == kind]
            if cols:
                ax.plot(log.t, np.abs(rl.error[:, cols]).max(axis=1), label=rl.name)
    axes[0].set_ylabel("tool position\nerror (mm)")
    axes[1].set_ylabel("largest revolute\njoint error (rad)")
    axes[2].set_ylabel("largest prismatic\njoint error (m)")
    axes[2].set_xlabel("t (s)")
    finish(fig, axes, "Tracking errors", "tracking.png")

    scene = insertion_figure(result)
    if scene is not None:
        figs["insertion.png"] = scene

    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
    axes[0].plot(series["t"], series["clearance_robots"] * 1e3, label="robot - robot")
    axes[0].plot(series["t"], series["clearance_container"] * 1e3, label="robot - container")
    axes[0].set_ylabel("clearance (mm)")
    axes[0].set_ylim(0, 300)
    for i, rl in enumerate(log.robots):
        axes[1].plot(series["t"], series["weld_force"][:, i], label=f"weld force, {rl.name}")
    # the dual hold's internal force (NaN elsewhere: drawn only while both hold the bar)
    axes[1].plot(series["t"], series["internal_force"], label="internal force |f_int|\n(dual hold)", color="k", lw=1)
    axes[1].plot(series["t"], series["squeeze"], label="squeeze (dual hold;\n> 0 pushing together)", color="k",
                 lw=1, ls="--")
    axes[1].set_ylabel("force (N)")
    error = np.linalg.norm(series["relative_pose_error"][:, :3], axis=1) * 1e3
    axes[2].plot(series["t"], error, label="clamps' relative\nposition error\n(dual hold)", color="k", lw=1)
    axes[2].set_ylabel("position error (mm)")
    axes[2].set_xlabel("t (s)")
    finish(fig, axes, "Clearances and grasp forces", "clearance_forces.png")
    return figs


def insertion_figure(result: TaskResult):
    """The scene in 3D halfway through the first cycle's insertion (``insertion.png``): the container seen
    from its side, its slope written over it, and an inset zoomed on the bar in SCARA #1's clamp. None for a
    run that never reached an insertion."""
    steps = [c.get("steps") or {} for c in result.report["cycles"]]
    span = next((s["insert"] for s in steps if s.get("insert") and s["insert"][1] is not None), None)
    if span is None:
        return None
    t = 0.5 * (span[0] + span[1])
    anim = view.animate(result.sim, t_start=t, t_end=t, inset=True, figsize=(8.0, 6.0),
                        label=lambda _: f"t = {t:.2f} s: the first bar going into the container")
    anim.show_frame(0)
    return anim.fig


def plot_report(result: TaskResult, out_dir, fmt: str = "png") -> List[str]:
    """The plots of a run into out_dir (:func:`report_figures`) as `fmt` (png, svg or pdf). Returns the paths."""
    return save_figures(report_figures(result), out_dir, fmt)

