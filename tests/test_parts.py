"""The robots' looks (coopsim.view.parts): the SCARAs from parts generated from their dimensions, a URDF arm
from its visual meshes, any other robot from its boxes; the parts on their link frames, following the
robot's forward kinematics; the same parts in the live page and the replay (in Debian's chromium, as
tests/test_replay.py and tests/test_live.py: the robot's colour where the parts are).
"""
from __future__ import annotations

import importlib.metadata
import io
import json
import math
import os

import numpy as np
import pytest

import coopsim as cs
from coopsim import urdf, view
from coopsim.view.parts import look_kind, mesh_triangles, part_poses, robot_parts

SCARA1_PARTS = {"base_plate": 0, "column": 0, "housing1": 1, "segment1": 1, "housing2": 2, "segment2": 2,
                "quill_guide": 2, "quill": 3, "housing4": 4, "housing5": 5, "clamp_body": 5, "clamp_rail": 5,
                "fixed_jaw": 5, "moving_jaw": 6}
SCARA2_PARTS = {"base_plate": 0, "column": 0, "housing1": 1, "segment1": 1, "housing2": 2, "segment2": 2,
                "housing3": 3, "segment3": 3, "quill_guide": 3, "quill": 4, "housing5": 5, "clamp_body": 5,
                "clamp_rail": 5, "fixed_jaw": 5, "moving_jaw": 6}
UR5_MESHES = ["base.dae", "shoulder.dae", "upperarm.dae", "forearm.dae", "wrist1.dae", "wrist2.dae", "wrist3.dae"]


def example_robot_data(relative: str) -> str:
    for f in importlib.metadata.files("example-robot-data"):
        if str(f).endswith(relative):
            return str(f.locate())
    raise FileNotFoundError(relative)


def fk_frames(robot, q):
    """DH frames 0..n in the world, chained here from the robot's DH table and base (not Robot.frames)."""
    def A(theta, d, a, alpha):
        ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
        return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])
    F = [np.asarray(robot.base, dtype=float)]
    for (theta, d, a, alpha), t, x in zip(robot.dh, robot.joint_types, q):
        F.append(F[-1] @ (A(theta + x, d, a, alpha) if t == "R" else A(theta, d + x, a, alpha)))
    return np.array(F)


def by_name(parts):
    return {p.name: p for p in parts}


# ---- the SCARAs ----

@pytest.mark.parametrize("make, expected", [(cs.robots.scara1, SCARA1_PARTS), (cs.robots.scara2, SCARA2_PARTS)])
def test_the_scaras_are_drawn_from_their_parts_each_on_its_link(make, expected):
    r = make(base_position=(0.3, -0.2, 0.0), base_yaw=0.7)
    assert look_kind(r) == r.name
    parts = robot_parts(r)
    assert {p.name: p.link for p in parts} == expected and len(parts) == len(expected)
    shapes = {p.name: p.shape for p in parts}
    assert all(shapes[n] == "cylinder" for n in expected if n.startswith(("housing", "column", "quill")))
    assert all(shapes[n] == "box" for n in expected if n.startswith(("segment", "base_plate", "clamp", "fixed", "moving")))
    colours = {p.name: p.color for p in parts}
    assert colours["base_plate"] == colours["column"] == "base"
    assert colours["fixed_jaw"] == colours["moving_jaw"] == colours["quill"] == "jaw"
    assert all(colours[n] == "robot" for n in expected if n.startswith(("segment", "housing")))


@pytest.mark.parametrize("make, key, segment", [(cs.robots.scara1, "L1", "segment1"), (cs.robots.scara1, "L2", "segment2"),
                                                (cs.robots.scara2, "L3", "segment3"), (cs.robots.scara2, "L1", "segment1")])
