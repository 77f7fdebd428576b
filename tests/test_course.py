"""A teacher grades the labs with nbgrader (scripts/course.py, docs/labs.md "Grading the labs"): the course
set up from notebooks/, each lab generated and released, two students fetching and submitting through the
exchange (the instructor's answers; a wrong answer to every exercise with one check per lab rewritten to
pass), the submissions collected, autograded and the grades exported."""
from __future__ import annotations

import csv
import glob
import importlib.util
import os
import re
import subprocess
import sys
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COURSE = os.path.join(ROOT, "scripts", "course.py")
NOTEBOOKS = sorted(glob.glob(os.path.join(ROOT, "notebooks", "[0-9][0-9]_*.ipynb")))
LABS = {"lab" + os.path.basename(p)[:2]: p for p in NOTEBOOKS}

# a wrong answer to every exercise: (the instructor's text, the wrong text in its place); each check then
# fails with an AssertionError naming what it expected and what it found
WRONG = {
    "lab01-ex1-answer": ("M11_ratio_pred = M11_stretched / M11_folded", "M11_ratio_pred = 1.0"),  # M11 the same
    "lab01-ex2-answer": ("g_flat = (0, 0, -9.81)", "g_flat = (0, -9.81, 0)"),     # still in the arm's plane
    "lab01-ex3-answer": ("np.cos(q1[0]), np.sin(q1[0])", "1.0, 0.0"),             # along x, as at q = 0
    "lab01-ex4-answer": ("ratio_pred = 2.0**4", "ratio_pred = 2.0**5"),           # the local error's order
    "lab01-ex5-answer": ("0.95 * dt *", "0.5 * dt *"),                            # too small a step: 411 steps
    "lab01-ex6-answer": ('("revolute", "continuous", "prismatic")', '("revolute", "continuous")'),
    "lab02-ex1-answer": ("opening=0.02", "opening=0.03"),
    "lab02-ex2-answer": ("r2.ik_solutions(T2_try, opening=0.02)", "[]"),
    "lab02-ex3-answer": ("cs.plan_cartesian(r, poses[::-1]", "cs.plan_cartesian(r, poses"),  # not reversed
    "lab02-ex4-answer": ("wrong.mass_matrix(q_end) * 900.0", "np.eye(6) * 900.0"),    # the quill's mass forgotten
    "lab02-ex5-answer": ("w_design = 100.0", "w_design = 160.0"),                 # θ4 at its torque limit
    "lab02-ex6-answer": ("+ self.robot.gravity(q)[2]", "+ self.robot.gravity(q)[2]\n        tau[3] = 1e-3"),
    "lab02-ex7-answer": (".idxmax()", ".idxmin()"),
    "lab02-ex8-answer": ('output="metrics")]', 'output="metrics")][::-1]'),
    "lab03-ex1-answer": ("rest = -sum(", "rest = sum("),                          # the bar's force on the floor
    "lab03-ex2-answer": ("mu_stick = 0.37", "mu_stick = 0.3"),                    # below tan 20°: it slides
    "lab03-ex3-answer": ('log_y.contacts["begin"].min()', "0.0"),
    "lab03-ex4-answer": ("d3 = 0.0225", "d3 = q_top[2]"),                          # the wrist in the arm
    "lab03-ex5-answer": ("mask.sum(axis=0)", "mask.any(axis=0).astype(int)"),
    "lab03-ex6-answer": ('failing_pred = ["touching"]', 'failing_pred = ["touching", "in_pads"]'),
    "lab04-ex1-answer": ("math.cos(yaw_deg * DEG), math.sin(yaw_deg * DEG)", "math.cos(yaw_deg), math.sin(yaw_deg)"),
    "lab04-ex2-answer": ("yaw_design = 300", "yaw_design = 290"),                # 81 mm apart, not 10 cm
    "lab04-ex3-answer": ('r.log[0].q[int(np.searchsorted(r.log.t, c["failed_at"])), 2]', "r.log[0].q[0, 2]"),
    "lab05-ex1-answer": ("-BAR_M * G", "BAR_M * G"),
    "lab05-ex2-answer": ("D_crit = 2 * np.sqrt(K_crit * M_crit)", "D_crit = np.sqrt(K_crit * M_crit)"),
    "lab05-ex3-answer": ("F_try + BAR_M * G", "F_try - BAR_M * G"),
    "lab05-ex4-answer": ("self.D * s.error_rate + self.K * s.error", "self.K * s.error"),  # no damping
    "lab06-ex1-answer": ("(1 - share_cmd) * BAR_M * G", "0.5 * BAR_M * G"),      # half the weight, not 70 %
    "lab06-ex2-answer": ("if p > 1.0)", "if p > 0.1)"),
    "lab06-ex3-answer": ("D_follow = 2 * np.sqrt(K_follow * M_follow)", "D_follow = 90.0"),  # rings: too little
    "lab06-ex4-answer": ("part * self.mass * G", "0.0 * part * self.mass * G"),   # the weight forgotten
    "lab07-ex1-answer": (" + model.damping * qd", ""),                             # the jaw's damping left out
    "lab07-ex2-answer": ("2 * (BAR_HALF[1] + 0.005)", "2 * BAR_HALF[1]"),         # the faces on the bar's sides
    "lab07-ex3-answer": (" - r1.tool_jacobian(q_mid).T @ f_bar", ""),             # the bar's weight forgotten
    "lab07-ex4-answer": ("BASE_DISTANCE = 0.52", "BASE_DISTANCE = 0.50"),         # the upper arm 14 mm off the floor
    "lab08-ex1-answer": ("n_zero_pred = 5 ", "n_zero_pred = 6 "),                # the pitch counted as free too
    "lab08-ex2-answer": ("Ad = np.linalg.matrix_power(T, steps)", "Ad = T"),      # one step, not `steps`
    "lab08-ex3-answer": ("(step(x + e, tau) - step(x - e, tau)) / (2 * h)", "(step(x + e, tau) - step(x, tau)) / (2 * h)"),
    "lab08-ex4-answer": ("dq_ok, dqd_ok = 0.022, 3.0", "dq_ok, dqd_ok = 0.01, 3.0"),  # too stiff: saturates
    "lab08-ex5-answer": ("r.mass_matrix(q0) * kp", "np.eye(n) * kp"),            # the inertia forgotten
    "lab08-ex6-answer": ("np.abs(z_cl).max()", "np.abs(z_cl).min()"),            # the fastest mode, not the slowest
    "lab08-ex7-answer": ("share_pred = dy[k_share]", "share_pred = -du[2] / (0.3 * 9.81)"),  # the bar's weight alone
    "lab08-ex8-answer": ("min(eig_soft[", "max(eig_soft["),                   # the fastest pair, not the welds' ring
    "lab09-ex1-answer": ("return np.min(arms, axis=1)", "return np.mean(arms, axis=1)"),  # a lazy partner earns half
    "lab09-ex2-answer": ("r_plus[best] - r_minus[best]", "r_minus[best] - r_plus[best]"),  # a step downhill
    "lab09-ex3-answer": ("k_two_worse = True ", "k_two_worse = False "),         # a loop gain of 2, a period late
}
TAMPER = "assert True  # the check, rewritten by the student"


