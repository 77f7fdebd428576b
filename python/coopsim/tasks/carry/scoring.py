"""The scores of a carry, from its log: the bar's pose against its planned path, the welds' wrenches and
stretch (slip), the joint torques, tracking, clearances, the force sensors against the welds, what the two
clamps do to the bar together (the engine's cooperation columns: squeeze, internal wrench, load share,
relative pose error) and every grasp and contact event."""
from __future__ import annotations

import math
from typing import List

import numpy as np

from ..._core import shape_clearances
from . import scene


def _angles(R) -> np.ndarray:
    """Rotation angles (N,) rad of rotations (N, 3, 3)."""
    return np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))


def _rms(x) -> float:
    """The root mean square of x, as np.sqrt(np.mean(np.square(x))) computes it (0 for none)."""
    return math.sqrt(np.add.reduce(x * x) / len(x)) if len(x) else 0.0


def _max(x) -> float:
    return float(x.max()) if len(x) else 0.0


def _norms(x) -> np.ndarray:
    """The rows' Euclidean norms of x (rows, k), as np.linalg.norm(x, axis=1) computes them."""
    return np.sqrt(np.add.reduce(x * x, axis=1))


def _peak(x) -> float:
    """The value of largest magnitude, with its sign (0 for none)."""
    return float(x[np.argmax(np.abs(x))]) if len(x) else 0.0


def clamp_link_frames(robot, q) -> np.ndarray:
    """The world poses (rows, 4, 4) of the clamp's link (the fixed jaw's) at joint positions q (rows, n): its DH
    frame, the robot's frames computed for all rows in one engine call."""
    return robot.frames(np.asarray(q, float))[:, robot.clamp.fixed_link]


def weld_stretch(robot, q, bar_poses, anchor, frames=None, points: bool = False):
    """The weld's stretch (m) per row: the distance between its point carried by the clamp's link (at joint
    positions q (rows, n)) and carried by the bar (poses (rows, 4, 4)); anchor: the point in both
    (``{'link': (3,), 'body': (3,)}``, recorded at the grasp). The clamp rule lets go beyond 5 mm. frames: the
    clamp's link frames at q when the caller has them (:func:`clamp_link_frames`). points: also return the
    point carried by the link, (rows, 3) m (world)."""
    F = clamp_link_frames(robot, q) if frames is None else frames
    by_link = F[:, :3, :3] @ anchor["link"] + F[:, :3, 3]
    by_body = bar_poses[:, :3, :3] @ anchor["body"] + bar_poses[:, :3, 3]
    stretch = _norms(by_link - by_body)
    return (stretch, by_link) if points else stretch


