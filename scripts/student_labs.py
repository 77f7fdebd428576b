"""Writes the student versions of the labs in notebooks/ (the instructor's versions) to OUT_DIR.

    python3 scripts/student_labs.py OUT_DIR [NOTEBOOK ...]      (default: every notebooks/*.ipynb)

The labs follow nbgrader's conventions, so `nbgrader generate_assignment` makes the same student
versions from them: an exercise is a solution cell (cell metadata ``nbgrader.solution``) whose
answer lies between ``### BEGIN SOLUTION`` and ``### END SOLUTION``, followed by a locked check
cell (``nbgrader.grade``) of asserts, whose ``### BEGIN HIDDEN TESTS`` ... ``### END HIDDEN TESTS``
part the student does not see. In the student version each answer becomes a stub, indented as its
markers, that raises ``NotImplementedError("Your turn: ...")``; checks stay, hidden tests go, and
every output and execution count is cleared.
"""
from __future__ import annotations

import argparse
import glob
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STUB = 'raise NotImplementedError("Your turn: replace this line with your answer, then run the check below")'
_SOLUTION = re.compile(r"^([ \t]*)### BEGIN SOLUTION[ \t]*\n.*?^[ \t]*### END SOLUTION[ \t]*$", re.M | re.S)
_HIDDEN = re.compile(r"^[ \t]*### BEGIN HIDDEN TESTS[ \t]*\n.*?^[ \t]*### END HIDDEN TESTS[ \t]*(\n|\Z)", re.M | re.S)


def _nbgrader(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {})


def _check_markers(source: str, begin: str, end: str, where: str) -> None:
    b, e = source.count(begin), source.count(end)
    if b != e:
        raise ValueError(f"{where}: {b} '{begin}' but {e} '{end}'")


def student_source(source: str, where: str = "cell") -> str:
    """The source of a solution cell with every answer region replaced by the stub (same indentation)."""
    _check_markers(source, "### BEGIN SOLUTION", "### END SOLUTION", where)
    if "### BEGIN SOLUTION" not in source:
        raise ValueError(f"{where}: a solution cell needs a ### BEGIN SOLUTION ... ### END SOLUTION region")
    return _SOLUTION.sub(lambda m: m.group(1) + "# YOUR CODE HERE\n" + m.group(1) + STUB, source)


def student_version(nb, name: str = "notebook"):
    """A student copy of an instructor's notebook (an nbformat NotebookNode); the input is not changed."""
    import copy

    out = copy.deepcopy(nb)
    for k, cell in enumerate(out.cells):
        where = f"{name} cell {k}"
        meta = _nbgrader(cell)
        src = cell.source
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
        if meta.get("solution"):
            cell.source = student_source(src, where)
        elif "### BEGIN SOLUTION" in src:
            raise ValueError(f"{where}: a ### BEGIN SOLUTION region outside a solution cell (nbgrader.solution)")
        _check_markers(cell.source, "### BEGIN HIDDEN TESTS", "### END HIDDEN TESTS", where)
        if "### BEGIN HIDDEN TESTS" in cell.source:
            if not meta.get("grade"):
                raise ValueError(f"{where}: hidden tests outside a check cell (nbgrader.grade)")
            cell.source = _HIDDEN.sub("", cell.source).rstrip("\n")
    return out


def main(argv=None) -> int:
    import nbformat

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir", help="folder for the student notebooks (made if missing)")
    ap.add_argument("notebooks", nargs="*", help="instructor notebooks (default: notebooks/*.ipynb)")
    args = ap.parse_args(argv)
    paths = args.notebooks or sorted(glob.glob(os.path.join(ROOT, "notebooks", "*.ipynb")))
    for path in paths:  # every input checked before anything is written: one line each, no traceback
        if not os.path.isfile(path):
            ap.error(f"notebook not found: {path}")
        if not path.endswith(".ipynb"):
            ap.error(f"not a notebook (.ipynb): {path}")
    os.makedirs(args.out_dir, exist_ok=True)
    for path in paths:
        try:
            nb = nbformat.read(path, as_version=4)
            student = student_version(nb, os.path.basename(path))
        except (ValueError, nbformat.reader.NotJSONError) as e:
            raise SystemExit(f"student_labs: {path}: {e}") from None
        dest = os.path.join(args.out_dir, os.path.basename(path))
        if os.path.abspath(dest) == os.path.abspath(path):
            raise SystemExit(f"student_labs: {dest} would overwrite the instructor's version")
        nbformat.write(student, dest)
        exercises = sum(bool(_nbgrader(c).get("solution")) for c in nb.cells)
        print(f"{dest}: {exercises} exercises")
    return 0


if __name__ == "__main__":
    sys.exit(main())
