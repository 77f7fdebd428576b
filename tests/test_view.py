"""coopsim.view: robots drawn as boxes, the paper's colours, animations from logs; plot_log overlays.

The stored picture tests/data/view_reference.png is rewritten (after a deliberate change of the
drawing) from the repository root with

    python3 tests/test_view.py --write-reference
"""
from __future__ import annotations

import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

import coopsim as cs  # noqa: E402
from coopsim import view  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REFERENCE = os.path.join(ROOT, "tests", "data", "view_reference.png")

R1 = cs.robots.scara1()
R2 = cs.robots.scara2(base_position=(0.75, 0.0, 0.0), base_yaw=np.pi)
# a known scene: SCARA #1 reaching left, its ghost turned 1.1 rad away; SCARA #2 reaching over
Q1 = np.array([-0.5, 1.2, 0.10, 0.0, np.pi / 2, 0.03])
Q2 = np.array([0.6, -0.8, -0.6, 0.1, 0.0, 0.03])
REF1 = Q1 + np.array([1.1, -0.6, 0.0, 0.0, 0.0, 0.0])
LIMITS = [[-0.45, 1.05], [-0.6, 0.7], [0.0, 0.8]]
FLOOR = (-0.4, 1.0, -0.5, 0.6)


def new_axes(w=4.0, h=3.0, dpi=60):
    """A 3D Axes filling a figure of w x h inches at dpi, outside pyplot (nothing to close)."""
    fig = Figure(figsize=(w, h), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    fig.subplots_adjust(0, 0, 1, 1)
    return ax


def render(fig) -> np.ndarray:
    """The figure as an (H, W, 3) int array."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)


def corners(T, h):
    """The 8 corners (8, 3) of a box of half extents h at pose T, computed directly."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    return np.array([(T @ np.append(s * h, 1.0))[:3] for s in signs])


def same_points(a, b, tol):
    """Every point of a is within tol of a point of b and the reverse."""
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    return d.min(axis=1).max() <= tol and d.min(axis=0).max() <= tol


def top_centre(robot, q, box, margin=0.0):
    """The centre (3,) of a box's top (+z) face at q (boxes `margin` m smaller, as ghosts are)."""
    P, H = robot.shapes(q)
    return (P[box] @ np.array([0.0, 0.0, H[box, 2] - min(margin, 0.25 * H[box, 2]), 1.0]))[:3]


def known_scene(ax, **kw):
    kw.setdefault("limits", LIMITS)
    kw.setdefault("floor", FLOOR)
    kw.setdefault("cull", True)
    return view.draw(ax, [R1, R2], [Q1, Q2], **kw)


# ---- geometry ----

@pytest.mark.parametrize("robot", [R1, R2], ids=["scara1", "scara2"])
def test_drawn_boxes_are_the_robots_shapes(robot):
    rng = np.random.default_rng(7)
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    poses = [np.zeros(robot.dof), (lo + hi) / 2] + [rng.uniform(lo, hi) for _ in range(4)]
    scene = view.draw(new_axes(), robot, poses[0])
    for q in poses:
        scene.update(q)
        P, H = robot.shapes(q)
        assert len(scene.faces("robot")) == 6 * len(robot.boxes)
        for k in range(len(robot.boxes)):
            drawn = scene.faces("robot", 0, box=k).reshape(-1, 3)
            assert drawn.shape == (24, 3)
            assert same_points(drawn, corners(P[k], H[k]), 1e-12), (robot.name, k)
        # the collection holds exactly these polygons
        if hasattr(scene.polys, "_faces"):
            np.testing.assert_array_equal(scene.polys._faces, scene.faces("robot"))


def test_ghost_bodies_and_floor_geometry():
    scene = view.draw(new_axes(), [R1, R2], [Q1, Q2], reference=[REF1, Q2], ghost_margin=0.0,
                      bodies=[view.Body("bar", [0.175, 0.01, 0.01], np.eye(4)),
                              view.Body("pair", [[0.1, 0.1, 0.1], [0.05, 0.05, 0.2]],
                                        [cs.dh_transform(0.3, 0.1, 0.2, 0.4), cs.dh_transform(-1, 0.5, 0.1, 0)])])
    for i, (r, q) in enumerate(((R1, REF1), (R2, Q2))):
        P, H = r.shapes(q)
        moving = [k for k, b in enumerate(r.boxes) if b.link != 0]
        assert len(scene.faces("ghost", i)) == 6 * len(moving)         # no ghost of the base column
        for k in moving:
            assert same_points(scene.faces("ghost", i, box=k).reshape(-1, 3), corners(P[k], H[k]), 1e-12)
    assert same_points(scene.faces("body", 0).reshape(-1, 3), corners(np.eye(4), np.array([0.175, 0.01, 0.01])),
                       1e-12)
    assert same_points(scene.faces("body", 1, box=1).reshape(-1, 3),
                       corners(cs.dh_transform(-1, 0.5, 0.1, 0), np.array([0.05, 0.05, 0.2])), 1e-12)
    # the default ghost is 2 mm smaller, so a robot on its reference hides it
    small = view.draw(new_axes(), [R1, R2], [Q1, Q2], reference=[Q1, None])
    P, H = R1.shapes(Q1)
    assert same_points(small.faces("ghost", 0, box=1).reshape(-1, 3), corners(P[1], H[1] - 0.002), 1e-12)
    assert len(small.faces("ghost", 1)) == 0
    # the floor: tiles at z = 0 covering everything's footprint
    tiles = scene.floor_faces()
    assert len(tiles) > 20 and np.all(tiles[..., 2] == 0.0)
    x0, x1, y0, y1 = scene.floor_extent
    pts = scene.faces("robot").reshape(-1, 3)
    assert x0 < pts[:, 0].min() and pts[:, 0].max() < x1 and y0 < pts[:, 1].min() and pts[:, 1].max() < y1
    # equal scales: the box aspect follows the limits
    L = scene.limits
    aspect = np.asarray(scene.ax.get_box_aspect())
    np.testing.assert_allclose(aspect / aspect[0], (L[:, 1] - L[:, 0]) / (L[0, 1] - L[0, 0]), rtol=1e-9)


def test_culling_keeps_the_faces_towards_the_camera():
    full = known_scene(new_axes(), cull=False)
    culled = known_scene(new_axes(), cull=True)
    assert len(culled.faces("robot")) < len(full.faces("robot"))
    # a top face is seen from above, a bottom face is not
    assert len(culled.faces("robot", 0, box=1, face=1)) == 1
    assert len(culled.faces("robot", 0, box=1, face=0)) == 0


# ---- pictures ----

def pixel(img, scene, point):
    x, y = scene.project(np.asarray(point))[0]
    return img[int(round(y)), int(round(x))]


def test_colours_where_the_ghost_a_holding_robot_and_a_colliding_box_appear():
    # the ghost: blue and transparent over what is behind it
    with_ghost = known_scene(new_axes(), reference=[REF1, None], holding=[False, True])
    img = render(with_ghost.fig)
    behind = render(known_scene(new_axes(), holding=[False, True]).fig)
    p_ghost = top_centre(R1, REF1, 1, margin=0.002)
    seen, under = pixel(img, with_ghost, p_ghost), pixel(behind, with_ghost, p_ghost)
    ghost = with_ghost.colors("ghost", 0, box=1, face=1)[0]
    expected = (1 - ghost[3]) * under + ghost[3] * 255 * ghost[:3]
    assert seen[2] > seen[0] + 40 and seen[2] > seen[1] + 20, seen           # blue
    assert np.abs(seen - expected).max() <= 8, (seen, expected)                # alpha-blended over the floor
    assert np.abs(seen - 255 * ghost[:3]).max() > 40                          # not opaque
    # the holding robot: its links green
    p_link = top_centre(R2, Q2, 2)
    green = 255 * with_ghost.colors("robot", 1, box=2, face=1)[0][:3]
    got = pixel(img, with_ghost, p_link)
    assert got[1] > got[0] + 60 and got[1] > got[2] + 60, got
    assert np.abs(got - green).max() <= 6, (got, green)
    # SCARA #1 keeps its own colour (amber)
    amber = pixel(img, with_ghost, top_centre(R1, Q1, 2))
    assert amber[0] > amber[1] > amber[2] + 50, amber

    # collision boxes: link 1 of SCARA #1 in contact is red, the others green; the contact a red line
    mask = [np.arange(len(R1.boxes)) == 1, np.zeros(len(R2.boxes), dtype=bool)]
    contact = top_centre(R1, Q1, 1)
    boxes = known_scene(new_axes(), collision_boxes=True, colliding=mask, contacts=[[contact, [0.0, 0.0, 1.0]]],
                        contact_length=0.1)
    img = render(boxes.fig)
    P, H = R1.shapes(Q1)
    red = pixel(img, boxes, (P[1] @ [0.5 * H[1, 0], 0.0, H[1, 2], 1.0])[:3])      # halfway out along link 1
    assert red[0] > red[1] + 100 and red[0] > red[2] + 100, red
    free = pixel(img, boxes, top_centre(R1, Q1, 2))
    assert free[1] > free[0] + 60 and free[1] > free[2] + 60, free
    x, y = boxes.project(contact + [0.0, 0.0, 0.06])[0]
    patch = img[int(y) - 1:int(y) + 2, int(x) - 1:int(x) + 2].reshape(-1, 3)
    assert any(p[0] > 180 and p[1] < 90 and p[2] < 90 for p in patch), patch


def reference_picture() -> np.ndarray:
    scene = known_scene(new_axes(3.2, 2.4, 50), reference=[REF1, None], holding=[False, True],
                        bodies=[view.Body("bar", [0.175, 0.01, 0.01], cs.dh_transform(0.3, 0.02, 0.5, 0.0))])
    return render(scene.fig).astype(np.uint8)


def test_picture_matches_the_stored_reference():
    from PIL import Image

    got = reference_picture().astype(int)
    want = np.asarray(Image.open(REFERENCE).convert("RGB")).astype(int)
    assert got.shape == want.shape
    diff = np.abs(got - want).max(axis=2)
    # antialiasing may differ between matplotlib versions; the picture may not
    assert diff.mean() < 2.0 and (diff > 60).mean() < 0.01, (diff.mean(), (diff > 60).mean())


# ---- animations ----

@pytest.fixture(scope="module")
def run_log():
    """Both SCARAs for 1 s under a slow PID (so that they lag their ghosts), logged every 10 ms."""
    refs = []
    for r, f in ((R1, [-0.2, 0.15, -0.1]), (R2, [0.15, -0.2, 0.1])):
        lo, hi = r.q_limits[:, 0], r.q_limits[:, 1]
        refs.append(cs.CubicTrajectory([0.0, 0.5, 1.0], np.array([(lo + hi) / 2 + x * (hi - lo) for x in f])))
    sim = cs.Simulation(dt=2e-4, log_every=50)
    for r, ref in zip((R1, R2), refs):
        sim.add_robot(r, cs.PID(np.full(6, 60.0), np.zeros(6), np.full(6, 8.0)), ref)
    return sim.run(1.0, progress=False), sim.robots


def frame_as_drawn(anim, log, robots, k):
    """draw() of the log's q and q_ref at frame k's time, with the animation's camera, floor and limits."""
    t = anim.times[k]
    row = int(np.argmin(np.abs(log.t - t)))
    assert abs(log.t[row] - t) < 1e-9
    w, h = anim.fig.get_size_inches()
    scene = view.draw(new_axes(w, h, anim.fig.dpi), robots, [rl.q[row] for rl in log.robots],
                      reference=[rl.q_ref[row] for rl in log.robots], limits=anim.scene.limits,
                      floor=anim.scene.floor_extent, zoom=anim.scene.zoom, cull=True)
    return render(scene.fig)


def test_animation_files_have_the_frames_and_duration_and_show_the_log(run_log, tmp_path):
    import imageio_ffmpeg
    from PIL import Image

    log, robots = run_log
    anim = view.animate(log, robots, fps=10, path=tmp_path / "run.mp4", figsize=(3.2, 2.4), dpi=50, label=False)
    assert len(anim) == 11 and anim.duration == pytest.approx(1.1)
    np.testing.assert_allclose(anim.times, np.arange(11) * 0.1, atol=1e-12)
    assert imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "run.mp4")) == (11, pytest.approx(1.1))
    # decoded with the same ffmpeg (imageio_ffmpeg.read_frames leaves its pipes open)
    raw = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(tmp_path / "run.mp4"),
                          "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], capture_output=True, check=True).stdout
    assert len(raw) == 11 * 120 * 160 * 3                              # 11 frames of 160 x 120
    mp4 = list(np.frombuffer(raw, np.uint8).reshape(11, 120, 160, 3).astype(int))
    assert anim.save(tmp_path / "run.gif") == str(tmp_path / "run.gif")
    with Image.open(tmp_path / "run.gif") as gif:
        assert gif.n_frames == 11
        frames, total = [], 0
        for k in range(gif.n_frames):
            gif.seek(k)
            total += gif.info["duration"]
            frames.append(np.asarray(gif.convert("RGB")).astype(int))
    assert total == 1100                                        # ms
    # frame k is the log at t = k / fps, and not another time's
    drawn = {k: frame_as_drawn(anim, log, robots, k) for k in (0, 5, 10)}
    for k in drawn:
        for video, tol in ((mp4, 4.0), (frames, 3.0)):
            err = np.abs(video[k] - drawn[k]).mean()
            others = [np.abs(video[k] - drawn[j]).mean() for j in drawn if j != k]
            assert err < tol and min(others) > 3 * err, (k, err, others)


