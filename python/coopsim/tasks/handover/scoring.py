"""The per-cycle scores of a run, from its log: tracking errors (joint and tool), the smallest clearances
robot-robot and robot-container, the peak weld forces, and during the dual hold the squeeze, the internal
force and moment, and the clamps' relative pose error (the engine's ``log.cooperation``), the contact and
grasp events."""
from __future__ import annotations

from typing import List

import numpy as np

from ..._core import box_clearances


def clearances(PA, HA, PB, HB):
    """The smallest distance between two sets of boxes in each of N rows (m; < 0: overlap depth) and the
    pair that has it.

    PA: (N, ka, 4, 4) poses, HA: (ka, 3) half extents; PB: (N, kb, 4, 4) or (kb, 4, 4) for boxes that do
    not move, HB: (kb, 3). Returns (d (N,), ia (N,), ib (N,)). Exact (box_distance, Bullet's GJK) on the
    pairs that bounding spheres and separating axes cannot rule out (``coopsim.box_clearances``).
    """
    return box_clearances(PA, HA, PB, HB)



def _cycle_rows(t, t0, t1) -> slice:
    """The log's rows from t0 to t1 (s), each end within 1e-12 s, as a slice (the log's times increase)."""
    return slice(int(np.searchsorted(t, t0 - 1e-12, "left")), int(np.searchsorted(t, t1 + 1e-12, "right")))


def _events(sim):
    """The run's grasp and contact events as the engine keeps them (Simulation.grasp_events and
    contact_events: a time array and lists per column), without a table."""
    empty = dict(t=np.zeros(0), robot=[], body=[], event=[], reason=[])
    if sim.world is None:
        return empty, dict(a=[], b=[], kind=[], begin=np.zeros(0), end=np.zeros(0), peak_force=np.zeros(0))
    return sim.grasp_events(), sim.contact_events()


def score_cycles(runner, results: List[dict]) -> dict:
    """Adds to each cycle of `results` its scores from the log of `runner` (the task's runner, after the
    run); returns the series behind the plots. Per cycle from the engine's arrays: the cycle's rows as a slice
    of them, its events picked by their times."""
    sim, log = runner.sim, runner.sim.log
    robots = (runner.r1, runner.r2)
    shapes, halves = zip(*(r.shapes(rl.q) for r, rl in zip(robots, log.robots)))
    names = [[f"{r.name}/{b.name}" for b in r.boxes] for r in robots]
    walls = [w[0] for w in runner.walls]
    PW = np.array([w[2] for w in runner.walls])
    HW = np.array([w[1] for w in runner.walls])
    # the three clearance series one after the other, each one engine call with the GIL released (a sweep of
    # runs on threads runs them side by side)
    d_rr, i_rr, j_rr = clearances(shapes[0], halves[0], shapes[1], halves[1])
    cont = [clearances(P, H, PW, HW) for P, H in zip(shapes, halves)]
    d_rc = np.minimum(cont[0][0], cont[1][0])
    tcp_err = np.column_stack([np.linalg.norm(r.fk(rl.q)[:, :3, 3] - r.fk(rl.q_ref)[:, :3, 3], axis=1)
                               for r, rl in zip(robots, log.robots)])
    weld = np.column_stack([np.linalg.norm(rl.weld[:, :3], axis=1) for rl in log.robots])
    # the dual hold, as the engine computed it per row (NaN where the robots do not both hold the bar)
    co = log.cooperation(0, 1)
    holding, internal, squeeze = co["holding"], co["internal"], co["squeeze"]
    internal_force = np.linalg.norm(internal[:, :3], axis=1)  # the same at both welds
    internal_moment = np.maximum(np.linalg.norm(internal[:, 3:6], axis=1), np.linalg.norm(internal[:, 9:], axis=1))
    pose_error = co["relative_pose_error"]
    errors = [rl.error for rl in log.robots]
    grasps, contacts = _events(sim)
    t = log.t
    for c in results:
        m = _cycle_rows(t, c["t_start"], c["t_end"])
        c["duration"] = c["t_end"] - c["t_start"]
        if m.start >= m.stop:
            continue
        c["tracking"] = [dict(robot=rl.name, rms_joint=np.sqrt((e[m] ** 2).mean(axis=0)).tolist(),
                              max_joint=np.abs(e[m]).max(axis=0).tolist(),
                              rms_tool=float(np.sqrt((tcp_err[m, i] ** 2).mean())),
                              max_tool=float(tcp_err[m, i].max()))
                         for i, (rl, e) in enumerate(zip(log.robots, errors))]
        k = m.start + int(np.argmin(d_rr[m]))
        c["clearance_robots"] = dict(min=float(d_rr[k]), t=float(t[k]), between=[names[0][i_rr[k]],
                                                                                 names[1][j_rr[k]]])
        k = m.start + int(np.argmin(d_rc[m]))
        r = 0 if cont[0][0][k] <= cont[1][0][k] else 1
        c["clearance_container"] = dict(min=float(d_rc[k]), t=float(t[k]),
                                        between=[names[r][cont[r][1][k]], walls[cont[r][2][k]]])
        c["peak_weld_force"] = [float(weld[m, i].max()) for i in range(2)]
        both = holding[m]
        c["dual_hold"] = float(both.sum() * (t[1] - t[0])) if len(t) > 1 else 0.0
        if both.any():
            k = m.start + np.flatnonzero(both)[np.argmax(np.abs(squeeze[m][both]))]
            c["peak_squeeze"] = float(squeeze[k])  # N, signed: > 0 pushing the bar together
            c["peak_internal_force"] = float(internal_force[m][both].max())
            c["peak_internal_moment"] = float(internal_moment[m][both].max())
            c["max_relative_pose_error"] = [float(np.linalg.norm(pose_error[m][both, :3], axis=1).max()),
                                            float(np.linalg.norm(pose_error[m][both, 3:], axis=1).max())]
        else:
            c["peak_squeeze"] = c["peak_internal_force"] = c["peak_internal_moment"] = 0.0
            c["max_relative_pose_error"] = [0.0, 0.0]
        g = np.flatnonzero((grasps["t"] >= c["t_start"]) & (grasps["t"] <= c["t_end"])).tolist()
        c["grasp_events"] = [dict(t=float(grasps["t"][j]), robot=int(grasps["robot"][j]), body=grasps["body"][j],
                                  event=grasps["event"][j], reason=grasps["reason"][j]) for j in g]
        begin, end, peak = contacts["begin"], contacts["end"], contacts["peak_force"]
        e = np.flatnonzero((begin >= c["t_start"] - 1e-12) & (begin <= c["t_end"])).tolist()
        c["contact_events"] = [dict(a=contacts["a"][j], b=contacts["b"][j], kind=contacts["kind"][j],
                                    begin=float(begin[j]), end=None if np.isnan(end[j]) else float(end[j]),
                                    peak_force=float(peak[j])) for j in e]
        c["outcome"] = runner.outcome.get(c["bar"])
    series = dict(t=log.t, clearance_robots=d_rr, clearance_container=d_rc, tool_error=tcp_err, weld_force=weld,
                  squeeze=co["squeeze"], internal_force=internal_force, internal_moment=internal_moment,
                  load_share=co["load_share"], relative_pose_error=pose_error)
    return series
