"""The live page's scene: the robots' parts, ghosts and boxes, the world's bodies, the contacts and the camera,
built once and redrawn from a :class:`Frame` taken on the simulation's thread."""
from __future__ import annotations

import time

import numpy as np

from ..geometry import box_corners, view_direction
from ..parts import UNIT_CUBE, UNIT_CYLINDER, mesh_triangles, part_corners, part_poses, robot_parts
from ..scene import COLORS, DEFAULT_ELEV, Scene
from ..world import colliding_from_contacts, contact_lines, holding_now, is_bar
from .common import (_CONTACT_LENGTH, _CUBE_F, _CUBE_V, _ENVIRONMENT, _GHOST_MARGIN, _TABLE_EVERY, _rgb8,
                     _role_colors, quaternions)

_FOV = np.radians(75.0)     # viser's camera: vertical field of view (rad)
_FILL = 0.8                 # the scene's extent as a fraction of the view's half-height, each way from its centre
_ELEV = DEFAULT_ELEV + 8.0  # degrees: the default camera's elevation
_FLOOR_MARGIN = 0.3         # m of floor beyond the scene on each side


class Frame:
    """One consistent snapshot of the simulation (taken on its thread between chunks).

    t (s), steps; per robot q, qd, q_ref (n,), poses (k, 4, 4) and half (k, 3) of its boxes at q,
    parts (m, 4, 4) the world poses of its parts at q (coopsim.view.parts), ghost the poses of its boxes
    and ghost_parts those of its parts at q_ref,
    holding (bool), colliding (k,) bool; bodies: {name: pose (4, 4)} of the free bodies; lines (m, 2, 3)
    contact points and directions."""

    __slots__ = ("t", "steps", "q", "qd", "q_ref", "poses", "half", "parts", "ghost", "ghost_parts", "holding",
                 "colliding", "bodies", "lines")


