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

Beliefs (``controller_report``, :meth:`ccm.control.base.Controller.report`, taken after the
trial and before the controller's end-of-trial update; a controller without contact beliefs
gives None for all of these), for every contact of the task, matched by name:

* ``contact_error_m_<name>`` = ‖belief mean − the task's nominal (true) position‖ (seed A
  Table 1 gives the error along the most significant axis; the norm is never smaller);
* ``contact_std_m_<name>`` = the largest standard deviation along an axis of the belief (the
  ± of Table 1);
* ``contact_prior_error_m_<name>`` / ``contact_prior_std_m_<name>``: the same for the belief
  the trial started from (trial 1: the noisy initial estimate, Table 1's "Initial");
* ``approach_velocity_mps_<name>`` / ``measured_impact_force_N_<name>``: for a collision
  whose Eq. 9 model was updated this trial, the commanded approach speed and the impact force
  F_m the controller measured (its F/T sensor, not the truth);
* ``n_contacts_learned``: contacts the controller added itself (first seen in a trial);
* ``detection_error_m_<name>`` = ‖z − the task's nominal position‖ for the first contact
  position z the controller measured for that contact in the trial (the Kalman filter's
  measurement, seed A §3.3; issue #38 item 3: the detection chain's own error, from the F/T
  noise, the onset test's latency, the contact's compliance and the tool's tracking error),
  and ``detection_depth_m_<name>`` = its part along −n_c (how far past the nominal surface
  the tool point was at the detected onset; negative short of it). None when not measured.

Impact-less transitions (seed A §4.5.2, Figs 19-20), for every task contact of kind
``impactless`` (its position: where the tool point crosses onto the new surface):

* **Patch window**: the steps at which the tool point is within ``patch_window_m`` of that
  position.
* ``patch_peak_acc_mps2_<name>`` / ``patch_peak_jerk_mps3_<name>`` = max ‖a‖ / ‖j‖ over the
  window, from the measured velocity through :func:`ccm.metrics.trial.derivatives` (None if the
  tool never comes that close);
* ``region_m_<name>`` = ``region_m`` (largest semi-axis of region C) of the controller's
  impact-less belief nearest to that position, if one lies within ``patch_window_m`` (the
  region it anticipates there), else None: the region size per trial of Fig. 20.
* **Switch onset** (ground truth): in the first contiguous run of the patch window, the
  first step at which ``truth_table_friction`` (the friction the simulator gives the table)
  differs from its value at the run's first step: where the tool's face starts to feel the
  new surface (with ``sim.patch_mode: footprint`` about half the tool's width before the tool
  point crosses). Without that column: the step of the run closest to the position.
  ``switch_onset_s_<name>`` = its time.
* ``switch_detect_delay_s_<name>`` = from the onset to the first step of the run at which
  Algorithm 1 decides a mode (``mode_event`` > 0) other than the ``mode`` at the onset (seed A:
  "detected"); ``switch_detected_<name>`` = 1.0. With no such decision before the tool leaves
  the window the delay is censored at the window's end (a lower bound on the true delay) and
  ``switch_detected_<name>`` = 0.0. All three are None without a run with an onset, and the
  last two None for a controller without mode detection (no ``mode`` column).
  ``switch_known_<name>`` = 1.0 if that detecting decision took a mode the controller already
  had (``mode_event`` = 1, Algorithm 1's known mode; seed A §4.5.2: segment 4 "recognized as a
  mode that it had experienced before"), 0.0 if it made a new one (2); None if undetected.

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
    out.update(_belief_metrics(params.get("task_contacts") or (), params.get("controller_report")))
    out.update(_patch_metrics(log, dim, params))
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


def _belief_metrics(
    task_contacts: Sequence[Mapping[str, Any]], report: Mapping[str, Any] | None
) -> dict[str, float | None]:
    """The belief metrics of the module docstring."""
    beliefs = {b["name"]: b for b in (report or {}).get("contacts", [])}
    out: dict[str, float | None] = {}
    for c in task_contacts:
        name = str(c["name"])
        b = beliefs.get(name)
        err = std = v = f = err0 = std0 = None
        if b is not None and b.get("prior_mean") is not None:
            err0 = float(np.linalg.norm(np.asarray(b["prior_mean"]) - np.asarray(c["position"])))
            std0 = float(b["prior_std"])
        if b is not None:
            err = float(np.linalg.norm(np.asarray(b["mean"]) - np.asarray(c["position"])))
            std = float(b["std"])
            v = None if b.get("approach_velocity") is None else float(b["approach_velocity"])
            f = None if b.get("impact_force") is None else float(b["impact_force"])
        out[f"contact_error_m_{name}"] = err
        out[f"contact_std_m_{name}"] = std
        out[f"contact_prior_error_m_{name}"] = err0
        out[f"contact_prior_std_m_{name}"] = std0
        out[f"approach_velocity_mps_{name}"] = v
        out[f"measured_impact_force_N_{name}"] = f
        out.update(_detection_error(name, c, b))
    learned = [b for b in beliefs.values() if b.get("source") == "observed"]
    out["n_contacts_learned"] = float(len(learned)) if report and "contacts" in report else None
    return out


def _detection_error(
    name: str, contact: Mapping[str, Any], belief: Mapping[str, Any] | None
) -> dict[str, float | None]:
    """``detection_error_m_<name>`` and ``detection_depth_m_<name>`` of the module docstring,
    from the first position the controller measured for this contact in the trial."""
    z = (belief or {}).get("measured") or []
    err = depth = None
    if z:
        e = np.asarray(z[0], dtype=float) - np.asarray(contact["position"], dtype=float)
        err = float(np.linalg.norm(e))
        if contact.get("normal") is not None:
            n = np.asarray(contact["normal"], dtype=float)
            depth = float(-e @ n / np.linalg.norm(n))
    return {f"detection_error_m_{name}": err, f"detection_depth_m_{name}": depth}


def contact_table(trials: Sequence[Mapping[str, Any]]) -> str | None:
    """Seed A Table 1 / §4.5.1 layout as markdown: per condition with contact beliefs, one row
    per trial and contact (belief error and std, commanded approach speed, true and measured
    impact force) and the trial's pattern and transition times. None if no trial has beliefs.
    """
    rows = []
    for tr in trials:
        names = [k[len("contact_error_m_") :] for k in tr if k.startswith("contact_error_m_")]
        for n in names:
            if tr.get(f"contact_error_m_{n}") is None:
                continue
            rows.append((tr, n))
    if not rows:
        return None

    def f(v: Any, fmt: str) -> str:
        return "–" if v is None else format(v, fmt)

    lines = [
        "| condition | trial | contact | error before [m] | std before [m] | error after [m] "
        "| std after [m] | approach v [m/s] | impact F true [N] | F_m measured [N] "
        "| pattern time [s] | transition time [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for tr, n in rows:
        lines.append(
            f"| {tr['condition']} | {tr['trial']} | {n} "
            f"| {f(tr.get(f'contact_prior_error_m_{n}'), '.4f')} "
            f"| {f(tr.get(f'contact_prior_std_m_{n}'), '.4f')} "
            f"| {f(tr.get(f'contact_error_m_{n}'), '.4f')} "
            f"| {f(tr.get(f'contact_std_m_{n}'), '.4f')} "
            f"| {f(tr.get(f'approach_velocity_mps_{n}'), '.4f')} "
            f"| {f(tr.get(f'impact_force_N_{n}'), '.1f')} "
            f"| {f(tr.get(f'measured_impact_force_N_{n}'), '.1f')} "
            f"| {f(tr.get('pattern_time_s'), '.2f')} | {f(tr.get('transition_time_s'), '.2f')} |"
        )
    return "\n".join(lines) + "\n"


def _patch_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]
) -> dict[str, float | None]:
    """The impact-less (patch) metrics of the module docstring."""
    near = check_positive("metrics.patch_window_m", params.get("patch_window_m", 0.03))
    contacts = [c for c in params.get("task_contacts") or () if c.get("kind") == "impactless"]
    if not contacts:
        return {}
    axes = "xyz"[:dim]
    t = np.asarray(log["t"], dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    pos = np.column_stack([log[f"pos_{a}"] for a in axes])
    vel = np.column_stack([log[f"vel_{a}"] for a in axes])
    acc, jerk = derivatives(vel, dt, check_positive("metrics.lowpass_hz", params.get("lowpass_hz")))
    acc_n, jerk_n = np.linalg.norm(acc, axis=1), np.linalg.norm(jerk, axis=1)
    report = params.get("controller_report") or {}
    beliefs = [b for b in report.get("contacts", []) if b.get("kind") == "impactless"]
    out: dict[str, float | None] = {}
    for c in contacts:
        name, p = str(c["name"]), np.asarray(c["position"], dtype=float)
        inside = np.linalg.norm(pos - p, axis=1) <= near
        out[f"patch_peak_acc_mps2_{name}"] = float(acc_n[inside].max()) if inside.any() else None
        out[f"patch_peak_jerk_mps3_{name}"] = float(jerk_n[inside].max()) if inside.any() else None
        dist = [float(np.linalg.norm(np.asarray(b["mean"]) - p)) for b in beliefs]
        k = int(np.argmin(dist)) if dist else -1
        ok = k >= 0 and dist[k] <= near
        out[f"region_m_{name}"] = float(beliefs[k]["region_m"]) if ok else None
        gap = np.linalg.norm(pos - p, axis=1)
        onset, delay, found, known = _switch_detection(log, t, inside, gap)
        out[f"switch_onset_s_{name}"] = onset
        out[f"switch_detect_delay_s_{name}"] = delay
        out[f"switch_detected_{name}"] = found
        out[f"switch_known_{name}"] = known
    return out


def _switch_detection(
    log: Mapping[str, np.ndarray], t: np.ndarray, inside: np.ndarray, gap: np.ndarray
) -> tuple[float | None, float | None, float | None, float | None]:
    """(onset time, detection delay, detected, known mode) of one surface switch (module docstring);
    ``inside``: the patch window per step, ``gap``: the tool point's distance from the switch
    position."""
    steps = np.flatnonzero(inside)
    if steps.size == 0:
        return None, None, None, None
    ends = np.flatnonzero(np.diff(steps) > 1)
    run = steps[: int(ends[0]) + 1] if ends.size else steps  # the first contiguous run
    mu = log.get("truth_table_friction")
    if mu is None:
        o = int(run[np.argmin(gap[run])])
    else:
        changed = np.flatnonzero(np.abs(np.asarray(mu)[run] - float(mu[run[0]])) > 1e-9)
        if changed.size == 0:
            return None, None, None, None
        o = int(run[changed[0]])
    mode, event = log.get("mode"), log.get("mode_event")
    if mode is None or event is None:
        return float(t[o]), None, None, None
    after = run[run >= o]
    event = np.asarray(event)
    hit = after[(event[after] > 0) & (np.asarray(mode)[after] != mode[o])]
    if hit.size:
        known = 1.0 if event[hit[0]] == 1 else 0.0
        return float(t[o]), float(t[hit[0]] - t[o]), 1.0, known
    return float(t[o]), float(t[after[-1]] - t[o]), 0.0, None
