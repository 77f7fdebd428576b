"""The live page's data: the Data panel's table of the last log rows and the log's downloads (CSV, Excel)."""
from __future__ import annotations

import math
import os
import tempfile
import threading

from .common import _TABLE_ROWS


class _Data:
    """The log as the page shows and sends it (a mixin: the view holds the simulation and the server)."""

    def _pick_table(self, i: int) -> None:
        self._table_robot = i
        self._last_table = -math.inf
        self._changes += 1

    def _table_text(self) -> str:
        if not self.robots or self.sim.log_every == 0:
            return "_no log (log_every = 0)_" if self.robots else ""
        log = self.sim.log
        rows = len(log.t)
        if rows == 0:
            return "_the log is empty_"
        i = self._table_robot
        rl = log.robots[i]
        lo = max(0, rows - _TABLE_ROWS)
        head = "| t (s) | " + " | ".join(f"q{j + 1}" for j in range(rl.dof)) + " |"
        sep = "|---" * (rl.dof + 1) + "|"
        body = "\n".join(f"| {log.t[k]:.4f} | " + " | ".join(f"{x:.3f}" for x in rl.q[k]) + " |"
                         for k in range(lo, rows))
        return f"{self.labels[i]}, last {rows - lo} of {rows} rows ({len(log.columns())} columns)\n\n" \
               f"{head}\n{sep}\n{body}"

    def download(self, kind: str, client=None) -> None:
        """Sends the log as 'csv' or 'xlsx' to the page that asked (every page if client is None). The
        log is taken on the simulation's thread (its arrays are views later steps do not change) and
        written on another thread, so the run goes on meanwhile."""
        if kind not in ("csv", "xlsx"):
            raise ValueError(f"kind must be 'csv' or 'xlsx', got {kind!r}")

        def take():
            log = self.sim.log
            threading.Thread(target=self._send_log, args=(log, kind, client), daemon=True).start()
        self.submit(take)

    def _send_log(self, log, kind, client) -> None:
        try:
            with tempfile.TemporaryDirectory() as d:
                path = os.path.join(d, f"coopsim_log.{kind}")
                (log.to_csv if kind == "csv" else log.to_excel)(path)
                with open(path, "rb") as f:
                    data = f.read()
            target = client if client is not None else self.server
            target.send_file_download(f"coopsim_log.{kind}", data, save_immediately=True)
            self._say(f"Log sent as {kind.upper()}: {len(log.t)} rows")
        except ValueError as e:
            self._say(f"Refused: {e}")