def test_blitted_frames_equal_full_draws(run_log):
    log, robots = run_log
    anim = view.animate(log, robots, fps=5, figsize=(3.2, 2.4), dpi=50, holding=[None, log.t > 0.5])
    blitted = [f[..., :3].astype(int) for f in anim.frames()]
    for k in (1, 4):
        anim.show_frame(k)
        np.testing.assert_array_equal(blitted[k], render(anim.fig))


def test_frame_times_speed_and_duration(run_log):
    log, robots = run_log
    a = view.animate(log, robots, fps=10, speed=2.0, figsize=(2, 2), dpi=20)
    np.testing.assert_allclose(a.times, np.arange(6) * 0.2, atol=1e-12)
    a = view.animate(log, robots, fps=25, speed=0.5, t_start=0.2, t_end=0.4, figsize=(2, 2), dpi=20)
    np.testing.assert_allclose(a.times, 0.2 + np.arange(11) * 0.02, atol=1e-12)
    a = view.animate(log, robots, fps=10, speed=0.0, duration=0.5, t_start=0.3, figsize=(2, 2), dpi=20)
    assert len(a) == 5 and np.all(a.times == 0.3)
    # a duration past the log's end holds the last pose
    a = view.animate(log, robots, fps=10, speed=4.0, duration=1.0, figsize=(2, 2), dpi=20)
    assert len(a) == 10 and a.times[-1] == pytest.approx(1.0) and a.times[2] == pytest.approx(0.8)
    assert "frames" in repr(a) and "<video" in a._repr_html_()
    # the same frames through matplotlib's own FuncAnimation and ffmpeg writer (imageio-ffmpeg's binary)
    assert "<video" in a.animation.to_html5_video()


