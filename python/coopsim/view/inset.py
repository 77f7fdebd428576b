"""The scene's inset: a zoom on the held body and the clamps holding it, a second scene of the same robots
and bodies in a framed 3D Axes in the upper right or left (whichever hides fewer boxes), hidden while nothing
is held; a mixin of :class:`~coopsim.view.scene.Scene`."""
from __future__ import annotations

import numpy as np

from .geometry import box_corners

#: The inset's places in the figure (x0, y0, width, height, figure fractions): the upper right or the upper left,
#: whichever covers fewer of the scene's boxes when it first shows.
INSET_PLACES = ((0.60, 0.47, 0.38, 0.43), (0.02, 0.47, 0.38, 0.43))


class _Inset:
    """The zoom on the held body (a mixin of Scene; ``Scene(..., inset=True)``)."""

    def _make_inset(self, **options) -> None:
        """The inset: a second scene of the same robots and bodies in a framed Axes at INSET_PLACES, seen from the
        same camera (orthographic), its limits framing the held body and the clamps that hold it."""
        from matplotlib.patches import Rectangle  # matplotlib loads only to draw

        x0, y0, w, h = INSET_PLACES[0]
        iax = self.fig.add_axes((x0, y0, w, h), projection="3d", zorder=2)
        iax.patch.set_alpha(0.0)
        # over the scene's boxes (drawn unclipped), under the inset's
        self.inset_frame = Rectangle((x0, y0), w, h, transform=self.fig.transFigure, facecolor="white",
                                     edgecolor="#444444", linewidth=1.0, zorder=1.5)
        self.fig.add_artist(self.inset_frame)
        self.inset_label = self.fig.text(x0 + 0.01, y0 + h - 0.01, "", va="top", ha="left", fontsize=7.5, zorder=4,
                                         bbox=dict(boxstyle="square,pad=0.2", fc="white", ec="none", alpha=0.85))
        self._inset_placed = False
        self.inset = type(self)(iax, self.robots, floor=False, axis=False, triad=False, names=False,
                           _inset_of=self, **options)
        self.inset._fitted = True
        self._show_inset(False)

    def _show_inset(self, visible: bool) -> None:
        for a in (self.inset.ax, self.inset_frame, self.inset_label):
            a.set_visible(visible)

    def _place_inset(self) -> None:
        """Moves the inset to the place of INSET_PLACES that covers the fewest of the scene's box corners."""
        from mpl_toolkits.mplot3d import proj3d  # matplotlib loads only to draw

        self._inset_placed = True
        pts = self._verts.reshape(-1, 3)
        if not len(pts):
            return
        self.ax.apply_aspect()
        x, y, _ = proj3d.proj_transform(pts[:, 0], pts[:, 1], pts[:, 2], self.ax.get_proj())
        f = self.fig.transFigure.inverted().transform(self.ax.transData.transform(np.column_stack([x, y])))
        inside = [int(np.sum((f[:, 0] >= x0) & (f[:, 0] <= x0 + w) & (f[:, 1] >= y0) & (f[:, 1] <= y0 + h)))
                  for x0, y0, w, h in INSET_PLACES]
        x0, y0, w, h = INSET_PLACES[int(np.argmin(inside))]
        self.inset.ax.set_position((x0, y0, w, h))
        self.inset_frame.set_bounds(x0, y0, w, h)
        self.inset_label.set_position((x0 + 0.01, y0 + h - 0.01))

    def held_points(self) -> np.ndarray:
        """The corners (m, 3) m of what the inset frames: every held body's boxes and the clamp boxes (links from
        the clamp's fixed link on) of the robots holding it; empty when nothing is held."""
        pts = []
        for i, name in enumerate(self._held):
            if not name or name not in self._body_names:
                continue
            half, poses, _ = self._bodies[self._body_names.index(name)]
            pts.append(box_corners(poses, half).reshape(-1, 3))
            r = self.robots[i]
            first = r.clamp.fixed_link if r.clamp is not None else r.dof
            poses_r, half_r = r.shapes(self._q[i])
            on = np.array([b.link >= first for b in r.boxes], dtype=bool)
            pts.append(box_corners(poses_r[on], half_r[on]).reshape(-1, 3))
        return np.concatenate(pts) if pts else np.zeros((0, 3))

    def _update_inset(self, changed: dict) -> None:
        """The inset shows what the scene shows, framed on the held body and its clamps (hidden when nothing is
        held): a cube 1.3 times the larger of their extents (at least 6 cm), centred on them."""
        pts = self.held_points()
        self._show_inset(bool(len(pts)))
        if not len(pts):
            return
        inset = self.inset
        if not self._inset_placed:
            self._place_inset()
        inset.ax.view_init(elev=self.ax.elev, azim=self.ax.azim)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        side = max(1.3 * float((hi - lo).max()), 0.06)
        c = (lo + hi) / 2
        inset._limits = np.column_stack([c - side / 2, c + side / 2])
        inset._given_limits = inset._limits
        for set_lim, (a, b) in zip((inset.ax.set_xlim, inset.ax.set_ylim, inset.ax.set_zlim), inset._limits):
            set_lim(a, b)
        inset.ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.25)
        inset.update(**changed)
        holders = [self.robots[i].name or f"robot {i}" for i, n in enumerate(self._held) if n]
        bodies = sorted({n for n in self._held if n})
        self.inset_label.set_text(f"zoom: {', '.join(bodies)} held by {' and '.join(holders)} "
                                  f"(a {side * 100:.0f} cm cube)")
