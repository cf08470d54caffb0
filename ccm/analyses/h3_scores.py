"""Scores of the H3 predictions against the test trial (seed A §4.4, Figs 11-14).

Each function scores one test trial. ``wall`` marks the predicted steps in contact with the
wall (mode 2 of :mod:`ccm.analyses.h3_data`), i.e. after the wall contact, where the test trial
meets the unseen friction 0.9; seed A Figs 13-14 discuss the force there. Scores on an empty
selection (a trial that never reached the wall) are None.

* :func:`joint_scores`: the joint-space rollouts (§4.4.1, Figs 11-12).
* :func:`gp_force_scores`: a force-*vector* prediction with its std (the task-space GPs,
  §4.4.2-4.4.3, Figs 13-14a), on ‖F‖ and on F_y, the force along the wall.
* :func:`norm_force_scores`: a force-*magnitude* prediction (ccm's incremental model, Fig.
  14b, and persistence), on ‖F‖ and on F_y after turning ‖F̂‖ into a vector along the latest
  measured force (:func:`along_latest`).
"""

from __future__ import annotations

import math

import numpy as np

Y = 1  # the axis along the wall (table_wall: the wall's friction acts along y; seed A Fig. 13)


def rmse(a: np.ndarray, b: np.ndarray) -> float | None:
    """Root-mean-square difference; None for no samples."""
    d = np.asarray(a) - np.asarray(b)
    return float(np.sqrt(np.mean(d**2))) if d.size else None


def coverage(truth: np.ndarray, mean: np.ndarray, std: np.ndarray) -> float | None:
    """Share of true values inside mean ± 1.96 std (a calibrated band gives 0.95); None for
    no samples."""
    inside = np.abs(np.asarray(truth) - mean) <= 1.96 * np.asarray(std)
    return float(np.mean(inside)) if inside.size else None


def lag(truth: np.ndarray, pred: np.ndarray, dt: float, max_s: float = 2.0) -> float:
    """Delay [s] that best aligns the truth with the prediction (least squares over the
    overlap): > 0 when the truth lags the prediction (seed A Fig. 11), < 0 when it leads."""
    n = len(truth)
    best, best_k = math.inf, 0
    for k in range(-int(max_s / dt), int(max_s / dt) + 1):
        a, b = (truth[k:], pred[: n - k]) if k >= 0 else (truth[: n + k], pred[-k:])
        err = float(np.mean((a - b) ** 2))
        if err < best:
            best, best_k = err, k
    return best_k * dt


def along_latest(norm_pred: np.ndarray, f_latest: np.ndarray) -> np.ndarray:
    """F̂ = ‖F̂‖ F_t / ‖F_t‖: a predicted magnitude (n,) as a vector (n, 3) along the latest
    measured force F_t (n, 3); zero where ‖F_t‖ = 0 (no direction to take)."""
    f_latest = np.asarray(f_latest, dtype=float)
    n = np.linalg.norm(f_latest, axis=1, keepdims=True)
    unit = np.divide(f_latest, n, out=np.zeros_like(f_latest), where=n > 0.0)
    return np.asarray(norm_pred, dtype=float)[:, None] * unit


def joint_scores(truth: np.ndarray, mean: np.ndarray, std: np.ndarray, dt: float) -> dict:
    """Scores of a joint-space rollout over the 7 joint positions (columns 0-6 of [q, q̇]):
    ``joint_pred_rmse_rad``, ``coverage_95``, the mean 95 % band width ``band_width_rad``
    (seed A Figs 11-12 compare band widths) and ``joint_lag_s`` (:func:`lag`, Fig. 11a)."""
    q, m, s = truth[:, :7], mean[:, :7], std[:, :7]
    return {
        "joint_pred_rmse_rad": rmse(m, q),
        "coverage_95": coverage(q, m, s),
        "band_width_rad": float(np.mean(2 * 1.96 * s)),
        "joint_lag_s": lag(q, m, dt),
    }


def gp_force_scores(
    truth: np.ndarray, mean: np.ndarray, std: np.ndarray, wall: np.ndarray
) -> dict[str, float | None]:
    """Scores of a force-vector prediction (n, 3) with its std (module docstring).

    ‖F‖: ``force_pred_rmse_N`` (‖F̂‖ of the predicted vector), ``force_pred_rmse_wall_N``;
    F_y: ``force_y_pred_rmse_N``, ``force_y_pred_rmse_wall_N`` (Figs 13-14); band:
    ``coverage_95`` / ``coverage_95_wall`` (all three axes), ``coverage_95_y_wall`` (F_y
    after the wall contact, Fig. 13), ``band_width_N`` (all axes, whole trial) and
    ``band_width_y_wall_N`` (F_y after the wall contact).
    """
    f_hat, f = np.linalg.norm(mean, axis=1), np.linalg.norm(truth, axis=1)
    y, y_hat, y_std = truth[:, Y], mean[:, Y], std[:, Y]
    return {
        "force_pred_rmse_N": rmse(f_hat, f),
        "force_pred_rmse_wall_N": rmse(f_hat[wall], f[wall]),
        "force_y_pred_rmse_N": rmse(y_hat, y),
        "force_y_pred_rmse_wall_N": rmse(y_hat[wall], y[wall]),
        "coverage_95": coverage(truth, mean, std),
        "coverage_95_wall": coverage(truth[wall], mean[wall], std[wall]),
        "coverage_95_y_wall": coverage(y[wall], y_hat[wall], y_std[wall]),
        "band_width_N": float(np.mean(2 * 1.96 * std)),
        "band_width_y_wall_N": float(np.mean(2 * 1.96 * y_std[wall])) if wall.any() else None,
    }


def norm_force_scores(
    norm_pred: np.ndarray, force: np.ndarray, wall: np.ndarray
) -> dict[str, float | None]:
    """Scores of a one-step magnitude prediction: ``norm_pred[k]`` predicts ‖F_{k+1}‖ from the
    data up to step k; ``force`` (n + 1, 3) is the measured force; ``wall`` (n,) marks the
    predicted steps after the wall contact. F_y is scored on :func:`along_latest` of the
    prediction and F_k (persistence, ‖F̂_{k+1}‖ = ‖F_k‖, thus predicts F_y,k)."""
    f = np.linalg.norm(force, axis=1)
    y_hat = along_latest(norm_pred, force[:-1])[:, Y]
    y = force[1:, Y]
    return {
        "force_pred_rmse_N": rmse(norm_pred, f[1:]),
        "force_pred_rmse_wall_N": rmse(norm_pred[wall], f[1:][wall]),
        "force_y_pred_rmse_N": rmse(y_hat, y),
        "force_y_pred_rmse_wall_N": rmse(y_hat[wall], y[wall]),
    }
