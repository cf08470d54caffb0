"""Prediction skill and stiffness adaptation metrics (ccm/metrics/adaptation.py, issue #16)."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.metrics.adaptation import environment_changes, prediction_skill, stiffness_adaptation


def log(n: int = 1000, **cols: np.ndarray) -> dict[str, np.ndarray]:
    base = {"t": np.arange(n) * 0.001, "force_x": np.zeros(n), "force_y": np.zeros(n)}
    return {**base, **cols}


def test_skill_is_one_minus_the_rmse_ratio_on_shared_samples() -> None:
    n = 100
    f = np.linspace(1.0, 2.0, n)
    pred = f + 0.1  # RMSE 0.1
    persist = f - 0.4  # RMSE 0.4
    pred[:10] = np.nan  # no prediction yet: those samples are skipped for both
    persist[10:20] = 999.0
    lg = log(n, force_x=f, pred_force_N=pred, persist_force_N=persist)
    rows = np.arange(n) >= 20
    out = prediction_skill(lg, 2, rows)
    assert out["pred_rmse_N"] == pytest.approx(0.1)
    assert out["persist_rmse_N"] == pytest.approx(0.4)
    assert out["pred_skill"] == pytest.approx(0.75)
    assert prediction_skill(log(n), 2) == {}, "no forward model, no skill"


def test_stiffness_rise_at_a_spring_attaching() -> None:
    """K = 3000 for 50 ms after a spring attaches, 300 elsewhere: active 5 %, rise > 1."""
    n = 2000
    springs = np.where(np.arange(n) >= 1000, 2.0, 1.0)
    k = np.full(n, 300.0)
    k[1000:1050] = 3000.0
    params = {"controller_report": {"k_free": 300.0}, "change_window_s": 0.2}
    out = stiffness_adaptation(log(n, stiffness_Npm=k, truth_springs_attached=springs), params)
    assert out["n_environment_changes"] == 1.0
    assert out["stiffness_active_frac"] == pytest.approx(0.025)
    window = (50 * 3000.0 + 150 * 300.0) / 200
    assert out["stiffness_rise_at_change"] == pytest.approx(window / 300.0)
    assert stiffness_adaptation(log(n, stiffness_Npm=k), {}) == {}, "needs K_free"


def test_environment_changes_ignore_a_ramp_but_see_a_step() -> None:
    n = 100
    visc = np.linspace(0.0, 2.5, n)  # 0.025 per step: a ramp
    visc[60:] += 5.0  # a step
    mu = np.full(n, -1.0)
    mu[30:50], mu[50:] = 0.2, 0.5  # contact made at 30, surface change at 50
    contact = (mu >= 0).astype(float)
    lg = log(n, truth_viscosity_Nspm=visc, truth_surface_friction=mu, truth_contact=contact)
    np.testing.assert_array_equal(environment_changes(lg, {}), [30, 50, 60])