def test_a_longer_segment_stretches_the_segment_and_not_the_housings(make, key, segment):
    a, b = make(), make(**{key: make().dimensions[key] + 0.15})
    pa, pb = by_name(robot_parts(a)), by_name(robot_parts(b))
    assert pb[segment].scale[0] == pytest.approx(b.dimensions[key], abs=1e-15)
    assert pa[segment].scale[0] == pytest.approx(a.dimensions[key], abs=1e-15)
    assert np.array_equal(pa[segment].scale[1:], pb[segment].scale[1:])        # its section as it was
    for name in pa:
        if name != segment:
            assert np.array_equal(pa[name].scale, pb[name].scale), name            # housings and all else unchanged
    i = int(segment[-1])
    # the housing sits at the joint's axis, the segment's middle halfway along it: both in frame i
    np.testing.assert_allclose(pb[f"housing{i}"].pose[:3, 3], [-b.dimensions[key], 0, 0], atol=1e-15)
    np.testing.assert_allclose(pb[segment].pose[:3, 3], [-b.dimensions[key] / 2, 0, 0], atol=1e-15)


def test_the_base_height_stretches_the_column_only():
    a, b = cs.robots.scara2(), cs.robots.scara2(L_base=0.6)
    pa, pb = by_name(robot_parts(a)), by_name(robot_parts(b))
    assert pb["column"].scale[2] - pa["column"].scale[2] == pytest.approx(0.2, abs=1e-12)
    assert all(np.array_equal(pa[n].scale, pb[n].scale) for n in pa if n != "column")


@pytest.mark.parametrize("make", [cs.robots.scara1, cs.robots.scara2])
def test_the_parts_follow_the_forward_kinematics(make):
    r = make(base_position=(0.4, 0.1, 0.0), base_yaw=-0.9)
    rng = np.random.default_rng(5)
    parts = robot_parts(r)
    d = r.dimensions
    for _ in range(5):
        q = rng.uniform(r.q_limits[:, 0], r.q_limits[:, 1])
        F = fk_frames(r, q)
        W = part_poses(r, parts, q)
        for p, w in zip(parts, W):
            np.testing.assert_allclose(w, F[p.link] @ p.pose, rtol=0, atol=1e-12, err_msg=p.name)
        # where they are, from the kinematics: each arm housing on its joint's axis (z of frame i-1) and along
        # it; each segment's middle halfway between its joint's axis and the next one's
        named = dict(zip([p.name for p in parts], W))
        for i in range(1, r.dof):
            if f"housing{i}" in named and f"segment{i}" in named:
                h = named[f"housing{i}"]
                off = h[:3, 3] - F[i - 1][:3, 3]
                assert np.linalg.norm(np.cross(off, F[i - 1][:3, 2])) < 1e-12
                assert np.linalg.norm(np.cross(h[:3, 2], F[i - 1][:3, 2])) < 1e-12
                mid = 0.5 * (h[:3, 3] + F[i][:3, 3])
                np.testing.assert_allclose(named[f"segment{i}"][:3, 3], mid, atol=1e-12)
        # the quill's tip at the prismatic joint's frame; the jaws' inner faces q6 apart across the opening
        k = r.joint_types.index("P") + 1
        tip = named["quill"] @ np.array([0, 0, d["quill_length"] / 2, 1.0])
        np.testing.assert_allclose(tip[:3], F[k][:3, 3], atol=1e-12)
        tj = d["jaw_thickness"]
        fixed = named["fixed_jaw"][:3, 3] + named["fixed_jaw"][:3, 2] * tj / 2
        moving = named["moving_jaw"][:3, 3] - named["moving_jaw"][:3, 2] * tj / 2
        face = F[r.clamp.fixed_link] @ r.clamp.fixed_face
        np.testing.assert_allclose(fixed, face[:3, 3], atol=1e-12)
        np.testing.assert_allclose(moving - fixed, q[5] * face[:3, 2], atol=1e-12)
    # N states at once: one (m, 4, 4) per state
    Q = rng.uniform(r.q_limits[:, 0], r.q_limits[:, 1], size=(3, r.dof))
    np.testing.assert_array_equal(part_poses(r, parts, Q), np.array([part_poses(r, parts, x) for x in Q]))


