"""The task as an item of :func:`coopsim.sweep` (:class:`TaskRun`) and over many seeds (:func:`sweep`)."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..._core import IKError
from ...sweeps import OptionsRun, sweep as _sweep
from .planning import random_bar
from .sequence import run


class TaskRun(OptionsRun):
    """One run of the cooperative task as an item of :func:`coopsim.sweep`: `options` are the keywords of
    :func:`coopsim.tasks.handover.run` (seed=, bars=, cycles=, container_shift=, ...; score=False unless
    given). Plain values only, so it pickles anywhere."""

    #: the sweep's first columns for these runs
    sweep_columns = ("success", "step", "reason", "bar_x", "bar_y", "bar_yaw")

    def sweep_run(self):
        """Runs the task; returns (its columns: success, step and reason of the failure, simulated_time, the
        bar's start bar_x, bar_y (m) and bar_yaw (rad); the Simulation it ran, or None when it could not
        start). An IKError at planning time (step 'planning') or a bad option is a row with its error."""
        options = dict(self.options)
        options.setdefault("score", False)
        try:
            res = run(**options)
        except Exception as e:  # noqa: BLE001 - the sweep gets a row saying why
            text = f"{type(e).__name__}: {e}"
            return dict(success=False, step="planning" if isinstance(e, IKError) else None, reason=text, error=text,
                        simulated_time=0.0), None
        c = res.report["cycles"][-1]
        bar = res.report["bars"][0]
        return dict(success=bool(res.success), step=c.get("failed_step"), reason=c.get("reason"),
                    simulated_time=float(res.report["simulated_time"]), bar_x=float(bar[0][3]),
                    bar_y=float(bar[1][3]), bar_yaw=float(math.atan2(bar[1][0], bar[0][0]))), res.sim


def sweep(seeds: Sequence[int], *, threads: int = 2, executor=None, **options) -> dict:
    """The task once per seed, each with one bar drawn from :data:`REGION` (:func:`random_bar`), by
    :func:`coopsim.sweep` (which gives the same as a table): on `threads` threads (the engine releases
    the GIL while it steps), or through `executor` (any concurrent.futures executor or a Dask
    distributed.Client). options go to :func:`run` (score=False by default: the success and failure
    reasons only).

    Returns dict(success_rate, runs=[dict(seed, bar=[x, y, yaw], success, step, reason, simulated_time)],
    failures=[the runs that failed]).
    """
    options.setdefault("score", False)
    seeds = [int(s) for s in seeds]
    # one mechanism for both: coopsim.sweep (threads here, or the executor), its rows read back per seed
    df = _sweep([TaskRun(seed=s, **options) for s in seeds], executor=executor,
                threads=None if executor is not None else max(1, int(threads)))
    runs = []
    for s, r in zip(seeds, df.itertuples()):
        bar = random_bar(s)
        entry = dict(seed=s, bar=[float(bar[0, 3]), float(bar[1, 3]), float(math.atan2(bar[1, 0], bar[0, 0]))])
        if r.step == "planning" or not isinstance(r.success, (bool, np.bool_)):
            # a planning error, or a run the executor lost (its error says why)
            runs.append(dict(entry, success=False, step=r.step if r.step == "planning" else "lost",
                             reason=r.reason if r.step == "planning" else r.error, simulated_time=0.0))
        else:
            runs.append(dict(entry, success=bool(r.success), step=r.step, reason=r.reason,
                             simulated_time=float(r.simulated_time)))
    return dict(success_rate=sum(r["success"] for r in runs) / max(1, len(runs)), runs=runs,
                failures=[r for r in runs if not r["success"]])
