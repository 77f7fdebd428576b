"""The live view (coopsim.view.live): a page served by viser on 127.0.0.1 while the simulation runs.

Without a browser: what the view draws is the engine's (box poses from Robot.shapes, quaternions checked
against their matrices), the requests reach the simulation through the simulation's thread, bad values are
refused and the run goes on, an exception of the run reaches Python, close() frees the port. In Debian's
chromium (headless, through Playwright, as tests/test_replay.py): the scene's colours where the camera puts
the robots and the bar, a holding robot green, colliding boxes red, the page's controls (slider, buttons,
text fields) reaching the pacer and the simulation, the downloads, several pages at once.
"""
from __future__ import annotations

import io
import math
import socket
import time

import numpy as np
import pytest

import coopsim as cs
from coopsim import view

viser = pytest.importorskip("viser", reason="the live view needs viser (the live extra; scripts/setup.sh)")

from test_grasp import BOX, closing, scene  # noqa: E402  (a SCARA #1 closing its clamp on a box)
# Debian's chromium through Playwright, its pages patient; WAIT (180 s): the generous bound for anything the page
# or the run must reach (never a timing assertion)
from test_replay import WAIT, browser, patient  # noqa: E402,F401


def until(cond, what, timeout=WAIT):
    """Polls cond() until it is true; fails naming `what` after `timeout` s."""
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            pytest.fail(f"not reached in {timeout} s: {what}")
        time.sleep(0.02)


def two_scaras(world=None, **kw):
    r1 = cs.robots.scara1()
    r2 = cs.robots.scara2(base_position=(0.75, 0.0, 0.0), base_yaw=np.pi)
    sim = cs.Simulation(world=world, **kw)
    for r, q0 in ((r1, [0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03]), (r2, [0.4, -0.5, -0.5, 0.0, 0.0, 0.02])):
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), np.array(q0, dtype=float))
    return sim


@pytest.fixture
def views():
    """Live views made by a test, closed after it."""
    made = []
    yield made
    for v in made:
        v.close()


def make(views, sim, **kw):
    kw.setdefault("quiet", True)
    v = view.live(sim, **kw)
    views.append(v)
    return v


# ---- without a browser ----

def test_quaternions_match_their_rotation_matrices():
    from coopsim.view.live import _rotation, quaternions

    rng = np.random.default_rng(3)
    Q = rng.normal(size=(200, 4))
    Q /= np.linalg.norm(Q, axis=1, keepdims=True)
    # near 180-degree turns about each axis, where the trace is about -1
    Q[:6] = [[1e-9, 1, 0, 0], [1e-9, 0, 1, 0], [1e-9, 0, 0, 1], [0, 1, 1, 0], [0, 0, 1, 1], [0, 1, 0, 1]]
    Q[:6] /= np.linalg.norm(Q[:6], axis=1, keepdims=True)
    R = np.array([_rotation(q) for q in Q])
    assert np.allclose(np.einsum("kij,kil->kjl", R, R), np.eye(3), atol=1e-12)
    back = quaternions(R)
    assert np.all(back[:, 0] >= 0)
    assert np.allclose(np.array([_rotation(q) for q in back]), R, atol=1e-12)
    assert np.allclose(np.abs(np.einsum("ki,ki->k", back, Q)), 1.0, atol=1e-12)   # q and -q: one rotation


def test_bad_arguments_name_what_is_wrong(views):
    sim = two_scaras()
    with pytest.raises(ValueError, match="sim must be a coopsim.Simulation"):
        view.live("sim")
    for kw, match in ((dict(port=-1), "port"), (dict(port=True), "port"), (dict(history=0), "history"),
                      (dict(holding="both"), "holding|mode"), (dict(speed=5), "speed"),
                      (dict(frame_rate=0), "frame_rate"), (dict(t_end="x"), "t_end"), (dict(move_time=0), "move time")):
        with pytest.raises(ValueError, match=match):
            view.live(sim, quiet=True, start=False, **kw)


def test_a_frame_is_the_engines_boxes_at_q_and_at_the_reference(views):
    sim = two_scaras(world=cs.World())
    sim.run(0.05, progress=False)
    v = make(views, sim, start=False)
    f = v.frame
    assert f.t == sim.time and f.steps == sim.steps
    for i, r in enumerate(sim.robots):
        q, qd = sim.state(i)
        P, H = r.shapes(q)
        G, _ = r.shapes(sim.references[i].evaluate(sim.time)[0])
        assert np.array_equal(f.q[i], q) and np.array_equal(f.poses[i], P) and np.array_equal(f.half[i], H)
        assert np.array_equal(f.ghost[i], G)
    # what was sent: the robot mesh's positions and orientations are those boxes (float32 on the wire)
    P = np.concatenate(f.poses)
    from coopsim.view.live import _rotation

    mesh = v._robot_mesh
    assert np.allclose(mesh.batched_positions, P[:, :3, 3], atol=1e-6)
    assert np.allclose(np.array([_rotation(q) for q in mesh.batched_wxyzs]), P[:, :3, :3], atol=1e-6)
    # the parts drawn: each batched mesh's instances at the parts' poses (Frame.parts, from coopsim.view.parts)
    from coopsim.view.parts import part_poses, robot_parts

    every = np.concatenate(f.parts)
    assert sum(len(m[1]) for m in v._part_meshes) == len(every) == sum(len(robot_parts(r)) for r in sim.robots)
    for handle, index, robot, *_ in v._part_meshes:
        assert np.allclose(handle.batched_positions, every[index, :3, 3], atol=1e-6)
        assert np.allclose(np.array([_rotation(q) for q in handle.batched_wxyzs]), every[index, :3, :3], atol=1e-6)
    for i, r in enumerate(sim.robots):
        assert np.array_equal(f.parts[i], part_poses(r, robot_parts(r), f.q[i]))
        assert np.array_equal(f.ghost_parts[i], part_poses(r, robot_parts(r), f.q_ref[i]))
    # the ghosts: the parts of the moving links (the bases never move)
    assert sum(len(m[1]) for m in v._ghost_meshes) == sum(sum(p.link != 0 for p in robot_parts(r)) for r in sim.robots)
    # the collision boxes hidden, the parts shown (collision_boxes=False); the Display toggle swaps them
    assert not mesh.visible and all(m[0].visible for m in v._part_meshes)
    v.set_display("collision_boxes", True)
    assert mesh.visible and not any(m[0].visible for m in v._part_meshes)
    v.set_display("collision_boxes", False)
    assert not mesh.visible and all(m[0].visible for m in v._part_meshes)


def test_requests_run_on_the_simulations_thread_and_bad_values_are_refused(views):
    sim = two_scaras(control_every=5)
    v = make(views, sim, speed=1.0)
    until(lambda: sim.time > 0.05, "the run started")
    seen = []
    v.submit(lambda: seen.append(__import__("threading").current_thread().name))
    until(lambda: seen, "a request applied")
    assert seen == ["coopsim-live"]                     # the view's run thread, never the caller's
    v.set_speed_percent(250)
    until(lambda: v.pacer.speed == 2.5 and "Speed 250 %" in v.message, "speed 250 %")   # applied and said
    for bad in ("fast", float("nan"), 401, -1):
        v.set_speed_percent(bad)
        until(lambda: "Refused" in v.message and "speed" in v.message, f"speed {bad!r} refused")
        v._say("")
    assert v.pacer.speed == 2.5
    # pause: the time stands still across two reads; resume: it moves
    v.pause()
    until(lambda: v.pacer.paused, "paused")
    time.sleep(0.1)
    t1 = sim.time
    time.sleep(0.2)
    assert sim.time == t1
    # one step: exactly one control period
    s0 = sim.steps
    v.one_step()
    until(lambda: sim.steps != s0, "one step")
    assert sim.steps - s0 == 5 and math.isclose(sim.time - t1, 5 * sim.dt, rel_tol=1e-12)
    v.resume()
    until(lambda: sim.time > t1 + 0.05, "running again")
    # bad joint targets: text, NaN, a wrong count, beyond a limit; the run goes on
    r = sim.robots[0]
    for bad, match in (("a, b", "6 numbers"), ("nan, 0, 0, 0, 0, 0", "finite"), ("1, 2, 3", "6 numbers"),
                       ("0, 0, 0.3, 0, 0, 0", "q3 = 0.3 is beyond")):
        v.teach_joints(0, bad)
        assert "Refused" in v.message and match in v.message, v.message
    for bad in ("x", "nan", "0", "-1", "100"):
        v._refusing(lambda: v.set_move_time(bad))
        assert "Refused" in v.message and "move time" in v.message, v.message
    t2 = sim.time
    until(lambda: sim.time > t2 + 0.05, "the run goes on after refusals")
    assert v.error is None and r is not None


def test_a_teach_target_becomes_a_cubic_from_where_the_robot_is(views):
    sim = two_scaras()
    v = make(views, sim, speed=1.0, move_time=0.5)
    until(lambda: sim.time > 0.02, "the run started")
    target = np.array([0.1, -0.4, 0.05, 0.3, 1.0, 0.02])
    v.teach_joints(1, ", ".join(str(float(x)) for x in target))
    until(lambda: isinstance(v.call(lambda: sim.references[1]), cs.CubicTrajectory), "the new reference")
    ref, log = v.call(lambda: (sim.references[1], sim.log))
    t0 = ref.t_start
    assert math.isclose(ref.t_end - t0, 0.5)
    assert np.array_equal(ref.q_points[-1], target) and np.array_equal(ref.qd_points[-1], np.zeros(6))
    # from where the robot was when the request was applied: the log's row at t0 (log_every=1)
    k = int(np.flatnonzero(log.t == t0)[0])
    assert np.array_equal(ref.q_points[0], log[1].q[k]) and np.array_equal(ref.qd_points[0], log[1].qd[k])
    # the clamp gizmo's handler: the closed-form IK of the pose, nearest the robot's q, as the new target
    r = sim.robots[0]
    T = r.fk(np.array([0.2, 0.9, 0.12, 0.4, np.pi / 2, 0.03]))
    v.teach_pose(0, T)
    until(lambda: isinstance(v.call(lambda: sim.references[0]), cs.CubicTrajectory), "the IK reference")
    ref, log = v.call(lambda: (sim.references[0], sim.log))
    k = int(np.flatnonzero(log.t == ref.t_start)[0])
    q_end = ref.q_points[-1]
    assert np.array_equal(q_end, r.ik(T, q_near=log[0].q[k]))
    assert np.allclose(r.fk(q_end), T, atol=1e-9)
    # out of reach: the IK's message, the reference kept
    far = T.copy()
    far[:3, 3] = [3.0, 0.0, 0.3]
    v.teach_pose(0, far)
    until(lambda: "Refused" in v.message, "an unreachable pose refused")
    assert np.array_equal(v.call(lambda: sim.references[0]).q_points[-1], q_end)
    v.teach_pose(0, np.full((4, 4), np.nan))
    assert "Refused" in v.message and "finite" in v.message


