"""A sweep's statistics (coopsim.tasks.carry.statistics): Student's t quantile against scipy and a printed
table, the intervals against a hand computation, the table per controller and disturbance, and the command
line's sweep alone printing and writing them."""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from coopsim.tasks import carry as C
from coopsim.tasks.carry import cli
from coopsim.tasks.carry import statistics as ST


# ---- Student's t, against a printed table and scipy ----

@pytest.mark.parametrize("df, t", [(1, 12.706), (2, 4.303), (3, 3.182), (4, 2.776), (9, 2.262), (29, 2.045),
                                   (120, 1.980)])
def test_the_t_quantile_is_the_printed_table_s(df, t):
    assert ST.student_t_quantile(0.975, df) == pytest.approx(t, abs=5e-4)


def test_the_t_quantile_is_scipy_s():
    stats = pytest.importorskip("scipy.stats")
    for df in (1, 2, 3, 4, 5, 7, 10, 19, 30, 99, 1000, 2.5):
        for p in (0.5, 0.6, 0.9, 0.95, 0.975, 0.995, 0.9995, 0.025, 0.1):
            assert ST.student_t_quantile(p, df) == pytest.approx(stats.t.ppf(p, df), rel=1e-9, abs=1e-12), (p, df)
    # as df grows it becomes the normal's
    assert ST.student_t_quantile(0.975, 1e7) == pytest.approx(1.959963984540054, rel=1e-6)
    for bad in (dict(p=0.0, df=3), dict(p=1.0, df=3), dict(p=0.9, df=0), dict(p=0.9, df=float("nan"))):
        with pytest.raises(ValueError):
            ST.student_t_quantile(**bad)


# ---- the intervals against a hand computation ----

def test_the_intervals_are_the_hand_computed_ones():
    # 1, 2, 3, 4: mean 2.5, s^2 = (2.25 + 0.25 + 0.25 + 2.25) / 3 = 5/3, t(0.975, 3) = 3.182446305284263,
    # half width t s / sqrt(4) = 3.182446305284263 * 1.2909944487358056 / 2 = 2.0542602568...
    n, mean, sd, lo, hi = ST.t_interval([1.0, 2.0, 3.0, 4.0, float("nan")])
    assert n == 4 and mean == 2.5 and sd == pytest.approx(math.sqrt(5 / 3), rel=1e-15)
    assert (lo, hi) == pytest.approx((2.5 - 2.0542602568, 2.5 + 2.0542602568), abs=1e-9)
    # 3 successes of 4, z = 1.959963984540054, z^2 = 3.8414588207: p = 0.75, 1 + z^2/4 = 1.9603647052, centre
    # (0.75 + z^2/8) / that = 0.6275272909, half z sqrt(0.046875 + z^2/64) / 1.9603647052 = 0.3268854483
    lo, hi = ST.wilson_interval(3, 4)
    assert (lo, hi) == pytest.approx((0.3006418426, 0.9544127392), abs=1e-9)
    assert ST.wilson_interval(0, 10) == pytest.approx((0.0, 0.277533), abs=1e-6)     # not empty at 0 of n
    assert ST.wilson_interval(10, 10)[1] == 1.0 and ST.wilson_interval(10, 10)[0] == pytest.approx(0.722467, abs=1e-6)
    assert ST.t_interval([5.0])[:2] == (1, 5.0) and math.isnan(ST.t_interval([5.0])[3])     # one value: no spread
    assert ST.t_interval([])[0] == 0


