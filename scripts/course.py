"""An nbgrader course of the labs in notebooks/: one assignment per lab (notebooks/NN_*.ipynb is labNN).

    python3 scripts/course.py COURSE_DIR STEP [STEP ...] [LAB ...] [--jobs N]

The teacher's steps, in order (docs/labs.md, "Grading the labs"):

    setup      the course folder: nbgrader_config.py (kept when there), source/labNN/ from notebooks/
               (refreshed: the repository's notebooks are the instructor's versions), exchange/
    generate   release/labNN/: the student versions, answers stubbed, hidden tests removed, checks locked,
               and the gradebook (gradebook.db) with each check's source and checksum
    release    the student versions to the exchange, where students fetch them
               (students: nbgrader fetch_assignment labNN, answer, nbgrader submit labNN)
    collect    the exchange's submissions into submitted/STUDENT/labNN/ (newer ones replace older ones)
    autograde  autograded/STUDENT/labNN/: every submission run with the instructor's checks, hidden
               tests included; a check the student changed or deleted is named here and graded as
               the instructor wrote it. One line per submission: its points, the points of its
               written answers still to grade by hand (nbgrader's formgrader), its changed checks.
    export     COURSE_DIR/grades.csv (nbgrader's CSV: a row per lab and student) and
               COURSE_DIR/changed_checks.csv (a row per check a submission had changed or deleted)

Several steps run in the order given (e.g. ``setup generate release``, later ``collect autograde
export``), in one process: nbgrader, 2 to 6 s to import, is loaded once. LAB is labNN or NN (default:
every lab). Every step may be run again. --jobs N autogrades N submissions at a time (default 1; each
runs its notebook in a kernel of its own). nbgrader comes with the ``teaching`` extra (scripts/setup.sh
installs it).
"""
from __future__ import annotations

import argparse
import csv
import glob
import importlib.util
import os
import shutil
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import student_labs  # noqa: E402  (scripts/student_labs.py: the stub, the checksums, tampered())

STEPS = ("setup", "generate", "release", "collect", "autograde", "export")
COURSE_ID = "coopsim-labs"
CONFIG = '''# nbgrader's configuration of the coopsim labs' course, written by scripts/course.py setup (edit freely:
# setup keeps it). https://nbgrader.readthedocs.io/en/stable/configuration/config_options.html
c = get_config()  # noqa: F821
c.CourseDirectory.course_id = {course_id!r}
c.CourseDirectory.root = {root!r}
# the exchange through which students fetch and submit: a folder every student can write to
# (on a shared server, e.g. "/srv/nbgrader/exchange")
c.Exchange.root = {exchange!r}
# scripts/student_labs.py's stub: nbgrader's release and that script's student versions are the same notebooks
c.ClearSolutions.code_stub = {{"python": {stub!r}}}
# a lab runs in about a minute on 2 cores; its slowest cell in well under 60 s
c.Execute.timeout = 600
'''


def labs() -> dict[str, str]:
    """Every lab: its assignment name (labNN) and the instructor's notebook (path)."""
    return {"lab" + os.path.basename(p)[:2]: p
            for p in sorted(glob.glob(os.path.join(ROOT, "notebooks", "[0-9][0-9]_*.ipynb")))}


def _api(course_dir: str):
    """nbgrader's API (NbGraderAPI) on the course folder, configured by its nbgrader_config.py."""
    from nbgrader.apps import NbGraderAPI
    from nbgrader.coursedir import CourseDirectory
    from traitlets.config.loader import PyFileConfigLoader

    cfg = PyFileConfigLoader("nbgrader_config.py", path=course_dir).load_config()
    cfg.CourseDirectory.root = os.path.abspath(course_dir)
    cfg.ExchangeReleaseAssignment.force = True  # a release again replaces the one in the exchange
    return NbGraderAPI(coursedir=CourseDirectory(config=cfg), config=cfg), cfg


def _run(what: str, result: dict) -> None:
    """Prints an nbgrader step's log; a failed step ends the script with its error."""
    if result.get("log"):
        print(result["log"].rstrip())
    if not result["success"]:
        print(result.get("error", ""), file=sys.stderr)
        raise SystemExit(f"course: {what} failed")


def setup(course_dir: str, names: list[str], course_id: str) -> None:
    os.makedirs(os.path.join(course_dir, "exchange"), exist_ok=True)
    os.chmod(os.path.join(course_dir, "exchange"), 0o777)  # nbgrader's rule for its exchange
    root = os.path.abspath(course_dir)
    config = os.path.join(course_dir, "nbgrader_config.py")
    if not os.path.exists(config):
        with open(config, "w", encoding="utf-8") as f:
            f.write(CONFIG.format(course_id=course_id, root=root, exchange=os.path.join(root, "exchange"),
                                  stub="# YOUR CODE HERE\n" + student_labs.STUB))
    for name in names:
        dest = os.path.join(course_dir, "source", name)
        shutil.rmtree(dest, ignore_errors=True)
        os.makedirs(dest)
        shutil.copy(labs()[name], dest)
    print(f"course: {course_dir} set up with {', '.join(names)}")


def _submissions(api, names: list[str]) -> list[tuple[str, str]]:
    """(lab, student) of every collected submission of the labs named."""
    out = []
    for name in names:
        for path in sorted(glob.glob(os.path.join(api.coursedir.root, api.coursedir.submitted_directory, "*", name))):
            out.append((name, os.path.basename(os.path.dirname(path))))
    return out


