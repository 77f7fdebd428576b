"""Sweeps: many independent runs (a gain grid, a task over seeds) on threads, any executor or a Dask cluster.

:func:`sweep` takes simulations (their descriptions pickle to the workers)
or runs that run themselves (:class:`coopsim.TaskRun`, the cooperative task
with the keywords of :func:`coopsim.tasks.handover.run`: see :func:`run_one`),
built from a grid or given as a list, runs them on this machine's threads (``executor=None``: simulations through
:func:`coopsim.run_batch`, tasks on a thread pool, the engine releasing the
GIL), on any ``concurrent.futures.Executor`` (a process pool), or on a Dask
``distributed.Client`` (a ``LocalCluster`` or a real scheduler: ``pip
install coopsim[cluster]``), and returns one row of metrics per run in the
order of the grid, whatever order the workers finish in. A run that raises
is a row with its error; a run whose worker dies is retried elsewhere by
Dask; a sweep that times out or is interrupted (Ctrl-C) returns what
finished, the rest as rows with the error 'not finished'.
"""
from __future__ import annotations

import concurrent.futures
import itertools
import math
import os
import pickle
import socket
import time
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Union

import numpy as np

from ._core import compiled_generated_names, generated_cache_dir, generated_info, load_generated_library
from .batch import run_batch
from .simulation import Simulation

__all__ = ["sweep", "grid", "run_one", "run_shipped", "generated_libraries", "install_libraries"]

NOT_FINISHED = "not finished"


def grid(**axes) -> List[dict]:
    """The points of a grid as dicts, the last axis varying fastest (nested loops in the order given):
    ``grid(kp=[100, 200], kd=[5, 10])`` -> [{kp: 100, kd: 5}, {kp: 100, kd: 10}, {kp: 200, kd: 5}, ...]."""
    names = list(axes)
    return [dict(zip(names, values)) for values in itertools.product(*(list(axes[k]) for k in names))]


def _where() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def _error_text(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}"


def _sim_metrics(sim: Simulation) -> dict:
    row = {}
    for i, m in enumerate(sim.metrics()):
        for name, key in (("rms_error", "rms_error"), ("max_error", "max_abs_error"), ("peak_tau", "max_abs_tau")):
            for j, v in enumerate(np.asarray(getattr(m, key), dtype=float)):
                row[f"{name}_{i}_{j}"] = float(v)
    return row


def _run_simulation(sim: Simulation, t_end: float, keep_log: bool) -> dict:
    w0 = time.perf_counter()
    row = dict(error=None, worker=_where())
    try:
        sim.run(t_end, progress=False)
    except Exception as e:  # a diverging run is a row with its error, its metrics up to the failure
        row["error"] = _error_text(e)
    row["wall_time"] = time.perf_counter() - w0
    row["simulated_time"] = sim.time
    row["steps"] = sim.steps
    row.update(_sim_metrics(sim))
    if keep_log:
        row["log"] = sim.log
    return row


class OptionsRun:
    """A run that runs itself from keywords (plain values, so it pickles anywhere): the base of the tasks'
    sweep items (:class:`coopsim.TaskRun`, :class:`coopsim.tasks.carry.CarryRun`), which define
    ``sweep_run()`` and ``sweep_columns``. Equal when their options are."""

    def __init__(self, **options):
        self.options = dict(options)

    def __eq__(self, other):
        return type(other) is type(self) and self.options == other.options

    __hash__ = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(" + ", ".join(f"{k}={v!r}" for k, v in self.options.items()) + ")"


def _is_run(x) -> bool:
    """A Simulation, or a run that runs itself (an instance with sweep_run(), such as coopsim.TaskRun)."""
    return isinstance(x, Simulation) or (not isinstance(x, type) and callable(getattr(x, "sweep_run", None)))


def _run_item(item, keep_log: bool) -> dict:
    w0 = time.perf_counter()
    row = dict(error=None, worker=_where())
    columns, sim = item.sweep_run()
    row.update(columns)
    row["wall_time"] = time.perf_counter() - w0
    if sim is not None:
        row["steps"] = sim.steps
        row.update(_sim_metrics(sim))
        if keep_log:
            row["log"] = sim.log
    return row


def run_one(item, t_end: Optional[float] = None, keep_log: bool = False) -> dict:
    """Runs one item of a sweep and returns its row as a dict: a Simulation up to t_end, or a run that runs
    itself (such as :class:`coopsim.TaskRun`): ``item.sweep_run()`` returns its own columns and the
    Simulation it ran (or None), whose metrics and log the row takes, and the class's ``sweep_columns``
    name the columns the sweep's table shows first.

    A module-level function, so any executor can run it; it never raises for a run that fails
    (the row's 'error' says why)."""
    try:
        if isinstance(item, Simulation):
            return _run_simulation(item, t_end, keep_log)
        return _run_item(item, keep_log)
    except Exception as e:  # noqa: BLE001 - whatever happens, the sweep gets its row
        return dict(error=_error_text(e), worker=_where())


