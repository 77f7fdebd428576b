"""The dual carry for a researcher's own work (coopsim.tasks.carry): the command line's controller options and
factories of one's own (module:factory, path/to/file.py:factory), at the command line, in run and in sweeps."""
from __future__ import annotations

import json
import re
import sys
import textwrap

import numpy as np
import pytest

import coopsim as cs
from coopsim.tasks import carry as C
from coopsim.tasks.carry import cli

LAW = '''
from coopsim.tasks import carry as C

calls = []


def make(robots, plan, *, gain=1.0, label="plain"):
    """The baseline's controllers, the call recorded."""
    calls.append((gain, label))
    return C.computed_torque(robots, plan)


def shared(robots, plan, *, squeeze=0.0, load_share=0.5):
    """ObjectControl through a law of one's own (the engine's, with this module's own defaults)."""
    from coopsim.tasks.carry.controllers import _object_control_law
    return _object_control_law(robots, plan, squeeze=squeeze, load_share=load_share)


cooperative_law = C.cooperative(shared)
not_callable = 3
'''


@pytest.fixture
def law_file(tmp_path, monkeypatch):
    """A module of one's own, both as a file and importable by name (its folder on sys.path)."""
    folder = tmp_path / "laws"
    folder.mkdir()
    (folder / "my_carry_laws.py").write_text(textwrap.dedent(LAW))
    (folder / "broken_law.py").write_text("raise RuntimeError('this module is broken')\n")
    monkeypatch.syspath_prepend(str(folder))
    yield folder
    for name in [m for m in sys.modules if "my_carry_laws" in m or "broken_law" in m]:
        del sys.modules[name]


def _parse_error(capsys, argv, tmp_path):
    with pytest.raises(SystemExit) as e:
        cli.parse_args(argv + ["--out", str(tmp_path / "out")])
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert e.value.code == 2 and line.startswith("python -m coopsim.tasks.carry: error: "), line
    return line


# ---- --controller-option ----

@pytest.mark.parametrize("text, value", [
    ("0.3", 0.3), ("-2", -2), ("1e3", 1000.0), ("True", True), ("None", None), ("[1, 2.5]", [1, 2.5]),
    ("(5000.0, 20.0)", (5000.0, 20.0)), ("'quoted'", "quoted"), ("plain", "plain"), ("[1", "[1"), ("", ""),
])
def test_an_option_value_is_a_python_literal_or_else_a_string(text, value):
    assert cli.option_value(text) == value and type(cli.option_value(text)) is type(value)


def test_controller_options_parse_to_every_controller_s_and_one_controller_s(tmp_path):
    a = cli.parse_args(["--out", str(tmp_path / "o"), "--controller", "object", "--controller-option",
                        "object:squeeze=-1.5", "--controller-option", "kp=1600", "--sweep", "2",
                        "--sweep-controllers", "object,object-impedance,leader-follower", "--controller-option",
                        "leader-follower:stiffness=(5000.0, 5000.0, 5000.0, 20.0)",
                        "--controller-option", "object-impedance:squeeze=0.5"])
    # kp without a controller goes to every one (all three take it); the scoped ones reach their controller only
    assert a.controller_options == {"kp": 1600}
    assert a.options_by_controller == {"object": {"squeeze": -1.5},
                                       "leader-follower": {"stiffness": (5000.0, 5000.0, 5000.0, 20.0)},
                                       "object-impedance": {"squeeze": 0.5}}
    assert cli.run_options(a, "object-impedance") == {"squeeze": 0.5, "kp": 1600}
    assert cli.run_options(a, "object") == {"squeeze": -1.5, "kp": 1600}
    assert cli.run_options(a, "leader-follower") == {"stiffness": (5000.0, 5000.0, 5000.0, 20.0), "kp": 1600}


# ---- factories of one's own ----

