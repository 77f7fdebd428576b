"""A point-to-point motion of SCARA #1 planned under its torque limits: sequential quadratic programming on
the exact Jacobians of the integrator's steps (coopsim.linearize), each QP solved by OSQP.

The motion: from rest at q_start to rest at q_goal in T seconds, the torque held over N intervals of T/N
(each integrated by the engine's RK4 in steps of 0.2 ms). Each iteration rolls the torques out with
coopsim.integrate, linearises every interval along the rollout (A_k, B_k: the exact Jacobians of its RK4
steps), and solves for the change of the torques that minimises

    sum_k |tau_k|^2_R + |x_N - x_goal|^2_Qf     subject to  dx_{k+1} = A_k dx_k + B_k dtau_k,
                                                            |tau_k + dtau_k| <= tau_max,  |dtau_k| <= trust,

then takes that change when it lowers the cost of the real rollout (else halves the trust region). Writes
into --out: plan_under_torque_limits.png (joints and torques against time, the limits dashed).
"""
from __future__ import annotations

import argparse
import os

import numpy as np
import scipy.sparse as sp

import coopsim as cs

DT = 2e-4   # s, the engine's step


def rollout(robot, x0, taus, steps):
    """States (N + 1, 2n) at the intervals' ends under the torques taus (N, n), each held for `steps` steps."""
    n = robot.dof
    _, Q, QD = cs.integrate(robot, x0[:n], x0[n:], np.repeat(taus, steps, axis=0), DT, len(taus) * steps,
                            record_every=steps)
    return np.hstack([Q, QD])


def effort(taus, R):
    return float(np.einsum("ki,ij,kj->", taus, R, taus))


def merit(x_end, taus, x_goal, R, mu=1e3):
    """The effort plus mu times the end state's error (rad, rad/s; m, m/s): what an iteration must lower."""
    return effort(taus, R) + mu * float(np.abs(x_end - x_goal).sum())


def qp_step(models, taus, x_end, x_goal, R, tau_max, trust, mu=1e3):
    """The change of the torques (N, n) the QP gives, and OSQP's status: the least effort plus mu times the
    linearised end state's error (an exact penalty: zero error whenever the trust region allows it). The QP is condensed: the end state's change is G dtau, G = [Phi_1 B_0, ...,
    B_{N-1}] with Phi_k the product of the later intervals' A; its variables are the changes scaled by the
    limits (dtau / tau_max)."""
    import osqp

    N, n = taus.shape
    G = np.zeros((2 * n, N * n))
    Phi = np.eye(2 * n)
    for k in range(N - 1, -1, -1):
        G[:, k * n:(k + 1) * n] = Phi @ models[k].B
        Phi = Phi @ models[k].A
    S = np.tile(tau_max, N)                     # dtau = S v
    r = np.tile(np.diag(R), N) * S * S
    m = 2 * n                                   # slacks: G S v - s_plus + s_minus = e, s >= 0, cost mu |s|_1
    P = sp.block_diag([sp.diags(2 * r), sp.csc_matrix((2 * m, 2 * m))], format="csc")
    q = np.r_[2 * r * taus.ravel() / S, np.full(2 * m, mu)]
    A = sp.vstack([sp.hstack([sp.csc_matrix(G * S), -sp.eye(m), sp.eye(m)]),
                   sp.hstack([sp.eye(N * n), sp.csc_matrix((N * n, 2 * m))]),
                   sp.hstack([sp.csc_matrix((2 * m, N * n)), sp.eye(2 * m)])], format="csc")
    e = x_goal - x_end
    lo = np.r_[e, np.maximum(-1.0 - taus.ravel() / S, -trust), np.zeros(2 * m)]
    hi = np.r_[e, np.minimum(1.0 - taus.ravel() / S, trust), np.full(2 * m, np.inf)]
    solver = osqp.OSQP()
    solver.setup(P, q, A, lo, hi, verbose=False, eps_abs=1e-9, eps_rel=1e-9, max_iter=50000, polishing=True)
    res = solver.solve(raise_error=False)
    if res.x is None or not np.all(np.isfinite(res.x)):
        return np.zeros_like(taus), res.info.status
    return (S * res.x[:N * n]).reshape(N, n), res.info.status


