"""A lab's own config directory (issue #19, :mod:`ccm.experiment.user_configs`): tasks and
experiments outside the package, named through Hydra's ``--config-dir`` / ``-cd`` or
``hydra.searchpath``, work in ``ccm list``, the precheck and the run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ccm.cli import config_dir, main


@pytest.fixture
def lab(tmp_path: Path) -> Path:
    """A user config dir: a copy of the smoke task and an experiment that uses it."""
    root = tmp_path / "lab"
    (root / "task").mkdir(parents=True)
    (root / "experiment").mkdir()
    task = (config_dir() / "task" / "smoke.yaml").read_text(encoding="utf-8")
    (root / "task" / "lab_task.yaml").write_text(task, encoding="utf-8")
    exp = (config_dir() / "experiment" / "smoke.yaml").read_text(encoding="utf-8")
    exp = exp.replace("override /task: smoke", "override /task: lab_task")
    exp = exp.replace("name: smoke", "name: lab_exp").replace("trials: 2", "trials: 1")
    # a condition naming a lab controller: checked again inside the job (Hydra's sources)
    (root / "controller").mkdir()
    ctrl = (config_dir() / "controller" / "fixed_impedance_high.yaml").read_text("utf-8")
    (root / "controller" / "lab_ctrl.yaml").write_text(ctrl, encoding="utf-8")
    exp = exp.replace("[controller=fixed_impedance_high]", "[controller=lab_ctrl]")
    assert "lab_ctrl" in exp
    assert "lab_task" in exp and "lab_exp" in exp
    (root / "experiment" / "lab_exp.yaml").write_text(exp, encoding="utf-8")
    return root


def test_list_shows_the_lab_options(lab: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["list", "--config-dir", str(lab)]) == 0
    out = capsys.readouterr().out
    assert "  lab_exp " in out and "  lab_task " in out and "  smoke " in out
    assert main(["list"]) == 0
    assert "lab_exp" not in capsys.readouterr().out


@pytest.mark.parametrize("how", ["--config-dir", "-cd", "searchpath"])
def test_a_lab_experiment_runs(lab: Path, tmp_path: Path, how: str) -> None:
    out = tmp_path / "run"
    where = [f"hydra.searchpath=[file://{lab}]"] if how == "searchpath" else [how, str(lab)]
    assert main(["run", *where, "experiment=lab_exp", f"hydra.run.dir={out}"]) == 0
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["status"] == "ok" and summary["experiment"] == "lab_exp"
    hydra = (out / ".hydra" / "hydra.yaml").read_text(encoding="utf-8")
    assert "task: lab_task" in hydra  # the choice Hydra made: the lab's file


def test_lab_options_need_the_lab_dir(lab: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["run", "experiment=lab_exp"]) == 2
    assert "experiment=lab_exp: unknown option" in capsys.readouterr().err
    assert main(["run", "-cd", str(lab / "missing"), "experiment=smoke"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1
        and err[0].startswith("ccm: error: --config-dir: ")
        and "not a directory" in err[0]
    )
    assert main(["run", "--config-dir"]) == 2
    assert "--config-dir: needs a directory" in capsys.readouterr().err


@pytest.mark.parametrize("how", ["--config-dir", "searchpath"])
def test_a_lab_file_of_the_packages_name_shadows_it(tmp_path: Path, how: str) -> None:
    """Issue #39: Hydra searched the package's configs first, so a lab's ``task/smoke.yaml``
    was listed as shadowing the package's but the run used the package's."""
    lab = tmp_path / "lab"
    (lab / "task").mkdir(parents=True)
    task = (config_dir() / "task" / "smoke.yaml").read_text(encoding="utf-8")
    assert "stiffness: 40.0" in task
    (lab / "task" / "smoke.yaml").write_text(task.replace("stiffness: 40.0", "stiffness: 41.5"))
    out = tmp_path / "run"
    where = [f"hydra.searchpath=[file://{lab}]"] if how == "searchpath" else [how, str(lab)]
    fast = ["experiment.fast=true", "experiment.figures=false"]
    assert main(["run", *where, "experiment=smoke", *fast, f"hydra.run.dir={out}"]) == 0
    saved = (out / ".hydra" / "config.yaml").read_text(encoding="utf-8")
    assert "stiffness: 41.5" in saved and "stiffness: 40.0" not in saved


def test_a_broken_lab_file_of_the_packages_name_is_not_ignored(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    lab = tmp_path / "lab"
    (lab / "task").mkdir(parents=True)
    (lab / "task" / "smoke.yaml").write_text("name: smoke\npattern: [\n")
    out = tmp_path / "run"
    assert main(["run", "-cd", str(lab), "experiment=smoke", f"hydra.run.dir={out}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "smoke.yaml" in err[0] and "YAML" in err[0], err
    assert not out.exists()


@pytest.mark.parametrize(
    ("condition", "expected"),
    [
        (["controller=fixed_impedance_high"], 800.0),  # the command line beats the option's value
        (["controller=fixed_impedance_high", "controller.stiffness=5000"], 5000.0),  # the key's own
    ],
)
def test_command_line_and_condition_precedence(condition: list[str], expected: float) -> None:
    """Issue #39, as docs/user-guide/configs.md states it: a command-line key overrides the
    values of the config option a condition selects (an ablation such as
    ``controller.loop.inertia=nominal`` reaches every condition), and a key the condition sets
    itself overrides the command line."""
    from hydra import initialize_config_dir

    from ccm.experiment.precheck import compose_extra

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        cfg = compose_extra(["experiment=smoke", "controller.stiffness=800"], condition, dirs=[])
    assert float(cfg.controller.stiffness) == expected
