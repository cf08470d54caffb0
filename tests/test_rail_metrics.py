"""The rail-task metrics of seed B §6.2 (ccm/metrics/mpc.py) on small synthetic logs, and
the mpc_rail configuration (issue #18)."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.metrics.mpc import gp_mpc_metrics, rail_distance, rail_metrics

PARAMS = {
    "rail_point": [0.0, 0.10],
    "rail_normal": [0.0, -1.0],
    "tool_half_extent_m": 0.0,
    "rail_contact_force_N": 5.0,
    "near_rail_m": 0.02,
    "far_rail_m": 0.05,
    "varied_axis": "x",
    "repeatable_axis": "y",
}


def _log(y: np.ndarray, fy: np.ndarray, dx: np.ndarray, dy: np.ndarray) -> dict:
    """A 2-D trial at 1 kHz: y path, contact force along y, damping per axis."""
    n = len(y)
    return {
        "t": np.arange(n) * 1e-3,
        "pos_x": np.zeros(n),
        "pos_y": y,
        "vel_x": np.zeros(n),
        "vel_y": np.gradient(y, 1e-3),
        "contact_force_x": np.zeros(n),
        "contact_force_y": fy,
        "n_contacts": (fy != 0).astype(float),
        "damping_x_Nspm": dx,
        "damping_y_Nspm": dy,
    }


def _approach(press_N: float) -> dict:
    """0.0 -> 0.1 m in 1 s, then 1 s on the rail pressed with ``press_N`` (pushing along -y)."""
    y = np.concatenate([np.linspace(0.0, 0.10, 1000), np.full(1000, 0.1001)])
    fy = np.concatenate([np.zeros(1000), np.full(1000, -press_N)])
    dy = np.where(y > 0.08, 2000.0, 500.0)  # high only within 2 cm of the rail
    dx = np.full_like(y, 600.0)
    return _log(y, fy, dx, dy)


def test_distance_is_the_gap_along_the_normal() -> None:
    log = _log(np.array([0.0, 0.05, 0.1, 0.11]), np.zeros(4), np.ones(4), np.ones(4))
    assert rail_distance(log, 2, PARAMS) == pytest.approx([0.10, 0.05, 0.0, -0.01])
    off = rail_distance(log, 2, {**PARAMS, "tool_half_extent_m": 0.02})
    assert off == pytest.approx([0.08, 0.03, -0.02, -0.03])


def test_reaching_and_pressing_is_a_success_with_its_time() -> None:
    out = rail_metrics(_approach(press_N=15.0), 2, PARAMS)
    assert out["task_success"] == 1.0
    assert out["time_to_rail_s"] == pytest.approx(1.0, abs=2e-3)
    # near = the last 2 cm and the contact: D_y 2000 there (the step at y = 0.08 is inside)
    assert out["near_damping_y_Nspm"] == pytest.approx(2000.0, rel=0.01)
    assert out["near_damping_x_Nspm"] == pytest.approx(600.0)
    assert out["far_damping_y_Nspm"] == pytest.approx(500.0)
    assert out["near_damping_ratio_varied_repeatable"] == pytest.approx(0.3, rel=0.01)


def test_the_ratchet_control_compares_the_two_axes_rises() -> None:
    """A rise that is only time (D ratcheting up on both axes alike) gives 1; a rise along y
    alone gives y's near/far ratio (issue #37: the control of B-6.2-rail-impedance-rises)."""
    out = rail_metrics(_approach(press_N=15.0), 2, PARAMS)
    # y: 500 far -> 2000 near (x4); x flat at 600 (x1): the repeatable axis rose 4x more
    assert out["damping_rise_repeatable_over_varied"] == pytest.approx(4.0, rel=0.01)
    log = _approach(press_N=15.0)
    ramp = np.linspace(500.0, 2000.0, 2000)  # both axes ratchet up alike with time
    log["damping_x_Nspm"], log["damping_y_Nspm"] = ramp.copy(), ramp.copy()
    timed = rail_metrics(log, 2, PARAMS)
    assert timed["near_damping_y_Nspm"] > 1.5 * timed["far_damping_y_Nspm"]  # "rises near"
    assert timed["damping_rise_repeatable_over_varied"] == pytest.approx(1.0)  # ... by time


def test_a_graze_below_the_force_threshold_is_not_a_success() -> None:
    out = rail_metrics(_approach(press_N=3.0), 2, PARAMS)
    assert out["task_success"] == 0.0
    assert out["time_to_rail_s"] is None
    assert out["near_damping_y_Nspm"] is not None  # it was near, just not pressing


def test_a_trial_that_stops_short_fails_and_has_no_near_rail_damping() -> None:
    y = np.linspace(0.0, 0.03, 2000)  # ends 7 cm before the rail (main's old behaviour)
    log = _log(y, np.zeros_like(y), np.full_like(y, 1200.0), np.full_like(y, 3000.0))
    out = rail_metrics(log, 2, PARAMS)
    assert out["task_success"] == 0.0 and out["time_to_rail_s"] is None
    assert out["min_rail_distance_m"] == pytest.approx(0.07)
    assert out["near_damping_y_Nspm"] is None
    assert out["near_damping_ratio_varied_repeatable"] is None
    assert out["far_damping_y_Nspm"] == pytest.approx(3000.0)


def test_a_force_pulling_away_from_the_rail_does_not_count() -> None:
    log = _approach(press_N=-15.0)  # +y force: not the rail's push (wrong sign)
    assert rail_metrics(log, 2, PARAMS)["task_success"] == 0.0


def test_gp_mpc_metrics_adds_the_rail_metrics_only_with_a_rail() -> None:
    log = {**_approach(15.0), "mass_x_kg": np.ones(2000)}
    with_rail = gp_mpc_metrics(log, 2, PARAMS)
    assert with_rail["task_success"] == 1.0
    without = gp_mpc_metrics(log, 2, {k: v for k, v in PARAMS.items() if k != "rail_point"})
    assert "task_success" not in without


def test_missing_threshold_names_its_key() -> None:
    params = {k: v for k, v in PARAMS.items() if k != "rail_contact_force_N"}
    with pytest.raises(ConfigError, match="metrics.rail_contact_force_N"):
        rail_metrics(_approach(15.0), 2, params)


def test_mpc_rail_config_composes(composer) -> None:
    cfg = composer(["experiment=mpc_rail"])
    assert list(cfg.metrics.rail_point) == [0.0, 0.10]
    assert list(cfg.metrics.rail_normal) == [0.0, -1.0]
    assert list(cfg.controller.mpc.f_ref_target) == [0.0, -15.0]
    assert cfg.controller.mpc.weights.f_ref_target > 0
    names = [p.name for p in cfg.experiment.phases]
    assert names == ["demo_left", "demo_middle", "demo_right", "autonomous", "execution"]
    assert "controller.mpc.weights.pos_var=0.0" in cfg.experiment.conditions.no_variance_cost
    assert cfg.controller.mpc.weights.pos_var > 0