def test_a_factory_of_one_s_own_loads_from_a_module_or_a_file(law_file):
    by_name = C.controllers.controller_factory("my_carry_laws:make")
    by_file = C.controllers.controller_factory(str(law_file / "my_carry_laws.py") + ":make")
    assert by_name.__doc__ == by_file.__doc__ == "The baseline's controllers, the call recorded."
    assert C.controllers.controller_factory(str(law_file / "my_carry_laws.py") + ":make") is by_file  # imported once
    assert C.controllers.controller_factory("my_carry_laws:cooperative_law").__name__ == "shared"
    assert C.controllers.controller_factory("object") is C.object_control


@pytest.mark.parametrize("spec, says", [
    ("lqr", "unknown controller 'lqr': choose from ct, ct-payload, object"),
    ("no_such_module_here:make", "controller 'no_such_module_here:make': cannot import 'no_such_module_here': "
                                 "ModuleNotFoundError: No module named 'no_such_module_here'"),
    ("broken_law:make", "cannot import 'broken_law': RuntimeError: this module is broken"),
    ("my_carry_laws:nothing", "controller 'my_carry_laws:nothing': 'my_carry_laws' has no 'nothing'"),
    ("my_carry_laws:not_callable", "'not_callable' is not callable (robots, plan, **options) -> controllers, it is int"),
    ("missing/file.py:make", "cannot import 'missing/file.py': FileNotFoundError: no file 'missing/file.py'"),
    ("my_carry_laws:", "give it as module:factory or path/to/file.py:factory"),
])
def test_a_factory_that_does_not_load_is_one_line_naming_it(law_file, spec, says):
    with pytest.raises(ValueError) as e:
        C.run(controllers=spec)
    assert says in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_the_command_line_runs_a_factory_of_one_s_own_with_its_options(law_file, tmp_path, capsys):
    import my_carry_laws

    out = tmp_path / "out"
    spec = str(law_file / "my_carry_laws.py") + ":make"
    # by name (sys.path) for the run, by file for the sweep: both work, both take their options
    code = cli.main(["--out", str(out), "--no-video", "--controller", "my_carry_laws:make", "--controller-option",
                     "my_carry_laws:make:gain=2.5", "--controller-option", "my_carry_laws:make:label=mine", "--sweep",
                     "2", "--sweep-controllers", f"{spec},object", "--controller-option", "object:squeeze=-0.5",
                     "--controller-option", f"{spec}:gain=4", "--threads", "2"])
    text = capsys.readouterr().out
    rep = json.loads((out / "report.json").read_text())
    assert code == 0 and rep["controller"] == "my_carry_laws:make"
    assert rep["controller_options"] == {"gain": 2.5, "label": "mine"}
    assert my_carry_laws.calls == [(2.5, "mine")] * 2          # checked before the run, then run
    table = json.loads((out / "sweep.json").read_text())["runs"]
    assert [(r["controller"], r["seed"]) for r in table] == [(spec, 0), (spec, 1), ("object", 0), ("object", 1)]
    assert all(r["success"] for r in table) and "FAILED" not in text
    # the file's module is its own (loaded by path, once), and it got its options: checked, then two runs
    mod = next(m for n, m in sys.modules.items() if n.startswith("coopsim_user_my_carry_laws"))
    assert mod.calls == [(4, "plain")] * 3


def test_a_sweep_table_of_a_law_of_one_s_own_with_options_per_controller(law_file):
    table = C.sweep_table(["my_carry_laws:cooperative_law", "object"], ["none"], [0], threads=2,
                          options_by_controller={"my_carry_laws:cooperative_law": {"squeeze": -1.0}})
    assert list(table.controller) == ["my_carry_laws:cooperative_law", "object"] and table.success.all()
    # the law of one's own pulled the bar apart as told, the named one did not
    assert table.squeeze_rms_N.iloc[0] == pytest.approx(1.0, abs=0.1) and table.squeeze_rms_N.iloc[1] < 0.1
    with pytest.raises(ValueError, match="options_by_controller must map controllers of the sweep"):
        C.sweep_table(["object"], options_by_controller={"ct": {}})
    with pytest.raises(ValueError, match="cannot import 'nope'"):
        C.sweep_table(["nope:make"])