def _student_labs():
    spec = importlib.util.spec_from_file_location("student_labs", os.path.join(ROOT, "scripts", "student_labs.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _grader(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {})


def _course(course, *args):
    res = subprocess.run([sys.executable, COURSE, str(course), *args], capture_output=True, text=True,
                         timeout=3600, env=dict(os.environ, MPLBACKEND="Agg"))  # a bound for a hung step, not a speed
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return res.stdout + res.stderr


def _exchange(course, home, student, lab, action):
    """What the student's `nbgrader fetch_assignment LAB` / `nbgrader submit LAB` do, in this process."""
    from nbgrader.auth import Authenticator
    from nbgrader.coursedir import CourseDirectory
    from nbgrader.exchange.default import ExchangeFetchAssignment, ExchangeSubmit
    from traitlets.config import Config

    cfg = Config()
    cfg.CourseDirectory.course_id = "coopsim-labs"
    cfg.Exchange.root = str(course / "exchange")
    cfg.Exchange.assignment_dir = str(home)
    cd = CourseDirectory(config=cfg)
    cd.assignment_id, cd.student_id = lab, student
    kind = ExchangeFetchAssignment if action == "fetch" else ExchangeSubmit
    kind(coursedir=cd, authenticator=Authenticator(config=cfg), config=cfg).start()


def _answer(nb, instructor, right: bool) -> str | None:
    """A student's answers in a fetched notebook (changed in place): the instructor's (without the markers),
    or the wrong ones of WRONG with the first check that has no hidden tests rewritten to pass; a written answer
    (graded by hand) is the instructor's model answer, or left unanswered. Returns the grade_id of the
    rewritten check."""
    rewritten = None
    for cell, inst in zip(nb.cells, instructor.cells):
        g = _grader(cell)
        if g.get("solution") and g.get("grade"):   # a written answer: the model answer, or none (nbgrader gives 0)
            if right:
                cell.source = re.sub(r"^[ \t]*### (BEGIN|END) SOLUTION[ \t]*\n", "", inst.source, flags=re.M)
        elif g.get("solution"):
            answer = re.sub(r"^[ \t]*### (BEGIN|END) SOLUTION[ \t]*\n", "", inst.source, flags=re.M)
            if right:
                cell.source = answer
            else:
                line, wrong = WRONG[g["grade_id"]]
                assert answer.count(line) == 1, g["grade_id"]
                cell.source = answer.replace(line, wrong)
        elif g.get("grade") and not right and rewritten is None and "HIDDEN" not in inst.source:
            cell.source, rewritten = TAMPER, g["grade_id"]
    return rewritten


@pytest.mark.slow
def test_a_course_grades_the_instructors_answers_full_and_wrong_answers_with_a_rewritten_check_zero(tmp_path):
    pytest.importorskip("nbgrader", reason="nbgrader is installed by the teaching extra (scripts/setup.sh)")
    import nbformat

    import coopsim as cs

    if cs.build_info()["sanitizers"]:  # scripts/test_sanitized.sh: the engine's memory, not the grading
        pytest.skip("the course runs every lab twice through nbgrader; the labs run against the sanitized "
                    "engine in tests/test_notebooks_and_examples.py")

    sl = _student_labs()
    course = tmp_path / "course"
    took = [time.perf_counter()]
    out = _course(course, "setup", "generate", "release")
    took.append(time.perf_counter())
    # nbgrader's student versions are scripts/student_labs.py's: the same stubs, locks and checksums
    for lab, path in LABS.items():
        released = nbformat.read(course / "release" / lab / os.path.basename(path), as_version=4)
        assert released == sl.student_version(nbformat.read(path, as_version=4)), lab
        assert (course / "exchange" / "coopsim-labs" / "outbound" / lab / os.path.basename(path)).is_file()
    assert "Released as: coopsim-labs lab06" in out

    rewritten = {}
    for student, right in (("alice", True), ("bob", False)):
        home = tmp_path / student
        for lab, path in LABS.items():
            _exchange(course, home, student, lab, "fetch")
            nb_path = home / lab / os.path.basename(path)
            nb = nbformat.read(nb_path, as_version=4)
            got = _answer(nb, nbformat.read(path, as_version=4), right)
            if not right:
                rewritten[lab] = got
            nbformat.write(nb, nb_path)
            _exchange(course, home, student, lab, "submit")
    assert all(rewritten.values()) and len(rewritten) == len(LABS)
    took.append(time.perf_counter())

    out = _course(course, "collect", "autograde", "--jobs", "2")
    # the teacher grades the written answers by hand (formgrader writes the same field): full points for the
    # instructor's model answers; bob answered none, and nbgrader gave those 0 without asking for a hand grade
    from nbgrader.api import Gradebook

    hand = {}
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gb:
        for lab in LABS:
            for student in ("alice", "bob"):
                for nb in gb.find_submission(lab, student).notebooks:
                    for grade in nb.grades:
                        if grade.needs_manual_grade:
                            hand.setdefault((lab, student), []).append(grade.name)
                            grade.manual_score, grade.needs_manual_grade = grade.max_score, False
            gb.db.commit()
    out += _course(course, "export")
    took.append(time.perf_counter())
    # the figures docs/labs.md quotes (pytest -s shows them)
    print("course: setup+generate+release {:.0f} s, students {:.0f} s, collect+autograde+export {:.0f} s".format(
        *(b - a for a, b in zip(took, took[1:]))))
    with open(course / "grades.csv", newline="", encoding="utf-8") as f:
        grades = {(r["assignment"], r["student_id"]): r for r in csv.DictReader(f)}
    assert sorted(grades) == sorted((lab, s) for lab in LABS for s in ("alice", "bob"))
    for lab, path in LABS.items():
        instructor = nbformat.read(path, as_version=4)
        points = sum(_grader(c).get("points", 0) for c in instructor.cells if _grader(c).get("grade"))
        written = {_grader(c)["grade_id"]: _grader(c)["points"] for c in instructor.cells
                   if _grader(c).get("grade") and _grader(c).get("solution")}
        assert hand.get((lab, "alice"), []) == list(written) and (lab, "bob") not in hand, (lab, hand)
        alice, bob = grades[(lab, "alice")], grades[(lab, "bob")]
        assert float(alice["max_score"]) == points and float(alice["score"]) == points, (lab, alice)
        assert float(bob["max_score"]) == points and float(bob["score"]) == 0.0, (lab, bob)
        # the rewritten check: named by the script and by nbgrader, graded as the instructor wrote it (it fails)
        gid = rewritten[lab]
        assert f"course: {lab} bob: 0 / {points:g} points; checks changed in the submission (graded as " \
               f"released): {gid}: changed (graded in " in out
        by_hand = f" ({sum(written.values()):g} to grade by hand)" if written else ""
        assert f"course: {lab} alice: {points - sum(written.values()):g} / {points:g} points{by_hand}; checks as " \
               f"released (graded in " in out
        assert re.search(rf"Attribute 'checksum' for cell {gid} has changed", out), gid
        graded = nbformat.read(course / "autograded" / "bob" / lab / os.path.basename(path), as_version=4)
        cell = next(c for c in graded.cells if _grader(c).get("grade_id") == gid)
        source = next(c for c in instructor.cells if _grader(c).get("grade_id") == gid).source
        assert cell.source == source != TAMPER
        # every check fails on its wrong answer with a message naming the value expected and the one found
        for c in graded.cells:
            if _grader(c).get("grade") and not _grader(c).get("solution"):
                errors = [o for o in c.outputs if o.output_type == "error"]
                assert len(errors) == 1 and errors[0].ename == "AssertionError", (_grader(c)["grade_id"], c.outputs)
                assert re.search(r"^[^:\n]+: expected .+, found .+", errors[0].evalue), errors[0].evalue
        # the instructor's answers pass every check, hidden tests included
        graded = nbformat.read(course / "autograded" / "alice" / lab / os.path.basename(path), as_version=4)
        for c in graded.cells:
            if _grader(c).get("grade") and not _grader(c).get("solution"):
                assert not [o for o in c.outputs if o.output_type == "error" or o.get("name") == "stderr"], \
                    (lab, _grader(c)["grade_id"], c.outputs)
        hidden = [c for c in instructor.cells if "### BEGIN HIDDEN TESTS" in c.source]
        for h in hidden:
            assert next(c for c in graded.cells if _grader(c).get("grade_id") == _grader(h)["grade_id"]).source \
                == h.source
    with open(course / "changed_checks.csv", newline="", encoding="utf-8") as f:
        changed = [(r["assignment"], r["student_id"], r["check"], r["what"]) for r in csv.DictReader(f)]
    assert changed == [(lab, "bob", rewritten[lab], "changed") for lab in sorted(LABS)]


def test_the_course_script_says_what_is_wrong_in_one_line(tmp_path):
    for args, message in [
        ([str(tmp_path), "grade"], "a step is needed: one or more of setup, generate, release, collect, autograde, export"),
        ([str(tmp_path), "setup", "99"], "no step or lab '99' (the steps: setup, generate, release, collect, "
                                          f"autograde, export; the labs: {', '.join(sorted(LABS))})"),
        ([str(tmp_path), "autograde"], f"{tmp_path} is not a course folder: run 'scripts/course.py {tmp_path} setup' first"),
        ([str(tmp_path), "autograde", "--jobs", "0"], "--jobs must be >= 1, got 0"),
    ]:
        res = subprocess.run([sys.executable, COURSE, *args], capture_output=True, text=True, timeout=120)
        assert res.returncode == 2 and res.stderr.splitlines()[-1].endswith(message), (args, res.stderr)
        assert "Traceback" not in res.stderr
    assert not any(tmp_path.iterdir()), "nothing written"
