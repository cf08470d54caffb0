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

Summary metrics per curve ``<integrator>/<objective>`` (the claims of seed B §5.2 in
``experiments/claims.yaml``):

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
  Hessian is indefinite (λ_min < 0): "indefinite for typical parameter values".

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

from ccm.core.errors import (
    ConfigError,
    check_bounds,
    check_int_positive,
    check_positive,
    config_block,
)
from ccm.core.records import save_figure, write_json_atomic

INTEGRATORS = ("euler", "implicit", "exponential")
OBJECTIVES = ("trace", "logdet")
_KEYS = ("ts", "mass", "damping", "sigma_x", "sigma_v", "q", "sigma_f_range", "n_points",
         "typical_sigma_f", "mass_range", "damping_range", "n_phi")  # fmt: skip


def hessian_functions(settings: Mapping[str, Any]) -> dict[str, Any]:
    """``{"<integrator>/<objective>": casadi Function (φ = [M, D], Σ_f) → 2×2 Hessian of the
    one-step cost over φ}`` (Eq. 8, one step; the integrators of the module docstring)."""
    import casadi as ca

    ts = settings["ts"]
    mass, damp, sf = ca.SX.sym("M"), ca.SX.sym("D"), ca.SX.sym("sigma_f")
    phi = ca.vertcat(mass, damp)
    sigma = ca.diag(ca.vertcat(settings["sigma_x"], settings["sigma_v"]))  # prior Σ (Eq. 8)
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
            out[f"{name}/{obj}"] = ca.Function("h", [phi, sf], [ca.hessian(cost, phi)[0]])
    return out


def hessian_min_eig(settings: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """``{"<integrator>/<objective>": min eigenvalue per Σ_f, "<...>/rel": the same divided
    by the largest |eigenvalue| (scale-free, in [-1, 1]), "sigma_f": Σ_f}``, at φ = (mass,
    damping) of ``settings``."""
    m0, d0 = settings["mass"], settings["damping"]
    lo, hi = settings["sigma_f_range"]
    sig_f = np.logspace(np.log10(lo), np.log10(hi), settings["n_points"])
    out: dict[str, np.ndarray] = {"sigma_f": sig_f}
    for key, h in hessian_functions(settings).items():
        eigs = np.array([np.linalg.eigvalsh(np.array(h([m0, d0], s))) for s in sig_f])
        out[key] = eigs[:, 0]
        out[f"{key}/rel"] = eigs[:, 0] / np.abs(eigs).max(axis=1)
    return out


def indefinite_fraction(settings: Mapping[str, Any]) -> dict[str, float]:
    """Per curve, the fraction of the (M, D) grid (``mass_range`` × ``damping_range``,
    ``n_phi`` log-spaced values each) where the Hessian at Σ_f = ``typical_sigma_f`` has a
    negative eigenvalue."""
    n = settings["n_phi"]
    grid = [(m, d) for m in np.geomspace(*settings["mass_range"], n)
            for d in np.geomspace(*settings["damping_range"], n)]  # fmt: skip
    sf = settings["typical_sigma_f"]
    return {
        key: float(
            np.mean([np.linalg.eigvalsh(np.array(h([m, d], sf)))[0] < 0.0 for m, d in grid])
        )  # fmt: skip
        for key, h in hessian_functions(settings).items()
    }


def rank_corr(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman rank correlation of ``y`` with ``x`` (average ranks for ties); 0.0 when either
    is constant (no trend)."""
    from scipy.stats import rankdata

    rx, ry = rankdata(x), rankdata(y)
    if np.ptp(rx) == 0.0 or np.ptp(ry) == 0.0:
        return 0.0
    return float(np.corrcoef(rx, ry)[0, 1])


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
    return s


def run_convexity(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Evaluate the curves, write ``figures/mpc_convexity.png`` and the summary: per curve,
    the minimum eigenvalue at the smallest, middle and largest Σ_f and the metrics of the
    module docstring; ``all_curves`` the metrics over the six curves."""
    s = _settings(cfg)
    t0 = time.perf_counter()
    curves = hessian_min_eig(s)
    indefinite = indefinite_fraction(s)
    conditions: dict[str, dict[str, Any]] = {}
    for key in indefinite:
        conditions[key] = curve_metrics(curves["sigma_f"], curves[key], curves[f"{key}/rel"])
        conditions[key]["indefinite_fraction_typical"] = indefinite[key]
    conditions["all_curves"] = across_curves(conditions)
    if cfg.experiment.get("figures", True):
        _figure(out_dir / "figures" / "mpc_convexity.png", curves)
    summary = {"experiment": str(cfg.experiment.name), "status": "ok", "seed": int(cfg.seed),
               "conditions": conditions, "trials": []}  # fmt: skip
    write_json_atomic(out_dir / "run_info.json", {"wall_time_s": time.perf_counter() - t0})
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


def _convex_above(sigma_f: np.ndarray, eig: np.ndarray) -> float | None:
    bad = np.flatnonzero(eig < 0.0)
    if bad.size == 0:
        return float(sigma_f[0])
    return float(sigma_f[bad[-1] + 1]) if bad[-1] + 1 < len(sigma_f) else None


def _figure(path: Path, curves: Mapping[str, np.ndarray]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, axs = plt.subplots(1, 2, figsize=(10, 4), sharey=False)
    for ax, obj in zip(axs, OBJECTIVES, strict=True):
        for integ in INTEGRATORS:
            ax.plot(curves["sigma_f"], curves[f"{integ}/{obj}/rel"], label=integ)
        ax.axhline(0.0, color="gray", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("GP force variance Σ_f [N²]")
        ax.set_ylabel("λ_min / max|λ| of the Hessian over (M, D) [-]")
        ax.set_title("Tr(QΣ⁺)" if obj == "trace" else "ln det(QΣ⁺)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(
        "Convexity over (M, D) of the one-step covariance cost (seed B Fig. 4; > 0: convex)"
    )
    save_figure(fig, path)
