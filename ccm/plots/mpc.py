"""Figures of the seed B (GP-MPC) experiments, from the last trial of each condition.

* ``mpc_force.png``: ‖true contact force‖ over time (seed B Fig. 6), one panel per condition
  group (the name up to its first ``_``, e.g. ``soft`` / ``variance`` / ``stiff``), each
  condition in its own line style (conditions that coincide stay visible), with the chance
  constraint's bound f̄ (Eq. 18) as a dashed line where a condition of the panel has one.
* ``mpc_impedance.png``: the rendered damping D and mass M per axis (seed B Fig. 8, 9d).
* ``mpc_belief.png``: the belief of each mode, with the human's true goal (seed B Fig. 11b);
  only when a condition has several modes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ccm.core.records import AXES


def _groups(names: list[str]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for n in names:
        out.setdefault(n.split("_", 1)[0], []).append(n)
    return out


_STYLES = ("-", "--", ":", "-.")


def write_mpc_figures(
    last: Mapping[str, Mapping[str, np.ndarray]],
    dim: int,
    save: Callable[[Any, str], None],
    force_bounds: Mapping[str, float] | None = None,
) -> None:
    """Write the figures above for the conditions whose log has GP-MPC signals
    (``force_bounds``: condition -> the chance constraint's f̄ [N], where it has one)."""
    import matplotlib.pyplot as plt

    logs = {n: lg for n, lg in last.items() if "mpc_infeasible" in lg}
    if not logs:
        return
    groups = _groups(list(logs))
    fig, axs = plt.subplots(len(groups), 1, figsize=(8, 2.6 * len(groups)), squeeze=False)
    bounds = force_bounds or {}
    for ax, (group, names) in zip(axs[:, 0], groups.items(), strict=True):
        for k, name in enumerate(names):
            lg = logs[name]
            fc = np.linalg.norm(
                np.column_stack([lg[f"contact_force_{a}"] for a in AXES[:dim]]), axis=1
            )
            ax.plot(lg["t"], fc, lw=1.0, ls=_STYLES[k % len(_STYLES)], label=name)
        for f_max in sorted({bounds[n] for n in names if n in bounds}):
            ax.axhline(f_max, color="k", ls="--", lw=0.8, label=f"f̄ = {f_max:g} N (Eq. 18)")
        ax.set_title(group, fontsize=9)
        ax.set_ylabel("contact force [N]")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    axs[-1, 0].set_xlabel("time [s]")
    save(fig, "mpc_force.png")

    fig, axs = plt.subplots(2, dim, figsize=(4.5 * dim, 5.5), squeeze=False)
    for name, lg in logs.items():
        for i, a in enumerate(AXES[:dim]):
            axs[0, i].plot(lg["t"], lg[f"damping_{a}_Nspm"], lw=1.0, label=name)
            axs[1, i].plot(lg["t"], lg[f"mass_{a}_kg"], lw=1.0, label=name)
    for i, a in enumerate(AXES[:dim]):
        axs[0, i].set_title(f"{a} axis", fontsize=9)
        axs[0, i].set_ylabel("damping D [N s/m]")
        axs[1, i].set_ylabel("mass M [kg]")
        axs[1, i].set_xlabel("time [s]")
        for ax in axs[:, i]:
            ax.grid(alpha=0.3)
    axs[0, 0].legend(fontsize=7)
    save(fig, "mpc_impedance.png")

    multi = {n: lg for n, lg in logs.items() if "belief_1" in lg}
    if not multi:
        return
    fig, axs = plt.subplots(len(multi), 1, figsize=(8, 2.4 * len(multi)), squeeze=False)
    for ax, (name, lg) in zip(axs[:, 0], multi.items(), strict=True):
        beliefs = sorted(k for k in lg if k.startswith("belief_"))
        for k in beliefs:
            ax.plot(lg["t"], lg[k], lw=1.2, label=k.replace("_", " "))
        if "truth_human_goal" in lg:
            ax.plot(lg["t"], lg["truth_human_goal"], "k:", lw=1.0, label="human's goal (index)")
        ax.set_title(name, fontsize=9)
        ax.set_ylabel("belief b[n]")
        ax.set_ylim(-0.05, max(1.05, len(beliefs) - 0.95))
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    axs[-1, 0].set_xlabel("time [s]")
    save(fig, "mpc_belief.png")
