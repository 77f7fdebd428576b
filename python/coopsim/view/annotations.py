"""What the scene writes beside its boxes: the world's x, y, z axes with their scale, the robots' names at their
bases, and the inclines among the scenery (:func:`inclines`) with their slopes over a dashed level line; a mixin
of :class:`~coopsim.view.scene.Scene`."""
from __future__ import annotations

from typing import List

import numpy as np

from .bodies import COLORS
from .geometry import box_corners, box_faces, view_direction

#: A scenery box whose longest axis rises more than this (degrees) from level, and less than 90 minus this, is
#: an incline: the default camera looks at its side, and a label gives its slope.
INCLINE_MIN = 2.0


def inclines(items) -> List[dict]:
    """The inclines among scenery boxes: items are (name, poses (k, 4, 4), half extents (k, 3)); boxes with the
    same orientation (a tube's walls) are one incline. Per incline a dict: names, slope (degrees, of the
    longest axis from level), axis (3,) the unit longest axis pointing downhill, top (3,) m the highest corner."""
    out = []
    for name, poses, half in items:
        for T, h in zip(np.asarray(poses, float).reshape(-1, 4, 4), np.asarray(half, float).reshape(-1, 3)):
            a = T[:3, int(np.argmax(h))]
            a = -a if a[2] > 0 else a
            slope = float(np.degrees(np.arcsin(min(1.0, abs(a[2])))))
            if not INCLINE_MIN < slope < 90.0 - INCLINE_MIN:
                continue
            top = box_corners(T[None], h[None])[0]
            top = top[np.argmax(top[:, 2])]
            for inc in out:
                if np.allclose(inc["rotation"], T[:3, :3], atol=1e-9):
                    inc["names"].append(name) if name not in inc["names"] else None
                    inc["top"] = top if top[2] > inc["top"][2] else inc["top"]
                    inc["size"] += float(np.prod(h))
                    break
            else:
                out.append(dict(names=[name], slope=slope, axis=a, top=top, rotation=T[:3, :3].copy(),
                                size=float(np.prod(h))))
    return out


class _Annotations:
    """The scene's axes, robot names and incline labels (a mixin of Scene)."""

    #: lengths (m) the world's axes may have: the largest below a fifth of the floor's (or the view's) smaller side
    SCALES = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)

    def _place_triad(self) -> None:
        """The world's x, y, z axes (red, green, blue) from the floor's corner nearest the camera's left, each
        ``scale`` m long, labelled, with the scale written beside them."""
        for t in self.triad_labels:
            t.remove()
        self.triad_labels = []
        self.triad_segments = np.zeros((0, 2, 3))
        if not self._show_triad or self._limits is None:
            self.triad.set_segments(self.triad_segments)
            return
        ext = self.floor_extent or (*self._limits[0], *self._limits[1])
        side = min(ext[1] - ext[0], ext[3] - ext[2])
        self.scale = max([s for s in self.SCALES if s <= side / 5] or [self.SCALES[0]])
        o = np.array([ext[0], ext[2], 0.0]) + 0.25 * self.scale
        L = self.scale
        ends = o + L * np.eye(3)
        self.triad_segments = np.stack([np.tile(o, (3, 1)), ends], axis=1)    # (3, 2, 3) m: x, y, z
        self.triad.set_segments(self.triad_segments)
        for name, e in zip("xyz", ends):
            self.triad_labels.append(self.ax.text(*(e + 0.12 * L * (e - o) / L), name, fontsize=8, ha="center",
                                                  va="center", zorder=4))
        text = f"{L * 100:g} cm" if L < 0.1 else f"{L:g} m"
        self.triad_labels.append(self.ax.text(*(o + np.array([0.0, 0.0, 1.45 * L])), f"axes {text}", fontsize=7,
                                              ha="center", va="bottom", zorder=4, color="#333333"))

    def _name_robots(self) -> None:
        """Each robot's name on the floor at the foot of its base (its boxes on link 0), on the camera's side,
        framed in its links' colour; drawn over the floor and under the boxes, so that it hides nothing."""
        for t in self.names:
            t.remove()
        self.names = []
        if not self._show_names:
            return
        for i, r in enumerate(self.robots):
            poses, half = r.shapes(self._q[i])
            base = [j for j, b in enumerate(r.boxes) if b.link == 0] or list(range(len(r.boxes)))
            pts = box_faces(poses[base], half[base]).reshape(-1, 3)
            centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
            towards = view_direction(self.ax.elev, self.ax.azim)[:2]
            towards = towards / max(np.linalg.norm(towards), 1e-12)
            reach = float(np.abs((pts[:, :2] - centre[:2]) @ towards).max())     # the base's half width that way
            x, y = centre[:2] + (reach + 0.06) * towards
            label = r.name or f"robot {i}"
            colour = COLORS["robots"][i % len(COLORS["robots"])]
            self.names.append(self.ax.text(x, y, 0.0, label, fontsize=8, ha="center",
                                           va="center", zorder=0.9, fontweight="bold",
                                           bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=colour, lw=1.2,
                                                     alpha=0.8)))

    def label_inclines(self) -> None:
        """Finds the inclines among the scenery bodies (:func:`inclines`) and writes each one's slope over its
        top, with a dashed level line from the top along its axis in plan view, the slope's run: the incline
        shows its angle against it. The scene's first fit calls it; the camera looks at an incline's side
        (:meth:`choose_azimuth`)."""
        for t in self.incline_labels:
            t.remove()
        self.incline_labels = []
        items = [(name, poses, half) for (half, poses, _), name, scenery
                 in zip(self._bodies, self._body_names, self._body_scenery) if scenery and poses.ndim == 3]
        self.inclines = [{k: v for k, v in inc.items() if k != "rotation"} for inc in inclines(items)]
        segments = []
        for inc in self.inclines:
            names = [n for n in inc["names"] if n in self._body_names]
            corners = np.concatenate([box_corners(*self._bodies[self._body_names.index(n)][1::-1]).reshape(-1, 3)
                                      for n in names])
            a = inc["axis"]
            run = float(np.ptp(corners @ (np.array([a[0], a[1], 0.0]) / max(np.hypot(a[0], a[1]), 1e-12))))
            top = inc["top"]
            segments.append([top, top + run * np.array([a[0], a[1], 0.0]) / max(np.hypot(a[0], a[1]), 1e-12)])
            if self._show_names and self._inset_of is None:
                self.incline_labels.append(self.ax.text(*(top + [0.0, 0.0, 0.04]), f"{inc['slope']:.0f}° incline",
                                                        fontsize=8, ha="center", va="bottom", zorder=4,
                                                        color="#222222"))
        self.level_segments = np.array(segments).reshape(-1, 2, 3)     # (m, 2, 3) m
        self.levels.set_segments(self.level_segments)