def _cache_folder() -> Path:
    d = generated_cache_dir()
    return Path(d) if d else Path.home() / ".cache" / "coopsim"


def generated_libraries(items) -> Dict[str, bytes]:
    """The shared libraries of the generated dynamics (``codegen.compile``) that the simulations among
    `items` use, as {name: bytes}, read from this process's ``codegen.cache_dir()`` (dynamics compiled
    into the engine need none). The sweep ships them to its workers (:func:`install_libraries`)."""
    builtin = set(compiled_generated_names())
    names = set()
    for it in items:
        if isinstance(it, Simulation):
            for r in it.robots:
                info = generated_info(r)
                if info is not None and info["name"] not in builtin:
                    names.add(info["name"])
    libs = {}
    for name in sorted(names):
        path = _cache_folder() / f"coopsim_{name}.so"
        if not path.is_file():
            raise ValueError(f"the generated dynamics {name!r} of a robot in the sweep are not in "
                             f"{_cache_folder()} (compiled with another cache=?): set COOPSIM_CACHE_DIR to "
                             "that folder to let the sweep ship them to its workers")
        libs[name] = path.read_bytes()
    return libs


def install_libraries(libs: Mapping[str, bytes]) -> List[str]:
    """On a worker: writes each generated library into this process's cache folder (unless the same bytes
    are there) and loads it, so robots compiled on the client unpickle here. Returns the names."""
    folder = _cache_folder()
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in libs.items():
        path = folder / f"coopsim_{name}.so"
        if not (path.is_file() and path.read_bytes() == data):
            tmp = folder / f".coopsim_{name}.{os.getpid()}.tmp"
            tmp.write_bytes(data)
            os.replace(tmp, path)  # atomic: workers sharing the folder never see half a library
        load_generated_library(str(path))
    return list(libs)


def run_shipped(payload: bytes, libs: Mapping[str, bytes], t_end: Optional[float] = None,
                keep_log: bool = False) -> dict:
    """:func:`run_one` for an item pickled with generated dynamics: installs `libs` here first
    (:func:`install_libraries`), then unpickles and runs it."""
    try:
        install_libraries(libs)
        item = pickle.loads(payload)
    except Exception as e:  # noqa: BLE001 - the run's row says why it could not start here
        return dict(error=_error_text(e), worker=_where())
    return run_one(item, t_end, keep_log)


def _is_dask_client(executor) -> bool:
    mod = type(executor).__module__ or ""
    return mod.split(".")[0] == "distributed" and hasattr(executor, "scheduler_info")


def _items_from(runs, grid_points) -> tuple:
    """(items, params): params a list of dicts (grid columns) or None."""
    if callable(runs) and not _is_run(runs):
        if grid_points is None:
            raise ValueError("a callable `runs` needs grid= (a dict of axes or a list of dicts)")
        points = grid(**grid_points) if isinstance(grid_points, Mapping) else [dict(p) for p in grid_points]
        return [runs(**p) for p in points], points
    if _is_run(runs):
        raise ValueError("runs must be a sequence of Simulation or TaskRun (or a callable with grid=), got one "
                         f"{type(runs).__name__}")
    items = list(runs)
    if grid_points is not None:
        points = grid(**grid_points) if isinstance(grid_points, Mapping) else [dict(p) for p in grid_points]
        if len(points) != len(items):
            raise ValueError(f"grid has {len(points)} points for {len(items)} runs")
        return items, points
    return items, None


