"""coopsim.view.replay_html: a simulation replayed in one self-contained HTML file.

Without a browser: the file has no network references, keeps meshcat's licence notice, stays
below a size bound, and its packed keyframes are the log's poses. In a real browser (Debian's
chromium, headless, driven by Playwright; scripts/setup.sh installs both): the page opens from
file:// with the network blocked and raises no error, a seek shows the log's poses (read back
through window.coopsim), the controls play at the chosen speed, and a screenshot shows the scene
with the bar's red.
"""
from __future__ import annotations

import base64
import io
import json
import os
import re
import shutil

import numpy as np
import pytest

import coopsim as cs
from coopsim import view
from coopsim.tasks import scene

T_END = 2.0
#: bound on the file of a 2 s log of both SCARAs in the task's scene (the viewer bundle is 0.85 MB of it)
SIZE_BOUND = 1.2e6
#: float32 poses: positions within a few 1e-7 m of the log's (coordinates below 2 m), rotations 1e-6
TOL = 2e-6
CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if os.path.exists("/usr/bin/chromium") else None)
#: s: the bound on anything a page in the browser must reach, each of Playwright's actions (a click, a fill, a
#: shot, a wait) too. On a loaded machine the pages' software WebGL may take tens of seconds for a frame, and
#: Playwright's actions wait for frames: a generous bound that load can only approach, never a timing (the tests
#: wait for the page's own signals: window.coopsim.ready here, the live page's data-coopsim-live in test_live)
WAIT = 180.0


def trajectory(robot, t_end, phase):
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    times = np.linspace(0.0, t_end, 5)
    return cs.CubicTrajectory(times, [mid + 0.2 * np.sin(phase + 1.3 * k) * span for k in range(len(times))])


def task_run(t_end=T_END, log_every=25):
    """Both SCARAs of the task's scene on cubic trajectories (PID, so the ghost shows), the bar on the
    floor and a second bar dropped from 0.4 m next to it."""
    high = scene.bar_pose(x=0.95, y=-0.25, yaw=0.4)
    high[2, 3] = 0.4
    sim = cs.Simulation(dt=2e-4, world=scene.world(bars=[scene.bar_pose(), high]), log_every=log_every)
    for i, r in enumerate(scene.scaras()):
        sim.add_robot(r, cs.PID(60.0, 0.0, 6.0), trajectory(r, t_end, 1.7 * i))
    sim.run(t_end, progress=False)
    return sim


@pytest.fixture(scope="module")
def sim():
    return task_run()


@pytest.fixture(scope="module")
def page_path(sim, tmp_path_factory):
    return view.replay_html(sim, str(tmp_path_factory.mktemp("replay") / "run.html"))


def holding_log(sim, begin=0.52, end=1.22):
    """The run's log with SCARA #1 holding the bar from begin to end (s)."""
    log = sim.log
    held = np.where((log.t >= begin) & (log.t < end), "bar", "").astype(object)
    robots = [cs.RobotLog(rl.name, rl.t, holding=held if i == 0 else None, **{k: getattr(rl, k) for k in cs.log.STORED})
              for i, rl in enumerate(log.robots)]
    return cs.SimulationLog(log.t, robots, bodies=list(log.bodies.values()))


def hexcolor(c):
    from matplotlib.colors import to_hex

    return to_hex(c)


def read(path) -> str:
    with open(path, encoding="utf-8") as f:
        return f.read()


def meta(path):
    text = read(path)
    return json.loads(re.search(r'<script type="application/json" id="cs-meta">(.*?)</script>', text, re.S).group(1))


def commands(path):
    import umsgpack

    text = read(path)
    packed = json.loads(re.search(r'<script type="application/json" id="cs-commands">(.*?)</script>', text,
                                  re.S).group(1))
    return [umsgpack.unpackb(base64.b64decode(c)) for c in packed]


def f32(ext):
    return np.frombuffer(ext.data, dtype="<f4")


def parts_of(robot):
    from coopsim.view.parts import robot_parts

    return robot_parts(robot)


def part_poses(robot, parts, q):
    from coopsim.view.parts import part_poses as poses

    return poses(robot, parts, q)


def box_index(robot, name):
    return [b.name for b in robot.boxes].index(name)


# ---- without a browser ----

def test_the_file_is_self_contained_licensed_and_small(page_path):
    text = read(page_path)
    size = os.path.getsize(page_path)
    assert size < SIZE_BOUND, f"{size / 1e6:.2f} MB"
    # nothing that a browser would fetch: no script or stylesheet from a URL, no remote url(), no @import
    assert not re.search(r"<script[^>]*\ssrc\s*=", text, re.I)
    assert not re.search(r"<link[^>]*\shref\s*=", text, re.I)
    assert not re.search(r"""\b(src|href|action)\s*=\s*["']?\s*(https?:)?//""", text, re.I)
    assert not re.search(r"""url\(\s*["']?\s*(https?:)?//""", text, re.I)
    assert "@import" not in text
    # the viewer is inside, with its licence notices
    assert "MeshCat.Viewer" in text and "Copyright (c) 2018 Robin Deits" in text
    assert "Three.js Authors" in text and "MIT" in text
    for control in ('id="cs-play"', 'id="cs-scrub"', 'id="cs-speed" type="range" min="0" max="400"'):
        assert control in text