def test_the_rule_is_the_robots_structure_not_its_name():
    s1 = cs.robots.scara1(L1=0.4, width=0.08)
    assert look_kind(s1) == "scara1" and look_kind(s1.with_backend("numeric")) == "scara1"
    tables = dict(dh=s1.dh, com=s1.com, masses=s1.masses, inertias=s1.inertias, joint_types=s1.joint_types,
                  boxes=s1.boxes, clamp=s1.clamp)
    # the same tables under the SCARA's name, but no recorded dimensions: a robot built from tables
    plain = cs.Robot.from_dh(name="scara1", **tables)
    assert look_kind(plain) == "boxes"
    # the dimensions recorded, but a DH table that is not the one they build
    dh = np.array(s1.dh)
    dh[1, 2] += 0.01
    odd = cs.Robot.from_dh(name="scara1", dimensions=s1.dimensions, **dict(tables, dh=dh))
    assert look_kind(odd) == "boxes"
    # the same dimensions and table under another name: the SCARA's look
    other = cs.Robot.from_dh(name="my arm", dimensions=s1.dimensions, **tables)
    assert look_kind(other) == "scara1"
    # a robot from tables is drawn as its boxes, box for box
    parts = robot_parts(plain)
    assert [p.shape for p in parts] == ["box"] * len(plain.boxes)
    q = np.array([0.2, -0.3, 0.1, 0.4, 0.5, 0.02])
    P, H = plain.shapes(q)
    np.testing.assert_allclose(part_poses(plain, parts, q), P, atol=1e-12)
    np.testing.assert_allclose(np.array([p.scale for p in parts]), 2 * H, atol=0)


# ---- URDF arms ----

UR5 = example_robot_data("ur_description/urdf/ur5_robot.urdf")


def test_a_urdf_arm_keeps_its_visual_meshes_and_is_drawn_with_them():
    pytest.importorskip("trimesh")
    r = urdf.from_urdf(UR5)
    vis = urdf.visuals(r)
    assert [os.path.basename(v.path) for v in vis] == UR5_MESHES and [v.link for v in vis] == list(range(7))
    assert all(os.path.isfile(v.path) and "/visual/" in v.path and np.array_equal(v.scale, [1, 1, 1]) for v in vis)
    assert look_kind(r) == "urdf"
    parts = robot_parts(r)
    assert [p.shape for p in parts] == ["mesh"] * 7 and [os.path.basename(p.mesh) for p in parts] == UR5_MESHES
    # a copy (as Simulation.robots gives) has them too
    sim = cs.Simulation()
    sim.add_robot(r.with_base([0.5, 0.0, 0.0]), cs.PID(10.0, 0.0, 1.0), np.zeros(6))
    assert [p.mesh for p in robot_parts(sim.robots[0])] == [p.mesh for p in parts]
    # the triangles: the upper arm (0.425 m between its joints) spans about that along its z
    v, f = mesh_triangles(parts[2].mesh)
    assert v.dtype == np.float32 and f.dtype == np.uint32 and len(f) > 1000 and f.max() < len(v)
    assert 0.45 < np.ptp(v[:, 2]) < 0.6


def test_a_urdf_arms_meshes_sit_where_pinocchio_puts_its_links():
    pin = pytest.importorskip("pinocchio")
    r = urdf.from_urdf(UR5)
    m = pin.buildModelFromUrdf(UR5)
    d = m.createData()
    parts = robot_parts(r)
    names = [v.name for v in urdf.visuals(r)]
    for q in np.random.default_rng(2).uniform(-np.pi, np.pi, size=(4, 6)):
        pin.framesForwardKinematics(m, d, q)
        for p, name, W in zip(parts, names, part_poses(r, parts, q)):
            # the UR5's visuals have no origin: the mesh sits at its link's frame (1e-10: the import reads the
            # file's 1.57079632679 as pi/2, tests/test_urdf_import.py)
            np.testing.assert_allclose(W, d.oMf[m.getFrameId(name)].homogeneous, atol=1e-10, err_msg=name)


