"""Figure of seed B's rail task (§6.2, Fig. 8): damping against the distance to the rail.

``mpc_rail_damping.png``: one column per condition, rows D_x and D_y [N s/m] against the
distance between the tool's contact point and the rail [m] (:func:`ccm.metrics.mpc.rail_distance`;
≤ 0 in contact), for every trial after the demonstrations (the autonomous trial dashed). The
trials are read back from the run's ``timeseries`` Parquet files, since the runner keeps only two
logs per condition in memory (so the rail experiment sets ``experiment.timeseries: all``; a trial
without a file is left out). Written only when ``metrics.rail_point`` is set.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from ccm.core.records import AXES
from ccm.core.timeseries import read_timeseries, trial_path
from ccm.metrics.mpc import rail_distance
from ccm.plots.style import merged_legend


def write_rail_figure(
    run_dir: Path,
    trials: Sequence[Mapping[str, Any]],
    dim: int,
    params: Mapping[str, Any],
    save: Callable[[Any, str], None],
) -> None:
    """Plot D per axis against the distance to the rail for the non-demonstration trials."""
    import matplotlib.pyplot as plt

    if params.get("rail_point") is None:
        return
    shown = [t for t in trials if not str(t.get("phase", "")).startswith("demo")]
    conds = list(dict.fromkeys(str(t["condition"]) for t in shown))
    if not conds:
        return
    fig, axs = plt.subplots(dim, len(conds), figsize=(4.2 * len(conds), 2.8 * dim), squeeze=False)
    for j, cond in enumerate(conds):
        for t in (t for t in shown if t["condition"] == cond):
            path = trial_path(run_dir, cond, int(t["trial"]))
            if not path.exists():
                continue
            log = read_timeseries(path)
            if f"damping_{AXES[0]}_Nspm" not in log:
                continue
            d = rail_distance(log, dim, params)
            style = "--" if t.get("phase") == "autonomous" else "-"
            for i, a in enumerate(AXES[:dim]):
                axs[i, j].plot(
                    d, log[f"damping_{a}_Nspm"], style, lw=1.0,
                    label=f"trial {t['trial']} ({t.get('phase')})",
                )  # fmt: skip
        axs[0, j].set_title(cond, fontsize=9)
        for i, a in enumerate(AXES[:dim]):
            axs[i, j].set_ylabel(f"damping D_{a} [N s/m]")
            axs[i, j].axvline(0.0, color="k", lw=0.8, ls=":")
            axs[i, j].invert_xaxis()  # the approach runs left to right, the rail at 0
            axs[i, j].grid(alpha=0.3)
        axs[-1, j].set_xlabel("distance of the tool to the rail [m]")
    merged_legend(axs[0, -1], axs.flat)
    save(fig, "mpc_rail_damping.png")
