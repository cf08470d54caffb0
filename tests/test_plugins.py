"""Controllers and simulators from outside ccm (issue #41, part 1): by import path
(``_target_``) or by an installed package's entry points; every bad plugin is one line that
names it, and a plugin that raises mid-run fails only its own run.

The plugins are ``tests/plugins/``; the entry points come from a package's metadata that a
test writes into a directory on ``sys.path``, as ``pip install`` would.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ccm.cli import list_plugins
from ccm.control.registry import make_controller
from ccm.core.errors import ConfigError
from ccm.core.plugins import load_object
from ccm.experiment.components import build_components
from ccm.experiment.trial import run_trial
from ccm.sim import make_sim
from ccm.tasks.trajectory import build_pattern
from tests.plugins.controllers import PlainPD

ROOT = Path(__file__).resolve().parents[1]
CCM = str(Path(sys.executable).parent / "ccm")
PLUGINS = "tests.plugins.controllers"


def _refusal(cfg: dict) -> str:
    with pytest.raises(ConfigError) as err:
        make_controller(cfg)
    line = str(err.value)
    assert "\n" not in line
    return line


def test_a_plugin_by_import_path_runs_a_trial(composer) -> None:
    """``controller=plugin controller._target_=module:Class``: the class is built with its
    own parameters (no ``key``) and closes the loop; the condition is named after it."""
    cfg = composer([
        "experiment=single", "task=smoke", "controller=plugin",
        f"controller._target_={PLUGINS}:PlainPD", "+controller.stiffness=450.0",
    ])  # fmt: skip
    comp = build_components(cfg)
    assert type(comp.controller) is PlainPD and comp.controller.stiffness == 450.0
    rec = run_trial(comp, seed=0, duration_s=0.2)
    cols = rec.arrays()
    x, x_d = cols["pos_x"], cols["target_pos_x"]
    assert abs(x[-1] - x[0]) > 1e-3  # it moved, toward the target: the PD acts
    assert abs(x_d[-1] - x[-1]) < abs(x_d[-1] - x[0])


def test_hydras_dotted_path_works_too() -> None:
    ctrl = make_controller({"_target_": f"{PLUGINS}.PlainPD", "damping": 10.0})
    assert isinstance(ctrl, PlainPD) and ctrl.damping == 10.0


@pytest.mark.parametrize(
    ("target", "expected"),
    [
        ("no_such_module:X", "importing 'no_such_module' failed: ModuleNotFoundError"),
        (f"{PLUGINS}:Nope", f"'{PLUGINS}' has no attribute 'Nope'"),
        (f"{PLUGINS}:NotAController", "is a class NotAController, not a subclass of "
         "ccm.control.base.Controller"),
        (f"{PLUGINS}:make_pd", "is a function, not a subclass"),
        (f"{PLUGINS}:NoSignals", "does not implement signals"),
        ("PlainPD", "is not an import path"),
        (3, "must be an import path 'module:Class', got 3"),
    ],
)  # fmt: skip
def test_a_bad_plugin_is_one_line_naming_it(target: object, expected: str) -> None:
    line = _refusal({"_target_": target})
    assert line.startswith("controller._target_: ") and expected in line, line


def test_the_plugin_template_without_a_target_says_what_to_set() -> None:
    line = _refusal({"type": None, "_target_": None})
    assert line.startswith("controller.type: is not set; allowed: fixed_impedance, ")
    assert line.endswith("(or controller._target_: an import path 'module:Class')")


def test_a_plugins_unknown_parameter_is_named() -> None:
    line = _refusal({"_target_": f"{PLUGINS}:PlainPD", "stifness": 1.0})
    assert line.startswith("controller.stifness: unknown key; allowed: stiffness, damping")


def test_a_simulator_plugin_by_import_path() -> None:
    """``sim._target_``: a subclass of a built-in backend with its own parameter."""
    scene = {"ee": {"mass": 1.0}}
    sim = make_sim(
        {"_target_": "tests.plugins.sims:HeavyPymunk", "mass_factor": 3.0}, scene, [0, 0]
    )
    assert type(sim).__name__ == "HeavyPymunk"
    with pytest.raises(ConfigError, match=r"^sim\._target_: plugin .* not a subclass of ccm\.sim"):
        make_sim({"_target_": f"{PLUGINS}:PlainPD"}, scene, [0, 0])


# ---------------------------------------------------------------- entry points


@pytest.fixture
def installed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A package's metadata registering three controllers and a simulator (one of the
    controllers broken, one taking a built-in's name), on ``sys.path``."""
    info = tmp_path / "ccm_user_plugins-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ccm-user-plugins\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[ccm.controllers]\n"
        f"plain_pd = {PLUGINS}:PlainPD\n"
        f"broken_one = {PLUGINS}:NotAController\n"
        f"avic = {PLUGINS}:PlainPD\n"
        "[ccm.simulators]\n"
        "heavy = tests.plugins.sims:HeavyPymunk\n"
        "[ccm.segments]\n"
        f"wave = {SEGMENTS}:Wave\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_an_entry_point_plugin_is_a_type(installed: Path) -> None:
    ctrl = make_controller({"type": "plain_pd", "stiffness": 200.0})
    assert isinstance(ctrl, PlainPD) and ctrl.stiffness == 200.0
    assert type(make_controller({"type": "avic"})).__name__ == "AVIC"  # built-ins win
    line = _refusal({"type": "broken_one"})
    assert line.startswith("controller.type: plugin 'broken_one' is a class NotAController")
    sim = make_sim({"name": "heavy"}, {"ee": {"mass": 1.0}}, [0, 0])
    assert type(sim).__name__ == "HeavyPymunk"


