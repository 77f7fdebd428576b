"""Load sharing between holders of one body: the grasp matrix, the minimum-norm split of a desired
body wrench, and the internal wrench of a dual hold (Walker's and Uchiyama's formulations).

Wrenches are [fx, fy, fz, mx, my, mz] (N, N m) in the world frame; each holder acts on the body at a
point p_k (m, world). The grasp matrix G (6, 6k) maps the holders' wrenches to the net wrench about the
body's reference point c: w = sum_k [f_k; m_k + (p_k - c) x f_k] = G [w_1; ...; w_k]. Any set of holder
wrenches splits into the minimum-norm share of the net wrench, G^+ w, and an internal part in G's null
space that squeezes or twists the body without moving it.

In the simulation each weld acts at its own point: midway between the centres of its clamp's two pads
when it grasped (the fixed pad's centre moved by half the jaw opening along the jaw axis), fixed from
then on in the clamp's link and in the body. ``sim.weld_wrench(i)`` and the log's ``weld`` columns are
that weld's force on the body and its moment about that point. Two holders' points differ (in the
cooperative task #1 grips 0.075 m on one side of the bar's centre and #2 0.125 m on the other), so
with c the body's centre of mass G is not [I I] and the internal part is :func:`internal_wrenches` at
those points (the log does not keep them). ``SimulationLog.internal_wrench`` is not that: it takes +-(w_1 - w_2) / 2, which is the
internal part only when both welds act at one point; with the points apart it counts an uneven split of
the weight between the holders as internal.
"""
from __future__ import annotations

import numpy as np

__all__ = ["grasp_matrix", "internal_wrenches", "load_split"]


# bounds that keep every product finite: points within the world's extent (m), wrenches (N, N m)
_MAX_DISTANCE, _MAX_WRENCH = 1e6, 1e12


def _array(x, what: str, bound: float, unit: str) -> np.ndarray:
    """x as a float array: ValueError naming `what` for anything but real numbers within +-bound."""
    try:
        a = np.asarray(x)
        if a.dtype.kind not in "biuf":  # complex, text, objects: no silent cast
            raise TypeError
        a = a.astype(float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be an array of real numbers, got {type(x).__name__}") from None
    if not np.all(np.abs(a) <= bound):
        raise ValueError(f"{what} must be finite and within +-{bound:g} {unit}")
    return a


def _points(points, centre):
    P = _array(points, "points", _MAX_DISTANCE, "m")
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 1:
        raise ValueError(f"wrong shape for points: expected (k, 3) with k >= 1, got {np.shape(P)}")
    c = _array(centre, "centre", _MAX_DISTANCE, "m")
    if c.shape != (3,):
        raise ValueError(f"wrong shape for centre: expected (3,), got {c.shape}")
    return P, c


def grasp_matrix(points, centre) -> np.ndarray:
    """G (6, 6k): the net wrench about `centre` (3,) m of wrenches applied at `points` (k, 3) m."""
    P, c = _points(points, centre)
    G = np.zeros((6, 6 * len(P)))
    for k, p in enumerate(P):
        r = p - c
        G[:3, 6 * k:6 * k + 3] = np.eye(3)
        G[3:, 6 * k + 3:6 * k + 6] = np.eye(3)
        G[3:, 6 * k:6 * k + 3] = [[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]]
    return G


def load_split(wrench, points, centre, internal=None) -> np.ndarray:
    """The holders' wrenches (k, 6) that give the net body wrench `wrench` (6,) about `centre` with the
    least norm, plus an optional internal part (k, 6) projected onto G's null space (so it leaves the
    net wrench unchanged): the share a controller can command to its robots."""
    G = grasp_matrix(points, centre)
    w = _array(wrench, "wrench", _MAX_WRENCH, "N, N m")
    if w.shape != (6,):
        raise ValueError(f"wrong shape for wrench: expected (6,), got {w.shape}")
    Gp = np.linalg.pinv(G)
    f = Gp @ w
    if internal is not None:
        e = _array(internal, "internal", _MAX_WRENCH, "N, N m")
        if e.shape not in ((G.shape[1] // 6, 6), (G.shape[1],)):
            raise ValueError(f"wrong shape for internal: expected ({G.shape[1] // 6}, 6), got {e.shape}")
        f = f + (np.eye(G.shape[1]) - Gp @ G) @ e.reshape(-1)
    return f.reshape(-1, 6)


def internal_wrenches(wrenches, points, centre) -> np.ndarray:
    """The internal part (k, 6) of holders' wrenches (k, 6) applied at `points` (k, 3): what is left
    after taking out the minimum-norm share of their net wrench; it sums to zero on the body."""
    G = grasp_matrix(points, centre)
    W = _array(wrenches, "wrenches", _MAX_WRENCH, "N, N m")
    if W.shape != (G.shape[1] // 6, 6):
        raise ValueError(f"wrong shape for wrenches: expected ({G.shape[1] // 6}, 6), got {W.shape}")
    f = W.reshape(-1)
    return (f - np.linalg.pinv(G) @ (G @ f)).reshape(-1, 6)
