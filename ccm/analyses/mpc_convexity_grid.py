"""Seed B §5.2 over a grid of operating points, with tolerances (issue #37).

The single-point study of :mod:`ccm.analyses.mpc_convexity` takes the Hessian of the one-step
covariance cost (Eq. 8) at one chosen (M, D, prior Σ); seed B gives none of these values, and
there its claims were decided by one step of the Σ_f grid. Here each claim's relation is
evaluated at every operating point (M, D, prior position std, prior velocity std) of
``convexity.grid``, and counts at a point only when it holds by ``convexity.tolerance``:

* ``trace_implicit_convex``: implicit/trace's convex threshold (the first Σ_f grid index from
  which λ_min ≥ 0 stays; ``n`` when the last point is indefinite) at least ``convex_steps``
  below euler/trace's;
* ``trace_beats_logdet_<integrator>``: trace's count of convex Σ_f grid points at least
  ``convex_steps`` above ln det's;
* ``convexity_grows``: every curve that is convex at some but not all Σ_f has at least
  ``convex_steps`` more convex points in the upper half of the (log) Σ_f range than in the lower;
* ``min_eig_grows``: the smallest Spearman correlation of λ_min with Σ_f over the six curves is
  at least ``rank_corr_min``;
* ``implicit_beats_<euler|exponential>_average``: with the trace cost, the mean over the Σ_f
  grid of λ_min / max|λ| of the implicit integrator at least ``mean_rel`` above the other's.

A comparison of convex ranges says nothing at a point where both curves are convex at every
swept Σ_f, or both at none (the transition lies outside the sweep): such a point is *not
informative* for it (``None``) and is left out of its fraction. Per relation the summary keeps
``grid_frac_<relation>``, the fraction of the informative points where it holds, and
``grid_informative_<relation>``, the fraction of the grid that is informative.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_int_positive,
    check_keys,
    check_positive,
    check_range,
)
from ccm.core.records import save_figure

INTEGRATORS = ("euler", "implicit", "exponential")
OBJECTIVES = ("trace", "logdet")
RELATIONS = (
    "trace_implicit_convex", "trace_beats_logdet_euler", "trace_beats_logdet_implicit",
    "trace_beats_logdet_exponential", "convexity_grows", "min_eig_grows",
    "implicit_beats_euler_average", "implicit_beats_exponential_average",
)  # fmt: skip
_GRID_KEYS = ("mass", "damping", "pos_std", "vel_std")
_TOL_KEYS = ("convex_steps", "mean_rel", "rank_corr_min")


@dataclass(frozen=True)
class Tolerance:
    """The margins by which a relation must hold to count (``convexity.tolerance``)."""

    convex_steps: int  # Σ_f grid steps between two convex counts / thresholds
    mean_rel: float  # between two means of λ_min / max|λ|
    rank_corr_min: float  # the smallest rank correlation that reads as "increases"


def rank_corr(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman rank correlation of ``y`` with ``x`` (average ranks for ties); 0.0 when either
    is constant (no trend)."""
    from scipy.stats import rankdata

    rx, ry = rankdata(x), rankdata(y)
    if np.ptp(rx) == 0.0 or np.ptp(ry) == 0.0:
        return 0.0
    return float(np.corrcoef(rx, ry)[0, 1])


def grid_settings(block: Mapping[str, Any]) -> tuple[dict[str, list[float]], Tolerance]:
    """Validate ``convexity.grid`` (four non-empty lists of positive values) and
    ``convexity.tolerance``; every error names its key."""
    grid = block.get("grid")
    if not isinstance(grid, Mapping):
        raise ConfigError("convexity.grid", f"must be a mapping of {', '.join(_GRID_KEYS)}")
    check_keys("convexity.grid", grid, _GRID_KEYS)
    out: dict[str, list[float]] = {}
    for k in _GRID_KEYS:
        vals = grid.get(k)
        if not isinstance(vals, list) or not vals:
            raise ConfigError(f"convexity.grid.{k}", f"must be a non-empty list, got {vals!r}")
        out[k] = [check_positive(f"convexity.grid.{k}[{i}]", v) for i, v in enumerate(vals)]
    tol = block.get("tolerance")
    if not isinstance(tol, Mapping):
        raise ConfigError("convexity.tolerance", f"must be a mapping of {', '.join(_TOL_KEYS)}")
    check_keys("convexity.tolerance", tol, _TOL_KEYS)
    return out, Tolerance(
        convex_steps=check_int_positive(
            "convexity.tolerance.convex_steps", tol.get("convex_steps")
        ),
        mean_rel=check_positive("convexity.tolerance.mean_rel", tol.get("mean_rel")),
        rank_corr_min=check_range(
            "convexity.tolerance.rank_corr_min", tol.get("rank_corr_min"), -1.0, 1.0
        ),
    )


