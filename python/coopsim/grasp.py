"""Load sharing between holders of one body: the grasp matrix, the least-norm split of a desired body
wrench, and the internal wrench of a multiple hold (Walker's and Uchiyama's formulations).

Wrenches are [fx, fy, fz, mx, my, mz] (N, N m) in the world frame; each holder acts on the body at a
point p_k (m, world). The grasp matrix G (6, 6k) maps the holders' wrenches to the net wrench about the
body's reference point c: w = sum_k [f_k; m_k + (p_k - c) x f_k] = G [w_1; ...; w_k]. Any set of holder
wrenches splits into a share of the net wrench, G# w, and an internal part in G's null space that
squeezes, twists or bends the body without moving it. Which share G# is depends on a metric (``metric``):

- ``"euclidean"``: the Moore-Penrose pseudo-inverse, least sum_k |f_k|^2 + |m_k|^2 in N and N m. It mixes
  units (scaling metres changes it), and holders at different distances from c that share the weight by
  the lever rule show a vertical internal force: it would rather carry part of the weight by moments.
- ``"forces"``: least sum_k |f_k|^2 + lambda^2 |m_k|^2 in the limit lambda -> infinity: the holders' forces
  carry all that forces at their points can, and moments only the rest (for two holders, the moment
  about the line between them). Two pins holding a body at rest carry no internal wrench however
  unevenly they share its weight. Computed as that limit, lexicographically: the least moments that
  make the rest reachable by forces, then the least forces.

The engine computes the two-holder case per log row in closed form (``SimulationLog.cooperation``,
``Simulation.cooperation``, with the ``"forces"`` metric; docs/world-and-grasp.md): these functions are
its independent reference. In the simulation each weld acts at its own point: midway between the
centres of its clamp's two pads when it grasped, fixed from then on in the clamp's link and in the body.
``sim.weld_wrench(i)`` and the log's ``weld`` columns are that weld's force on the body and its moment
about that point; the cooperation columns give the points.
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


_METRICS = ("euclidean", "forces")


def _share(G: np.ndarray, w: np.ndarray, metric: str) -> np.ndarray:
    """Holders' wrenches (6k,) with G h = w (when reachable), least in `metric`."""
    if metric == "euclidean":
        return np.linalg.pinv(G) @ w
    forces = np.zeros(G.shape[1], dtype=bool)
    for k in range(G.shape[1] // 6):
        forces[6 * k:6 * k + 3] = True
    Gf, Gm = G[:, forces], G[:, ~forces]
    Gf_pinv = np.linalg.pinv(Gf, rcond=1e-10)
    Q = np.eye(6) - Gf @ Gf_pinv  # what forces at the points cannot give
    m = np.linalg.pinv(Q @ Gm, rcond=1e-10) @ (Q @ w)
    h = np.zeros(G.shape[1])
    h[~forces] = m
    h[forces] = Gf_pinv @ (w - Gm @ m)
    return h


def _metric(metric) -> str:
    if not isinstance(metric, str) or metric not in _METRICS:
        raise ValueError(f"metric must be one of {list(_METRICS)}, got {metric!r}")
    return metric


def load_split(wrench, points, centre, internal=None, metric: str = "euclidean") -> np.ndarray:
    """The holders' wrenches (k, 6) that give the net body wrench `wrench` (6,) about `centre` with the
    least norm in `metric` ("euclidean" or "forces", see the module), plus an optional internal part
    (k, 6) projected onto G's null space (so it leaves the net wrench unchanged): the share a controller
    can command to its robots."""
    metric = _metric(metric)
    G = grasp_matrix(points, centre)
    w = _array(wrench, "wrench", _MAX_WRENCH, "N, N m")
    if w.shape != (6,):
        raise ValueError(f"wrong shape for wrench: expected (6,), got {w.shape}")
    f = _share(G, w, metric)
    if internal is not None:
        e = _array(internal, "internal", _MAX_WRENCH, "N, N m")
        if e.shape not in ((G.shape[1] // 6, 6), (G.shape[1],)):
            raise ValueError(f"wrong shape for internal: expected ({G.shape[1] // 6}, 6), got {e.shape}")
        e = e.reshape(-1)
        f = f + e - _share(G, G @ e, metric)
    return f.reshape(-1, 6)


def internal_wrenches(wrenches, points, centre, metric: str = "euclidean") -> np.ndarray:
    """The internal part (k, 6) of holders' wrenches (k, 6) applied at `points` (k, 3): what is left
    after taking out the share of their net wrench that is least in `metric` ("euclidean" or "forces",
    see the module); it sums to zero on the body (G of it is zero)."""
    metric = _metric(metric)
    G = grasp_matrix(points, centre)
    W = _array(wrenches, "wrenches", _MAX_WRENCH, "N, N m")
    if W.shape != (G.shape[1] // 6, 6):
        raise ValueError(f"wrong shape for wrenches: expected ({G.shape[1] // 6}, 6), got {W.shape}")
    f = W.reshape(-1)
    return (f - _share(G, G @ f, metric)).reshape(-1, 6)