def test_reset_goes_back_to_the_start_with_the_first_references(views):
    sim = two_scaras()
    ref0 = [r.q for r in sim.references]
    v = make(views, sim)
    until(lambda: sim.time > 0.05, "the run started")
    v.teach_joints(0, [0.1, 0.2, 0.1, 0.0, 1.0, 0.02])
    until(lambda: isinstance(v.call(lambda: sim.references[0]), cs.CubicTrajectory), "the teach move")
    v.pause()
    until(lambda: v.pacer.paused, "paused")
    v.reset()
    until(lambda: sim.time == 0.0, "back at t = 0")
    assert [np.array_equal(r.q, q) for r, q in zip(v.call(lambda: sim.references), ref0)] == [True, True]
    v.resume()
    until(lambda: sim.time > 0.02, "running from the start")


def test_an_exception_in_the_run_reaches_python_and_the_panel(views):
    class Failing(cs.Controller):
        def __init__(self):
            super().__init__()

        def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
            if t > 0.05:
                raise RuntimeError("controller failed on purpose")
            return np.zeros(len(q))

    sim = cs.Simulation()
    sim.add_robot(cs.robots.scara1(), Failing(), np.array([0.3, 0.6, 0.1, 0.0, 1.0, 0.03]))
    v = make(views, sim, t_end=1.0, speed=4.0)
    with pytest.raises(RuntimeError, match="controller failed on purpose"):
        v.wait(timeout=WAIT)
    assert "Run stopped" in v.message and "controller failed on purpose" in v.message
    assert "controller failed on purpose" in v._msg.content


def test_keep_clock_paces_a_run_in_short_pieces_as_one_run():
    """A run sequenced in 10 ms pieces (a task waiting for a grasp) keeps real time with keep_clock; without
    it each piece waits for a frame of its own. A fake clock: exact, whatever the machine's load."""
    def paced(keep_clock):
        now = [0.0]
        pacer = cs.Pacer(speed=1.0, frame_rate=50.0, clock=lambda: now[0],
                         sleep=lambda d: now.__setitem__(0, now[0] + d))
        sim = two_scaras()
        for k in range(1, 21):
            pacer.run(sim, 0.01 * k, keep_clock=keep_clock)
        assert math.isclose(sim.time, 0.2, abs_tol=sim.dt / 2)
        return now[0]

    assert paced(True) <= 0.2 + 0.02 + 1e-9          # real time, but for the first frame (20 ms)
    assert paced(False) >= 2 * 0.2                   # a frame or more per piece


def test_run_to_drives_from_the_callers_thread_and_close_frees_the_port(views):
    sim = two_scaras()
    v = make(views, sim, start=False, speed=4.0, resettable=False)
    v.run_to(0.2)
    assert math.isclose(sim.time, 0.2, abs_tol=sim.dt / 2) and v.frames > 1
    v.reset()
    assert "Refused" in v.message and sim.time > 0.19
    port = v.port
    v.close()
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", port))          # free again
    v2 = make(views, sim, start=False, port=port)
    assert v2.port == port and v2.url == f"http://127.0.0.1:{port}"


def test_the_server_binds_localhost_by_default(views):
    v = make(views, two_scaras(), start=False)
    assert v.host == "127.0.0.1" and v.server.get_host() == "127.0.0.1"
    assert v.url.startswith("http://127.0.0.1:")
    assert v.server._share_tunnel is None


# ---- in a browser ----

def live_page(browser, width, height):  # noqa: F811
    """A new browser page for a live view. Every action of Playwright (a click, a fill, a shot) waits for
    the page's rendered frames, and on a loaded machine the live page's software WebGL may take many seconds
    for a frame: each action may take up to WAIT s (a bound load can only approach, never a timing)."""
    return patient(browser.new_page(viewport={"width": width, "height": height}, accept_downloads=True))


def page_ready(page):
    """Waits (up to WAIT s) until the live page says it takes input: its <html data-coopsim-live="ready">,
    set by the page itself once it is connected, its tabs are built and it has drawn frames since
    (coopsim.view.live.serving.announce_readiness), and again after a reconnect."""
    from coopsim.view.live.serving import READY_ATTRIBUTE

    page.locator(f'html[{READY_ATTRIBUTE}="ready"]').wait_for(state="attached", timeout=WAIT * 1000)


def open_live(page, url):
    """Opens the live page at `url` in `page` and waits until it is ready (page_ready)."""
    page.goto(url)
    page_ready(page)
    return page


class LivePage:
    """A browser page of a live view (or of any object with the view's `url`, e.g. a view served by another
    process: _Url); waits for the page's own readiness and elements, never for a fixed time."""

    def __init__(self, browser, v, width=900, height=560, keep=None):   # noqa: F811
        self.v, self.keep = v, keep
        self.page = open_live(live_page(browser, width, height), v.url)
        if getattr(v, "server", None) is not None:
            until(lambda: len(v.server.get_clients()) > 0, "the page connected")

    def ready(self):
        page_ready(self.page)

    def reload(self):
        self.page.reload()
        self.ready()

    def tab(self, name):
        self.ready()                       # connected (a disconnected page's panel takes no clicks)
        self.page.get_by_role("tab", name=name).click()

    def click(self, name):
        self.ready()
        self.page.get_by_role("button", name=name, exact=True).click()

    def slider(self, label):
        """The thumb of the (first visible) slider with this label (its label names the slider's root)."""
        lab = self.page.locator("label:visible", has_text=label).first
        return self.page.locator(f'[id="{lab.get_attribute("for")}"] [role="slider"]')

    def field(self, label):
        """The (first visible) text input labelled so (the label sits beside it in its row)."""
        return self.page.locator(f'xpath=//label[normalize-space()="{label}"]/ancestor::div'
                                 f'[contains(@class, "mantine-Flex-root")][1]//input').first

    def camera(self):
        client = list(self.v.server.get_clients().values())[-1]
        return client.camera

    def canvas_pixels(self):
        """The canvas as drawn now, (rows, columns, 3) ints (a page shot clipped to the canvas: no waiting
        for the element to be still, which a live page never is)."""
        from PIL import Image

        box = self.page.locator("canvas").first.bounding_box()
        png = self.page.screenshot(clip=box)
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)

    def shows(self, point, test, what, radius=4):
        """Waits until the canvas shows a pixel passing `test` within `radius` px of where the page's camera
        puts the world point (3,) (projected anew each time: the camera settles after the page loads);
        returns the shot."""
        shot = []

        def look():
            shot[:] = [self.canvas_pixels()]
            return colour_near(shot[0], self.project(point)[0], test, radius)
        try:
            until(look, what)
        finally:
            if shot and self.keep is not None:       # what the page showed last, to look at
                from PIL import Image

                Image.fromarray(shot[0].astype(np.uint8)).save(self.keep / "last_shot.png")
        return shot[0]

    def project(self, points):
        """Pixel (column, row) of world points (m, 3) in the canvas, from the page's camera."""
        cam = self.camera()
        p, look = np.asarray(cam.position), np.asarray(cam.look_at)
        f = (look - p) / np.linalg.norm(look - p)
        right = np.cross(f, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, f)
        d = np.asarray(points, dtype=float).reshape(-1, 3) - p
        W, H = cam.image_width, cam.image_height
        k = (H / 2) / math.tan(cam.fov / 2)
        z = d @ f
        return np.column_stack([W / 2 + k * (d @ right) / z, H / 2 - k * (d @ up) / z])

    def close(self):
        self.page.close()


def colour_near(img, uv, test, radius=6):
    """Whether a pixel within `radius` px of uv passes test(r, g, b) (arrays)."""
    u, v = int(round(uv[0])), int(round(uv[1]))
    patch = img[max(0, v - radius):v + radius + 1, max(0, u - radius):u + radius + 1]
    return bool(np.any(test(patch[..., 0], patch[..., 1], patch[..., 2])))


def hue_sat(r, g, b):
    """Hue (degrees, 0 .. 360) and saturation (0 .. 1) of RGB arrays: shading changes neither much."""
    r, g, b = (np.asarray(x, dtype=float) for x in (r, g, b))
    hi, lo = np.maximum(np.maximum(r, g), b), np.minimum(np.minimum(r, g), b)
    c = np.where(hi > lo, hi - lo, 1.0)
    h = np.where(hi == r, ((g - b) / c) % 6, np.where(hi == g, (b - r) / c + 2, (r - g) / c + 4)) * 60.0
    return np.where(hi > lo, h, 0.0), np.where(hi > 0, (hi - lo) / np.maximum(hi, 1), 0.0)


def hue_test(centre, width=15.0, saturation=0.35):
    """A pixel test: hue within `width` degrees of `centre` (the colour's own hue), saturated."""
    def test(r, g, b):
        h, s = hue_sat(r, g, b)
        return (np.abs((h - centre + 180.0) % 360.0 - 180.0) <= width) & (s >= saturation)
    return test


def hue_of(colour):
    from matplotlib.colors import to_rgb

    return float(hue_sat(*np.array(to_rgb(colour)) * 255)[0])


# faces lit from above (the links' tops, which the start camera's fitted view shows) come out paler: saturation
# 0.27 to 0.30 measured on the SCARAs' links; the hues keep the colours apart (grey floor and columns are
# under 0.05)
is_red = hue_test(hue_of(view.COLORS["body"]))                 # the bar; colliding boxes (the same hue)
is_green = hue_test(hue_of(view.COLORS["holding"]), width=25, saturation=0.22)  # holding; free collision boxes
is_orange = hue_test(hue_of(view.COLORS["robots"][0]), saturation=0.2)          # SCARA #1's links


