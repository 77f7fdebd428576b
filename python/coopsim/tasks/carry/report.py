"""The carry's outputs: a summary in text, the report as JSON (stamped), the time series (the log and the
cooperation columns as CSV and Excel, or one table as .npz or Parquet), the figures (the bar's path against its
plan, the welds' forces and stretch, the joint torques, a few frames of the scene; PNG, SVG or PDF) and the
animation."""
from __future__ import annotations

import importlib.util
import os
from typing import Dict, List, Optional

import numpy as np

from ... import view
from ...log import _atomic_write, cooperation_schema
from ..handover.report import FIGURE_FORMATS, save_figures, write_report
from . import scene
from .sequence import CarryResult

__all__ = ["FIGURE_FORMATS", "SERIES_FORMATS", "cooperation_table", "report_figures", "series_table", "summary",
           "sweep_series_table", "write_outputs", "write_report", "write_table"]

#: the formats of one table of series (the command line's --series): NumPy's .npz (nothing to install) and
#: Parquet (pyarrow)
SERIES_FORMATS = ("npz", "parquet")

#: the components of the cooperation columns, by quantity (the columns are '<quantity>.<component>')
_COMPONENTS = {"centre": "xyz", "point_a": "xyz", "point_b": "xyz",
               "external": ("fx", "fy", "fz", "mx", "my", "mz"),
               "internal": ("fx_a", "fy_a", "fz_a", "mx_a", "my_a", "mz_a", "fx_b", "fy_b", "fz_b", "mx_b", "my_b",
                            "mz_b"),
               "bending": ("a", "b"), "load_share": ("a", "b"),
               "relative_pose_error": ("x", "y", "z", "rx", "ry", "rz")}


def summary(report: dict) -> str:
    """A few lines: the outcome (or the failed step, time and reason), then the scores."""
    d = report["disturbance"]
    what = ", ".join(d["names"]) or "none"
    pair = report.get("robots", "scara")
    lines = [f"dual carry{'' if pair == 'scara' else ' by the ' + pair + ' pair'}, controller {report['controller']}, "
             f"disturbance {what}"
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
            first = report.get("robot_names", ["SCARA #1"])[0]
            sq = c["squeeze_N"]
            f_int = c["internal_force_N"]
            lines.append(f"  together while carried: squeeze {sq['mean']:+.3f} N mean, {sq['rms']:.3f} N RMS, peak "
                         f"{sq['peak']:+.3f} N (compression > 0; commanded {c['squeeze_commanded_N']:+.2f} N); "
                         f"internal force {f_int['rms']:.3f} N RMS, {f_int['max']:.3f} N max; {first}'s load share "
                         f"{ls['mean']:.3f} (commanded {c['load_share_commanded']:.2f}, off by "
                         f"{ls['mean_abs_deviation']:.3f} on average); relative pose error "
                         f"{c['relative_position_error_mm']:.2f} mm, {c['relative_angle_error_mrad']:.2f} mrad max")
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
    names = tuple(result.report.get("robot_names", ("SCARA #1", "SCARA #2")))
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


def cooperation_table(log, a: int = 0, b: int = 1):
    """The log's cooperation columns of robots a and b (:meth:`coopsim.SimulationLog.cooperation`) as a pandas
    DataFrame, one row per log row: t (s), holding (1: both hold one body, else 0; the other columns are NaN
    then), then '<quantity>' or '<quantity>.<component>' in the order of :func:`coopsim.log.cooperation_schema`:
    centre.x .. z, point_a.*, point_b.* (m, world), external.fx .. mz (N, N m), internal.fx_a .. mz_b (N,
    N m), squeeze (N, compression > 0), twist (N m), bending.a, bending.b (N m), shear (N), load_share.a,
    load_share.b, relative_pose_error.x .. z (m), .rx .. rz (rad)."""
    import pandas as pd  # pandas loads only for tables

    co = log.cooperation(a, b)
    cols = {"t": np.asarray(co["t"], float), "holding": co["holding"].astype(np.int8)}
    for name, width, _ in cooperation_schema():
        if name == "body":
            continue
        x = np.asarray(co[name], float)
        if width == 1:
            cols[name] = x
        else:
            for k, c in enumerate(_COMPONENTS[name]):
                cols[f"{name}.{c}"] = x[:, k]
    return pd.DataFrame(cols)


def series_table(result: CarryResult):
    """The run's time series as one pandas DataFrame, one row per log row: the log's columns
    (:meth:`coopsim.SimulationLog.to_dataframe`: t, each robot's joints' quantities, the bar's pose and twist)
    then its cooperation columns (:func:`cooperation_table`, without its t); for a scored run also the carry's
    own per row: bar.position_error (m) and bar.angle_error (rad) against its planned path, weld_stretch.a and
    .b (m), carried, pair and airborne (1 or 0: the rows of the scores, docs/carry.md)."""
    import pandas as pd  # pandas loads only for tables

    parts = [result.log.to_dataframe(), cooperation_table(result.log).drop(columns="t")]
    s = result.series
    if s is not None:
        parts.append(pd.DataFrame({"bar.position_error": s["position_error"], "bar.angle_error": s["angle_error"],
                                   "weld_stretch.a": s["weld_stretch"][:, 0], "weld_stretch.b": s["weld_stretch"][:, 1],
                                   "carried": s["carried"].astype(np.int8), "pair": s["pair"].astype(np.int8),
                                   "airborne": s["airborne"].astype(np.int8)}))
    return pd.concat(parts, axis=1)


def sweep_series_table(table):
    """One table of a sweep's time series (:func:`~.runs.sweep_table` with ``keep_logs=True``): per run that
    has a log, its rows with the columns controller, disturbance, seed, then the log's columns and its
    cooperation columns (:func:`series_table` without the carry's scores). Runs whose robots' joints differ
    would not share columns: all runs of the carry have the same robots."""
    import pandas as pd  # pandas loads only for tables

    if "log" not in table:
        raise ValueError("table must hold the runs' logs: sweep_table(..., keep_logs=True)")
    parts = []
    for r in table.itertuples():
        if r.log is None or not hasattr(r.log, "to_dataframe"):
            continue
        df = pd.concat([r.log.to_dataframe(), cooperation_table(r.log).drop(columns="t")], axis=1)
        df.insert(0, "seed", int(r.seed))
        df.insert(0, "disturbance", str(r.disturbance))
        df.insert(0, "controller", str(r.controller))
        parts.append(df)
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=["controller", "disturbance", "seed"])


