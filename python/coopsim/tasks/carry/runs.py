"""The carry as an item of :func:`coopsim.sweep` (:class:`CarryRun`), a sweep of controllers x disturbances x
seeds as a table (:func:`sweep_table`), and the carry over seeds (:func:`sweep`)."""
from __future__ import annotations

from typing import Iterable, Optional, Sequence

import numpy as np

from ... import _checks
from ..._core import IKError
from ...batch import MAX_THREADS
from ...sweeps import OptionsRun, sweep as _sweep
from .controllers import controller_factory
from .disturbances import DISTURBANCES
from .planning import random_start
from .scoring import score_row
from .sequence import run

__all__ = ["CarryRun", "sweep", "sweep_table"]


class CarryRun(OptionsRun):
    """One carry as an item of :func:`coopsim.sweep`: `options` are the keywords of :func:`~.sequence.run`
    (seed=, disturbance=, controllers= a name of :data:`~.controllers.CONTROLLERS` or 'module:factory',
    controller_options=, ...;
    score_run=True unless given). Plain values only, so it pickles anywhere."""

    #: the sweep's first columns for these runs (:func:`~.scoring.score_row`'s)
    sweep_columns = ("success", "step", "reason", "bar_error_rms_mm", "bar_error_max_mm", "bar_angle_max_mrad",
                     "squeeze_mean_N", "squeeze_rms_N", "squeeze_peak_N", "squeeze_max_N", "internal_force_rms_N", "internal_force_max_N",
                     "load_share_deviation", "relative_position_max_mm", "relative_angle_max_mrad",
                     "slip_max_mm_0", "slip_max_mm_1", "torque_fraction_0", "torque_fraction_1")

    def sweep_run(self):
        """Runs the carry; returns (:func:`~.scoring.score_row` of its report with simulated_time, the
        Simulation it ran), or for a run that could not start (an IKError at planning time: step 'planning';
        a bad option) a row with its error and None."""
        options = dict(self.options)
        options.setdefault("score_run", True)
        try:
            res = run(**options)
        except Exception as e:  # noqa: BLE001 - the sweep gets a row saying why
            text = f"{type(e).__name__}: {e}"
            return dict(success=False, step="planning" if isinstance(e, IKError) else None, reason=text, error=text,
                        simulated_time=0.0), None
        return dict(score_row(res.report), simulated_time=float(res.report["simulated_time"])), res.sim


def _names(values, what, choices) -> list:
    values = [values] if isinstance(values, str) or values is None else list(values)
    if not values:
        raise ValueError(f"{what} must name at least one, got none")
    for v in values:
        if v is not None and (not isinstance(v, str) or any(n.strip() not in choices for n in v.split(","))):
            raise ValueError(f"unknown {what[:-1]} {v!r}: choose from {', '.join(choices)}")
    return values


def _controllers(values) -> list:
    values = [values] if isinstance(values, str) else list(values)
    if not values:
        raise ValueError("controllers must name at least one, got none")
    for v in values:
        controller_factory(v)         # a name of CONTROLLERS or a module:factory that loads, else its ValueError
    return values


def sweep_table(controllers: Iterable[str] = ("ct",), disturbances: Iterable[Optional[str]] = ("none",),
                seeds: Iterable[int] = (0,), *, threads: int = 2, executor=None,
                options_by_controller: Optional[dict] = None, keep_logs: bool = False, **options):
    """The carry for every controller x disturbance x seed (the grid's order: controllers slowest, seeds
    fastest) through :func:`coopsim.sweep`, on `threads` threads (the engine releases the GIL while it
    steps) or through `executor` (a concurrent.futures executor or a Dask distributed.Client).

    controllers: names of :data:`~.controllers.CONTROLLERS` or factories of one's own as 'module:factory' or
    'path/to/file.py:factory' (:func:`~.controllers.controller_factory`; imported by each worker). disturbances: names of
    :data:`~.disturbances.DISTURBANCES` (one per run; 'a,b' combines two). seeds: integers >= 0 (each shifts
    and turns the start stands). options: more keywords of :func:`~.sequence.run` for every run
    (controller_options=, dt=, ...). options_by_controller: {controller: its controller_options} for the
    controllers named, over `controller_options` (the options one controller takes and another does not).

    Returns a pandas DataFrame, one row per run: controller, disturbance, seed, then
    :attr:`CarryRun.sweep_columns` (:func:`~.scoring.score_row`: success, the failure's step and reason, the
    bar's path error, squeeze, internal force, load share deviation, relative pose error, slips, torques),
    error, wall_time, simulated_time, steps, worker and the sweep's per-joint metrics. ValueError names an
    unknown controller or disturbance, or a bad seed, before anything runs."""
    controllers = _controllers(controllers)
    disturbances = _names(disturbances, "disturbances", list(DISTURBANCES))
    seeds = list(seeds)
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, int) or s < 0:
            raise ValueError(f"seeds must be integers >= 0, got {s!r}")
    if not seeds:
        raise ValueError("seeds must hold at least one seed")
    _checks.integer(threads, "threads", 0, MAX_THREADS)
    by = dict(options_by_controller or {})
    if not all(isinstance(v, dict) for v in by.values()) or not set(by) <= set(controllers):
        raise ValueError(f"options_by_controller must map controllers of the sweep ({', '.join(controllers)}) to "
                         f"dicts of options, got {options_by_controller!r}")

    def make(controller, disturbance, seed):
        o = dict(options)
        if controller in by:
            o["controller_options"] = {**(o.get("controller_options") or {}), **by[controller]}
        return CarryRun(controllers=controller, disturbance=disturbance, seed=seed, **o)

    grid = dict(controller=controllers, disturbance=[d or "none" for d in disturbances], seed=seeds)
    return _sweep(make, grid=grid, executor=executor, threads=None if executor is not None else threads,
                  keep_logs=keep_logs)


def sweep(seeds: Sequence[int], *, threads: int = 2, executor=None, **options) -> dict:
    """The carry once per seed (:func:`~.sequence.run` with ``seed=``, unscored unless ``score_run=True``),
    through :func:`coopsim.sweep` as :func:`sweep_table` (threads, or `executor`); options go to run.
    Returns dict(success_rate, runs=[dict(seed, start=[x, y, z, yaw], success, step, reason)],
    failures=[the runs that failed])."""
    options.setdefault("score_run", False)
    seeds = [int(s) for s in seeds]
    df = _sweep([CarryRun(seed=s, **options) for s in seeds], executor=executor,
                threads=None if executor is not None else max(1, int(threads)))
    runs = []
    for s, r in zip(seeds, df.itertuples()):
        lost = not isinstance(r.success, (bool, np.bool_))      # a run the executor lost: its error says why
        runs.append(dict(seed=s, start=[float(v) for v in random_start(s)], success=False if lost else bool(r.success),
                         step="lost" if lost else r.step, reason=r.error if lost else r.reason))
    return dict(success_rate=sum(r["success"] for r in runs) / max(1, len(runs)), runs=runs,
                failures=[r for r in runs if not r["success"]])
