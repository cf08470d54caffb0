"""The presentation every run figure shares: one style per condition and legends outside the data.

* :func:`condition_style`: the colour, line style and marker of the ``index``-th condition of a
  figure. Colour, dash pattern and marker all change from one condition to the next, so two
  conditions whose lines coincide both stay visible (the dashes and the offset markers of the
  upper one leave the lower one showing).
* :func:`bound_style`: the dashed black-and-grey lines of force bounds and targets.
* :func:`outside_legend`: a legend beside (right of) or above an axes, never over its data;
  :func:`merged_legend`: one such legend for the labelled artists of several axes.
  The layout of :func:`ccm.core.records.save_figure` (``tight_layout``) makes room for it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

#: dash patterns cycled over the conditions of a figure
LINESTYLES = ("-", "--", "-.", ":")
#: marker shapes cycled over the conditions of a figure (with a period prime to the dashes')
MARKERS = ("o", "s", "^", "v", "D", "P", "X")
#: colours: matplotlib's default cycle (tab10), so single-condition figures look as before
N_COLORS = 10
#: markers every this fraction of the axes' diagonal; each condition starts a bit later
MARK_STEP = 0.12


def condition_style(index: int, n_points: int | None = None) -> dict[str, Any]:
    """Keyword arguments of ``ax.plot`` for the ``index``-th condition of a figure.

    Args:
        index: the condition's position among the figure's conditions (0-based).
        n_points: the samples of the line, for markers evenly spaced in samples (time); None:
            spaced along the drawn line (for short lines, e.g. one point per trial).

    Returns:
        ``color``, ``ls``, ``marker``, ``markevery``, ``ms`` and ``mfc`` (hollow markers).
    """
    if n_points is None:
        every: Any = ((index * 0.37 * MARK_STEP) % MARK_STEP, MARK_STEP)
    else:
        step = max(1, int(n_points * MARK_STEP))
        every = (int(index * 0.37 * step) % step, step)
    return {
        "color": f"C{index % N_COLORS}",
        "ls": LINESTYLES[index % len(LINESTYLES)],
        "marker": MARKERS[index % len(MARKERS)],
        "markevery": every,
        "ms": 4.0,
        "mfc": "none",
    }


def bound_style(kind: str = "limit") -> dict[str, Any]:
    """Keyword arguments of ``ax.plot`` / ``ax.axhline`` for a force limit or target.

    Args:
        kind: ``"limit"`` (a bound a controller must keep to: black dashes) or ``"target"``
            (a value it aims at: grey, longer dashes).

    Returns:
        ``color``, ``ls``, ``lw`` and ``zorder`` (above the data, which often tracks a target).
    """
    if kind == "limit":
        return {"color": "k", "ls": (0, (5, 3)), "lw": 1.0, "zorder": 3}
    return {"color": "0.35", "ls": (0, (8, 3)), "lw": 1.2, "zorder": 3}


def nonzero(y: Any) -> np.ndarray:
    """``y`` as floats with its zeros NaN: a target drawn only where one is set (0: none)."""
    a = np.asarray(y, dtype=float)
    return np.where(a != 0.0, a, np.nan)


def outside_legend(
    ax: Any,
    where: str = "right",
    handles: Sequence[Any] | None = None,
    labels: Sequence[str] | None = None,
    fontsize: float = 7.0,
    ncol: int | None = None,
) -> Any:
    """Put ``ax``'s legend outside its data area; return it (None when nothing is labelled).

    Args:
        ax: the axes the legend belongs to (and is laid out with).
        where: ``"right"``: beside the axes, top-aligned; ``"above"``: over the axes' top
            edge, in columns (for wide figures; the axes' title, if any, goes above it).
        handles: the artists to list; default the labelled ones of ``ax``.
        labels: their labels; default the artists' own.
        fontsize: the legend's font size [pt].
        ncol: columns; default 1 beside and up to 4 above.

    Returns:
        The legend, or None if there is nothing to list.
    """
    if handles is None:
        handles, found = ax.get_legend_handles_labels()
        labels = found if labels is None else labels
    elif labels is None:
        labels = [h.get_label() for h in handles]
    if not handles:
        return None
    if where == "above":
        cols = ncol or min(4, len(handles))
        leg = ax.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.0),
                        ncol=cols, fontsize=fontsize, borderaxespad=0.3, frameon=False)  # fmt: skip
        if ax.get_title():
            ax.set_title(ax.get_title(), fontsize=ax.title.get_fontsize(), pad=_pad(leg, cols))
        return leg
    return ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                     ncol=ncol or 1, fontsize=fontsize, borderaxespad=0.0)  # fmt: skip


def merged_legend(anchor: Any, axes: Iterable[Any], where: str = "right") -> Any:
    """One :func:`outside_legend` at ``anchor`` listing each label of ``axes`` once (the
    first artist that carries it), for panels that share their legend entries.

    Args:
        anchor: the axes the legend is placed beside or above.
        axes: the axes whose labelled artists are listed.
        where: as :func:`outside_legend`.

    Returns:
        The legend, or None if nothing is labelled.
    """
    entries: dict[str, Any] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    return outside_legend(anchor, where, list(entries.values()), list(entries))


def _pad(legend: Any, ncol: int) -> float:
    """The title pad [pt] that clears a legend of ``ncol`` columns above the axes: its gap to
    the axes (0.3), border (2 x 0.4), rows (~1.4 each) and row spacing (0.5), in font sizes,
    and 4 pt for the title's descent."""
    rows = -(-len(legend.get_texts()) // ncol)
    size = legend.get_texts()[0].get_fontsize()
    return size * (0.3 + 0.8 + 1.4 * rows + 0.5 * (rows - 1)) + 4.0
