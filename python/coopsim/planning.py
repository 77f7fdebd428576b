"""Cartesian planning: tool poses with times -> inverse kinematics -> cubic
joint trajectory (paper section 7).

The paper samples the tool path at user-given poses, maps each through the
inverse kinematics and joins the joint via-points with cubic polynomials;
the more poses, the closer the tool follows the intended path between them.
``plan_cartesian`` does that in one call, keeping the elbow branch of the
first pose and unwrapping angles (each solution is the 2 pi k copy nearest the
previous one), and can insert straight-line intermediate poses.

Poses are (4, 4) homogeneous transforms of the tool centre point in the
world (what ``Robot.fk`` returns). Units: m, rad, s.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ._core import CubicTrajectory, IKError, Robot

__all__ = ["plan_cartesian", "clamp_pose", "interpolate_poses", "rotz"]


def rotz(angle: float) -> np.ndarray:
    """Rotation (3, 3) by `angle` rad about z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def clamp_pose(robot: Robot, position, yaw: float = 0.0, pitch: float | None = None) -> np.ndarray:
    """TCP pose (4, 4) of a SCARA clamp from its position, yaw and pitch.

    position: (3,) m in the world. yaw: rad about the world vertical,
    measured from the clamp orientation at q = 0 with the base unrotated (for
    both built-in SCARAs, yaw = 0 has the approach along world +x for robot #1
    at pitch 0 and the jaw axis along world +y for robot #2). pitch: SCARA #1
    only, theta5 in rad (0 horizontal, pi/2 pointing down; default 0).
    """
    kind = robot.ik_kind
    if kind is None:
        raise ValueError(f"clamp_pose needs a SCARA structure: {robot.ik_kind_reason()}")
    p = np.asarray(position, dtype=float)
    if p.shape != (3,):
        raise ValueError(f"wrong shape for position: expected (3,) m, got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"position must be finite (got {p.tolist()})")
    if not math.isfinite(yaw):
        raise ValueError("yaw must be finite")
    q = np.zeros(robot.dof)
    if kind == "scara1":
        pitch = 0.0 if pitch is None else float(pitch)
        if not math.isfinite(pitch):
            raise ValueError("pitch must be finite")
        q[4] = pitch
    elif pitch is not None:
        raise ValueError("pitch applies to SCARA #1 only: SCARA #2's clamp always points down")
    R_ref = robot.with_base(np.zeros(3), 0.0).fk(q)[:3, :3]
    T = np.eye(4)
    T[:3, :3] = rotz(yaw) @ R_ref
    T[:3, 3] = p
    return T


def _log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) of a rotation matrix (angle in [0, pi])."""
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s, c = 0.5 * np.linalg.norm(v), 0.5 * (np.trace(R) - 1.0)
    angle = math.atan2(s, c)
    if angle < 1e-9:
        return 0.5 * v
    if math.pi - angle < 1e-6:
        # near pi the skew part vanishes: axis from the symmetric part
        B = 0.5 * (R + np.eye(3))
        axis = B[:, int(np.argmax(np.diag(B)))]
        axis = axis / np.linalg.norm(axis)
        if np.dot(axis, v) < 0:
            axis = -axis
        return angle * axis
    return angle / (2.0 * math.sin(angle)) * v


def interpolate_poses(T0, T1, s, mode: str = "geodesic") -> np.ndarray:
    """Poses (len(s), 4, 4) on the straight line from T0 to T1, s in [0, 1].

    Position is linear in s. Orientation, by `mode`:
    - 'geodesic': along the shortest rotation (constant angular rate);
    - 'clamp': a yaw about the world vertical times a pitch about the tool's
      y axis (the jaw axis), each linear in s (shortest way round). These are
      the only rotations a SCARA clamp makes, so every pose on the way stays
      reachable, which a geodesic between two yawed and pitched clamp poses
      in general is not.
    s = 0 gives T0 and s = 1 gives T1 exactly.
    """
    T0, T1 = np.asarray(T0, dtype=float), np.asarray(T1, dtype=float)
    s = np.atleast_1d(np.asarray(s, dtype=float))
    if mode not in ("geodesic", "clamp"):
        raise ValueError(f"mode must be 'geodesic' or 'clamp', got {mode!r}")
    at0, at1 = s == 0.0, s == 1.0
    ends = at0 | at1
    if ends.all():      # the end poses themselves (plan_cartesian's knots without poses between)
        return np.where(at1[:, None, None], T1, T0)
    R0, R1 = T0[:3, :3], T1[:3, :3]
    if mode == "geodesic":
        w = _log_so3(R0.T @ R1)
        R = R0 @ _exp_so3_many(s[:, None] * w)
    elif mode == "clamp":
        # yaw: turn of the jaw axis about the vertical; pitch: what is left, about the jaw axis (the products
        # and sums on the jaw axes' components as floats: the same operations as on numpy's scalars)
        (a0, a1), (b0, b1) = R0[:2, 1].tolist(), R1[:2, 1].tolist()
        dpsi = math.atan2(a0 * b1 - a1 * b0, a0 * b0 + a1 * b1)
        M = R0.T @ rotz(-dpsi) @ R1
        dphi = math.atan2(M[0, 2], M[0, 0])
        R = _rotz_many(s * dpsi) @ R0 @ _roty_many(s * dphi)
    # all samples at once (one set of array operations, whatever their number)
    out = np.zeros((len(s), 4, 4))
    out[:, 3, 3] = 1.0
    out[:, :3, :3] = R
    out[:, :3, 3] = (1.0 - s)[:, None] * T0[:3, 3] + s[:, None] * T1[:3, 3]
    if ends.any():
        out[at0] = T0
        out[at1] = T1
    return out


def _rotz_many(a: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) by the angles a (N,) rad about z."""
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((len(a), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def _roty_many(a: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) by the angles a (N,) rad about y."""
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((len(a), 3, 3))
    R[:, 0, 0], R[:, 0, 2], R[:, 1, 1], R[:, 2, 0], R[:, 2, 2] = c, s, 1.0, -s, c
    return R


def _exp_so3_many(w: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) of the rotation vectors w (N, 3) (Rodrigues' formula)."""
    angle = np.linalg.norm(w, axis=1)
    small = angle < 1e-12
    k = w / np.where(small, 1.0, angle)[:, None]
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 0], K[:, 1, 2], K[:, 2, 0], K[:, 2, 1] = \
        -k[:, 2], k[:, 1], k[:, 2], -k[:, 0], -k[:, 1], k[:, 0]
    sa, ca = np.sin(angle)[:, None, None], (1.0 - np.cos(angle))[:, None, None]
    R = np.eye(3) + sa * K + ca * (K @ K)
    R[small] = np.eye(3)
    return R


#: the time laws of plan_cartesian: the fraction of a segment's way reached at the fraction tau of its time
_TIME_LAWS = {
    "uniform": lambda tau: tau,
    "cubic": lambda tau: tau * tau * (3.0 - 2.0 * tau),
    "quintic": lambda tau: tau ** 3 * (10.0 + tau * (-15.0 + 6.0 * tau)),
}


@functools.lru_cache(maxsize=64)
def _fractions(intermediate: int, time_law: str):
    """plan_cartesian's fractions of a segment's time at its knots, s (intermediate + 2,) evenly spaced in
    [0, 1], the fractions of the way there (the time law's), and 1 minus those (read-only arrays, made once)."""
    s = np.linspace(0.0, 1.0, intermediate + 2)
    way = _TIME_LAWS[time_law](s)
    rest = 1.0 - way
    for a in (s, way, rest):
        a.flags.writeable = False
    return s, way, rest


def _poses_arg(poses) -> np.ndarray:
    if isinstance(poses, (list, tuple)):
        for i, T in enumerate(poses):
            shape = T.shape if isinstance(T, np.ndarray) else np.shape(T)
            if shape != (4, 4):
                raise ValueError(f"wrong shape for poses[{i}]: expected (4, 4), got {shape}")
    try:
        P = np.asarray(poses, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("poses must be an (N, 4, 4) array of numbers") from None
    if P.ndim == 2:
        P = P[None]
    if P.ndim != 3 or P.shape[1:] != (4, 4):
        raise ValueError(f"wrong shape for poses: expected (N, 4, 4), got {np.shape(poses)}")
    if not np.isfinite(P).all():
        raise ValueError("poses must be finite (got NaN or inf)")
    return P


def plan_cartesian(robot: Robot, poses, times, *, opening=None, q_start=None, branch=None,
                   intermediate: int = 0, spline: bool = False, qd_start=None, qd_end=None,
                   method: str = "auto", keep_branch: bool = True, info: bool = False, time_law: str = "uniform",
                   **ik_options):
    """Joint trajectory whose tool passes through `poses` at `times`.

    robot: the Robot. poses: (N, 4, 4) TCP poses in the world, N >= 2.
    times: (N,) s, strictly increasing.
    opening: the clamp's jaw opening (m; d6 on the SCARAs), a scalar or (N,) one per pose
        (interpolated linearly for intermediate poses); default q_start's,
        else 0.
    q_start: (n,) configuration to start near (picks the first branch and the
        2 pi k copy of each angle); branch: +1 / -1 elbow branch for the first
        pose (closed-form IK). With keep_branch (default) every later pose
        uses the first pose's branch, so the elbow never flips on the way.
    intermediate: number of poses inserted on the straight line between
        consecutive given poses, at evenly spaced times (interpolate_poses:
        position linear; orientation 'clamp' for the SCARAs, else
        'geodesic'); more points, closer to the line.
    time_law: how the tool moves along each straight segment between given
        poses, through the fraction of the way s(tau) reached at the fraction
        tau of the segment's time (the intermediate poses are placed at
        s(tau) for evenly spaced tau): 'uniform' (s = tau), 'cubic'
        (3 tau^2 - 2 tau^3: starts and stops with zero speed) or 'quintic'
        (10 tau^3 - 15 tau^4 + 6 tau^5: zero speed and acceleration at both
        ends). With enough intermediate poses the tool's speed follows
        L s'(tau) / T for a segment of length L and duration T.
    spline, qd_start, qd_end: passed to CubicTrajectory (C2 spline instead
        of the averaged-slope rule; end velocities, default rest).
    method and further keywords (tol, weights, locked, restarts, ...) go to
        Robot.ik; each pose after the first is solved near the previous q.
    info: also return a dict with the knot times, poses and joint points.

    Returns a CubicTrajectory (and the dict when info). Raises IKError naming
    the pose that cannot be reached, ValueError on bad input.
    """
    P = _poses_arg(poses)
    # the engine checks the times
    t = CubicTrajectory(times, np.zeros(len(times) if isinstance(times, (list, tuple)) else np.shape(times)[:1])).times
    if len(P) != len(t):
        raise ValueError(f"poses and times must have the same length: got {len(P)} poses and {len(t)} times")
    if isinstance(intermediate, bool) or int(intermediate) != intermediate or intermediate < 0:
        raise ValueError(f"intermediate must be an integer >= 0, got {intermediate!r}")
    intermediate = int(intermediate)
    N = len(t)
    kind = robot.ik_kind
    mode = "clamp" if kind is not None else "geodesic"
    if opening is not None:
        if robot.clamp is None:
            raise ValueError(f"opening applies to a robot with a clamp; robot '{robot.name}' has none "
                             f"(cs.robots.add_clamp puts one on)")
        op = np.asarray(opening, dtype=float)
        if op.ndim == 0:
            op = np.full(N, op)
        if op.shape != (N,):
            raise ValueError(f"wrong shape for opening: expected a scalar or ({N},), got {op.shape}")
        if not np.isfinite(op).all():
            raise ValueError("opening must be finite")
    else:
        op = None
    if q_start is not None:
        q_start = np.asarray(q_start, dtype=float)
        if q_start.shape != (robot.dof,) or not np.isfinite(q_start).all():
            raise ValueError(f"wrong shape for q_start: expected ({robot.dof},) finite, got {q_start.shape}")

    # knots: the given poses plus straight-line poses between them, at evenly spaced times and at the
    # fractions of the way the time law gives
    if time_law not in _TIME_LAWS:
        raise ValueError(f"time_law must be one of {', '.join(map(repr, _TIME_LAWS))}, got {time_law!r}")
    # (segment k, knot j of it: t[k] + s_j (t[k+1] - t[k]), the opening (1 - w_j) op[k] + w_j op[k+1]), all
    # segments' knots at once, then the last pose's
    s, way, rest = _fractions(intermediate, time_law)
    K = (N - 1) * (intermediate + 1) + 1
    knot_t = np.empty(K)
    knot_t[:-1] = (t[:-1, None] + s[:-1] * (t[1:] - t[:-1])[:, None]).ravel()
    knot_t[-1] = t[-1]
    if intermediate == 0:
        knot_T = P.copy()
    else:
        knot_T = np.empty((K, 4, 4))
        for k in range(N - 1):
            knot_T[k * (intermediate + 1):(k + 1) * (intermediate + 1)] = interpolate_poses(P[k], P[k + 1], way[:-1],
                                                                                            mode)
        knot_T[-1] = P[-1]
    if op is None:
        knot_op = None
    else:
        knot_op = np.empty(K)
        knot_op[:-1] = (rest[:-1] * op[:-1, None] + way[:-1] * op[1:, None]).ravel()
        knot_op[-1] = op[-1]
    given = [j == 0 for _ in range(N - 1) for j in range(intermediate + 1)] + [True]

    analytic = kind is not None and method in ("auto", "analytic")
    if branch is not None and not analytic:
        raise ValueError("branch applies to the closed-form IK (SCARA robots, method 'auto' or 'analytic')")
    # every knot in one engine call: each solved near the one before; a numeric solver kept to the previous knot's
    # branch (no random restarts after the first) unless restarts are asked for
    local = not analytic and keep_branch and "restarts" not in ik_options
    options = dict(ik_options)
    restarts = options.pop("restarts", 10)
    Q, first_branch, failed, error = robot.ik_path(
        knot_T, openings=knot_op, q_start=q_start,
        branch=branch, method=method, keep_branch=keep_branch, restarts=restarts,
        later_restarts=0 if local else restarts, **options)
    if failed is not None:
        i = failed
        which = f"pose {given[:i + 1].count(True) - 1}" if given[i] else \
            f"the straight-line pose at t = {knot_t[i]:.6g} s"
        extra = f" on elbow branch {first_branch:+d}" if analytic and keep_branch and first_branch else ""
        hint = (" (solved from the previous knot only, to keep its branch: the path leaves that branch's reach; "
                "a solution on another branch would flip the arm between the knots. Move the path, add "
                "poses, or pass keep_branch=False to allow the jump)") if local and i > 0 else ""
        raise IKError(f"{which}{extra}: {error}{hint}")
    traj = CubicTrajectory(knot_t, Q, spline=spline, qd_start=qd_start, qd_end=qd_end)
    if info:
        return traj, dict(times=knot_t, poses=knot_T, q_points=Q,
                          given=np.array(given), branch=first_branch)
    return traj
