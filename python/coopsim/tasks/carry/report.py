"""The carry's outputs: a summary in text, the report as JSON, the figures (the bar's path against its plan,
the welds' forces and stretch, the joint torques, a few frames of the scene) and the animation."""
from __future__ import annotations

import os
from typing import Dict, List

import numpy as np

from ... import view
from ..handover.report import write_report
from . import scene
from .sequence import CarryResult

__all__ = ["report_figures", "summary", "write_outputs", "write_report"]


def summary(report: dict) -> str:
    """A few lines: the outcome (or the failed step, time and reason), then the scores."""
    d = report["disturbance"]
    what = ", ".join(d["names"]) or "none"
    lines = [f"dual carry, controller {report['controller']}, disturbance {what}"
             + (f", seed {report['seed']}" if report["seed"] is not None else "")]
    f = report["failure"]
    if f:
        lines.append(f"FAILED in {f['step']} at t = {f['t']:.3f} s: {f['reason']}")
    else:
        p = report["placed"]
        lines.append(f"success in {report['simulated_time']:.2f} s: the bar on the end stands "
                     f"{p['position_error'] * 1e3:.2f} mm and {p['angle_error'] * 1e3:.2f} mrad from its planned pose; "
                     f"the robots backed off to {min(report['backed_off']) * 1e3:.0f} mm from it")
    s = report.get("scores")
    if s:
        e, a = s["bar_position_error_mm"], s["bar_angle_error_mrad"]
        lines.append(f"  bar against its planned path while carried: {e['rms']:.2f} mm RMS, {e['max']:.2f} mm max; "
                     f"{a['rms']:.2f} mrad RMS, {a['max']:.2f} mrad max (dual hold {s['dual_hold']:.2f} s)")
        for x in s["robots"]:
            lines.append(f"  {x['robot']}: peak weld force {x['peak_weld_force']:.2f} N, moment "
                         f"{x['peak_weld_moment'] * 1e3:.1f} mN m; slip {x['max_slip_mm']:.2f} mm; peak torque "
                         f"{x['torque_limit_fraction'] * 100:.0f} % of its limit; tool error "
                         f"{x['tool_error_mm']['rms']:.2f} / {x['tool_error_mm']['max']:.2f} mm RMS / max; sensed "
                         f"force error {x['sensed_force_error']['rms']:.2f} N RMS")
        c = s.get("cooperation")
        if c:
            ls = c["load_share"]
            lines.append(f"  together while carried: squeeze {c['squeeze_N']['rms']:.3f} N RMS, {c['squeeze_N']['max']:.3f} N "
                         f"max (commanded {c['squeeze_commanded_N']:.2f} N); internal force {c['internal_force_N']['rms']:.3f} "
                         f"N RMS, {c['internal_force_N']['max']:.3f} N max; SCARA #1's load share {ls['mean']:.3f} "
                         f"(commanded {c['load_share_commanded']:.2f}, off by {ls['mean_abs_deviation']:.3f} on average); "
                         f"relative pose error {c['relative_position_error_mm']:.2f} mm, "
                         f"{c['relative_angle_error_mrad']:.2f} mrad max")
        if s["clearance_robots"]:
            lines.append(f"  min clearance robot-robot {s['clearance_robots']['min'] * 1e3:.0f} mm at t = "
                         f"{s['clearance_robots']['t']:.2f} s; {len(s['grasp_events'])} grasp events, "
                         f"{len(s['contact_events'])} contact events")
    return "\n".join(lines)