def test_the_readiness_script_follows_the_panels_and_names_their_tabs(views):
    """The page's readiness (serving.announce_readiness) is a script queued after every element of the panels,
    so a page runs it once it has received them all (and again on a reconnect's replay), waiting for the tabs
    the panels built (TAB_TITLES, checked here against the tab group sent)."""
    import json

    from viser import _messages

    from coopsim.view.live.panels import TAB_TITLES
    from coopsim.view.live.serving import READY_ATTRIBUTE

    v = make(views, two_scaras(), start=False)
    items = sorted(v.server.gui._websock_interface.get_message_buffer().message_from_id.items())
    scripts = [(i, m.source) for i, m in items
               if isinstance(m, _messages.RunJavascriptMessage) and READY_ATTRIBUTE in m.source]
    assert len(scripts) == 1
    made = [i for i, m in items if type(m).__name__.startswith("Gui") and hasattr(m, "container_uuid")]
    assert len(made) > 40 and max(made) < scripts[0][0]           # every button, field, folder and tab before it
    groups = [m.props._tab_labels for _, m in items if isinstance(m, _messages.GuiTabGroupMessage)]
    assert groups == [TAB_TITLES] and json.dumps(list(TAB_TITLES)) in scripts[0][1]


@pytest.mark.slow
def test_the_page_says_it_is_ready_only_while_connected(browser, views):  # noqa: F811
    """<html data-coopsim-live>: 'ready' once the tabs are built and take clicks; 'connecting' again once the
    server is gone (viser freezes the panel), as a script or a test waiting on it needs."""
    from coopsim.view.live.panels import TAB_TITLES

    v = make(views, two_scaras(), speed=1.0)
    page = open_live(live_page(browser, 900, 560), v.url)
    try:
        live = page.evaluate("({state: window.coopsimLive.state, ready: window.coopsimLive.ready, "
                             "tabs: window.coopsimLive.tabs})")
        assert live == {"state": "ready", "ready": True, "tabs": list(TAB_TITLES)}
        page.get_by_role("tab", name="Data").click()
        page.get_by_text("Download CSV").first.wait_for()
        v.close()
        page.locator('html[data-coopsim-live="connecting"]').wait_for(state="attached")
        assert page.evaluate("window.coopsimLive.ready") is False
    finally:
        page.close()


@pytest.mark.slow
def test_the_page_shows_the_robots_and_the_bar_where_the_scene_puts_them(browser, views, tmp_path):  # noqa: F811
    from coopsim.tasks import scene as task_scene

    world = task_scene.world([task_scene.bar_pose()])
    r1, r2 = task_scene.scaras()
    sim = cs.Simulation(world=world)
    for r, q0 in ((r1, [0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03]), (r2, [0.2, -0.6, -0.6, 0.0, 0.0, 0.02])):
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), np.array(q0))
    v = make(views, sim, t_end=0.05, contact_lines=False)
    v.wait(timeout=WAIT)
    lp = LivePage(browser, v, keep=tmp_path)
    try:
        from PIL import Image

        bar = np.asarray(sim.body_state("bar").position)
        img = lp.shows(bar, is_red, "the bar red where it lies")
        Image.fromarray(img.astype(np.uint8)).save(tmp_path / "scene.png")
        P, _ = r1.shapes(sim.state(0)[0])
        links = [k for k, b in enumerate(r1.boxes) if b.name in ("link1", "link2")]
        assert any(colour_near(img, uv, is_orange) for uv in lp.project(P[links, :3, 3])), \
            "SCARA #1's arm in its colour where it is"
    finally:
        lp.close()


@pytest.mark.slow
def test_a_holding_robot_turns_green(browser, views, tmp_path):  # noqa: F811
    r, w = scene(BOX)
    sim = closing(r, w)
    v = make(views, sim, t_end=0.3, holding="any", contact_lines=False)
    v.wait(timeout=WAIT)
    assert sim.holding(0) == "box"
    lp = LivePage(browser, v, keep=tmp_path)
    try:
        from PIL import Image

        P, _ = r.shapes(sim.state(0)[0])
        arm = [k for k, b in enumerate(r.boxes) if b.name in ("link1", "link2")]
        lp.shows(P[arm[0], :3, 3], is_green, "link1 green")
        img = lp.shows(P[arm[1], :3, 3], is_green, "link2 green too")     # a shot the page has drawn whole
        Image.fromarray(img.astype(np.uint8)).save(tmp_path / "holding.png")
        assert not any(colour_near(img, uv, is_orange, radius=2) for uv in lp.project(P[arm, :3, 3]))
    finally:
        lp.close()


@pytest.mark.slow
def test_collision_boxes_turn_red_where_a_link_meets_scenery(browser, views, tmp_path):  # noqa: F811
    from PIL import Image

    r = cs.robots.scara1()
    q0 = np.array([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03])
    P, H = r.shapes(q0)
    k2 = [b.name for b in r.boxes].index("link2")
    a = int(np.argmax(H[k2]))                  # along the link
    post = np.eye(4)
    post[:3, 3] = P[k2, :3, 3] + P[k2, :3, a] * H[k2, a]
    post[2, 3] = 0.25
    w = cs.World()
    w.add_static_box("post", [0.015, 0.015, 0.25], post)
    sim = cs.Simulation(world=w, contact_forces=False)       # contacts reported, the robot not pushed
    sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), q0)
    v = make(views, sim, t_end=0.02, collision_boxes=True, contact_lines=True)
    v.wait(timeout=WAIT)
    hit = v.frame.colliding[0]
    assert hit[k2] and not hit[[b.name for b in r.boxes].index("link1")]
    assert len(v.frame.lines) > 0 and v._lines.visible
    lp = LivePage(browser, v, keep=tmp_path)
    try:
        P, _ = r.shapes(sim.state(0)[0])
        img = lp.shows(P[k2, :3, 3], is_red, "the link meeting the post red", radius=3)
        uv = lp.project(P[:, :3, 3])
        Image.fromarray(img.astype(np.uint8)).save(tmp_path / "collision.png")
        free = np.flatnonzero(~hit)                    # the base column, link1, ...: touching nothing
        assert any(colour_near(img, uv[k], is_green, radius=3) for k in free), "boxes touching nothing are green"
        # off: the robot's own colours again
        lp.tab("Display")
        lp.page.get_by_label("Collision boxes").uncheck()
        until(lambda: not v._show["collision_boxes"], "collision boxes off")
        lp.shows(P[k2, :3, 3], is_orange, "link2 orange again", radius=3)
    finally:
        lp.close()


@pytest.mark.slow
def test_the_pages_controls_reach_the_simulation(browser, views):  # noqa: F811
    sim = two_scaras(control_every=5)
    v = make(views, sim, speed=1.0)
    lp = LivePage(browser, v)
    try:
        page = lp.page
        lp.tab("Run")
        thumb = lp.slider("Speed (%)")
        thumb.focus()
        page.keyboard.press("End")
        until(lambda: v.pacer.speed == 4.0, "the slider at 400 %")
        page.keyboard.press("Home")
        until(lambda: v.pacer.speed == 0.0, "the slider at 0 %")
        t1 = sim.time
        page.keyboard.press("ArrowRight")
        until(lambda: v.pacer.speed == 0.01, "the slider at 1 %")
        until(lambda: sim.time > t1, "1 % moves the time")
        page.keyboard.press("End")
        until(lambda: v.pacer.speed == 4.0, "400 % again")
        lp.click("Pause")
        until(lambda: v.pacer.paused, "paused from the page")
        f1 = v.frames
        until(lambda: v.frames > f1 + 2, "frames drawn after the pause")       # the chunk under way is over
        t1, f1 = sim.time, v.frames
        until(lambda: v.frames > f1 + 10, "ten frames drawn while paused")
        assert sim.time == t1                                                  # and the time stood still
        s0 = sim.steps
        lp.click("One step")
        until(lambda: sim.steps != s0, "one step from the page")
        assert sim.steps - s0 == sim.control_every == 5
        lp.click("Resume")
        until(lambda: sim.time > t1 + 0.05, "resumed from the page")
        # a joint target typed in and sent: the robot's new reference; a bad one: a visible message
        lp.tab("Robots")
        field = lp.field("Joint target")
        field.fill("0.1, 0.2, 0.05, 0.3, 1.2, 0.02")
        page.get_by_role("button", name="Move to joint target").first.click()
        until(lambda: isinstance(v.call(lambda: sim.references[0]), cs.CubicTrajectory), "the typed target")
        assert np.array_equal(v.call(lambda: sim.references[0]).q_points[-1], [0.1, 0.2, 0.05, 0.3, 1.2, 0.02])
        for bad in ("zero, 1, 2", "nan, 0, 0, 0, 0, 0", "0, 0, 9, 0, 0, 0"):
            field.fill(bad)
            page.get_by_role("button", name="Move to joint target").first.click()
            page.get_by_text("Refused:").first.wait_for(timeout=WAIT * 1000)
            v._say("", "robots")
            page.get_by_text("Refused:").first.wait_for(state="detached", timeout=WAIT * 1000)
        # a joint slider moved in the page: a move to the slider's value
        slider = lp.slider("q1 (rad)")
        slider.focus()
        page.keyboard.press("Home")
        low = sim.robots[0].q_limits[0, 0]
        until(lambda: v.call(lambda: sim.references[0]).q_points[-1][0] == low, "q1 to its lower limit")
        assert v.error is None
    finally:
        lp.close()



def pid_scara(**kw):
    """A SCARA #1 under a PID (gains from its joint inertias at q0, bandwidth 40 rad/s) at a set point."""
    r = cs.robots.scara1()
    q0 = np.array([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03])
    J = np.maximum(np.diag(r.mass_matrix(q0)), 0.01)
    sim = cs.Simulation(**kw)
    sim.add_robot(r, cs.PID(J * 1600.0, J * 6400.0, J * 80.0, derivative_filter=1e-3), q0)
    return sim


