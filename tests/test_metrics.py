"""Metrics on synthetic signals with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.filters import derivatives, lowpass
from ccm.metrics.trial import (
    aggregate,
    force_prediction_metrics,
    learning_curve,
    motion_error,
    trial_metrics,
)


def test_lowpass_step_response_time_constant() -> None:
    dt, fc = 1e-3, 10.0
    y = lowpass(np.ones(2000), dt, fc)
    y0 = lowpass(np.r_[0.0, np.ones(1999)], dt, fc)
    assert y[-1] == pytest.approx(1.0)
    tau = 1.0 / (2 * np.pi * fc)
    k = int(round(tau / dt))
    assert y0[k] == pytest.approx(1 - np.exp(-1), abs=0.02)


def test_derivatives_of_slow_sine() -> None:
    dt = 1e-3
    t = np.arange(0, 4, dt)
    w = 2 * np.pi * 0.5  # 0.5 Hz, far below the 30 Hz cut-off
    vel = np.sin(w * t)[:, None]
    acc, jerk = derivatives(vel, dt, 30.0)
    mid = slice(1000, 3000)
    # filter lag at 0.5 Hz is ~1.7 ms: compare with a 5 % amplitude tolerance
    assert np.max(np.abs(acc[mid, 0])) == pytest.approx(w, rel=0.05)
    assert np.max(np.abs(jerk[mid, 0])) == pytest.approx(w**2, rel=0.05)


def test_motion_error_ignores_force_direction() -> None:
    pos = np.array([[0.0, 0.3], [0.0, 0.0]])
    tgt = np.array([[0.1, 0.0], [0.0, 0.2]])
    fdir = np.array([[0.0, -1.0], [0.0, 0.0]])
    np.testing.assert_allclose(motion_error(pos, tgt, fdir), [0.1, 0.2])


def test_trial_metrics_on_known_log() -> None:
    n, dt = 1000, 1e-3
    t = np.arange(n) * dt
    log = {
        "t": t,
        "pos_x": np.zeros(n),
        "pos_y": np.zeros(n),
        "target_pos_x": np.full(n, 0.003),
        "target_pos_y": np.zeros(n),
        "vel_x": np.zeros(n),
        "vel_y": np.zeros(n),
        "force_dir_x": np.zeros(n),
        "force_dir_y": np.zeros(n),
        "true_force_x": np.zeros(n),
        "true_force_y": np.r_[np.zeros(n - 1), -7.0],
        "stiffness_Npm": np.full(n, 250.0),
    }
    m = trial_metrics(log, 2, dt, 0.5, 30.0, 0.01)
    assert m["rms_tracking_error_m"] == pytest.approx(0.003)
    assert m["max_tracking_error_m"] == pytest.approx(0.003)
    assert m["peak_force_N"] == pytest.approx(7.0)
    assert m["peak_acc_mps2"] == 0.0
    assert m["completion_time_s"] == pytest.approx(0.5)
    assert m["mean_stiffness_Npm"] == pytest.approx(250.0)
    m2 = trial_metrics(log, 2, dt, 0.5, 30.0, 0.001)
    assert m2["completion_time_s"] is None


def test_aggregate_skips_none() -> None:
    out = aggregate([{"a": 1.0, "b": None}, {"a": 3.0, "b": None}])
    assert out == {"a": 2.0, "b": None}


def test_learning_curve_spread_and_ratio() -> None:
    """Seed A Fig. 7b: a learner still moving in its last ten trials has a spread > 0."""
    settled = [{"rms_tracking_error_m": e} for e in [4.0, 2.0] + [1.0] * 10]
    moving = [{"rms_tracking_error_m": e} for e in np.linspace(4.0, 1.0, 12)]
    assert learning_curve(settled) == {
        "rms_error_spread_last10": 0.0,
        "rms_error_last_over_first": 0.25,
    }
    spread = learning_curve(moving)["rms_error_spread_last10"]
    tail = np.linspace(4.0, 1.0, 12)[-10:]
    assert spread == pytest.approx((tail.max() - tail.min()) / tail.mean())
    assert learning_curve(settled[:5])["rms_error_spread_last10"] is None, "needs ten trials"


def test_force_prediction_splits_tracking_at_the_unseen_viscosity() -> None:
    n = 100
    visc = np.linspace(0.0, 150.0, n)
    err = np.where(visc > 80.0, 0.004, 0.001)  # m, along x
    z = np.zeros(n)
    log = {
        "t": np.arange(n) * 1e-3, "truth_viscosity_Nspm": visc,
        "pos_x": z, "pos_y": z, "target_pos_x": err, "target_pos_y": z,
        "force_dir_x": z, "force_dir_y": z, "force_x": z + 1.0, "force_y": z,
        "pred_force_N": z + 1.0, "persist_force_N": z + 1.5,
    }  # fmt: skip
    out = force_prediction_metrics(log, 2, {"unseen_above_Nspm": 80.0})
    assert out["rms_tracking_error_unseen_m"] == pytest.approx(0.004)
    assert out["rms_tracking_error_seen_m"] == pytest.approx(0.001)
    assert out["pred_skill_unseen"] == pytest.approx(1.0), "exact prediction, persistence off"