# ---- series and stamps in the outputs ----

@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """The command line's outputs of one carry with a sweep of two runs, series as npz, figures as SVG."""
    out = tmp_path_factory.mktemp("carry") / "out"
    code = cli.main(["--out", str(out), "--no-video", "--controller", "object", "--format", "svg", "--series", "npz",
                     "--sweep", "2", "--sweep-controllers", "ct,object", "--seed", "1"])
    return code, out


def test_the_carry_writes_its_series_as_csv_and_excel_and_one_npz_table(outputs):
    import pandas as pd

    code, out = outputs
    assert code == 0
    log = cs.SimulationLog.read_csv(out / "carry.csv")             # the log, as the handover writes it
    again = C.run(controllers="object", seed=1)
    np.testing.assert_array_equal(log.t, again.log.t)
    np.testing.assert_array_equal(log[1].tau, again.log[1].tau)
    assert (out / "carry.xlsx").stat().st_size > 100_000
    co = pd.read_csv(out / "cooperation.csv")
    table = C.report.series_table(again)
    assert list(co.columns) == ["t"] + list(table.columns[len(again.log.columns()):])
    assert {"squeeze", "load_share.a", "internal.fx_b", "relative_pose_error.rz", "bar.position_error",
            "weld_stretch.b", "airborne"} <= set(co.columns)
    want = again.log.cooperation(0, 1)
    np.testing.assert_array_equal(co["squeeze"].to_numpy(), want["squeeze"])             # NaN where not held
    np.testing.assert_array_equal(co["load_share.b"].to_numpy(), want["load_share"][:, 1])
    x = pd.read_excel(out / "cooperation.xlsx", sheet_name="cooperation", engine="openpyxl")
    assert list(x.columns) == list(co.columns) and len(x) == len(co)
    np.testing.assert_allclose(x["squeeze"].to_numpy(), co["squeeze"].to_numpy(), rtol=1e-15, equal_nan=True)
    # one table with everything, read back column for column
    npz = pd.DataFrame(dict(np.load(out / "series.npz")))
    assert list(npz.columns) == list(table.columns)
    for c in ("t", "scara1.q1", "bar.x", "squeeze", "bar.angle_error"):
        np.testing.assert_array_equal(npz[c].to_numpy(), table[c].to_numpy())


def test_the_sweep_writes_every_run_s_series_in_one_table(outputs):
    import pandas as pd

    _, out = outputs
    s = pd.DataFrame(dict(np.load(out / "sweep_series.npz")))
    assert list(s.columns[:5]) == ["controller", "disturbance", "seed", "t", "scara1.q1"] and "squeeze" in s
    runs = s.groupby(["controller", "seed"], sort=False).size()
    assert list(runs.index) == [("ct", 0), ("ct", 1), ("object", 0), ("object", 1)]
    one = C.run(controllers="object", seed=1, score_run=False)
    rows = s[(s.controller == "object") & (s.seed == 1)]
    np.testing.assert_array_equal(rows["squeeze"].to_numpy(), one.log.cooperation()["squeeze"])
    np.testing.assert_array_equal(rows["scara2.q4"].to_numpy(), one.log[1].q[:, 3])
    assert "log" not in pd.read_csv(out / "sweep.csv")


def test_every_report_of_the_carry_is_stamped_with_its_arguments(outputs):
    _, out = outputs
    rep = json.loads((out / "report.json").read_text())
    st = rep["stamp"]
    assert st["seed"] == 1 and st["arguments"]["controller"] == "object" and st["arguments"]["series"] == "npz"
    assert st["arguments"]["sweep_controllers"] == ["ct", "object"] and st["build"]["compiler"]
    sw = json.loads((out / "sweep.json").read_text())
    assert sw["stamp"]["seed"] == [0, 1] and sw["stamp"]["arguments"] == st["arguments"]