def test_gains_set_from_the_view_replace_the_controller_and_bad_ones_are_refused(views):
    sim = two_scaras(control_every=5)
    sim.add_robot(cs.robots.scara1(base_position=(0.0, 0.8, 0.0)),
                  cs.PID(100.0, 0.0, 10.0, derivative_filter=2e-3, integral_limit=5.0),
                  np.array([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03]))
    v = make(views, sim, speed=1.0)
    until(lambda: sim.time > 0.02, "the run started")
    old = v.call(lambda: sim.controllers[0])
    v.set_gains(0, kp="900", kd=[60.0] * 6)
    until(lambda: v.call(lambda: sim.controllers[0]) is not old, "the new controller")
    c = v.call(lambda: sim.controllers[0])
    assert isinstance(c, cs.ComputedTorque) and c.model is None
    assert np.array_equal(c.kp, [900.0]) and np.array_equal(c.kd, np.full(6, 60.0))
    assert "900" in v._controller_md[0].content
    # a PID keeps its other settings; the gain not given stays
    v.set_gains(2, ki="7")
    until(lambda: np.array_equal(v.call(lambda: sim.controllers[2]).ki, [7.0]), "the PID's new ki")
    p = v.call(lambda: sim.controllers[2])
    assert np.array_equal(p.kp, [100.0]) and np.array_equal(p.kd, [10.0])
    assert p.derivative_filter == 2e-3 and np.array_equal(p.integral_limit, [5.0]) and p.gravity_compensation
    for i, gains, what in ((0, dict(kp="fast"), r"kp\[0\] of .* must be a number"),
                           (0, dict(kd="-1"), "kd must be >= 0"),
                           (0, dict(kp="1, 2"), "wrong size for kp: expected 1 or 6"),
                           (0, dict(ki="1"), "gain must be one of"),
                           (2, dict(kp=""), "kp of .* must be 1 or 6 numbers")):
        v.set_gains(i, **gains)
        until(lambda: v.message.startswith("Refused:"), f"{gains} refused")
        assert __import__("re").search(what, v.message), v.message
        v._say("")
    assert v.call(lambda: sim.controllers[0]) is c and v.call(lambda: sim.controllers[2]) is p
    t = sim.time
    until(lambda: sim.time > t + 0.02, "the run goes on")
    assert v.error is None


@pytest.mark.slow
def test_gains_typed_in_the_page_reach_the_simulation(browser, views):  # noqa: F811
    sim = pid_scara(control_every=5)
    v = make(views, sim, speed=1.0)
    lp = LivePage(browser, v)
    try:
        page = lp.page
        lp.tab("Robots")
        assert lp.field("kp").input_value() == v._gain_text(0, "kp")
        ki, kd = sim.controllers[0].ki, sim.controllers[0].kd
        lp.field("kp").fill("100, 200, 300, 400, 50, 60")
        page.get_by_role("button", name="Set gains").first.click()
        until(lambda: np.array_equal(v.call(lambda: sim.controllers[0]).kp, [100, 200, 300, 400, 50, 60]),
              "the typed kp")
        c = v.call(lambda: sim.controllers[0])
        assert isinstance(c, cs.PID) and np.array_equal(c.ki, ki) and np.array_equal(c.kd, kd)
        for bad in ("-5", "1, 2", "nan"):
            lp.field("kp").fill(bad)
            page.get_by_role("button", name="Set gains").first.click()
            page.get_by_text("Refused:").first.wait_for(timeout=WAIT * 1000)
            v._say("", "robots")
            page.get_by_text("Refused:").first.wait_for(state="detached", timeout=WAIT * 1000)
        assert v.call(lambda: sim.controllers[0]) is c
        t = sim.time
        until(lambda: sim.time > t + 0.02, "the run goes on")
        assert v.error is None
    finally:
        lp.close()



def test_dimensions_set_from_the_view_rebuild_the_robot_and_the_run_goes_on(views):
    sim = two_scaras(world=cs.World(), control_every=5)
    r0 = sim.robots[0]
    v = make(views, sim, speed=1.0)
    until(lambda: sim.time > 0.02, "the run started")
    v.set_dimensions(0, L1="0.35", L_base=0.45)
    until(lambda: v.call(lambda: sim.robots[0].dimensions["L1"]) == 0.35, "the rebuilt robot")
    got = v.call(lambda: sim.robots[0])
    want = cs.robots.scara1(L1=0.35, L_base=0.45)
    assert got.dimensions == want.dimensions and np.array_equal(got.dh, want.dh)
    np.testing.assert_allclose(got.masses, want.masses, rtol=1e-14)   # the maker's masses, scaled as it scales
    assert got.dimensions["L2"] == r0.dimensions["L2"] and v.robots[0].dimensions["L1"] == 0.35
    # the page draws the new boxes: their sizes on the mesh (float32 on the wire)
    half = v.call(lambda: np.concatenate([r.shapes(sim.state(i)[0])[1] for i, r in enumerate(sim.robots)]))
    np.testing.assert_allclose(v._robot_mesh.batched_scales, 2 * half, rtol=1e-6)
    # and the new parts: segment 1 stretched to the new L1, the housings as they were
    from coopsim.view.parts import robot_parts

    scales = {}
    for handle, index, *_ in v._part_meshes:
        for k, s in zip(index, handle.batched_scales):
            scales[k] = s
    names = [p.name for p in robot_parts(got)]
    np.testing.assert_allclose(scales[names.index("segment1")][0], 0.35, rtol=1e-6)
    np.testing.assert_allclose(scales[names.index("housing1")], robot_parts(r0)[names.index("housing1")].scale,
                               rtol=1e-6)
    assert "0.35" in v._dimensions_md[0].content
    for dims, what in ((dict(L1="long"), "L1 of .* must be a number"), (dict(L2="-0.1"), "L2 must be finite and > 0"),
                       (dict(L9="1"), "dimension must be one of")):
        v.set_dimensions(0, **dims)
        until(lambda: v.message.startswith("Refused:"), f"{dims} refused")
        assert __import__("re").search(what, v.message), v.message
        v._say("")
    t = sim.time
    until(lambda: sim.time > t + 0.02, "the run goes on")
    assert v.error is None and v.call(lambda: sim.robots[0].dimensions["L1"]) == 0.35


@pytest.mark.slow
def test_dimensions_typed_in_the_page_rebuild_the_robot(browser, views):  # noqa: F811
    sim = two_scaras(control_every=5)
    v = make(views, sim, speed=1.0)
    lp = LivePage(browser, v)
    try:
        page = lp.page
        lp.tab("Robots")
        assert float(lp.field("L2 (m)").input_value()) == sim.robots[0].dimensions["L2"]
        lp.field("L2 (m)").fill("0.3")
        page.get_by_role("button", name="Set dimensions").first.click()
        until(lambda: v.call(lambda: sim.robots[0].dimensions["L2"]) == 0.3, "the typed L2")
        assert np.array_equal(v.call(lambda: sim.robots[0]).dh, cs.robots.scara1(L2=0.3).dh)
        lp.field("L2 (m)").fill("0")
        page.get_by_role("button", name="Set dimensions").first.click()
        page.get_by_text("Refused:").first.wait_for(timeout=WAIT * 1000)
        t = sim.time
        until(lambda: sim.time > t + 0.02, "the run goes on")
        assert v.error is None and v.call(lambda: sim.robots[0].dimensions["L2"]) == 0.3
    finally:
        lp.close()


@pytest.mark.slow
def test_the_downloads_hold_the_logs_rows_and_columns(browser, views, tmp_path):  # noqa: F811
    from coopsim.log import SimulationLog

    sim = two_scaras(world=cs.World(), log_every=20)
    v = make(views, sim, t_end=0.3, speed=4.0)
    v.wait(timeout=WAIT)
    log = sim.log
    lp = LivePage(browser, v, keep=tmp_path)
    try:
        lp.tab("Data")
        lp.page.get_by_text("last 8 of").wait_for(timeout=WAIT * 1000)
        for button, ext in (("Download CSV", "csv"), ("Download Excel", "xlsx")):
            with lp.page.expect_download(timeout=WAIT * 1000) as d:
                lp.click(button)
            path = tmp_path / f"log.{ext}"
            d.value.save_as(path)
            got = SimulationLog.read_csv(path) if ext == "csv" else SimulationLog.read_excel(path)
            assert got.columns() == log.columns() and len(got.t) == len(log.t) == 76     # t = 0, 4 ms, ..., 0.3 s
            A, B = got.to_array(), log.to_array()
            if ext == "csv":
                np.testing.assert_array_equal(A, B)                  # every value, exactly (full precision)
            else:
                # an xlsx number can be one unit in the last place off; the errors e = q_ref - q (recomputed
                # from the read q_ref and q) then differ by a few units of q's last place
                cols = log.columns()
                e = np.array([".e" in c for c in cols])
                q = np.array([c.split(".")[-1].rstrip("0123456789") in ("q", "q_ref") for c in cols])
                np.testing.assert_allclose(A[:, ~e], B[:, ~e], rtol=1e-15, atol=0)
                np.testing.assert_allclose(A[:, e], B[:, e], rtol=0, atol=4e-16 * np.abs(B[:, q]).max())
    finally:
        lp.close()


@pytest.mark.slow
def test_two_pages_a_closed_page_and_a_reload_leave_the_run_intact(browser, views):  # noqa: F811
    sim = two_scaras()
    v = make(views, sim, speed=1.0)
    a, b = LivePage(browser, v), LivePage(browser, v)
    try:
        until(lambda: len(v.server.get_clients()) == 2, "two pages")
        a.close()
        t1, f1 = sim.time, v.frames
        until(lambda: sim.time > t1 + 0.1 and v.frames > f1 + 3, "the run goes on after a page closed")
        b.reload()                                       # connected again, its tabs built again
        t2 = sim.time
        until(lambda: sim.time > t2 + 0.1, "the run goes on after a reload")
        assert v.error is None and v._thread.is_alive()
    finally:
        b.close()


@pytest.mark.slow
def test_the_task_runs_in_the_live_page_with_the_headless_result(views):
    """The cooperative task sequenced phase by phase through a live view (paced, here at 400 %): the same
    report, bit for bit, as the headless run (pacing changes when the steps run, not what they compute)."""
    from coopsim.tasks import handover

    headless = handover.run(cycles=1, score=False)
    res = handover.run(cycles=1, score=False, live=dict(speed=4.0, quiet=True))
    views.append(res.live)
    assert res.success and res.report == headless.report
    assert res.live.frames > 10 and res.live.error is None
    assert res.live.run_state == "finished" and "1 of 1 cycles succeeded" in res.live.outcome


