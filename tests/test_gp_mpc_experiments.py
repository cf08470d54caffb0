"""Seed B experiments end to end, shortened: demonstrations -> GP fit -> MPC trials, with the
metrics of ccm/metrics/mpc.py and a byte-identical summary for the same seed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ccm.experiment.runner import run_experiment
from ccm.metrics.mpc import goal_metrics

GOALS = [
    "experiment=mpc_goal_inference",
    "experiment.figures=false",
    "task.pattern.0.duration=1.5",
    "controller.demo_modes=[0,1]",
    "experiment.phases=[{name: d0, trials: 1, overrides: ['task.scene.human.goal_index=0']},"
    " {name: d1, trials: 1, overrides: ['task.scene.human.goal_index=1']},"
    " {name: execution, trials: 1, overrides: ['task.scene.human.goal_index=1']}]",
]


def _run(composer, overrides: list[str], out: Path) -> dict:
    cfg = composer(overrides)
    return run_experiment(cfg, lambda extra: composer([*overrides, *extra]), out, False)


def test_goal_inference_finds_the_goal_and_is_deterministic(composer, tmp_path: Path) -> None:
    a = _run(composer, GOALS, tmp_path / "a")
    m = a["conditions"]["gp_mpc"]
    assert m["mpc_solves"] > 30 and m["mpc_infeasible"] == 0
    assert m["belief_correct_final"] == 1.0  # the human chose goal 1; the belief finds it
    assert m["time_to_belief_s"] is not None and m["time_to_belief_s"] < 1.0
    for cond in ("gp_mpc", "uniform_belief"):  # the §6.4 claims' metrics, for the ablation too
        c = a["conditions"][cond]
        assert isinstance(c["f_ref_toward_goal_N"], float), cond
        assert isinstance(c["goal_approach_m"], float), cond
    _run(composer, GOALS, tmp_path / "b")
    assert (tmp_path / "a" / "summary.json").read_bytes() == (
        tmp_path / "b" / "summary.json"
    ).read_bytes()
    info = json.loads((tmp_path / "a" / "run_info.json").read_text())
    assert info["mpc_rate_hz"]["gp_mpc"] > 0  # wall-clock rate: run_info, not the summary
    # Table 2's context: the process's CPU-time rate and IPOPT's iterations per solve
    assert info["mpc_cpu_rate_hz"]["gp_mpc"] > 0 and info["mpc_iterations_median"]["gp_mpc"] >= 1
    assert info["mpc_ms_per_iteration"]["gp_mpc"] > 0
    # the run's CPU by part, for make bench's paper budget (ccm/bench/floor.py)
    assert set(info["cpu_s"]) == {"plan", "trials", "figures"}
    assert all(v >= 0.0 for v in info["cpu_s"].values()) and info["cpu_s"]["trials"] > 0.0


def test_contact_well_damped_raises_damping_on_stiff_contact(composer, tmp_path: Path) -> None:
    """mpc_contact's stiff condition, shortened: the well-damped constraint (Eq. 19-20) raises
    D along the contact normal above the unconstrained plan's, and the wall is touched."""
    base = [
        "experiment=mpc_contact",
        "experiment.figures=false",
        "~experiment.conditions",
        "+experiment.conditions={stiff_none: [],"
        " stiff_well_damped: ['controller.mpc.well_damped={zeta: 1.2}']}",
        "task.pattern.0.duration=3.0",
        "task.scene.compliant_walls.0.point=[0.03,0.0]",
        "task.scene.compliant_walls.0.stiffness=126000",
        "controller.demo_modes=[0]",
        "experiment.phases=[{name: demo, trials: 1, overrides: []},"
        " {name: execution, trials: 1, overrides: []}]",
    ]
    s = _run(composer, base, tmp_path / "s")
    free, damped = s["conditions"]["stiff_none"], s["conditions"]["stiff_well_damped"]
    assert free["first_contact_s"] is not None and damped["first_contact_s"] is not None
    assert damped["mean_damping_x_Nspm"] > free["mean_damping_x_Nspm"] + 100.0


def _goal_log(f_ref_y: float, end_y: float) -> dict[str, np.ndarray]:
    """A 2-D log: the EE from (0, 0) to (0, end_y); the human's goal at (0.12, 0.06)."""
    n = 11
    return {
        "pos_x": np.zeros(n), "pos_y": np.linspace(0.0, end_y, n),
        "f_ref_x_N": np.zeros(n), "f_ref_y_N": np.full(n, f_ref_y),
        "truth_human_goal_x_m": np.full(n, 0.12), "truth_human_goal_y_m": np.full(n, 0.06),
    }  # fmt: skip


def test_goal_metrics_sign_and_the_inert_case() -> None:
    """Seed B Fig. 11c: −f^r pushes the admittance (Eq. 4), so f^r_y < 0 pushes toward a goal
    at +y: positive; the opposite f^r negative; f^r = 0 (a plan that ignores the goal) 0."""
    unit_y = 0.06 / np.hypot(0.12, 0.06)
    toward = goal_metrics(_goal_log(-2.0, 0.03), 2)
    assert toward["f_ref_toward_goal_N"] == pytest.approx(2.0 * unit_y)
    d0, d1 = np.hypot(0.12, 0.06), np.hypot(0.12, 0.03)
    assert toward["goal_approach_m"] == pytest.approx(d0 - d1)
    away = goal_metrics(_goal_log(+2.0, -0.03), 2)
    assert away["f_ref_toward_goal_N"] == pytest.approx(-2.0 * unit_y)
    assert away["goal_approach_m"] < 0.0
    assert goal_metrics(_goal_log(0.0, 0.0), 2) == {
        "goal_approach_m": 0.0, "f_ref_toward_goal_N": 0.0,
    }  # fmt: skip
    no_human = {k: v for k, v in _goal_log(-2.0, 0.03).items() if not k.startswith("truth")}
    assert goal_metrics(no_human, 2) == {}
