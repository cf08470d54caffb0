"""Collision metrics from a trial log (seed A §4.5.1, H4, Fig. 16; issue #5).

Inputs are the trial-log columns ``t``, ``segment``, ``vel_*`` (measured velocity),
``true_force_*`` (noise-free external force on the end-effector: ground truth, metrics only,
never a controller), optionally ``truth_normal_force_*`` (its normal part, for the onset)
and, for the anticipation controller, ``transition_alpha`` (Eq. 10 blend weight) and
``collision_event`` (1: detected collision, 2: quasi-static contact). Parameters
come from ``cfg.metrics``: ``impact_onset_N``, ``impact_near_m``, ``impact_window_s``,
``impact_acc_window_s`` (two numbers [w0, w1]), ``lowpass_hz``, plus ``task_contacts``, which
:func:`ccm.metrics.trial.compute_extra_metrics` adds: the task's contacts in pattern order, each a
dict with ``name``, ``kind``, ``position``, ``segment_index`` and ``normal`` (see
:class:`ccm.tasks.task.Task`, ``contact_annotations``).

Definitions (one trial; step k is one control step, ``t[k]`` its time, dt the median step):

* **Scored contacts**: the task's contacts of kind ``collision`` that have both a ``segment``
  and a ``normal``; the others are skipped (and give no keys).
* **Normal force** of contact c: f_c[k] = n_c · F_true[k], the true external force on the
  end-effector along c's unit outward normal n_c (the direction the surface pushes the tool).
* **Search interval** of c: from s_c, the first step whose ``segment`` equals c's segment
  index, up to (excluding) the first step after s_c whose ``segment`` equals the segment index
  of a later scored contact (the next one in the list with a larger index), or the log's end.
  If c's segment never appears in the log (a trial cut short), c has no onset.
* **Near step** r_c: the first step k ≥ s_c in the search interval at which the tool point is
  within ``impact_near_m`` of c's surface plane, n_c · (p[k] − p_c) ≤ ``impact_near_m`` (p_c the
  nominal contact position, n_c pointing from the surface to the tool). Measuring from here,
  not from s_c, keeps friction that builds up as a slide starts (the table's, along a wall's
  normal) out of the onset.
* **Onset** o_c: the first step k ≥ r_c in the search interval with g_c[k] − g_c[r_c] ≥
  ``impact_onset_N``, i.e. the force along n_c has risen by that much over its level near the
  surface; no onset if it never does. g_c = n_c · N_true[k] is the *normal part* of the true
  contact force (``truth_normal_force_*``: the contact points' normal forces, friction left
  out; PyBullet logs it) when the log has it, else f_c. With f_c the friction along n_c
  counts: a tool that slows down and stiffens or softens within ``impact_near_m`` of the
  surface changes it by more than ``impact_onset_N`` before any touch, and the onset was
  missed (seed 1 of ``h4_contact_learning``: 13.4 N of sliding friction at the near step,
  3.5 N later, 5.2 N at the touch).
* ``contact_time_s_<name>`` = t[o_c] (None without an onset).
* ``impact_force_N_<name>`` = max of f_c over the steps with t[o_c] ≤ t ≤ t[o_c] +
  ``impact_window_s``; ``peak_impact_force_N`` = the largest of these over the scored contacts.
  Absolute, like the F_m the controller measures (Eq. 9): for a wall met while sliding it
  includes the friction of the surfaces already touched that acts along the wall's normal
  (a few N here).
* ``impact_force_error_N_<name>`` = |``impact_force_N_<name>`` − ``impact_force_target_N``|:
  how far the impact is from Eq. 9's F_d (seed A §4.5.1: 8 N).
* ``impact_acc_mps2_<name>`` = max ‖a[k]‖ over t[o_c] + w0 ≤ t[k] ≤ t[o_c] + w1, with a the
  acceleration from the measured velocity through :func:`ccm.metrics.trial.derivatives` (the same
  low-pass, ``lowpass_hz``, as ``peak_acc_mps2`` of every condition); ``peak_impact_acc_mps2``
  = the largest over the scored contacts. Steps outside the log are left out.
* ``impact_rms_jerk_mps3_<name>`` = the RMS of ‖j[k]‖ over t[o_c] ≤ t[k] ≤ t[o_c] +
  ``impact_jerk_window_s`` (W), with j the jerk from the same :func:`ccm.metrics.trial.derivatives`
  as the acceleration; ``post_impact_rms_jerk_mps3`` = the RMS over the union of these windows
  of every scored contact with an onset (a step in two windows counts once): seed A §3.4.1's
  "jerk in motion after impact" (:func:`impact_jerk`). W defaults to 0.2 s, Eq. 10's T
  (``anticipation.blend_s``): after the contact is made the transition controller hands back
  to the base over T (§3.5.1), so K* acts on the motion for about that long after the impact
  and the base controller alone after it; it is also the end of ``impact_acc_window_s``.
* ``transition_time_s`` = dt × the number of steps with ``transition_alpha`` > 0 (the time the
  transition-phase controller is active); 0.0 when the column is absent (no contact handling).
* ``n_collision_events`` = the number of runs of consecutive steps with ``collision_event`` > 0
  (the controller flags one step per event, so this is the number of events); None when the
  column is absent.

Beliefs (``contact_error_m_<name>``, ``detection_error_m_<name>``, ...) are defined in
:mod:`ccm.metrics.contact_beliefs`; impact-less transitions (``patch_peak_acc_mps2_<name>``,
``switch_detect_delay_s_<name>``, ...) in :mod:`ccm.metrics.contact_patches`.
:func:`contact_metrics` returns all three families.

Every value is a plain float or None, and the keys are the same every trial of a task (a
missing onset gives None, not a missing key). ``completion_time_s``, ``peak_acc_mps2`` and
``rms_jerk_mps3`` come from :func:`ccm.metrics.trial.trial_metrics` and are not repeated here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_finite, check_nonneg, check_positive
from ccm.core.filters import derivatives
from ccm.metrics.contact_beliefs import belief_metrics
from ccm.metrics.contact_patches import patch_metrics

__all__ = ["contact_metrics", "impact_jerk", "scored_contacts"]


def scored_contacts(task_contacts: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The collision contacts that carry both a segment index and a normal, in task order."""
    return [
        c
        for c in task_contacts
        if c.get("kind", "collision") == "collision"
        and c.get("segment_index") is not None
        and c.get("normal") is not None
    ]