def operating_points(grid: Mapping[str, Sequence[float]], single: Sequence[float]) -> np.ndarray:
    """Rows ``[M, D, prior position variance, prior velocity variance]``: every combination of
    ``grid``'s lists (stds squared; grouped by prior, then M, then D), then ``single`` (M, D,
    variances) unless it is already one of them."""
    rows = [
        (m, d, sx**2, sv**2)
        for sx, sv, m, d in itertools.product(
            grid["pos_std"], grid["vel_std"], grid["mass"], grid["damping"]
        )
    ]
    if not any(np.allclose(r, single, rtol=1e-12, atol=0.0) for r in rows):
        rows.append(tuple(float(v) for v in single))
    return np.array(rows, dtype=float)


def curve_stats(eig: np.ndarray, rel: np.ndarray, sigma_f: np.ndarray) -> dict[str, Any]:
    """What the relations read from one curve λ_min(Σ_f): counts of convex grid points (all,
    lower and upper half), the threshold index, ``saturated`` ("all" / "none" convex, else
    None), the rank correlation of λ_min with Σ_f and the mean of λ_min / max|λ|."""
    n = len(eig)
    convex = eig >= 0.0
    bad = np.flatnonzero(~convex)
    n_convex = int(convex.sum())
    return {
        "n_convex": n_convex,
        "n_lower": int(convex[: n // 2].sum()),
        "n_upper": int(convex[(n + 1) // 2 :].sum()),
        "threshold": 0 if bad.size == 0 else int(bad[-1]) + 1,
        "saturated": "all" if n_convex == n else ("none" if n_convex == 0 else None),
        "rank_corr": rank_corr(sigma_f, eig),
        "mean_rel": float(np.mean(rel)),
    }


def _informative(a: Mapping[str, Any], b: Mapping[str, Any]) -> bool:
    """False when both curves are convex at every swept Σ_f, or both at none."""
    return a["saturated"] is None or a["saturated"] != b["saturated"]


def point_relations(stats: Mapping[str, Mapping[str, Any]], tol: Tolerance) -> dict[str, Any]:
    """Each relation of the module docstring at one operating point: True / False, or None
    where the point is not informative for it. ``stats``: :func:`curve_stats` per curve."""
    steps = tol.convex_steps
    impl, euler = stats["implicit/trace"], stats["euler/trace"]
    out: dict[str, Any] = {
        "trace_implicit_convex": (euler["threshold"] - impl["threshold"] >= steps)
        if _informative(impl, euler)
        else None
    }
    for integ in INTEGRATORS:
        tr, ld = stats[f"{integ}/trace"], stats[f"{integ}/logdet"]
        out[f"trace_beats_logdet_{integ}"] = (
            (tr["n_convex"] - ld["n_convex"] >= steps) if _informative(tr, ld) else None
        )
    grows = [c["n_upper"] - c["n_lower"] >= steps for c in stats.values() if not c["saturated"]]
    out["convexity_grows"] = all(grows) if grows else None
    out["min_eig_grows"] = min(c["rank_corr"] for c in stats.values()) >= tol.rank_corr_min
    for other in ("euler", "exponential"):
        diff = impl["mean_rel"] - stats[f"{other}/trace"]["mean_rel"]
        out[f"implicit_beats_{other}_average"] = bool(diff >= tol.mean_rel)
    return out


def grid_fractions(rows: Sequence[Mapping[str, Any]]) -> dict[str, float | None]:
    """Per relation, ``grid_frac_<relation>``: the fraction of the informative points where it
    holds (None: no informative point), and ``grid_informative_<relation>``: the fraction of
    the points that are informative."""
    out: dict[str, float | None] = {}
    for name in RELATIONS:
        counted = [bool(r[name]) for r in rows if r[name] is not None]
        out[f"grid_frac_{name}"] = float(np.mean(counted)) if counted else None
        out[f"grid_informative_{name}"] = len(counted) / len(rows) if rows else None
    return out


def saturation_fractions(per_point: Sequence[Mapping[str, Mapping[str, Any]]], key: str) -> dict:
    """For curve ``key``: the fractions of the operating points where it is convex at every
    swept Σ_f (``grid_always_convex_fraction``) and at none (``grid_never_convex_fraction``)."""
    sat = [p[key]["saturated"] for p in per_point]
    return {
        "grid_always_convex_fraction": sat.count("all") / len(sat),
        "grid_never_convex_fraction": sat.count("none") / len(sat),
    }


def grid_figure(
    path: Path,
    points: np.ndarray,
    sigma_f: np.ndarray,
    per_point: Sequence[Mapping[str, Mapping[str, Any]]],
    relations: Sequence[Mapping[str, Any]],
    n_grid: int,
) -> None:
    """Top: each curve's convex threshold Σ_f per operating point (▲ at the top edge: never
    convex in the sweep; ▼ at the bottom: convex everywhere). Bottom: each relation per point
    (holds by the tolerance / fails / not informative). ``n_grid``: the number of grid points
    before the single point."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    path.parent.mkdir(parents=True, exist_ok=True)
    n, x = len(sigma_f), np.arange(len(points))
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(14, 8), sharex=True,
                                 gridspec_kw={"height_ratios": [3, 2]})  # fmt: skip
    markers = {"trace": "o", "logdet": "s"}
    colors = {"euler": "tab:blue", "implicit": "tab:orange", "exponential": "tab:green"}
    lo, hi = sigma_f[0] / 3.0, sigma_f[-1] * 3.0
    for integ, obj in itertools.product(INTEGRATORS, OBJECTIVES):
        k = np.array([p[f"{integ}/{obj}"]["threshold"] for p in per_point])
        y = np.where(k >= n, hi, sigma_f[np.minimum(k, n - 1)])
        y = np.where(k == 0, lo, y)
        ax.scatter(x, y, s=14, marker=markers[obj], facecolors="none" if obj == "logdet" else
                   colors[integ], edgecolors=colors[integ], label=f"{integ}/{obj}")  # fmt: skip
    ax.axhline(sigma_f[0], color="gray", lw=0.6, ls=":")
    ax.axhline(sigma_f[-1], color="gray", lw=0.6, ls=":")
    ax.set_yscale("log")
    ax.set_ylim(lo / 2.0, hi * 2.0)
    ax.set_ylabel("convex from Σ_f [N²]\n(top: never, bottom: always)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.grid(alpha=0.3)
    code = {True: 2, False: 0, None: 1}
    mat = np.array([[code[r[name]] for r in relations] for name in RELATIONS])
    bx.imshow(mat, aspect="auto", interpolation="nearest", vmin=0, vmax=2,
              cmap=ListedColormap(["tab:red", "lightgray", "tab:green"]))  # fmt: skip
    bx.set_yticks(range(len(RELATIONS)), RELATIONS, fontsize=7)
    bx.set_xlabel(_point_axis_label())
    blocks = _prior_blocks(points, n_grid)
    bx.set_xticks([b[0] for b in blocks], [b[1] for b in blocks], fontsize=7)
    for b in blocks[1:]:
        ax.axvline(b[0] - 0.5, color="gray", lw=0.4)
    fig.suptitle("Seed B §5.2 over the operating-point grid; bottom: green holds by the "
                 "tolerance, red fails, gray not informative")  # fmt: skip
    save_figure(fig, path)


def _prior_blocks(points: np.ndarray, n_grid: int) -> list[tuple[int, str]]:
    """The first index and label of each run of grid points with the same prior stds, and of
    the single point when it follows the grid (index ``n_grid``)."""
    out: list[tuple[int, str]] = []
    for i, (m, d, vx, vv) in enumerate(points):
        label = f"{np.sqrt(vx) * 1e3:.3g} mm\n{np.sqrt(vv) * 1e3:.3g} mm/s"
        if i >= n_grid:
            out.append((i, f"single\npoint:\nM {m:g}\nD {d:g}"))
        elif not out or out[-1][1] != label:
            out.append((i, label))
    return out


def _point_axis_label() -> str:
    return ("operating point: blocks of prior std (position [mm], velocity [mm/s]), each over "
            "M [kg] (outer) × D [N s/m] (inner) of the grid; last: the single point")  # fmt: skip
