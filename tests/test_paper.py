"""``ccm paper`` (``make reproduce-paper``, issue #8 part 2): sweeps an experiment over its
configured seeds with the local launcher, records the wall times and builds the report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ccm.reporting.paper import PAPER_EXPERIMENTS, experiment_sim, main, sweep_command


def test_paper_pipeline_on_one_experiment(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "paper"
    assert main(["--quick", "--out", str(out), "mpc_convexity"]) == 0
    assert json.loads(next(out.rglob("summary.json")).read_text())["status"] == "ok"
    timing = json.loads((out / "paper_timing.json").read_text())
    assert list(timing["sweeps_s"]) == ["mpc_convexity"] and timing["failed"] == []
    assert (out / "report.html").is_file() and (out / "mpc_convexity.log").is_file()
    assert "1/1 sweeps ok" in capsys.readouterr().out
    # again (resumed: the run is skipped): the first invocation's timing is kept, not replaced
    assert main(["--quick", "--out", str(out), "mpc_convexity"]) == 0
    again = json.loads((out / "paper_timing.json").read_text())
    timing.pop("earlier")
    assert again["earlier"] == [timing] and list(again["sweeps_s"]) == ["mpc_convexity"]


def test_paper_rejects_unknown_experiments_and_lanes(capsys: pytest.CaptureFixture) -> None:
    assert main(["nope"]) == 2
    assert "unknown experiment 'nope'; allowed:" in capsys.readouterr().err
    assert main(["--lanes", "0", "mpc_convexity"]) == 2
    assert "--lanes must be >= 1" in capsys.readouterr().err
    assert main(["--launcher", "ray", "mpc_convexity"]) == 2
    assert "allowed: local, slurm, submitit_local_test" in capsys.readouterr().err


def test_every_paper_experiment_is_a_sweep_with_the_local_launcher(tmp_path: Path) -> None:
    from ccm.cli import group_options

    assert set(PAPER_EXPERIMENTS) <= set(group_options("experiment"))
    full = sweep_command("h1_adaptive_control", tmp_path, quick=False)
    assert {"-m", "experiment=h1_adaptive_control", "hydra/launcher=local"} <= set(full)
    assert f"hydra.sweep.dir={tmp_path / 'h1_adaptive_control'}" in full
    assert "seed=0" not in full  # the seeds come from the experiment config
    quick = sweep_command("h1_adaptive_control", tmp_path, quick=True)
    assert {"seed=0", "experiment.fast=true"} <= set(quick)
    assert "--force" not in full
    forced = sweep_command("h1_adaptive_control", tmp_path, quick=False, force=True)
    assert forced[forced.index("run") + 1] == "--force"  # ccm run --force -m …


def test_sim_puts_the_3d_experiments_on_another_engine(tmp_path) -> None:  # noqa: ANN001
    """``--sim mujoco3d`` (issue #42): the sweep gets ``sim=mujoco3d``, and only the 3-D
    experiments are run (a 2-D one composes to pymunk2d)."""
    assert "sim=mujoco3d" in sweep_command("h4_collisions", tmp_path, False, sim="mujoco3d")
    assert not any(a.startswith("sim=") for a in sweep_command("h4_collisions", tmp_path, False))
    assert experiment_sim("h4_collisions") == "pybullet3d"
    assert experiment_sim("h1_adaptive_control") == "pymunk2d"
