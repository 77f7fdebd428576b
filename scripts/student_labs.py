"""Writes the student versions of the labs in notebooks/ (the instructor's versions) to OUT_DIR.

    python3 scripts/student_labs.py OUT_DIR [NOTEBOOK ...]      (default: every notebooks/*.ipynb)
    python3 scripts/student_labs.py --verify SUBMISSION ...     (a student's notebooks: checks untouched?)

The labs follow nbgrader's conventions, so `nbgrader generate_assignment` makes the same student
versions from them: an exercise is a solution cell (cell metadata ``nbgrader.solution``) whose
answer lies between ``### BEGIN SOLUTION`` and ``### END SOLUTION``, followed by a locked check
cell (``nbgrader.grade``) of asserts, whose ``### BEGIN HIDDEN TESTS`` ... ``### END HIDDEN TESTS``
part the student does not see. In the student version each answer becomes a stub, indented as its
markers, that raises ``NotImplementedError("Your turn: ...")``; checks stay, hidden tests go, and
every output and execution count is cleared. A written answer is a markdown solution cell that is also
a grade cell (graded by hand, its model answer and rubric between the markers): its answer becomes
nbgrader's text stub, ``YOUR ANSWER HERE``.

The student version is locked as nbgrader's ``generate_assignment`` locks it (its LockCells and
ComputeChecksums steps): a check cell is read-only and undeletable (``metadata.editable = false``,
``metadata.deletable = false``), an answer cell undeletable, and each cell nbgrader grades carries
``nbgrader.checksum`` (nbgrader's rule, :func:`checksum`) and ``nbgrader.cell_type``. With
nbgrader's ``ClearSolutions.code_stub`` set to this script's stub (scripts/course.py does), nbgrader's
release and these student versions are the same notebooks. ``--verify`` compares a submitted
notebook's check cells with the student version of the instructor's notebook of the same name and
names each check that was changed or deleted (exit status 1); nbgrader's ``autograde`` does the
same and grades with the instructor's checks.
"""
from __future__ import annotations

import argparse
import glob
import hashlib
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STUB = 'raise NotImplementedError("Your turn: replace this line with your answer, then run the check below")'
TEXT_STUB = "YOUR ANSWER HERE"   # nbgrader's ClearSolutions.text_stub: a written answer's stub (a markdown cell)
_SOLUTION = re.compile(r"^([ \t]*)### BEGIN SOLUTION[ \t]*\n.*?^[ \t]*### END SOLUTION[ \t]*$", re.M | re.S)
_HIDDEN = re.compile(r"^[ \t]*### BEGIN HIDDEN TESTS[ \t]*\n.*?^[ \t]*### END HIDDEN TESTS[ \t]*(\n|\Z)", re.M | re.S)


def _nbgrader(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {})


def _is_grade(cell) -> bool:
    return bool(_nbgrader(cell).get("grade", False))


def _is_solution(cell) -> bool:
    return bool(_nbgrader(cell).get("solution", False))


def _is_locked(cell) -> bool:
    """nbgrader's rule: a solution cell is never locked, a grade (check) cell always, others as marked."""
    if not _nbgrader(cell) or _is_solution(cell):
        return False
    return True if _is_grade(cell) else bool(_nbgrader(cell).get("locked", False))


def checksum(cell) -> str:
    """nbgrader's checksum of a cell (nbgrader.utils.compute_checksum, nbgrader 0.7 to 0.9): the MD5 hex
    digest of its source, its type, whether it is a grade, a solution and a locked cell, its grade_id and,
    for a grade cell, its points as a float. nbgrader records it at release and, at autograding, gives a
    locked cell whose checksum changed back its instructor's source. tests/test_labs.py checks it against
    nbgrader's own function on every cell of the labs."""
    meta = _nbgrader(cell)
    if "grade_id" not in meta:
        raise ValueError("cell has no nbgrader.grade_id: it is not one nbgrader grades")
    m = hashlib.md5()
    for part in (cell.source, cell.cell_type, str(_is_grade(cell)), str(_is_solution(cell)),
                 str(_is_locked(cell)), meta["grade_id"]):
        m.update(part.encode("utf-8"))
    if _is_grade(cell):
        m.update(str(float(meta["points"])).encode("utf-8"))
    return m.hexdigest()