def parquet_missing() -> Optional[str]:
    """None when Parquet can be written here (pyarrow imports), else one line saying what to install."""
    if importlib.util.find_spec("pyarrow") is None:
        return "Parquet needs pyarrow, which is not installed: pip install pyarrow (or use npz, which needs nothing)"
    return None


def write_table(df, path, fmt: str) -> str:
    """Writes a DataFrame as one file, atomically: 'npz' (NumPy's compressed archive, one array per column in
    the table's order, text columns as str arrays: ``pandas.DataFrame(dict(numpy.load(path)))`` reads it back)
    or 'parquet' (needs pyarrow: ValueError saying so without it). Returns the path."""
    if fmt not in SERIES_FORMATS:
        raise ValueError(f"fmt must be one of {', '.join(SERIES_FORMATS)}, got {fmt!r}")
    if fmt == "parquet":
        missing = parquet_missing()
        if missing:
            raise ValueError(missing)

        def write(tmp):
            df.to_parquet(tmp, index=False, engine="pyarrow")
    else:
        arrays = {str(c): (df[c].to_numpy(dtype=str) if df[c].dtype == object or str(df[c].dtype) in ("str", "string")
                           else df[c].to_numpy()) for c in df.columns}

        def write(tmp):
            with open(tmp, "wb") as f:          # a file object: savez adds no .npz to the temporary name
                np.savez_compressed(f, **arrays)
    return _atomic_write(path, "." + fmt, write)


def write_outputs(result: CarryResult, out_dir, *, video: bool = True, speed: float = 1.0, fmt: str = "png",
                  series: Optional[str] = None, arguments: Optional[dict] = None) -> List[str]:
    """Writes into out_dir (made if missing): report.json (stamped with `arguments`, every argument of the
    command line or call: :func:`~coopsim.tasks.handover.report.write_report`), summary.txt, the time series
    as the handover writes them (the log as carry.csv and carry.xlsx, :meth:`coopsim.SimulationLog.to_csv`
    and ``to_excel``; the cooperation columns with the carry's own series as cooperation.csv and
    cooperation.xlsx: :func:`series_table`'s columns past the log's), with `series` ('npz' or 'parquet') also
    all of them as one table series.npz or series.parquet (:func:`write_table`), the figures as `fmt` (png,
    svg or pdf) and, with `video`, carry.mp4. Returns the paths."""
    if fmt not in FIGURE_FORMATS:
        raise ValueError(f"fmt must be one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    if series is not None and series not in SERIES_FORMATS:
        raise ValueError(f"series must be None or one of {', '.join(SERIES_FORMATS)}, got {series!r}")
    os.makedirs(out_dir, exist_ok=True)
    paths = [write_report(result.report, os.path.join(out_dir, "report.json"), arguments=arguments)]
    p = os.path.join(out_dir, "summary.txt")
    with open(p, "w", encoding="utf-8") as f:
        f.write(summary(result.report) + "\n")
    paths.append(p)
    paths += [result.log.to_csv(os.path.join(out_dir, "carry.csv")),
              result.log.to_excel(os.path.join(out_dir, "carry.xlsx"))]
    table = series_table(result)
    together = table[["t"] + list(table.columns[len(result.log.columns()):])]
    paths.append(_atomic_write(os.path.join(out_dir, "cooperation.csv"), ".csv",
                               lambda tmp: together.to_csv(tmp, index=False, float_format="%.17g")))
    paths.append(_atomic_write(os.path.join(out_dir, "cooperation.xlsx"), ".xlsx",
                               lambda tmp: together.to_excel(tmp, index=False, sheet_name="cooperation",
                                                             engine="xlsxwriter")))
    if series is not None:
        paths.append(write_table(table, os.path.join(out_dir, "series." + series), series))
    if result.series is not None:
        paths += save_figures(report_figures(result), out_dir, fmt)
    if video:
        # the world's stands are drawn as its scenery, the bar at its logged poses
        anim = view.animate(result.sim, speed=speed, fps=20, path=os.path.join(out_dir, "carry.mp4"))
        paths.append(anim.path)
    return paths