def score(runner, report: dict, log=None) -> dict:
    """Adds report['scores'] from the run's log and returns the series behind the figures (numpy arrays over the
    log's rows): t, bar_planned (rows, 4, 4), bar (rows, 4, 4), position_error (m), angle_error (rad),
    weld (rows, 2, 6) N and N m, weld_stretch (rows, 2) m, tau (2 lists of (rows, n)), holding (rows, 2) bool,
    clearance_robots (m), cooperation (the log's cooperation columns of the two robots), pair (rows) bool (both
    carry the bar: the rows of the cooperation scores), airborne (rows) bool (and it touches no stand). log: the
    run's log when the caller has it (else read)."""
    log = runner.sim.log if log is None else log
    plan, robots = runner.plan, runner.robots
    t = log.t
    body = log.bodies[scene.BAR]
    bar = body.poses() if len(body.t) == len(t) else _resample(body, t)
    planned = plan.bar.pose(t)
    pos_err = _norms(bar[:, :3, 3] - planned[:, :3, 3])
    ang_err = _angles(np.swapaxes(planned[:, :3, :3], 1, 2) @ bar[:, :3, :3])
    holding = np.column_stack([rl.holding == scene.BAR for rl in log.robots])
    both = holding.all(axis=1)
    carried = both & (t >= plan.steps["lift"][0]) & (t <= plan.steps["place"][1])
    weld = np.stack([rl.weld for rl in log.robots], axis=1)
    stretch = np.zeros((len(t), 2))
    weld_points = np.full((len(t), 2, 3), np.nan)   # each weld's point carried by its clamp, where it holds
    for i, (r, rl) in enumerate(zip(robots, log.robots)):
        a = runner.anchors[i]
        if a is not None and holding[:, i].any():
            rows = np.flatnonzero(holding[:, i])
            q = rl.q[rows]
            stretch[rows, i], weld_points[rows, i] = weld_stretch(r, q, bar[rows], a, clamp_link_frames(r, q), True)
    shapes = [r.shapes(rl.q) for r, rl in zip(robots, log.robots)]
    d_rr = shape_clearances(shapes[0][0], list(robots[0].boxes), shapes[1][0], list(robots[1].boxes))[0]
    # the tool's tracking error with the jaw where it is (closed on the bar the jaw stops at the bar's width,
    # short of its squeezing reference, and the tool centre point midway between the jaws would count that)
    tcp_err = np.column_stack([_norms(r.fk(rl.q)[:, :3, 3] - r.fk(_jaw_as(rl.q_ref, rl.q))[:, :3, 3])
                               for r, rl in zip(robots, log.robots)])
    s = dict(
        # the bar against its planned path while both clamps carry it (lift, carry, place)
        bar_position_error_mm=dict(rms=_rms(pos_err[carried]) * 1e3, max=_max(pos_err[carried]) * 1e3),
        bar_angle_error_mrad=dict(rms=_rms(ang_err[carried]) * 1e3, max=_max(ang_err[carried]) * 1e3),
        dual_hold=float(both.sum() * (t[1] - t[0])) if len(t) > 1 else 0.0,
        robots=[])
    for i, (r, rl) in enumerate(zip(robots, log.robots)):
        h = holding[:, i]
        tau = np.abs(rl.tau)
        sensed = _norms(rl.ft_world[h, :3] - weld[h, i, :3])
        s["robots"].append(dict(
            robot=runner.names[i],
            # the raw weld wrench on the bar, world axes, moment about the weld's point
            peak_weld_force=_max(_norms(weld[h, i, :3])),
            peak_weld_moment=_max(_norms(weld[h, i, 3:])),
            max_slip_mm=_max(stretch[h, i]) * 1e3,
            peak_torque=tau.max(axis=0).tolist(),
            peak_torque_held=(tau[both].max(axis=0) if both.any() else np.zeros(r.dof)).tolist(),
            torque_limit_fraction=float((tau / r.tau_limits).max()),
            tool_error_mm=dict(rms=_rms(tcp_err[:, i]) * 1e3, max=_max(tcp_err[:, i]) * 1e3),
            # the force sensor's reading against the weld's force it measures while holding (nothing else
            # touches the clamp then): its noise and filter
            sensed_force_error=dict(rms=_rms(sensed), max=_max(sensed))))
    # ---- the two clamps together: the engine's cooperation columns (SimulationLog.cooperation) ----
    co = log.cooperation(0, 1)
    pair = co["holding"] & (co["body"] == scene.BAR) & carried   # as the bar's pose: lift, carry, place
    grasps, contacts = _events(runner.sim)
    airborne = pair & ~_touching_stands(contacts, t)
    s["cooperation"] = cooperation_scores(co, pair, airborne, report.get("commanded"))
    k = np.flatnonzero(np.isfinite(d_rr))
    j = k[np.argmin(d_rr[k])] if len(k) else 0
    s["clearance_robots"] = dict(min=float(d_rr[j]), t=float(t[j])) if len(k) else None
    s["grasp_events"] = [dict(t=float(t_), robot=int(robot), body=body, event=event, reason=reason)
                         for t_, robot, body, event, reason in zip(grasps["t"].tolist(), grasps["robot"], grasps["body"],
                                                                   grasps["event"], grasps["reason"])]
    s["contact_events"] = [dict(a=a, b=b, kind=kind, begin=float(begin), end=None if math.isnan(end) else float(end),
                                peak_force=float(peak))
                           for a, b, kind, begin, end, peak in zip(contacts["a"], contacts["b"], contacts["kind"],
                                                                   contacts["begin"].tolist(), contacts["end"].tolist(),
                                                                   contacts["peak_force"].tolist())]
    report["scores"] = s
    return dict(t=t, bar=bar, bar_planned=planned, position_error=pos_err, angle_error=ang_err, weld=weld,
                weld_points=weld_points, weld_stretch=stretch, holding=holding, carried=carried,
                tau=[rl.tau for rl in log.robots], clearance_robots=d_rr, tool_error=tcp_err, cooperation=co,
                pair=pair, airborne=airborne)


def _events(sim):
    """The run's grasp and contact events as the engine keeps them (Simulation.grasp_events and
    contact_events: time arrays and lists per column), without a table."""
    if sim.world is None:
        return (dict(t=np.zeros(0), robot=[], body=[], event=[], reason=[]),
                dict(a=[], b=[], kind=[], begin=np.zeros(0), end=np.zeros(0), peak_force=np.zeros(0)))
    return sim.grasp_events(), sim.contact_events()


def _touching_stands(contacts, t) -> np.ndarray:
    """(rows,) bool: the bar touches a stand at the log's times t (its contact events with the stands, an
    event's end NaN while it lasts; contacts: Simulation.contact_events' columns)."""
    out = np.zeros(len(t), bool)
    for a, b, begin, end in zip(contacts["a"], contacts["b"], contacts["begin"].tolist(), contacts["end"].tolist()):
        other = b if a == scene.BAR else a if b == scene.BAR else None
        if other is not None and "stand" in other:
            out |= (t >= begin) & (t <= (np.inf if math.isnan(end) else end))
    return out


