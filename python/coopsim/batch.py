"""Many independent simulations at once: on the threads of this machine, or through any executor.

:func:`run_batch` steps many simulations in one C++ call on a thread pool
with the GIL released (a gain sweep); :func:`simulate` runs one and is a
module-level function, so any ``concurrent.futures`` executor can map it
over pickled simulations.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from . import _checks
from .simulation import Simulation

__all__ = ["run_batch", "simulate"]


def _output(sim: Simulation, output: str):
    if output == "log":
        return sim.log
    if output == "metrics":
        return sim.metrics()
    return None


#: the most threads a batch runs on (forward_dynamics_batch's bound too); 0 or None: every core
MAX_THREADS = 4096


def run_batch(sims: Sequence[Simulation], t_end: float, *, threads: Optional[int] = None, output: str = "log",
              errors: str = "raise") -> list:
    """Runs many independent simulations up to t_end (s) in one call, on threads.

    The stepping is C++ on a pool of `threads` threads (None or 0: every core; at most 4096)
    with the GIL released, each thread taking the next simulation when idle (runs of unequal
    length keep every thread busy). Runs of one description are best made with
    ``sim.replicate(n)`` (one model shared, each run its own data); inputs set afterwards
    with ``set_applied`` keep the model shared, while a new reference, controller or sensor
    option gives that run a copy of it. Results, in the order of `sims`: their logs
    (output='log'), their per-robot metrics ('metrics', see
    Simulation.metrics) or None ('none'). A run that fails (e.g. diverges)
    does not stop the others: errors='raise' raises the first failure after
    all have finished, errors='return' puts the exception in its place.
    The simulations must not share controller instances. Each keeps its own
    state and log afterwards, exactly as if run one by one; its ``stats``
    give the wall time of its own run (runs overlap on the threads, so the
    batch takes less than their sum).
    """
    sims = list(sims)
    for i, s in enumerate(sims):
        if not isinstance(s, Simulation):
            raise ValueError(f"sims[{i}] must be a coopsim.Simulation, got {type(s).__name__}")
    _checks.one_of(output, "output", ("log", "metrics", "none"))
    if errors not in ("raise", "return"):
        raise ValueError(f"errors must be 'raise' or 'return', got {errors!r}")
    if threads is None:
        threads = 0
    _checks.integer(threads, "threads", 0, MAX_THREADS)
    if not isinstance(t_end, (int, float, np.floating, np.integer)) or not math.isfinite(t_end):
        raise ValueError(f"t_end must be a finite number of seconds, got {t_end!r}")
    for i, s in enumerate(sims):
        if not s.robot_count:
            raise ValueError(f"sims[{i}] has no robot")
        s.steps_until(float(t_end))  # t_end in the past -> ValueError now, not per thread
    errs = Simulation.advance_all(sims, float(t_end), int(threads))
    results = []
    first = None
    for i, (s, e) in enumerate(zip(sims, errs)):
        if e is not None:
            if first is None:
                first = (i, e)
            results.append(e)
        else:
            results.append(_output(s, output))
    if first is not None and errors == "raise":
        i, e = first
        if hasattr(e, "add_note"):
            e.add_note(f"raised by sims[{i}] of the batch")
        raise e
    return results


def simulate(sim: Simulation, t_end: float, output: str = "log"):
    """Runs `sim` headless up to t_end (s) and returns its log, metrics or None (see run_batch).

    A module-level function, so a sweep can go through any
    concurrent.futures executor: ``pool.map(functools.partial(simulate,
    t_end=2.0), sims)`` pickles each simulation's description to a worker
    and its log back.
    """
    _checks.one_of(output, "output", ("log", "metrics", "none"))
    if not isinstance(sim, Simulation):
        raise ValueError(f"sim must be a coopsim.Simulation, got {type(sim).__name__}")
    sim.run(t_end, progress=False)
    return _output(sim, output)