def test_per_row_holding_colliding_contacts_and_bodies(run_log):
    log, robots = run_log
    rows = len(log.t)
    colliding = np.zeros((rows, len(R1.boxes)), dtype=bool)
    colliding[log.t >= 0.5, 2] = True
    contacts = [None] * rows
    contacts[60] = [[[0.3, 0.0, 0.2], [0.0, 0.0, 2.0]], [[0.3, 0.1, 0.2], [1.0, 0.0, 0.0]]]
    bar = np.tile(np.eye(4), (rows, 1, 1))
    bar[:, 0, 3] = np.linspace(0.0, 0.5, rows)
    anim = view.animate(log, robots, fps=10, holding=[None, log.t >= 0.5], figsize=(2, 2), dpi=20,
                        bodies=[view.Body("bar", [0.175, 0.01, 0.01], bar)])
    anim.show_frame(4)
    c = anim.scene.colors("robot", 1, box=2)[0]
    assert c[1] < c[0] + 0.05                                           # not green yet (the robot's own colour)
    drawn = anim.scene.faces("body", 0).reshape(-1, 3)      # the faces seen (culled), so corners of the bar at row 40
    d = np.linalg.norm(drawn[:, None] - corners(bar[40], np.array([0.175, 0.01, 0.01]))[None], axis=2)
    assert len(drawn) and d.min(axis=1).max() < 1e-12
    anim.show_frame(5)
    c = anim.scene.colors("robot", 1, box=2)[0]
    assert c[1] > c[0] + 0.2 and c[1] > c[2] + 0.2                       # green: holding from t = 0.5 s
    assert anim.scene.colors("robot", 1, box=0)[0][1] < 0.6               # the base column is not
    boxes = view.animate(log, robots, fps=10, collision_boxes=True, colliding=[colliding, None],
                         contacts=contacts, figsize=(2, 2), dpi=20)
    boxes.show_frame(4)
    assert len(boxes.scene.contact_lines()) == 0
    assert boxes.scene.colors("robot", 0, box=2)[0][1] > boxes.scene.colors("robot", 0, box=2)[0][0]   # free
    boxes.show_frame(6)
    c = boxes.scene.colors("robot", 0, box=2)[0]
    assert c[0] > c[1] + 0.3                                              # red: in contact
    assert boxes.scene.colors("robot", 1, box=2)[0][1] > 0.3              # the other robot's boxes free
    lines = boxes.scene.contact_lines()                                  # row 60, t = 0.6 s
    np.testing.assert_allclose(lines[0], [[0.3, 0.0, 0.2], [0.3, 0.0, 0.2 + boxes.scene.contact_length]])
    np.testing.assert_allclose(lines[1], [[0.3, 0.1, 0.2], [0.3 + boxes.scene.contact_length, 0.1, 0.2]])


# ---- the world: scenery, free bodies, colliding boxes and contacts from a simulation ----

WALL_Y = 0.25          # the wall's mid-plane, 5 mm thick


@pytest.fixture(scope="module")
def wall_sim():
    """SCARA #1 driven into a wall (test_world.py's scenario), every contact point logged; a bar lying on the
    floor and a cube beside it, both free."""
    r = cs.robots.scara1()
    q0 = np.array([0.0, 0.3, 0.10, 0.0, np.pi / 2, 0.02])
    w = cs.World()
    w.add_static_box("wall", [0.3, 0.0025, 0.4], position=[0.45, WALL_Y, 0.4])
    w.add_free_box("bar", [0.175, 0.01, 0.01], 0.15, position=[0.45, -0.25, 0.01], friction=0.5)
    w.add_free_box("cube", [0.03, 0.03, 0.03], 0.2, position=[0.2, -0.3, 0.03])
    sim = cs.Simulation(dt=2e-4, world=w, log_every=10, log_contacts=True)
    turn = cs.CubicTrajectory([0.0, 0.6], np.array([q0, q0 + [1.2, 0, 0, 0, 0, 0]]))
    sim.add_robot(r, cs.PID(400.0, 0.0, 40.0), turn)
    sim.run(0.4, progress=False)
    return sim


def box_names(robot):
    return [b.name for b in robot.boxes]


def face_towards_camera(scene, robot, q, box):
    """The centre (3,) of the face of a box that looks most towards the camera."""
    from coopsim.view.geometry import FACE_NORMALS, view_direction

    P, H = robot.shapes(q)
    k = int(np.argmax(FACE_NORMALS @ (P[box, :3, :3].T @ view_direction(scene.ax.elev, scene.ax.azim))))
    return (P[box] @ np.append(FACE_NORMALS[k] * H[box], 1.0))[:3]


def on_box(points, T, h, tol=1e-12):
    """Whether the drawn points (m, 3) are the box's surface: every point on a face of the box of half extents
    h at pose T, reaching both ends along each of its axes (the world's bodies are drawn in tiles, and only
    the faces towards the camera when culled)."""
    local = (points - T[:3, 3]) @ T[:3, :3]
    on_surface = np.all(np.abs(local) <= h + tol, axis=1) & np.any(np.abs(np.abs(local) - h) <= tol, axis=1)
    spans = np.allclose(local.min(axis=0), -h, atol=tol) and np.allclose(local.max(axis=0), h, atol=tol)
    return bool(on_surface.all() and spans)


def is_red(p):
    return p[0] > p[1] + 100 and p[0] > p[2] + 100


def is_green(p):
    return p[1] > p[0] + 60 and p[1] > p[2] + 60


def test_a_wall_contact_draws_the_touching_box_red_a_free_one_green_and_the_contact_lines(wall_sim):
    sim = wall_sim
    robot = sim.robots[0]
    now = sim.contacts()
    touching = {c.b.split("/")[1] for c in now if c.a == "wall"}
    assert "link3" in touching and "link2" not in touching          # the quill is against the wall, the arm free
    scene = view.draw(new_axes(6.4, 4.8, 80), sim, collision_boxes=True)
    # the world's bodies: the wall as scenery, the bar red, the cube in the other bodies' colour
    assert scene.body_names == ["wall", "bar", "cube"]
    assert set(scene.floor_faces()[..., 2].ravel()) == {0.0}
    q = sim.state(0)[0]
    img = render(scene.fig)
    names = box_names(robot)
    quill, arm = names.index("link3"), names.index("link2")
    red = pixel(img, scene, face_towards_camera(scene, robot, q, quill))
    green = pixel(img, scene, face_towards_camera(scene, robot, q, arm))
    assert is_red(red), red
    assert is_green(green), green
    # every box is red exactly when the world reports a contact of it
    for k, name in enumerate(names):
        c = scene.colors("robot", 0, box=k)[0]
        assert (c[0] > c[1]) == (name in {n.split("/")[1] for c_ in now for n in (c_.a, c_.b)
                                          if n.startswith("scara1/")}), name
    # a contact line per contact point, from the point on a along the push on b (out of the wall: -y)
    lines = scene.contact_lines()
    assert len(lines) == len(now)
    for seg, c in zip(lines, now):
        np.testing.assert_allclose(seg[0], c.point_a, atol=1e-12)
        np.testing.assert_allclose(seg[1] - seg[0], -scene.contact_length * c.normal, atol=1e-12)
    wall_lines = [seg for seg, c in zip(lines, now) if c.a == "wall"]
    assert wall_lines and all(seg[1, 1] < seg[0, 1] for seg in wall_lines)
    # scenery grey, the bar red, the cube purple: the colours of the faces drawn
    from matplotlib.colors import to_rgb

    for name, colour in (("wall", view.COLORS["scenery"]), ("bar", view.COLORS["body"]),
                         ("cube", view.COLORS["free_body"])):
        c = scene.colors("body", scene.body_index(name))[:, :3]
        hue = c / c.max(axis=1, keepdims=True)
        base = np.array(to_rgb(colour))
        np.testing.assert_allclose(hue, np.tile(base / base.max(), (len(c), 1)), atol=1e-9)
    # the bar's face towards the camera is red in the picture
    bar = sim.body_state("bar").pose
    assert is_red(pixel(img, scene, (bar @ [0.0, 0.0, 0.01, 1.0])[:3]))
    # without collision boxes: the robot's own colours, no lines
    plain = view.draw(new_axes(), sim)
    assert len(plain.contact_lines()) == 0 and not is_red(255 * plain.colors("robot", 0, box=quill)[0])


def rows_expected(log, robot, label="scara1"):
    """Colliding masks from the contact points (an independent count): row r is True when a point of the box
    (depth >= 0, as the events count them) falls in [t[r], t[r+1]): the row that held at its time."""
    cp = log.contact_points
    cp = cp[cp["depth"] >= 0]
    t = log.t
    out = np.zeros((len(t), len(robot.boxes)), dtype=bool)
    for k, name in enumerate(box_names(robot)):
        mine = cp[(cp["a"] == f"{label}/{name}") | (cp["b"] == f"{label}/{name}")]
        for tp in mine["t"].to_numpy():
            out[max(0, int(np.searchsorted(t, tp + 1e-12, side="right")) - 1), k] = True
    return out


