"""Collision-transition figures (seed A §4.5.1, H4, Fig. 16) for the ``contacts`` experiment.

* ``contact_transitions.png``: three rows — speed ‖v‖ [m/s], acceleration ‖a‖ [m/s²] (the
  measured velocity through :func:`ccm.metrics.trial.derivatives`, the same low-pass as every
  metric) and true external force ‖F_true‖ [N] — and one column per condition, first trial of
  each; y-axes shared per row. Spans where the transition-phase controller is active
  (``transition_alpha`` > 0) are shaded; detected collisions (``collision_event`` == 1) are
  dashed red lines, quasi-static contacts (== 2) dashed grey ones. The force row also draws
  the task's hybrid force target (``force_target_N``, seed A Eq. 1 u_fc, where it is not 0)
  and the impact force target F_d (``metrics.impact_force_target_N``, seed A Eq. 9) as
  dashed lines; one legend for the figure, right of the top-right panel.
* ``contact_transitions_last.png``: the same for the latest trial, when a condition has more
  than one.

Drawn when the experiment computes the ``contacts`` metric (a trial record holds
``transition_time_s``) or a log has ``transition_alpha``. ``F_true`` is ground truth, drawn
only for reading the figure.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.filters import derivatives
from ccm.core.records import axes_columns
from ccm.plots.modes import shade_runs
from ccm.plots.style import bound_style, merged_legend, nonzero

Log = Mapping[str, np.ndarray]


def wants_contact_figures(
    logs: Mapping[str, Sequence[Log]], trials: Sequence[Mapping[str, Any]]
) -> bool:
    """Whether the run is an H4 contacts experiment (see the module docstring)."""
    if any("transition_time_s" in tr for tr in trials):
        return True
    return any("transition_alpha" in log for runs in logs.values() for log in runs)


def _trial_label(name: str, trials: Sequence[Mapping[str, Any]], which: int) -> str:
    nums = sorted(int(tr["trial"]) for tr in trials if tr.get("condition") == name)
    if nums:
        return f"{name}, trial {nums[which]}"
    return f"{name}, {'first' if which == 0 else 'latest'} trial"


def _column(axs: Sequence[Any], log: Log, dim: int, lowpass_hz: float) -> None:
    """Speed, acceleration and force of one trial, with transition spans and events."""
    t = np.asarray(log["t"], dtype=float)
    vel = axes_columns(log, "vel", dim)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    acc, _ = derivatives(vel, dt, lowpass_hz)
    f_true = axes_columns(log, "true_force", dim)
    series = (
        (np.linalg.norm(vel, axis=1), "tab:blue"),
        (np.linalg.norm(acc, axis=1), "tab:orange"),
        (np.linalg.norm(f_true, axis=1), "tab:green"),
    )
    alpha = log.get("transition_alpha")
    events = log.get("collision_event")
    for ax, (y, color) in zip(axs, series, strict=True):
        ax.plot(t, y, color=color, lw=1.1)
        if alpha is not None:
            shade_runs(ax, t, np.asarray(alpha) > 0.0, "transition phase (α > 0)")
        if events is not None:
            ev = np.asarray(events, dtype=float)
            for code, col, text in ((1.0, "red", "collision event"), (2.0, "0.4", "quasi-static")):
                for k in np.flatnonzero(ev == code):
                    ax.axvline(t[k], color=col, ls="--", lw=1.0, label=text)
        ax.grid(alpha=0.3)
    target = log.get("force_target_N")
    if target is not None and np.any(np.asarray(target) != 0.0):
        axs[2].step(t, nonzero(target), where="post", label="force target u_fc (task)",
                    **bound_style("target"))  # fmt: skip


def _figure(
    chosen: list[tuple[str, Log]], dim: int, lowpass_hz: float, title: str, f_d: float | None
) -> Any:
    import matplotlib.pyplot as plt

    n = len(chosen)
    fig, axs = plt.subplots(3, n, figsize=(4.6 * n + 1.8, 7.5), sharey="row", sharex="col",
                            squeeze=False)  # fmt: skip
    for c, (label, log) in enumerate(chosen):
        _column(axs[:, c], log, dim, lowpass_hz)
        if f_d is not None:
            axs[2, c].axhline(f_d, label=f"impact force target F_d = {f_d:g} N",
                              **bound_style("limit"))  # fmt: skip
        axs[0, c].set_title(label, fontsize=9)
        axs[2, c].set_xlabel("time [s]")
    merged_legend(axs[0, -1], axs.flat)  # one entry per label over every panel
    axs[0, 0].set_ylabel("speed ‖v‖ [m/s]")
    axs[1, 0].set_ylabel("acceleration ‖a‖ [m/s²]")
    axs[2, 0].set_ylabel("true force ‖F‖ [N]")
    fig.suptitle(title, fontsize=10)
    return fig


def write_contact_figures(
    logs: Mapping[str, Sequence[Log]],
    dim: int,
    trials: Sequence[Mapping[str, Any]],
    lowpass_hz: float,
    save: Callable[[Any, str], None],
    impact_target_N: float | None = None,
) -> None:
    """Draw ``contact_transitions.png`` (and ``_last``) through ``save(fig, name)``; the
    speed and acceleration are low-passed at ``lowpass_hz``; ``impact_target_N``, F_d, is
    drawn in the force row when given.

    Nothing is drawn unless :func:`wants_contact_figures`. Call with the Agg backend selected
    (as :func:`ccm.plots.run.write_figures` does).
    """
    runs = {name: r for name, r in logs.items() if r}
    if not runs or not wants_contact_figures(runs, trials):
        return
    f_d = None if impact_target_N is None else float(impact_target_N)
    sub = (
        f"low-pass {lowpass_hz:g} Hz; shaded: transition phase; vertical dashes: detected contacts"
    )
    first = [(_trial_label(n, trials, 0), r[0]) for n, r in runs.items()]
    save(
        _figure(first, dim, lowpass_hz, f"Contact transitions, first trial\n({sub})", f_d),
        "contact_transitions.png",
    )
    if any(len(r) > 1 for r in runs.values()):
        last = [(_trial_label(n, trials, -1), r[-1]) for n, r in runs.items()]
        save(
            _figure(last, dim, lowpass_hz, f"Contact transitions, latest trial\n({sub})", f_d),
            "contact_transitions_last.png",
        )
