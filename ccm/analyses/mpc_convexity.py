"""Convexity of the MPC's covariance cost over impedance parameters (seed B §5.2, Fig. 4).

One degree of freedom of the admittance (Eq. 4 without K), state ξ = [x, ẋ], one step of
the covariance propagation (Eq. 8): Σ⁺ = A Σ Aᵀ + B Σ_f Bᵀ, with B = [0, T_s/M]ᵀ and the
velocity row of A given by the integrator:

* ``euler`` (explicit): ẋ⁺ = (1 − T_s D/M) ẋ. Seed B §5.2 prints ``1 + T_s D/M``; the
  minus sign is the explicit Euler step of M ẍ = −D ẋ (the printed sign is a typo: it would
  make any damping destabilising);
* ``implicit`` (Eq. 5, seed B's choice): ẋ⁺ = M (M + T_s D)⁻¹ ẋ;
* ``exponential``: ẋ⁺ = exp(−T_s D/M) ẋ.

For each integrator and for the objectives Tr(QΣ⁺) and ln det(QΣ⁺), the Hessian with
respect to φ = (M, D) is taken symbolically (casadi) and its minimum eigenvalue evaluated as
the GP force variance Σ_f sweeps ``sigma_f_range``; the objective is convex at φ where it is
≥ 0. Seed B's claims: the trace is better than the log-determinant, the implicit integrator
better on average than explicit Euler (indefinite at typical values), and convexity
improves as Σ_f grows.

The claims of seed B §5.2 (``experiments/claims.yaml``) are judged over a grid of operating
points (M, D, prior Σ) with tolerances (issue #37): :mod:`ccm.analyses.mpc_convexity_grid`,
whose fractions ``grid_frac_<relation>`` / ``grid_informative_<relation>`` and
``grid_n_points`` go to the condition ``all_curves``; per point, ``operating_points.json``;
figure ``mpc_convexity_grid.png``.

At the single point of the config (``mass``, ``damping``, ``sigma_x``, ``sigma_v``; Fig. 4's
analogue, ``mpc_convexity.png``) the diagnostics per curve ``<integrator>/<objective>``:

* ``convex_fraction``: the fraction of the Σ_f grid where λ_min ≥ 0; ``convex_above_sigma_f``
  the smallest Σ_f from which it stays convex (None: never);
* ``convex_fraction_lower_half`` / ``_upper_half``: the same over the lower / upper half of
  the log-spaced grid (the middle point of an odd grid in neither);
* ``min_eig_rank_corr``: Spearman rank correlation of λ_min with Σ_f (1: increasing
  everywhere, −1: decreasing; 0 for a constant curve);
* ``mean_rel_min_eig``: the mean over the grid of λ_min / max|λ| (Fig. 4's curve, scale-free):
  "average performance over the range of Σ_f";
* ``indefinite_fraction_typical``: at Σ_f = ``typical_sigma_f``, the fraction of a log-spaced
  ``n_phi`` × ``n_phi`` grid of (M, D) over ``mass_range`` × ``damping_range`` where the
  Hessian is indefinite (λ_min < 0): "indefinite for typical parameter values";
  ``indefinite_fraction_typical_grid`` the same pooled over the prior stds of
  ``convexity.grid`` (the claim);
* ``grid_always_convex_fraction`` / ``grid_never_convex_fraction``: the fractions of the
  operating points where the curve is convex at every / no swept Σ_f;

and over the six curves (condition ``all_curves``): ``frac_curves_convexity_grows``, the
fraction of curves whose upper-half convex fraction exceeds the lower-half one, and
``min_rank_corr``, the smallest ``min_eig_rank_corr``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.analyses.mpc_convexity_grid import (
    INTEGRATORS,
    OBJECTIVES,
    curve_stats,
    grid_figure,
    grid_fractions,
    grid_settings,
    operating_points,
    point_relations,
    rank_corr,
    saturation_fractions,
)
from ccm.core.errors import (
    ConfigError,
    check_bounds,
    check_int_positive,
    check_positive,
    config_block,
)
from ccm.core.records import save_figure, write_json_atomic
from ccm.plots.style import condition_style, merged_legend

_KEYS = ("ts", "mass", "damping", "sigma_x", "sigma_v", "q", "sigma_f_range", "n_points",
         "typical_sigma_f", "mass_range", "damping_range", "n_phi",
         "grid", "tolerance")  # fmt: skip


def hessian_functions(settings: Mapping[str, Any]) -> dict[str, Any]:
    """``{"<integrator>/<objective>": casadi Function (φ = [M, D], Σ_f, prior = [Σ_xx, Σ_vv])
    → 2×2 Hessian of the one-step cost over φ}`` (Eq. 8, one step; the integrators of the
    module docstring). Built once; :func:`batch_min_eig` evaluates it at many points."""
    import casadi as ca

    ts = settings["ts"]
    mass, damp, sf = ca.SX.sym("M"), ca.SX.sym("D"), ca.SX.sym("sigma_f")
    phi, prior = ca.vertcat(mass, damp), ca.SX.sym("prior", 2)
    sigma = ca.diag(prior)  # prior Σ (Eq. 8)
    q = ca.SX(np.diag(settings["q"]))
    rows = {
        "euler": 1 - ts * damp / mass,
        "implicit": mass / (mass + ts * damp),
        "exponential": ca.exp(-ts * damp / mass),
    }
    out: dict[str, Any] = {}
    for name, a22 in rows.items():
        a = ca.vertcat(ca.horzcat(1, ts), ca.horzcat(0, a22))
        b = ca.vertcat(0, ts / mass)
        sig_plus = a @ sigma @ a.T + b @ sf @ b.T  # Eq. 8, one step
        qs = q @ sig_plus
        costs = {"trace": ca.trace(qs), "logdet": ca.log(ca.det(qs))}
        for obj, cost in costs.items():
            hess = ca.hessian(cost, phi)[0]
            out[f"{name}/{obj}"] = ca.Function("h", [phi, sf, prior], [hess])
    return out


def batch_min_eig(fn: Any, phi: np.ndarray, sf: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """``(λ_min, λ_min / max|λ|)`` of the Hessian ``fn`` at the rows of ``phi`` (N × 2),
    ``sf`` (N) and ``prior`` (N × 2), as a 2 × N array (one mapped casadi call)."""
    n = len(sf)
    flat = np.array(fn.map(n)(phi.T, np.reshape(sf, (1, n)), prior.T))  # 2 × 2N
    eigs = np.linalg.eigvalsh(flat.reshape(2, n, 2).transpose(1, 0, 2))
    return np.stack([eigs[:, 0], eigs[:, 0] / np.abs(eigs).max(axis=1)])


def sigma_f_grid(settings: Mapping[str, Any]) -> np.ndarray:
    """The swept Σ_f: ``n_points`` log-spaced values over ``sigma_f_range`` [N²]."""
    lo, hi = settings["sigma_f_range"]
    return np.logspace(np.log10(lo), np.log10(hi), settings["n_points"])


def hessian_min_eig(settings: Mapping[str, Any], fns: Mapping | None = None) -> dict:
    """``{"<integrator>/<objective>": min eigenvalue per Σ_f, "<...>/rel": the same divided
    by the largest |eigenvalue| (scale-free, in [-1, 1]), "sigma_f": Σ_f}``, at φ = (mass,
    damping) and the prior (sigma_x, sigma_v) of ``settings``."""
    fns = fns or hessian_functions(settings)
    sig_f = sigma_f_grid(settings)
    n = len(sig_f)
    phi = np.tile([settings["mass"], settings["damping"]], (n, 1))
    prior = np.tile([settings["sigma_x"], settings["sigma_v"]], (n, 1))
    out: dict[str, np.ndarray] = {"sigma_f": sig_f}
    for key, h in fns.items():
        out[key], out[f"{key}/rel"] = batch_min_eig(h, phi, sig_f, prior)
    return out


def indefinite_fraction(
    settings: Mapping[str, Any], fns: Mapping | None = None, priors: np.ndarray | None = None
) -> dict[str, float]:
    """Per curve, the fraction of the (M, D) grid (``mass_range`` × ``damping_range``,
    ``n_phi`` log-spaced values each) where the Hessian at Σ_f = ``typical_sigma_f`` has a
    negative eigenvalue; pooled over the rows [Σ_xx, Σ_vv] of ``priors`` (default: the
    settings' one prior)."""
    fns = fns or hessian_functions(settings)
    n = settings["n_phi"]
    if priors is None:
        priors = np.array([[settings["sigma_x"], settings["sigma_v"]]])
    md = [(m, d) for m in np.geomspace(*settings["mass_range"], n)
          for d in np.geomspace(*settings["damping_range"], n)]  # fmt: skip
    phi = np.array([p for _ in priors for p in md])
    prior = np.repeat(priors, len(md), axis=0)
    sf = np.full(len(phi), settings["typical_sigma_f"])
    return {key: float(np.mean(batch_min_eig(h, phi, sf, prior)[0] < 0.0))
            for key, h in fns.items()}  # fmt: skip


def grid_curves(settings: Mapping[str, Any], fns: Mapping, points: np.ndarray) -> dict:
    """``{curve: (λ_min, λ_min / max|λ|)}``, each an array (operating point × Σ_f), at the
    rows [M, D, Σ_xx, Σ_vv] of ``points`` (one mapped call per curve)."""
    sig_f = sigma_f_grid(settings)
    p, n = len(points), len(sig_f)
    phi = np.repeat(points[:, :2], n, axis=0)
    prior = np.repeat(points[:, 2:], n, axis=0)
    sf = np.tile(sig_f, p)
    return {key: batch_min_eig(h, phi, sf, prior).reshape(2, p, n) for key, h in fns.items()}


def curve_metrics(sigma_f: np.ndarray, eig: np.ndarray, rel: np.ndarray) -> dict[str, Any]:
    """The per-curve summary metrics of the module docstring (Σ_f grid part)."""
    n = len(eig)
    convex = eig >= 0.0
    return {
        "min_eig_low_sigma_f": float(eig[0]),
        "min_eig_mid_sigma_f": float(eig[n // 2]),
        "min_eig_high_sigma_f": float(eig[-1]),
        "convex_fraction": float(np.mean(convex)),
        # the smallest swept Σ_f from which the objective stays convex (None: never)
        "convex_above_sigma_f": _convex_above(sigma_f, eig),
        "convex_fraction_lower_half": float(np.mean(convex[: n // 2])),
        "convex_fraction_upper_half": float(np.mean(convex[(n + 1) // 2 :])),
        "min_eig_rank_corr": rank_corr(sigma_f, eig),
        "mean_rel_min_eig": float(np.mean(rel)),
    }


def across_curves(per_curve: Mapping[str, Mapping[str, Any]]) -> dict[str, float]:
    """``all_curves``: the fraction of curves whose convex fraction grows from the lower to
    the upper half of the Σ_f range, and the smallest rank correlation of λ_min with Σ_f."""
    curves = list(per_curve.values())
    grows = [c["convex_fraction_upper_half"] > c["convex_fraction_lower_half"] for c in curves]
    return {
        "frac_curves_convexity_grows": float(np.mean(grows)),
        "min_rank_corr": float(min(c["min_eig_rank_corr"] for c in curves)),
    }


def _settings(cfg: DictConfig) -> dict[str, Any]:
    s = config_block(cfg, "convexity", _KEYS)
    for k in ("ts", "mass", "damping", "sigma_x", "sigma_v"):
        s[k] = check_positive(f"convexity.{k}", s.get(k))
    s["typical_sigma_f"] = check_positive("convexity.typical_sigma_f", s.get("typical_sigma_f"))
    for k in ("n_points", "n_phi"):
        s[k] = check_int_positive(f"convexity.{k}", s.get(k))
    for k in ("sigma_f_range", "mass_range", "damping_range"):
        s[k] = check_bounds(f"convexity.{k}", s.get(k))
    q = s.get("q")
    if not isinstance(q, list) or len(q) != 2:
        raise ConfigError("convexity.q", f"must be the 2 diagonal weights of Q, got {q!r}")
    for i, v in enumerate(q):
        check_positive(f"convexity.q[{i}]", v)
    s["grid"], s["tolerance"] = grid_settings(s)
    return s


def grid_study(s: Mapping[str, Any], fns: Mapping) -> dict[str, Any]:
    """The claims' grid (issue #37; :mod:`ccm.analyses.mpc_convexity_grid`): the operating
    points, per point the curves' stats and the relations, and the fractions over the grid."""
    single = (s["mass"], s["damping"], s["sigma_x"], s["sigma_v"])
    points = operating_points(s["grid"], single)
    sig_f = sigma_f_grid(s)
    curves = grid_curves(s, fns, points)
    per_point = [
        {key: curve_stats(eig[i], rel[i], sig_f) for key, (eig, rel) in curves.items()}
        for i in range(len(points))
    ]
    relations = [point_relations(p, s["tolerance"]) for p in per_point]
    grid = s["grid"]
    priors = np.array([(sx**2, sv**2) for sx in grid["pos_std"] for sv in grid["vel_std"]])
    n_grid = int(np.prod([len(v) for v in grid.values()]))
    return {"points": points, "sigma_f": sig_f, "per_point": per_point,
            "relations": relations, "fractions": grid_fractions(relations),
            "indefinite": indefinite_fraction(s, fns, priors), "n_grid": n_grid}  # fmt: skip


def _points_table(study: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One row per operating point for ``operating_points.json``: its values, relations and
    per curve the convex threshold Σ_f (None: never convex in the sweep)."""
    sig_f, n = study["sigma_f"], len(study["sigma_f"])
    rows = []
    for (m, d, vx, vv), stats, rel in zip(
        study["points"], study["per_point"], study["relations"], strict=True
    ):
        above = {k: None if c["threshold"] >= n else float(sig_f[c["threshold"]])
                 for k, c in stats.items()}  # fmt: skip
        rows.append({"mass": float(m), "damping": float(d), "pos_std": float(np.sqrt(vx)),
                     "vel_std": float(np.sqrt(vv)), "relations": rel,
                     "convex_above_sigma_f": above})  # fmt: skip
    return rows


def run_convexity(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Evaluate the curves at the single point and over the grid, write the figures,
    ``operating_points.json`` and the summary: per curve the single-point metrics of the
    module docstring plus its grid facts; ``all_curves`` the metrics over the six curves and
    the claims' grid fractions."""
    s = _settings(cfg)
    t0 = time.perf_counter()
    fns = hessian_functions(s)
    curves = hessian_min_eig(s, fns)
    indefinite = indefinite_fraction(s, fns)
    study = grid_study(s, fns)
    conditions: dict[str, dict[str, Any]] = {}
    for key in indefinite:
        conditions[key] = curve_metrics(curves["sigma_f"], curves[key], curves[f"{key}/rel"])
        conditions[key]["indefinite_fraction_typical"] = indefinite[key]
        conditions[key]["indefinite_fraction_typical_grid"] = study["indefinite"][key]
        conditions[key].update(saturation_fractions(study["per_point"], key))
    conditions["all_curves"] = {**across_curves(conditions), **study["fractions"],
                                "grid_n_points": len(study["points"])}  # fmt: skip
    cpu0 = time.process_time()
    if cfg.experiment.get("figures", True):
        figs = out_dir / "figures"
        _figure(figs / "mpc_convexity.png", curves, s)
        grid_figure(figs / "mpc_convexity_grid.png", study["points"], study["sigma_f"],
                    study["per_point"], study["relations"], study["n_grid"])  # fmt: skip
    figures_cpu = time.process_time() - cpu0
    summary = {"experiment": str(cfg.experiment.name), "status": "ok", "seed": int(cfg.seed),
               "conditions": conditions, "trials": []}  # fmt: skip
    write_json_atomic(out_dir / "operating_points.json", _points_table(study))
    info = {
        "wall_time_s": time.perf_counter() - t0,
        "cpu_s": {"figures": figures_cpu},
    }
    write_json_atomic(out_dir / "run_info.json", info)
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


def _convex_above(sigma_f: np.ndarray, eig: np.ndarray) -> float | None:
    bad = np.flatnonzero(eig < 0.0)
    if bad.size == 0:
        return float(sigma_f[0])
    return float(sigma_f[bad[-1] + 1]) if bad[-1] + 1 < len(sigma_f) else None


def _figure(path: Path, curves: Mapping[str, np.ndarray], s: Mapping[str, Any]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, axs = plt.subplots(1, 2, figsize=(10, 4), sharey=False)
    for ax, obj in zip(axs, OBJECTIVES, strict=True):
        for i, integ in enumerate(INTEGRATORS):  # own styles: the curves coincide at 0 and -1
            ax.plot(curves["sigma_f"], curves[f"{integ}/{obj}/rel"], label=integ,
                    **condition_style(i))  # fmt: skip
        ax.axhline(0.0, color="gray", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("GP force variance Σ_f [N²]")
        ax.set_ylabel("λ_min / max|λ| of the Hessian over (M, D) [-]")
        ax.set_title("Tr(QΣ⁺)" if obj == "trace" else "ln det(QΣ⁺)")
        ax.grid(alpha=0.3)
    merged_legend(axs[-1], axs)
    fig.suptitle(
        "Convexity over (M, D) of the one-step covariance cost (seed B Fig. 4; > 0: convex)\n"
        f"single point: M {s['mass']:g} kg, D {s['damping']:g} N s/m, prior std "
        f"{np.sqrt(s['sigma_x']) * 1e3:.3g} mm, {np.sqrt(s['sigma_v']) * 1e3:.3g} mm/s"
    )
    save_figure(fig, path)