def test_colliding_masks_from_the_log_of_a_wall_contact(wall_sim):
    sim = wall_sim
    log = sim.log
    robot = sim.robots[0]
    names = box_names(robot)
    masks = view.colliding_from_log(log, sim.robots)
    assert len(masks) == 1 and masks[0].shape == (len(log.t), len(robot.boxes)) and masks[0].dtype == bool
    m = masks[0]
    np.testing.assert_array_equal(m, rows_expected(log, robot))
    assert view.colliding_from_log(sim)[0].tolist() == m.tolist()      # a Simulation: its log and robots
    ev = log.contacts
    links = ev[ev["b"].str.startswith("scara1/")]
    assert set(links["a"]) == {"wall"}
    # boxes that never touch the wall stay False; those that do are True only from begin to end
    t = log.t
    for k, name in enumerate(names):
        mine = links[links["b"] == f"scara1/{name}"]
        if mine.empty:
            assert not m[:, k].any(), name
            continue
        following = np.concatenate([t[1:], [np.inf]])      # row r stands for [t[r], t[r+1])
        for _, e in mine.iterrows():
            end = np.inf if np.isnan(e["end"]) else e["end"]
            inside = (following > e["begin"] + 1e-12) & (t < end - 1e-12)
            assert m[inside, k].all(), name
        # outside every event of the box: False (the rows before its first beginning)
        first = mine["begin"].min()
        assert not m[following <= first + 1e-12, k].any(), name
    assert not m[:, [names.index(n) for n in ("base", "link1", "link2")]].any()
    quill = names.index("link3")
    assert m[-1, quill] and not m[0, quill]
    # a contact shorter than a log row (link4 touched the wall for two world steps) shows in one row
    short = links[(links["steps"] <= 5) & links["end"].notna()]
    assert len(short)
    for _, e in short.iterrows():
        assert m[:, names.index(e["b"].split("/")[1])].sum() == 1
    # contact points per row: the first world step's points of each pair in the row's interval (the last
    # row: the contacts of the final state)
    pts = view.contacts_from_log(log)
    assert len(pts) == len(t) and pts[0] is not None                 # the bar and the cube on the floor
    last = log.contact_points[log.contact_points["t"] == log.contact_points["t"].max()]
    np.testing.assert_allclose(pts[-1][:, 0], last[["point_x", "point_y", "point_z"]].to_numpy(), atol=1e-12)
    np.testing.assert_allclose(pts[-1][:, 1], -last[["normal_x", "normal_y", "normal_z"]].to_numpy(), atol=1e-12)
    # a log kept without contact points has none; the masks come from the events alone
    sim2 = cs.Simulation(dt=2e-4, world=cs.World(), log_every=10)
    sim2.add_robot(cs.robots.scara1(), cs.PID(0.0, 0.0, 0.0), np.array([0.0, 0.3, 0.1, 0.0, np.pi / 2, 0.02]))
    log2 = sim2.run(0.01, progress=False)
    assert view.contacts_from_log(log2) is None
    assert not view.colliding_from_log(log2, sim2.robots)[0].any()


def test_an_animation_of_a_simulation_draws_the_bar_at_its_logged_pose_and_the_colliding_boxes(wall_sim):
    sim = wall_sim
    log = sim.log
    anim = view.animate(sim, fps=25, figsize=(6.4, 4.8), dpi=80, collision_boxes=True, reference=False)
    assert len(anim) == 11 and anim.scene.body_names == ["wall", "bar", "cube"]
    bar_log = log.bodies["bar"]
    quill = box_names(sim.robots[0]).index("link3")
    masks = view.colliding_from_log(log, sim.robots)[0]
    for k in (0, 5, 10):
        anim.show_frame(k)
        row = int(np.argmin(np.abs(log.t - anim.times[k])))
        T = bar_log.poses()[row]
        drawn = anim.scene.faces("body", anim.scene.body_index("bar")).reshape(-1, 3)
        assert on_box(drawn, T, np.array([0.175, 0.01, 0.01]))          # at the logged pose of this frame's row
        img = render(anim.fig)
        assert is_red(pixel(img, anim.scene, bar_log.position[row] + [0.0, 0.0, 0.01])), k
        c = anim.scene.colors("robot", 0, box=quill)[0]
        assert (c[0] > c[1] + 0.3) == bool(masks[row, quill]), k
    assert masks[0, quill] is np.False_ and masks[-1, quill]


def test_an_animation_follows_a_moving_bar_frame_by_frame():
    # a bar thrown across the floor: frame k shows it, red, where the log has it at that frame's time
    w = cs.World()
    w.add_free_box("bar", [0.1, 0.03, 0.03], 0.15, position=[-0.3, 0.0, 0.35], velocity=[1.2, 0.0, 0.5], friction=0.5)
    w.add_static_box("block", [0.05, 0.2, 0.05], position=[0.6, 0.0, 0.05])
    sim = cs.Simulation(dt=2e-4, world=w, log_every=25)
    log = sim.run(0.5, progress=False)
    anim = view.animate(sim, fps=20, figsize=(6.4, 4.8), dpi=80)
    assert anim.scene.robots == [] and anim.scene.body_names == ["bar", "block"]      # in the order added
    bar = log.bodies["bar"]
    positions = []
    for k in (2, 6, 9):
        anim.show_frame(k)
        row = int(np.argmin(np.abs(log.t - anim.times[k])))
        img = render(anim.fig)
        drawn = anim.scene.faces("body", anim.scene.body_index("bar")).reshape(-1, 3)
        assert on_box(drawn, bar.poses()[row], np.array([0.1, 0.03, 0.03]))
        if np.linalg.norm(bar.position[row] - bar.position[row - 2]) > 1e-6:  # by frame 9 it has landed and rests
            assert not on_box(drawn, bar.poses()[row - 2], np.array([0.1, 0.03, 0.03]))
        p = bar.position[row]
        positions.append(p)
        assert is_red(pixel(img, anim.scene, p)), (k, pixel(img, anim.scene, p))
    # and not where it was in another frame: the pixel of frame 2's position is floor by frame 9
    assert np.linalg.norm(positions[0] - positions[2]) > 0.2
    assert not is_red(pixel(img, anim.scene, positions[0]))
    # the block: grey scenery
    anim.show_frame(0)
    img = render(anim.fig)
    grey = pixel(img, anim.scene, [0.6, 0.0, 0.1])
    assert np.ptp(grey) < 30 and 40 < grey.mean() < 200, grey


def test_the_task_scene_shows_the_container_and_the_bar_past_the_robots():
    from coopsim.tasks import scene as task
    from coopsim.view.geometry import box_samples, hidden, view_direction

    r1, r2 = task.scaras()
    sim = cs.Simulation(dt=2e-4, world=task.world())
    for r in (r1, r2):
        sim.add_robot(r, cs.PID(0.0, 0.0, 0.0), r.q_limits.mean(axis=1))
    scene = view.draw(new_axes(6.4, 4.8, 80), sim)
    names = [w[0] for w in task.container_walls()]
    assert scene.body_names == names + ["bar"]
    walls = [(w[2], w[1]) for w in task.container_walls()]
    robot_boxes = [r.shapes(r.q_limits.mean(axis=1)) for r in (r1, r2)]
    P = np.concatenate([b[0] for b in robot_boxes])
    H = np.concatenate([b[1] for b in robot_boxes])

    def hidden_fraction(azim):
        pts = np.concatenate([box_samples(T[None], h[None]) for T, h in walls])
        return hidden(pts, view_direction(scene.ax.elev, azim), P, H).mean()

    # matplotlib's usual camera (-62 degrees) has the container behind SCARA #1; the default turns past it
    assert hidden_fraction(-62.0) > 0.3
    assert hidden_fraction(scene.ax.azim) == 0.0
    # in the picture: the container's top wall where it is drawn, in its shade of the scenery's grey
    img = render(scene.fig)
    bare = render(view.draw(new_axes(6.4, 4.8, 80), sim, world=False, azim=scene.ax.azim, limits=scene.limits,
                            floor=scene.floor_extent, zoom=scene.zoom).fig)
    T, h = walls[1]
    top = (T @ [0.05, 0.0, h[2], 1.0])[:3]           # the middle of a tile (4 along the wall), off the seams
    seen = pixel(img, scene, top)
    want = 255 * scene.colors("body", names.index("container_top"), face=1)[0, :3]
    assert np.abs(seen - want).max() <= 6, (seen, want)
    assert np.abs(seen - pixel(bare, scene, top)).max() > 20
    # every box of the scene inside the picture
    h_px, w_px = img.shape[:2]
    xy = scene.project(scene.faces("robot").reshape(-1, 3))
    xy = np.concatenate([xy, scene.project(scene.faces("body").reshape(-1, 3))])
    assert (xy[:, 0] >= 0).all() and (xy[:, 0] < w_px).all() and (xy[:, 1] >= 0).all() and (xy[:, 1] < h_px).all()