def _lock(cell) -> None:
    """nbgrader's LockCells and ComputeChecksums on one cell of a student version (in place)."""
    if _is_solution(cell):
        cell.metadata["deletable"] = False          # an answer cell stays editable
    elif _is_grade(cell) or _is_locked(cell):
        cell.metadata["deletable"] = False
        cell.metadata["editable"] = False
    if _is_grade(cell) or _is_solution(cell) or _is_locked(cell):
        cell.metadata["nbgrader"]["checksum"] = checksum(cell)
        cell.metadata["nbgrader"]["cell_type"] = cell.cell_type


def _check_markers(source: str, begin: str, end: str, where: str) -> None:
    b, e = source.count(begin), source.count(end)
    if b != e:
        raise ValueError(f"{where}: {b} '{begin}' but {e} '{end}'")


def student_source(source: str, where: str = "cell", cell_type: str = "code") -> str:
    """The source of a solution cell with every answer region replaced by the stub (same indentation): the code
    stub in a code cell, nbgrader's text stub in a markdown cell (a written answer, graded by hand)."""
    _check_markers(source, "### BEGIN SOLUTION", "### END SOLUTION", where)
    if "### BEGIN SOLUTION" not in source:
        raise ValueError(f"{where}: a solution cell needs a ### BEGIN SOLUTION ... ### END SOLUTION region")
    if cell_type == "markdown":
        return _SOLUTION.sub(lambda m: m.group(1) + TEXT_STUB, source)
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
            cell.source = student_source(src, where, cell.cell_type)
        elif "### BEGIN SOLUTION" in src:
            raise ValueError(f"{where}: a ### BEGIN SOLUTION region outside a solution cell (nbgrader.solution)")
        _check_markers(cell.source, "### BEGIN HIDDEN TESTS", "### END HIDDEN TESTS", where)
        if "### BEGIN HIDDEN TESTS" in cell.source:
            if not meta.get("grade"):
                raise ValueError(f"{where}: hidden tests outside a check cell (nbgrader.grade)")
            cell.source = _HIDDEN.sub("", cell.source).rstrip("\n")
        _lock(cell)
    out.metadata.pop("celltoolbar", None)
    return out


def tampered(submission, instructor, name: str = "notebook") -> list[str]:
    """The locked cells (the checks) of a student's submitted notebook that are not those of the student
    version of ``instructor`` (both nbformat NotebookNodes): one line per cell, "<grade_id>: changed" or
    "<grade_id>: deleted". Empty when every check is as released. A check is compared by its checksum
    computed from the submitted cell (source, type, flags, points), not by the checksum it carries, which
    a student can rewrite."""
    expected = {_nbgrader(c)["grade_id"]: checksum(c) for c in student_version(instructor, name).cells
                if _is_locked(c)}
    found = {}
    for cell in submission.cells:
        gid = _nbgrader(cell).get("grade_id")
        if gid in expected:
            found[gid] = checksum(cell) if found.get(gid) is None else "twice"
    return [f"{gid}: {'deleted' if gid not in found else 'changed'}" for gid in expected
            if found.get(gid) != expected[gid]]


def main(argv=None) -> int:
    import nbformat

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir", nargs="?", help="folder for the student notebooks (made if missing)")
    ap.add_argument("notebooks", nargs="*", help="instructor notebooks (default: notebooks/*.ipynb)")
    ap.add_argument("--verify", nargs="+", metavar="SUBMISSION",
                    help="submitted student notebooks to compare, check cell by check cell, with the student "
                         "versions of the instructor's notebooks of the same names")
    ap.add_argument("--instructor", default=os.path.join(ROOT, "notebooks"),
                    help="with --verify: the folder of the instructor's notebooks (default: notebooks/)")
    args = ap.parse_args(argv)
    if args.verify:
        if args.out_dir is not None:
            ap.error("--verify takes submissions only, no OUT_DIR")
        return _verify(ap, args.verify, args.instructor)
    if args.out_dir is None:
        ap.error("the following arguments are required: out_dir")
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


def _verify(ap, submissions, instructor_dir) -> int:
    import nbformat

    bad = 0
    for path in submissions:
        source = os.path.join(instructor_dir, os.path.basename(path))
        for p, what in ((path, "submission"), (source, "instructor's notebook")):
            if not os.path.isfile(p):
                ap.error(f"{what} not found: {p}")
        try:
            found = tampered(nbformat.read(path, as_version=4), nbformat.read(source, as_version=4),
                             os.path.basename(path))
        except (ValueError, KeyError, nbformat.reader.NotJSONError) as e:
            raise SystemExit(f"student_labs: {path}: {e}") from None
        bad += bool(found)
        print(f"{path}: " + ("checks as released" if not found else "TAMPERED " + ", ".join(found)))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