def sweep(runs: Union[Sequence[Any], Callable[..., Any]], t_end: Optional[float] = None, *,
          grid: Union[Mapping[str, Iterable], Sequence[Mapping], None] = None, executor=None,
          threads: Optional[int] = None, keep_logs: bool = False, timeout: Optional[float] = None,
          on_result: Optional[Callable[[int, dict], Any]] = None, chunk: int = 1):
    """Runs many independent runs and returns a pandas DataFrame, one row per run in the order given.

    runs: a sequence of coopsim.Simulation (run from their state up to t_end, s) and/or
    :class:`coopsim.TaskRun` (the cooperative task; t_end unused), or a callable called here, on the client,
    with each point of `grid` as keywords and returning one of those (``grid`` a dict of axes, see
    :func:`grid`, or a list of dicts; its values become the first columns).

    executor: None (this machine's threads: simulations in one :func:`coopsim.run_batch` call, tasks on
    a thread pool; `threads` of them, None for every core; each idle thread takes the next run, so runs of
    unequal length keep every thread busy), any concurrent.futures.Executor (each run
    pickled to a worker, see :func:`run_one`), or a Dask distributed.Client (a worker that dies has its
    runs retried on the others by the scheduler).

    Columns: the grid's, then error (None, or 'Type: message' for a run that raised: a diverging
    simulation, an IKError, a worker lost too often; the metrics are then those up to the failure or
    NaN), wall_time (s, the run's own, on its worker), simulated_time (s), steps, worker
    ('host:pid'), rms_error_i_j, max_error_i_j and peak_tau_i_j (robot i, joint j: RMS and largest
    absolute tracking error over every step, largest absolute commanded torque), and for the task
    success, step and reason (of the failure), bar_x, bar_y, bar_yaw. keep_logs=True adds a 'log'
    column (each run's SimulationLog, shipped back from the workers).

    timeout (s, wall): runs not finished by then (or when Ctrl-C interrupts the sweep) are cancelled
    and are rows with error 'not finished' (a run already started goes on to its end on its worker;
    simulations on this machine's threads, one run_batch call, take no timeout). on_result(index, row) is called here as each run
    finishes (progress; the row as a dict).
    chunk: runs per task sent to an executor or Dask (consecutive runs of the grid, one after the
    other on one worker): a few cut the fixed cost per task (pickling, scheduling) on short runs; a
    lost worker then has a whole chunk retried.
    The simulations given are run in place, from their state, only with executor=None; otherwise
    their descriptions are pickled and run from t = 0 on the workers.
    Robots with generated dynamics built at run time (``codegen.compile``, found in this process's
    ``codegen.cache_dir()``) have their libraries shipped with the runs and installed on the workers
    (same platform and coopsim as here; no compiler needed there).
    """
    import pandas as pd  # pandas' import is heavy: only when a sweep builds its table

    items, points = _items_from(runs, grid)
    for i, it in enumerate(items):
        if not _is_run(it):
            raise ValueError(f"runs[{i}] must be a coopsim.Simulation or a coopsim.TaskRun, got {type(it).__name__}")
    if any(isinstance(it, Simulation) for it in items):
        if t_end is None or not isinstance(t_end, (int, float, np.integer, np.floating)) or not math.isfinite(t_end):
            raise ValueError(f"t_end must be a finite number of seconds for simulations, got {t_end!r}")
        t_end = float(t_end)
    if timeout is not None and not (isinstance(timeout, (int, float)) and timeout > 0):
        raise ValueError(f"timeout must be a positive number of seconds or None, got {timeout!r}")
    if not isinstance(chunk, (int, np.integer)) or isinstance(chunk, bool) or chunk < 1:
        raise ValueError(f"chunk must be an integer >= 1, got {chunk!r}")
    rows: List[Optional[dict]] = [None] * len(items)

    def done(i, row):
        rows[i] = row
        if on_result is not None:
            on_result(i, row)

    t0 = time.perf_counter()
    if executor is None:
        _sweep_local(items, t_end, threads, keep_logs, timeout, done)
    elif _is_dask_client(executor):
        _sweep_dask(executor, items, t_end, keep_logs, timeout, done, chunk)
    elif isinstance(executor, concurrent.futures.Executor):
        _sweep_executor(executor, items, t_end, keep_logs, timeout, done, chunk)
    else:
        raise ValueError(f"executor must be None, a concurrent.futures.Executor or a distributed.Client, "
                         f"got {type(executor).__name__}")
    for i, r in enumerate(rows):
        if r is None:
            rows[i] = dict(error=NOT_FINISHED)
    df = pd.DataFrame(rows)
    first = ["error", "wall_time", "simulated_time", "steps", "worker"]
    lead = [c for it in items if not isinstance(it, Simulation) for c in getattr(it, "sweep_columns", ())]
    first = list(dict.fromkeys(lead)) + first
    for c in first:
        if c not in df:
            df[c] = None
    df = df[first + [c for c in df.columns if c not in first]]
    if points is not None:
        df = pd.concat([pd.DataFrame(points, index=df.index), df], axis=1)
    df.index.name = "run"
    df.attrs["wall_time"] = time.perf_counter() - t0
    return df


