"""Statistics of a sweep of carries (:func:`~.runs.sweep_table`'s table), per controller and disturbance: each
score's mean, standard deviation and a confidence interval of its mean (Student's t), and the success rate with
its Wilson score interval. numpy and the standard library only (Student's t quantile from the regularised
incomplete beta function, the normal one from :class:`statistics.NormalDist`)."""
from __future__ import annotations

import math
from statistics import NormalDist
from typing import Optional, Sequence

import numpy as np

__all__ = ["SCORES", "format_statistics", "student_t_quantile", "sweep_statistics", "t_interval", "wilson_interval"]

#: the scores a sweep's statistics summarise by default (columns of :func:`~.scoring.score_row`, and the
#: run's wall time, s)
SCORES = ("bar_error_rms_mm", "bar_error_max_mm", "bar_angle_max_mrad", "squeeze_mean_N", "squeeze_rms_N",
          "squeeze_peak_N", "internal_force_rms_N", "internal_force_max_N", "load_share_deviation",
          "relative_position_max_mm", "relative_angle_max_mrad", "wall_time")


def _betacf(a: float, b: float, x: float) -> float:
    """The continued fraction of the incomplete beta function (modified Lentz's method)."""
    tiny, eps = 1e-300, 1e-16
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 10_000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < eps:
            break
    return h


def _betainc(a: float, b: float, x: float) -> float:
    """The regularised incomplete beta function I_x(a, b), 0 <= x <= 1."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = math.exp(math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _betacf(a, b, x) / a
    return 1.0 - front * _betacf(b, a, 1.0 - x) / b


def _t_cdf(t: float, df: float) -> float:
    """Student's t distribution's cumulative probability at t with df degrees of freedom."""
    tail = 0.5 * _betainc(df / 2.0, 0.5, df / (df + t * t))
    return 1.0 - tail if t > 0 else tail


def student_t_quantile(p: float, df: float) -> float:
    """The p quantile (0 < p < 1) of Student's t distribution with df > 0 degrees of freedom: the t with
    P(T <= t) = p (e.g. 12.706 for p = 0.975, df = 1; 1.960 as df grows). Closed forms for df 1 and 2, else the
    cumulative probability (the regularised incomplete beta function) inverted by bisection to 1e-12 relative."""
    if not (0.0 < p < 1.0):
        raise ValueError(f"p must be in (0, 1), got {p!r}")
    if not (df > 0 and math.isfinite(df)):
        raise ValueError(f"df must be finite and > 0, got {df!r}")
    if p == 0.5:
        return 0.0
    if p < 0.5:
        return -student_t_quantile(1.0 - p, df)
    if df == 1:
        return math.tan(math.pi * (p - 0.5))
    if df == 2:
        a = 4.0 * p * (1.0 - p)
        return 2.0 * (p - 0.5) * math.sqrt(2.0 / a)
    lo, hi = 0.0, max(1.0, NormalDist().inv_cdf(p))
    while _t_cdf(hi, df) < p:
        lo, hi = hi, 2.0 * hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if _t_cdf(mid, df) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * hi:
            break
    return 0.5 * (lo + hi)


def t_interval(values, level: float = 0.95):
    """(n, mean, standard deviation (n - 1 in its denominator), low, high) of the finite `values`: the
    interval mean -+ t s / sqrt(n) with t Student's (1 + level) / 2 quantile on n - 1 degrees of freedom. With
    fewer than two values the deviation and the interval are NaN (one value says nothing of its spread)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n == 0:
        return 0, math.nan, math.nan, math.nan, math.nan
    mean = float(np.mean(x))
    if n < 2:
        return 1, mean, math.nan, math.nan, math.nan
    sd = float(np.std(x, ddof=1))
    half = student_t_quantile(0.5 + level / 2.0, n - 1) * sd / math.sqrt(n)
    return n, mean, sd, mean - half, mean + half


