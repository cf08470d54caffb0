"""Contact-mode detection metrics from a trial log (seed A §3.2, Algorithm 1, §4.3, H2).

Inputs are the trial-log columns of the mode-aware controller (``mode``, ``mode_trigger``,
``mode_event``, ``mode_confidence``, ``mode_second_confidence``, ``mode_collecting``), its
``stiffness_Npm``, and the simulator's ground truth ``truth_surface_friction`` and
``truth_contact`` (metrics only; controllers never see them). Parameters come from
``cfg.metrics``: ``transition_pre_s``, ``transition_tolerance_s``, ``high_stiffness_Npm``.
A log without a ``mode`` column (any other controller) gives ``None`` for every metric; a log
without the two truth columns gives ``None`` for the metrics that need them.

Definitions (one trial; step k is one control step, ``t[k]`` its time):

* **True surface id** of step k: the distinct values of ``truth_surface_friction`` that are
  ≥ 0, rounded to 1e-6, numbered 0, 1, 2, … in order of first appearance in the trial; −1
  where the friction is < 0 or NaN (out of contact).
* **In-contact steps**: ``truth_contact == 1`` and a true surface id ≥ 0.
* **True transitions**: the in-contact steps whose true surface id differs from that of the
  previous in-contact step (a change from one surface to another while sliding, or across a
  lift-off). The first in-contact step of the trial is not a transition: it is an initial
  assignment. (Corner case: a touchdown on a *different* surface after a lift-off is a true
  transition, but a controller that shows mode −1 in the gap cannot detect it, since its next
  decision follows −1; such a transition counts as missed.)
* **Decision**: a step d with ``mode_event > 0`` (1 = known mode, 2 = new mode); its decided
  mode is ``mode[d]`` (NaN in ``mode`` counts as −1). Its **trigger** is the last step s ≤ d
  with ``mode_trigger == 1`` (d itself if there is none). Its **previous mode** is
  ``mode[s − 1]`` (−1 if s = 0).
* **Detected transitions**: the decisions whose decided mode differs from their previous mode
  *and* whose previous mode is ≥ 0. A decision after −1 is an initial assignment (excluded,
  like the first contact); a decision back to the previous mode is an anomaly (Algorithm 1:
  the change that fired the trigger was not a transition).
* **Matching**: greedy one-to-one in time order. Detected transitions are taken in order of
  their trigger time; each matches the earliest still-unmatched true transition at step j
  with ``t[j] − transition_pre_s ≤ t[s] ≤ t[j] + transition_tolerance_s``, if there is one.
* ``transition_recall`` = matched true transitions / all true transitions (None if there are
  none); ``transition_precision`` = matched detected transitions / all detected transitions
  (None if none were detected); ``n_true_transitions``, ``n_detected_transitions``.
* **Mode → surface mapping**: modes are visited in ascending id. Mode m owns the true surface
  that is most frequent over the in-contact steps with ``mode == m`` (ties: the lower surface
  id), unless a lower mode id already owns that surface — then m owns no surface. A mode
  that is never active on an in-contact step owns no surface.
* ``mode_accuracy``: over the in-contact steps with ``mode ≥ 0``, the fraction where the owned
  surface of ``mode`` equals the true surface id (None if there are no such steps).
* ``false_new_modes``: the number of new-mode decisions (``mode_event == 2``) in this trial
  whose mode owns no surface under that mapping (None without the truth columns).
* ``mean_confidence_margin``: mean over the known-mode decisions (``mode_event == 1``) of
  ``mode_confidence − mode_second_confidence`` at the decision step, i.e. how clearly the
  recognised mode beat the runner-up (seed A Fig. 9). A new-mode decision has no recognised
  mode (its best confidence is below the threshold), so it is left out. A NaN second-best
  counts as 0, a NaN confidence is left out (None if no decision remains).
* ``high_stiffness_time_new_s`` / ``high_stiffness_time_known_s``: for a decision d with
  trigger s, the time ``t[k] − t[s]`` where k is the first step k ≥ d with ``stiffness_Npm <
  high_stiffness_Npm``, searched only up to the next trigger after d (or the trial's end); if
  the stiffness does not drop before that cap, the time runs to the cap (``t`` of the next
  trigger, or the last ``t`` of the trial). Mean over the new-mode / known-mode decisions made
  *while sliding* (previous mode ≥ 0: surface changes and anomalies), the case of seed A
  Fig. 10 (None if there is no decision of that kind, or no ``stiffness_Npm`` column).
* ``high_stiffness_time_initial_s``: the same time for the initial assignments (previous mode
  −1, after making contact), reported apart because it also covers however long the pattern
  presses before it starts to slide.
* ``n_modes_total``: the largest mode id in the log + 1 (mode ids persist across trials, so
  this counts the modes created so far, not only in this trial).

The mapping and the counts use this trial's log only; modes created in earlier trials are
mapped by how they are used in this one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ccm.core.errors import check_nonneg, check_positive

#: keys returned by :func:`mode_metrics`
MODE_METRIC_KEYS = (
    "transition_recall",
    "transition_precision",
    "n_true_transitions",
    "n_detected_transitions",
    "mode_accuracy",
    "false_new_modes",
    "mean_confidence_margin",
    "high_stiffness_time_new_s",
    "high_stiffness_time_known_s",
    "high_stiffness_time_initial_s",
    "n_modes_total",
)

#: ``mode_event`` codes at a decision step
KNOWN, NEW = 1, 2
INITIAL = 0  # bookkeeping only: a decision after mode −1 (first classification in contact)


@dataclass(frozen=True)
class Decision:
    """One classified batch: decision step, trigger step, kind, decided and previous mode."""

    step: int
    trigger: int
    kind: int  # KNOWN or NEW
    mode: int
    previous: int

    @property
    def is_transition(self) -> bool:
        """A detected transition: a change of mode away from a mode ≥ 0."""
        return self.previous >= 0 and self.mode != self.previous


def true_surface_ids(friction: np.ndarray) -> np.ndarray:
    """True surface id per step: friction values ≥ 0 (to 1e-6) numbered by first appearance."""
    ids = np.full(len(friction), -1, dtype=int)
    seen: dict[float, int] = {}
    for k, mu in enumerate(np.asarray(friction, dtype=float)):
        if mu >= 0.0:  # False for NaN
            ids[k] = seen.setdefault(round(float(mu), 6), len(seen))
    return ids


def in_contact_steps(log: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
    """(true surface id per step, in-contact mask), or None without the truth columns."""
    if "truth_surface_friction" not in log or "truth_contact" not in log:
        return None
    sid = true_surface_ids(log["truth_surface_friction"])
    return sid, (np.asarray(log["truth_contact"]) == 1.0) & (sid >= 0)


def true_transition_steps(sid: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Steps where the surface differs from the previous in-contact step's (first contact
    excluded)."""
    steps = np.flatnonzero(contact)
    return steps[1:][sid[steps[1:]] != sid[steps[:-1]]]


