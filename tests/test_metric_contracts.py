"""The metrics' contracts that the oracle tests leave open (issue #39 item 1): the key set a
metric returns when its input is missing, each setting's refusal naming its key, and the
learning-curve and goal-belief edge cases, each against the value its definition gives.

The mutation run (``make mutation ARGS=metrics``) showed these: a misspelt output key, a
refusal that loses its key, a goal read from the first row instead of the last.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.metrics.contacts import contact_metrics
from ccm.metrics.modes import mode_metrics
from ccm.metrics.mpc import gp_mpc_metrics
from ccm.metrics.trial import (
    condition_summary,
    force_prediction_metrics,
    learning_curve,
    trial_metrics,
)
from tests.refusals import refusal
from tests.test_mpc_metrics_oracle import PARAMS, _log

_line = partial(refusal, ConfigError)


# ----------------------------------------------------------------------------- learning curve


def _trials(*errors: float) -> list[dict[str, float]]:
    return [{"rms_tracking_error_m": e} for e in errors]


def test_learning_curve_by_its_definition() -> None:
    """Spread (max − min) / mean of the last n trials; last over first (seed A Fig. 7b)."""
    got = learning_curve(_trials(0.2, 0.1, 0.05), last_n=2)
    assert got == pytest.approx({"rms_error_spread_last10": 0.05 / 0.075,
                                 "rms_error_last_over_first": 0.25})  # fmt: skip
    # one trial has no curve; a first error of 0 gives no ratio; fewer than n trials no spread
    assert learning_curve(_trials(0.2), last_n=1)["rms_error_last_over_first"] is None
    assert learning_curve(_trials(0.0, 0.1), last_n=5) == {
        "rms_error_spread_last10": None, "rms_error_last_over_first": None,
    }  # fmt: skip
    assert _line(learning_curve, _trials(0.1), 0) == (
        "metrics.convergence_trials: must be an integer >= 1, got 0"
    )


def test_condition_summary_passes_its_convergence_window() -> None:
    """Three trials: with a window of 2 the spread exists; with the default 10 it does not."""
    trials = _trials(0.2, 0.1, 0.05)
    assert condition_summary(trials, 2)["rms_error_spread_last10"] == pytest.approx(0.05 / 0.075)
    assert condition_summary(trials)["rms_error_spread_last10"] is None


# ----------------------------------------------------------------------------- key sets


def test_force_prediction_without_a_forward_model_reports_its_keys_as_none() -> None:
    assert force_prediction_metrics({"t": np.zeros(3)}, 2, {}) == {
        "force_pred_rmse_N": None, "force_pred_rmse_unseen_N": None,
    }  # fmt: skip


def test_force_prediction_names_its_seen_and_unseen_rows() -> None:
    n = 4
    log = {
        "t": np.arange(n) * 0.001, "pred_force_N": np.full(n, 1.0),
        "persist_force_N": np.full(n, 2.0), "truth_viscosity_Nspm": np.array([10, 10, 90, 90]),
        **{f"{p}_{a}": np.zeros(n) for p in ("pos", "target_pos", "force_dir") for a in "xy"},
        "force_x": np.full(n, 1.5), "force_y": np.zeros(n),
    }  # fmt: skip
    out = force_prediction_metrics(log, 2, {"unseen_above_Nspm": 80.0})
    for rows in ("seen", "unseen"):
        assert out[f"pred_rmse_{rows}_N"] == pytest.approx(0.5)
        assert out[f"persist_rmse_{rows}_N"] == pytest.approx(0.5)
        assert f"pred_skill_{rows}" in out and f"rms_tracking_error_{rows}_m" in out


def test_far_from_human_without_damping_keeps_its_keys() -> None:
    log = {k: v for k, v in _log().items() if not k.startswith("damping_")}
    out = gp_mpc_metrics(log, 2, PARAMS)
    assert out["mean_damping_far_Nspm"] is None
    assert out["far_from_human_frac"] == pytest.approx(0.4)  # 1 m from the shoulder from 0.6 s


# ----------------------------------------------------------------------------- seed B edges


def test_the_goal_is_the_last_rows_and_a_wrong_belief_scores_zero() -> None:
    """The human's goal at the end of the trial counts (row −1, not an early row); a final
    belief on another goal gives belief_correct_final 0 and no time to belief."""
    log = _log()
    log["truth_human_goal"] = log["truth_human_goal"].copy()
    log["truth_human_goal"][:2] = 0.0  # the goal changed early in the trial
    assert gp_mpc_metrics(log, 2, PARAMS)["belief_correct_final"] == 1.0
    log["truth_human_goal"] = np.zeros(len(log["t"]))  # the belief ends on goal 1, truth is 0
    m = gp_mpc_metrics(log, 2, PARAMS)
    assert m["belief_correct_final"] == 0.0 and m["time_to_belief_s"] is None


def test_a_one_step_loss_counts_when_the_minimum_is_one_step() -> None:
    log = _log()
    log["n_contacts"] = log["n_contacts"].copy()
    log["n_contacts"][600] = 0.0  # one step without contact
    params = {**PARAMS, "contact_loss_min_s": 0.001}
    assert gp_mpc_metrics(log, 2, params)["contact_losses"] == 3.0  # 10 ms, 3 ms and 1 ms


# ----------------------------------------------------------------------------- refusals


def test_metric_settings_refusals_name_their_keys() -> None:
    log = _log()
    assert _line(gp_mpc_metrics, log, 2, {**PARAMS, "press_hold_s": -1.0}) == (
        "metrics.press_hold_s: must be >= 0, got -1.0"
    )
    rail = {"rail_point": [0.0, 0.0], "rail_normal": [1.0, 0.0], "rail_contact_force_N": 1.0,
            "near_rail_m": -0.1}  # fmt: skip
    assert _line(gp_mpc_metrics, log, 2, rail) == "metrics.near_rail_m: must be >= 0, got -0.1"
    assert _line(contact_metrics, log, 2, {"impact_force_target_N": 0.0}) == (
        "metrics.impact_force_target_N: must be > 0, got 0.0"
    )
    modes = {"transition_pre_s": 0.1, "transition_tolerance_s": 0.1, "high_stiffness_Npm": -1}
    assert _line(mode_metrics, {"mode": np.zeros(3), "t": np.zeros(3)}, 2, modes) == (
        "metrics.high_stiffness_Npm: must be > 0, got -1"
    )
    assert _line(trial_metrics, log, 2, 0.001, 1.0, 0.0, 0.01) == (
        "metrics.lowpass_hz: must be > 0, got 0.0"
    )


@pytest.mark.parametrize(
    ("event", "runs"),
    [([0, 1, 1, 1, 0, 0, 1, 1, 0], 2), ([1, 1, 0, 1], 2), ([0, 0, 0], 0), ([1, 1, 1], 1)],
)
def test_collision_events_are_counted_as_runs(event: list[int], runs: int) -> None:
    """``n_collision_events``: runs of consecutive steps with ``collision_event`` > 0 (a
    detector that holds its flag for several steps reports one event)."""
    n = len(event)
    log = {"t": np.arange(n) * 0.001, "collision_event": np.array(event, float)}
    assert contact_metrics(log, 2, {"lowpass_hz": 20.0})["n_collision_events"] == runs


def test_two_trials_make_a_learning_curve() -> None:
    assert learning_curve(_trials(0.2, 0.1), last_n=1)["rms_error_last_over_first"] == 0.5
