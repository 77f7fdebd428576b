"""Regenerates every file in cpp/generated: ``python -m coopsim.codegen [--out DIR] [--check]``.

Run from the repository root (default DIR is ./cpp/generated), with coopsim
installed (the robots' tables come from ``coopsim.robots``). --check writes
nothing and exits 1 with a diff if any committed file differs.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import sympy as sp

from .builtin import check_generated, write_generated
from .files import SYMPY_VERSION


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m coopsim.codegen", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="cpp/generated", help="output folder (default: cpp/generated)")
    ap.add_argument("--check", action="store_true", help="compare with the files in --out, write nothing")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if sp.__version__ != SYMPY_VERSION:
        print(f"warning: sympy {sp.__version__} is not the pinned {SYMPY_VERSION}; the output will differ "
              f"from the committed files (pip install sympy=={SYMPY_VERSION})", file=sys.stderr)
    t0 = time.perf_counter()
    if args.check:
        diff = check_generated(out)
        if diff:
            sys.stdout.write(diff)
            print(f"generated files in {out} differ from the generator", file=sys.stderr)
            return 1
        print(f"{out}: up to date ({time.perf_counter() - t0:.1f} s)")
        return 0
    if not out.is_dir():
        ap.error(f"--out {out} is not a folder (run from the repository root or pass --out)")
    written = write_generated(out)
    for name in written:
        print(f"wrote {out / name}")
    print(f"generated in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
