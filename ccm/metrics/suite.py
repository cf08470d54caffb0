"""The benchmark suite's per-trial metrics (``ccm suite``, issue #41 part 3).

What people in contact-rich control read, each lower-is-better, from one trial log (the
columns ``t``, ``vel_*``, ``cmd_force_*``, ``contact_force_*``, ``n_contacts``: the contact
columns are the simulator's truth, for metrics only, never for a controller):

* ``peak_contact_force_N``: max over the trial of ‖contact force‖ (impacts included; springs
  and drag are not contacts); 0 when nothing was touched.
* ``force_overshoot_N``: that peak minus the median ‖contact force‖ over the in-contact
  samples: how far the transient (an impact, a ringing press) rises above the force the
  contact is held at. None without contact. ccm's definition: the tasks have no common force
  target (seed A's hybrid segments, seed B's demonstrated push, none on the springs).
* ``contact_losses``: after the first contact, the runs of at least ``contact_loss_min_s``
  without contact (:func:`count_contact_losses`); None without contact. It is ranked only on
  tasks that hold contact once made (the suite's task list says which).
* ``time_to_complete_s``: ``completion_time_s`` (:func:`ccm.metrics.trial.trial_metrics`:
  the first time at or after the pattern's end with the motion error within
  ``completion_tol_m``), or the trial's end when it never settles (a censored time, so that
  a trial that fails to finish ranks behind one that finishes late); ``completed`` says which
  (1 or 0).
* ``effort_Ns``: ∫ ‖F_cmd‖ dt, the commanded task-space force's impulse (a held push costs
  effort though it does no work).
* ``energy_J``: ∫ |F_cmd · ẋ| dt, the work the commanded force does, braking counted as
  spent (motors spend energy either way).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.core.records import AXES


def count_contact_losses(touching: np.ndarray, dt: float, min_s: float) -> float | None:
    """Runs without contact after the first contact that last at least ``min_s`` (and are
    followed by contact again or last to the end); None if never in contact."""
    if not touching.any():
        return None
    first = int(np.argmax(touching))
    c = touching[first:].astype(int)
    runs = np.split(c, np.flatnonzero(np.diff(c) != 0) + 1)
    min_len = max(1, int(round(min_s / dt)))
    return float(sum(1 for r in runs if r[0] == 0 and len(r) >= min_len))


def _columns(log: Mapping[str, np.ndarray], prefix: str, dim: int) -> np.ndarray:
    return np.column_stack([log[f"{prefix}_{a}"] for a in AXES[:dim]])


def suite_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]
) -> dict[str, float | None]:
    """The suite's metrics of one trial (module docstring). ``params``: ``cfg.metrics``
    (``contact_loss_min_s``) plus ``completion_time_s``, the trial's own (None: never)."""
    t = np.asarray(log["t"], dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1e-3
    fc = np.linalg.norm(_columns(log, "contact_force", dim), axis=1)
    touching = np.asarray(log["n_contacts"]) > 0
    cmd = _columns(log, "cmd_force", dim)
    vel = _columns(log, "vel", dim)
    done = params.get("completion_time_s")
    peak = float(fc.max()) if fc.size else 0.0
    return {
        "peak_contact_force_N": peak,
        "force_overshoot_N": peak - float(np.median(fc[touching])) if touching.any() else None,
        "contact_losses": count_contact_losses(
            touching, dt, float(params.get("contact_loss_min_s", 0.005))
        ),
        "time_to_complete_s": float(done) if done is not None else float(t[-1] + dt),
        "completed": 1.0 if done is not None else 0.0,
        "effort_Ns": float(np.sum(np.linalg.norm(cmd, axis=1)) * dt),
        "energy_J": float(np.sum(np.abs(np.sum(cmd * vel, axis=1))) * dt),
    }
