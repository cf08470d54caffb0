"""Per-trial metrics from a trial log (the summary.json metrics; names carry units)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_int_positive, check_positive
from ccm.core.filters import derivatives
from ccm.core.protocols import Metric
from ccm.metrics._lag_kernels import best_lag_steps
from ccm.metrics.adaptation import measured_force_norm, prediction_skill, stiffness_adaptation
from ccm.metrics.contacts import contact_metrics
from ccm.metrics.modes import in_contact_steps, mode_metrics, true_transition_steps
from ccm.metrics.mpc import gp_mpc_metrics
from ccm.metrics.suite import suite_metrics

#: metrics every trial reports (issue #2)
BASE_METRICS = (
    "rms_tracking_error_m",
    "max_tracking_error_m",
    "peak_force_N",
    "peak_acc_mps2",
    "rms_jerk_mps3",
    "completion_time_s",
    "mean_stiffness_Npm",
)


def motion_error(position: np.ndarray, target: np.ndarray, force_dir: np.ndarray) -> np.ndarray:
    """Tracking error [m] in the motion-controlled subspace, per sample.

    Along a force-controlled direction d the position target is not tracked (Eq. 1's u_fc
    regulates force there), so that component is removed: e = (I − d dᵀ)(x_d − x). Rows of
    ``force_dir`` that are zero mean pure motion control.
    """
    err = target - position
    along = np.sum(err * force_dir, axis=1, keepdims=True)
    return np.linalg.norm(err - along * force_dir, axis=1)


def trial_metrics(
    log: Mapping[str, np.ndarray],
    dim: int,
    control_dt: float,
    pattern_duration: float,
    lowpass_hz: float,
    completion_tol_m: float,
) -> dict[str, float | None]:
    """Compute the issue #2 metrics for one trial.

    ``log`` holds arrays keyed like the time-series columns: ``t``, ``pos_*``, ``target_pos_*``,
    ``vel_*``, ``force_dir_*``, ``true_force_*``, ``stiffness_Npm``.

    * peak_force_N: max |true external force| (noise-free, ground truth — metrics may use it).
    * peak_acc_mps2 / rms_jerk_mps3: from the measured velocity through :func:`derivatives`.
    * completion_time_s: first time at or after the pattern's end when the motion error is
      within ``completion_tol_m``; ``None`` if never reached during the trial.
    * pred_skill, pred_rmse_N, persist_rmse_N: for a controller with a forward model
      (:func:`ccm.metrics.adaptation.prediction_skill`).
    """
    check_positive("metrics.lowpass_hz", lowpass_hz)
    axes = "xyz"[:dim]
    t = log["t"]
    pos = np.column_stack([log[f"pos_{a}"] for a in axes])
    tgt = np.column_stack([log[f"target_pos_{a}"] for a in axes])
    vel = np.column_stack([log[f"vel_{a}"] for a in axes])
    fdir = np.column_stack([log[f"force_dir_{a}"] for a in axes])
    f_true = np.column_stack([log[f"true_force_{a}"] for a in axes])
    err = motion_error(pos, tgt, fdir)
    acc, jerk = derivatives(vel, control_dt, lowpass_hz)
    done = np.nonzero((t >= pattern_duration - 1e-12) & (err <= completion_tol_m))[0]
    stiff = log.get("stiffness_Npm")
    mean_stiff = (
        float(np.nanmean(stiff)) if stiff is not None and np.any(np.isfinite(stiff)) else None
    )
    return {
        **prediction_skill(log, dim),
        "rms_tracking_error_m": float(np.sqrt(np.mean(err**2))),
        "max_tracking_error_m": float(np.max(err)),
        "peak_force_N": float(np.max(np.linalg.norm(f_true, axis=1))),
        "peak_acc_mps2": float(np.max(np.linalg.norm(acc, axis=1))),
        "rms_jerk_mps3": float(np.sqrt(np.mean(np.sum(jerk**2, axis=1)))),
        "completion_time_s": float(t[done[0]]) if done.size else None,
        "mean_stiffness_Npm": mean_stiff,
    }


def aggregate(trials: Sequence[Mapping[str, float | None]]) -> dict[str, float | None]:
    """Mean of each metric over trials, skipping ``None``; ``None`` if no trial has a value."""
    keys: list[str] = []
    for tr in trials:
        keys.extend(k for k in tr if k not in keys)
    out: dict[str, float | None] = {}
    for k in keys:
        vals = [float(tr[k]) for tr in trials if isinstance(tr.get(k), int | float)]
        out[k] = float(np.mean(vals)) if vals else None
    return out


def learning_curve(
    trials: Sequence[Mapping[str, float | None]], last_n: int = 10
) -> dict[str, float | None]:
    """Across-trial facts of one condition's RMS tracking error (seed A Fig. 7b).

    ``rms_error_spread_last10``: (max − min) / mean of the last ``last_n`` trials' errors
    (``metrics.convergence_trials``), 0 for a settled learner, None with fewer trials;
    ``rms_error_last_over_first``: the last trial's error over the first's.
    """
    e = [float(t["rms_tracking_error_m"]) for t in trials
         if isinstance(t.get("rms_tracking_error_m"), int | float)]  # fmt: skip
    n = check_int_positive("metrics.convergence_trials", last_n)
    tail = np.asarray(e[-n:])
    return {
        "rms_error_spread_last10": float(np.ptp(tail) / np.mean(tail))
        if len(e) >= n and np.mean(tail) > 0
        else None,
        "rms_error_last_over_first": e[-1] / e[0] if len(e) > 1 and e[0] > 0 else None,
    }


def condition_summary(
    trials: Sequence[Mapping[str, float | None]], convergence_trials: int = 10
) -> dict[str, float | None]:
    """A condition's entry in summary.json: the trial means (:func:`aggregate`) and the
    :func:`learning_curve` of its trials (in trial order)."""
    return {**aggregate(trials), **learning_curve(trials, convergence_trials)}


def force_prediction_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, float]
) -> dict[str, float | None]:
    """Force-prediction RMSE and skill (seed A §4.1, Fig. 4).

    Compares the controller's ``pred_force_N`` signal — its prediction of ‖F_t‖ made from
    S_{t−H} (Eq. 6, horizon H) — with the measured ‖F_t‖. ``unseen`` rows are those whose true
    viscosity exceeds ``params['unseen_above_Nspm']`` (the end of the training ramp);
    ``pred_skill_seen`` / ``pred_skill_unseen`` compare with persistence on those rows, and
    ``rms_tracking_error_seen_m`` / ``_unseen_m`` give the tracking error there.
    """
    if "pred_force_N" not in log:
        return {"force_pred_rmse_N": None, "force_pred_rmse_unseen_N": None}
    meas = measured_force_norm(log, dim)
    pred = log["pred_force_N"]
    ok = np.isfinite(pred)
    out: dict[str, float | None] = {
        "force_pred_rmse_N": float(np.sqrt(np.mean((pred[ok] - meas[ok]) ** 2)))
        if ok.any()
        else None
    }
    visc = log.get("truth_viscosity_Nspm")
    limit = params.get("unseen_above_Nspm")
    beyond = visc > float(limit) if visc is not None and limit is not None else ok & False
    unseen = ok & beyond
    out["force_pred_rmse_unseen_N"] = (
        float(np.sqrt(np.mean((pred[unseen] - meas[unseen]) ** 2))) if unseen.any() else None
    )
    seen = ok & ~unseen
    out["force_pred_rmse_seen_N"] = (
        float(np.sqrt(np.mean((pred[seen] - meas[seen]) ** 2))) if seen.any() else None
    )
    out.update(prediction_skill(log, dim, seen, "_seen"))
    out.update(prediction_skill(log, dim, unseen, "_unseen"))
    axes = "xyz"[:dim]
    err = motion_error(*(np.column_stack([log[f"{p}_{a}"] for a in axes])
                         for p in ("pos", "target_pos", "force_dir")))  # fmt: skip
    for name, rows in (("seen", ~beyond), ("unseen", beyond)):  # seed A §4.1: tracking there
        out[f"rms_tracking_error_{name}_m"] = (
            float(np.sqrt(np.mean(err[rows] ** 2))) if rows.any() else None
        )
    return out


def lag_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, float]
) -> dict[str, float | None]:
    """Lag behind the target [s]: the delay τ ∈ [0, max_lag_s] minimising the RMS distance
    between the path x(t) and the delayed target x_d(t − τ) (seed A §4.2.2, "AIC lags")."""
    t = log["t"]
    if len(t) < 3:
        return {"lag_s": None}
    dt = float(np.median(np.diff(t)))
    pos = np.column_stack([log[f"pos_{a}"] for a in "xyz"[:dim]])
    tgt = np.column_stack([log[f"target_pos_{a}"] for a in "xyz"[:dim]])
    max_shift = min(len(t) // 2, int(round(float(params.get("max_lag_s", 1.0)) / dt)))
    # every 2 ms of delay; the first smallest mean of ‖x(t_i + k) − x_d(t_i)‖² over i
    best_k = best_lag_steps(pos, tgt, max_shift, max(1, int(round(0.002 / dt))))
    return {"lag_s": best_k * dt}


def _block_peaks(err: np.ndarray, mask: np.ndarray, length: int) -> np.ndarray:
    """Peak of ``err`` in each whole block of ``length`` consecutive ``mask`` steps."""
    steps = np.flatnonzero(mask)
    runs = np.split(steps, np.flatnonzero(np.diff(steps) > 1) + 1) if steps.size else []
    peaks = [
        err[r[i : i + length]].max() for r in runs for i in range(0, len(r) - length + 1, length)
    ]
    return np.asarray(peaks, dtype=float)


def error_spike_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, float]
) -> dict[str, float | None]:
    """Tracking-error spikes at surface changes (seed A §4.3, Fig. 10b: "the peaks in the
    trajectory error plot correspond to a sudden change of surface").

    True transitions are those of :mod:`ccm.metrics.modes` (truth columns; metrics only). Each
    has a window [t_j − ``transition_pre_s``, t_j + ``spike_window_s``]. The in-contact steps
    outside every window are cut into blocks of the same length; their peaks of the motion
    error (:func:`motion_error`) are the background. A transition *spikes* if its window's
    peak exceeds the ``spike_quantile`` quantile of the background peaks.
    ``error_spike_frac``: spiking transitions / all; ``error_spike_ratio``: the median window
    peak over the median background peak (≈ 1 when changes look like anywhere else). Both
    None without truth columns, transitions, or at least 5 background blocks.
    """
    out: dict[str, float | None] = {"error_spike_frac": None, "error_spike_ratio": None}
    truth = in_contact_steps(log)
    if truth is None:
        return out
    sid, contact = truth
    steps = true_transition_steps(sid, contact)
    pre = check_positive("metrics.transition_pre_s", params.get("transition_pre_s"))
    after = check_positive("metrics.spike_window_s", params.get("spike_window_s"))
    q = check_positive("metrics.spike_quantile", params.get("spike_quantile"))
    if q >= 1.0:
        raise ConfigError("metrics.spike_quantile", f"must be a quantile in (0, 1), got {q}")
    t = np.asarray(log["t"], dtype=float)
    if not steps.size or len(t) < 2:
        return out
    axes = "xyz"[:dim]
    err = motion_error(*(np.column_stack([log[f"{p}_{a}"] for a in axes])
                         for p in ("pos", "target_pos", "force_dir")))  # fmt: skip
    windows = [(t >= t[j] - pre) & (t <= t[j] + after) for j in steps]
    length = max(1, int(round((pre + after) / float(np.median(np.diff(t))))))
    background = _block_peaks(err, contact & ~np.any(windows, axis=0), length)
    if background.size < 5:
        return out
    peaks = np.array([err[w].max() for w in windows])
    out["error_spike_frac"] = float(np.mean(peaks > np.quantile(background, q)))
    typical = float(np.median(background))
    out["error_spike_ratio"] = float(np.median(peaks) / typical) if typical > 0 else None
    return out


#: name -> function(log, dim, params) -> metrics; chosen per experiment in experiment.metrics
EXTRA_METRICS: dict[str, Metric] = {
    "force_prediction": force_prediction_metrics,
    "lag": lag_metrics,
    "modes": mode_metrics,
    "error_spikes": error_spike_metrics,
    "contacts": contact_metrics,
    "gp_mpc": gp_mpc_metrics,
    "suite": suite_metrics,
}


def check_extra_metrics(cfg: Any) -> list[str]:
    """Validate ``experiment.metrics`` (names from :data:`EXTRA_METRICS`)."""
    names = cfg.experiment.get("metrics") or []
    for name in names:
        if name not in EXTRA_METRICS:
            raise ConfigError(
                "experiment.metrics",
                f"unknown metric {name!r}; allowed: {', '.join(EXTRA_METRICS)}",
            )
    return [str(n) for n in names]


def compute_extra_metrics(
    names: Sequence[str], log: Mapping[str, np.ndarray], comp: Any, cfg: Any,
    base: Mapping[str, Any] | None = None,
) -> dict[str, float | None]:  # fmt: skip
    """Run the experiment's extra metrics on one trial log.

    Each metric gets ``params`` = ``cfg.metrics`` plus ``task_contacts``: the task's expected
    contacts in pattern order, each ``{name, position, kind}`` merged with its annotations
    ``{segment, segment_index, normal}`` (:class:`ccm.tasks.task.Task`; used by ``contacts``,
    :mod:`ccm.metrics.contacts`, seed A §4.5.1) and ``controller_report``: what the controller
    believes after the trial (:meth:`ccm.control.base.Controller.report`), and the trial's
    base metrics as ``completion_time_s`` (``base``; used by ``suite``). Every controller
    that reports K_free (the AVIC family) also gets
    :func:`ccm.metrics.adaptation.stiffness_adaptation`.
    """
    params = dict(cfg.metrics)
    task = comp.task
    notes = getattr(task, "contact_annotations", ()) or ({},) * len(task.contacts)
    params["task_contacts"] = [{**c, **a} for c, a in zip(task.contacts, notes, strict=True)]
    params["controller_report"] = comp.controller.report() if hasattr(comp, "controller") else {}
    params["completion_time_s"] = (base or {}).get("completion_time_s")
    out: dict[str, float | None] = {}
    for name in names:
        out.update(EXTRA_METRICS[name](log, comp.task.dim, params))
    out.update(stiffness_adaptation(log, params))
    return out
