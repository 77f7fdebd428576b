"""Box geometry for the views: corners, faces, normals and flat shading (numpy only).

A box is a pose (4, 4), its centre and axes in the world, and half extents
(3,) m along its own x, y, z, as returned by ``Robot.shapes(q)``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CORNER_SIGNS", "FACE_CORNERS", "FACE_NORMALS", "box_corners", "box_faces", "box_normals",
           "box_samples", "hidden", "shade", "floor_tiles", "split_quads", "view_direction"]

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


def box_samples(poses, half_extents) -> np.ndarray:
    """Points (k * 15, 3) m that stand for k boxes when seen: each box's centre, 8 corners and 6 face
    centres, pulled 2 % towards the centre (so that a box lying on another is not hidden by it)."""
    poses = np.asarray(poses, dtype=float)
    h = 0.98 * np.asarray(half_extents, dtype=float)
    signs = np.concatenate([np.zeros((1, 3)), CORNER_SIGNS, FACE_NORMALS])              # (15, 3)
    local = signs[None, :, :] * h[:, None, :]
    return (np.einsum("kij,kcj->kci", poses[:, :3, :3], local) + poses[:, None, :3, 3]).reshape(-1, 3)


def hidden(points, direction, poses, half_extents, margin: float = 1e-3) -> np.ndarray:
    """(m,) bool: whether each point (m, 3) m is hidden behind one of the boxes (poses (k, 4, 4), half
    extents (k, 3)) when seen from far away along `direction` (3,), from the points towards the camera.

    A box hides a point when the ray from the point towards the camera enters it more than `margin` m
    away (a point inside a box, or on its surface, is not hidden by it). Parallel projection: the
    camera's perspective is left out.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    poses = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
    h = np.asarray(half_extents, dtype=float).reshape(-1, 3)
    if not len(p) or not len(poses):
        return np.zeros(len(p), dtype=bool)
    R, c = poses[:, :3, :3], poses[:, :3, 3]
    d = np.asarray(direction, dtype=float)
    pl = np.einsum("kji,mkj->mki", R, p[:, None, :] - c[None, :, :])      # (m, k, 3) in each box's axes
    dl = np.einsum("kji,j->ki", R, d)[None, :, :]                          # (1, k, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-h[None] - pl) / dl
        t2 = (h[None] - pl) / dl
    lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
    # along an axis the ray is parallel to: inside the slab for all s, or never
    par = np.broadcast_to(dl == 0.0, pl.shape)
    inside = np.abs(pl) <= h[None]
    lo = np.where(par, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(par, np.where(inside, np.inf, -np.inf), hi)
    t_in, t_out = lo.max(axis=2), hi.min(axis=2)
    return ((t_in > margin) & (t_out >= t_in)).any(axis=1)


def split_quads(quads, size: float):
    """Each parallelogram of quads (m, 4, 3) m (corners in order) cut into a grid of pieces no longer than
    `size` m along either edge. Returns (pieces (p, 4, 3), counts (m,), the pieces of each quad, in order).

    Big faces cut into pieces sort by depth with their neighbours piece by piece (matplotlib's painter's
    algorithm sorts whole polygons), so that a wall does not cover a box in front of part of it.
    """
    quads = np.asarray(quads, dtype=float).reshape(-1, 4, 3)
    u = quads[:, 1] - quads[:, 0]
    v = quads[:, 3] - quads[:, 0]
    nu = np.maximum(1, np.ceil(np.linalg.norm(u, axis=1) / size - 1e-9)).astype(int)
    nv = np.maximum(1, np.ceil(np.linalg.norm(v, axis=1) / size - 1e-9)).astype(int)
    pieces = []
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    for q, a, b, i_n, j_n in zip(quads, u, v, nu, nv):
        I, J = np.meshgrid(np.arange(i_n), np.arange(j_n), indexing="ij")
        s = (I.ravel()[:, None] + corners[None, :, 0]) / i_n            # (pieces, 4)
        t = (J.ravel()[:, None] + corners[None, :, 1]) / j_n
        pieces.append(q[0] + s[..., None] * a + t[..., None] * b)
    return (np.concatenate(pieces) if pieces else np.zeros((0, 4, 3))), nu * nv