# ---- holding: green while both robots hold the bar ----

@pytest.fixture(scope="module")
def handover():
    """test_grasp.py's two gantry grippers on one bar: a holds it from the start, b closes at 0.3 s, a opens
    at 0.7 s (a second of simulated time)."""
    from test_grasp import two_holders

    sim = two_holders(-0.1, 0.12, close_b=0.3, open_a=0.7)
    sim.run(1.0, progress=False)
    return sim


def test_holding_masks_from_the_log_are_the_dual_hold(handover):
    sim = handover
    log = sim.log
    t = log.t
    g = log.grasps
    assert list(zip(g["robot"], g["event"])) == [(0, "grasp"), (1, "grasp"), (0, "release")]
    # a row shows the grasp state at its time: both hold from b's grasp until a's release
    t_b, t_a = g["t"].iloc[1], g["t"].iloc[2]
    both = (t >= t_b) & (t < t_a)
    assert 25 < both.sum() < 60 and not (np.abs(t - t_b).min() < 1e-9 or np.abs(t - t_a).min() < 1e-9)
    masks = view.holding_from_log(log)
    assert len(masks) == 2 and all(m.dtype == bool and m.shape == t.shape for m in masks)
    np.testing.assert_array_equal(masks[0], both)
    np.testing.assert_array_equal(masks[1], both)
    for other in (view.holding_from_log(sim), view.holding_from_log(log, sim.robots)):
        assert all(np.array_equal(a, b) for a, b in zip(masks, other))
    # 'any': each robot whenever it holds the bar
    a, b = view.holding_from_log(log, mode="any")
    np.testing.assert_array_equal(a, (t >= g["t"].iloc[0]) & (t < t_a))
    np.testing.assert_array_equal(b, t >= t_b)
    np.testing.assert_array_equal(a, log[0].holding == "bar")
    # two robots holding different bodies are not a dual hold
    held = np.array([["bar", "box"], ["bar", "bar"], ["", ""]], dtype=object)
    from coopsim.view.world import _held_masks

    np.testing.assert_array_equal(_held_masks(held, "shared"), [[False, False], [True, True], [False, False]])
    # now, in draw: at the end b holds alone, so nothing is green unless holding='any'
    assert view.holding_now(sim) == [False, False] and view.holding_now(sim, mode="any") == [False, True]
    with pytest.raises(ValueError, match="mode"):
        view.holding_from_log(log, mode="both")
    with pytest.raises(ValueError, match="robots must match"):
        view.holding_from_log(log, [sim.robots[0]])


def inside_boxes(scene, robot, q, pts_xy, boxes, margin=1.5):
    """Whether each pixel (m, 2) lies in the picture of one of the robot's boxes at q (the convex hull of its
    projected corners, widened by margin pixels)."""
    from matplotlib.path import Path

    P, H = robot.shapes(q)
    inside = np.zeros(len(pts_xy), dtype=bool)
    for k in boxes:
        hull = Path(convex_hull(scene.project(corners(P[k], H[k]))))
        # a positive or negative radius widens the path depending on its orientation: take both
        inside |= hull.contains_points(pts_xy, radius=2 * margin) | hull.contains_points(pts_xy, radius=-2 * margin)
    return inside


