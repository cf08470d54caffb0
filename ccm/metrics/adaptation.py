"""Does AVIC's learning act? Prediction skill and stiffness adaptation (seed A §3.1, issue #16).

Seed A's mechanism: the forward model predicts the interaction force (Eq. 6), and the
stiffness rises with its prediction error and falls as it learns (Eq. 4b–4c). Two questions
tell whether that happens in a run:

* **Does the model know more than the last reading?** ``pred_skill`` = 1 − RMSE_model /
  RMSE_persistence on the same samples, where the model's prediction of ‖F_t‖ was made from
  S_{t−H} (``pred_force_N``) and persistence predicts ‖F_{t−H}‖ (``persist_force_N``). 0: no
  better than persistence; 1: perfect.
* **Does the stiffness move where the environment changes?** ``stiffness_active_frac`` is the
  fraction of steps with K_p more than ``active_stiffness_margin`` above K_free, and
  ``stiffness_rise_at_change`` is the mean K_p within ``change_window_s`` after each
  environment change divided by the mean K_p elsewhere. Changes are read from the
  simulator's truth columns (metrics may use ground truth; the controller never sees it): a
  spring attaching or detaching, a viscosity step of at least ``change_min_viscosity_step``,
  a change of the touched surface's friction, a contact made.
* On porridge stirring, ``mean_stiffness_seen_Npm`` / ``mean_stiffness_unseen_Npm`` split the
  trial at ``unseen_above_Nspm`` (the end of seed A §4.1's training ramp).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


def _rmse(err: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(err**2))) if err.size else None


def skill(model_rmse: float | None, persist_rmse: float | None) -> float | None:
    """1 − model / persistence RMSE (None if either is missing or persistence is exact)."""
    if model_rmse is None or persist_rmse is None or persist_rmse <= 0.0:
        return None
    return 1.0 - model_rmse / persist_rmse


def measured_force_norm(log: Mapping[str, np.ndarray], dim: int) -> np.ndarray:
    """‖F_t‖ of the measured force, per sample."""
    return np.linalg.norm(np.column_stack([log[f"force_{a}"] for a in "xyz"[:dim]]), axis=1)


def prediction_skill(
    log: Mapping[str, np.ndarray], dim: int, rows: np.ndarray | None = None, suffix: str = ""
) -> dict[str, float | None]:
    """``pred_rmse_N``, ``persist_rmse_N`` and ``pred_skill`` (with ``suffix``) on the
    samples where both predictions exist (and ``rows``, a boolean mask, holds); {} for a
    controller without a forward model."""
    if "pred_force_N" not in log or "persist_force_N" not in log:
        return {}
    meas = measured_force_norm(log, dim)
    pred, persist = log["pred_force_N"], log["persist_force_N"]
    ok = np.isfinite(pred) & np.isfinite(persist)
    if rows is not None:
        ok &= rows
    m, p = _rmse(pred[ok] - meas[ok]), _rmse(persist[ok] - meas[ok])
    return {
        f"pred_rmse{suffix}_N": m,
        f"persist_rmse{suffix}_N": p,
        f"pred_skill{suffix}": skill(m, p),
    }


def environment_changes(log: Mapping[str, np.ndarray], params: Mapping[str, Any]) -> np.ndarray:
    """Sample indices at which the environment changed (module docstring), sorted."""
    idx: list[np.ndarray] = []
    springs = log.get("truth_springs_attached")
    if springs is not None:
        idx.append(np.nonzero(np.diff(springs) != 0.0)[0] + 1)
    visc = log.get("truth_viscosity_Nspm")
    if visc is not None:
        step = float(params.get("change_min_viscosity_step", 1.0))
        idx.append(np.nonzero(np.abs(np.diff(visc)) >= step)[0] + 1)
    mu = log.get("truth_surface_friction")
    if mu is not None:
        both = (mu[1:] >= 0.0) & (mu[:-1] >= 0.0)
        idx.append(np.nonzero(both & (np.abs(np.diff(mu)) > 1e-9))[0] + 1)
    contact = log.get("truth_contact")
    if contact is not None:
        idx.append(np.nonzero((contact[1:] > 0.5) & (contact[:-1] <= 0.5))[0] + 1)
    return np.unique(np.concatenate(idx)) if idx else np.zeros(0, dtype=int)


def stiffness_adaptation(
    log: Mapping[str, np.ndarray], params: Mapping[str, Any]
) -> dict[str, float | None]:
    """``stiffness_active_frac``, ``stiffness_rise_at_change``, ``n_environment_changes`` and,
    with a viscosity column, the stiffness in the seen / unseen viscosity range; {} unless the
    controller reports K_free (the AVIC family)."""
    k_free = (params.get("controller_report") or {}).get("k_free")
    stiff = log.get("stiffness_Npm")
    if k_free is None or stiff is None or not np.any(np.isfinite(stiff)):
        return {}
    margin = float(params.get("active_stiffness_margin", 0.05))
    out: dict[str, float | None] = {
        "stiffness_active_frac": float(np.mean(stiff > (1.0 + margin) * float(k_free)))
    }
    changes = environment_changes(log, params)
    out["n_environment_changes"] = float(changes.size)
    t = log["t"]
    window = np.zeros(len(t), dtype=bool)
    for i in changes:
        window |= (t >= t[i]) & (t < t[i] + float(params.get("change_window_s", 0.2)))
    rest = ~window
    at, elsewhere = (float(np.mean(stiff[m])) if m.any() else None for m in (window, rest))
    out["stiffness_at_change_Npm"], out["stiffness_elsewhere_Npm"] = at, elsewhere
    out["stiffness_rise_at_change"] = at / elsewhere if at is not None and elsewhere else None
    visc, limit = log.get("truth_viscosity_Nspm"), params.get("unseen_above_Nspm")
    if visc is not None and limit is not None:
        unseen = visc > float(limit)
        for name, rows in (("seen", ~unseen), ("unseen", unseen)):
            out[f"mean_stiffness_{name}_Npm"] = float(np.mean(stiff[rows])) if rows.any() else None
    return out