def test_ccm_list_shows_the_plugins_and_names_the_broken(installed: Path, capsys) -> None:
    assert list_plugins() == 2  # the broken one and the one shadowed by a built-in
    out = capsys.readouterr().out
    assert f"  plain_pd                     {PLUGINS}:PlainPD\n" in out
    assert "broken_one" in out and "broken: controller.type: plugin 'broken_one'" in out
    assert "not used, 'avic' is a built-in controller" in out
    assert "  heavy                        tests.plugins.sims:HeavyPymunk\n" in out
    assert f"  wave                         {SEGMENTS}:Wave\n" in out


# ---------------------------------------------------------------- task segments

SEGMENTS = "tests.plugins.segments"


def test_a_segment_plugin_by_import_path_is_part_of_the_pattern() -> None:
    """``{_target_: module:Class, ...}`` in a task's pattern: built from where the previous
    segment ends, with its own parameters; its samples are the class's law (x = start + a
    sin(2π t/T) along the axis), and the next segment starts where it ends."""
    spec = [
        {"type": "line", "to": [0.1, 0.0], "duration": 1.0},
        {"_target_": f"{SEGMENTS}:Wave", "duration": 2.0, "amplitude": 0.02, "axis": [0, 1],
         "name": "wave"},
        {"type": "hold", "duration": 0.5},
    ]  # fmt: skip
    pattern = build_pattern(spec, [0.0, 0.0], control_dt=0.001)
    assert pattern.duration == pytest.approx(3.5)
    quarter = pattern.sample(1.0 + 0.5)  # a quarter period into the wave
    np.testing.assert_allclose(quarter.position, [0.1, 0.02], atol=1e-12)
    np.testing.assert_allclose(quarter.velocity, [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(quarter.acceleration, [0.0, -0.02 * math.pi**2], rtol=1e-12)
    np.testing.assert_allclose(pattern.sample(3.2).position, [0.1, 0.0], atol=1e-12)


def test_an_entry_point_segment_is_a_type(installed: Path) -> None:
    pattern = build_pattern([{"type": "wave", "duration": 1.0}], [0.0, 0.0], control_dt=0.001)
    np.testing.assert_allclose(pattern.sample(0.25).position, [0.01, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    ("entry", "expected"),
    [
        ({"type": "spiral"}, "task.pattern[0].type: unknown value 'spiral'; allowed: line, arc"),
        ({"_target_": f"{PLUGINS}:PlainPD"}, "task.pattern[0]._target_: plugin "
         f"'{PLUGINS}:PlainPD' is a class PlainPD, not a subclass of ccm.tasks.segments.Segment"),
        ({"_target_": f"{SEGMENTS}:Picky"}, f"task.pattern[0]: plugin '{SEGMENTS}:Picky' refused "
         "its parameters: ValueError: amplitude must be in furlongs"),
        ({"_target_": f"{SEGMENTS}:Elsewhere"}, f"task.pattern[0]: plugin '{SEGMENTS}:Elsewhere' "
         "starts at [1.0, 1.0], not where the previous segment ends ([0.0, 0.0])"),
        ({"_target_": f"{SEGMENTS}:Wave", "colour": 3}, "refused its parameters: TypeError"),
    ],
)  # fmt: skip
def test_a_bad_segment_plugin_is_one_line_naming_it(entry: dict, expected: str) -> None:
    with pytest.raises(ConfigError) as err:
        build_pattern([{"duration": 1.0, **entry}], [0.0, 0.0], control_dt=0.001)
    assert expected in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_without_plugins_ccm_list_says_none(capsys, monkeypatch) -> None:
    # no installed distribution at all (a user may have installed examples/my_controller)
    bare = [p for p in sys.path if not p or not any(Path(p).glob("*.dist-info"))]
    monkeypatch.setattr(sys, "path", bare)
    assert list_plugins() == 0
    assert (
        "controller plugins (entry points ccm.controllers): none installed"
        in capsys.readouterr().out
    )


def test_load_object_quotes_the_import_error_of_a_broken_module(
    tmp_path: Path, monkeypatch
) -> None:
    (tmp_path / "user_broken_mod.py").write_text("raise ImportError('needs torch>=9')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigError) as err:
        load_object("user_broken_mod:Ctrl", "controller._target_")
    assert str(err.value) == (
        "controller._target_: plugin 'user_broken_mod:Ctrl': importing 'user_broken_mod' "
        "failed: ImportError: needs torch>=9"
    )


# ---------------------------------------------------------------- on the command line


def _ccm(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [CCM, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300
    )


def test_the_cli_refuses_a_bad_plugin_in_one_line(tmp_path: Path) -> None:
    res = _ccm("run", "experiment=single", "task=smoke", "controller=plugin",
               f"controller._target_={PLUGINS}:NotAController", cwd=tmp_path)  # fmt: skip
    assert res.returncode != 0
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("ccm: error:")]
    assert len(errors) == 1 and "NotAController" in errors[0], res.stderr
    assert not (tmp_path / "outputs").exists() or not any((tmp_path / "outputs").rglob("*.json"))


def test_a_plugin_raising_mid_run_fails_its_runs_and_the_sweep_goes_on(tmp_path: Path) -> None:
    res = _ccm("run", "-m", "experiment=single", "task=smoke", "controller=plugin",
               f"controller._target_={PLUGINS}:RaisesMidRun", "seed=0,1", cwd=tmp_path)  # fmt: skip
    assert res.returncode != 0
    summaries = sorted((tmp_path / "multirun").rglob("summary.json"))
    assert len(summaries) == 2, res.stderr  # the second seed ran after the first failed
    for path in summaries:
        summary = json.loads(path.read_text())
        assert summary["status"] == "failed"
        assert "RuntimeError: the plugin's own bug" in json.dumps(summary)
