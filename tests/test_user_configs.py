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
