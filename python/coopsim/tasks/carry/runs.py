"""The carry over many seeds (:func:`sweep`): each seed shifts and turns the start stands."""
from __future__ import annotations

from typing import Sequence

from .planning import random_start
from .sequence import run


def sweep(seeds: Sequence[int], **options) -> dict:
    """The carry once per seed (:func:`~.sequence.run` with ``seed=``, unscored unless ``score_run=True``);
    options go to run. Returns dict(success_rate, runs=[dict(seed, start=[x, y, z, yaw], success, step,
    reason)], failures=[the runs that failed])."""
    options.setdefault("score_run", False)
    runs = []
    for s in seeds:
        res = run(seed=int(s), **options)
        f = res.report["failure"] or {}
        runs.append(dict(seed=int(s), start=list(random_start(int(s))), success=res.success, step=f.get("step"),
                         reason=f.get("reason")))
    return dict(success_rate=sum(r["success"] for r in runs) / max(1, len(runs)), runs=runs,
                failures=[r for r in runs if not r["success"]])
