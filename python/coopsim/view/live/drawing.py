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
        # everything in view: boxes of robots and world at the start, the floor under them
        pts = [self._corners(*r.shapes(self.sim.state(i)[0])) for i, r in enumerate(self.robots)]
        pts += [part_corners(p, part_poses(r, p, self.sim.state(i)[0])) for i, (r, p) in
                enumerate(zip(self.robots, self._parts)) if p]
        scenery = []
        if world is not None:
            for name in world.body_names:
                d = world.body(name)
                if d["kind"] == "static":
                    scenery.append((name, np.array(d["pose"]), np.array(d["half_extents"])))
                    pts.append(self._corners(np.array(d["pose"])[None], np.array(d["half_extents"])[None]))
                elif d["kind"] == "free":
                    pts.append(self._corners(np.array(self.sim.body_state(name)["pose"])[None],
                                             np.array(d["half_extents"])[None]))
        pts = np.concatenate(pts) if pts else np.zeros((1, 3))
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self._centre = 0.5 * (lo + hi)
        self._radius = max(0.3, float(np.linalg.norm(hi - lo)) / 2)
        self._azim = self._choose_azimuth(scenery)
        size = max(hi[0] - lo[0], hi[1] - lo[1]) + 0.6
        floor = world is None or world.floor
        # the environment's light at a little under half: the paper's colours stay recognisable
        sc.configure_environment_map("warehouse", environment_intensity=_ENVIRONMENT)
        if floor:
            sc.add_box("/floor", color=_rgb8(COLORS["floor"][0]), dimensions=(size, size, 0.01),
                       position=(self._centre[0], self._centre[1], -0.005), cast_shadow=False)
            sc.add_grid("/floor/grid", width=size, height=size, cell_size=0.1, section_size=0.5,
                        cell_color=_rgb8(COLORS["floor"][1]), position=(0.0, 0.0, 0.0051), shadow_opacity=0.0)
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
            self._label_nodes.append(sc.add_label(f"/labels/{n}", n, position=self.sim.body_state(n)["position"],
                                                  visible=self._show["labels"]))
        self._set_camera("perspective", initial=True)

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
        frame += [(False, np.asarray(self.sim.body_state(n)["pose"])[None],
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
            pos, up = c + 2.1 * r * view_direction(DEFAULT_ELEV + 8.0, self._azim), (0.0, 0.0, 1.0)
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
        f.bodies = {n: np.asarray(sim.body_state(n)["pose"]) for n in self._free_names}
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