def _acc_window(value: Any) -> tuple[float, float]:
    key = "metrics.impact_acc_window_s"
    try:
        w0, w1 = (check_finite(key, v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(key, f"must be two numbers [w0, w1] in s, got {value!r}") from None
    if w1 < w0:
        raise ConfigError(key, f"must have w0 <= w1, got {[w0, w1]}")
    return w0, w1


def _onset(
    f_n: np.ndarray,
    gap: np.ndarray,
    seg: np.ndarray,
    index: int,
    later: Sequence[int],
    rise: float,
    near: float,
) -> int | None:
    """Onset step of one contact (see the module docstring), or None. ``f_n``: the force
    along the contact's normal per step (g_c); ``gap``: the tool point's signed distance from
    the contact's surface plane per step."""
    starts = np.flatnonzero(seg == index)
    if starts.size == 0:
        return None
    end = len(seg)
    ends = np.flatnonzero(np.isin(seg[int(starts[0]) :], later))
    if ends.size:
        end = int(starts[0]) + int(ends[0])
    close = np.flatnonzero(gap[int(starts[0]) : end] <= near)
    if close.size == 0:
        return None
    s = int(starts[0]) + int(close[0])
    hits = np.flatnonzero(f_n[s:end] - f_n[s] >= rise)
    return s + int(hits[0]) if hits.size else None


def contact_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]
) -> dict[str, float | None]:
    """Impact force, impact acceleration, contact times and transition time for one trial."""
    settings = {
        "rise": check_nonneg("metrics.impact_onset_N", params.get("impact_onset_N", 1.0)),
        "window": check_nonneg("metrics.impact_window_s", params.get("impact_window_s", 0.05)),
        "f_target": check_positive(
            "metrics.impact_force_target_N", params.get("impact_force_target_N", 8.0)
        ),
        "near": check_nonneg("metrics.impact_near_m", params.get("impact_near_m", 0.01)),
        "acc_window": _acc_window(params.get("impact_acc_window_s", (-0.05, 0.2))),
        "jerk_window": check_positive(
            "metrics.impact_jerk_window_s", params.get("impact_jerk_window_s", 0.2)
        ),
        "lowpass_hz": check_positive("metrics.lowpass_hz", params.get("lowpass_hz")),
    }
    contacts = scored_contacts(params.get("task_contacts") or ())
    t = np.asarray(log["t"], dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    out = _impact_metrics(log, "xyz"[:dim], t, dt, contacts, settings)
    out.update(belief_metrics(params.get("task_contacts") or (), params.get("controller_report")))
    out.update(patch_metrics(log, dim, params))
    alpha = log.get("transition_alpha")
    out["transition_time_s"] = (
        float(np.count_nonzero(np.asarray(alpha) > 0.0) * dt) if alpha is not None else 0.0
    )
    event = log.get("collision_event")
    if event is None:
        out["n_collision_events"] = None
    else:
        on = np.asarray(event, dtype=float) > 0.0
        out["n_collision_events"] = float(np.count_nonzero(on[1:] & ~on[:-1]) + int(on[:1].sum()))
    return out


def _impact_metrics(
    log: Mapping[str, np.ndarray],
    axes: str,
    t: np.ndarray,
    dt: float,
    contacts: Sequence[Mapping[str, Any]],
    settings: Mapping[str, Any],
) -> dict[str, float | None]:
    """Per expected contact: the true normal force's peak in the window after its onset,
    |F_peak − target|, the acceleration's peak around it, the RMS jerk after it
    (:func:`impact_jerk`) and the onset time; and the peaks and the pooled jerk over all
    contacts."""
    out: dict[str, float | None] = {}
    impact_f: list[float] = []
    impact_a: list[float] = []
    if contacts:
        seg = np.rint(np.asarray(log["segment"], dtype=float)).astype(int)
        f_true = np.column_stack([log[f"true_force_{a}"] for a in axes])
        normal_cols = [f"truth_normal_force_{a}" for a in axes]
        n_true = (
            np.column_stack([log[k] for k in normal_cols])
            if all(k in log for k in normal_cols) else f_true
        )  # fmt: skip
        vel = np.column_stack([log[f"vel_{a}"] for a in axes])
        pos = np.column_stack([log[f"pos_{a}"] for a in axes])
        acc, jerk = derivatives(vel, dt, settings["lowpass_hz"])
        acc_n, jerk_n = np.linalg.norm(acc, axis=1), np.linalg.norm(jerk, axis=1)
        indices = [int(c["segment_index"]) for c in contacts]
        window, (w0, w1) = settings["window"], settings["acc_window"]
        for i, c in enumerate(contacts):
            name = str(c["name"])
            n = np.asarray(c["normal"], dtype=float)
            gap = (pos - np.asarray(c["position"], dtype=float)) @ n
            later = [j for j in indices[i + 1 :] if j > indices[i]]
            o = _onset(n_true @ n, gap, seg, indices[i], later, settings["rise"], settings["near"])
            force = acc_peak = t_on = None
            if o is not None:
                t_on = float(t[o])
                in_f = (t >= t_on - 1e-12) & (t <= t_on + window + 1e-12)
                force = float(np.max((f_true @ n)[in_f]))
                in_a = (t >= t_on + w0 - 1e-12) & (t <= t_on + w1 + 1e-12)
                acc_peak = float(np.max(acc_n[in_a]))
                impact_f.append(force)
                impact_a.append(acc_peak)
            error = None if force is None else abs(force - settings["f_target"])
            out[f"impact_force_N_{name}"] = force
            out[f"impact_force_error_N_{name}"] = error
            out[f"impact_acc_mps2_{name}"] = acc_peak
            out[f"contact_time_s_{name}"] = t_on
        onsets = {str(c["name"]): out[f"contact_time_s_{c['name']}"] for c in contacts}
        out.update(impact_jerk(jerk_n, t, onsets, settings["jerk_window"]))
    else:
        out["post_impact_rms_jerk_mps3"] = None
    out["peak_impact_force_N"] = max(impact_f) if impact_f else None
    out["peak_impact_acc_mps2"] = max(impact_a) if impact_a else None
    return out


def impact_jerk(
    jerk_n: np.ndarray,
    t: np.ndarray,
    onsets: Mapping[str, float | None],
    window: float,
) -> dict[str, float | None]:
    """RMS jerk after each impact (module docstring): ``impact_rms_jerk_mps3_<name>`` over
    [onset, onset + ``window``] per contact (None without an onset) and
    ``post_impact_rms_jerk_mps3`` over the union of those windows (None if no contact has one).

    Args:
        jerk_n: ‖jerk‖ per step [m/s³]; ``t``: the step times [s].
        onsets: contact name -> onset time [s] or None.
        window: W [s], the window's length after each onset.
    """
    out: dict[str, float | None] = {}
    union = np.zeros(len(t), dtype=bool)
    for name, t_on in onsets.items():
        if t_on is None:
            out[f"impact_rms_jerk_mps3_{name}"] = None
            continue
        inside = (t >= t_on - 1e-12) & (t <= t_on + window + 1e-12)
        union |= inside
        out[f"impact_rms_jerk_mps3_{name}"] = float(np.sqrt(np.mean(jerk_n[inside] ** 2)))
    out["post_impact_rms_jerk_mps3"] = (
        float(np.sqrt(np.mean(jerk_n[union] ** 2))) if union.any() else None
    )
    return out
