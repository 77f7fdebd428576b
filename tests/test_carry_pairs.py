"""The carry with other arms (coopsim.tasks.carry.run(robots=...)): two UR5s and two Pandas of example-robot-data
with the paper's clamp, placed facing each other across the bar's path; the plan reached on one branch per arm
with clearances between the collision shapes, the stands and the floor; the Pandas' redundancy drawn to their
rest posture; every named controller completing the default carry with each pair, every disturbance run and
scored; a pair of one's own; bad input; the SCARAs' carry unchanged."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from coopsim.tasks import carry as C
from coopsim.tasks.carry import cli, constants as K, pairs as PR, planning as P, scene as S
from coopsim.tasks.carry.scoring import score_row

ARMS = ("ur5", "panda")
G = 9.81


@pytest.fixture(scope="module")
def plans():
    return {w: P.make_plan(robots=w) for w in ARMS}


class _Runs(dict):
    """The carries of this module, each run once when a test first asks for it: (pair, controller, disturbance)."""

    def __missing__(self, key):
        which, controller, disturbance = key
        self[key] = C.run(robots=which, controllers=controller, disturbance=disturbance)
        return self[key]


@pytest.fixture(scope="module")
def runs():
    return _Runs()


# ---- the pairs in the views ----

@pytest.mark.parametrize("which", ARMS)
def test_the_views_draw_the_pairs_arms_by_their_meshes_and_their_clamps_as_boxes(which):
    """The live page, the replay and the animation draw a robot as coopsim.view.parts.robot_parts gives it: the
    pair's arms by their URDF meshes (every link that has one in the file, the last one turned with add_clamp's
    DH row), the clamp add_clamp put on them as its three boxes, where the robot's own boxes of those names are."""
    from coopsim.view.parts import look_kind, part_poses, robot_parts

    for r in C.pair(which).robots:
        assert look_kind(r) == "urdf"
        parts = robot_parts(r)
        n = r.dof - 1                          # the arm's last link; n + 1: the moving jaw's
        meshed = {p.link for p in parts if p.shape == "mesh"}
        assert set(range(1, n + 1)) <= meshed and n + 1 not in meshed
        q = 0.5 * (r.q_limits[:, 0] + r.q_limits[:, 1]) + 0.1
        poses = part_poses(r, parts, q)
        shapes, halves = r.shapes(q)
        by_name = {b.name: k for k, b in enumerate(r.boxes)}
        for name, link in (("clamp_body", n), ("fixed_jaw", n), ("moving_jaw", n + 1)):
            [k] = [k for k, p in enumerate(parts) if p.shape == "box" and p.name.endswith("_" + name)]
            assert parts[k].link == link
            b = by_name[name]
            np.testing.assert_allclose(poses[k], shapes[b], atol=1e-12)
            np.testing.assert_allclose(parts[k].scale, 2 * np.asarray(halves[b]), atol=1e-12)


# ---- the pairs and their plans ----

@pytest.mark.parametrize("which", ARMS)
def test_the_named_pairs_face_each_other_across_the_bar_s_path(which):
    """Both arms carry the clamp; #1 stands on the bar's +x side of the path's centre (its grip's side), #2 on
    the other, as far, each base's x axis pointing at the centre; the two are the same arm."""
    pair = C.pair(which)
    c, u = PR.path_frame()
    d = (PR.UR5 if which == "ur5" else PR.PANDA)["distance"]
    assert pair.name == which and pair.names == tuple(f"{which.upper() if which == 'ur5' else 'Panda'} #{i}"
                                                     for i in (1, 2))
    for r, s in zip(pair.robots, (1.0, -1.0)):
        assert r.clamp is not None and r.joint_types.endswith("P")
        np.testing.assert_allclose(r.base_position, c + s * d * u, atol=1e-12)
        x = np.array([math.cos(r.base_yaw), math.sin(r.base_yaw), 0.0])
        np.testing.assert_allclose(x, -s * u, atol=1e-12)
    np.testing.assert_array_equal(pair.robots[0].dh, pair.robots[1].dh)
    assert pair.robots[0].dof == (7 if which == "ur5" else 8)
    assert pair.simulation == dict(dt=1e-3, world_every=1, control_every=1)