def cooperation_scores(co: dict, pair, airborne, commanded=None) -> dict:
    """The scores of the two clamps together, from the log's cooperation columns `co`
    (:meth:`coopsim.SimulationLog.cooperation`) over the rows `pair` where both hold the bar (the carry's
    scores: both carrying it, from the lift to the end of the place, as the bar's pose error; the grasp's
    closing and the release's hand-over to the free controllers are left out) and `airborne` where they hold
    it off the stands:

    - squeeze_N: the internal force along the line between the welds, signed (compression positive, tension
      negative): mean (signed), rms, peak (signed: the value of largest magnitude, so a steady pull reads as a
      negative mean and peak); internal_force_N: the magnitude of the internal wrench's force (each weld's,
      equal and opposite): rms, max; twist_Nm, bending_Nm: their largest magnitudes (pair rows);
    - load_share: SCARA #1's part of the vertical load against the commanded one (``commanded['load_share']``,
      the lever rule's when the controllers command none): mean and mean_abs_deviation (airborne rows only:
      while a stand carries part of the bar, the welds' vertical load is not its weight);
    - relative_position_error_mm, relative_angle_error_mrad: the clamps' relative pose against the one they
      had when the second weld attached, largest (pair rows);
    - squeeze_commanded_N, load_share_commanded; rows_pair, rows_airborne (the rows counted)."""
    pair, airborne = np.asarray(pair, bool), np.asarray(airborne, bool)
    sq = co["squeeze"][pair]
    f_int = _norms(co["internal"][pair][:, :3])
    share = co["load_share"][airborne, 0]
    share = share[np.isfinite(share)]
    want = (commanded or {}).get("load_share", [0.5, 0.5])[0]
    rel = co["relative_pose_error"][pair]
    return dict(
        squeeze_N=dict(mean=float(np.mean(sq)) if len(sq) else 0.0, rms=_rms(sq), peak=_peak(sq)),
        internal_force_N=dict(rms=_rms(f_int), max=_max(f_int)),
        twist_Nm=_max(np.abs(co["twist"][pair])), bending_Nm=_max(np.abs(co["bending"][pair])),
        load_share=dict(mean=float(np.mean(share)) if len(share) else float("nan"),
                        mean_abs_deviation=float(np.mean(np.abs(share - want))) if len(share) else float("nan")),
        relative_position_error_mm=_max(_norms(rel[:, :3])) * 1e3,
        relative_angle_error_mrad=_max(_norms(rel[:, 3:])) * 1e3,
        squeeze_commanded_N=float((commanded or {}).get("squeeze", 0.0)), load_share_commanded=float(want),
        rows_pair=int(pair.sum()), rows_airborne=int(airborne.sum()))


def score_row(report: dict) -> dict:
    """One flat row of a run's outcome and scores (a sweep's columns): success, step, reason (of a failure);
    the bar's position error rms and max (mm) and angle error max (mrad) while carried; the squeeze (N,
    compression positive): its signed mean, its rms and its signed peak (squeeze_mean_N, squeeze_rms_N,
    squeeze_peak_N; squeeze_max_N, the peak's magnitude, is kept for older tables), the internal force's rms and
    max (N); the load share's mean absolute deviation from the
    commanded one; the relative pose error's max (mm, mrad); each robot's largest slip (mm) and its largest
    joint torque as a fraction of its limits. The scores are NaN for a run not scored."""
    f = report.get("failure") or {}
    row = dict(success=bool(report["success"]), step=f.get("step"), reason=f.get("reason"))
    s = report.get("scores")
    nan = float("nan")
    c = (s or {}).get("cooperation", {})
    get = (lambda *k: _dig(s, k)) if s else (lambda *k: nan)
    row.update(
        bar_error_rms_mm=get("bar_position_error_mm", "rms"), bar_error_max_mm=get("bar_position_error_mm", "max"),
        bar_angle_max_mrad=get("bar_angle_error_mrad", "max"),
        squeeze_mean_N=get("cooperation", "squeeze_N", "mean"), squeeze_rms_N=get("cooperation", "squeeze_N", "rms"),
        squeeze_peak_N=get("cooperation", "squeeze_N", "peak"),
        squeeze_max_N=abs(get("cooperation", "squeeze_N", "peak")),
        internal_force_rms_N=get("cooperation", "internal_force_N", "rms"),
        internal_force_max_N=get("cooperation", "internal_force_N", "max"),
        load_share_deviation=get("cooperation", "load_share", "mean_abs_deviation"),
        relative_position_max_mm=c.get("relative_position_error_mm", nan),
        relative_angle_max_mrad=c.get("relative_angle_error_mrad", nan))
    for i in range(2):
        r = s["robots"][i] if s else {}
        row[f"slip_max_mm_{i}"] = r.get("max_slip_mm", nan)
        row[f"torque_fraction_{i}"] = r.get("torque_limit_fraction", nan)
    return row


def _dig(d, keys):
    for k in keys:
        d = d[k]
    return float(d)


def _jaw_as(q_ref, q) -> np.ndarray:
    out = np.array(q_ref, float)
    out[:, -1] = q[:, -1]
    return out


def _resample(body, t) -> np.ndarray:
    """The body's poses at times t (the log's rows), from its own rows (the nearest at or before)."""
    k = np.clip(np.searchsorted(body.t, t + 1e-12, side="right") - 1, 0, len(body.t) - 1)
    return body.poses()[k]
