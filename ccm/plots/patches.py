"""Impact-less transition close-ups (seed A §4.5.2, Figs 19-20) for the ``contacts`` metric.

``patch_transitions.png``: for each of the task's impact-less contacts (a surface boundary,
one column each), the speed ‖v‖ [m/s], acceleration ‖a‖ [m/s²] (measured velocity through
:func:`ccm.metrics.trial.derivatives`, the metrics' low-pass), the horizontal part of the true
force [N] (on the table: the friction force) and, where the log has it, the friction the
simulator gives the table (``truth_table_friction``) against the time from the moment the
tool point comes closest to the boundary position, ±0.5 s. One line per condition and kept
trial (first and latest); where the anticipating controller ran its transition phase
(``transition_alpha`` > 0) the line is drawn thick; on the acceleration, x marks Algorithm
1's trigger (``mode_trigger``) and o its decision for a new current mode (``mode_event`` with
a change of ``mode``). Seed A
shows trial 1 (Fig. 19) and trials 2-3 (Fig. 20); ccm keeps the first and the latest trial.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.filters import derivatives
from ccm.core.records import axes_columns
from ccm.plots.style import merged_legend

Log = Mapping[str, np.ndarray]
HALF_WINDOW_S = 0.5  # s either side of the crossing (seed A Figs 19-20 show ~1 s sections)


def write_patch_figure(
    logs: Mapping[str, Sequence[Log]],
    contacts: Sequence[Mapping[str, Any]],
    dim: int,
    lowpass_hz: float,
    save: Callable[[Any, str], None],
) -> None:
    """Draw ``patch_transitions.png`` if the task has impact-less contacts (module docstring)."""
    import matplotlib.pyplot as plt

    patches = [c for c in contacts if c.get("kind") == "impactless"]
    if not patches or not any(logs.values()):
        return
    rows = ["speed ‖v‖ [m/s]", "acceleration ‖a‖ [m/s²]", "true friction force ‖F_h‖ [N]"]
    if any("truth_table_friction" in log for runs in logs.values() for log in runs):
        rows.append("table friction μ under the tool (truth)")
    n = len(rows)
    fig, axs = plt.subplots(n, len(patches), figsize=(5.2 * len(patches), 2.5 * n), squeeze=False)
    styles = ("-", "--", ":", "-.")
    for j, c in enumerate(patches):
        p = np.asarray(c["position"], dtype=float)
        for i, (name, runs) in enumerate(logs.items()):
            kept = list(runs) if len(runs) > 1 else list(runs[:1])
            for which, log in zip(("first", "latest"), kept, strict=False):
                _trace(axs[:, j], log, p, dim, lowpass_hz, f"{name}, {which} trial",
                       f"C{i}", styles[0 if which == "first" else 1])  # fmt: skip
        axs[0, j].set_title(f"{c['name']}: crossing at {np.round(p[:2], 3).tolist()} m")
        for r, label in enumerate(rows):
            axs[r, j].set_ylabel(label, fontsize=8)
            axs[r, j].grid(alpha=0.3)
        axs[n - 1, j].set_xlabel("time from the tool point's crossing [s]")
    merged_legend(axs[0, -1], axs.flat)
    fig.suptitle(
        f"Impact-less transitions (low-pass {lowpass_hz:g} Hz; thick: transition phase active)\n"
        "Algorithm 1: x trigger fires, o new mode decided; F_h: horizontal part of the force",
        fontsize=10,
    )
    save(fig, "patch_transitions.png")


def _trace(
    axs: Sequence[Any], log: Log, p: np.ndarray, dim: int, lowpass_hz: float, label: str,
    color: str, style: str,
) -> None:  # fmt: skip
    t = np.asarray(log["t"], dtype=float)
    pos = axes_columns(log, "pos", dim)
    k = int(np.argmin(np.linalg.norm(pos - p[:dim], axis=1)))
    sel = np.abs(t - t[k]) <= HALF_WINDOW_S
    vel = axes_columns(log, "vel", dim)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    acc, _ = derivatives(vel, dt, lowpass_hz)
    f_h = axes_columns(log, "true_force", dim)[:, :-1]  # the last axis is vertical
    rel = t[sel] - t[k]
    alpha = np.asarray(log.get("transition_alpha", np.zeros(len(t))))[sel] > 0.0
    series = [np.linalg.norm(y[sel], axis=1) for y in (vel, acc, f_h)]
    if len(axs) > 3:
        series.append(np.asarray(log.get("truth_table_friction", np.full(len(t), np.nan)))[sel])
    for ax, yn in zip(axs, series, strict=True):
        ax.plot(rel, yn, style, color=color, lw=1.0, label=label)
        if alpha.any():
            ax.plot(rel, np.where(alpha, yn, np.nan), style, color=color, lw=3.0, alpha=0.5)
    mode, event, trig = log.get("mode"), log.get("mode_event"), log.get("mode_trigger")
    if mode is None or event is None or trig is None:
        return
    m, idx = np.asarray(mode), np.flatnonzero(sel)
    changed = (np.asarray(event) > 0) & (m != np.r_[m[:1], m[:-1]])
    for steps, marker in ((np.asarray(trig) > 0, "x"), (changed, "o")):
        at = np.flatnonzero(steps & sel)
        axs[1].plot(
            t[at] - t[k], series[1][np.searchsorted(idx, at)], marker, color=color, ms=7, mew=1.5
        )
