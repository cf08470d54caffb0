"""H3 figures (seed A Figs 11-14): predictions with their 95 % band against the truth.

* ``h3_joint.png``: joint 1 position [rad] over the test trial for the joint-space variants
  (trained at one friction / at 0.1-0.7 / with high stiffness; seed A Figs 11a, 11b, 12);
* ``h3_force.png``: the force along the wall F_y [N] for the task-space variants (long
  horizon, Fig. 13; one step with feedback, Fig. 14a) and ‖F‖ [N] for ccm's incremental
  model (one step, Fig. 14b).

Bands are mean ± 1.96 std; the dotted line marks the first wall contact of the test trial.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ccm.records import save_figure

TITLES = {
    "joint_single": "joint space, trained at wall friction 0.6 (Fig. 11a)",
    "joint_multi": "joint space, trained at 0.1-0.7 (Fig. 11b)",
    "joint_high": "joint space, high stiffness (Fig. 12)",
    "task_long": "task space, long horizon: F_y (Fig. 13)",
    "task_one_step": "task space, one step with feedback: F_y (Fig. 14a)",
    "igmm": "ccm incremental IGMM, one step: ‖F‖ (Fig. 14b)",
}


def write_h3_figures(fig_dir: Path, curves: Mapping[str, Mapping[str, np.ndarray]]) -> None:
    """Write the two figures of the module docstring from :func:`ccm.h3.evaluate`'s curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    groups = {
        "h3_joint.png": (["joint_single", "joint_multi", "joint_high"], "joint 1 position [rad]"),
        "h3_force.png": (["task_long", "task_one_step", "igmm"], "force [N]"),
    }
    for fname, (names, ylabel) in groups.items():
        names = [n for n in names if n in curves]
        if not names:
            continue
        fig, axs = plt.subplots(len(names), 1, figsize=(8, 2.6 * len(names)), squeeze=False)
        for ax, n in zip(axs[:, 0], names, strict=True):
            c = curves[n]
            ax.plot(
                c["t"], c["truth"], color="black", lw=1.0, label="measured (test, friction 0.9)"
            )
            ax.plot(c["t"], c["mean"], color="tab:blue", lw=1.0, label="predicted mean")
            if np.any(np.isfinite(c["std"])):
                lo, hi = c["mean"] - 1.96 * c["std"], c["mean"] + 1.96 * c["std"]
                ax.fill_between(c["t"], lo, hi, color="tab:blue", alpha=0.25, lw=0,
                                label="95 % band")  # fmt: skip
            if np.isfinite(c["contact_t"]):
                ax.axvline(float(c["contact_t"]), color="gray", ls=":", label="wall contact")
            ax.set_title(TITLES[n], fontsize=10)
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
        axs[-1, 0].set_xlabel("time [s]")
        axs[0, 0].legend(fontsize=7, loc="best")
        save_figure(fig, fig_dir / fname)
