"""Load sharing between holders of one body: the grasp matrix, the minimum-norm split of a desired
body wrench, and the internal wrench of a dual hold (Walker's and Uchiyama's formulations).

Wrenches are [fx, fy, fz, mx, my, mz] (N, N m) in the world frame; each holder acts on the body at a
point p_k (m, world). The grasp matrix G (6, 6k) maps the holders' wrenches to the net wrench about the
body's reference point c: w = sum_k [f_k; m_k + (p_k - c) x f_k] = G [w_1; ...; w_k]. Any set of holder
wrenches splits into the minimum-norm share of the net wrench, G^+ w, and an internal part in G's null
space that squeezes or twists the body without moving it. In the simulation the welds act at the body's
centre of mass, so there c = p_k for every holder, G = [I I ...] and the internal part of two welds is
+-(w_1 - w_2) / 2.
"""
from __future__ import annotations

import numpy as np

__all__ = ["grasp_matrix", "internal_wrenches", "load_split"]


def _points(points, centre):
    P = np.asarray(points, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 1:
        raise ValueError(f"wrong shape for points: expected (k, 3) with k >= 1, got {np.shape(points)}")
    c = np.asarray(centre, dtype=float)
    if c.shape != (3,):
        raise ValueError(f"wrong shape for centre: expected (3,), got {c.shape}")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(c))):
        raise ValueError("points and centre must be finite")
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
    w = np.asarray(wrench, dtype=float)
    if w.shape != (6,) or not np.all(np.isfinite(w)):
        raise ValueError(f"wrench must be 6 finite numbers, got shape {w.shape}")
    Gp = np.linalg.pinv(G)
    f = Gp @ w
    if internal is not None:
        e = np.asarray(internal, dtype=float).reshape(-1)
        if e.shape != (G.shape[1],):
            raise ValueError(f"wrong shape for internal: expected ({len(G.T) // 6}, 6), got {np.shape(internal)}")
        f = f + (np.eye(G.shape[1]) - Gp @ G) @ e
    return f.reshape(-1, 6)


def internal_wrenches(wrenches, points, centre) -> np.ndarray:
    """The internal part (k, 6) of holders' wrenches (k, 6) applied at `points` (k, 3): what is left
    after taking out the minimum-norm share of their net wrench; it sums to zero on the body."""
    W = np.asarray(wrenches, dtype=float)
    G = grasp_matrix(points, centre)
    if W.shape != (G.shape[1] // 6, 6):
        raise ValueError(f"wrong shape for wrenches: expected ({G.shape[1] // 6}, 6), got {W.shape}")
    f = W.reshape(-1)
    return (f - np.linalg.pinv(G) @ (G @ f)).reshape(-1, 6)