def wilson_interval(successes: int, n: int, level: float = 0.95):
    """The Wilson score interval (low, high) of a success rate of `successes` in `n` trials at `level`:
    (p + z^2 / 2n -+ z sqrt(p (1 - p) / n + z^2 / 4n^2)) / (1 + z^2 / n), z the normal (1 + level) / 2
    quantile. It stays within [0, 1] and is not empty at 0 or n successes (unlike p -+ z sqrt(p (1 - p) / n)).
    (NaN, NaN) for n = 0."""
    if n <= 0:
        return math.nan, math.nan
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be 0 .. n = {n}, got {successes!r}")
    z = NormalDist().inv_cdf(0.5 + level / 2.0)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2.0 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def sweep_statistics(table, scores: Optional[Sequence[str]] = None, level: float = 0.95):
    """The statistics of a sweep's table (:func:`~.runs.sweep_table`) per controller and disturbance (in the
    table's order), as a pandas DataFrame in long form, one row per controller, disturbance and quantity:

    - quantity 'success_rate': n (the runs), mean (the rate of successes, 0 .. 1), std NaN, ci_low and ci_high
      the Wilson score interval (:func:`wilson_interval`), interval 'wilson';
    - each of `scores` (default :data:`SCORES`, those the table has): n (the runs with a finite score: a
      run that could not start has none), mean, std (n - 1), ci_low and ci_high the Student t interval of the
      mean (:func:`t_interval`), interval 't'.

    The scores count every run that has them, failed or not (a failed run's scores cover what it did).
    `level`: the intervals' confidence, 0 < level < 1 (default 0.95)."""
    import pandas as pd  # pandas loads only for tables

    if not (0.0 < level < 1.0):
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    missing = {"controller", "disturbance", "success"} - set(table.columns)
    if missing:
        raise ValueError(f"table must be a sweep_table's, with controller, disturbance and success; it lacks "
                         f"{', '.join(sorted(missing))}")
    if scores is None:
        scores = [c for c in SCORES if c in table.columns]
    else:
        scores = list(scores)
        unknown = [c for c in scores if c not in table.columns]
        if unknown:
            raise ValueError(f"scores must be columns of the table, got {', '.join(map(repr, unknown))}")
    rows = []
    for (controller, disturbance), g in table.groupby(["controller", "disturbance"], sort=False):
        ok = [v is True or (isinstance(v, (bool, np.bool_)) and bool(v)) for v in g["success"]]
        lo, hi = wilson_interval(sum(ok), len(ok), level)
        rows.append(dict(controller=controller, disturbance=disturbance, quantity="success_rate", n=len(ok),
                         mean=sum(ok) / len(ok) if ok else math.nan, std=math.nan, ci_low=lo, ci_high=hi,
                         interval="wilson"))
        for c in scores:
            n, mean, sd, lo, hi = t_interval(pd.to_numeric(g[c], errors="coerce"), level)
            rows.append(dict(controller=controller, disturbance=disturbance, quantity=c, n=n, mean=mean, std=sd,
                             ci_low=lo, ci_high=hi, interval="t"))
    return pd.DataFrame(rows, columns=["controller", "disturbance", "quantity", "n", "mean", "std", "ci_low",
                                       "ci_high", "interval"])


def format_statistics(stats, level: float = 0.95) -> str:
    """The statistics as text, one block per controller and disturbance: each quantity's mean, standard
    deviation and interval, and n."""
    lines = []
    for (controller, disturbance), g in stats.groupby(["controller", "disturbance"], sort=False):
        lines.append(f"{controller}, {disturbance}:")
        for r in g.itertuples():
            if r.quantity == "success_rate":
                lines.append(f"  {'success rate':<26} {r.mean * 100:9.1f} %   {level * 100:.0f} % Wilson interval "
                             f"[{r.ci_low * 100:.1f}, {r.ci_high * 100:.1f}] % of {r.n} runs")
            else:
                lines.append(f"  {r.quantity:<26} {r.mean:11.4g} +- {r.std:<9.3g} {level * 100:.0f} % CI "
                             f"[{r.ci_low:.4g}, {r.ci_high:.4g}]  n = {r.n}")
    return "\n".join(lines)
