"""Contact-belief metrics from the controller's report (seed A §4.5.1, Table 1; issue #5).

Part of :func:`ccm.metrics.contacts.contact_metrics` (the collision metrics and the log
columns are described there), and :func:`contact_table`, the Table 1 layout of a run's trials.

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
  and ``detection_depth_m_<name>`` = its part along −n_c (n_c the contact's unit outward
  normal, as in :mod:`ccm.metrics.contacts`; how far past the nominal surface
  the tool point was at the detected onset; negative short of it). None when not measured.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["belief_metrics", "contact_table"]


def belief_metrics(
    task_contacts: Sequence[Mapping[str, Any]], report: Mapping[str, Any] | None
) -> dict[str, float | None]:
    """The belief metrics of the module docstring, for every contact of the task.

    Args:
        task_contacts: The task's contacts (``name``, ``position``, ``normal``).
        report: The controller's report (``contacts``: its beliefs), or None.
    """
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