@pytest.mark.slow
def test_the_tasks_command_line_runs_it_live(tmp_path):
    import json
    import subprocess
    import sys

    # --speed: at once at 400 % (without it the page waits at t = 0 for its Start)
    res = subprocess.run([sys.executable, "-m", "coopsim.tasks.handover", "--live", "--speed", "4", "--cycles", "1",
                          "--no-video", "--hold", "0", "--out", str(tmp_path)], capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "coopsim live view: http://127.0.0.1:" in res.stdout
    with open(tmp_path / "report.json", encoding="utf-8") as f:
        assert json.load(f)["success"] is True


def test_a_lab_notebook_puts_the_live_page_in_a_cell():
    """Lab 02 runs its PID plan in the live page shown in a cell (the notebook itself is executed by
    tests/test_notebooks_and_examples.py)."""
    import json
    from pathlib import Path

    nb = json.loads((Path(__file__).resolve().parents[1] / "notebooks" / "02_planning_and_control.ipynb").read_text())
    code = ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]
    assert any("cs.view.live(" in c and ".show(" in c and ".run_to(" in c for c in code)


# ---- the main job as a session ----

def _cli(tmp_path, *args):
    """The main job's command line with --live in a process of its own; (process, the page's URL)."""
    import os
    import subprocess
    import sys

    import signal

    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # Ctrl-C (SIGINT) must reach it even where the tests run with SIGINT ignored (a background job), which a child
    # would inherit: while it starts, SIGINT is handled here, so the child gets its default
    ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    if ignored:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen([sys.executable, "-m", "coopsim.tasks.handover", "--live", "--cycles", "1",
                                 "--no-video", "--out", str(tmp_path), *args], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, env=env)
    finally:
        if ignored:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    lines = []
    end = time.monotonic() + WAIT
    while time.monotonic() < end:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if "coopsim live view: http://" in line:
            return proc, line.split("coopsim live view: ")[1].split()[0], lines
    proc.kill()
    pytest.fail("the command line printed no URL: " + "".join(lines))


def _finish(proc, lines, sig=None, timeout=WAIT):
    import signal
    import subprocess

    if sig is not None:
        proc.send_signal(signal.SIGINT)
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()                  # no process or pipe left to the next tests
        out, _ = proc.communicate()
        pytest.fail(f"the command line did not end in {timeout} s" + (" after Ctrl-C" if sig else "") + ": "
                    + "".join(lines) + out)
    return proc.returncode, "".join(lines) + out


class _Url:
    """What LivePage needs of a view served by another process: its URL (the page's state read in the page)."""

    def __init__(self, url):
        self.url = url


def _text_in_page(page, text):
    page.get_by_text(text).first.wait_for(timeout=WAIT * 1000)


def _run_table(page):
    """The Run panel's table as the page shows it now: {row's name: its number} (units dropped)."""
    rows = page.locator("table", has_text="Simulated time").first.locator("tr").all_inner_texts()
    out = {}
    for row in rows:
        name, _, value = row.partition("\t")
        try:
            out[name.strip()] = float(value.split()[0])
        except (IndexError, ValueError):
            pass
    return out


@pytest.mark.slow
def test_the_main_job_waits_for_start_then_serves_downloads_and_reset_after_the_run(browser, tmp_path):  # noqa: F811
    """`--live`: paused at t = 0 until Start; after the run the page states it finished, shows the summary,
    sends the log and runs the task again on Reset; Ctrl-C closes it with no traceback."""
    proc, url, lines = _cli(tmp_path, "--hold", "600")
    try:
        page = open_live(live_page(browser, 900, 700), url)
        _text_in_page(page, "waiting")
        # still waiting, at t = 0 (no Start yet), after a second of the run's wall time (the page's own table)
        until(lambda: _run_table(page).get("Wall time (this run)", 0.0) >= 1.0, "a second of waiting shown")
        assert _run_table(page)["Simulated time"] == 0.0
        thumb = page.locator('label:visible', has_text="Speed (%)").first
        slider = page.locator(f'[id="{thumb.get_attribute("for")}"] [role="slider"]')
        slider.focus()
        page.keyboard.press("End")           # 400 %
        page_ready(page)
        page.get_by_role("button", name="Start", exact=True).click()
        _text_in_page(page, "1 of 1 cycles succeeded")
        _text_in_page(page, "finished")
        _text_in_page(page, "the page stays until Ctrl-C")      # the outputs written, the page served
        page_ready(page)
        page.get_by_role("tab", name="Data").click()
        with page.expect_download(timeout=WAIT * 1000) as d:
            page.get_by_role("button", name="Download CSV", exact=True).click()
        path = tmp_path / "page.csv"
        d.value.save_as(path)
        got = cs.SimulationLog.read_csv(path)
        assert got.t[-1] > 10.0              # the whole run (about 16 s simulated)
        # Reset after the run: the task again, in the page, from t = 0
        page_ready(page)
        page.get_by_role("tab", name="Run").click()
        page.get_by_role("button", name="Reset to start", exact=True).click()
        _text_in_page(page, "running")
        page.close()
    finally:
        rc, out = _finish(proc, lines, sig=True)
    assert rc == 0, out                      # the run succeeded; Ctrl-C only closed the page
    assert "Traceback" not in out
    import json

    with open(tmp_path / "report.json", encoding="utf-8") as f:
        assert json.load(f)["success"] is True


@pytest.mark.slow
def test_ctrl_c_during_the_main_jobs_run_writes_the_log_and_an_interrupted_report(browser, tmp_path):  # noqa: F811
    import json

    # at 1 % the task's 16 s simulated take over 1600 s: Ctrl-C comes during the run however loaded the machine
    proc, url, lines = _cli(tmp_path, "--speed", "0.01", "--hold", "0")
    try:
        lp = LivePage(browser, _Url(url))
        until(lambda: _run_table(lp.page).get("Simulated time", 0.0) > 0.0, "the run under way (the page's time)")
        lp.close()
    finally:
        rc, out = _finish(proc, lines, sig=True)
    assert rc == 130, out
    assert "Traceback" not in out
    said = [line for line in out.splitlines() if line.startswith("interrupted")]
    assert len(said) == 1 and "report.json" in said[0] and "task.csv" in said[0]
    with open(tmp_path / "report.json", encoding="utf-8") as f:
        rep = json.load(f)
    assert rep["interrupted"] is True and rep["success"] is False
    assert rep["cycles"][-1]["reason"] == "interrupted (Ctrl-C)"
    log = cs.SimulationLog.read_csv(tmp_path / "task.csv")      # the log up to where it stopped
    assert len(log.t) >= 1 and 0 <= log.t[-1] <= rep["simulated_time"] + 1e-9 < 16.0


@pytest.mark.slow
def test_a_failed_cycle_shows_its_step_time_and_reason_in_the_page(browser, views):  # noqa: F811
    from coopsim.tasks import handover

    res = handover.run(cycles=1, score=False, container_shift=(0.1, 0.0, 0.05), live=dict(speed=4.0, quiet=True))
    v = res.live
    views.append(v)
    c = res.report["cycles"][0]
    assert not res.success and v.run_state == "failed"
    import threading

    serving = threading.Thread(target=v.serve, kwargs=dict(seconds=WAIT), daemon=True)
    serving.start()
    lp = LivePage(browser, v)
    try:
        _text_in_page(lp.page, f"FAILED in {c['failed_step']} at t = {c['failed_at']:.3f} s: {c['reason']}")
        _text_in_page(lp.page, "failed")
        assert "(running)" not in lp.page.content()
    finally:
        lp.close()
        v.close()
        serving.join(timeout=WAIT)


def test_a_sequenced_runs_reset_restarts_its_driver_and_serve_runs_it_again(views):
    """run_to(restart=True) raises Restart on the page's Reset (the simulation back at t = 0); after the run,
    serve() calls the view's rerun on Reset."""
    from coopsim.view.live import Restart

    sim = two_scaras()
    v = make(views, sim, start=False, speed=4.0)
    v.run_to(0.05, restart=True)
    v.reset()
    with pytest.raises(Restart):
        v.run_to(0.2, restart=True)
    assert sim.time == 0.0
    ran = []

    def again():
        ran.append(sim.time)
        v.run_to(0.02)
        v.close()                 # ends serve()
    v.rerun = again
    v.finish("done", ok=True)
    assert v.run_state == "finished" and v.outcome == "done"
    v.reset()
    assert v.serve(WAIT) == "closed"
    assert ran == [0.0] and sim.time >= 0.02 - 1e-12


# ---- long runs and downloads ----

def _counting(monkeypatch, cls, name):
    """Counts the calls of cls.name (a method) from now on; returns the list of calls."""
    calls = []
    real = getattr(cls, name)

    def counted(self, *a, **kw):
        calls.append(name)
        return real(self, *a, **kw)
    monkeypatch.setattr(cls, name, counted)
    return calls


def test_the_table_shows_the_newest_rows_reading_only_them(views, monkeypatch):
    """As the run goes on, the Data table shows the last 8 rows of the chosen robot's log; its update reads
    those rows alone (a count that a long log cannot change) and never builds the whole log
    (Simulation.log / log_snapshot, which copy every logged contact point)."""
    sim = two_scaras(world=cs.World(), log_every=20, log_contacts=True)
    sim.run(1.0, progress=False)                  # a log already there: 251 rows
    built = _counting(monkeypatch, cs.Simulation, "log_snapshot")
    v = make(views, sim, speed=4.0)
    counts, reads = set(), []

    def progressed():
        text = v._table.content
        reads.append(v.table_rows_read)
        if " rows (" in text:
            counts.add(int(text.split(" of ")[1].split(" rows")[0]))
        return len(counts) >= 3
    until(progressed, "the table updated three times as the run went on")
    v.pause()
    until(lambda: v.pacer.paused, "paused")
    rows = v.call(lambda: sim.log_rows)
    until(lambda: f"of {rows} rows" in v._table.content, "the table at the paused run's last row")
    assert built == []                            # the table never built the whole log
    assert max(reads) == 8 and rows > 251 + 8
    v._pick_table(1)                              # the second robot's rows
    until(lambda: v._table.content.startswith(v.labels[1]), "the table of the second robot")
    log = v.call(lambda: sim.log)
    text = v._table.content
    assert f"last 8 of {rows} rows ({len(log.columns())} columns)" in text
    lines = text.splitlines()[-8:]
    for line, t, q in zip(lines, log.t[-8:], log[1].q[-8:]):
        assert line == f"| {t:.4f} | " + " | ".join(f"{x:.3f}" for x in q) + " |"
    assert v.error is None


