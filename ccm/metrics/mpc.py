"""Metrics of the seed B (GP-MPC) experiments, from one trial log (issue #7).

Inputs: the log columns ``t``, ``vel_*`` (measured velocity), ``contact_force_*`` and
``n_contacts`` (ground truth, metrics only), the controller's signals ``damping_<axis>_Nspm``
and ``belief_<n>`` (:class:`ccm.control.mpc.gp_mpc.GPMPC`), the truth ``truth_human_goal`` of a
simulated human, and ``controller_report`` (solve counts). Parameters (``cfg.metrics``):
``contact_loss_min_s``, ``oscillation_highpass_hz``, ``vel_split_hz``, ``belief_level``,
``varied_axis``, ``repeatable_axis``, ``press_force_N``, ``press_tol_N``, ``press_hold_s``,
``human_shoulder``, ``far_from_human_m``, ``approach_dir``, ``pause_speed_frac``,
and for a rail (``mpc_rail``) ``rail_point``, ``rail_normal``, ``tool_half_extent_m``,
``rail_contact_force_N``, ``near_rail_m``, ``far_rail_m``.

Definitions (dt = the log's median step):

* ``peak_force_N``: max over the trial of ‖true contact force‖ (seed B Fig. 6).
* ``contact_made``: 1.0 if the tool touched anything during the trial, else 0.0 (a peak force
  of 0 N from a trial that never reached the wall is no lower peak).
* ``contact_losses``: after the first contact, the number of runs of ≥ ``contact_loss_min_s``
  with no contact that are followed by contact again or last to the end ("lost contact due to
  oscillation", seed B §6.1).
* ``force_oscillation_rms_N``: RMS, from the first contact to the end, of ‖contact force‖
  minus its zero-phase low-pass at ``oscillation_highpass_hz`` (FFT mask): the oscillating part.
* ``press_settle_time_s`` (only when ``press_force_N`` is set, e.g. ``contact_head_to_head``):
  the first time t_s at or after the first contact from which ‖contact force‖ stays within
  ± ``press_tol_N`` of ``press_force_N`` at every step up to t_s + ``press_hold_s`` (that
  whole span inside the log); None if never. Like ``completion_time_s`` it is measured from
  the trial's start. It depends on the contact force alone, so a controller that ignores the
  target pattern (GP-MPC) is timed the same way as one that follows it.
* Approach metrics (only when ``approach_dir`` is set: the unit direction in which the tool
  moves into contact, e.g. ``mpc_contact``'s +x). With p(t) = dir·(x(t) − x(0)) the progress
  and v_a(t) = dir·v(t) the approach speed, over the *approach*: from the start to the first
  contact (the whole trial if the tool never touches):

  * ``approach_pullback_m``: the largest retreat max_t (max_{s≤t} p(s) − p(t)): how far the
    tool pulled back from the farthest point it had reached ("the robot pulled back from the
    contact approach", seed B §6.1); 0 for a monotone approach;
  * ``pre_contact_dwell_s`` (None without contact): the time between the peak approach speed
    and the first contact during which v_a is below ``pause_speed_frac`` × that peak ("the
    well-damped constraint paused ... before making contact", seed B §6.1); 0 for an approach
    that never slows down;
  * ``damping_at_contact_Nspm`` (None without contact): the rendered damping along dir at the
    first contact, dirᵀ diag(D) dir.
* ``mpc_solves``, ``mpc_infeasible``: MPC solves and unsuccessful solves of the trial.
* ``rms_vel_low_mps``, ``rms_vel_high_mps``: RMS of the velocity (all axes) below / above
  ``vel_split_hz`` (seed B Table 3: 15 Hz), by an FFT mask on the whole trial.
* ``mean_damping_<axis>_Nspm``, ``mean_mass_<axis>_kg`` and ``damping_ratio_varied_repeatable``:
  the mean rendered damping and mass per axis (seed B Fig. 9: across the polishing path) and
  the damping ratio varied / repeatable axis (seed B Fig. 8).
* ``mean_sigma_f_<axis>_N2`` and ``max_sigma_f_<axis>_N2``: the mean and largest GP force
  variance Σ^f that the MPC saw at its plans' last points ξ_{t+H} (signal ``sigma_f_<axis>_N2``,
  where the chance constraint of Eq. 18 is imposed), over the trial's solves; None before any.
* ``mean_damping_far_Nspm`` and ``far_from_human_frac`` (only when ``human_shoulder`` is set,
  seed B §6.3, Fig. 9c): the rendered damping, averaged over the axes and over the samples whose
  tool point (z = 0 in a planar task) lies at least ``far_from_human_m`` from the human's
  shoulder ``human_shoulder`` ([x, y, z] m), and the fraction of such samples; the damping is
  None when there are none.
* ``disturbance_alpha_N``: α of Eq. 16 as the controller estimated it from its demonstrations
  (``controller_report``; only when it estimated one).
* Rail metrics (only when ``rail_point`` is set; seed B §6.2, Fig. 8). The distance to the
  rail is d(t) = (x(t) − rail_point)·n − ``tool_half_extent_m``, with n the rail's outward
  normal ``rail_normal`` (the gap between the tool's contact point and the rail; ≤ 0 in
  contact). The rail's push on the tool is f_n = contact_force·n.
  ``task_success``: 1.0 if at some step the tool touches (``n_contacts`` > 0) with f_n ≥
  ``rail_contact_force_N``, else 0.0; ``time_to_rail_s``: the first such time (None if never).
  ``near_damping_<axis>_Nspm`` and ``near_damping_ratio_varied_repeatable``: the mean damping
  over the steps with d ≤ ``near_rail_m`` and the ratio of those means (None if the tool never
  came that near); ``far_damping_<axis>_Nspm``: the mean over the steps with d >
  ``far_rail_m``; ``min_rail_distance_m``: the smallest d of the trial.
  ``damping_rise_repeatable_over_varied``: (near / far damping along ``repeatable_axis``) over
  (near / far along ``varied_axis``). The MPC's damping only ratchets up within a trial, so a
  near-rail rise along one axis can be time, not place; both axes share that time, so this
  ratio is above 1 only where the repeatable axis rises more than the varied one (seed B §6.2:
  "increased substantially [in the repeatable DOF], while kept low in the DOF which varied").
* ``belief_correct_final``: 1.0 if the final belief's largest entry is the human's goal;
  ``time_to_belief_s``: the first time the belief in the true goal reaches ``belief_level``
  (None if never; seed B Fig. 11).
* ``f_ref_toward_goal_N`` (seed B Fig. 11c): the mean over the trial of −f^r · ĝ, with ĝ the
  unit vector from the trial's first position to the human's true goal (``truth_human_goal_*``)
  and f^r the controller's ``f_ref_<axis>_N``. The admittance is driven by f − f^r (Eq. 4), so
  this is the commanded push toward the goal the human chose; None if the start is the goal.
* ``goal_approach_m``: the distance to the human's true goal at the start minus at the end.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_finite, check_nonneg, check_positive
from ccm.core.filters import fft_split as _split
from ccm.core.records import AXES
from ccm.metrics.suite import count_contact_losses


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else 0.0


def _press_settle_time(
    t: np.ndarray, fc: np.ndarray, touching: np.ndarray, dt: float, params: Mapping[str, Any]
) -> float | None:
    """``press_settle_time_s`` of the module docstring (None without contact or settling)."""
    target = check_finite("metrics.press_force_N", params["press_force_N"])
    tol = check_positive("metrics.press_tol_N", params.get("press_tol_N", 1.5))
    hold = check_nonneg("metrics.press_hold_s", params.get("press_hold_s", 0.5))
    if not touching.any():
        return None
    n = int(round(hold / dt))  # steps after t_s that must stay in the band too
    bad = np.concatenate([[0], np.cumsum(np.abs(fc - target) > tol)])
    k = np.arange(int(np.argmax(touching)), len(fc) - n)  # candidate t_s steps
    ok = k[bad[k + n + 1] == bad[k]]
    return float(t[ok[0]]) if ok.size else None


def _far_from_human(
    log: Mapping[str, np.ndarray], ax: tuple[str, ...], damp: Mapping[str, Any], params: Mapping
) -> dict[str, float | None]:
    """``mean_damping_far_Nspm`` and ``far_from_human_frac`` of the module docstring."""
    shoulder = np.asarray(params["human_shoulder"], dtype=float)
    if shoulder.shape != (3,) or not np.all(np.isfinite(shoulder)):
        raise ConfigError("metrics.human_shoulder", f"must be [x, y, z] in m, got {shoulder}")
    far = check_positive("metrics.far_from_human_m", params.get("far_from_human_m"))
    pos = np.column_stack([log[f"pos_{a}"] for a in ax])
    pos = np.column_stack([pos, np.zeros((len(pos), 3 - len(ax)))])
    is_far = np.linalg.norm(pos - shoulder, axis=1) >= far
    if any(d is None for d in damp.values()):
        return {"mean_damping_far_Nspm": None, "far_from_human_frac": float(np.mean(is_far))}
    d_mean = np.mean(np.column_stack([damp[a] for a in ax]), axis=1)
    return {
        "mean_damping_far_Nspm": float(np.mean(d_mean[is_far])) if is_far.any() else None,
        "far_from_human_frac": float(np.mean(is_far)),
    }


def _approach_metrics(
    log: Mapping[str, np.ndarray], dim: int, touching: np.ndarray, params: Mapping[str, Any]
) -> dict[str, float | None]:
    """``approach_pullback_m``, ``pre_contact_dwell_s`` and ``damping_at_contact_Nspm`` of the
    module docstring (seed B §6.1's behaviour approaching contact)."""
    ax = AXES[:dim]
    raw = params["approach_dir"]
    try:
        d = np.asarray(list(raw), dtype=float)
    except (TypeError, ValueError):
        d = np.zeros(0)
    if d.shape != (dim,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0.0:
        raise ConfigError("metrics.approach_dir", f"must be a non-zero {dim}-vector, got {raw!r}")
    d = d / np.linalg.norm(d)
    frac = check_positive("metrics.pause_speed_frac", params.get("pause_speed_frac", 0.5))
    pos = np.column_stack([log[f"pos_{a}"] for a in ax])
    vel = np.column_stack([log[f"vel_{a}"] for a in ax])
    n = int(np.argmax(touching)) if touching.any() else len(pos)  # steps of the approach
    p = (pos[:n] - pos[0]) @ d
    out: dict[str, float | None] = {
        "approach_pullback_m": float(np.max(np.maximum.accumulate(p) - p)) if n else 0.0,
        "pre_contact_dwell_s": None,
        "damping_at_contact_Nspm": None,
    }
    if not touching.any():
        return out
    dt = float(np.median(np.diff(log["t"]))) if len(log["t"]) > 1 else 1e-3
    va = vel[:n] @ d
    if n:
        k = int(np.argmax(va))
        slow = va[k:] < frac * va[k] if va[k] > 0.0 else np.zeros(0, dtype=bool)
        out["pre_contact_dwell_s"] = float(np.count_nonzero(slow) * dt)
    damp = [log.get(f"damping_{a}_Nspm") for a in ax]
    if all(v is not None for v in damp):
        along = sum(di**2 * v[n] for di, v in zip(d, damp, strict=True))
        out["damping_at_contact_Nspm"] = float(along)
    return out


def rail_distance(log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]) -> np.ndarray:
    """d(t) of the module docstring [m]: gap between the tool's contact point and the rail."""
    point = np.asarray(params["rail_point"], dtype=float)
    normal = np.asarray(params["rail_normal"], dtype=float)
    if point.shape != (dim,) or normal.shape != (dim,) or not np.linalg.norm(normal) > 0:
        raise ConfigError("metrics.rail_point", f"rail_point and rail_normal need {dim} values")
    normal = normal / np.linalg.norm(normal)
    half = check_nonneg("metrics.tool_half_extent_m", params.get("tool_half_extent_m", 0.0))
    pos = np.column_stack([log[f"pos_{a}"] for a in AXES[:dim]])
    return (pos - point) @ normal - half


def _sigma_f(x: np.ndarray | None, axis: str) -> dict[str, float | None]:
    """``mean_sigma_f_<axis>_N2`` and ``max_sigma_f_<axis>_N2`` (module docstring)."""
    if x is None:
        return {}
    seen = x[np.isfinite(x)]
    return {
        f"mean_sigma_f_{axis}_N2": float(np.mean(seen)) if seen.size else None,
        f"max_sigma_f_{axis}_N2": float(np.max(seen)) if seen.size else None,
    }


def _mean_over(x: np.ndarray | None, mask: np.ndarray) -> float | None:
    return float(np.mean(x[mask])) if x is not None and mask.any() else None


def rail_metrics(log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]) -> dict:
    """Task success, time to the rail and the damping near / far from it (module docstring;
    seed B §6.2, Fig. 8). Reads the rail's truth: evaluation only."""
    ax = AXES[:dim]
    d = rail_distance(log, dim, params)
    normal = np.asarray(params["rail_normal"], dtype=float)
    normal = normal / np.linalg.norm(normal)
    f_n = np.column_stack([log[f"contact_force_{a}"] for a in ax]) @ normal
    thr = check_positive("metrics.rail_contact_force_N", params.get("rail_contact_force_N"))
    reached = np.flatnonzero((log["n_contacts"] > 0) & (f_n >= thr))
    near = d <= check_nonneg("metrics.near_rail_m", params.get("near_rail_m"))
    far = d > check_nonneg("metrics.far_rail_m", params.get("far_rail_m"))
    out: dict[str, float | None] = {
        "task_success": 1.0 if reached.size else 0.0,
        "time_to_rail_s": float(log["t"][reached[0]]) if reached.size else None,
        "min_rail_distance_m": float(d.min()) if d.size else None,
    }
    damp = {a: log.get(f"damping_{a}_Nspm") for a in ax}
    for a, x in damp.items():
        out[f"near_damping_{a}_Nspm"] = _mean_over(x, near)
        out[f"far_damping_{a}_Nspm"] = _mean_over(x, far)
    va, ra = params.get("varied_axis"), params.get("repeatable_axis")
    nv, nr = out.get(f"near_damping_{va}_Nspm"), out.get(f"near_damping_{ra}_Nspm")
    out["near_damping_ratio_varied_repeatable"] = nv / nr if nv is not None and nr else None
    fv, fr = out.get(f"far_damping_{va}_Nspm"), out.get(f"far_damping_{ra}_Nspm")
    known = None not in (nv, nr, fv, fr) and fv and fr and nv
    out["damping_rise_repeatable_over_varied"] = (nr / fr) / (nv / fv) if known else None
    return out


