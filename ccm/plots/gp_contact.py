"""Figure of the ``gp_contact_models`` analysis (seed B Fig. 5): GP force over position."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.records import save_figure
from ccm.plots.style import condition_style, outside_legend


def write_gp_contact_figure(
    path: Path,
    curves: Mapping[str, Mapping[str, Any]],
    panels: Sequence[tuple[str, Sequence[tuple[str, str]]]],
) -> None:
    """Seed B Fig. 5 (a), (b), (c) in three columns, ``panels`` = (title, [(case, label), ...])
    each; top: the whole demonstrations, bottom: zoomed on the contact. Data as dots, GP mean
    ± 2σ (predictive: latent and noise), true contact positions dashed (one per demonstration
    for a varying wall)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, axs = plt.subplots(2, 3, figsize=(16, 8.5))
    for col, (title, cases) in enumerate(panels):
        present = [(curves[c], lab) for c, lab in cases if c in curves]
        for row in (0, 1):
            ax = axs[row, col]
            if not present:
                ax.text(0.5, 0.5, "case not run", ha="center", va="center", transform=ax.transAxes)
                ax.set_axis_off()
                continue
            for i, (c, label) in enumerate(present):
                _draw(ax, c, label, i)
            xs = np.concatenate([c["x"] for c, _ in present])
            lo, hi = float(xs.min()), float(xs.max())
            if row == 1:  # the stiff slope is a few tenths of a mm wide
                cs = [x for c, _ in present for x in c["contacts"]]
                lo, hi = min(cs) - 0.002, max(hi, max(cs)) + 0.0005
            ax.set_xlim(lo, hi)
            fs = np.concatenate([c["f"][(c["x"] >= lo) & (c["x"] <= hi)] for c, _ in present])
            pad = 0.1 * (fs.max() - fs.min()) + 1.0
            ax.set_ylim(fs.min() - pad, fs.max() + pad)
            ax.set_title(title if row == 0 else "zoom on the contact", fontsize=10)
            ax.set_xlabel("EE position x [m]")
            ax.set_ylabel("measured force f_x [N]")
            ax.grid(alpha=0.3)
            if row == 0:  # the zoom below has the same cases in the same styles
                outside_legend(ax, "above", fontsize=8, ncol=2)
    fig.suptitle(
        "Hinge-mean GP force models (seed B Fig. 5): data (dots), GP mean (line) ± 2σ "
        "predictive (band), true contact position (dashed)", fontsize=11,
    )  # fmt: skip
    save_figure(fig, path)


def _draw(ax: Any, c: Mapping[str, Any], label: str, index: int) -> None:
    style = condition_style(index, len(c["grid"]))  # cases whose means coincide stay visible
    color = style["color"]
    ax.plot(c["x"], c["f"], ".", ms=2.5, color=color, alpha=0.35)
    ax.plot(c["grid"], c["mu"], lw=1.5, label=label, **style)
    lo, hi = c["mu"] - 2 * c["std"], c["mu"] + 2 * c["std"]
    ax.fill_between(c["grid"], lo, hi, color=color, alpha=0.18, lw=0)
    for x in sorted(set(c["contacts"])):
        ax.axvline(x, color=color, ls="--", lw=0.9)
