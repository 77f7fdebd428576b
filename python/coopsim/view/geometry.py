"""Box geometry for the views: corners, faces, normals and flat shading (numpy only).

A box is a pose (4, 4), its centre and axes in the world, and half extents
(3,) m along its own x, y, z, as returned by ``Robot.shapes(q)``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CORNER_SIGNS", "FACE_CORNERS", "FACE_NORMALS", "box_corners", "box_faces", "box_normals",
           "shade", "floor_tiles", "view_direction"]

#: Corner k of a box is centre + R @ (CORNER_SIGNS[k] * half_extents): the bottom ring 0-3, then the top ring 4-7,
#: each counter-clockwise seen from +z.
CORNER_SIGNS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                         [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
#: The six faces as corner indices, counter-clockwise seen from outside: -z, +z, -y, +x, +y, -x.
FACE_CORNERS = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
#: Outward normals of the six faces in the box's own axes.
FACE_NORMALS = np.array([[0, 0, -1], [0, 0, 1], [0, -1, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0]], dtype=float)


def box_corners(poses, half_extents) -> np.ndarray:
    """World corners (k, 8, 3) m of k boxes: poses (k, 4, 4), half_extents (k, 3) m."""
    poses = np.asarray(poses, dtype=float)
    h = np.asarray(half_extents, dtype=float)
    local = CORNER_SIGNS[None, :, :] * h[:, None, :]                       # (k, 8, 3)
    return np.einsum("kij,kcj->kci", poses[:, :3, :3], local) + poses[:, None, :3, 3]


def box_faces(poses, half_extents) -> np.ndarray:
    """Quadrilateral faces (k * 6, 4, 3) m of k boxes, box by box in FACE_CORNERS order."""
    return box_corners(poses, half_extents)[:, FACE_CORNERS, :].reshape(-1, 4, 3)


def box_normals(poses) -> np.ndarray:
    """World outward unit normals (k * 6, 3) of the faces of k boxes (poses (k, 4, 4)), as box_faces."""
    poses = np.asarray(poses, dtype=float)
    return np.einsum("kij,fj->kfi", poses[:, :3, :3], FACE_NORMALS).reshape(-1, 3)


def view_direction(elev: float, azim: float) -> np.ndarray:
    """Unit vector (3,) from the scene towards a camera at elevation `elev` and azimuth `azim` (degrees),
    matplotlib's convention."""
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def light_direction(elev: float, azim: float) -> np.ndarray:
    """A key light (3,) over the camera's left shoulder: from the camera, turned 40 deg left and 35 deg up."""
    return view_direction(min(elev + 35.0, 85.0), azim - 40.0)


def shade(rgba, normals, light, ambient: float = 0.45) -> np.ndarray:
    """Flat (Lambert) shading: rgb x (ambient + (1 - ambient) max(0, n . light)); alpha unchanged.

    rgba (m, 4) in 0..1, normals (m, 3) unit, light (3,) unit. Returns (m, 4).
    """
    out = np.array(rgba, dtype=float, copy=True)
    k = ambient + (1.0 - ambient) * np.clip(np.asarray(normals) @ light, 0.0, 1.0)
    out[:, :3] *= k[:, None]
    return out


def floor_tiles(x_range, y_range, tile: float, z: float = 0.0) -> np.ndarray:
    """Square tiles (m, 4, 3) covering [x0, x1] x [y0, y1] at height z, each `tile` m wide, row by row.

    The range is widened to whole tiles on a grid through the origin. Small tiles keep the floor behind
    the robots in matplotlib's depth sort (painter's algorithm sorts whole polygons).
    """
    x0, x1 = np.floor(x_range[0] / tile) * tile, np.ceil(x_range[1] / tile) * tile
    y0, y1 = np.floor(y_range[0] / tile) * tile, np.ceil(y_range[1] / tile) * tile
    xs = np.arange(x0, x1 - tile / 2, tile)
    ys = np.arange(y0, y1 - tile / 2, tile)
    X, Y = np.meshgrid(xs, ys)
    X, Y = X.ravel(), Y.ravel()
    quads = np.empty((len(X), 4, 3))
    for c, (dx, dy) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
        quads[:, c, 0] = X + dx * tile
        quads[:, c, 1] = Y + dy * tile
        quads[:, c, 2] = z
    return quads
