"""The shared figure presentation (ccm/plots/style.py, issue #43 item 4): conditions told apart
when their lines coincide, legends outside the data, force targets passed to the figures."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ccm.plots.run import _force_targets_of
from ccm.plots.style import condition_style, merged_legend, outside_legend

matplotlib.use("Agg")


def test_consecutive_conditions_differ_in_colour_dashes_and_marker() -> None:
    styles = [condition_style(i, 1000) for i in range(10)]
    for a, b in zip(styles, styles[1:], strict=False):
        assert a["color"] != b["color"] and a["ls"] != b["ls"] and a["marker"] != b["marker"]
    starts = {s["markevery"][0] for s in styles[:3]}
    assert len(starts) == 3  # markers of coinciding lines do not sit on each other


def test_legends_sit_outside_the_axes() -> None:
    fig, (left, right) = plt.subplots(1, 2)
    for ax in (left, right):
        ax.plot([0, 1], [0, 1], label="a")
        ax.plot([0, 1], [1, 0], label="b")
    left.set_title("panel")
    beside, above = outside_legend(right), outside_legend(left, "above")
    fig.canvas.draw()
    assert beside.get_window_extent().x0 >= right.get_window_extent().x1
    assert above.get_window_extent().y0 >= left.get_window_extent().y1
    assert left.title.get_window_extent().y0 >= above.get_window_extent().y1 - 1.0
    plt.close(fig)


def test_a_title_clears_a_legend_of_several_rows_above() -> None:
    fig, ax = plt.subplots(figsize=(4, 6))
    for k in range(5):
        ax.plot([0, 1], [k, k], label=f"case {k}")
    ax.set_title("(a) a long panel title", fontsize=10)
    above = outside_legend(ax, "above", fontsize=8, ncol=2)  # three rows
    fig.canvas.draw()
    assert ax.title.get_window_extent().y0 >= above.get_window_extent().y1
    plt.close(fig)


def test_merged_legend_lists_each_label_once() -> None:
    fig, axs = plt.subplots(1, 2)
    for ax in axs:
        ax.axvline(0.5, label="event")
    axs[1].plot([0, 1], [0, 1], label="speed")
    legend = merged_legend(axs[-1], axs)
    assert [t.get_text() for t in legend.get_texts()] == ["event", "speed"]
    assert outside_legend(plt.figure().add_subplot()) is None  # nothing labelled
    plt.close("all")


def test_force_targets_only_where_the_cost_is_weighted() -> None:
    def comp(target: object, weight: float) -> SimpleNamespace:
        cfg = {"f_ref_target": target, "weights": {"f_ref_target": weight}}
        return SimpleNamespace(controller=SimpleNamespace(mpc_cfg=cfg))

    comps = {
        "press": comp([-15.0, 0.0], 1.0),
        "unweighted": comp([-15.0, 0.0], 0.0),
        "zero": comp(0.0, 1.0),
        "no_mpc": SimpleNamespace(controller=None),
    }
    assert _force_targets_of(comps) == {"press": 15.0}
    assert np.isclose(_force_targets_of({"d": comp([3.0, 4.0], 0.5)})["d"], 5.0)