def convex_hull(xy):
    """The convex hull of points (m, 2) as a closed ring, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(map(tuple, xy))

    def half(points):
        out = []
        for p in points:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    ring = half(pts) + half(pts[::-1])
    return np.array(ring + ring[:1])


def green_pixels(img):
    """(m, 2) x, y of the pixels in the holding green (not the bar's red nor the jaws' dark grey)."""
    g = (img[..., 1] > img[..., 0] + 40) & (img[..., 1] > img[..., 2] + 40)
    y, x = np.nonzero(g)
    return np.column_stack([x, y]).astype(float)


def test_an_animation_shows_the_robots_green_during_the_dual_hold_and_only_on_their_links(handover):
    sim = handover
    log = sim.log
    masks = view.holding_from_log(log)
    anim = view.animate(sim, fps=10, figsize=(6.4, 4.8), dpi=80, reference=False, label=False)
    for k in (2, 5, 9):                                   # a alone, both, b alone
        anim.show_frame(k)
        img = render(anim.fig)
        row = int(np.flatnonzero(log.t <= anim.times[k] + 1e-9)[-1])
        both = bool(masks[0][row])
        assert both == (k == 5)
        green = green_pixels(img)
        if not both:
            assert len(green) == 0, k
            continue
        # green on each robot's hand, where its face towards the camera is drawn, and nowhere else
        for i, robot in enumerate(sim.robots):
            q = np.interp(anim.times[k], log.t, log[i].q[:, 0]), np.interp(anim.times[k], log.t, log[i].q[:, 1])
            hand = [b.name for b in robot.boxes].index("hand")
            assert is_green(pixel(img, anim.scene, face_towards_camera(anim.scene, robot, np.array(q), hand)))
        on_robot = np.zeros(len(green), dtype=bool)
        for i, robot in enumerate(sim.robots):
            q = np.array([np.interp(anim.times[k], log.t, log[i].q[:, j]) for j in range(robot.dof)])
            on_robot |= inside_boxes(anim.scene, robot, q, green, range(len(robot.boxes)))
        assert len(green) > 2000 and on_robot.all(), green[~on_robot][:10]
    # holding='any': robot a green while it holds alone, b not
    anim = view.animate(sim, fps=10, figsize=(6.4, 4.8), dpi=80, holding="any")
    anim.show_frame(2)
    assert anim.scene.colors("robot", 0, box=0)[0][1] > anim.scene.colors("robot", 0, box=0)[0][0] + 0.2
    assert not anim.scene.colors("robot", 1, box=0)[0][1] > anim.scene.colors("robot", 1, box=0)[0][0] + 0.2
    # False: never green
    anim = view.animate(sim, fps=10, figsize=(2, 2), dpi=20, holding=False)
    anim.show_frame(5)
    assert all(anim.scene.colors("robot", i, box=0)[0][1] < anim.scene.colors("robot", i, box=0)[0][0] + 0.2
               for i in (0, 1))


def test_draw_from_a_simulation_colours_the_dual_hold_now():
    from test_grasp import two_holders

    sim = two_holders(-0.1, 0.1)
    sim.run(0.1, progress=False)
    assert sim.holding(0) == sim.holding(1) == "bar"
    scene = view.draw(new_axes(), sim)
    for i in (0, 1):
        c = scene.colors("robot", i, box=0)[0]
        assert c[1] > c[0] + 0.2 and c[1] > c[2] + 0.2
    sim.release(1)                                        # a alone: green only with holding='any'
    plain, anyone = view.draw(new_axes(), sim), view.draw(new_axes(), sim, holding="any")
    assert all(plain.colors("robot", i, box=0)[0][1] < plain.colors("robot", i, box=0)[0][0] + 0.2 for i in (0, 1))
    c = anyone.colors("robot", 0, box=0)[0]
    assert c[1] > c[0] + 0.2
    with pytest.raises(ValueError, match="holding"):
        view.draw(new_axes(), sim.robots, [np.zeros(2)] * 2, holding="any")   # no Simulation to ask
    with pytest.raises(ValueError, match="holding"):
        view.draw(new_axes(), sim, holding="all")


# ---- bad input ----

def test_bad_input_names_the_argument(run_log, tmp_path):
    log, robots = run_log
    small = dict(figsize=(2, 2), dpi=20)
    for speed in (-0.1, 4.5, float("nan"), "fast"):
        with pytest.raises(ValueError, match="speed"):
            view.animate(log, robots, speed=speed, **small)
    for fps in (0, -5, float("inf")):
        with pytest.raises(ValueError, match="fps"):
            view.animate(log, robots, fps=fps, **small)
    with pytest.raises(ValueError, match="duration"):
        view.animate(log, robots, speed=0, **small)
    for path in ("run.avi", "run", "run.mp4.txt"):
        with pytest.raises(ValueError, match="path"):
            view.animate(log, robots, path=tmp_path / path, **small)
    assert not list(tmp_path.iterdir())
    with pytest.raises(ValueError, match="fps"):
        view.animate(log, robots, fps=60, **small).save(tmp_path / "x.gif")
    with pytest.raises(ValueError, match="t_start"):
        view.animate(log, robots, t_start=2.0, **small)
    with pytest.raises(ValueError, match="holding"):
        view.animate(log, robots, holding=[None, np.ones(5, bool)], **small)
    with pytest.raises(ValueError, match=r"colliding\[0\]"):
        view.animate(log, robots, collision_boxes=True, colliding=[np.ones((len(log.t), 3), bool), None], **small)
    with pytest.raises(ValueError, match="reference"):
        view.animate(log, robots, reference=[np.zeros((len(log.t), 5)), None], **small)
    with pytest.raises(ValueError, match="contacts"):
        view.animate(log, robots, contacts=[None] * 3, **small)
    with pytest.raises(ValueError, match="holding must hold one array per robot"):
        view.animate(log, robots, holding=np.zeros(len(log.t), bool), **small)
    # one robot: its array alone; robots of different box counts each checked against their own
    one = cs.SimulationLog(log.t, [log[0]])
    view.animate(one, [R1], holding=list(log.t > 0.5), reference=log[0].q_ref, **small)
    with pytest.raises(ValueError, match=r"wrong shape for colliding: expected \(101, 8\)"):
        view.animate(one, [R1], collision_boxes=True, colliding=np.zeros((len(log.t), 7), bool), **small)
    arm = cs.Robot.from_dh([[0, 0, 0.3, 0]], [[0, 0, 0.15, 0]], [1.0], [cs.box_inertia(1.0, 0.3, 0.05, 0.05)],
                           joint_types="R")
    k_arm = len(arm.boxes)
    mixed = cs.SimulationLog(log.t, [log[0], cs.RobotLog("arm", log.t, **{k: getattr(log[0], k)[:, :1]
                                                                        for k in cs.log.STORED})])
    view.animate(mixed, [R1, arm], collision_boxes=True, **small,
                 colliding=[np.zeros((len(log.t), 8), bool), np.ones((len(log.t), k_arm), bool)])
    with pytest.raises(ValueError, match="robots"):
        view.animate(log, [R1], **small)
    with pytest.raises(ValueError, match=r"bodies\[0\].poses"):
        view.animate(log, robots, bodies=[view.Body("bar", [0.1, 0.1, 0.1], np.eye(3))], **small)

    ax = new_axes()
    with pytest.raises(ValueError, match=r"wrong shape for q\[1\]: expected \(6,\), got \(5,\)"):
        view.draw(ax, [R1, R2], [Q1, Q2[:5]])
    with pytest.raises(ValueError, match="q must hold one joint vector per robot"):
        view.draw(ax, [R1, R2], [Q1])
    with pytest.raises(ValueError, match="q"):
        view.draw(ax, R1, np.full(6, np.nan))
    scene = view.draw(new_axes(), [R1, R2], [Q1, Q2])
    with pytest.raises(ValueError, match=r"reference\[0\]"):
        scene.update(reference=[np.zeros(7), None])
    with pytest.raises(ValueError, match=r"wrong shape for colliding\[1\]: expected \(8,\)"):
        scene.update(colliding=[np.zeros(8, bool), np.zeros(7, bool)])
    with pytest.raises(ValueError, match="colliding"):
        scene.update(colliding=[np.zeros(8), np.full(8, 0.5)])
    with pytest.raises(ValueError, match="holding"):
        scene.update(holding=[True])
    with pytest.raises(ValueError, match="contacts"):
        scene.update(contacts=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="contacts"):
        scene.update(contacts=[[[0, 0, 0], [0, 0, 0]]])
    with pytest.raises(ValueError, match="half_extents"):
        scene.update(bodies=[view.Body("bar", [0.1, -0.1, 0.1], np.eye(4))])
    with pytest.raises(ValueError, match="ax"):
        fig = Figure()
        view.draw(fig.add_subplot(), R1, Q1)
    for kw, name in (({"floor": (1, 0, 0, 1)}, "floor"), ({"limits": [[0, 1], [0, 1]]}, "limits"),
                     ({"tile": 0}, "tile"), ({"colors": ["red"]}, "colors"), ({"zoom": -1}, "zoom"),
                     ({"elev": float("nan")}, "elev")):
        with pytest.raises(ValueError, match=name):
            view.draw(new_axes(), [R1, R2], [Q1, Q2], **kw)
    with pytest.raises(ValueError, match="kind"):
        scene.faces("floor")
    with pytest.raises(ValueError, match="k must be a frame index"):
        view.animate(log, robots, **small).show_frame(99)


def test_bad_world_input_names_the_argument(run_log):
    log, robots = run_log
    small = dict(figsize=(2, 2), dpi=20)
    for bad in ("wall", 42, [cs.World()], cs.robots.scara1()):
        with pytest.raises(ValueError, match="world must be a coopsim.World, a coopsim.Simulation"):
            view.draw(new_axes(), [R1, R2], [Q1, Q2], world=bad)
        with pytest.raises(ValueError, match="world must be"):
            view.animate(log, robots, world=bad, **small)
        with pytest.raises(ValueError, match="world must be"):
            view.world_bodies(bad)
    with pytest.raises(ValueError, match="robots must be given"):
        view.animate(log, **small)
    with pytest.raises(ValueError, match="q must be given"):
        view.draw(new_axes(), [R1, R2])
    with pytest.raises(ValueError, match="log must be"):
        view.colliding_from_log(np.zeros(3), [R1])
    with pytest.raises(ValueError, match="robots must match"):
        view.colliding_from_log(log, [R1])
    with pytest.raises(ValueError, match="no body named"):
        view.draw(new_axes(), [R1, R2], [Q1, Q2]).body_index("bar")
    with pytest.raises(ValueError, match="nothing to draw"):
        view.draw(new_axes(), [], world=cs.World())


# ---- plots ----

def test_plot_log_overlays_runs_with_labels_colours_and_whole_tick_values(run_log):
    import matplotlib.pyplot as plt

    from coopsim.plotting import plot_log, plot_trajectory

    log, _ = run_log
    fig = plot_log(log, robot=0, quantity="q", joints=[0, 2], joint_types="RRPRRP", label="slow PID", color="C2")
    try:
        shifted = cs.SimulationLog.from_dataframe(log.to_dataframe())
        plot_log(shifted, robot=0, quantity="q", joints=[0, 2], joint_types="RRPRRP", axes=fig.axes,
                 label="again", color="C3", reference=False)
        ax = fig.axes[1]
        assert len(ax.get_lines()) == 3
        assert [t.get_text() for t in ax.get_legend().get_texts()] == \
            ["slow PID: d3", "slow PID: d3 reference", "again: d3"]
        assert matplotlib.colors.same_color(ax.get_lines()[2].get_color(), "C3")
        assert ax.get_ylabel() == "d3 (m)"
        with pytest.raises(ValueError, match="color"):
            plot_log(log, color="not a colour")
    finally:
        plt.close(fig)
    # values near 0.3 varying by 1e-6: whole values on the ticks, no offset text
    from coopsim.log import STORED

    t = np.linspace(0.0, 1.0, 50)
    arrays = {k: np.zeros((50, 1)) for k in STORED}
    arrays["q"] = 0.3 + 1e-6 * np.sin(t)[:, None]
    fig = plot_log(cs.SimulationLog(t, [cs.RobotLog("x", t, **arrays)]), joint_types="P", reference=False)
    try:
        fig.canvas.draw()
        ax = fig.axes[0]
        assert ax.yaxis.get_offset_text().get_text() == ""
        ticks = [lab.get_text().replace("$\\mathdefault{", "").rstrip("}$") for lab in ax.get_yticklabels()]
        assert ticks and all(x.startswith(("0.30000", "0.29999")) for x in ticks), ticks
    finally:
        plt.close(fig)
    tr = cs.CubicTrajectory([0.0, 1.0], [[0.0, 0.1], [1.0, 0.2]])
    fig = plot_trajectory(tr, "RP", samples=20)
    try:
        # no axis mixes rad and m: the prismatic joint on a twin axis at the right
        assert [ax.get_ylabel() for ax in fig.axes] == [
            "position (rad, solid)", "velocity (rad/s, solid)", "acceleration (rad/s², solid)",
            "position (m, dashed)", "velocity (m/s, dashed)", "acceleration (m/s², dashed)"]
    finally:
        plt.close(fig)
    fig = plot_trajectory(tr, samples=20)
    try:
        assert fig.axes[0].get_ylabel() == "position (rad or m)"
    finally:
        plt.close(fig)


# ---- the live view example ----

@pytest.mark.slow  # a subprocess importing matplotlib and coopsim, drawing frames: seconds
def test_live_view_example_writes_its_frames(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    res = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "live_view.py"), "--matplotlib",
                          "--frames", "3", "--speed", "4", "--out", str(tmp_path)], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    frames = sorted(p.name for p in tmp_path.iterdir())
    assert frames == [f"live_view_{k:04d}.png" for k in range(3)]
    from PIL import Image

    with Image.open(tmp_path / frames[-1]) as im:
        assert im.size == (640, 480)


if __name__ == "__main__":
    if sys.argv[1:] == ["--write-reference"]:
        from PIL import Image

        os.makedirs(os.path.dirname(REFERENCE), exist_ok=True)
        Image.fromarray(reference_picture()).save(REFERENCE)
        print("wrote", REFERENCE)
    else:
        sys.exit(f"usage: python3 {sys.argv[0]} --write-reference")


# ---- one row for one time: the video, the replay and the contact masks ----

def test_rows_at_is_the_row_that_held_at_each_time():
    t = np.array([0.0, 0.1, 0.2, 0.2, 0.3])     # two rows at 0.2: the applied inputs changed there
    rows_at = cs.log.rows_at
    assert rows_at(t, [0.0, 0.1, 0.2, 0.3]).tolist() == [0, 1, 3, 4]        # at a row's time: that row, the last
    assert rows_at(t, [0.05, 0.15, 0.25, 0.2999]).tolist() == [0, 1, 3, 3]  # of two; between rows: the one before
    assert rows_at(t, [-1.0, -1e-3]).tolist() == [0, 0]                      # before the first row: the first
    assert rows_at(t, [0.3001, 7.0]).tolist() == [4, 4]                      # after the last row: the last
    assert 3 * 0.1 > 0.3 and rows_at(t, 3 * 0.1) == 4 and rows_at(t, 0.3 - 1e-12) == 4   # computed times meet
    assert rows_at(t, 0.3 - 1e-6) == 3                                       # their row; a microsecond is not it
    assert rows_at(t, np.full((2, 3), 0.1)).shape == (2, 3) and rows_at(t, 0.1).shape == ()
    assert rows_at([5.0], [0.0, 5.0, 9.0]).tolist() == [0, 0, 0]
    with pytest.raises(ValueError, match="at least one row"):
        rows_at([], 0.0)


def test_the_video_and_the_replay_show_the_row_that_held_at_each_time(tmp_path):
    # a bar thrown across the floor, logged every 40 ms, seen at 30 frames per second: most frames fall
    # between rows, and the nearest row would often be the next one
    w = cs.World()
    w.add_free_box("bar", [0.1, 0.03, 0.03], 0.15, position=[-0.3, 0.0, 0.35], velocity=[1.2, 0.0, 0.5], friction=0.5)
    sim = cs.Simulation(dt=2e-4, world=w, log_every=200)
    log = sim.run(0.4, progress=False)
    t = np.asarray(log.t)
    poses = log.bodies["bar"].poses()
    anim = view.animate(sim, fps=30, figsize=(3.2, 2.4), dpi=50)
    held = [int(np.flatnonzero(t <= tau + 1e-12)[-1]) for tau in anim.times]   # by hand: the last row at or before
    nearest = [int(np.argmin(np.abs(t - tau))) for tau in anim.times]
    assert sum(h != n for h, n in zip(held, nearest)) >= 3
    for k in range(len(anim)):
        anim.show_frame(k)
        drawn = anim.scene.faces("body", anim.scene.body_index("bar")).reshape(-1, 3)
        assert on_box(drawn, poses[held[k]], np.array([0.1, 0.03, 0.03]), tol=1e-9), k
    # the replay at the same rate: its keyframes are the rows that held at the frames' times (and the last
    # row), so at each of those times the replay holds the same row as the video
    import json
    import re

    with open(view.replay_html(sim, tmp_path / "r.html", fps=30), encoding="utf-8") as f:
        meta = json.loads(re.search(r'<script type="application/json" id="cs-meta">(.*?)</script>', f.read(),
                                    re.S).group(1))
    keys = np.array(meta["frames"])
    assert keys.tolist() == t[sorted(set(held) | {len(t) - 1})].tolist()
    for tau, h in zip(anim.times, held):
        assert keys[np.flatnonzero(keys <= tau + 1e-12)[-1]] == t[h]


def test_a_contact_shows_in_the_rows_that_held_while_it_lasted():
    # a log with two rows at one time (an applied force set between runs), contact events of one box
    # beginning and ending between rows, at a row's time and at the duplicate time: row r stands for
    # [t[r], t[r+1]), so a contact shows from the row that held at its beginning to the last row before its end
    t = np.array([0.0, 0.1, 0.2, 0.2, 0.3])
    robot = cs.robots.scara1()
    rl = cs.RobotLog("scara1", t, holding=np.full(len(t), ""), weld=np.zeros((len(t), 6)),
                     **{k: np.zeros((len(t), 6)) for k in cs.log.STORED})
    box = [b.name for b in robot.boxes].index("link3")
    for begin, end, rows in ((0.05, 0.07, [0]), (0.05, 0.1, [0]), (0.05, 0.1001, [0, 1]), (0.1, 0.2, [1]),
                             (0.2, 0.25, [3]), (0.15, np.nan, [1, 2, 3, 4]), (0.3, np.nan, [4])):
        events = dict(a=["wall"], b=["scara1/link3"], kind=["robot-scenery"], begin=[begin], end=[end],
                      peak_force=[1.0], max_depth=[0.0], steps=[1])
        log = cs.SimulationLog(t, [rl], dt=0.01, control_every=1, log_every=10, contacts=events)
        mask = view.colliding_from_log(log, [robot])[0]
        assert np.flatnonzero(mask[:, box]).tolist() == rows, (begin, end)
        assert not np.delete(mask, box, axis=1).any()


# ---- what the picture tells: the world's axes and a scale, the robots' names, two holding robots ----

def test_the_scene_draws_the_worlds_axes_with_their_scale_and_names_the_robots():
    s = known_scene(new_axes())
    # the floor (1.4 x 1.1 m) takes axes 0.2 m long (the largest scale below a fifth of its smaller side)
    assert s.scale == 0.2
    seg = s.triad_segments
    assert seg.shape == (3, 2, 3)
    np.testing.assert_allclose(seg[:, 1] - seg[:, 0], 0.2 * np.eye(3), atol=1e-12)   # x, y, z, 0.2 m each
    np.testing.assert_allclose(seg[:, 0], [[FLOOR[0] + 0.05, FLOOR[2] + 0.05, 0.05]] * 3, atol=1e-12)
    assert [t.get_text() for t in s.triad_labels] == ["x", "y", "z", "axes 0.2 m"]
    # each robot's name on the floor at the foot of its base, on the camera's side, over the floor, under the boxes
    assert [t.get_text() for t in s.names] == [R1.name, R2.name]
    cam = np.array([np.cos(np.radians(s.ax.azim)), np.sin(np.radians(s.ax.azim))])
    for t, r, base_xy in zip(s.names, (R1, R2), ((0.0, 0.0), (0.75, 0.0))):
        x, y, z = t.get_position_3d()
        off = np.array([x, y]) - base_xy
        assert z == 0.0 and 0.06 < off @ cam < 0.25 and abs(off @ [-cam[1], cam[0]]) < 1e-6, off
        assert s.floor.get_zorder() < t.get_zorder() < s.polys.get_zorder()
    # off on request; with matplotlib's own axes (axis=True) no triad
    off = known_scene(new_axes(), triad=False, names=False)
    assert len(off.triad_segments) == 0 and off.triad_labels == [] and off.names == []
    assert len(known_scene(new_axes(), axis=True, limits=None).triad_segments) == 0


def test_two_holding_robots_are_different_greens():
    s = known_scene(new_axes(), holding=[True, True], cull=False)
    # the same face (the top of link 2, facing up in both) of each robot: both green, told apart
    a, b = s.colors("robot", 0, box=2, face=1)[0][:3], s.colors("robot", 1, box=2, face=1)[0][:3]
    for c in (a, b):
        assert c[1] > c[0] + 0.1 and c[1] > c[2] + 0.1, c
    assert np.abs(a - b).max() > 0.2, (a, b)
    # the shades are COLORS' holding_shades, the first the holding colour
    assert view.COLORS["holding_shades"][0] == view.COLORS["holding"]


# ---- inclines and the zoom on a held body ----

@pytest.fixture(scope="module")
def task_run():
    """One cycle of the cooperative task (under a second), for its figures."""
    from coopsim.tasks.handover import run

    return run(cycles=1, score=False)


def test_an_inclined_static_body_is_drawn_rotated_and_seen_from_its_side():
    from coopsim.tasks import scene as task_scene

    w = task_scene.world()
    r1, r2 = task_scene.scaras()
    sc = view.draw(new_axes(6.4, 4.8, 50), [r1, r2], [np.zeros(6), np.zeros(6)], world=w)
    slope = task_scene.CONTAINER["slope"]
    downhill = np.array([0.0, np.cos(slope), -np.sin(slope)])      # the tube's axis (scene.container_axes)
    for name, half, T in task_scene.container_walls():
        drawn = sc.faces("body", sc.body_index(name)).reshape(-1, 3)
        # the polygons (tiles of the faces) lie on the box turned by its pose, and its corners (computed here
        # directly) are among their vertices
        local = (drawn - T[:3, 3]) @ T[:3, :3]
        assert np.all(np.abs(local) <= half + 1e-12), name
        assert np.all(np.isclose(np.abs(local), half, atol=1e-12).any(axis=1)), name
        d = np.linalg.norm(corners(T, half)[:, None, :] - drawn[None, :, :], axis=2)
        assert d.min(axis=1).max() < 1e-12, name
        # and its long edges go down the axis at the slope, not level
        c = corners(T, half)
        edges = [c[j] - c[i] for i in range(8) for j in range(8) if np.isclose(np.linalg.norm(c[j] - c[i]),
                                                                                 2 * half[0])]
        for e in edges:
            assert abs(abs(e @ downhill) / np.linalg.norm(e) - 1.0) < 1e-12
            assert np.degrees(np.arcsin(abs(e[2]) / np.linalg.norm(e))) == pytest.approx(25.0, abs=1e-9)
    # one incline (the tube's four walls), its slope written over it beside a level line
    (inc,) = sc.inclines
    assert sorted(inc["names"]) == sorted(n for n, _, _ in task_scene.container_walls())
    assert inc["slope"] == pytest.approx(25.0, abs=1e-9)
    np.testing.assert_allclose(inc["axis"], downhill, atol=1e-12)
    assert [t.get_text() for t in sc.incline_labels] == ["25° incline"]
    (level,) = sc.level_segments
    assert level[0, 2] == pytest.approx(level[1, 2])                       # level
    run = level[1] - level[0]
    np.testing.assert_allclose(run / np.linalg.norm(run), [0.0, 1.0, 0.0], atol=1e-12)   # along the axis in plan
    # the camera looks at the tube's side: its plan view direction within 45 degrees of square to the axis
    v = view.geometry.view_direction(sc.ax.elev, sc.ax.azim)[:2]
    assert abs(v @ downhill[:2]) / (np.linalg.norm(v) * np.linalg.norm(downhill[:2])) <= np.cos(np.radians(45)) + 1e-9


def test_a_level_box_turned_about_z_is_no_incline():
    w = cs.World(floor=True)
    T = np.eye(4)
    T[:3, :3] = [[np.cos(0.7), -np.sin(0.7), 0.0], [np.sin(0.7), np.cos(0.7), 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = [0.5, 0.2, 0.05]
    w.add_static_box("table", [0.3, 0.1, 0.05], T)
    sc = view.draw(new_axes(), [R1], [Q1], world=w)
    assert sc.inclines == [] and sc.incline_labels == []


def held_inside(sc, robot, body):
    """Whether the inset's limits hold every corner of the body and of the robot's clamp boxes."""
    L = sc.inset.limits
    half, poses, _ = sc._bodies[sc.body_index(body)]
    pts = [np.concatenate([corners(T, h) for T, h in zip(poses, half)])]
    r = sc.robots[robot]
    P, H = r.shapes(sc._q[robot])
    pts += [corners(P[k], H[k]) for k, b in enumerate(r.boxes) if b.link >= r.clamp.fixed_link]
    pts = np.concatenate(pts)
    return bool(np.all((pts >= L[:, 0] - 1e-9) & (pts <= L[:, 1] + 1e-9))), pts


def test_the_inset_frames_the_held_body_and_the_clamp_holding_it(task_run):
    sim = task_run.sim
    log = sim.log
    t = 0.5 * sum(task_run.report["cycles"][0]["steps"]["insert"])
    anim = view.animate(sim, t_start=t, t_end=t, inset=True, figsize=(6.4, 4.8), dpi=50)
    sc = anim.scene
    row = int(np.searchsorted(log.t, t, side="right")) - 1
    assert log.robots[0].holding[row] == "bar"
    assert sc.inset is not None and sc.inset.ax in sc.fig.axes and sc.inset.ax.get_visible()
    ok, pts = held_inside(sc, 0, "bar")
    assert ok
    # a tight frame: a cube 1.3 times the larger extent of the bar and the clamp, much smaller than the scene's
    side = np.ptp(sc.inset.limits, axis=1)
    np.testing.assert_allclose(side, max(1.3 * np.ptp(pts, axis=0).max(), 0.06), rtol=1e-12)
    assert side[0] < 0.5 * np.ptp(sc.limits, axis=1).max()
    assert "bar held by scara1" in sc.inset_label.get_text()
    # the inset shows the same boxes: the bar's faces as in the scene
    np.testing.assert_allclose(sc.inset.faces("body", sc.inset.body_index("bar")),
                               sc.faces("body", sc.body_index("bar")))
    # the task's figure (insertion.png among report_figures) is this one
    from coopsim.tasks.handover.report import insertion_figure

    fig = insertion_figure(task_run)
    assert len(fig.axes) == 2 and fig.axes[1].get_visible()
    assert "bar held by scara1" in "".join(t.get_text() for t in fig.texts)


def test_the_inset_follows_the_hold_and_hides_without_one(task_run):
    sim = task_run.sim
    log = sim.log
    anim = view.animate(sim, fps=1, speed=2.0, inset=True, figsize=(3.2, 2.4), dpi=50)
    shown = 0
    for k, t in enumerate(anim.times):
        anim.show_frame(k)
        row = int(np.searchsorted(log.t, t, side="right")) - 1
        holders = [i for i, rl in enumerate(log.robots) if rl.holding[row]]
        assert anim.scene.inset.ax.get_visible() == bool(holders), t
        for i in holders:
            assert held_inside(anim.scene, i, log.robots[i].holding[row])[0], (t, i)
        shown += bool(holders)
    assert 0 < shown < len(anim.times)
    # blitting draws the inset as a full draw does
    frames = [f[..., :3].astype(int) for f in anim.frames()]
    for k in (0, len(anim) // 2):
        anim.show_frame(k)
        np.testing.assert_array_equal(frames[k], render(anim.fig))


def test_draw_insets_what_a_simulation_holds(task_run):
    sc = view.draw(new_axes(), task_run.sim, inset=True)
    held = [task_run.sim.holding(i) for i in range(2)]
    assert sc.inset.ax.get_visible() == any(held)
    sc2 = view.draw(new_axes(), task_run.sim, inset=True, held=[None, "bar"])
    assert sc2.inset.ax.get_visible() and held_inside(sc2, 1, "bar")[0]
    with pytest.raises(ValueError, match="held must hold one body name"):
        view.draw(new_axes(), task_run.sim, inset=True, held=["bar"])
