"""The scene's camera and framing: the default elevation and azimuth, the azimuth that shows robots and bodies
past each other (or an incline's side), the limits, box aspect and zoom that keep every box in the picture,
and where a world point lands in the image; a mixin of :class:`~coopsim.view.scene.Scene`."""
from __future__ import annotations

import numpy as np

from .annotations import inclines
from .bodies import COLORS, _array
from .checks import _rgba
from .geometry import box_corners, box_samples, floor_tiles, hidden, view_direction

#: The default camera (degrees, matplotlib's convention): from the front right, above the floor.
DEFAULT_ELEV = 22.0
DEFAULT_AZIM = -62.0


class _Camera:
    """The scene's camera, limits and zoom (a mixin of Scene)."""

    def choose_azimuth(self, frames) -> float:
        """Turns the camera, when the scene was made with azim=None, so that robots and bodies are seen
        past each other; returns the azimuth (degrees).

        frames: one or more arrangements of the scene (e.g. a few frames of
        an animation), each a list of (robot, poses (k, 4, 4), half extents
        (k, 3), scenery) tuples: robot True for a robot's boxes, False for
        a body's; scenery True for fixed surroundings (a world's static
        boxes).

        The preferred azimuth looks across low scenery (all of it below the
        robots' top) at the robots, from the robots' centre towards the
        scenery's in plan view, when it is away from them; else (no
        scenery, or tall scenery such as a wall, which stays behind the
        robots) DEFAULT_AZIM. With an incline among the scenery (a box tilted
        from level, :func:`inclines`; the largest if several), the preferred
        azimuth looks at the incline's side instead, square to its axis in
        plan view, so that its slope shows, and the search below stays within
        45 degrees of it. The score of an azimuth is the mean over the
        boxes of every frame of the square of the fraction of the box's
        sample points (:func:`~coopsim.view.geometry.box_samples`) hidden
        behind boxes of the other kind (bodies behind robots, robots behind
        bodies; a box out of sight weighs more than parts of several).
        From the preferred azimuth outwards in 7.5 degree steps either way,
        the first whose score is at most 0.02 wins (if none, the best).
        Without bodies, or with a given azim, the camera stays."""
        if not self._auto_azim:
            return float(self.ax.azim)
        frames = [[(bool(rb), np.asarray(p, float).reshape(-1, 4, 4), np.asarray(h, float).reshape(-1, 3), bool(sc))
                   for rb, p, h, sc in f] for f in frames]

        def stack(items):
            items = [(p, h) for p, h in items if len(h)]
            if not items:
                return np.zeros((0, 4, 4)), np.zeros((0, 3))
            return np.concatenate([p for p, _ in items]), np.concatenate([h for _, h in items])

        tests = []      # per frame and kind: its boxes' sample points, their count, the other kind's boxes
        for f in frames:
            robots = stack([(p, h) for rb, p, h, _ in f if rb])
            bodies = stack([(p, h) for rb, p, h, _ in f if not rb])
            if len(robots[1]) and len(bodies[1]):
                tests.append((box_samples(*bodies), len(bodies[1]), *robots))
                tests.append((box_samples(*robots), len(robots[1]), *bodies))
        preferred = DEFAULT_AZIM
        robot = stack([(p, h) for rb, p, h, _ in frames[0] if rb])
        scen = stack([(p, h) for rb, p, h, sc in frames[0] if sc and not rb])
        if len(robot[1]) and len(scen[1]):
            # low scenery (a container, a table) is looked across; tall scenery (a wall) stays behind
            low = box_corners(*scen)[..., 2].max() < box_corners(*robot)[..., 2].max()
            d = scen[0][:, :2, 3].mean(axis=0) - robot[0][:, :2, 3].mean(axis=0)
            if low and np.hypot(*d) > 0.1:
                preferred = float(np.degrees(np.arctan2(d[1], d[0])))
        steps = 24
        slopes = inclines([("", p, h) for rb, p, h, sc in frames[0] if sc and not rb])
        if slopes:
            # an incline is seen from its side, square to its axis in plan view (of the two sides, the one
            # nearer the camera's preferred direction), or its slope would not show: at most 45 degrees off
            a = max(slopes, key=lambda inc: inc["size"])["axis"]
            side = float(np.degrees(np.arctan2(a[0], -a[1])))
            preferred = min((side, side + 180.0), key=lambda x: abs((x - preferred + 180.0) % 360.0 - 180.0))
            steps = 6
        if not tests:
            if slopes:
                self.ax.view_init(elev=self.ax.elev, azim=(preferred + 180.0) % 360.0 - 180.0)
            return float(self.ax.azim)
        n_boxes = sum(t[1] for t in tests)
        elev = self.ax.elev
        candidates = preferred + 7.5 * np.array([0] + [s * k for k in range(1, steps + 1) for s in (1, -1)])

        def score(a):
            v = view_direction(elev, a)
            return sum((hidden(pts, v, OP, OH).reshape(k, 15).mean(axis=1) ** 2).sum()
                       for pts, k, OP, OH in tests) / n_boxes

        scores = []
        for a in candidates:
            scores.append(score(a))
            if scores[-1] <= 0.02:
                break
        best = float(candidates[len(scores) - 1] if scores[-1] <= 0.02 else candidates[int(np.argmin(scores))])
        best = (best + 180.0) % 360.0 - 180.0
        self.ax.view_init(elev=elev, azim=best)
        return best

    def fit(self, points) -> None:
        """Fixes the floor, the axis limits (equal scales) and the box aspect so that the points (m, 3) m
        are in view. The first update fits what it shows; an animation fits all its frames first."""
        corners = _array(points, "points").reshape(-1, 3)
        if not len(corners):
            raise ValueError("points must hold at least one point")
        self._fitted = True
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        if self._floor_given is not None:
            if isinstance(self._floor_given, str):
                pad = 1.5 * self.tile
                ext = (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)
            else:
                ext = tuple(self._floor_given)
            tiles = floor_tiles(ext[:2], ext[2:], self.tile)
            cols = [_rgba(c, "COLORS['floor']") for c in COLORS["floor"]]
            ij = np.round(tiles[:, 0, :2] / self.tile).astype(int).sum(axis=1) % 2
            self.floor.set_verts(tiles)
            self.floor.set_facecolor(np.array([cols[k] for k in ij]).reshape(-1, 4))
            lo = np.minimum(lo, [tiles[..., 0].min(), tiles[..., 1].min(), 0.0])
            hi = np.maximum(hi, [tiles[..., 0].max(), tiles[..., 1].max(), 0.0])
        if self._given_limits is None:
            self._limits = np.column_stack([lo - 0.02, hi + 0.02])
        L = self._limits
        self.ax.set_xlim(*L[0])
        self.ax.set_ylim(*L[1])
        self.ax.set_zlim(*L[2])
        self.ax.set_box_aspect(tuple(L[:, 1] - L[:, 0]), zoom=self._zoom)
        if self._zoom_auto:
            # no box out of the picture: zoom less where they would reach past its edges
            zoom = self._zoom
            for _ in range(3):
                reach = self._reach(corners)
                if reach <= 0.97:
                    break
                zoom *= 0.95 / reach
                self.ax.set_box_aspect(tuple(L[:, 1] - L[:, 0]), zoom=zoom)
            self._zoom_now = zoom
        else:
            self._zoom_now = self._zoom
        self._place_triad()
        self._name_robots()      # the bases (link 0) do not move: where they are with any q

    def _reach(self, points) -> float:
        """How far the points (m, 3) reach from the middle of the axes' place in the figure towards its edges,
        at most: 1 at an edge (the larger of x and y, as fractions of the half width and half height). A 3D
        Axes draws into a square, but its artists are not clipped: the place is the whole subplot."""
        from mpl_toolkits.mplot3d import proj3d  # matplotlib loads only to draw

        self.ax.apply_aspect()           # as drawing will: the square the Axes draws into
        x, y, _ = proj3d.proj_transform(points[:, 0], points[:, 1], points[:, 2], self.ax.get_proj())
        disp = self.ax.transData.transform(np.column_stack([x, y]))
        bb = self.ax.get_position(original=True).transformed(self.fig.transFigure)
        fx = np.abs(disp[:, 0] - (bb.x0 + bb.x1) / 2) / (bb.width / 2)
        fy = np.abs(disp[:, 1] - (bb.y0 + bb.y1) / 2) / (bb.height / 2)
        return float(max(fx.max(), fy.max()))

    def project(self, points) -> np.ndarray:
        """Pixel coordinates (m, 2) of world points (m, 3) m in the figure's image: x to the right, y down
        from the top-left corner, as in ``np.asarray(fig.canvas.buffer_rgba())[y, x]``. Draw the figure
        first (e.g. ``fig.canvas.draw()``) so that the layout is final."""
        from mpl_toolkits.mplot3d import proj3d  # matplotlib loads only to draw

        p = _array(points, "points").reshape(-1, 3)
        x, y, _ = proj3d.proj_transform(p[:, 0], p[:, 1], p[:, 2], self.ax.get_proj())
        disp = self.ax.transData.transform(np.column_stack([x, y]))
        h = self.fig.bbox.height
        return np.column_stack([disp[:, 0], h - disp[:, 1]])
