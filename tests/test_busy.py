"""scripts/busy.py: a command run beside busy processes (docs/development.md: the browser tests under load). Its
exit status is the command's, and the busy processes it started are gone when it returns."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

BUSY = Path(__file__).resolve().parents[1] / "scripts" / "busy.py"


def test_the_command_runs_beside_busy_processes_which_are_stopped_after_it():
    # the command sees its busy sibling running: busy.py's other child (in /proc), spinning (state R or S)
    probe = ("import os, sys; p = os.getppid(); kids = open(f'/proc/{p}/task/{p}/children').read().split(); "
             "others = [k for k in kids if int(k) != os.getpid()]; "
             "cmd = [open(f'/proc/{k}/cmdline').read() for k in others]; "
             "sys.exit(3 if len(others) == 1 and 'while True' in cmd[0] else 4)")
    r = subprocess.run([sys.executable, str(BUSY), "--procs", "1", "--", sys.executable, "-c", probe],
                       capture_output=True, text=True, timeout=300)
    first = r.stdout.splitlines()[0]
    pid = int(re.search(r"pids (\d+)\)", first).group(1))
    assert r.returncode == 3, r.stdout + r.stderr                   # the command's own exit status
    assert "the command's exit status 3" in r.stdout and "load average (1 min) mean" in r.stdout
    try:
        os.kill(pid, 0)
        with open(f"/proc/{pid}/stat") as f:
            alive = f.read().split()[2] != "Z"
    except (ProcessLookupError, FileNotFoundError):
        alive = False
    assert not alive, f"busy process {pid} still runs"


def test_bad_arguments_are_refused_in_one_line():
    for args, match in ((["--procs", "0", "--", "true"], "--procs: must be at least 1, got 0"),
                        (["--seconds", "nan"], "--seconds: must be > 0, got nan"),
                        (["--seconds", "1", "--", "true"], "a command or --seconds, not both")):
        r = subprocess.run([sys.executable, str(BUSY), *args], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and match in r.stderr.splitlines()[-1], r.stderr
