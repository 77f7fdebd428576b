#!/usr/bin/env python3
"""Runs a command with busy processes beside it: a loaded machine, for tests that must not depend on its speed.

    python3 scripts/busy.py [--procs N] [--seconds S] [-- COMMAND ...]

Starts N processes (default: one per core, os.cpu_count()), each a plain Python loop that never sleeps, at
the default priority, so they take their share of the cores from everything else. With a COMMAND, runs it
beside them, stops them when it ends (or on Ctrl-C) and exits with its return code; without one, keeps them
busy for S seconds (default: until Ctrl-C or SIGTERM). Prints, when done, the wall time (s) and the one-minute load
average sampled every 5 s (mean and maximum), e.g. to run the browser tests under load (docs/development.md):

    python3 scripts/busy.py -- python3 -m pytest -q -m slow tests/test_live.py tests/test_replay.py tests/test_parts.py

Only the processes this script started are stopped, by their ids.
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time

SPIN = "while True:\n    pass\n"     # one busy core: no sleep, no I/O
SAMPLE_EVERY = 5.0                   # s between samples of the load average


def start_busy(n: int) -> list:
    """n busy Python processes (subprocess.Popen), started now."""
    return [subprocess.Popen([sys.executable, "-c", SPIN], stdin=subprocess.DEVNULL) for _ in range(n)]


def stop_busy(procs: list) -> None:
    """Stops the processes this script started (SIGTERM, then SIGKILL after 5 s), by their ids."""
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


class LoadSampler(threading.Thread):
    """Samples os.getloadavg()[0] every SAMPLE_EVERY s until stopped."""

    def __init__(self):
        super().__init__(daemon=True)
        self.samples: list = []
        self._done = threading.Event()

    def run(self) -> None:
        while True:
            self.samples.append(os.getloadavg()[0])
            if self._done.wait(SAMPLE_EVERY):
                return

    def stop(self) -> None:
        self._done.set()
        self.join()


def _terminated(signum, frame):
    raise KeyboardInterrupt("SIGTERM")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--procs", type=int, default=os.cpu_count() or 1,
                    help="busy processes to start (default: one per core, %(default)s here)")
    ap.add_argument("--seconds", type=float, default=None,
                    help="without a command: how long to stay busy (default: until Ctrl-C)")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="the command to run beside them (after --)")
    args = ap.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if args.procs < 1:
        ap.error(f"argument --procs: must be at least 1, got {args.procs}")
    if args.seconds is not None and not args.seconds > 0:       # also NaN
        ap.error(f"argument --seconds: must be > 0, got {args.seconds}")
    if command and args.seconds is not None:
        ap.error("give a command or --seconds, not both (the command decides how long)")

    # Ctrl-C reaches this script and the command even when started in the background, where a shell ignores
    # SIGINT and children inherit that (a handled signal is reset to its default in a child); SIGTERM stops
    # the busy processes as Ctrl-C does
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _terminated)
    sampler = LoadSampler()
    sampler.start()
    procs = start_busy(args.procs)
    print(f"busy.py: {args.procs} busy process(es) started (pids {', '.join(str(p.pid) for p in procs)})",
          flush=True)
    t0 = time.monotonic()
    rc = 0
    child = None
    try:
        if command:
            child = subprocess.Popen(command)
            rc = child.wait()
        elif args.seconds is not None:
            time.sleep(args.seconds)
        else:
            signal.pause()
    except KeyboardInterrupt:
        if child is not None:
            # from a terminal the command got the Ctrl-C too (one process group); else it is passed on
            try:
                rc = child.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                child.send_signal(signal.SIGINT)
                try:
                    rc = child.wait(timeout=30.0)
                except subprocess.TimeoutExpired:
                    child.kill()
                    rc = child.wait()
        else:
            rc = 130
    finally:
        stop_busy(procs)
        sampler.stop()
    wall = time.monotonic() - t0
    s = sampler.samples
    print(f"busy.py: {wall:.1f} s of wall time with {args.procs} busy process(es); load average (1 min) "
          f"mean {sum(s) / len(s):.1f}, max {max(s):.1f} over {len(s)} samples"
          + (f"; the command's exit status {rc}" if command else ""), flush=True)
    return 128 - rc if rc < 0 else rc          # a command killed by signal k: 128 + k, as a shell says


if __name__ == "__main__":
    sys.exit(main())