def test_the_figures_come_in_the_format_asked_for(outputs):
    _, out = outputs
    for name in ("bar_path", "weld_forces", "joint_torques", "frames"):
        assert (out / f"{name}.svg").read_text()[:200].lstrip().startswith("<?xml")
        assert not (out / f"{name}.png").exists()


def test_parquet_is_written_with_pyarrow_or_refused_in_one_line_naming_what_to_install(capsys, tmp_path):
    import importlib.util

    if importlib.util.find_spec("pyarrow") is None:
        line = _parse_error(capsys, ["--series", "parquet"], tmp_path)
        assert line.endswith("argument --series: Parquet needs pyarrow, which is not installed: pip install pyarrow "
                             "(or use npz, which needs nothing)")
        with pytest.raises(ValueError, match="Parquet needs pyarrow"):
            C.report.write_table(None, tmp_path / "x.parquet", "parquet")
    else:
        import pandas as pd

        res = C.run(score_run=True)
        p = C.report.write_table(C.report.series_table(res), tmp_path / "s.parquet", "parquet")
        back = pd.read_parquet(p)
        np.testing.assert_array_equal(back["squeeze"].to_numpy(), res.log.cooperation()["squeeze"])
    for argv, says in ((["--series", "csv"], "argument --series: invalid choice: 'csv'"),
                       (["--format", "jpg"], "argument --format: invalid choice: 'jpg'")):
        assert says in _parse_error(capsys, argv, tmp_path)


# ---- signed squeeze read-outs and what a cooperative law commands ----

def test_the_squeeze_reads_signed_everywhere_it_is_summarised():
    """The baseline pulls the bar apart a little (tension, a negative squeeze) for the whole carry: the scores,
    the sweep's row and the printed summary say so with the sign; a commanded compression reads positive."""
    from coopsim.tasks.carry.scoring import score_row

    for options, sign in ((None, -1.0), (dict(squeeze=1.0), 1.0)):
        res = C.run(controllers="object" if options else "ct", controller_options=options)
        sq = res.series["cooperation"]["squeeze"][res.series["pair"]]
        c = res.report["scores"]["cooperation"]["squeeze_N"]
        assert set(c) == {"mean", "rms", "peak"}
        # (a law taking over starts from the baseline's pull: all but its first rows)
        assert np.sign(c["mean"]) == np.sign(c["peak"]) == sign and np.mean(np.sign(sq) == sign) > 0.99
        assert (c["mean"], c["peak"]) == (pytest.approx(sq.mean(), rel=1e-12), sq[np.argmax(np.abs(sq))])
        row = score_row(res.report)
        assert (row["squeeze_mean_N"], row["squeeze_rms_N"], row["squeeze_peak_N"]) == (c["mean"], c["rms"], c["peak"])
        assert row["squeeze_max_N"] == abs(c["peak"])
        line = next(ln for ln in C.summary(res.report).splitlines() if "together while carried" in ln)
        assert f"squeeze {c['mean']:+.3f} N mean, {c['rms']:.3f} N RMS, peak {c['peak']:+.3f} N (compression > 0" in line
    # the baseline's steady pull: about -0.09 N, which the old read-out printed as "0.094 N RMS, 0.114 N max"
    assert line.count("+") >= 2 and "commanded +1.00 N" in line
    base = C.run().report["scores"]["cooperation"]["squeeze_N"]
    assert -0.12 < base["mean"] < -0.06 and base["peak"] < base["mean"] < 0


class _Declaring(cs.CooperativeController):
    """A cooperative law of one's own that declares what it commands as its attributes (the protocol)."""

    def __init__(self, robots, plan, load_share=None, squeeze=None):
        super().__init__()
        self.inner = C.controllers._object_control_law(robots, plan, load_share=load_share or 0.5,
                                                       squeeze=squeeze or 0.0)
        if load_share is not None:
            self.load_share = load_share
        if squeeze is not None:
            self.squeeze = squeeze

    def reset(self, robots, period):
        self.inner.reset(robots, period)

    def compute(self, t, members):
        return self.inner.compute(t, members)