def report_figures(result: CarryResult) -> Dict[str, object]:
    """The figures of a scored run, {file name: matplotlib Figure}: ``bar_path.png`` (the bar's centre in plan
    view, its height and yaw over time, against the plan, and the pose errors), ``weld_forces.png`` (each
    weld's force and moment and its stretch over time), ``joint_torques.png`` (each robot's joint torques over
    time). Each panel's y axis names its quantity and unit; the steps are marked."""
    import matplotlib.pyplot as plt  # matplotlib's import is heavy: only when plotting

    s, rep = result.series, result.report
    if s is None:
        raise ValueError("the run was not scored (score_run=False): no series to plot")
    t, figs = s["t"], {}
    marks = [(v[0], k) for k, v in rep["planned_steps"].items()]

    def steps(ax):
        for t0, _ in marks[1:]:
            ax.axvline(t0, color="0.7", lw=0.7, ls=":")

    fig = plt.figure(figsize=(11, 7))
    ax = fig.add_subplot(2, 2, 1)
    ax.plot(s["bar_planned"][:, 0, 3], s["bar_planned"][:, 1, 3], "k--", lw=1, label="plan")
    ax.plot(s["bar"][:, 0, 3], s["bar"][:, 1, 3], color="C3", lw=1.5, label="bar")
    for name, he, T in scene.stands(rep["start"], rep["end"]):
        c = T[:2, 3]
        ax.plot(*c, "s", color="0.5", ms=5)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("the bar's centre in plan view (stands: grey)")
    ax.legend(fontsize="small")
    ax = fig.add_subplot(2, 2, 2)
    ax.plot(t, s["bar_planned"][:, 2, 3] * 1e3, "k--", lw=1, label="plan")
    ax.plot(t, s["bar"][:, 2, 3] * 1e3, color="C3", lw=1.2, label="bar")
    ax.set_ylabel("height of the centre (mm)")
    ax.legend(fontsize="small")
    steps(ax)
    ax = fig.add_subplot(2, 2, 3)
    yaw_p = np.degrees(np.unwrap(np.arctan2(s["bar_planned"][:, 1, 0], s["bar_planned"][:, 0, 0])))
    yaw = np.degrees(np.unwrap(np.arctan2(s["bar"][:, 1, 0], s["bar"][:, 0, 0])))
    ax.plot(t, yaw_p, "k--", lw=1, label="plan")
    ax.plot(t, yaw, color="C3", lw=1.2, label="bar")
    ax.set_ylabel("yaw (deg)")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize="small")
    steps(ax)
    ax = fig.add_subplot(2, 2, 4)
    ax.plot(t, s["position_error"] * 1e3, color="C0", label="position (mm)")
    ax.plot(t, s["angle_error"] * 1e3, color="C1", label="orientation (mrad)")
    ax.set_ylabel("bar pose error\n(mm, mrad)")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize="small")
    steps(ax)
    fig.suptitle("The bar against its planned path")
    fig.tight_layout()
    figs["bar_path.png"] = fig

    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    names = ("SCARA #1", "SCARA #2")
    for i in range(2):
        axes[0].plot(t, np.linalg.norm(s["weld"][:, i, :3], axis=1), label=names[i])
        axes[1].plot(t, np.linalg.norm(s["weld"][:, i, 3:], axis=1) * 1e3, label=names[i])
        axes[2].plot(t, s["weld_stretch"][:, i] * 1e3, label=names[i])
    axes[0].axhline(scene.BAR_MASS * 9.81 / 2, color="k", lw=0.7, ls="--", label="half the bar's weight")
    axes[0].set_ylabel("weld force (N)")
    axes[1].set_ylabel("weld moment\n(mN m)")
    axes[2].set_ylabel("weld stretch,\nslip (mm)")
    axes[2].set_xlabel("t (s)")
    for ax in axes:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
        steps(ax)
    fig.suptitle("The welds: raw wrenches on the bar (world axes, moment about each weld's point) and stretch")
    fig.tight_layout()
    figs["weld_forces.png"] = fig

    log = result.log
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    for i, rl in enumerate(log.robots):
        types = rl.joint_types or ""
        for col, kind, unit in ((0, "R", "N m"), (1, "P", "N")):
            ax = axes[i, col]
            for j, c in enumerate(types):
                if c == kind:
                    ax.plot(log.t, rl.tau[:, j], lw=1, label=f"joint {j + 1}")
            ax.set_ylabel(f"{names[i]}\n{'revolute' if kind == 'R' else 'prismatic'} torque ({unit})")
            ax.legend(fontsize="x-small", ncol=2)
            steps(ax)
    for ax in axes[1]:
        ax.set_xlabel("t (s)")
    fig.suptitle("Joint torques")
    fig.tight_layout()
    figs["joint_torques.png"] = fig
    figs["frames.png"] = frames_figure(result)
    return figs


def frames_figure(result: CarryResult, steps=("grasp", "carry", "place", "back off")):
    """A few frames of the run: the scene at the start of each of `steps` (robots, references as ghosts,
    stands, the bar at its logged pose), drawn with :func:`coopsim.view.draw`."""
    import matplotlib.pyplot as plt  # matplotlib loads only to draw

    log, rep = result.log, result.report
    robots = result.sim.robots
    bar = log.bodies[scene.BAR]
    stands = [view.Body(name, he, T, color="0.6", scenery=True) for name, he, T in scene.stands(rep["start"], rep["end"])]
    fig = plt.figure(figsize=(12, 3.6))
    for k, step in enumerate(steps):
        t = min(rep["planned_steps"][step][0] + 0.3, log.t[-1])
        row = int(np.clip(np.searchsorted(log.t, t), 0, len(log.t) - 1))
        brow = int(np.clip(np.searchsorted(bar.t, log.t[row]), 0, len(bar.t) - 1))
        ax = fig.add_subplot(1, len(steps), k + 1, projection="3d")
        held = [log.robots[i].holding[row] == scene.BAR for i in range(2)]
        view.draw(ax, robots, [rl.q[row] for rl in log.robots], reference=[rl.q_ref[row] for rl in log.robots],
                  holding=[all(held)] * 2, bodies=[view.Body("bar", scene.BAR_HALF_EXTENTS, bar.poses()[brow])] + stands,
                  world=False, names=False, triad=False, elev=30, azim=-60, zoom=1.6)
        ax.set_title(f"{step}, t = {log.t[row]:.2f} s", fontsize="small")
    fig.tight_layout()
    return fig


def write_outputs(result: CarryResult, out_dir, *, video: bool = True, speed: float = 1.0) -> List[str]:
    """Writes report.json, summary.txt, the figures (PNG) and, with `video`, carry.mp4 into out_dir (made if
    missing). Returns the paths."""
    import matplotlib.pyplot as plt  # matplotlib loads only to draw

    os.makedirs(out_dir, exist_ok=True)
    paths = [write_report(result.report, os.path.join(out_dir, "report.json"))]
    p = os.path.join(out_dir, "summary.txt")
    with open(p, "w", encoding="utf-8") as f:
        f.write(summary(result.report) + "\n")
    paths.append(p)
    if result.series is not None:
        for name, fig in report_figures(result).items():
            p = os.path.join(out_dir, name)
            fig.savefig(p, dpi=90)
            plt.close(fig)
            paths.append(p)
    if video:
        # the world's stands are drawn as its scenery, the bar at its logged poses
        anim = view.animate(result.sim, speed=speed, fps=20, path=os.path.join(out_dir, "carry.mp4"))
        paths.append(anim.path)
    return paths