def test_frames_are_log_rows_at_the_chosen_rate(sim, tmp_path):
    log = sim.log
    m = meta(page_path := view.replay_html(sim, str(tmp_path / "a.html"), fps=10))
    assert m["fps"] == 10 and m["t0"] == 0.0 and m["t1"] == pytest.approx(T_END)
    assert len(m["frames"]) == int(T_END * 10) + 1
    assert np.allclose(m["frames"], np.arange(21) / 10, atol=1e-12)
    assert set(m["frames"]) <= set(np.asarray(log.t).tolist())
    names = m["names"]
    for n in ("robot0/link1", "robot1/fixed_jaw", "robot0/parts/link1", "robot0/parts/link1/segment1",
              "robot1/parts/link0/column", "ghost0/parts/link2/segment2", "ghost1/parts/link6/moving_jaw", "bodies/bar",
              "bodies/bar1", "scenery/container_bottom", "floor"):
        assert n in names
    assert not any(n.startswith("ghost0/parts/link0") for n in names)      # the base never moves: no ghost of it
    # a log coarser than the frame rate keeps all its rows; a part of the log
    m = meta(view.replay_html(log, str(tmp_path / "b.html"), robots=sim.robots, world=sim.world, fps=1000,
                              t_start=0.5, t_end=1.0))
    assert np.allclose(m["frames"], np.asarray(log.t)[(log.t >= 0.5 - 1e-9) & (log.t <= 1.0 + 1e-9)])
    assert os.path.getsize(page_path) < SIZE_BOUND