def test_a_cooperative_law_of_one_s_own_declares_its_commands_by_the_protocol():
    plan = C.make_plan()
    robots = C.scene.scaras()
    from coopsim.tasks.carry.sequence import commanded_sharing

    def coop(*, declared=(), law_kw=None):
        return C.Cooperative(free=C.computed_torque(robots, plan), law=_Declaring(robots, plan, **(law_kw or {})),
                             **dict(declared))

    # nothing declared: the lever rule's share, no squeeze
    assert commanded_sharing(coop(), plan) == dict(load_share=[0.5, 0.5], squeeze=0.0, source="lever rule")
    # the law's attributes, one or both
    assert commanded_sharing(coop(law_kw=dict(squeeze=-1.5)), plan) == dict(load_share=[0.5, 0.5], squeeze=-1.5,
                                                                           source="controller")
    got = commanded_sharing(coop(law_kw=dict(load_share=0.3)), plan)
    assert got["load_share"] == pytest.approx([0.3, 0.7]) and got["squeeze"] == 0.0
    # the Cooperative's declaration over the law's
    got = commanded_sharing(coop(declared=dict(squeeze=2.0), law_kw=dict(squeeze=-1.5)), plan)
    assert got["squeeze"] == 2.0
    for bad, says in ((dict(load_share=1.5), "load_share must be in [0, 1], got 1.5"),
                      (dict(squeeze=float("nan")), "squeeze must be finite"),
                      (dict(squeeze="tight"), "squeeze must be a number, got 'tight'")):
        with pytest.raises(ValueError, match=re.escape(says)):
            commanded_sharing(coop(declared=bad), plan)


class _Pulling(cs.CooperativeController):
    """A cooperative law in Python that commands a squeeze without showing it: computed torque per arm, plus
    through J^T at each tool half of the bar's weight and the squeeze along the line between the tools
    (compression positive)."""

    def __init__(self, robots, mass, squeeze):
        super().__init__()
        self.robots, self.mass, self.s = robots, mass, squeeze
        self.ct = [cs.ComputedTorque(*C.controllers._gains(i)) for i in range(2)]

    def reset(self, robots, period):
        for c, r in zip(self.ct, robots):
            c.reset(r, period)

    def compute(self, t, members):
        p = [r.fk(m.q)[:3, 3] for r, m in zip(self.robots, members)]
        e = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
        out = []
        for k, (r, c, m) in enumerate(zip(self.robots, self.ct, members)):
            f = np.r_[np.array([0.0, 0.0, self.mass * 9.81 / 2]) + (self.s if k == 0 else -self.s) * e, 0, 0, 0]
            out.append(c.compute(t, m.q, m.qd, m.q_ref, m.qd_ref, m.qdd_ref) + r.tool_jacobian(m.q).T @ f)
        return out


def test_cooperative_takes_squeeze_beside_load_share_and_the_report_and_scores_follow():
    def pulling(robots, plan, *, pull=0.0):
        return _Pulling(robots, plan.model_bar_mass, -pull)

    factory = C.cooperative(pulling, load_share=0.5, squeeze=lambda pull=0.0, **_: -pull)
    res = C.run(controllers=factory, controller_options=dict(pull=1.0))
    assert res.success, res.report["failure"]
    assert res.report["commanded"] == dict(load_share=[0.5, 0.5], squeeze=-1.0, source="controller")
    c = res.report["scores"]["cooperation"]
    # the law pulls open loop (feedforward on stiff position control): measured -0.81 N of the -1 N, tension
    assert c["squeeze_commanded_N"] == -1.0 and -1.1 < c["squeeze_N"]["mean"] < -0.6
    assert "commanded -1.00 N" in C.summary(res.report)
    # undeclared, the same law commands nothing the report knows of
    assert C.run(controllers=C.cooperative(pulling), controller_options=dict(pull=1.0),
                 score_run=False).report["commanded"]["source"] == "lever rule"
    for bad in ("tight", True, [1.0]):
        with pytest.raises(ValueError, match="squeeze must be None, a number"):
            C.cooperative(pulling, squeeze=bad)
