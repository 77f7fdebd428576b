"""The live page's shared values: constants, colours, quaternions (its fields' numbers: coopsim._checks)."""
from __future__ import annotations

import numpy as np

from ..parts import _box_role
from ..scene import COLORS

_HOST = "127.0.0.1"
_CONTACT_LENGTH = 0.04        # m, drawn length of a contact line
_GHOST_MARGIN = 0.002         # m, ghost parts this much smaller on each side (a robot on its reference hides its ghost)
_PLOT_EVERY = 0.1             # s of wall time between plot updates
_TABLE_EVERY = 0.5            # s of wall time between updates of the data table
_DIMENSION_FIELDS = (("L1", "L1 (m)"), ("L2", "L2 (m)"), ("L_base", "Base height (m)"))   # the built-in SCARAs'
_TABLE_ROWS = 8
_WINDOW = 1.0                 # s of wall time over which the supervision's rates are measured
_ENVIRONMENT = 0.15          # intensity of the environment map's lighting (viser's default 1 washes colours out)
_FOREVER = 1e7                # s: t_end of a run "until closed"
_GONE = 10.0                  # s: a held page ends when every page has been closed this long (a reload is shorter)

# a unit cube (side 1, centred) as 8 vertices and 12 outward triangles
_CUBE_V = np.array([[-.5, -.5, -.5], [.5, -.5, -.5], [.5, .5, -.5], [-.5, .5, -.5],
                    [-.5, -.5, .5], [.5, -.5, .5], [.5, .5, .5], [-.5, .5, .5]], dtype=np.float32)
_CUBE_F = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                    [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]], dtype=np.uint32)


def _rgb8(c) -> np.ndarray:
    from matplotlib.colors import to_rgb

    return np.round(np.array(to_rgb(c)) * 255).astype(np.uint8)


def quaternions(R) -> np.ndarray:
    """Unit quaternions (k, 4) [w, x, y, z] of rotation matrices (k, 3, 3) (Shepperd's method, w >= 0)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    tr = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    cand = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(cand, axis=1)
    q = np.empty((len(R), 4))
    for j in range(4):
        s = k == j
        if not s.any():
            continue
        m = R[s]
        if j == 0:
            r = np.sqrt(1.0 + tr[s]) * 2
            q[s] = np.column_stack([0.25 * r, (m[:, 2, 1] - m[:, 1, 2]) / r, (m[:, 0, 2] - m[:, 2, 0]) / r,
                                    (m[:, 1, 0] - m[:, 0, 1]) / r])
        else:
            a, b, c = j - 1, j % 3, (j + 1) % 3
            r = np.sqrt(1.0 + m[:, a, a] - m[:, b, b] - m[:, c, c]) * 2
            v = np.empty((s.sum(), 4))
            v[:, 0] = (m[:, c, b] - m[:, b, c]) / r
            v[:, 1 + a] = 0.25 * r
            v[:, 1 + b] = (m[:, b, a] + m[:, a, b]) / r
            v[:, 1 + c] = (m[:, c, a] + m[:, a, c]) / r
            q[s] = v
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _rotation(wxyz) -> np.ndarray:
    w, x, y, z = np.asarray(wxyz, dtype=float) / np.linalg.norm(wxyz)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _role_colors(roles, i: int) -> np.ndarray:
    """(k, 3) uint8: robot i's colours of parts or boxes by their colour name ('robot', 'base', 'jaw')."""
    c = {"robot": _rgb8(COLORS["robots"][i % len(COLORS["robots"])]), "base": _rgb8(COLORS["base"]),
         "jaw": _rgb8(COLORS["jaw"])}
    return np.array([c[x] for x in roles], dtype=np.uint8).reshape(-1, 3)


def _robot_colors(robot, i: int) -> np.ndarray:
    """(k, 3) uint8: the normal colour of each of robot i's boxes (as coopsim.view.Scene: base columns,
    jaws, links in the robot's colour)."""
    return _role_colors([_box_role(robot, b) for b in robot.boxes], i)