def plan(robot=None, q_start=None, q_goal=None, T=0.35, N=20, iterations=25, tol=1e-6):
    """Plans the motion; returns dict(taus (N, n) N m or N, states (N + 1, 2n), times (N + 1,) s,
    merits (per accepted iteration), statuses (OSQP's), tau_max (n,), q_goal (n,)). Stops when the end
    state is within tol (rad, rad/s; m, m/s) of the goal and the effort no longer falls."""
    robot = robot or cs.robots.scara1()
    n = robot.dof
    q_start = np.array([0.0, 0.3, 0.1, 0.0, np.pi / 2, 0.02]) if q_start is None else q_start
    q_goal = np.array([1.2, -0.6, 0.1, 0.5, np.pi / 2, 0.02]) if q_goal is None else q_goal
    steps = int(round(T / N / DT))
    x0, x_goal = np.r_[q_start, np.zeros(n)], np.r_[q_goal, np.zeros(n)]
    tau_max = np.asarray(robot.tau_limits, float)
    R = np.diag(1.0 / tau_max ** 2)              # effort: the torques in units of their limits
    # first guess: the inverse dynamics of a smooth rest-to-rest motion (a quintic in time), within the limits
    t = (np.arange(N) + 0.5) / N
    taus = np.empty((N, n))
    for k, s in enumerate(t):
        p, v, a = 10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4) / T, (60 * s - 180 * s**2 + 120 * s**3) / T**2
        dq = q_goal - q_start
        taus[k] = robot.inverse_dynamics(q_start + p * dq, v * dq, a * dq)
    taus = np.clip(taus, -tau_max, tau_max)
    X = rollout(robot, x0, taus, steps)
    merits, statuses, trust = [merit(X[-1], taus, x_goal, R)], [], 1.0   # trust: in units of the limits
    for _ in range(iterations):
        models = [cs.linearize(robot, X[k, :n], X[k, n:], taus[k], dt=DT, steps=steps, end_stops=False)
                  for k in range(N)]
        d, status = qp_step(models, taus, X[-1], x_goal, R, tau_max, trust)
        statuses.append(status)
        trial = np.clip(taus + d, -tau_max, tau_max)
        Xt = rollout(robot, x0, trial, steps)
        m = merit(Xt[-1], trial, x_goal, R)
        if m < merits[-1]:
            done = np.abs(Xt[-1] - x_goal).max() < tol and merits[-1] - m < 1e-6 * m
            taus, X = trial, Xt
            merits.append(m)
            if done:
                break
        else:
            trust *= 0.5
    return dict(taus=taus, states=X, times=np.arange(N + 1) * steps * DT, merits=merits, statuses=statuses,
                tau_max=tau_max, q_goal=q_goal)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res = plan()
    n = len(res["tau_max"])
    X, t = res["states"], res["times"]
    err = np.abs(X[-1, :n] - res["q_goal"]).max()
    print(f"merit {res['merits'][0]:.4g} -> {res['merits'][-1]:.4g} in {len(res['statuses'])} QPs; end error "
          f"{err * 1e3:.3f} mrad (mm), end speed {np.abs(X[-1, n:]).max() * 1e3:.3f} mrad/s; "
          f"largest |tau| / limit {np.max(np.abs(res['taus']) / res['tau_max']):.3f}")
    fig, (a, b) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for j in range(2):
        a.plot(t, X[:, j], label=f"q{j + 1}")
        b.step(t[:-1], res["taus"][:, j], where="post", label=f"tau{j + 1}")
        b.axhline(res["tau_max"][j], ls="--", color=f"C{j}")
        b.axhline(-res["tau_max"][j], ls="--", color=f"C{j}")
    a.set_ylabel("joint (rad)")
    b.set_ylabel("torque (N m)")
    b.set_xlabel("time (s)")
    a.legend()
    b.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "plan_under_torque_limits.png"), dpi=100)


if __name__ == "__main__":
    main()
