"""The task's summary: a few lines per cycle from its report (printed by the command line, shown in the live
page)."""
from __future__ import annotations


def summary(report: dict) -> str:
    """A few lines per cycle: outcome, duration, tracking, clearances and forces, or the failure; then how many
    cycles succeeded, and which were not run after a failure."""
    lines = []
    for c in report["cycles"]:
        head = f"cycle {c['cycle']} ({c['bar']}): "
        if not c["success"]:
            lines.append(head + f"FAILED in {c['failed_step']} at t = {c['failed_at']:.3f} s: {c['reason']}")
            continue
        # an unscored report (score=False) has the cycle's times but not its duration
        duration = c["duration"] if "duration" in c else c["t_end"] - c["t_start"]
        lines.append(head + f"success in {duration:.2f} s" +
                     (f", the bar {c['outcome']}" if c.get("outcome") is not None else ""))
        if "tracking" in c:
            tr = ", ".join(f"{x['robot']} {x['rms_tool'] * 1e3:.2f} / {x['max_tool'] * 1e3:.2f} mm"
                           for x in c["tracking"])
            lines.append(f"  tool tracking error RMS / max: {tr}")
            cr, cc = c["clearance_robots"], c["clearance_container"]
            lines.append(f"  min clearance robot-robot {cr['min'] * 1e3:.1f} mm ({' - '.join(cr['between'])}, "
                         f"t = {cr['t']:.2f} s), robot-container {cc['min'] * 1e3:.1f} mm "
                         f"({' - '.join(cc['between'])})")
            lines.append(f"  peak weld force #1 {c['peak_weld_force'][0]:.2f} N, #2 {c['peak_weld_force'][1]:.2f} N; "
                         f"{len(c['grasp_events'])} grasp events, {len(c['contact_events'])} contact events")
            pe = c["max_relative_pose_error"]
            lines.append(f"  dual hold {c['dual_hold']:.3f} s: peak squeeze {c['peak_squeeze']:+.3f} N (> 0 pushing the "
                         f"bar together), internal force {c['peak_internal_force']:.2f} N, internal moment "
                         f"{c['peak_internal_moment']:.3f} N m; clamps' relative pose error {pe[0] * 1e3:.2f} mm, "
                         f"{pe[1] * 1e3:.2f} mrad")
    ok = sum(c["success"] for c in report["cycles"])
    not_run = report["cycles_planned"] - len(report["cycles"])
    tail = (f" (cycle {len(report['cycles'])} not run: the run stops at the first failure)" if not_run == 1 else
            f" (cycles {len(report['cycles'])} .. {report['cycles_planned'] - 1} not run: the run stops at the first "
            f"failure)" if not_run > 1 else "")
    lines.append(f"{ok} of {report['cycles_planned']} cycles succeeded" + tail)
    return "\n".join(lines)
