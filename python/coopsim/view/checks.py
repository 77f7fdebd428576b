"""The scene's arguments checked: per robot its joint vector, flag and box mask, contact points and normals,
bodies, colours (numbers: coopsim._checks); a bad one is a ValueError naming the argument."""
from __future__ import annotations

import numpy as np

from .bodies import Body, _array


def _per_robot_q(q, robots, what: str, allow_none: bool = False) -> list:
    """One (n_i,) float array per robot (or None where allowed) from q for one robot or a sequence."""
    n = len(robots)
    if q is None:
        if allow_none:
            return [None] * n
        raise ValueError(f"{what} must be given")
    if n == 1 and not (isinstance(q, (list, tuple)) and len(q) == 1 and (q[0] is None or np.ndim(q[0]) == 1)):
        items = [q]
    else:
        if isinstance(q, np.ndarray) and q.ndim != 2:
            raise ValueError(f"wrong shape for {what}: expected one (n,) array per robot for {n} robots, "
                             f"got {q.shape}")
        items = list(q)
        if len(items) != n:
            raise ValueError(f"{what} must hold one joint vector per robot ({n}), got {len(items)}")
    out = []
    for i, (x, r) in enumerate(zip(items, robots)):
        name = what if n == 1 else f"{what}[{i}]"
        if x is None and allow_none:
            out.append(None)
            continue
        a = _array(x, name)
        if a.shape != (r.dof,):
            raise ValueError(f"wrong shape for {name}: expected ({r.dof},), got {a.shape}")
        out.append(a)
    return out


def _per_robot_bool(x, robots, what: str) -> list:
    n = len(robots)
    if x is None or isinstance(x, (bool, np.bool_)):
        return [bool(x)] * n
    items = list(x) if isinstance(x, (list, tuple, np.ndarray)) else None
    if items is None or len(items) != n:
        raise ValueError(f"{what} must be a bool or one bool per robot ({n}), got {x!r}")
    out = []
    for i, v in enumerate(items):
        if not isinstance(v, (bool, np.bool_, int, np.integer)) or v not in (0, 1):
            raise ValueError(f"{what}[{i}] must be a bool, got {v!r}")
        out.append(bool(v))
    return out


def _per_robot_mask(x, robots, what: str) -> list:
    """One (k_i,) bool array per robot (k_i = its box count); None (for all or one robot) -> all False."""
    n = len(robots)
    ks = [len(r.boxes) for r in robots]
    if x is None:
        return [np.zeros(k, dtype=bool) for k in ks]
    if n == 1 and np.ndim(x) == 1 and not (isinstance(x, (list, tuple)) and len(x) == 1 and np.ndim(x[0]) == 1):
        items = [x]
    else:
        items = list(x)
        if len(items) != n:
            raise ValueError(f"{what} must hold one (boxes,) mask per robot ({n}), got {len(items)}")
    out = []
    for i, (m, k) in enumerate(zip(items, ks)):
        name = what if n == 1 else f"{what}[{i}]"
        if m is None:
            out.append(np.zeros(k, dtype=bool))
            continue
        a = np.asarray(m)
        if a.shape != (k,):
            raise ValueError(f"wrong shape for {name}: expected ({k},), one flag per box of robot {i}, got {a.shape}")
        if a.dtype != bool and not (np.issubdtype(a.dtype, np.integer) and np.isin(a, (0, 1)).all()):
            raise ValueError(f"{name} must be booleans, got dtype {a.dtype}")
        out.append(a.astype(bool))
    return out


def _contacts(x, what: str = "contacts") -> np.ndarray:
    """(m, 2, 3): contact points and unit normals."""
    if x is None:
        return np.zeros((0, 2, 3))
    if isinstance(x, (list, tuple)) and len(x) == 0:
        return np.zeros((0, 2, 3))
    a = _array(x, what)
    if a.ndim != 3 or a.shape[1:] != (2, 3):
        raise ValueError(f"wrong shape for {what}: expected (m, 2, 3), m pairs of (point, normal), got {a.shape}")
    norm = np.linalg.norm(a[:, 1], axis=1)
    if np.any(norm <= 0):
        raise ValueError(f"{what}: every normal must be non-zero")
    a = a.copy()
    a[:, 1] /= norm[:, None]
    return a


def _bodies(bodies, what: str = "bodies") -> list:
    if bodies is None:
        return []
    if isinstance(bodies, Body):
        bodies = [bodies]
    out = []
    for i, b in enumerate(bodies):
        if not isinstance(b, Body):
            raise ValueError(f"{what}[{i}] must be a coopsim.view.Body, got {type(b).__name__}")
        out.append(b._checked(f"{what}[{i}]"))
    return out


def _rgba(c, what: str) -> np.ndarray:
    from matplotlib.colors import to_rgba  # matplotlib loads only to draw

    try:
        return np.array(to_rgba(c))
    except (ValueError, TypeError):
        raise ValueError(f"{what}: not a matplotlib colour: {c!r}") from None


def _is_colour(c) -> bool:
    from matplotlib.colors import is_color_like  # matplotlib loads only to draw

    if isinstance(c, str):
        return is_color_like(c)
    return isinstance(c, tuple) and len(c) in (3, 4) and all(isinstance(v, (int, float)) for v in c)
