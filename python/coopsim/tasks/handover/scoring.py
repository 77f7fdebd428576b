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



def _cycle_window(log, t0, t1):
    return (log.t >= t0 - 1e-12) & (log.t <= t1 + 1e-12)


def score_cycles(runner, results: List[dict]) -> dict:
    """Adds to each cycle of `results` its scores from the log of `runner` (the task's runner, after the
    run); returns the series behind the plots."""
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
    holding, internal = co["holding"], co["internal"]
    internal_force = np.linalg.norm(internal[:, :3], axis=1)  # the same at both welds
    internal_moment = np.maximum(np.linalg.norm(internal[:, 3:6], axis=1), np.linalg.norm(internal[:, 9:], axis=1))
    pose_error = co["relative_pose_error"]
    grasps, contacts = log.grasps, log.contacts
    for c in results:
        m = _cycle_window(log, c["t_start"], c["t_end"])
        c["duration"] = c["t_end"] - c["t_start"]
        if not m.any():
            continue
        c["tracking"] = [dict(robot=rl.name, rms_joint=np.sqrt((rl.error[m] ** 2).mean(axis=0)).tolist(),
                              max_joint=np.abs(rl.error[m]).max(axis=0).tolist(),
                              rms_tool=float(np.sqrt((tcp_err[m, i] ** 2).mean())),
                              max_tool=float(tcp_err[m, i].max()))
                         for i, rl in enumerate(log.robots)]
        k = np.flatnonzero(m)[np.argmin(d_rr[m])]
        c["clearance_robots"] = dict(min=float(d_rr[k]), t=float(log.t[k]), between=[names[0][i_rr[k]],
                                                                                     names[1][j_rr[k]]])
        k = np.flatnonzero(m)[np.argmin(d_rc[m])]
        r = 0 if cont[0][0][k] <= cont[1][0][k] else 1
        c["clearance_container"] = dict(min=float(d_rc[k]), t=float(log.t[k]),
                                        between=[names[r][cont[r][1][k]], walls[cont[r][2][k]]])
        c["peak_weld_force"] = [float(weld[m, i].max()) for i in range(2)]
        both = m & holding
        c["dual_hold"] = float(both.sum() * (log.t[1] - log.t[0])) if len(log.t) > 1 else 0.0
        if both.any():
            k = np.flatnonzero(both)[np.argmax(np.abs(co["squeeze"][both]))]
            c["peak_squeeze"] = float(co["squeeze"][k])  # N, signed: > 0 pushing the bar together
            c["peak_internal_force"] = float(internal_force[both].max())
            c["peak_internal_moment"] = float(internal_moment[both].max())
            c["max_relative_pose_error"] = [float(np.linalg.norm(pose_error[both, :3], axis=1).max()),
                                            float(np.linalg.norm(pose_error[both, 3:], axis=1).max())]
        else:
            c["peak_squeeze"] = c["peak_internal_force"] = c["peak_internal_moment"] = 0.0
            c["max_relative_pose_error"] = [0.0, 0.0]
        g = grasps[(grasps.t >= c["t_start"]) & (grasps.t <= c["t_end"])]
        c["grasp_events"] = [dict(t=float(e.t), robot=int(e.robot), body=e.body, event=e.event, reason=e.reason)
                             for e in g.itertuples()]
        e = contacts[(contacts.begin >= c["t_start"] - 1e-12) & (contacts.begin <= c["t_end"])]
        c["contact_events"] = [dict(a=x.a, b=x.b, kind=x.kind, begin=float(x.begin),
                                    end=None if np.isnan(x.end) else float(x.end), peak_force=float(x.peak_force))
                               for x in e.itertuples()]
        c["outcome"] = runner.outcome.get(c["bar"])
    series = dict(t=log.t, clearance_robots=d_rr, clearance_container=d_rc, tool_error=tcp_err, weld_force=weld,
                  squeeze=co["squeeze"], internal_force=internal_force, internal_moment=internal_moment,
                  load_share=co["load_share"], relative_pose_error=pose_error)
    return series