def test_a_urdf_without_meshes_or_with_missing_files_is_drawn_with_boxes(tmp_path, monkeypatch):
    exported = cs.Robot.from_urdf(urdf.to_urdf(cs.robots.scara1()))     # box visuals only: its boxes again
    assert all(p.shape == "box" for p in robot_parts(exported))
    with open(UR5, encoding="utf-8") as f:
        text = f.read()
    text = text.replace("package://example-robot-data/robots/ur_description/meshes/ur5/visual/",
                                    "package://nowhere/")
    path = tmp_path / "ur5_moved.urdf"
    path.write_text(text)
    # (the copy's collision meshes are not found from tmp_path either: not read, the visuals are the point here)
    r = urdf.from_urdf(str(path), name="ur5 without its meshes", collision_meshes=False)
    assert urdf.visuals(r) == [] and look_kind(r) == "boxes"
    parts = robot_parts(r)
    assert [p.shape for p in parts] == ["box"] * len(r.boxes) and len(parts) > 0
    # found again through ROS_PACKAGE_PATH
    pkg = tmp_path / "pkgs" / "nowhere"
    pkg.mkdir(parents=True)
    src = os.path.dirname(urdf.visuals(urdf.from_urdf(UR5))[0].path)
    os.symlink(os.path.join(src, "wrist3.dae"), pkg / "wrist3.dae")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "pkgs"))
    r = urdf.from_urdf(str(path), name="ur5 with one mesh", collision_meshes=False)
    vis = urdf.visuals(r)
    assert [os.path.basename(v.path) for v in vis] == ["wrist3.dae"] and look_kind(r) == "urdf"
    parts = robot_parts(r)
    # the link with a mesh drawn with it, the others with their boxes
    assert [p.link for p in parts if p.shape == "mesh"] == [6]
    assert {p.link for p in parts if p.shape == "box"} == {b.link for b in r.boxes} - {6}


def test_the_live_page_and_the_replay_get_the_urdf_meshes(tmp_path):
    pytest.importorskip("viser")
    r = urdf.from_urdf(UR5)
    sim = cs.Simulation(dt=1e-3, log_every=10)
    sim.add_robot(r, cs.PID(100.0, 0.0, 10.0), np.array([0.0, -1.0, 1.0, 0.0, 0.5, 0.0]))
    sim.run(0.05, progress=False)
    v = view.live(sim, quiet=True, start=False)
    try:
        shown = sorted(os.path.basename(p.mesh) for p in robot_parts(r))
        assert len(v._part_meshes) == 7 and sorted(len(m[1]) for m in v._part_meshes) == [1] * 7
        assert shown == sorted(UR5_MESHES)
    finally:
        v.close()
    import test_replay as tr

    path = view.replay_html(sim, str(tmp_path / "ur5.html"))
    cmds = tr.commands(path)
    meshes = {c["path"]: c for c in cmds if c["type"] == "set_object"
              and c["object"]["geometries"][0]["type"] == "BufferGeometry" and "/parts/" in c["path"]}
    assert sorted(p.split("/")[-1] for p in meshes if p.startswith("/coopsim/robot0/")) == \
        sorted(f"visual{k}_{n}" for k, n in enumerate(v.name for v in urdf.visuals(r)))
    # the triangles sent are the file's
    c = meshes["/coopsim/robot0/parts/link2/visual2_upper_arm_link"]["object"]["geometries"][0]["data"]
    vv, ff = mesh_triangles(robot_parts(r)[2].mesh)
    assert np.array_equal(tr.f32(c["attributes"]["position"]["array"]).reshape(-1, 3), vv)
    assert np.array_equal(np.frombuffer(c["index"]["array"].data, "<u4").reshape(-1, 3), ff)


# ---- in a browser: the parts in the robot's colour ----