def test_packed_keyframes_are_the_logs_poses(sim, page_path):
    log, (r1, r2) = sim.log, sim.robots
    m = meta(page_path)
    rows = np.searchsorted(log.t, m["frames"])
    assert np.allclose(np.asarray(log.t)[rows], m["frames"], atol=0, rtol=0)
    anim = [c for c in commands(page_path) if c["type"] == "set_animation"]
    assert len(anim) == 1
    tracks = {a["path"]: a["clip"]["tracks"] for a in anim[0]["animations"]}

    def keyed(path):
        pos = f32(tracks[path][0]["values"]).reshape(-1, 3)
        quat = f32(tracks[path][1]["values"]).reshape(-1, 4)
        assert np.allclose(f32(tracks[path][0]["times"]), np.asarray(m["frames"]) - m["t0"], atol=1e-6)
        return pos, quat

    def rot(q):       # [x, y, z, w] -> R
        x, y, z, w = q
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])

    for i, r, box in ((0, r1, "link3"), (1, r2, "fixed_jaw")):
        pos, quat = keyed(f"/coopsim/robot{i}/{box}")
        j = box_index(r, box)
        link = r.boxes[j].link
        fpos, fquat = keyed(f"/coopsim/robot{i}/parts/link{link}")       # the parts' link frame
        gpos, gquat = keyed(f"/coopsim/ghost{i}/parts/link{link}")
        for k in (0, len(rows) // 3, len(rows) - 1):
            T = r.shapes(log[i].q[rows[k]])[0][j]
            assert np.abs(pos[k] - T[:3, 3]).max() < TOL
            assert np.abs(rot(quat[k]) - T[:3, :3]).max() < 1e-6
            F, G = r.frames(log[i].q[rows[k]])[link], r.frames(log[i].q_ref[rows[k]])[link]
            assert np.abs(fpos[k] - F[:3, 3]).max() < TOL and np.abs(rot(fquat[k]) - F[:3, :3]).max() < 1e-6
            assert np.abs(gpos[k] - G[:3, 3]).max() < TOL and np.abs(rot(gquat[k]) - G[:3, :3]).max() < 1e-6
    bar = log.bodies["bar1"].poses()
    pos, _ = keyed("/coopsim/bodies/bar1")
    assert np.abs(pos - bar[rows][:, :3, 3]).max() < TOL
    assert pos[0, 2] > 0.39 and pos[-1, 2] < 0.011        # it fell
    # what never moves has one fixed pose, no keyframes
    assert not any(p.startswith(("/coopsim/scenery", "/coopsim/floor")) or p.endswith(("/base", "/link0")) or
                   "/link0/" in p for p in tracks)


def test_colours_the_bar_red_scenery_other_bodies_and_a_holding_robot_green(sim, tmp_path):
    # one holder: green with holding='any' (the default greens only a dual hold, as the views do)
    path = view.replay_html(holding_log(sim), str(tmp_path / "held.html"), robots=sim.robots, world=sim.world,
                            holding="any")
    shared = commands(view.replay_html(holding_log(sim), str(tmp_path / "shared.html"), robots=sim.robots,
                                       world=sim.world))
    anim = next(c for c in shared if c["type"] == "set_animation")["animations"]
    assert all(t["name"] != "box.material.color" for a in anim for t in a["clip"]["tracks"])
    cmds = commands(path)
    color = {c["path"]: "#%06x" % c["object"]["materials"][0]["color"] for c in cmds if c["type"] == "set_object"}
    assert color["/coopsim/bodies/bar"] == color["/coopsim/bodies/bar1"] == view.COLORS["body"]
    assert color["/coopsim/scenery/container_top"] == view.COLORS["scenery"]
    assert color["/coopsim/robot0/link2"] == view.COLORS["robots"][0]
    assert color["/coopsim/robot1/link2"] == view.COLORS["robots"][1]
    assert color["/coopsim/robot0/base"] == view.COLORS["base"]
    assert color["/coopsim/ghost0/parts/link2/segment2"] == view.COLORS["ghost"]
    # the parts: the robot's colour, the base's, the jaws'
    assert color["/coopsim/robot0/parts/link2/segment2"] == color["/coopsim/robot0/parts/link1/housing1"] == \
        view.COLORS["robots"][0]
    assert color["/coopsim/robot1/parts/link2/segment2"] == view.COLORS["robots"][1]
    assert color["/coopsim/robot0/parts/link0/column"] == color["/coopsim/robot1/parts/link0/base_plate"] == \
        view.COLORS["base"]
    assert color["/coopsim/robot0/parts/link6/moving_jaw"] == color["/coopsim/robot0/parts/link5/fixed_jaw"] == \
        view.COLORS["jaw"]
    tracks = {a["path"]: a["clip"]["tracks"] for a in next(c for c in cmds if c["type"] == "set_animation")["animations"]}
    green = [t for t in tracks["/coopsim/robot0/link2"] if t["name"] == "box.material.color"]
    assert len(green) == 1 and green[0]["interpolation"] == 2300
    times, rgb = f32(green[0]["times"]), f32(green[0]["values"]).reshape(-1, 3)
    frames = np.asarray(meta(path)["frames"])
    assert np.allclose(times, [0.0, frames[frames >= 0.52][0], frames[frames >= 1.22][0], T_END], atol=1e-6)
    assert [hexcolor(c) for c in rgb] == [view.COLORS["robots"][0], view.COLORS["holding"], view.COLORS["robots"][0],
                                          view.COLORS["robots"][0]]
    # the parts turn green where the boxes do: the same keys on every part of a moving link
    for part in ("link2/segment2", "link1/housing1", "link6/moving_jaw", "link3/quill"):
        track = [t for t in tracks[f"/coopsim/robot0/parts/{part}"] if t["name"] == "box.material.color"]
        assert len(track) == 1 and np.array_equal(f32(track[0]["times"]), times), part
        assert hexcolor(f32(track[0]["values"]).reshape(-1, 3)[1]) == view.COLORS["holding"], part
    for p in ("/coopsim/robot0/base", "/coopsim/robot1/link2", "/coopsim/ghost0/parts/link2/segment2",
              "/coopsim/robot0/parts/link0/column", "/coopsim/robot1/parts/link2/segment2"):
        assert all(t["name"] != "box.material.color" for t in tracks.get(p, []))
    # holding=False: no colour changes; given per robot
    cmds = commands(view.replay_html(holding_log(sim), str(tmp_path / "off.html"), robots=sim.robots,
                                     world=sim.world, holding=False))
    anim = next(c for c in cmds if c["type"] == "set_animation")["animations"]
    assert all(t["name"] != "box.material.color" for a in anim for t in a["clip"]["tracks"])
    rows = len(sim.log.t)
    cmds = commands(view.replay_html(sim, str(tmp_path / "given.html"), holding=[None, np.arange(rows) > rows // 2]))
    anim = {a["path"]: a["clip"]["tracks"] for a in next(c for c in cmds if c["type"] == "set_animation")["animations"]}
    assert any(t["name"] == "box.material.color" for t in anim["/coopsim/robot1/link1"])
    assert all(t["name"] != "box.material.color" for t in anim["/coopsim/robot0/link1"])


def test_a_simulation_or_its_log_robots_and_world_give_the_same_replay(sim, tmp_path):
    a = meta(view.replay_html(sim, str(tmp_path / "a.html")))
    b = meta(view.replay_html(sim.log, tmp_path / "b.html", robots=sim.robots, world=sim.world))
    assert a == b


def test_bad_input_names_the_argument(sim, tmp_path):
    p = str(tmp_path / "x.html")
    with pytest.raises(ValueError, match="robots must be given"):
        view.replay_html(sim.log, p)
    with pytest.raises(ValueError, match="free bodies .*bar.*world"):
        view.replay_html(sim.log, p, robots=sim.robots)
    with pytest.raises(ValueError, match="2 robot"):
        view.replay_html(sim.log, p, robots=sim.robots[:1], world=sim.world)
    for kw, what in ((dict(fps=0), "fps"), (dict(fps="30"), "fps"), (dict(speed=4.5), "speed"),
                     (dict(speed=-0.1), "speed"), (dict(t_start=1.0, t_end=0.5), "t_end"),
                     (dict(t_start=1.001, t_end=1.002), "no log row"), (dict(colors=["red"]), "colors"),
                     (dict(elev=120), "elev"), (dict(zoom=0), "zoom"), (dict(holding=[None]), "holding"),
                     (dict(holding=[None, np.ones(3, bool)]), "holding\\[1\\]")):
        with pytest.raises(ValueError, match=what):
            view.replay_html(sim, p, **kw)
    with pytest.raises(ValueError, match="log must be"):
        view.replay_html("run.csv", p)
    with pytest.raises(ValueError, match="path"):
        view.replay_html(sim, None)
    assert not os.path.exists(p)


def spoiled_log(log, t=None, robot=0, bar=None, **arrays):
    """The log with its times, robot `robot`'s arrays or the bar's data replaced (as a hand-made log)."""
    t = log.t if t is None else t
    robots = [cs.RobotLog(rl.name, t, holding=rl.holding, weld=rl.weld,
                          **{k: arrays.get(k, getattr(rl, k)) if i == robot else getattr(rl, k)
                             for k in cs.log.STORED})
              for i, rl in enumerate(log.robots)]
    bodies = [cs.BodyLog(b.name, t, bar if bar is not None and b.name == "bar" else b.data)
              for b in log.bodies.values()]
    return cs.SimulationLog(t, robots, bodies=bodies, contacts=log._contacts)


def test_a_log_that_does_not_hold_together_is_named(sim, tmp_path):
    """Hand-made or damaged logs: each gave an IndexError, an OverflowError, numpy's messages or
    overflow warnings before (in brackets)."""
    log, p = sim.log, str(tmp_path / "x.html")
    rows = len(log.t)
    q, bar = np.array(log[0].q), np.array(log.bodies["bar"].data)
    huge = q.copy()
    huge[:, 2] = 1e300  # the quill, a prismatic joint
    nan_t, nan_bar = np.array(log.t), bar.copy()
    nan_t[3], nan_bar[2, 0] = np.nan, np.nan
    cases = [
        (dict(t=nan_t), r"log\.t must be finite"),                     # (cannot convert float NaN to integer)
        (dict(t=np.array(log.t)[::-1]), r"log\.t must be in time order"),       # (t_end must not be before t_start)
        (dict(t=np.array(log.t).astype(str)), r"log\.t must be an array of real numbers"),
        (dict(t=np.array(log.t) * 1e300), "frames is too many"),                 # (Maximum allowed size exceeded)
        (dict(q=q[:-3]), rf"wrong shape for log\[0\]\.q: expected \({rows}, n\)"),   # (IndexError)
        (dict(q=q[:, 0]), r"wrong shape for log\[0\]\.q"),                       # (IndexError)
        (dict(q_ref=q[:, :5]), rf"wrong shape for log\[0\]\.q_ref: expected \({rows}, 6\)"),
        (dict(q=huge), r"puts robot 0's boxes more than 1e\+06 m from the origin"),  # (overflow in cast)
        (dict(bar=nan_bar), r"log\.bodies\['bar'\] must hold finite positions"),  # (invalid value in multiply)
    ]
    for kw, match in cases:
        with pytest.raises(ValueError, match=match):
            view.replay_html(spoiled_log(log, **kw), p, robots=sim.robots, world=sim.world)
    assert not os.path.exists(p)
    robots, small = sim.robots, dict(figsize=(2, 2), dpi=20)
    for kw, match in cases[:6] + [(dict(t=np.array(log.t) * 1e200), r"^6e\+201 frames is too many")]:
        with pytest.raises(ValueError, match=match):  # (fp and xp are not of the same length, 200 digits ...)
            view.animate(spoiled_log(log, **kw), robots, world=sim.world, **small)
    with pytest.raises(ValueError, match="path must be a file name ending in .mp4 or .gif, got 5"):
        view.animate(sim, path=5, **small)  # (TypeError: expected str, bytes or os.PathLike object)
    # what the views derive from a log: NaN poses given back, an IndexError for a flat body log before
    with pytest.raises(ValueError, match=r"log\.bodies\['bar'\] must hold finite positions"):
        view.world_bodies(sim.world, spoiled_log(log, bar=nan_bar))
    with pytest.raises(ValueError, match=r"wrong shape for log\.bodies\['bar'\]"):
        view.world_bodies(sim.world, spoiled_log(log, bar=bar[:, 0]))
    for derive in (lambda x: view.colliding_from_log(x, robots), view.contacts_from_log, view.holding_from_log):
        with pytest.raises(ValueError, match=r"log\.t must be in time order"):
            derive(spoiled_log(log, t=np.array(log.t)[::-1]))
    # tables: a clear error for rows that do not match (numpy's hstack before), inf written as it is
    with pytest.raises(ValueError, match=r"wrong shape for log\[0\]\.q"):
        spoiled_log(log, q=q[:-1]).to_dataframe()
    inf = q.copy()
    inf[1, 1] = np.inf
    df = spoiled_log(log, q=inf, q_ref=inf).to_dataframe()  # e = inf - inf: NaN, without numpy's warning
    assert np.isnan(df[f"{log.labels[0]}.e2"].iloc[1])


def test_a_robot_alone_without_a_world(tmp_path):
    r = cs.robots.scara1()
    s = cs.Simulation(dt=2e-4, log_every=50)
    s.add_robot(r, cs.PID(50.0, 0.0, 5.0), trajectory(r, 0.5, 0.3))
    s.run(0.5, progress=False)
    m = meta(view.replay_html(s.log, str(tmp_path / "one.html"), robots=r, reference=False, speed=4))
    assert m["speed"] == 4 and "floor" in m["names"] and not any(n.startswith("ghost") for n in m["names"])


def test_a_world_without_robots_and_a_title_kept_as_text(tmp_path):
    w = cs.World(floor=False)
    w.add_free_box("box", [0.05, 0.05, 0.05], 1.0, position=[0.0, 0.0, 1.0])
    s = cs.Simulation(dt=2e-4, world=w, log_every=50)
    s.run(0.3, progress=False)
    title = "a </script> <b>title</b> @COMMANDS@"
    path = view.replay_html(s, str(tmp_path / "sub" / "fall.html"), title=title)
    m = meta(path)
    assert m["names"] == ["bodies/box"] and len(m["frames"]) == 10
    box = next(c for c in commands(path) if c["type"] == "set_object")
    assert "#%06x" % box["object"]["materials"][0]["color"] == view.COLORS["free_body"]     # not a bar: not red
    text = read(path)
    assert text.count("@COMMANDS@") == 2 and "&lt;/script&gt; &lt;b&gt;title&lt;/b&gt;" in text


# ---- in a browser ----

def _browser_or_skip():
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright is not installed (scripts/setup.sh installs it with the test extra)")
    if CHROMIUM is None:
        pytest.skip("Debian's chromium is not installed (scripts/setup.sh installs it)")
    return sync_playwright


def patient(page):
    """`page` with Playwright's default timeouts (30 s, tuned to an idle machine) raised to WAIT for every action,
    navigation and wait of it (a download awaited, a function waited for) that names no timeout of its own."""
    page.set_default_timeout(WAIT * 1000)
    page.set_default_navigation_timeout(WAIT * 1000)
    return page


class PatientBrowser:
    """A Playwright Browser whose new pages are :func:`patient`; everything else is the browser's."""

    def __init__(self, browser):
        self._browser = browser

    def new_page(self, **kwargs):
        return patient(self._browser.new_page(**kwargs))

    def __getattr__(self, name):
        return getattr(self._browser, name)


@pytest.fixture(scope="module")
def browser():
    """Debian's chromium, headless, through Playwright, for a test module; its pages wait up to WAIT s for
    each action (:class:`PatientBrowser`)."""
    sync_playwright = _browser_or_skip()
    with sync_playwright() as p:
        # without the sanitizers' runtimes that scripts/test_sanitized.sh preloads for the interpreter:
        # Chromium, never instrumented, does not start with them
        env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}
        b = p.chromium.launch(executable_path=CHROMIUM, args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
                              env=env)
        try:
            yield PatientBrowser(b)
        finally:
            b.close()


#: a script resolving once the page has drawn two more frames (a paused page's time must not move across them)
TWO_FRAMES = "new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(() => done(true))))"


class Page:
    """A page opened from file:// with every other request blocked; errors and blocked requests collected."""

    def __init__(self, browser, path, width=1000, height=700):
        self.errors, self.blocked = [], []
        self.page = patient(browser.new_page(viewport={"width": width, "height": height}))
        self.page.on("console", lambda msg: self.errors.append(f"console {msg.type}: {msg.text}")
                     if msg.type == "error" else None)
        self.page.on("pageerror", lambda exc: self.errors.append(f"page error: {exc}"))

        def route(r):
            if r.request.url.startswith(("file:", "data:", "blob:")):
                r.continue_()
            else:
                self.blocked.append(r.request.url)
                r.abort()

        self.page.route("**/*", route)
        self.page.goto("file://" + os.path.abspath(path))
        self.page.wait_for_function("window.coopsim && window.coopsim.ready")      # the page's own signal

    def js(self, expr):
        return self.page.evaluate(expr)

    def pose(self, name):
        p = self.js(f"window.coopsim.pose({json.dumps(name)})")
        return None if p is None else np.array(p)

    def pixels(self):
        from PIL import Image

        return np.asarray(Image.open(io.BytesIO(self.page.screenshot())).convert("RGB")).astype(int)

    def close(self):
        self.page.close()


@pytest.fixture(scope="module")
def page(browser, page_path):
    p = Page(browser, page_path)
    yield p
    p.close()


@pytest.mark.slow
def test_the_page_opens_offline_without_errors(page):
    assert page.js("typeof window.coopsim.seek") == "function"
    assert page.js("window.coopsim.t1") == pytest.approx(T_END)
    assert page.js("document.querySelector('canvas') !== null")
    assert page.errors == [] and page.blocked == []


@pytest.mark.slow
def test_a_seek_shows_the_logs_poses(page, sim):
    log, robots = sim.log, sim.robots
    frames = page.js("window.coopsim.frames")
    for k in (0, 17, 40, len(frames) - 1):
        t = frames[k]
        row = int(np.searchsorted(log.t, t))
        assert page.js(f"window.coopsim.seek({t!r})") == pytest.approx(t)
        assert page.js("window.coopsim.time()") == pytest.approx(t)
        for i, r in enumerate(robots):
            P, _ = r.shapes(log[i].q[row])
            F, G = r.frames(log[i].q[row]), r.frames(log[i].q_ref[row])
            for j, b in enumerate(r.boxes):
                assert np.abs(page.pose(f"robot{i}/{b.name}") - P[j]).max() < TOL, (t, i, b.name)
            for p, W in zip(parts_of(r), part_poses(r, parts_of(r), log[i].q[row])):
                assert np.abs(page.pose(f"robot{i}/parts/link{p.link}/{p.name}") - W).max() < TOL, (t, i, p.name)
            for k in range(1, r.dof + 1):
                assert np.abs(page.pose(f"robot{i}/parts/link{k}") - F[k]).max() < TOL, (t, i, k)
                assert np.abs(page.pose(f"ghost{i}/parts/link{k}") - G[k]).max() < TOL, (t, i, k)
        for name in ("bar", "bar1"):
            assert np.abs(page.pose(f"bodies/{name}") - log.bodies[name].poses()[row]).max() < TOL
    # between frames, three.js interpolates: the falling bar is between its neighbouring frames' heights
    t = 0.5 * (frames[8] + frames[9])
    page.js(f"window.coopsim.seek({t})")
    z = page.pose("bodies/bar1")[2, 3]
    z8, z9 = (log.bodies["bar1"].poses()[np.searchsorted(log.t, f)][2, 3] for f in (frames[8], frames[9]))
    assert min(z8, z9) - 1e-6 <= z <= max(z8, z9) + 1e-6 and abs(z8 - z9) > 1e-3
    # clamped to the replay; static scenery where the world has it; unknown names give null
    assert page.js("window.coopsim.seek(99)") == pytest.approx(T_END)
    assert page.js("window.coopsim.seek(-1)") == 0
    wall = next(b for b in (sim.world.body(n) for n in sim.world.body_names) if b["name"] == "container_top")
    assert np.abs(page.pose("scenery/container_top") - wall["pose"]).max() < TOL
    assert page.pose("robot7/link1") is None and page.pose("nothing") is None
    assert page.errors == []


@pytest.mark.slow
def test_the_controls_play_pause_scrub_and_set_the_speed(page):
    js = page.js
    # the play button plays and pauses (at 1 % the 2 s replay lasts 200 s, beyond the bound WAIT on a click:
    # the second click lands before the end however loaded the machine)
    js("window.coopsim.seek(0); window.coopsim.setSpeed(0.01)")
    page.page.click("#cs-play")
    assert js("window.coopsim.playing()")
    page.page.wait_for_function("window.coopsim.time() > 0")
    page.page.click("#cs-play")
    t = js("window.coopsim.time()")
    assert not js("window.coopsim.playing()") and 0 < t < T_END
    page.page.evaluate(TWO_FRAMES)
    assert js("window.coopsim.time()") == t                                # paused: two frames drawn, no time
    js("window.coopsim.setSpeed(1)")
    # the replay's time runs at the speed times the wall time
    # (time() reads the page's clock when called: the played time lies between speed times the wall time
    # measured inside and outside the play() .. time() span, however loaded the machine)
    played = """(speed) => new Promise((done) => {
        const c = window.coopsim;
        c.seek(0.1); c.setSpeed(speed);
        const s0 = performance.now(); c.play(); const s1 = performance.now();
        setTimeout(() => {
            const e0 = performance.now(); const t = c.time(); const e1 = performance.now();
            done([t - 0.1, (e0 - s1) / 1000, (e1 - s0) / 1000]); c.pause();
        }, 120);
    })"""
    for speed in (1.0, 4.0, 0.5, 0.0):
        dt, inner, outer = page.page.evaluate(played, speed)
        assert speed * inner - 1e-9 <= dt <= speed * outer + 1e-9, (speed, dt, inner, outer)
        assert dt > 0 or speed == 0
    # the speed slider: 0 to 400 %
    slider = "(v) => { const s = document.getElementById('cs-speed'); s.value = v; s.dispatchEvent(new Event('input')); }"
    page.page.evaluate(slider, 400)
    assert js("window.coopsim.speed()") == 4 and js("document.getElementById('cs-speed-value').textContent") == "400 %"
    page.page.evaluate(slider, 900)
    assert js("window.coopsim.speed()") == 4
    page.page.evaluate(slider, 25)
    assert js("window.coopsim.speed()") == 0.25
    js("window.coopsim.setSpeed(1)")
    # played to the end it stops there; the space bar plays from the start again
    js("window.coopsim.seek(1.95); window.coopsim.play()")
    page.page.wait_for_function("!window.coopsim.playing()")
    assert js("window.coopsim.time()") == pytest.approx(T_END)
    page.page.keyboard.press("Space")
    assert js("window.coopsim.playing()") and js("window.coopsim.time()") < 1.0
    page.page.keyboard.press("Space")
    assert not js("window.coopsim.playing()")
    # the scrubber seeks; the arrow keys step a frame
    page.page.evaluate("(v) => { const s = document.getElementById('cs-scrub'); s.value = v; "
                       "s.dispatchEvent(new Event('input')); }", 1.25)
    assert js("window.coopsim.time()") == pytest.approx(1.25)
    assert js("document.getElementById('cs-time').textContent") == "1.250 s / 2.000 s"
    frames = js("window.coopsim.frames")
    js("document.activeElement.blur()")
    page.page.keyboard.press("ArrowRight")
    assert js("window.coopsim.time()") == pytest.approx(min(f for f in frames if f > 1.25 + 1e-9))
    page.page.keyboard.press("ArrowLeft")
    assert js("window.coopsim.time()") == pytest.approx(max(f for f in frames if f < 1.25 - 1e-9))
    assert page.errors == []


@pytest.mark.slow
def test_a_robot_is_green_while_it_holds_something(browser, sim, tmp_path):
    p = Page(browser, view.replay_html(holding_log(sim), str(tmp_path / "held.html"), robots=sim.robots, holding="any",
                                       world=sim.world), width=400, height=300)
    try:
        for t, expected in ((0.2, view.COLORS["robots"][0]), (0.6, view.COLORS["holding"]), (1.0, view.COLORS["holding"]),
                            (1.25, view.COLORS["robots"][0]), (2.0, view.COLORS["robots"][0]), (0.7, view.COLORS["holding"])):
            p.js(f"window.coopsim.seek({t})")
            assert p.js("window.coopsim.color('robot0/link2')") == expected, t
            assert p.js("window.coopsim.color('robot0/link6')") == (view.COLORS["holding"] if expected ==
                                                                   view.COLORS["holding"] else view.COLORS["jaw"])
            assert p.js("window.coopsim.color('robot0/base')") == view.COLORS["base"]
            assert p.js("window.coopsim.color('robot1/link2')") == view.COLORS["robots"][1]
        assert p.js("window.coopsim.color('bodies/bar')") == view.COLORS["body"]
        assert p.js("window.coopsim.color('nothing')") is None
        assert p.errors == [] and p.blocked == []
    finally:
        p.close()


@pytest.mark.slow
def test_a_screenshot_shows_the_scene_and_the_bars_red(page, sim):
    page.js("window.coopsim.seek(1.0)")
    img = page.pixels()
    assert img.std() > 20 and len(np.unique(img.reshape(-1, 3), axis=0)) > 500      # not blank
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    red = (r > 120) & (r > 2.2 * g) & (r > 2.2 * b)
    assert red.sum() > 30, red.sum()           # the bars (the paper's red) are on screen
    blue = (b > 1.3 * r) & (b > 1.2 * g) & (b > 120)
    assert blue.sum() > 30                     # the ghost
    orange = (r > 180) & (g > 100) & (g < 200) & (b < 110)
    assert orange.sum() > 30                   # SCARA #1's links
    # the bars' red is there because of the bars: hidden, it is gone
    page.js("window.coopsim.viewer.scene_tree.children['coopsim'].children['bodies'].object.visible = false;"
            "window.coopsim.seek(1.0)")
    img = page.pixels()
    page.js("window.coopsim.viewer.scene_tree.children['coopsim'].children['bodies'].object.visible = true;"
            "window.coopsim.seek(1.0)")
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    assert ((r > 120) & (r > 2.2 * g) & (r > 2.2 * b)).sum() < 5


# ---- opening, marks on the timeline, meshcat's controls, the camera ----

GRASPS = {"t": [0.52, 1.22], "robot": [0, 0], "body": ["bar", "bar"], "event": ["grasp", "release"],
          "reason": ["grasp", "opened"]}


def grasping_log(sim):
    """holding_log with the grasp and the release as the log's events."""
    log = holding_log(sim)
    return cs.SimulationLog(log.t, log.robots, bodies=list(log.bodies.values()), grasps=GRASPS)


def meta_of(path) -> dict:
    return json.loads(re.search(r'<script type="application/json" id="cs-meta">(.*?)</script>', read(path),
                                re.S).group(1).replace("<\\/", "</"))


def test_the_timeline_marks_the_grasps_releases_and_given_steps(sim, tmp_path):
    log = grasping_log(sim)
    p = view.replay_html(log, str(tmp_path / "m.html"), robots=sim.robots, world=sim.world,
                         markers=[(1.5, "cycle 0: carry"), (0.1, "cycle 0: pick"), (9.0, "after the end")])
    m = meta_of(p)["markers"]
    assert m == [{"t": 0.1, "label": "cycle 0: pick"}, {"t": 0.52, "label": "scara1 grasps bar"},
                 {"t": 1.22, "label": "scara1 releases bar (opened)"}, {"t": 1.5, "label": "cycle 0: carry"}]
    assert meta_of(p)["autoplay"] is True                  # the page starts playing
    q = view.replay_html(log, str(tmp_path / "n.html"), robots=sim.robots, world=sim.world, events=False)
    assert meta_of(q)["markers"] == []
    with pytest.raises(ValueError, match="markers must be"):
        view.replay_html(log, str(tmp_path / "x.html"), robots=sim.robots, world=sim.world, markers=[1.0, 2.0])
    with pytest.raises(ValueError, match="a marker's t"):
        view.replay_html(log, str(tmp_path / "x.html"), robots=sim.robots, world=sim.world, markers=[("a", "b")])


def test_the_task_steps_become_markers():
    from coopsim.tasks.handover.report import step_markers

    rep = {"cycles": [{"cycle": 0, "bar": "bar", "success": True, "steps": {"pick": [0.0, 2.5], "carry": [2.5, 6.0]}},
                      {"cycle": 1, "bar": "bar1", "success": False, "steps": {"pick": [16.0, None]},
                       "failed_step": "pick", "failed_at": 17.25, "reason": "missed"}]}
    assert step_markers(rep) == [(0.0, "cycle 0 (bar): pick"), (2.5, "cycle 0 (bar): carry"),
                                 (16.0, "cycle 1 (bar1): pick"), (17.25, "cycle 1 (bar1) FAILED in pick: missed")]


@pytest.mark.slow
def test_the_page_plays_when_opened_or_opens_at_the_time_in_its_address(browser, sim, tmp_path):
    path = view.replay_html(sim, str(tmp_path / "a.html"))
    p = Page(browser, path, width=400, height=300)
    try:
        assert p.js("window.coopsim.playing()")
        p.page.wait_for_function("window.coopsim.time() > 0.05")
    finally:
        p.close()
    p = Page(browser, path + "#t=1.25", width=400, height=300)
    try:
        assert not p.js("window.coopsim.playing()") and p.js("window.coopsim.time()") == pytest.approx(1.25)
        p.page.evaluate(TWO_FRAMES)
        assert p.js("window.coopsim.time()") == pytest.approx(1.25)          # paused there, two frames later
        assert p.js("document.getElementById('cs-time').textContent") == "1.250 s / 2.000 s"
    finally:
        p.close()
    p = Page(browser, path + "#t=0.5&play", width=400, height=300)
    try:
        # playing from 0.5 s (on a loaded machine it may have reached the end already)
        p.page.wait_for_function("window.coopsim.time() > 0.5")
        assert p.js("window.coopsim.playing() || window.coopsim.time() === window.coopsim.t1")
        assert p.errors == [] and p.blocked == []
    finally:
        p.close()


@pytest.mark.slow
def test_the_marks_are_on_the_timeline_and_seek_and_meshcats_controls_are_hidden(browser, sim, tmp_path):
    path = view.replay_html(grasping_log(sim), str(tmp_path / "m.html"), robots=sim.robots, world=sim.world,
                            markers=[(1.5, "cycle 0: carry")])
    p = Page(browser, path)
    try:
        marks = p.js("Array.from(document.querySelectorAll('#cs-marks .cs-mark')).map(e => "
                     "[e.title, e.getBoundingClientRect().left, e.getBoundingClientRect().width])")
        assert [m[0] for m in marks] == ["0.520 s: scara1 grasps bar", "1.220 s: scara1 releases bar (opened)",
                                         "1.500 s: cycle 0: carry"]
        assert marks[0][1] < marks[1][1] < marks[2][1] and all(m[2] > 0 for m in marks)   # in time order, drawn
        track = p.js("(() => { const r = document.getElementById('cs-scrub').getBoundingClientRect(); "
                     "return [r.left, r.right]; })()")
        # each mark sits over the scrubber at its fraction of the replay (the thumb's inset: 8 px each side)
        for (title, left, w), t in zip(marks, (0.52, 1.22, 1.5)):
            x = track[0] + 8 + (track[1] - track[0] - 16) * t / T_END
            assert abs(left + w / 2 - x) < 3, (title, left, x)
        p.page.click("#cs-marks .cs-mark >> nth=1")
        assert not p.js("window.coopsim.playing()") and p.js("window.coopsim.time()") == pytest.approx(1.22)
        # meshcat's dat.gui panel ("Open Controls") is there but hidden: the page's bar has the controls
        assert p.js("document.querySelector('.dg.main .close-button').textContent") == "Open Controls"
        assert p.js("document.querySelector('.dg.main .close-button').offsetParent") is None   # not rendered
        assert p.js("getComputedStyle(document.querySelector('.dg.main')).display") == "none"
        assert p.errors == [] and p.blocked == []
    finally:
        p.close()


@pytest.mark.slow
def test_the_camera_frames_the_robots_not_a_body_far_away(browser, tmp_path):
    far = scene.bar_pose(x=3.5, y=3.0, yaw=0.2)      # a bar far off: it does not pull the camera away
    sim = cs.Simulation(dt=2e-4, world=scene.world(bars=[scene.bar_pose(), far]), log_every=25)
    for i, r in enumerate(scene.scaras()):
        sim.add_robot(r, cs.PID(60.0, 0.0, 6.0), trajectory(r, 0.2, 1.7 * i))
    sim.run(0.2, progress=False)
    p = Page(browser, view.replay_html(sim, str(tmp_path / "far.html"), autoplay=False))
    try:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
        pts = []
        for i, r in enumerate(sim.robots):
            P, H = r.shapes(sim.log[i].q[0])
            for T, h in zip(P, H):
                pts += list((T[:3, :3] @ (corners * h).T).T + T[:3, 3])
        ndc = np.array(p.page.evaluate("""(pts) => { const c = window.coopsim.viewer.camera; c.updateMatrixWorld();
            return pts.map(q => { const v = new MeshCat.THREE.Vector3(q[0], q[2], -q[1]).project(c);
                                  return [v.x, v.y]; }); }""", [list(map(float, x)) for x in pts]))
        assert np.all(np.abs(ndc) <= 1.0), np.abs(ndc).max()                   # every robot box in view
        span = (ndc.max(axis=0) - ndc.min(axis=0)).max()
        assert span > 0.9, span      # and filling most of it (1.12; 0.42 when the far bar was framed too)
    finally:
        p.close()
