"""Contact-mode figures (seed A §4.3, Figs. 9-10) for controllers that log ``mode``.

* ``modes.png`` (Fig. 9): detected mode over time against the true surface id, true
  transitions as red vertical lines, and at each decision the best confidence above (green,
  "N" for a new mode) and the second-best below (red).
* ``mode_stiffness_error.png`` (Fig. 10): stiffness K_p and tracking error over time, true
  transitions marked, batch collection (``mode_collecting``) shaded.

One row per condition and kept trial: the first trial (where new modes appear) and the
latest one when they differ. Ground truth (true surfaces and transitions, as defined in
:mod:`ccm.metrics.modes`) is drawn only for reading the figure; nothing here feeds a controller.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.records import axes_columns
from ccm.metrics.modes import NEW, decisions, in_contact_steps, mode_ids, true_transition_steps
from ccm.metrics.trial import motion_error
from ccm.plots.style import outside_legend

Log = Mapping[str, np.ndarray]


def _rows(
    logs: Mapping[str, Sequence[Log]], trials: Sequence[Mapping[str, Any]]
) -> list[tuple[str, Log]]:
    """(label, log) for the first and latest kept trial of every condition that logs ``mode``."""
    rows: list[tuple[str, Log]] = []
    for name, runs in logs.items():
        if not runs or "mode" not in runs[-1]:
            continue
        nums = sorted(int(tr["trial"]) for tr in trials if tr.get("condition") == name)
        first = f"trial {nums[0]}" if nums else "first trial"
        rows.append((f"{name}, {first}", runs[0]))
        if len(runs) > 1:
            rows.append((f"{name}, trial {nums[-1]}" if nums else f"{name}, latest", runs[-1]))
    return rows


def shade_runs(ax: Any, t: np.ndarray, mask: np.ndarray, label: str | None) -> None:
    """Shade (gold) every run of steps where ``mask`` is true; ``label`` on the first only.
    Shared by the mode and contact-transition figures."""
    d = np.diff(np.r_[0, np.asarray(mask).astype(int), 0])
    for i, (a, b) in enumerate(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True)):
        ax.axvspan(
            t[a], t[min(b, len(t) - 1)], color="gold", alpha=0.35, lw=0,
            label=label if i == 0 else None,
        )  # fmt: skip


def _mark(ax: Any, log: Log, legend: bool) -> None:
    """Red lines at the true transitions and shaded batch-collection spans."""
    t = log["t"]
    truth = in_contact_steps(log)
    if truth is not None:
        for i, j in enumerate(true_transition_steps(*truth)):
            ax.axvline(
                t[j],
                color="red",
                lw=1.0,
                alpha=0.8,
                label="true transition" if legend and i == 0 else None,
            )
    if "mode_collecting" in log:
        label = "collecting batch" if legend else None
        shade_runs(ax, t, np.asarray(log["mode_collecting"]) == 1.0, label)


def _modes_panel(ax: Any, label: str, log: Log) -> None:
    """Seed A Fig. 9 for one trial."""
    t = log["t"]
    mode = mode_ids(log)
    top = max(int(mode.max(initial=0)), 0)
    truth = in_contact_steps(log)
    if truth is not None:
        ax.step(t, truth[0], where="post", color="0.2", ls="--", lw=1.2, zorder=3,
                label="true surface")  # fmt: skip
        top = max(top, int(truth[0].max(initial=0)))
    ax.step(t, mode, where="post", color="tab:blue", lw=1.6, label="detected mode")
    _mark(ax, log, legend=True)
    conf = log.get("mode_confidence")
    second = log.get("mode_second_confidence")
    for d in decisions(log):
        ax.plot(t[d.step], d.mode, "o", color="k", ms=3.5)
        # right of the decision, so the labels clear the step's vertical edge
        at = {"xy": (t[d.step], d.mode), "textcoords": "offset points", "fontsize": 7}
        if conf is not None and np.isfinite(conf[d.step]):
            tag = f"N {conf[d.step]:.2f}" if d.kind == NEW else f"{conf[d.step]:.2f}"
            ax.annotate(tag, xytext=(3, 4), color="green", va="bottom", **at)
        if second is not None and np.isfinite(second[d.step]):
            ax.annotate(f"{second[d.step]:.2f}", xytext=(3, -4), color="red", va="top", **at)
    ax.set_yticks(np.arange(-1, top + 1))
    ax.set_ylim(-1.6, top + 0.9)
    ax.set_ylabel("id (−1: none)")
    ax.set_title(label, fontsize=9)
    ax.grid(alpha=0.3)
    outside_legend(ax)


def _stiffness_error_panels(ax_k: Any, ax_e: Any, label: str, log: Log, dim: int) -> None:
    """Seed A Fig. 10 for one trial: stiffness (top) and tracking error (bottom)."""
    t = log["t"]
    if "stiffness_Npm" in log:
        ax_k.plot(t, log["stiffness_Npm"], color="tab:blue", lw=1.2, label="K_p")
    err = motion_error(
        axes_columns(log, "pos", dim),
        axes_columns(log, "target_pos", dim),
        axes_columns(log, "force_dir", dim),
    )
    ax_e.plot(t, 1000.0 * err, color="tab:purple", lw=1.0, label="tracking error")
    _mark(ax_k, log, legend=True)
    _mark(ax_e, log, legend=False)
    ax_k.set_ylabel("stiffness [N/m]")
    ax_e.set_ylabel("tracking error [mm]")
    ax_e.set_xlabel("time [s]")
    ax_k.set_title(label, fontsize=9)
    for ax in (ax_k, ax_e):
        ax.grid(alpha=0.3)
        outside_legend(ax)


def write_mode_figures(
    logs: Mapping[str, Sequence[Log]],
    dim: int,
    trials: Sequence[Mapping[str, Any]],
    save: Callable[[Any, str], None],
) -> None:
    """Draw ``modes.png`` and ``mode_stiffness_error.png`` through ``save(fig, name)``.

    Nothing is drawn when no condition's logs contain ``mode``. Call with the Agg backend
    selected (as :func:`ccm.plots.run.write_figures` does).
    """
    rows = _rows(logs, trials)
    if not rows:
        return
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(len(rows), 1, figsize=(10, 2.8 * len(rows)), squeeze=False)
    for ax, (label, log) in zip(axs[:, 0], rows, strict=True):
        _modes_panel(ax, label, log)
    axs[-1, 0].set_xlabel("time [s]")
    fig.suptitle(
        "Detected contact modes vs true surfaces; green: confidence, red: second best, N: new mode"
    )
    save(fig, "modes.png")

    fig, axs = plt.subplots(2 * len(rows), 1, figsize=(10, 2.2 * 2 * len(rows)), squeeze=False)
    for i, (label, log) in enumerate(rows):
        _stiffness_error_panels(axs[2 * i, 0], axs[2 * i + 1, 0], label, log, dim)
    fig.suptitle("Stiffness and tracking error around contact-mode transitions")
    save(fig, "mode_stiffness_error.png")