def gp_mpc_metrics(log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]) -> dict:
    """The seed B metrics of one trial (module docstring)."""
    t = log["t"]
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1e-3
    ax = AXES[:dim]
    fc = np.linalg.norm(np.column_stack([log[f"contact_force_{a}"] for a in ax]), axis=1)
    touching = log["n_contacts"] > 0
    out: dict[str, float | None] = {
        "peak_force_N": float(fc.max()) if fc.size else 0.0,
        "contact_made": 1.0 if touching.any() else 0.0,
    }
    if touching.any():
        first = int(np.argmax(touching))
        out["contact_losses"] = count_contact_losses(
            touching, dt, float(params.get("contact_loss_min_s", 0.005))
        )
        _, high = _split(fc[first:], dt, float(params.get("oscillation_highpass_hz", 5.0)))
        out["force_oscillation_rms_N"] = _rms(high)
        out["first_contact_s"] = float(t[first])
    else:
        out.update(contact_losses=None, force_oscillation_rms_N=None, first_contact_s=None)
    if params.get("press_force_N") is not None:
        out["press_settle_time_s"] = _press_settle_time(t, fc, touching, dt, params)
    if params.get("approach_dir") is not None:
        out.update(_approach_metrics(log, dim, touching, params))
    rep = params.get("controller_report") or {}
    out["mpc_solves"] = float(rep.get("mpc_solves", 0))
    out["mpc_infeasible"] = float(rep.get("mpc_infeasible", 0))
    split = float(params.get("vel_split_hz", 15.0))
    lows, highs = zip(*(_split(log[f"vel_{a}"], dt, split) for a in ax), strict=True)
    out["rms_vel_low_mps"] = _rms(np.concatenate(lows)) * np.sqrt(dim)
    out["rms_vel_high_mps"] = _rms(np.concatenate(highs)) * np.sqrt(dim)
    damp = {a: log.get(f"damping_{a}_Nspm") for a in ax}
    for a, d in damp.items():
        if d is not None:
            out[f"mean_damping_{a}_Nspm"] = float(np.mean(d))
        if f"mass_{a}_kg" in log:
            out[f"mean_mass_{a}_kg"] = float(np.mean(log[f"mass_{a}_kg"]))
        out.update(_sigma_f(log.get(f"sigma_f_{a}_N2"), a))
    if params.get("human_shoulder") is not None:
        out.update(_far_from_human(log, ax, damp, params))
    if rep.get("disturbance_alpha") is not None:
        out["disturbance_alpha_N"] = float(rep["disturbance_alpha"])
    va, ra = params.get("varied_axis"), params.get("repeatable_axis")
    if va in damp and ra in damp and damp[va] is not None and damp[ra] is not None:
        out["damping_ratio_varied_repeatable"] = float(np.mean(damp[va]) / np.mean(damp[ra]))
    out.update(goal_metrics(log, dim))
    if params.get("rail_point") is not None:
        out.update(rail_metrics(log, dim, params))
    beliefs = sorted(k for k in log if k.startswith("belief_"))
    if len(beliefs) > 1 and "truth_human_goal" in log:
        b = np.column_stack([log[k] for k in beliefs])
        goal = int(log["truth_human_goal"][-1])
        out["belief_correct_final"] = 1.0 if int(np.argmax(b[-1])) == goal else 0.0
        hit = np.flatnonzero(b[:, goal] >= float(params.get("belief_level", 0.9)))
        out["time_to_belief_s"] = float(t[hit[0]]) if hit.size else None
    return out


def goal_metrics(log: Mapping[str, np.ndarray], dim: int) -> dict[str, float | None]:
    """``goal_approach_m`` and ``f_ref_toward_goal_N`` (module docstring); ``{}`` when the log
    has no true human goal for every axis (no simulated human)."""
    ax = AXES[:dim]
    if not all(f"truth_human_goal_{a}_m" in log for a in ax):
        return {}
    goal = np.array([log[f"truth_human_goal_{a}_m"][-1] for a in ax], dtype=float)
    pos = np.column_stack([log[f"pos_{a}"] for a in ax])
    dist0 = float(np.linalg.norm(goal - pos[0]))
    out: dict[str, float | None] = {
        "goal_approach_m": dist0 - float(np.linalg.norm(goal - pos[-1]))
    }
    if all(f"f_ref_{a}_N" in log for a in ax):
        f_ref = np.column_stack([log[f"f_ref_{a}_N"] for a in ax])
        out["f_ref_toward_goal_N"] = (
            float(np.mean(-f_ref @ ((goal - pos[0]) / dist0))) if dist0 > 0.0 else None
        )
    return out
