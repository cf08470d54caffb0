"""H3 figures (seed A Figs 11-14): predictions with their 95 % band against the truth.

* ``h3_joint.png``: joint 1 position [rad] over the test trial for the joint-space variants
  (trained at one friction / at 0.1-0.7 / with high stiffness; seed A Figs 11a, 11b, 12);
* ``h3_force.png``: the force along the wall F_y [N] for the absolute task-space GP (long
  horizon, Fig. 13; one step with feedback, Fig. 14a) and for ccm's incremental model (one
  step, its ‖F̂‖ along the latest measured force; Fig. 14b);
* ``h3_force_delta.png``: F_y [N] for the increment GP (long horizon, one step), ccm's
  variant of Figs 13-14a.

Bands are mean ± 1.96 std; the dotted line marks the first wall contact of the test trial.
The one-step panels show the range of the truth and the mean: their bands spike at the
wall impact and would otherwise squash the force along the wall, which Fig. 14 is about.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.records import save_figure
from ccm.plots.style import outside_legend

TITLES = {
    "joint_single": "joint space, trained at wall friction 0.6 (Fig. 11a)",
    "joint_multi": "joint space, trained at 0.1-0.7 (Fig. 11b)",
    "joint_high": "joint space, high stiffness (Fig. 12)",
    "task_long": "task space, absolute GP, long horizon (Fig. 13)",
    "task_one_step": "task space, absolute GP, one step with feedback (Fig. 14a)",
    "igmm": "ccm incremental IGMM, one step: ‖F̂‖ along the latest F (Fig. 14b)",
    "task_long_delta": "task space, increment GP, long horizon (ccm's variant of Fig. 13)",
    "task_one_step_delta": "task space, increment GP, one step (ccm's variant of Fig. 14a)",
}
F_Y = "F_y along the wall [N]"
FIGURES = {
    "h3_joint.png": (["joint_single", "joint_multi", "joint_high"], "joint 1 position [rad]"),
    "h3_force.png": (["task_long", "task_one_step", "igmm"], F_Y),
    "h3_force_delta.png": (["task_long_delta", "task_one_step_delta"], F_Y),
}


def _panel(ax: Any, name: str, c: Mapping[str, np.ndarray], ylabel: str) -> None:
    """One variant: truth, predicted mean, 95 % band, wall contact."""
    ax.plot(c["t"], c["truth"], color="black", lw=1.0, label="measured (test, friction 0.9)")
    ax.plot(c["t"], c["mean"], color="tab:blue", lw=1.0, label="predicted mean")
    if np.any(np.isfinite(c["std"])):
        lo, hi = c["mean"] - 1.96 * c["std"], c["mean"] + 1.96 * c["std"]
        ax.fill_between(c["t"], lo, hi, color="tab:blue", alpha=0.25, lw=0, label="95 % band")
    if np.isfinite(c["contact_t"]):
        ax.axvline(float(c["contact_t"]), color="gray", ls=":", label="wall contact")
    if "one_step" in name:  # module docstring: clip the band's impact spikes
        lo, hi = np.nanmin([c["truth"], c["mean"]]), np.nanmax([c["truth"], c["mean"]])
        pad = 0.1 * max(hi - lo, 1e-6)
        ax.set_ylim(lo - pad, hi + pad)
    ax.set_title(TITLES[name], fontsize=10)
    ax.set_ylabel(ylabel)
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3)


def write_h3_figures(fig_dir: Path, curves: Mapping[str, Mapping[str, np.ndarray]]) -> None:
    """Write the figures of the module docstring from :func:`ccm.analyses.h3.evaluate`'s curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    for fname, (names, ylabel) in FIGURES.items():
        names = [n for n in names if n in curves]
        if not names:
            continue
        fig, axs = plt.subplots(len(names), 1, figsize=(8, 2.8 * len(names)), squeeze=False)
        for ax, n in zip(axs[:, 0], names, strict=True):
            _panel(ax, n, curves[n], ylabel)
        outside_legend(axs[0, 0])
        save_figure(fig, fig_dir / fname)