def test_a_download_asked_while_one_is_prepared_says_so_and_the_first_is_sent(views, monkeypatch):
    """The log's file is written off the simulation's thread with its progress in the Data panel's line
    ('preparing CSV… 0 %' ... 'sent: N rows, X MB'); a second request meanwhile is refused with a line
    saying so; the log is taken without its contact points (the tables do not hold them)."""
    sim = two_scaras(world=cs.World(), log_every=1, log_contacts=True)
    sim.run(0.5, progress=False)
    taken = []
    real = cs.Simulation.log_snapshot
    monkeypatch.setattr(cs.Simulation, "log_snapshot",
                        lambda self, **kw: taken.append(kw) or real(self, **kw))
    v = make(views, sim, start=False)
    v.download("csv")
    v.download("xlsx")
    assert "one download at a time" in v.download_text
    until(lambda: v.download_state in ("sent", "failed"), "the CSV sent")
    rows = sim.log_rows
    assert v.download_state == "sent" and v.download_text.startswith(f"sent: {rows} rows, ")
    assert taken == [{"contact_points": False}]   # one log taken, for the CSV alone
    assert any(line.startswith("preparing CSV… 0 %") for line in v.download_lines)
    assert not any("Excel…" in line for line in v.download_lines)
    v.download("xlsx")                            # now one may ask again
    until(lambda: v.download_state in ("sent", "failed") and "Excel" in v.download_text, "the Excel sent")
    assert v.download_text.startswith(f"sent: {rows} rows, ")
    with pytest.raises(ValueError, match="kind must be 'csv' or 'xlsx'"):
        v.download("pdf")


@pytest.mark.slow
def test_a_20_mb_log_arrives_complete_with_its_progress_shown(browser, views, tmp_path):  # noqa: F811
    """A log of about 20 MB (a run at full speed, every step logged) downloads from the page as CSV and as
    Excel, every row and column read back; the Data panel's line shows 'preparing CSV… N %' while the file
    is written (the writer waits at its first percent until the page has shown it), then 'sent: N rows'."""
    import re
    import threading

    from coopsim.log import SimulationLog

    sim = two_scaras(world=cs.World(), log_every=1)
    sim.run(2.5, progress=False)                  # 12501 rows x 109 columns: about 20 MB of CSV
    v = make(views, sim, t_end=sim.time)          # the run over, the page served
    log = sim.log
    shown = threading.Event()
    real_show = v._show_download

    def show(state, text):
        real_show(state, text)
        if re.fullmatch(r"preparing CSV… \d+ %", text) and not shown.is_set():
            shown.wait(WAIT)                      # the writer waits until the page has shown its progress
    v._show_download = show
    lp = LivePage(browser, v, keep=tmp_path)
    try:
        lp.tab("Data")
        lp.page.get_by_text(f"last 8 of {len(log.t)} rows").wait_for(timeout=WAIT * 1000)
        with lp.page.expect_download(timeout=WAIT * 1000) as d:
            lp.click("Download CSV")
            lp.page.get_by_text(re.compile(r"preparing CSV… \d+ %")).wait_for(timeout=WAIT * 1000)
            lp.page.screenshot(path=str(tmp_path / "progress.png"))
            shown.set()
        path = tmp_path / "log.csv"
        d.value.save_as(path)
        lp.page.get_by_text(f"sent: {len(log.t)} rows").wait_for(timeout=WAIT * 1000)
        lp.page.screenshot(path=str(tmp_path / "sent.png"))
        assert path.stat().st_size > 18e6
        got = SimulationLog.read_csv(path)
        assert got.columns() == log.columns() and len(got.t) == len(log.t) == 12501
        np.testing.assert_array_equal(got.to_array(), log.to_array())
        with lp.page.expect_download(timeout=WAIT * 1000) as d:
            lp.click("Download Excel")
        path = tmp_path / "log.xlsx"
        d.value.save_as(path)
        until(lambda: v.download_state == "sent" and "Excel" in v.download_text, "the Excel's line")
        got = SimulationLog.read_excel(path)
        assert got.columns() == log.columns() and len(got.t) == len(log.t)
        np.testing.assert_array_equal(got.to_array(), log.to_array())    # %.17g: every value exactly
        assert v.error is None
    finally:
        lp.close()


# ---- panels ----

class Together(cs.CooperativeController):
    """A cooperative law written in Python: each member on a joint PD to its reference."""

    def __init__(self):
        super().__init__()

    def compute(self, t, members):
        return [400.0 * (m.q_ref - m.q) + 40.0 * (m.qd_ref - m.qd) for m in members]


def coop_scaras(**kw):
    """Two SCARAs and a cooperative law for both (their own PIDs to stand aside under it)."""
    sim = two_scaras(**kw)
    for i in range(2):
        sim.set_controller(i, cs.PID(100.0, 0.0, 10.0))
    return sim, Together()


def impedance_scara(world=None, **kw):
    r = cs.robots.scara1()
    sim = cs.Simulation(world=world, **kw)
    sim.add_robot(r, cs.Impedance(400.0, 40.0, 1.0, force_feedback=False),
                  np.array([0.3, 0.6, 0.1, 0.0, np.pi / 2, 0.03]))
    return sim


def test_the_robots_panel_names_the_cooperative_law_driving_and_gains_say_when_they_act(views):
    sim, law = coop_scaras(control_every=5)
    v = make(views, sim, speed=1.0)
    until(lambda: sim.time > 0.02, "the run started")
    assert "PID" in v._controller_md[0].content and "cooperative" not in v._controller_md[0].content
    group = v.call(lambda: sim.add_cooperative(law, [0, 1]))
    for i in range(2):
        until(lambda: "cooperative group" in v._controller_md[i].content, f"robot {i} named under the group")
        text = v._controller_md[i].content
        assert f"group {group}" in text and "Together (written in Python, a cooperative law" in text
        assert "stands aside" in text
    v.set_gains(0, kp="500")
    until(lambda: np.array_equal(v.call(lambda: sim.controllers[0]).kp, [500.0]), "the stand-aside PID's kp")
    until(lambda: "acts when cooperative group" in v._msgs["robots"].content, "the message saying when")
    v.call(lambda: sim.remove_cooperative(group))
    until(lambda: "cooperative" not in v._controller_md[0].content, "the PID named again")
    assert "PID" in v._controller_md[0].content and "500" in v._controller_md[0].content
    assert v.error is None


def test_a_task_space_laws_stiffness_set_from_the_view_builds_the_same_law_with_it(views):
    sim = impedance_scara(control_every=5)
    v = make(views, sim, speed=1.0)
    until(lambda: sim.time > 0.02, "the run started")
    text = v._controller_md[0].content
    assert "Impedance" in text and "Python" not in text and "N/m" in text
    assert set(v._gain_fields[0]) == {"stiffness", "damping", "mass"}
    old = v.call(lambda: sim.controllers[0])
    v.set_gains(0, stiffness="900, 900, 800, 50, 60")
    until(lambda: v.call(lambda: sim.controllers[0]) is not old, "the new law")
    c = v.call(lambda: sim.controllers[0])
    assert isinstance(c, cs.Impedance) and np.array_equal(c.stiffness, [900, 900, 800, 50, 60])
    assert np.array_equal(c.damping, old.damping) and np.array_equal(c.mass, old.mass)
    assert c.force_feedback is False and c.directions == old.directions and c.jaw_kp == old.jaw_kp
    until(lambda: "800" in v._controller_md[0].content, "the line shows the new stiffness")
    assert v._gain_fields[0]["stiffness"].value == v._gain_text(0, "stiffness")
    # refused: a negative damping, a wrong count; the message replaced by a later success
    for gains in (dict(damping="-1"), dict(mass="1, 2")):
        v.set_gains(0, **gains)
        until(lambda: v._msgs["robots"].content.startswith("**Refused"), f"{gains} refused")
    assert v.call(lambda: sim.controllers[0]) is c
    v.set_gains(0, mass="2")
    until(lambda: np.array_equal(v.call(lambda: sim.controllers[0]).mass, [2.0]), "the new mass")
    until(lambda: "Refused" not in v._msgs["robots"].content and "mass" in v._msgs["robots"].content,
          "the refusal replaced by the success")
    assert v.error is None


def test_each_panel_has_its_message_line_and_speeds_are_refused_in_percent(views):
    sim = two_scaras(control_every=5)
    v = make(views, sim, speed=1.0)
    until(lambda: sim.time > 0.02, "the run started")
    v.set_speed_percent(500)
    assert v._msgs["run"].content == "**Refused: speed must be 0 .. 400 %, got 500 %**"
    v.set_speed_percent("fast")
    assert "Refused" in v._msgs["run"].content and "speed (%)" in v._msgs["run"].content
    v.teach_joints(0, "1, 2")                        # a refusal in the Robots panel leaves the Run panel's
    assert "Refused" in v._msgs["robots"].content and "speed" in v._msgs["run"].content
    v.set_speed_percent(250)
    until(lambda: v._msgs["run"].content == "**Speed 250 %**", "the success replaces the refusal")
    assert v.pacer.speed == 2.5 and v._speed.value == 250
    assert "Refused" in v._msgs["robots"].content
    v.teach_joints(0, [0.1, 0.2, 0.05, 0.3, 1.2, 0.02])
    until(lambda: "moving to" in v._msgs["robots"].content, "the teach move replaces the refusal")
    with pytest.raises(ValueError, match="panel must be one of"):
        v._say("x", "nowhere")


def test_the_state_line_says_finished_paused_and_why_nothing_moves_without_nan(views):
    sim = two_scaras()
    v = make(views, sim, t_end=0.1, speed=4.0)
    v.wait(timeout=WAIT)
    until(lambda: "finished" in v._state_md.content, "finished stated")
    assert "running" not in v._state_md.content and v.run_state == "finished"
    v._resume_pressed()
    assert "finished" in v._msgs["run"].content
    v.close()
    sim2 = two_scaras(control_every=5)
    v2 = make(views, sim2, speed=1.0)
    until(lambda: sim2.time > 0.02 and "running at 100 %" in v2._state_md.content, "running stated")
    v2._pause_pressed()
    until(lambda: "paused" in v2._state_md.content, "paused stated")
    until(lambda: "– / – µs" in v2._time.content,
          "no step time while nothing steps")
    assert "nan" not in (v2._time.content + v2._state_md.content).lower()
    assert v2.stats["step_mean"] is None and v2.stats["state"] == "paused"
    v2.set_speed_percent(0)
    until(lambda: v2.pacer.speed == 0.0, "speed 0")
    v2._resume_pressed()
    assert "speed is 0 %" in v2._msgs["run"].content and "nothing moves" in v2._msgs["run"].content
    until(lambda: "speed 0 %" in v2._state_md.content, "paused at speed 0 stated")
    v2.set_speed_percent(100)
    until(lambda: "running at 100 %" in v2._state_md.content, "running again")
    assert v2._outcome_md.content == ""


