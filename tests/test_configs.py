"""Every config in every group composes and builds; every experiment runs in fast mode (slow)."""

from __future__ import annotations

from pathlib import Path

import pytest

from ccm.analyses.dispatch import run as run_experiment
from ccm.cli import GROUPS, config_dir, group_options
from ccm.experiment.components import check_experiment, plan_experiment

ALL_OPTIONS = [(g, o) for g in GROUPS for o in group_options(g)]


def test_every_group_has_options() -> None:
    for group in GROUPS:
        assert group_options(group), f"config group {group}/ is empty"


def _partner(group: str, option: str) -> list[str]:
    """A sim/task of matching dimension for 3-D options (the defaults are 2-D)."""
    from omegaconf import OmegaConf

    node = OmegaConf.load(config_dir() / group / f"{option}.yaml")
    if group == "task" and node.get("dim") == 3:
        return ["sim=pybullet3d"]
    if group == "sim" and option in ("pybullet3d", "mujoco3d"):
        return ["task=press_slide_3d"]
    return []


@pytest.mark.parametrize(("group", "option"), ALL_OPTIONS, ids=[f"{g}={o}" for g, o in ALL_OPTIONS])
def test_option_composes_and_builds(composer, group: str, option: str) -> None:
    overrides = [f"{group}={option}", *_partner(group, option)]
    cfg = composer(overrides)
    trials = check_experiment(cfg)["trials"]
    plan = plan_experiment(cfg, lambda extra: composer([*overrides, *extra]), trials)
    assert plan
    for _, phases in plan:
        for _, comp in phases:
            assert comp.task.pattern.duration > 0
            assert comp.sim.dim == comp.task.dim


@pytest.mark.parametrize("option", group_options("experiment"))
def test_experiment_configs_follow_the_template(option: str) -> None:
    text = (config_dir() / "experiment" / f"{option}.yaml").read_text(encoding="utf-8")
    assert text.startswith("# @package _global_"), "experiment configs are global packages"
    # an analysis that simulates nothing (experiment.kind: mpc_convexity) picks no groups
    if "kind: mpc_convexity" not in text:
        assert "override /" in text, "experiment configs pick groups with `override /group: x`"
    assert f"name: {option}" in text, "experiment.name must match the file name"


@pytest.mark.slow
@pytest.mark.parametrize("option", group_options("experiment"))
def test_every_experiment_runs_in_fast_mode(composer, tmp_path: Path, option: str) -> None:
    overrides = [f"experiment={option}", "experiment.fast=true", "experiment.figures=false"]
    cfg = composer(overrides)
    summary = run_experiment(
        cfg, lambda extra: composer([*overrides, *extra]), tmp_path, show_progress=False
    )
    assert summary["status"] == "ok"
    assert (tmp_path / "summary.json").is_file()
    for metrics in summary["conditions"].values():
        if cfg.experiment.kind in ("h3", "forward_model_horizon"):  # offline prediction scores
            assert any(k.endswith(("_rmse_rad", "_rmse_N")) for k in metrics)
        elif cfg.experiment.kind == "mpc_convexity":  # an analysis of the MPC cost
            # per curve: its convexity; the all_curves pseudo-condition: the trend over curves
            key = "convex_fraction" if "convex_fraction" in metrics else "min_rank_corr"
            assert metrics[key] is not None
        elif cfg.experiment.kind == "gp_contact_models":  # GP fits of contact data
            assert metrics["stiffness_ratio"] is not None
        elif cfg.experiment.kind == "mpc_table2":  # replayed MPC solves per Table 2 row
            assert metrics["ticks"] > 0 and metrics["iterations_median"] is not None
        else:
            assert metrics["rms_tracking_error_m"] is not None
