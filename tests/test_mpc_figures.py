"""The seed B figures (ccm/plots/mpc.py): mpc_force.png draws the chance constraint's bound f̄
(Eq. 18) where a condition of the panel has one, and keeps coinciding conditions visible."""

from __future__ import annotations

from typing import Any

import matplotlib
import numpy as np

from ccm.plots.mpc import write_mpc_figures

matplotlib.use("Agg")


def _log(force: float) -> dict[str, np.ndarray]:
    t = np.linspace(0.0, 1.0, 101)
    one = np.ones_like(t)
    return {
        "t": t, "contact_force_x": force * one, "contact_force_y": 0 * one,
        "mpc_infeasible": 0 * one, "damping_x_Nspm": 500 * one, "damping_y_Nspm": 500 * one,
        "mass_x_kg": 5 * one, "mass_y_kg": 5 * one,
    }  # fmt: skip


def test_force_panels_show_the_chance_bound_and_distinct_styles() -> None:
    figs: dict[str, Any] = {}
    last = {"soft_none": _log(10.0), "soft_chance": _log(10.0), "stiff_none": _log(15.0)}
    write_mpc_figures(last, 2, lambda fig, name: figs.setdefault(name, fig), {"soft_chance": 12.0})
    soft, stiff = figs["mpc_force.png"].axes
    bound = [ln for ln in soft.get_lines() if ln.get_label().startswith("f̄")]
    assert len(bound) == 1 and np.allclose(bound[0].get_ydata(), 12.0)
    assert not [ln for ln in stiff.get_lines() if ln.get_label().startswith("f̄")]
    styles = [ln.get_linestyle() for ln in soft.get_lines() if "soft" in ln.get_label()]
    assert len(set(styles)) == 2  # the two coinciding soft conditions are told apart


def test_force_target_is_drawn_and_legends_sit_outside_the_data() -> None:
    figs: dict[str, Any] = {}
    last = {"soft_none": _log(10.0), "soft_chance": _log(10.0)}
    write_mpc_figures(
        last, 2, lambda fig, name: figs.setdefault(name, fig), {"soft_chance": 12.0},
        {"soft_none": 10.0},
    )  # fmt: skip
    (soft,) = figs["mpc_force.png"].axes
    target = [ln for ln in soft.get_lines() if ln.get_label().startswith("f^r target")]
    assert len(target) == 1 and np.allclose(target[0].get_ydata(), 10.0)
    fig = figs["mpc_force.png"]
    fig.canvas.draw()
    legend, axes = soft.get_legend().get_window_extent(), soft.get_window_extent()
    assert legend.x0 >= axes.x1  # beside the panel, not over its lines