def mode_ids(log: Mapping[str, np.ndarray]) -> np.ndarray:
    """The ``mode`` column as integers (NaN counts as −1, no mode)."""
    return np.nan_to_num(np.asarray(log["mode"], dtype=float), nan=-1.0).astype(int)


def trigger_steps(log: Mapping[str, np.ndarray]) -> np.ndarray:
    """Steps with ``mode_trigger == 1`` (a transition was triggered, batch collection began)."""
    return np.flatnonzero(np.asarray(log["mode_trigger"], dtype=float) == 1.0)


def decisions(log: Mapping[str, np.ndarray]) -> list[Decision]:
    """The classified batches of a mode-aware controller's log, in time order."""
    mode = mode_ids(log)
    event = np.nan_to_num(np.asarray(log["mode_event"], dtype=float))
    trig = trigger_steps(log)
    out = []
    for d in np.flatnonzero(event > 0):
        before = trig[trig <= d]
        s = int(before[-1]) if before.size else int(d)
        prev = int(mode[s - 1]) if s > 0 else -1
        kind = NEW if event[d] == NEW else KNOWN
        out.append(Decision(int(d), s, kind, int(mode[d]), prev))
    return out


def match_transitions(
    t: np.ndarray, true_steps: np.ndarray, detected: list[Decision], pre_s: float, tol_s: float
) -> int:
    """Number of detected transitions matched one-to-one to true ones (greedy, time order)."""
    free = [int(j) for j in true_steps]
    matched = 0
    for dec in sorted(detected, key=lambda x: x.trigger):
        ts = t[dec.trigger]
        for j in free:
            if t[j] - pre_s <= ts <= t[j] + tol_s:
                free.remove(j)
                matched += 1
                break
    return matched


def mode_owners(mode: np.ndarray, sid: np.ndarray, contact: np.ndarray) -> dict[int, int]:
    """Mode id → owned true surface id (−1: owns none), for every mode ≥ 0 in ``mode``.

    ``mode`` holds integer mode ids per step (:func:`mode_ids`).
    """
    m = np.asarray(mode, dtype=int)
    owners: dict[int, int] = {}
    taken: set[int] = set()
    for mid in sorted(int(x) for x in np.unique(m[m >= 0])):
        surf = sid[contact & (m == mid)]
        owners[mid] = -1
        if surf.size:
            best = int(np.argmax(np.bincount(surf)))  # ties -> lowest surface id
            if best not in taken:
                owners[mid] = best
                taken.add(best)
    return owners