class _Drawing:
    """The scene of a LiveView (a mixin: the view holds the server, the simulation and the display switches)."""

    def _build_scene(self) -> None:
        sc = self.server.scene
        world = self._world
        # the environment's light at a little under half: the paper's colours stay recognisable
        sc.configure_environment_map("warehouse", environment_intensity=_ENVIRONMENT)
        scenery = self._scenery()
        self._floor = world is None or world.floor
        self._azim = None
        self._fit_scene()          # the extent and the floor; the camera once its azimuth is chosen
        self._azim = self._unhidden_azimuth(self._choose_azimuth(scenery))
        self._set_camera("perspective", initial=True)
        for name, P, H in scenery:          # fixed: one box each, sent once
            sc.add_box(f"/scenery/{name}", color=_rgb8(COLORS["scenery"]), dimensions=2 * H,
                       wxyz=quaternions(P[:3, :3])[0], position=P[:3, 3])
        k = sum(len(r.boxes) for r in self.robots)
        half = np.concatenate([self.sim.robots[i].shapes(self.sim.state(i)[0])[1] for i in range(len(self.robots))]) \
            if self.robots else np.zeros((0, 3))
        self._half = half
        self._robot_mesh = None
        if k:
            self._robot_mesh = sc.add_batched_meshes_simple(
                "/robots", _CUBE_V, _CUBE_F, np.tile([1.0, 0, 0, 0], (k, 1)), np.zeros((k, 3)),
                batched_scales=2 * half, batched_colors=np.concatenate(self._colors), lod="off", flat_shading=True)
            self._robot_mesh.visible = self._show["collision_boxes"]
            self._build_parts()
        self._body_mesh = None
        if self._free_names:
            H = np.array([world.body(n)["half_extents"] for n in self._free_names])
            cols = np.array([_rgb8(COLORS["body"] if is_bar(n) else COLORS["free_body"]) for n in self._free_names])
            self._body_mesh = sc.add_batched_meshes_simple(
                "/bodies", _CUBE_V, _CUBE_F, np.tile([1.0, 0, 0, 0], (len(H), 1)), np.zeros((len(H), 3)),
                batched_scales=2 * H, batched_colors=cols, lod="off", flat_shading=True)
        self._lines = sc.add_line_segments("/contacts", np.zeros((1, 2, 3), dtype=np.float32),
                                           colors=_rgb8(COLORS["contact"]), thickness=4.0,
                                           thickness_units="screen", visible=False)
        self._label_nodes = []
        for i, r in enumerate(self.robots):
            p = r.base_position + np.array([0.0, 0.0, 0.05])
            self._label_nodes.append(sc.add_label(f"/labels/robot{i}", self.labels[i], position=p,
                                                  visible=self._show["labels"]))
        for n in self._free_names:
            self._label_nodes.append(sc.add_label(f"/labels/{n}", n, position=self.sim.body_state(n).position,
                                                  visible=self._show["labels"]))

    def _scenery(self) -> list:
        """[(name, pose (4, 4), half extents (3,))] of the world's static boxes."""
        world = self._world
        if world is None:
            return []
        out = []
        for name in world.body_names:
            d = world.body(name)
            if d["kind"] == "static":
                out.append((name, np.array(d["pose"]), np.array(d["half_extents"])))
        return out

    def _scene_points(self) -> np.ndarray:
        """(m, 3) corners of everything to frame now: the robots' boxes and parts, the scenery, the free bodies."""
        pts = [self._corners(*r.shapes(self.sim.state(i)[0])) for i, r in enumerate(self.robots)]
        pts += [part_corners(p, part_poses(r, p, self.sim.state(i)[0])) for i, (r, p) in
                enumerate(zip(self.robots, self._parts)) if p]
        pts += [self._corners(P[None], H[None]) for _, P, H in self._scenery()]
        pts += [self._corners(np.array(self.sim.body_state(n).pose)[None],
                              np.array(self._world.body(n)["half_extents"])[None]) for n in self._free_names]
        return np.concatenate(pts) if pts else np.zeros((1, 3))

    def _fit_scene(self) -> None:
        """Frames the scene as it is now: the floor under everything (_FLOOR_MARGIN beyond it), the camera's
        centre, direction and distance (:meth:`_camera_pose`); the initial camera of pages to come set."""
        pts = self._scene_points()
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self._centre = 0.5 * (lo + hi)
        self._radius = max(0.3, float(np.linalg.norm(hi - lo)) / 2)
        self._points = pts
        self._floor_size = float(max(hi[0] - lo[0], hi[1] - lo[1]) + 2 * _FLOOR_MARGIN)
        if self._floor:
            sc, size = self.server.scene, self._floor_size
            sc.add_box("/floor", color=_rgb8(COLORS["floor"][0]), dimensions=(size, size, 0.01),
                       position=(self._centre[0], self._centre[1], -0.005), cast_shadow=False)
            sc.add_grid("/floor/grid", width=size, height=size, cell_size=0.1, section_size=0.5,
                        cell_color=_rgb8(COLORS["floor"][1]), position=(0.0, 0.0, 0.0051), shadow_opacity=0.0)
        if self._azim is not None:
            self._set_camera("perspective", initial=True)

    def _unhidden_azimuth(self, preferred: float) -> float:
        """The azimuth (degrees) nearest `preferred` (every 15 degrees around) from which the camera sees the
        centres of the free bodies and of the scenery past the robots' boxes (the bar not hidden behind a
        robot at the start), those hidden counted, the free bodies first."""
        targets = []            # the free bodies' top faces' centres
        for n in self._free_names:
            P = np.asarray(self.sim.body_state(n).pose)
            targets.append(P[:3, 3] + P[:3, :3] @ [0.0, 0.0, self._world.body(n)["half_extents"][2]])
        weights = [10.0] * len(targets)
        for _, P, _ in self._scenery():
            targets.append(P[:3, 3])
            weights.append(1.0)
        if not targets or not self.robots:
            return preferred
        # what may hide them: the robots' boxes and parts (a cylinder as its box), the scenery
        poses, half = [], []
        for i, r in enumerate(self.robots):
            P, H = r.shapes(self.sim.state(i)[0])
            poses.append(P)
            half.append(H)
            if self._parts[i]:
                poses.append(part_poses(r, self._parts[i], self.sim.state(i)[0]))
                half.append(np.array([p.scale for p in self._parts[i]]) / 2)
        for _, P, H in self._scenery():
            poses.append(P[None])
            half.append(H[None])
        poses, half = np.concatenate(poses), np.concatenate(half)
        best = None
        for k, step in enumerate(sorted(range(0, 360, 15), key=lambda a: min(a, 360 - a))):
            azim = preferred + step
            eye = self._camera_pose(view_direction(_ELEV, azim))[0]
            hidden = sum(w for T, w in zip(targets, weights) if _segment_hits_boxes(eye, T, poses, half))
            score = (hidden, min(step, 360 - step))
            if best is None or score < best[0]:
                best = (score, azim)
        return float(best[1])

    def _camera_pose(self, direction) -> tuple:
        """(position (3,), look_at (3,)) of a camera looking at the scene's centre from `direction` (unit (3,),
        from the centre towards the camera), as near as frames every point of the scene within _FILL of the
        half-height of the view (viser's vertical field of view) vertically and horizontally (a landscape page
        with its panel on the right leaves about a square to the scene)."""
        d = np.asarray(direction, dtype=float)
        right = np.cross(-d, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, -d)
        o = self._points - self._centre
        t = _FILL * np.tan(_FOV / 2)
        depth_margin = np.maximum(np.abs(o @ right), np.abs(o @ up)) / t
        dist = max(float(np.max(o @ d + depth_margin)), 0.3)
        return self._centre + dist * d, self._centre.copy()

    def _build_parts(self) -> None:
        """The robots' parts as batched meshes, one per shape (unit cube, unit cylinder, each mesh file), each
        instance a part scaled and placed every frame; shown unless the collision boxes are."""
        for m in self._part_meshes + self._ghost_meshes:
            m[0].remove()
        self._part_meshes = self._batched_parts("/parts", False)
        self._ghost_meshes = self._batched_parts("/ghosts", True)

    def _batched_parts(self, root: str, ghost: bool) -> list:
        """[(handle, part indices in the frame's concatenated parts, robot of each, colours, on a moving link)]
        of the parts grouped by shape; ghost: the moving links' parts only, _GHOST_MARGIN smaller, in the
        ghost's colour and transparency (a robot on its reference hides its ghost)."""
        groups: dict = {}
        flat = 0
        for i, parts in enumerate(self._parts):
            for p in parts:
                if not ghost or p.link != 0:
                    groups.setdefault((p.shape, p.mesh), []).append((i, flat, p))
                flat += 1
        out = []
        for (shape, mesh), members in groups.items():
            v, fc = UNIT_CUBE if shape == "box" else UNIT_CYLINDER if shape == "cylinder" else mesh_triangles(mesh)
            parts = [p for _, _, p in members]
            k = len(members)
            scales = np.array([p.scale for p in parts])
            if ghost:
                cols = np.tile(_rgb8(COLORS["ghost"]), (k, 1))
                if shape != "mesh":
                    scales = np.maximum(scales - 2 * _GHOST_MARGIN, 0.5 * scales)
                style = dict(opacity=float(COLORS["ghost_alpha"]), cast_shadow=False, receive_shadow=False,
                             visible=self._show["ghosts"])
            else:
                cols = np.concatenate([_role_colors([p.color], i) for i, _, p in members])
                style = dict(visible=not self._show["collision_boxes"])
            handle = self.server.scene.add_batched_meshes_simple(
                f"{root}/{len(out)}", v, fc, np.tile([1.0, 0, 0, 0], (k, 1)), np.zeros((k, 3)),
                batched_scales=scales, batched_colors=cols, lod="off", flat_shading=shape == "box",
                side="double" if shape == "mesh" else "front", **style)
            moving = np.array([p.link != 0 for p in parts])
            out.append((handle, np.array([x[1] for x in members]), np.array([x[0] for x in members]), cols, moving))
        return out

    def _choose_azimuth(self, scenery) -> float:
        """The default camera's azimuth (degrees), chosen as coopsim.view.Scene chooses it: robots, scenery and
        bodies seen past each other (Scene.choose_azimuth, on a figure never drawn)."""
        from matplotlib.figure import Figure

        ax = Figure().add_subplot(projection="3d")
        frame = [(True, *r.shapes(self.sim.state(i)[0]), False) for i, r in enumerate(self.robots)]
        frame += [(False, P[None], H[None], True) for _, P, H in scenery]
        frame += [(False, np.asarray(self.sim.body_state(n).pose)[None],
                   np.asarray(self._world.body(n)["half_extents"])[None], False) for n in self._free_names]
        return Scene(ax, self.robots).choose_azimuth([frame])

    @staticmethod
    def _corners(poses, half):
        return box_corners(poses, half).reshape(-1, 3)

    def _split(self, rows) -> list:
        """A (sum k_i, ...) array cut into one part per robot."""
        ks = np.cumsum([len(r.boxes) for r in self.robots])[:-1]
        return np.split(rows, ks)

    def _set_camera(self, view: str, initial: bool = False) -> None:
        c, r = self._centre, self._radius
        if view == "top":
            pos, up = c + r * np.array([0.0, -0.3, 2.6]), (0.0, 0.0, 1.0)
        elif view == "side":
            pos, up = c + r * np.array([0.0, -2.4, 0.3]), (0.0, 0.0, 1.0)
        else:
            pos, up = self._camera_pose(view_direction(_ELEV, self._azim))[0], (0.0, 0.0, 1.0)
        if initial:
            self.server.initial_camera.position = tuple(pos)
            self.server.initial_camera.look_at = tuple(c)
            return
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.up_direction = up
                client.camera.position = tuple(pos)
                client.camera.look_at = tuple(c)

    def _snapshot(self) -> Frame:
        sim = self.sim
        f = Frame()
        f.t, f.steps = sim.time, sim.steps
        f.q, f.qd, f.q_ref, f.poses, f.half, f.ghost, f.parts, f.ghost_parts = [], [], [], [], [], [], [], []
        refs = sim.references
        for i, r in enumerate(self.robots):
            q, qd = sim.state(i)
            q_ref = refs[i].evaluate(f.t)[0]
            P, H = r.shapes(np.vstack([q, q_ref]))       # one engine call: the boxes at q and at q_ref
            f.q.append(q)
            f.qd.append(qd)
            f.q_ref.append(q_ref)
            f.poses.append(P[0])
            f.ghost.append(P[1])
            f.half.append(H)
            f.parts.append(part_poses(r, self._parts[i], q))
            f.ghost_parts.append(part_poses(r, self._parts[i], q_ref))
        f.holding = holding_now(sim, mode=self._holding_mode) if self.robots else []
        f.bodies = {n: np.asarray(sim.body_state(n).pose) for n in self._free_names}
        need = self._world is not None and (self._show["collision_boxes"] or self._show["contact_lines"])
        contacts = sim.contacts() if need else []
        f.colliding = colliding_from_contacts(contacts, self.robots, self.labels)
        f.lines = contact_lines(contacts)
        return f

    def _robot_colours(self, f: Frame) -> np.ndarray:
        cols = []
        ok, bad, hold = _rgb8(COLORS["free"]), _rgb8(COLORS["colliding"]), _rgb8(COLORS["holding"])
        for i in range(len(self.robots)):
            if self._show["collision_boxes"]:
                c = np.where(f.colliding[i][:, None], bad, ok)
            else:
                c = self._colors[i].copy()
                if f.holding[i]:
                    c[self._moving[i]] = hold
            cols.append(c)
        return np.concatenate(cols).astype(np.uint8)

    def _draw(self, f: Frame) -> None:
        now = time.perf_counter()
        # nothing new to show (paused, or past the end): the scene is left as it is, the panels go on
        key = (f.steps, self._changes, tuple(self._show.values()))
        same, self._shown = key == self._shown, key
        with self._lock, self.server.atomic():
            if not same:
                self._draw_scene(f)
            self._supervise(f, now)
            if not same:
                self._plots(f, now)
            if now - self._last_table >= _TABLE_EVERY:
                self._last_table = now
                self._table.content = self._table_text()
        self.frame = f
        self.frames += 1

    def _draw_scene(self, f: Frame) -> None:
        # the collision boxes while they are shown (and in the first frame), else the parts
        if self._robot_mesh is not None and (self._show["collision_boxes"] or self.frame is None):
            P = np.concatenate(f.poses)
            self._robot_mesh.batched_positions = P[:, :3, 3]
            self._robot_mesh.batched_wxyzs = quaternions(P[:, :3, :3])
            cols = self._robot_colours(f)
            if self.frame is None or not np.array_equal(cols, self._robot_mesh.batched_colors):
                self._robot_mesh.batched_colors = cols
        if self._robot_mesh is not None and (not self._show["collision_boxes"] or self.frame is None):
            hold = _rgb8(COLORS["holding"])
            every = np.concatenate(f.parts)
            holding = np.array(f.holding, dtype=bool)
            for handle, index, robot, cols, moving in self._part_meshes:
                P = every[index]
                handle.batched_positions = P[:, :3, 3]
                handle.batched_wxyzs = quaternions(P[:, :3, :3])
                c = cols.copy()
                c[holding[robot] & moving] = hold
                if self.frame is None or not np.array_equal(c, handle.batched_colors):
                    handle.batched_colors = c
        if self._robot_mesh is not None:
            if self._show["ghosts"]:
                every = np.concatenate(f.ghost_parts)
                for handle, index, *_ in self._ghost_meshes:
                    G = every[index]
                    handle.batched_positions = G[:, :3, 3]
                    handle.batched_wxyzs = quaternions(G[:, :3, :3])
        if self._body_mesh is not None:
            B = np.array([f.bodies[n] for n in self._free_names])
            self._body_mesh.batched_positions = B[:, :3, 3]
            self._body_mesh.batched_wxyzs = quaternions(B[:, :3, :3])
            if self._show["labels"]:
                for node, n in zip(self._label_nodes[len(self.robots):], self._free_names):
                    node.position = B[self._free_names.index(n), :3, 3] + np.array([0, 0, 0.05])
        show_lines = self._show["contact_lines"] and len(f.lines) > 0
        if show_lines:
            seg = np.stack([f.lines[:, 0], f.lines[:, 0] + _CONTACT_LENGTH * f.lines[:, 1]], axis=1)
            self._lines.points = seg.astype(np.float32)
        if self._lines.visible != show_lines:
            self._lines.visible = show_lines

    def _rescale(self) -> None:
        """The robots' drawn boxes and parts at their sizes now (after a robot was replaced)."""
        self._half = np.concatenate([r.shapes(self.sim.state(i)[0])[1] for i, r in enumerate(self.robots)])
        if self._robot_mesh is not None:
            self._robot_mesh.batched_scales = 2 * self._half
            self._parts = [robot_parts(r) for r in self.robots]
            self._build_parts()
        # the floor and the camera's framing follow the new size (the pages' cameras moved to it)
        self._fit_scene()
        self._set_camera("perspective")


def _segment_hits_boxes(a, b, poses, half) -> bool:
    """Whether the segment a -> b (3,) passes through any of the boxes (poses (k, 4, 4), half extents (k, 3))
    but those that hold b (the target's own), its last 2 % left out (the target's surface)."""
    R, c = poses[:, :3, :3], poses[:, :3, 3]
    p = np.einsum("kji,kj->ki", R, a - c)          # the segment in each box's frame
    q = np.einsum("kji,kj->ki", R, b - c)
    others = ~np.all(np.abs(q) <= half + 1e-9, axis=1)
    R, c, p, q, half = R[others], c[others], p[others], q[others], half[others]
    d = q - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - p) / d, (half - p) / d
    lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
    inside = np.abs(p) <= half                     # parallel to a slab: inside it or never
    lo = np.where(d == 0, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(d == 0, np.where(inside, np.inf, -np.inf), hi)
    enter, leave = np.max(lo, axis=1), np.min(hi, axis=1)
    return bool(np.any((enter <= leave) & (leave >= 0.0) & (enter <= 0.98)))