@pytest.mark.parametrize("which", ARMS)
def test_the_plan_reaches_the_path_on_one_branch_with_clearances(which, plans):
    """Every knot of the carry is the bar's planned pose times the clamp's grip (the numeric IK to 1e-9); the
    arms stay within their limits, on one branch (the UR5s' elbow sign and wrist away from its singularity, the
    Pandas' elbow bent; no joint steps more than MAX_KNOT_STEP between knots; the arm's Jacobian well
    conditioned throughout); the collision shapes clear each other, the stands and the floor."""
    plan = plans[which]
    for i, r in enumerate(plan.robots):
        tk, Q = plan.knots[i]
        held = (tk >= plan.steps["lift"][0]) & (tk <= plan.steps["place"][1])
        want = plan.bar.pose(tk[held]) @ plan.grips[i]
        got = r.fk(Q[held])
        assert np.abs(got[:, :3, 3] - want[:, :3, 3]).max() < 1e-9
        assert np.abs(got[:, :3, :3] - want[:, :3, :3]).max() < 1e-9
        lo, hi = r.q_limits.T
        assert np.all(Q >= lo - 1e-12) and np.all(Q <= hi + 1e-12)
        assert np.abs(np.diff(Q[:, :-1], axis=0)).max() <= P.MAX_KNOT_STEP
        if which == "ur5":
            assert len(set(np.sign(Q[:, 2]))) == 1 and np.abs(np.sin(Q[:, 4])).min() > 0.9
        else:
            assert Q[:, 3].max() < -1.5 and 1.5 < Q[:, 5].min()
        sigma = min(np.linalg.svd(r.jacobian(q)[:, :-1], compute_uv=False).min() for q in Q)
        assert sigma > 0.1, sigma
    assert P.reference_disagreement(plan) < 5e-4      # 0.13 mm (UR5s), 0.22 mm (Pandas): the cubics between knots
    c = P.clearances(plan)
    assert c["robots"] > K.MIN_CLEARANCE               # 0.12 m (UR5s), 0.086 m (Pandas)
    assert c["jaws_stands"] > K.JAW_STAND_CLEARANCE    # 0.015 m
    assert c["robots_stands"] > 0.02                   # 0.034 m: the wrists above the stands
    assert c["floor"] > 0.005 and c["self"] > 0.005


def test_the_pandas_redundancy_is_drawn_to_their_rest_posture(plans):
    """The Pandas' seven arm joints for a six-dimensional pose: the plan's null-space step keeps each knot's
    null-space distance from the rest posture several times smaller than the IK from the previous knot alone."""
    pair = plans["panda"].pair
    free = P.make_plan(robots=dataclasses.replace(pair, redundant=False))

    def null_distance(plan, i):
        r, rest = pair.robots[i], pair.posture[i]
        out = []
        for q in plan.knots[i][1]:
            J = r.jacobian(q)[:, :-1]
            d = (rest - q)[:-1]
            out.append(np.linalg.norm(d - np.linalg.pinv(J) @ (J @ d)))
        return np.mean(out)

    for i in range(2):
        assert null_distance(plans["panda"], i) < 0.3 * null_distance(free, i)


# ---- the carry ----

@pytest.mark.slow
@pytest.mark.parametrize("controller", list(C.CONTROLLERS))
@pytest.mark.parametrize("which", ARMS)
def test_every_controller_completes_the_default_carry(which, controller, runs):
    """Success, and the scores reported as for the SCARAs: the bar within millimetres of its path, the welds
    carrying its weight between them, a small squeeze, the load share near the commanded, no slip to speak of."""
    res = runs[which, controller, "none"]
    rep = res.report
    assert rep["success"], rep["failure"]
    assert rep["robots"] == which and rep["robot_names"] == list(C.pair(which).names)
    assert list(rep["steps"]) == list(C.STEPS) and min(rep["backed_off"]) >= K.BACKED_OFF
    row = score_row(rep)
    assert row["bar_error_rms_mm"] < 2.5 and row["bar_error_max_mm"] < 5.0
    assert row["bar_angle_max_mrad"] < 20.0
    assert abs(row["squeeze_mean_N"]) < 0.5 and row["load_share_deviation"] < 0.1
    assert max(row["slip_max_mm_0"], row["slip_max_mm_1"]) < 1.0
    assert max(row["torque_fraction_0"], row["torque_fraction_1"]) < 1.0
    s = res.series
    weight = s["weld"][s["airborne"], 0, 2] + s["weld"][s["airborne"], 1, 2]
    assert np.mean(weight) == pytest.approx(S.BAR_MASS * G, rel=0.02)
    assert f"dual carry by the {which} pair, controller {controller}" in C.summary(rep)


