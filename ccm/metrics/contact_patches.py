"""Impact-less transition metrics from a trial log (seed A §4.5.2, Figs 19-20; issue #5).

Part of :func:`ccm.metrics.contacts.contact_metrics` (the log columns and the collision
metrics are described there).

For every task contact of kind ``impactless`` (its position: where the tool point crosses onto
the new surface):

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
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.core.errors import check_positive
from ccm.core.filters import derivatives

__all__ = ["patch_metrics"]


def patch_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]
) -> dict[str, float | None]:
    """The impact-less (patch) metrics of the module docstring.

    Args:
        log: The trial log's columns.
        dim: Task dimension (the axes ``"xyz"[:dim]``).
        params: ``cfg.metrics`` with ``task_contacts`` and ``controller_report``.
    """
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