@pytest.mark.slow
def test_the_replay_shows_the_parts_in_the_robots_colour_and_the_boxes_on_request(tmp_path):
    import test_replay as tr

    sync_playwright = tr._browser_or_skip()
    r = cs.robots.scara1()
    sim = cs.Simulation(dt=2e-4, log_every=50)
    q0 = np.array([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03])
    sim.add_robot(r, cs.PID(50.0, 0.0, 5.0), q0, q0=q0)
    sim.run(0.1, progress=False)
    path = view.replay_html(sim, str(tmp_path / "parts.html"), autoplay=False, reference=False)
    with sync_playwright() as p:
        env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}
        b = p.chromium.launch(executable_path=tr.CHROMIUM, args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
                              env=env)
        try:
            page = tr.Page(b, path, width=800, height=600)
            page.js("window.coopsim.seek(0.1)")
            img = page.pixels()
            from PIL import Image

            Image.fromarray(img.astype(np.uint8)).save(tmp_path / "replay_parts.png")
            parts = robot_parts(r)
            W = part_poses(r, parts, sim.state(0)[0])
            uv = np.array(page.page.evaluate("""(pts) => { const c = window.coopsim.viewer.camera; c.updateMatrixWorld();
                const w = window.innerWidth, h = window.innerHeight;
                return pts.map(q => { const v = new MeshCat.THREE.Vector3(q[0], q[2], -q[1]).project(c);
                                      return [(v.x + 1) / 2 * w, (1 - v.y) / 2 * h]; }); }""",
                                             [list(map(float, w[:3, 3])) for w in W]))
            scale = img.shape[1] / 800
            from matplotlib.colors import rgb_to_hsv, to_rgb

            hue = rgb_to_hsv(to_rgb(view.COLORS["robots"][0]))[0]

            def orange(px):       # SCARA #1's colour, however shaded: its hue, saturated
                hsv = rgb_to_hsv(px / 255.0)
                return (np.abs((hsv[..., 0] - hue + 0.5) % 1.0 - 0.5) < 15 / 360) & (hsv[..., 1] > 0.35)

            def grey(px):         # the base's grey, unsaturated
                return rgb_to_hsv(px / 255.0)[..., 1] < 0.1

            def near(k, test, radius=3):
                x, y = (uv[k] * scale).round().astype(int)
                return bool(test(img[y - radius:y + radius + 1, x - radius:x + radius + 1]).any())
            names = [p.name for p in parts]
            for n in ("segment1", "segment2", "housing1", "housing2"):
                assert near(names.index(n), orange), n           # the robot's colour where its parts are
            assert near(names.index("column"), grey) and not near(names.index("column"), orange)
            # the collision boxes on request: shown, the parts hidden, and back
            assert page.js("window.coopsim.boxes()") is False
            assert page.js("window.coopsim.boxes(true)") is True
            assert page.js("document.getElementById('cs-boxes').checked")
            vis = page.js("[window.coopsim.viewer.scene_tree.children.coopsim.children.robot0.children.parts.object.visible,"
                          " window.coopsim.viewer.scene_tree.children.coopsim.children.robot0.children.link1.object.visible]")
            assert vis == [False, True]
            page.js("window.coopsim.boxes(false)")
            assert page.errors == [] and page.blocked == []
            page.close()
        finally:
            b.close()


@pytest.mark.slow
def test_the_live_page_shows_the_parts_in_the_robots_colour(browser, tmp_path):  # noqa: F811
    pytest.importorskip("viser")
    import test_live as tl

    r = cs.robots.scara1()
    sim = cs.Simulation()
    sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), np.array([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03]))
    v = view.live(sim, quiet=True, t_end=0.02, ghosts=False)
    try:
        v.wait(timeout=tl.WAIT)
        lp = tl.LivePage(browser, v, keep=tmp_path)
        try:
            parts = robot_parts(r)
            W = part_poses(r, parts, sim.state(0)[0])
            names = [p.name for p in parts]
            img = lp.shows(W[names.index("segment1"), :3, 3], tl.is_orange, "segment 1 orange", radius=3)
            from PIL import Image

            Image.fromarray(img.astype(np.uint8)).save(tmp_path / "live_parts.png")
            uv = lp.project(W[:, :3, 3])
            for n in ("segment2", "housing1", "housing2"):
                assert tl.colour_near(img, uv[names.index(n)], tl.is_orange, radius=3), n
            assert not tl.colour_near(img, uv[names.index("column")], tl.is_orange, radius=3)
        finally:
            lp.close()
    finally:
        v.close()


from test_replay import browser  # noqa: E402,F401  (Debian's chromium through Playwright)