def test_the_statistics_table_per_controller_and_disturbance_is_the_hand_computed_one():
    table = pd.DataFrame(dict(
        controller=["a"] * 4 + ["b"] * 3, disturbance=["none"] * 4 + ["push"] * 3,
        success=[True, True, False, True, True, True, True],
        bar_error_rms_mm=[1.0, 2.0, 3.0, 4.0, 0.5, 0.5, float("nan")],
        squeeze_rms_N=[0.1, 0.1, 0.1, 0.1, 1.0, 2.0, 3.0]))
    s = C.sweep_statistics(table)
    assert list(s.columns) == ["controller", "disturbance", "quantity", "n", "mean", "std", "ci_low", "ci_high",
                               "interval"]
    assert list(zip(s.controller, s.disturbance, s.quantity)) == [
        ("a", "none", "success_rate"), ("a", "none", "bar_error_rms_mm"), ("a", "none", "squeeze_rms_N"),
        ("b", "push", "success_rate"), ("b", "push", "bar_error_rms_mm"), ("b", "push", "squeeze_rms_N")]
    r = s.set_index(["controller", "quantity"])
    assert r.loc[("a", "success_rate"), "mean"] == 0.75 and r.loc[("a", "success_rate"), "n"] == 4
    assert r.loc[("a", "success_rate"), ["ci_low", "ci_high"]].tolist() == pytest.approx([0.3006418426, 0.9544127392], abs=1e-9)
    assert r.loc[("a", "bar_error_rms_mm"), ["mean", "ci_low", "ci_high"]].tolist() == \
        pytest.approx([2.5, 0.4457397432, 4.5542602568], abs=1e-9)
    # identical values: no spread, the interval is the value; a NaN score is left out of its n
    assert r.loc[("a", "squeeze_rms_N"), ["std", "ci_low", "ci_high"]].tolist() == pytest.approx([0.0, 0.1, 0.1])
    assert r.loc[("b", "bar_error_rms_mm"), "n"] == 2 and r.loc[("b", "bar_error_rms_mm"), "std"] == 0.0
    # 1, 2, 3: mean 2, s = 1, t(0.975, 2) = 4.302652729911275, half 4.3026527 / sqrt(3) = 2.4841377...
    assert r.loc[("b", "squeeze_rms_N"), ["mean", "std", "ci_low", "ci_high"]].tolist() == \
        pytest.approx([2.0, 1.0, 2.0 - 2.4841377118, 2.0 + 2.4841377118], abs=1e-9)
    assert r.loc[("b", "success_rate"), "interval"] == "wilson" and r.loc[("b", "squeeze_rms_N"), "interval"] == "t"
    with pytest.raises(ValueError, match="scores must be columns of the table, got 'nope'"):
        C.sweep_statistics(table, scores=["nope"])
    with pytest.raises(ValueError, match="lacks controller"):
        C.sweep_statistics(table.drop(columns="controller"))
    with pytest.raises(ValueError, match="level must be in"):
        C.sweep_statistics(table, level=95)
    text = ST.format_statistics(s)
    assert "a, none:" in text and "75.0 %   95 % Wilson interval [30.1, 95.4] % of 4 runs" in text


def test_the_command_line_s_sweep_alone_prints_and_writes_its_statistics(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["--out", str(out), "--sweep", "3", "--sweep-only", "--sweep-controllers", "ct,object",
                     "--sweep-disturbances", "none,push", "--threads", "2"])
    text = capsys.readouterr().out
    assert code == 0
    # no run of --controller first: no report, figures, series or video
    assert sorted(p.name for p in out.iterdir()) == ["sweep.csv", "sweep.json", "sweep_statistics.csv"]
    table = pd.read_csv(out / "sweep.csv", index_col=0)
    stats = pd.read_csv(out / "sweep_statistics.csv")
    assert list(stats.groupby(["controller", "disturbance"], sort=False).size().index) == \
        [("ct", "none"), ("ct", "push"), ("object", "none"), ("object", "push")]
    # each figure is the table's own, computed again here
    for (c, d), g in table.groupby(["controller", "disturbance"], sort=False):
        row = stats[(stats.controller == c) & (stats.disturbance == d) & (stats.quantity == "bar_error_rms_mm")].iloc[0]
        x = g.bar_error_rms_mm.to_numpy()
        half = ST.student_t_quantile(0.975, 2) * x.std(ddof=1) / math.sqrt(3)
        assert (row["n"], row["mean"], row["ci_low"], row["ci_high"]) == pytest.approx((3, x.mean(), x.mean() - half,
                                                                                        x.mean() + half), rel=1e-12)
    assert "ct, push:" in text and "95 % Wilson interval [43.9, 100.0] % of 3 runs" in text and "95 % CI [" in text
    sw = json.loads((out / "sweep.json").read_text())
    assert len(sw["statistics"]) == len(stats) and sw["stamp"]["seed"] == [0, 1, 2]
    with pytest.raises(SystemExit):
        cli.parse_args(["--out", str(out), "--sweep-only"])
    assert "argument --sweep-only: give --sweep N" in capsys.readouterr().err
