"""``stiffness.png``: does the stiffness adapt? (seed A Eq. 4b–4c, Fig. 10a; issue #16)

Top: K_p against time in the last trial of every condition, with the environment changes of
that trial marked (:func:`ccm.metrics.adaptation.environment_changes`: a spring attaching, a
viscosity step, a surface change, a contact made). Bottom, when conditions repeat trials:
per trial, the mean K_p over the whole trial, in the windows after the environment changes
(``stiffness_at_change_Npm``) and in the unseen viscosity range
(``mean_stiffness_unseen_Npm``), so K rising at the changes and falling as the model learns
can be read across trials.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ccm.metrics.adaptation import environment_changes
from ccm.plots.style import condition_style, outside_legend

#: per-trial series of the bottom panel: metric -> (label, line style)
SERIES = {
    "mean_stiffness_Npm": ("whole trial", "-"),
    "stiffness_at_change_Npm": ("after environment changes", "--"),
    "mean_stiffness_unseen_Npm": ("unseen viscosity range", ":"),
}


def _per_trial(trials: Sequence[Mapping[str, Any]]) -> dict[tuple[str, str], list[tuple]]:
    """(condition, metric) -> [(trial, value)] for the metrics of :data:`SERIES`."""
    out: dict[tuple[str, str], list[tuple]] = {}
    for tr in trials:
        for metric in SERIES:
            v = tr.get(metric)
            if isinstance(v, int | float) and np.isfinite(v):
                out.setdefault((tr["condition"], metric), []).append((tr["trial"], float(v)))
    return out


def write_stiffness_figure(
    last: Mapping[str, Mapping[str, np.ndarray]],
    trials: Sequence[Mapping[str, Any]],
    params: Mapping[str, Any],
    save: Callable[[Any, str], None],
) -> None:
    """Draw ``stiffness.png`` (module docstring) through ``save(fig, name)``; ``params`` are
    the ``metrics`` settings (the change detection's thresholds). Nothing when no condition
    logs a stiffness (GP-MPC logs its impedance in ``mpc_impedance.png``): an empty axes
    would read as a stiffness of nothing."""
    import matplotlib.pyplot as plt

    if not any("stiffness_Npm" in log for log in last.values()):
        return
    series = {k: v for k, v in _per_trial(trials).items() if len(v) > 1}
    rows = 2 if series else 1
    fig, axs = plt.subplots(rows, 1, figsize=(8, 3.5 * rows), squeeze=False)
    ax = axs[0, 0]
    marked = False
    for c, (name, log) in enumerate(last.items()):
        if "stiffness_Npm" not in log:
            continue
        ax.plot(log["t"], log["stiffness_Npm"], label=name,
                **condition_style(c, len(log["stiffness_Npm"])))  # fmt: skip
        for i in environment_changes(log, params):
            ax.axvline(log["t"][i], color="0.5", ls=":", lw=1,
                       label=None if marked else "environment change")  # fmt: skip
            marked = True
    ax.set_xlabel("time [s]")
    ax.set_ylabel("stiffness K_p [N/m]")
    ax.set_title("Controller stiffness (last trial)")
    ax.grid(alpha=0.3)
    outside_legend(ax, fontsize=8)
    if series:
        ax = axs[1, 0]
        names = list(dict.fromkeys(n for n, _ in series))
        for (name, metric), pts in series.items():
            xs, ys = zip(*pts, strict=True)
            label, style = SERIES[metric]
            if metric == "mean_stiffness_unseen_Npm" and params.get("unseen_above_Nspm"):
                label = f"viscosity > {float(params['unseen_above_Nspm']):g} N s/m"
            color = f"C{list(last).index(name)}" if name in last else f"C{names.index(name)}"
            ax.plot(xs, ys, style, marker="o", ms=2.5, color=color, label=f"{name}: {label}")
        ax.set_xlabel("trial")
        ax.set_ylabel("mean K_p [N/m]")
        ax.set_title("Mean stiffness per trial")
        ax.grid(alpha=0.3)
        outside_legend(ax)
    save(fig, "stiffness.png")