def test_plots_of_the_sensed_wrench_task_error_and_cooperation_only_when_the_run_has_them(views):
    v = make(views, two_scaras(), speed=4.0, t_end=0.05)
    v.wait(timeout=WAIT)
    assert set(v._plot_made) == {"q", "e"}
    v.close()
    sim = impedance_scara(world=cs.World())
    v = make(views, sim, speed=4.0)
    until(lambda: sim.time > 0.05 and v._plot_made["force"].data[0].size > 2, "the wrench plotted")
    assert set(v._plot_made) == {"q", "e", "force", "moment", "task"}
    t, fx, fy, fz = v._plot_made["force"].data
    assert len(t) == len(fx) and np.all(np.isfinite(fz))
    v.close()
    sim, law = coop_scaras()
    v = make(views, sim, speed=4.0)
    until(lambda: sim.time > 0.02, "the run started")
    v.call(lambda: sim.add_cooperative(law, [0, 1]))
    until(lambda: "share" in v._plot_made and v._plot_made["share"].data[0].size > 1, "the cooperation plotted")
    assert {"squeeze", "share", "force"} <= set(v._plot_made)


def test_the_teach_controls_follow_the_target_and_the_reference(views):
    sim = two_scaras()
    v = make(views, sim, speed=1.0, move_time=0.3)
    until(lambda: sim.time > 0.02, "the run started")
    target = np.array([0.1, -0.4, 0.05, 0.3, 1.0, 0.02])
    v.teach_joints(1, target)
    sliders, field = v._teach[1]
    until(lambda: np.allclose([s.value for s in sliders], target), "the sliders at the typed target")
    until(lambda: field.value == ", ".join(f"{x:.4g}" for x in target), "the joint target field at the target")
    v._toggle_gizmo(1, True)
    until(lambda: np.allclose(v.gizmo_pose(1), sim.robots[1].fk(target), atol=1e-6), "the gizmo at the target")
    # a reference set from Python: the controls follow what the robot tracks
    other = np.array([0.2, -0.3, -0.1, 0.0, 0.5, 0.01])
    v.call(lambda: sim.set_reference(1, other))
    until(lambda: np.allclose([s.value for s in sliders], other), "the sliders follow the new reference")
    until(lambda: np.allclose(v.gizmo_pose(1), sim.robots[1].fk(other), atol=1e-6), "the gizmo follows it")
    # a user touching the controls is not fought: they are left as they are for a while
    v._touch(0)
    before = [s.value for s in v._teach[0][0]]
    v.call(lambda: sim.set_reference(0, np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])))
    time.sleep(0.3)
    assert [s.value for s in v._teach[0][0]] == before
    assert v.error is None


@pytest.mark.slow
def test_the_page_names_a_cooperative_law_and_states_finished_without_nan(browser, views, tmp_path):  # noqa: F811
    sim, law = coop_scaras()
    sim.add_cooperative(law, [0, 1])
    v = make(views, sim, t_end=0.2, speed=4.0)
    lp = LivePage(browser, v, width=1200, height=900)
    try:
        page = lp.page
        v.wait(timeout=WAIT)
        lp.tab("Run")
        page.get_by_text("State: finished").wait_for(timeout=WAIT * 1000)
        assert "nan" not in page.locator("body").inner_text().lower()
        v.set_speed_percent(500)
        page.get_by_text("got 500 %").wait_for(timeout=WAIT * 1000)
        lp.tab("Robots")
        page.get_by_text("Driven by").first.wait_for(timeout=WAIT * 1000)
        body = page.locator("body").inner_text()
        assert "cooperative group 0: Together" in body and "stands aside" in body
        page.screenshot(path=str(tmp_path / "robots_coop.png"))
        lp.tab("Plots")
        page.get_by_text("squeeze (N)").first.wait_for(timeout=WAIT * 1000)
        page.screenshot(path=str(tmp_path / "plots_coop.png"))
    finally:
        lp.close()


# ---- notebook, remote and rough edges ----

def test_show_puts_the_page_in_a_cell_once_and_a_closed_view_says_so(views, monkeypatch):
    import IPython.display

    import coopsim.view.live.session  # noqa: F401  (the module, for its notebook check)
    live_module = __import__("sys").modules["coopsim.view.live.session"]
    shown = []
    monkeypatch.setattr(live_module, "_in_notebook", lambda: True)
    monkeypatch.setattr(IPython.display, "display", shown.append)
    v = make(views, two_scaras(), start=False)
    assert v.show(height=480) is None            # a cell's last line: nothing more to display
    assert len(shown) == 1 and isinstance(shown[0], IPython.display.HTML)
    frame = shown[0].data
    assert f'<iframe src="{v.url}"' in frame and 'height="480"' in frame and "url_prefix" in frame
    assert f'<iframe src="{v.url}"' in v._repr_html_()   # the view as a cell's last value: the page once
    with pytest.raises(ValueError, match="height"):
        v.show(height=0)
    v.close()
    for call, what in ((v.show, "show"), (lambda: v.run_to(1.0), "run_to")):
        with pytest.raises(RuntimeError, match=rf"^this live view is closed: {what}\(\)"):
            call()
    assert len(shown) == 1 and "closed" in v._repr_html_() and "iframe" not in v._repr_html_()


def test_quiet_prints_nothing_and_the_url_is_printed_once(views, capfd):
    v = make(views, two_scaras(), start=False, quiet=True)
    v.run_to(0.02)
    v.close()
    out, err = capfd.readouterr()              # the process's own stdout and stderr, every thread's
    assert out == "" and err == "", (out, err)
    v = make(views, two_scaras(), start=False, quiet=False)
    v.close()
    out, err = capfd.readouterr()
    assert out == f"coopsim live view: {v.url}\n" and err == "", (out, err)   # viser's banner not among them


def test_a_busy_port_is_refused_and_a_host_beyond_loopback_warns(views):
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(ValueError, match=rf"^port {port} is in use on 127.0.0.1 .*port=0"):
            make(views, two_scaras(), start=False, port=port)
    with pytest.warns(UserWarning, match=r"^host='0.0.0.0': the live page has no authentication") as w:
        v = make(views, two_scaras(), start=False, host="0.0.0.0")
    assert len(w) == 1 and w[0].filename == __file__        # pointed at the caller's line
    assert v.server_url == f"http://127.0.0.1:{v.port}"
    v.close()
    from coopsim.view.live.serving import is_loopback

    assert all(map(is_loopback, ("127.0.0.1", "127.0.1.1", "localhost", "::1", "[::1]")))
    assert not any(map(is_loopback, ("0.0.0.0", "::", "", "192.168.1.20", "example.org")))


def test_the_url_prefix_from_the_argument_or_the_environment(views, monkeypatch):
    from coopsim.view.live.serving import ENV_PREFIX, url_prefix

    monkeypatch.delenv(ENV_PREFIX, raising=False)
    monkeypatch.delenv("JUPYTERHUB_SERVICE_PREFIX", raising=False)
    v = make(views, two_scaras(), start=False, url_prefix="/proxy/{port}/")
    assert v.url == f"/proxy/{v.port}/" and v.server_url == f"http://127.0.0.1:{v.port}"
    assert v.server.get_host() == "127.0.0.1"       # the server stays on loopback: the proxy reaches it there
    v.close()
    monkeypatch.setenv(ENV_PREFIX, "https://hub.example.org/user/me/proxy/{port}")
    v = make(views, two_scaras(), start=False)
    assert v.url == f"https://hub.example.org/user/me/proxy/{v.port}/"
    v.close()
    assert url_prefix("") == ""                     # given: the server's own address, whatever the environment
    monkeypatch.delenv(ENV_PREFIX)
    assert url_prefix(None) == ""
    monkeypatch.setenv("JUPYTERHUB_SERVICE_PREFIX", "/user/me/")
    assert url_prefix("jupyter") == "/user/me/proxy/{port}/"
    for bad, match in (("proxy/{port}", "url_prefix must be a path"), ("/p/{host}/", r"only \{port\}"),
                       ("/p/?a=1", "plain path"), (3, "url_prefix must be a text")):
        with pytest.raises(ValueError, match=match):
            view.live(two_scaras(), start=False, quiet=True, url_prefix=bad)
    monkeypatch.setenv(ENV_PREFIX, "ftp://x/")
    with pytest.raises(ValueError, match=ENV_PREFIX):
        view.live(two_scaras(), start=False, quiet=True)


def test_a_scaras_dimensions_are_bounded_by_its_model():
    for make_robot, defaults, bounds in ((cs.robots.scara1, cs.robots.SCARA1_DEFAULTS, cs.robots.SCARA1_BOUNDS),
                                         (cs.robots.scara2, cs.robots.SCARA2_DEFAULTS, cs.robots.SCARA2_BOUNDS)):
        assert set(bounds) == set(defaults)
        for key, b in bounds.items():
            assert 0 < b.low <= defaults[key] <= b.high and b.why
            for v in (b.low, b.high):
                assert make_robot(**{key: v}).dimensions[key] == v          # both ends included
            for v in (b.low * 0.99, b.high * 1.01):
                with pytest.raises(ValueError, match=rf"^{key} of {make_robot.__name__} must be {b.low:g} \.\. "
                                                     rf"{b.high:g} m \("):
                    make_robot(**{key: v})
    with pytest.raises(ValueError, match=r"^L1 of scara1 must be 0.08 \.\. 0.6 m .*got 100$"):
        cs.robots.scara1(L1=100)