def _high_stiffness_time(
    t: np.ndarray, stiff: np.ndarray, dec: Decision, next_trigger: int, k_high: float
) -> float:
    low = np.flatnonzero(stiff[dec.step : next_trigger] < k_high)
    end = dec.step + int(low[0]) if low.size else next_trigger
    t_end = t[end] if end < len(t) else t[-1]
    return float(t_end - t[dec.trigger])


def _mean(values: list[float]) -> float | None:
    return float(np.mean(values)) if values else None


def mode_metrics(
    log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, float]
) -> dict[str, float | None]:
    """The H2 contact-mode metrics of one trial (definitions in the module docstring).

    Args:
        log: Trial-log columns (see :class:`ccm.core.records.TrialRecorder`).
        dim: Task dimension (unused: the metrics need no axis columns; kept for the
            :data:`ccm.metrics.trial.EXTRA_METRICS` signature).
        params: ``cfg.metrics`` with ``transition_pre_s`` [s], ``transition_tolerance_s``
            [s] and ``high_stiffness_Npm`` [N/m].
    """
    out: dict[str, float | None] = dict.fromkeys(MODE_METRIC_KEYS)
    if "mode" not in log:
        return out
    pre = check_nonneg("metrics.transition_pre_s", params.get("transition_pre_s"))
    tol = check_nonneg("metrics.transition_tolerance_s", params.get("transition_tolerance_s"))
    k_high = check_positive("metrics.high_stiffness_Npm", params.get("high_stiffness_Npm"))
    t = np.asarray(log["t"], dtype=float)
    mode = mode_ids(log)
    decs = decisions(log)
    detected = [d for d in decs if d.is_transition]
    out["n_detected_transitions"] = float(len(detected))
    out["n_modes_total"] = float(max(int(mode.max(initial=-1)) + 1, 0))

    truth = in_contact_steps(log)
    if truth is not None:
        sid, contact = truth
        true_steps = true_transition_steps(sid, contact)
        matched = match_transitions(t, true_steps, detected, pre, tol)
        out["n_true_transitions"] = float(len(true_steps))
        out["transition_recall"] = matched / len(true_steps) if len(true_steps) else None
        out["transition_precision"] = matched / len(detected) if detected else None
        owners = mode_owners(mode, sid, contact)
        used = contact & (mode >= 0)
        if used.any():
            owned = np.array([owners[m] for m in mode[used]])
            out["mode_accuracy"] = float(np.mean(owned == sid[used]))
        out["false_new_modes"] = float(
            sum(1 for d in decs if d.kind == NEW and owners.get(d.mode, -1) < 0)
        )

    conf = np.asarray(log.get("mode_confidence", np.full(len(t), np.nan)), dtype=float)
    second = np.asarray(log.get("mode_second_confidence", np.full(len(t), np.nan)), dtype=float)
    margins = [
        float(conf[d.step] - np.nan_to_num(second[d.step]))
        for d in decs
        if d.kind == KNOWN and np.isfinite(conf[d.step])
    ]
    out["mean_confidence_margin"] = _mean(margins)

    if "stiffness_Npm" in log:
        out.update(_high_stiffness_times(log, t, decs, k_high))
    return out


def _high_stiffness_times(
    log: Mapping[str, np.ndarray], t: np.ndarray, decs: list[Decision], k_high: float
) -> dict[str, float | None]:
    """Mean time at high stiffness after a decision, per kind (new, known, initial mode),
    each capped at the next trigger (module docstring)."""
    stiff = np.nan_to_num(np.asarray(log["stiffness_Npm"], dtype=float), nan=np.inf)
    trig = trigger_steps(log)
    times: dict[int, list[float]] = {KNOWN: [], NEW: [], INITIAL: []}
    for d in decs:
        later = trig[trig > d.step]
        cap = int(later[0]) if later.size else len(t)
        kind = d.kind if d.previous >= 0 else INITIAL
        times[kind].append(_high_stiffness_time(t, stiff, d, cap, k_high))
    return {
        "high_stiffness_time_new_s": _mean(times[NEW]),
        "high_stiffness_time_known_s": _mean(times[KNOWN]),
        "high_stiffness_time_initial_s": _mean(times[INITIAL]),
    }