@pytest.mark.slow
@pytest.mark.parametrize("which", ARMS)
def test_each_disturbance_applies_and_is_scored(which, runs):
    """Under object-level control (its model takes the bar's mass), every disturbance runs to success and is
    scored, and each changes what it should: the model's mass the law's weight of the bar, the push the welds'
    peak force, the grip offset the welds' stretch, the noise the sensors' readings (not the motion's scores
    beyond a few tenths of a millimetre)."""
    base = runs[which, "object", "none"]
    got = {d: runs[which, "object", d] for d in ("mass+50", "mass-50", "push", "grip-offset", "noise")}
    for d, res in got.items():
        assert res.report["success"], (d, res.report["failure"])
        assert np.isfinite(score_row(res.report)["bar_error_rms_mm"]), d

    def robots(res, key):
        return [x[key] for x in res.report["scores"]["robots"]]

    for d, f in (("mass+50", 1.5), ("mass-50", 0.5)):
        assert got[d].plan.model_bar_mass == pytest.approx(f * S.BAR_MASS)
        assert not np.array_equal(got[d].log.robots[0].tau, base.log.robots[0].tau)
    assert all(p > b + 0.3 for p, b in zip(robots(got["push"], "peak_weld_force"), robots(base, "peak_weld_force")))
    assert sum(robots(got["grip-offset"], "max_slip_mm")) > sum(robots(base, "max_slip_mm")) + 1.0
    assert max(robots(got["grip-offset"], "max_slip_mm")) < 5.0
    noisy, quiet = robots(got["noise"], "sensed_force_error"), robots(base, "sensed_force_error")
    assert all(n["rms"] > 0.2 > q["rms"] for n, q in zip(noisy, quiet))


@pytest.mark.slow
def test_the_scara_carry_is_the_one_it_was():
    """run() and run(robots='scara') are the same carry (the SCARAs' rates, gains and branches), to the bit."""
    a, b = C.run(score_run=False), C.run(robots="scara", score_run=False)
    assert a.report["robots"] == b.report["robots"] == "scara"
    assert (a.report["dt"], a.report["world_every"], a.report["control_every"], a.report["log_every"]) == \
        (2e-4, 5, 5, 25)
    for ra, rb in zip(a.log.robots, b.log.robots):
        np.testing.assert_array_equal(ra.q, rb.q)
        np.testing.assert_array_equal(ra.tau, rb.tau)


# ---- a pair of one's own, bad input, the command line ----

def _my_pair():
    """Two UR5s with the carry's clamp, the bases given: as a user's factory returns them."""
    arm = PR._arm("ur5")
    c, u = PR.path_frame()
    return (arm, arm), ((c + 0.5 * u, math.atan2(-u[1], -u[0])), (c - 0.5 * u, math.atan2(u[1], u[0])))


def test_a_factory_of_one_s_own_gives_the_pair_and_its_bases():
    pair = C.pair(_my_pair)
    assert pair.name == "_my_pair" and pair.names == ("ur5 #1", "ur5 #2") and pair.branch == (None, None)
    ur5 = C.pair("ur5")
    for mine, named in zip(pair.robots, ur5.robots):
        np.testing.assert_allclose(mine.base_position, named.base_position, atol=1e-12)
        assert mine.base_yaw == pytest.approx(named.base_yaw, abs=1e-12)
    plan = P.make_plan(robots=_my_pair)
    assert plan.pair.name == "_my_pair" and P.clearances(plan)["robots"] > K.MIN_CLEARANCE


@pytest.mark.parametrize("robots,says", [
    ("kuka", r"^unknown robots 'kuka': choose from scara, ur5, panda"),
    ("no_such_module:pair", r"^robots 'no_such_module:pair': cannot import 'no_such_module'"),
    (lambda: (PR._arm("ur5"),), r"^robots must be a name \(scara, ur5, panda\), a Pair"),
    (lambda: ((S.scaras()[0], 3), ((0, 0, 0), 0.0)), r"^robots must be a name"),
    (lambda: (PR._arm("ur5").with_geometry(clamp=None), PR._arm("ur5")), r"^robot #1 \('ur5'\) has no clamp"),
])
def test_bad_robots_are_one_line_errors(robots, says):
    with pytest.raises(ValueError, match=says) as e:
        C.run(robots=robots)
    assert "\n" not in str(e.value)


def test_bad_robots_at_the_command_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        cli.parse_args(["--robots", "kuka", "--out", str(tmp_path)])
    assert e.value.code == 2
    assert "argument --robots: unknown pair 'kuka': choose from scara, ur5, panda" in capsys.readouterr().err
    args = cli.parse_args(["--robots", "panda", "--controller", "leader-follower", "--out", str(tmp_path)])
    assert args.robots == "panda"


@pytest.mark.slow
def test_the_command_line_carries_with_two_ur5s(tmp_path, capsys):
    assert cli.main(["--robots", "ur5", "--controller", "object", "--no-video", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "dual carry by the ur5 pair, controller object" in out and "UR5 #1's load share" in out
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["robots"] == "ur5" and rep["success"] and rep["command_line"]["robots"] == "ur5"
    assert (tmp_path / "frames.png").exists()