def test_a_rebuild_beyond_the_bounds_is_refused_and_the_floor_and_camera_follow_an_accepted_one(views):
    sim = two_scaras(world=cs.World(), control_every=5)
    v = make(views, sim, start=False)
    radius, floor = v._radius, v._floor_size
    distance = np.linalg.norm(np.asarray(v.server.initial_camera.position) - v._centre)
    v.set_dimensions(0, L1=100)
    assert v.message.startswith("Refused: L1 of scara1 must be 0.08 .. 0.6 m"), v.message
    v.run_to(0.01)              # the page's requests are applied between chunks
    assert sim.robots[0].dimensions["L1"] == cs.robots.SCARA1_DEFAULTS["L1"]
    v.set_dimensions(0, L1=0.6, L2=0.6)
    v.run_to(0.02)
    assert sim.robots[0].dimensions["L1"] == 0.6
    # the frame of the new scene: every box of the robots over the floor, the camera farther off
    pts = np.concatenate([box_points(*r.shapes(sim.state(i)[0])) for i, r in enumerate(sim.robots)])
    assert v._floor_size > floor and v._radius > radius
    lo, hi = v._centre[:2] - v._floor_size / 2, v._centre[:2] + v._floor_size / 2
    assert np.all(pts[:, :2] >= lo) and np.all(pts[:, :2] <= hi)
    assert np.linalg.norm(np.asarray(v.server.initial_camera.position) - v._centre) > distance


def box_points(poses, half):
    from coopsim.view.geometry import box_corners

    return box_corners(poses, half).reshape(-1, 3)


class PrefixProxy:
    """A reverse proxy on 127.0.0.1 as jupyter-server-proxy serves one: /proxy/<port>/<path> to
    http://127.0.0.1:<port>/<path>, the page's HTTP requests and its websocket (with its subprotocol); in a
    thread of its own, stopped by close()."""

    def __init__(self):
        import asyncio
        import threading

        self.requests = []
        self._ready = threading.Event()
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        assert self._ready.wait(WAIT), "the proxy started"

    def _target(self, path):
        import re

        m = re.match(r"^/proxy/(\d+)(/.*)?$", path.partition("?")[0])
        return (int(m.group(1)), m.group(2) or "/") if m else (None, None)

    def _http(self, connection, request):
        import urllib.request

        from websockets.datastructures import Headers
        from websockets.http11 import Response

        self.requests.append(request.path)
        if request.headers.get("Upgrade", "").lower() == "websocket":
            return None
        port, rest = self._target(request.path)
        if port is None:
            return Response(404, "Not Found", Headers(), b"")
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{rest}", timeout=WAIT) as r:
            body = r.read()
            return Response(r.status, "OK", Headers({"Content-Type": r.headers.get("Content-Type", ""),
                                                     "Content-Length": str(len(body))}), body)

    async def _ws(self, connection):
        import asyncio

        from websockets.asyncio.client import connect

        port, rest = self._target(connection.request.path)
        sub = [connection.subprotocol] if connection.subprotocol else None
        async with connect(f"ws://127.0.0.1:{port}{rest}", subprotocols=sub, max_size=None,
                           compression=None) as back:
            async def pump(a, b):
                async for m in a:
                    await b.send(m)
            tasks = [asyncio.ensure_future(pump(connection, back)), asyncio.ensure_future(pump(back, connection))]
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
            for t in tasks:
                t.cancel()

    def _run(self):
        import asyncio

        from websockets.asyncio.server import serve

        asyncio.set_event_loop(self._loop)

        async def main():
            self._stop = asyncio.Event()
            async with serve(self._ws, "127.0.0.1", 0, process_request=self._http, max_size=None, compression=None,
                             select_subprotocol=lambda c, offered: offered[0] if offered else None) as server:
                self.port = server.sockets[0].getsockname()[1]
                self._ready.set()
                await self._stop.wait()
        try:
            self._loop.run_until_complete(main())
        finally:
            self._loop.run_until_complete(self._loop.shutdown_asyncgens())
            self._loop.close()          # its sockets too: nothing left for a later test's garbage collection

    def close(self):
        self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(WAIT)


@pytest.mark.slow
def test_the_page_through_a_jupyter_style_proxy_connects_and_its_tab_is_titled(browser, views, monkeypatch):  # noqa: F811
    from coopsim.view.live.serving import ENV_PREFIX

    proxy = PrefixProxy()
    try:
        monkeypatch.setenv(ENV_PREFIX, f"http://127.0.0.1:{proxy.port}/proxy/{{port}}/")
        v = make(views, two_scaras(), speed=1.0, title="a proxied run")
        assert v.url == f"http://127.0.0.1:{proxy.port}/proxy/{v.port}/"
        lp = LivePage(browser, v)          # loads v.url (the proxy's) and waits for the view to see the page
        try:
            assert lp.page.title() == "a proxied run"
            # the page's websocket: the proxy's address (the client keeps it in the page's query)
            assert lp.page.url == f"{v.url}?websocket=ws://127.0.0.1:{proxy.port}/proxy/{v.port}"
            assert any(p.rstrip("/") == f"/proxy/{v.port}" for p in proxy.requests)     # the websocket: proxied
            t = v.sim.time
            until(lambda: v.sim.time > t + 0.05 and v.frames > 5, "the run goes on, drawn")
        finally:
            lp.close()
    finally:
        proxy.close()


@pytest.mark.slow
def test_the_tasks_page_frames_the_robots_the_container_and_the_bar_at_the_start(browser, views, tmp_path):  # noqa: F811
    """The main job's page at t = 0, as `python -m coopsim.tasks.handover --live` opens it: its tab titled
    after the task, the bar, both robots and the container projected into the view's central part, the bar's
    pixel the bar's red (not hidden behind SCARA #1)."""
    from coopsim.tasks.handover.planning import default_bars
    from coopsim.tasks.handover.sequence import _Runner

    # the task's own simulation at its start (as handover.run(live=...) makes it)
    sim = _Runner(default_bars(1), dt=2e-4, log_every=25, world_every=5, control_every=5, mouth=None, slope=None,
                  handover_yaw=None, t_limit=120.0).sim
    v = make(views, sim, start=False, title="coopsim: the cooperative bar handover")
    lp = LivePage(browser, v, width=1280, height=720, keep=tmp_path)
    try:
        from PIL import Image

        assert lp.page.title() == "coopsim: the cooperative bar handover"
        bar = np.asarray(sim.body_state("bar").position)
        box = lp.page.locator("canvas").first.bounding_box()
        shot = []

        def look():       # a large page drawn in software: a shot may take long
            png = lp.page.screenshot(clip=box, timeout=WAIT * 1000)
            shot[:] = [np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)]
            return colour_near(shot[0], lp.project(bar)[0], is_red, radius=3)
        until(look, "the bar red where it lies")
        img = shot[0]
        Image.fromarray(img.astype(np.uint8)).save(tmp_path / "task_t0.png")
        H, W = img.shape[:2]
        panel = 330            # px: the page's panel over the canvas's right-hand side
        points = [bar] + [r.base_position + [0, 0, r.dimensions["L_base"]] for r in sim.robots]
        points += [P[:3, 3] for _, P, _ in v._scenery()]
        for uv in lp.project(np.array(points)):
            assert 0.1 * W <= uv[0] <= W - panel and 0.1 * H <= uv[1] <= 0.9 * H, (uv, W, H)
        # the robots fill the view: their parts span a good part of its height
        rows = lp.project(v._scene_points())[:, 1]
        assert rows.max() - rows.min() > 0.5 * H
    finally:
        lp.close()



# ---- one driver per run ----

def test_live_twice_on_one_simulation_returns_its_view_and_other_threads_are_refused(views):
    """A notebook cell run again: live() on a simulation whose view is open returns that view (20 times in a
    row, the task's world stepping meanwhile), a second LiveView is refused in one line, and advancing the
    simulation from another thread while the view runs it raises SimulationBusyError naming the view."""
    from coopsim.tasks import scene as task_scene

    sim = two_scaras(world=task_scene.world([task_scene.bar_pose(0.95, 0.30 + 0.07 * k) for k in range(3)]))
    v = make(views, sim, speed=4.0)
    until(lambda: sim.time > 0.02, "the view's thread runs the run")
    for _ in range(20):
        again = view.live(sim, quiet=True)
        assert again is v
        with pytest.raises(cs.SimulationBusyError, match=f"the live view at {v.url}"):
            sim.advance(sim.time + 0.01)
    with pytest.raises(RuntimeError, match=f"already has a live view at {v.url}"):
        view.LiveView(sim, quiet=True, start=False)
    t1 = sim.time
    until(lambda: sim.time > t1 + 0.02, "the run goes on, one driver")
    assert v.error is None and v._thread.is_alive()
    v.close()
    fresh = make(views, sim, start=False)            # closed: a new view for the same simulation
    assert fresh is not v and view.live(sim, quiet=True) is fresh
    fresh.run_to(sim.time + 0.01)
    sim.advance(sim.time + 0.01)                     # nobody drives between the view's runs: the caller may


# ---- plots drawn ----

_CANVAS_HAS = """([r, g, b, tol]) => {
    // whether the Plots tab's first uPlot canvas (the q plot) holds a pixel of colour (r, g, b) within tol
    const c = document.querySelector('.uplot canvas');
    if (!c || c.width === 0 || c.height === 0) return false;
    const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    for (let k = 0; k < px.length; k += 4)
        if (px[k + 3] > 200 && Math.abs(px[k] - r) <= tol && Math.abs(px[k + 1] - g) <= tol
            && Math.abs(px[k + 2] - b) <= tol) return true;
    return false;
}"""


@pytest.mark.slow
def test_the_plots_tab_draws_the_q_curves_across_the_panel(browser, views):  # noqa: F811
    """The plot is made while its tab is hidden (width 0 in the page) and sizes itself once the tab shows;
    a starved page renders few frames, so everything here waits for conditions, never for a time."""
    from coopsim.view.live.plots_panel import _PALETTE

    sim = two_scaras()
    v = make(views, sim, speed=1.0)
    lp = LivePage(browser, v, width=1200, height=800)
    until(lambda: sim.time > 0.05, "the run started")
    lp.tab("Plots")

    def wide():       # the first canvas's box in the page, read without waiting on the (busy) page's frames
        box = lp.page.evaluate("() => { const c = document.querySelector('.uplot canvas');"
                               " if (!c) return null; const r = c.getBoundingClientRect();"
                               " return [r.width, r.height]; }")
        return box is not None and box[0] > 200 and box[1] > 100
    until(wide, "the q plot's canvas spread across the panel (over 200 px wide)")
    rgb = [int(_PALETTE[0][k:k + 2], 16) for k in (1, 3, 5)]       # q1's stroke
    until(lambda: lp.page.evaluate(_CANVAS_HAS, rgb + [40]), "q1's curve drawn in its colour")
    assert not lp.page.evaluate(_CANVAS_HAS, [255, 0, 255, 40])    # a colour no series has: the check can fail
    lp.tab("Robots")                                                         # the tabs still answer
    lp.close()
