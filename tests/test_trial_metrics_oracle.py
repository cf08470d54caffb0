"""Oracle test of the per-trial metrics every hypothesis reads (``ccm.metrics.trial.
trial_metrics``; issue #39 item 1): each value against its definition on a constructed log."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.filters import derivatives
from ccm.metrics.trial import trial_metrics

DT, N = 0.001, 2000


def _log() -> dict[str, np.ndarray]:
    """Two axes: velocities with different spectra (so that per-row norms differ from a
    whole-matrix norm), the true force (3, 4) N at one step and (0, 1) N elsewhere, a
    tracking error of 2 mm that falls to 0.5 mm from 1.5 s."""
    t = np.arange(N) * DT
    vx = 0.1 * np.sin(2 * np.pi * 2.0 * t)
    vy = 0.05 * np.sin(2 * np.pi * 5.0 * t + 0.3)
    err = np.where(t < 1.5 - 1e-9, 0.002, 0.0005)
    fx, fy = np.zeros(N), np.ones(N)
    fx[700], fy[700] = 3.0, 4.0
    zeros = np.zeros(N)
    return {
        "t": t, "pos_x": err, "pos_y": zeros, "target_pos_x": zeros, "target_pos_y": zeros,
        "vel_x": vx, "vel_y": vy, "force_dir_x": zeros, "force_dir_y": zeros,
        "true_force_x": fx, "true_force_y": fy, "stiffness_Npm": np.full(N, 400.0),
    }  # fmt: skip


def test_trial_metrics_give_their_definitions_values() -> None:
    log = _log()
    m = trial_metrics(log, 2, DT, pattern_duration=1.0, lowpass_hz=30.0, completion_tol_m=0.001)
    acc, jerk = derivatives(np.column_stack([log["vel_x"], log["vel_y"]]), DT, 30.0)
    # per step: the norm over the axes; then the max (acceleration) or RMS over steps (jerk)
    assert m["peak_acc_mps2"] == pytest.approx(np.max(np.hypot(acc[:, 0], acc[:, 1])))
    assert m["rms_jerk_mps3"] == pytest.approx(np.sqrt(np.mean(jerk[:, 0] ** 2 + jerk[:, 1] ** 2)))
    assert m["peak_force_N"] == pytest.approx(5.0)  # ‖(3, 4)‖, not the whole log's norm
    # error 2 mm until 1.5 s: done at the first step after the pattern's end within 1 mm
    assert m["completion_time_s"] == pytest.approx(1.5)
    assert m["rms_tracking_error_m"] == pytest.approx(np.sqrt(0.75 * 0.002**2 + 0.25 * 0.0005**2))
    assert m["max_tracking_error_m"] == pytest.approx(0.002)
    assert m["mean_stiffness_Npm"] == 400.0


def test_completion_counts_from_the_patterns_end_inclusive() -> None:
    log = _log()
    log["pos_x"] = np.full(N, 0.0005)  # always within tolerance
    m = trial_metrics(log, 2, DT, pattern_duration=0.7, lowpass_hz=30.0, completion_tol_m=0.001)
    assert m["completion_time_s"] == pytest.approx(0.7)
    never = trial_metrics(_log(), 2, DT, 1.0, 30.0, completion_tol_m=0.0001)
    assert never["completion_time_s"] is None