def _sweep_local(items, t_end, threads, keep_logs, timeout, done):
    sims = [(i, s) for i, s in enumerate(items) if isinstance(s, Simulation)]
    tasks = [(i, s) for i, s in enumerate(items) if not isinstance(s, Simulation)]
    if sims:
        # one C++ call on a thread pool, GIL released; a run that raises returns its exception
        out = run_batch([s for _, s in sims], t_end, threads=threads, output="none", errors="return")
        for (i, s), e in zip(sims, out):
            row = dict(error=None if e is None else _error_text(e), worker=_where(),
                       wall_time=s.stats.wall_time if s.stats is not None else float("nan"),
                       simulated_time=s.time, steps=s.steps)
            row.update(_sim_metrics(s))
            if keep_logs:
                row["log"] = s.log
            done(i, row)
    if tasks:
        # balanced: each idle thread takes the next run from the pool's queue (one future per run, in the grid's
        # order), whatever the runs' lengths; a task sequences its run in Python between the engine's calls,
        # which release the GIL (benchmarks/bench_scaling.py measures the fraction released)
        pool = concurrent.futures.ThreadPoolExecutor(max_workers=min(threads or os.cpu_count() or 1, len(tasks)))
        try:
            _collect({pool.submit(run_many, [t], None, keep_logs): [i] for i, t in tasks}, timeout, done)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _chunks(items, chunk):
    """[(indices, items)] of at most `chunk` runs each, in order."""
    return [(list(range(k, min(k + chunk, len(items)))), items[k:k + chunk]) for k in range(0, len(items), chunk)]


def run_many(items, t_end: Optional[float] = None, keep_log: bool = False) -> List[dict]:
    """:func:`run_one` for each of `items` in turn (one task of a chunked sweep)."""
    return [run_one(it, t_end, keep_log) for it in items]


def run_many_shipped(payloads, libs: Mapping[str, bytes], t_end: Optional[float] = None,
                     keep_log: bool = False) -> List[dict]:
    """:func:`run_shipped` for each of `payloads` in turn (one task of a chunked sweep)."""
    return [run_shipped(p, libs, t_end, keep_log) for p in payloads]


def _deliver(indices, result, done):
    for i, row in zip(indices, result):
        done(i, row)


def _collect(futures: Dict[concurrent.futures.Future, list], timeout, done):
    try:
        for f in concurrent.futures.as_completed(futures, timeout=timeout):
            try:
                result = f.result()
            except Exception as e:  # a broken pool, a run that could not be pickled
                result = [dict(error=_error_text(e))] * len(futures[f])
            _deliver(futures[f], result, done)
    except (concurrent.futures.TimeoutError, KeyboardInterrupt):
        pass  # what finished is kept; the rest are 'not finished'
    finally:
        for f in futures:
            f.cancel()


def _sweep_executor(executor, items, t_end, keep_logs, timeout, done, chunk):
    libs = generated_libraries(items)
    if libs:  # each run carries the libraries its robots need, and is unpickled after they are installed
        futures = {executor.submit(run_many_shipped, [pickle.dumps(it) for it in part], libs, t_end, keep_logs): idx
                   for idx, part in _chunks(items, chunk)}
    else:
        futures = {executor.submit(run_many, part, t_end, keep_logs): idx for idx, part in _chunks(items, chunk)}
    _collect(futures, timeout, done)


def _sweep_dask(client, items, t_end, keep_logs, timeout, done, chunk):
    from distributed import as_completed  # the optional cluster extra: only with a Dask client

    libs = generated_libraries(items)
    parts = _chunks(items, chunk)
    # pure=False: every chunk is its own task, even two equal descriptions
    if libs:  # sent once to every worker; each run installs them before unpickling its description
        shared = client.scatter([libs], broadcast=True, hash=False)[0]
        futures = client.map(run_many_shipped, [[pickle.dumps(it) for it in part] for _, part in parts], libs=shared,
                             t_end=t_end, keep_log=keep_logs, pure=False)
    else:
        futures = client.map(run_many, [part for _, part in parts], t_end=t_end, keep_log=keep_logs, pure=False)
    index = {f.key: idx for f, (idx, _) in zip(futures, parts)}
    deadline = None if timeout is None else time.monotonic() + timeout
    try:
        for f in as_completed(futures, timeout=timeout):
            idx = index[f.key]
            try:
                result = f.result(timeout=None if deadline is None else max(0.0, deadline - time.monotonic()))
            except Exception as e:  # KilledWorker (lost more often than allowed), a cancelled run
                result = [dict(error=_error_text(e))] * len(idx)
            _deliver(idx, result, done)
    except (TimeoutError, concurrent.futures.TimeoutError, KeyboardInterrupt):
        pass  # what finished is kept; the rest are 'not finished'

    finally:
        client.cancel([f for f in futures if not f.done()])
