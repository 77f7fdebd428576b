"""The live page's data: the Data panel's table of the last log rows and the log's downloads (CSV, Excel).

Nothing here costs time that grows with the run's length on the simulation's thread: the table reads the
row count and the last rows of one robot's views (:meth:`coopsim.Simulation.log_arrays`, no copy), and a
download takes the log's views there (:meth:`coopsim.Simulation.log_snapshot` without the contact points,
which the tables do not hold) and writes the file on a thread of its own, showing its progress in the
Data panel."""
from __future__ import annotations

import math
import os
import tempfile
import threading
import time

from ...log import BODY_COLUMNS, QUANTITIES
from .common import _TABLE_ROWS

_PROGRESS_EVERY = 0.2       # s of wall time between updates of the download's progress line
_KINDS = {"csv": "CSV", "xlsx": "Excel"}


class _Data:
    """The log as the page shows and sends it (a mixin: the view holds the simulation and the server)."""

    #: rows read from the log by the table's last update (at most _TABLE_ROWS, whatever the log's length)
    table_rows_read = 0
    #: the download's state: '' (none yet), 'preparing', 'sent' or 'failed', with its line in the Data panel
    download_state = ""
    download_text = ""
    #: every line the download's progress showed, in order
    download_lines: list = []

    def _pick_table(self, i: int) -> None:
        self._table_robot = i
        self._last_table = -math.inf
        self._changes += 1

    def _table_text(self) -> str:
        """The Data panel's table: the last rows of the chosen robot's joint positions. Called on the
        simulation's thread; reads the row count and _TABLE_ROWS rows of two views (O(1) in the log's
        length)."""
        self.table_rows_read = 0
        if not self.robots or self.sim.log_every == 0:
            return "_no log (log_every = 0)_" if self.robots else ""
        rows = self.sim.log_rows
        if rows == 0:
            return "_the log is empty_"
        i = self._table_robot
        a = self.sim.log_arrays(i)
        lo = max(0, rows - _TABLE_ROWS)
        t, q = a["t"][lo:rows].tolist(), a["q"][lo:rows].tolist()
        self.table_rows_read = rows - lo
        dof = len(q[0])
        head = "| t (s) | " + " | ".join(f"q{j + 1}" for j in range(dof)) + " |"
        sep = "|---" * (dof + 1) + "|"
        body = "\n".join(f"| {tk:.4f} | " + " | ".join(f"{x:.3f}" for x in qk) + " |" for tk, qk in zip(t, q))
        return f"{self.labels[i]}, last {rows - lo} of {rows} rows ({self._table_columns()} columns)\n\n" \
               f"{head}\n{sep}\n{body}"

    def _table_columns(self) -> int:
        """The number of columns of the log's tables (as SimulationLog.columns): t, every quantity of every
        joint of every robot, the free bodies' columns."""
        return 1 + sum(len(QUANTITIES) * r.dof for r in self.sim.robots) + len(BODY_COLUMNS) * len(self._free_names)

    def _show_download(self, state: str, text: str) -> None:
        self.download_state, self.download_text = state, text
        self.__dict__.setdefault("download_lines", []).append(text)
        line = getattr(self, "_download_line", None)
        if line is not None:
            line.content = text

    def download(self, kind: str, client=None) -> None:
        """Sends the log as 'csv' or 'xlsx' to the page that asked (every page if client is None). The
        log's views are taken on the simulation's thread (without the contact points, which the tables do
        not hold: constant time) and the file is written on another thread, so the run goes on meanwhile;
        the Data panel's line shows 'preparing CSV… 40 %', then 'sent: N rows, X MB'. One download at a
        time: a request while one is being prepared is refused with a line saying so."""
        if kind not in _KINDS:
            raise ValueError(f"kind must be 'csv' or 'xlsx', got {kind!r}")
        lock = self.__dict__.setdefault("_download_lock", threading.Lock())
        with lock:
            busy = self.download_state == "preparing"
            if not busy:
                self._show_download("preparing", f"preparing {_KINDS[kind]}… (taking the log)")
        if busy:
            self._show_download("preparing", f"{self.download_text}  \n_one download at a time: the "
                                              f"{_KINDS[kind]} was not started, ask again when this one is sent_")
            return

        def take():
            try:
                log = self.sim.log_snapshot(contact_points=False)
            except BaseException as e:       # the page's line says it; nothing is left preparing
                self._show_download("failed", f"download failed: {type(e).__name__}: {e}")
                raise
            threading.Thread(target=self._send_log, args=(log, kind, client), name="coopsim-live-download",
                             daemon=True).start()
        if self._driving.acquire(blocking=False):      # nobody runs the simulation now: take it at once
            try:
                take()
            finally:
                self._driving.release()
        else:
            self.submit(take)

    def _send_log(self, log, kind, client) -> None:
        name = _KINDS[kind]
        t0 = time.perf_counter()
        last = [-math.inf]

        def progress(fraction):
            now = time.perf_counter()
            if now - last[0] >= _PROGRESS_EVERY:
                last[0] = now
                self._show_download("preparing", f"preparing {name}… {100 * fraction:.0f} %")
        try:
            progress(0.0)
            with tempfile.TemporaryDirectory() as d:
                path = os.path.join(d, f"coopsim_log.{kind}")
                (log.to_csv if kind == "csv" else log.to_excel)(path, progress=progress)
                with open(path, "rb") as f:
                    data = f.read()
            self._show_download("preparing", f"sending {name}… {len(data) / 1e6:.1f} MB")
            target = client if client is not None else self.server
            target.send_file_download(f"coopsim_log.{kind}", data, save_immediately=True)
            rows = len(log.t)
            self._show_download("sent", f"sent: {rows} rows, {len(data) / 1e6:.1f} MB ({name}, "
                                        f"{time.perf_counter() - t0:.1f} s)")
        except Exception as e:    # e.g. Excel's row limit (ValueError), a full disk (OSError): said, not raised
            self._show_download("failed", f"download refused: {e}" if isinstance(e, ValueError)
                                else f"download failed: {type(e).__name__}: {e}")
