"""Figures of the seed B (GP-MPC) experiments, from the last trial of each condition.

* ``mpc_force.png``: ‖true contact force‖ over time (seed B Fig. 6), one panel per condition
  group (the name up to its first ``_``, e.g. ``soft`` / ``variance`` / ``stiff``), each
  condition in its own line style (conditions that coincide stay visible), with the chance
  constraint's bound f̄ (Eq. 18) as a dashed black line where a condition of the panel has
  one, and the target of the f^r-target cost (‖f_target‖, seed B §6.2) as a dashed grey one
  where a condition weights it. Legends beside the panels (:mod:`ccm.plots.style`).
* ``mpc_impedance.png``: the rendered damping D and mass M per axis (seed B Fig. 8, 9d).
* ``mpc_belief.png``: the belief of each mode, with the human's true goal (seed B Fig. 11b);
  only when a condition has several modes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ccm.core.records import AXES
from ccm.plots.style import bound_style, condition_style, outside_legend


def _groups(names: list[str]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for n in names:
        out.setdefault(n.split("_", 1)[0], []).append(n)
    return out


def write_mpc_figures(
    last: Mapping[str, Mapping[str, np.ndarray]],
    dim: int,
    save: Callable[[Any, str], None],
    force_bounds: Mapping[str, float] | None = None,
    force_targets: Mapping[str, float] | None = None,
) -> None:
    """Write the figures above for the conditions whose log has GP-MPC signals.

    Args:
        last: condition -> the columns of its last trial.
        dim: the task's dimension.
        save: ``save(fig, name)`` writes a figure.
        force_bounds: condition -> the chance constraint's f̄ [N], where it has one.
        force_targets: condition -> ‖f_target‖ [N] of its f^r-target cost, where it has one.
    """
    logs = {n: lg for n, lg in last.items() if "mpc_infeasible" in lg}
    if not logs:
        return
    _force_figure(logs, dim, save, force_bounds or {}, force_targets or {})
    _impedance_figure(logs, dim, save)
    _belief_figure(logs, save)


def _force_figure(
    logs: Mapping[str, Mapping[str, np.ndarray]],
    dim: int,
    save: Callable[[Any, str], None],
    bounds: Mapping[str, float],
    targets: Mapping[str, float],
) -> None:
    """``mpc_force.png``: one panel per condition group, its bounds and targets dashed."""
    import matplotlib.pyplot as plt

    order = list(logs)  # a condition's style is the same in every panel and figure
    groups = _groups(order)
    fig, axs = plt.subplots(len(groups), 1, figsize=(9.5, 2.6 * len(groups)), squeeze=False)
    for ax, (group, names) in zip(axs[:, 0], groups.items(), strict=True):
        for name in names:
            lg = logs[name]
            fc = np.linalg.norm(
                np.column_stack([lg[f"contact_force_{a}"] for a in AXES[:dim]]), axis=1
            )
            ax.plot(lg["t"], fc, lw=1.0, label=name, **condition_style(order.index(name), len(fc)))
        for f_max in sorted({bounds[n] for n in names if n in bounds}):
            ax.axhline(f_max, label=f"f̄ = {f_max:g} N (Eq. 18)", **bound_style("limit"))
        for f_t in sorted({targets[n] for n in names if n in targets}):
            ax.axhline(f_t, label=f"f^r target = {f_t:g} N (cost)", **bound_style("target"))
        ax.set_title(group, fontsize=9)
        ax.set_ylabel("contact force [N]")
        outside_legend(ax)
        ax.grid(alpha=0.3)
    axs[-1, 0].set_xlabel("time [s]")
    save(fig, "mpc_force.png")


def _impedance_figure(
    logs: Mapping[str, Mapping[str, np.ndarray]], dim: int, save: Callable[[Any, str], None]
) -> None:
    """``mpc_impedance.png``: D and M per axis, every condition in its own style."""
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(2, dim, figsize=(4.5 * dim + 2.0, 5.5), squeeze=False)
    for c, (name, lg) in enumerate(logs.items()):
        style = condition_style(c, len(lg["t"]))
        for i, a in enumerate(AXES[:dim]):
            axs[0, i].plot(lg["t"], lg[f"damping_{a}_Nspm"], lw=1.0, label=name, **style)
            axs[1, i].plot(lg["t"], lg[f"mass_{a}_kg"], lw=1.0, label=name, **style)
    for i, a in enumerate(AXES[:dim]):
        axs[0, i].set_title(f"{a} axis", fontsize=9)
        axs[0, i].set_ylabel("damping D [N s/m]")
        axs[1, i].set_ylabel("mass M [kg]")
        axs[1, i].set_xlabel("time [s]")
        for ax in axs[:, i]:
            ax.grid(alpha=0.3)
    outside_legend(axs[0, -1])
    save(fig, "mpc_impedance.png")


def _belief_figure(
    logs: Mapping[str, Mapping[str, np.ndarray]], save: Callable[[Any, str], None]
) -> None:
    """``mpc_belief.png``: each mode's belief and the human's true goal, per condition."""
    import matplotlib.pyplot as plt

    multi = {n: lg for n, lg in logs.items() if "belief_1" in lg}
    if not multi:
        return
    fig, axs = plt.subplots(len(multi), 1, figsize=(9.5, 2.4 * len(multi)), squeeze=False)
    for ax, (name, lg) in zip(axs[:, 0], multi.items(), strict=True):
        beliefs = sorted(k for k in lg if k.startswith("belief_"))
        for j, k in enumerate(beliefs):
            ax.plot(lg["t"], lg[k], lw=1.2, label=k.replace("_", " "),
                    **condition_style(j, len(lg[k])))  # fmt: skip
        if "truth_human_goal" in lg:
            ax.plot(lg["t"], lg["truth_human_goal"], "k:", lw=1.0, label="human's goal (index)")
        ax.set_title(name, fontsize=9)
        ax.set_ylabel("belief b[n]")
        ax.set_ylim(-0.05, max(1.05, len(beliefs) - 0.95))
        outside_legend(ax)
        ax.grid(alpha=0.3)
    axs[-1, 0].set_xlabel("time [s]")
    save(fig, "mpc_belief.png")