def changed_checks(api, name: str, student: str) -> list[str]:
    """The checks of a student's submitted lab that are not as released ("<grade_id>: changed|deleted")."""
    import nbformat

    found = []
    folder = os.path.join(api.coursedir.root, api.coursedir.submitted_directory, student, name)
    for src in sorted(glob.glob(os.path.join(api.coursedir.root, api.coursedir.source_directory, name, "*.ipynb"))):
        sub = os.path.join(folder, os.path.basename(src))
        if not os.path.exists(sub):
            found.append(f"{os.path.basename(src)}: not submitted")
            continue
        found += student_labs.tampered(nbformat.read(sub, as_version=4), nbformat.read(src, as_version=4),
                                       os.path.basename(src))
    return found


def _autograde_one(course_dir: str, name: str, student: str) -> tuple[bool, str, float]:
    t0 = time.perf_counter()
    api, _ = _api(course_dir)
    res = api.autograde(name, student)
    return (res["success"], res.get("log", "") + (res.get("error", "") if not res["success"] else ""),
            time.perf_counter() - t0)


def autograde(course_dir: str, names: list[str], jobs: int) -> None:
    from nbgrader.api import Gradebook

    api, _ = _api(course_dir)
    todo = _submissions(api, names)
    if not todo:
        print(f"course: no submissions of {', '.join(names)} in {api.coursedir.submitted_directory}/")
        return
    with Gradebook(api.coursedir.db_url) as gb:  # students made here, once, not by two graders at a time
        for student in sorted({s for _, s in todo}):
            gb.update_or_create_student(student)
    if jobs == 1:
        results = [_autograde_one(course_dir, n, s) for n, s in todo]
    else:
        import multiprocessing

        # forked workers share the imported nbgrader; each opens the gradebook (SQLite) for its own writes.
        # One submission at a time to whichever worker is free, the later (longer) labs first
        order = sorted(range(len(todo)), key=lambda k: todo[k][0], reverse=True)
        with multiprocessing.get_context("fork").Pool(jobs) as pool:
            done = pool.starmap(_autograde_one, [(course_dir, *todo[k]) for k in order], chunksize=1)
        results = [None] * len(todo)
        for k, r in zip(order, done):
            results[k] = r
    failed = []
    with Gradebook(api.coursedir.db_url) as gb:
        for (name, student), (ok, log, took) in zip(todo, results):
            print(log.rstrip())
            if not ok:
                failed.append(f"{name} {student}")
                continue
            sub = gb.find_submission(name, student)
            changed = changed_checks(api, name, student)
            by_hand = sum(g.max_score for nb in sub.notebooks for g in nb.grades if g.needs_manual_grade)
            print(f"course: {name} {student}: {sub.score:g} / {sub.max_score:g} points"
                  + (f" ({by_hand:g} to grade by hand)" if by_hand else "") + "; "
                  + ("checks as released" if not changed else
                     "checks changed in the submission (graded as released): " + ", ".join(changed))
                  + f" (graded in {took:.0f} s)")
    if failed:
        raise SystemExit(f"course: autograde failed for {', '.join(failed)}")


def export(course_dir: str) -> None:
    from nbgrader.api import Gradebook
    from nbgrader.plugins import CsvExportPlugin

    api, cfg = _api(course_dir)
    plugin = CsvExportPlugin(config=cfg)
    plugin.to = os.path.join(api.coursedir.root, "grades.csv")
    with Gradebook(api.coursedir.db_url) as gb:
        plugin.export(gb)
    changed = os.path.join(api.coursedir.root, "changed_checks.csv")
    with open(changed, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["assignment", "student_id", "check", "what"])
        for name, student in _submissions(api, sorted(labs())):
            for line in changed_checks(api, name, student):
                w.writerow([name, student, *line.rsplit(": ", 1)])
    print(f"course: grades in {plugin.to}, changed checks in {changed}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("course_dir", help="the course folder (made by setup)")
    ap.add_argument("steps_and_labs", nargs="+", metavar="STEP_OR_LAB",
                    help="steps, of " + ", ".join(STEPS) + " (run in the order given), then labs: labNN or NN "
                         "(default: every lab)")
    ap.add_argument("--jobs", type=int, default=1, help="autograde: submissions graded at a time (default 1)")
    ap.add_argument("--course-id", default=COURSE_ID, help=f"setup: the course's name in the exchange "
                                                           f"(default {COURSE_ID})")
    args = ap.parse_args(argv)
    steps = [a for a in args.steps_and_labs if a in STEPS]
    given = [a for a in args.steps_and_labs if a not in STEPS]
    if not steps:
        ap.error(f"a step is needed: one or more of {', '.join(STEPS)}")
    if args.jobs < 1:
        ap.error(f"--jobs must be >= 1, got {args.jobs}")
    known = labs()
    names = []
    for a in given or sorted(known):
        name = "lab" + a if len(a) == 2 and a.isdigit() else a
        if name not in known:
            ap.error(f"no step or lab {a!r} (the steps: {', '.join(STEPS)}; the labs: {', '.join(sorted(known))})")
        names.append(name)
    if importlib.util.find_spec("nbgrader") is None:
        ap.error("nbgrader is not installed: pip install '.[teaching]' (scripts/setup.sh installs it)")
    config = os.path.join(args.course_dir, "nbgrader_config.py")
    if steps[0] != "setup" and not os.path.isfile(config):
        ap.error(f"{args.course_dir} is not a course folder: run 'scripts/course.py {args.course_dir} setup' first")
    for step in steps:
        if step == "setup":
            setup(args.course_dir, names, args.course_id)
        elif step == "autograde":
            autograde(args.course_dir, names, args.jobs)
        elif step == "export":
            export(args.course_dir)
        else:
            api, _ = _api(args.course_dir)
            for name in names:
                if step == "generate":
                    _run(f"generate {name}", api.generate_assignment(name))
                elif step == "release":
                    _run(f"release {name}", api.release_assignment(name))
                else:
                    _run(f"collect {name}", api.collect(name))
    return 0


if __name__ == "__main__":
    sys.exit(main())
