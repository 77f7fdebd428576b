"""The dual carry for a researcher's own work (coopsim.tasks.carry): the command line's controller options and
factories of one's own (module:factory, path/to/file.py:factory), at the command line, in run and in sweeps."""
from __future__ import annotations

import json
import sys
import textwrap

import pytest

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
