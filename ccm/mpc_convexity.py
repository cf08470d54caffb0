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
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.errors import ConfigError, check_int_positive, check_positive, config_block
from ccm.records import save_figure, write_json_atomic

INTEGRATORS = ("euler", "implicit", "exponential")
OBJECTIVES = ("trace", "logdet")
_KEYS = ("ts", "mass", "damping", "sigma_x", "sigma_v", "q", "sigma_f_range", "n_points")


def hessian_min_eig(settings: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """``{"<integrator>/<objective>": min eigenvalue per Σ_f, "<...>/rel": the same divided
    by the largest |eigenvalue| (scale-free, in [-1, 1]), "sigma_f": Σ_f}``."""
    import casadi as ca

    ts, m0, d0 = settings["ts"], settings["mass"], settings["damping"]
    lo, hi = settings["sigma_f_range"]
    sig_f = np.logspace(np.log10(lo), np.log10(hi), settings["n_points"])
    mass, damp, sf = ca.SX.sym("M"), ca.SX.sym("D"), ca.SX.sym("sigma_f")
    phi = ca.vertcat(mass, damp)
    sigma = ca.diag(ca.vertcat(settings["sigma_x"], settings["sigma_v"]))  # prior Σ (Eq. 8)
    q = ca.SX(np.diag(settings["q"]))
    rows = {
        "euler": 1 - ts * damp / mass,
        "implicit": mass / (mass + ts * damp),
        "exponential": ca.exp(-ts * damp / mass),
    }
    out: dict[str, np.ndarray] = {"sigma_f": sig_f}
    for name, a22 in rows.items():
        a = ca.vertcat(ca.horzcat(1, ts), ca.horzcat(0, a22))
        b = ca.vertcat(0, ts / mass)
        sig_plus = a @ sigma @ a.T + b @ sf @ b.T  # Eq. 8, one step
        qs = q @ sig_plus
        costs = {"trace": ca.trace(qs), "logdet": ca.log(ca.det(qs))}
        for obj, cost in costs.items():
            h = ca.Function("h", [phi, sf], [ca.hessian(cost, phi)[0]])
            eigs = np.array([np.linalg.eigvalsh(np.array(h([m0, d0], s))) for s in sig_f])
            out[f"{name}/{obj}"] = eigs[:, 0]
            out[f"{name}/{obj}/rel"] = eigs[:, 0] / np.abs(eigs).max(axis=1)
    return out


def _settings(cfg: DictConfig) -> dict[str, Any]:
    s = config_block(cfg, "convexity", _KEYS)
    for k in ("ts", "mass", "damping", "sigma_x", "sigma_v"):
        s[k] = check_positive(f"convexity.{k}", s.get(k))
    s["n_points"] = check_int_positive("convexity.n_points", s.get("n_points"))
    rng = s.get("sigma_f_range")
    if not isinstance(rng, list) or len(rng) != 2 or not 0 < rng[0] < rng[1]:
        raise ConfigError("convexity.sigma_f_range", f"must be [low, high], 0 < low < high: {rng}")
    q = s.get("q")
    if not isinstance(q, list) or len(q) != 2:
        raise ConfigError("convexity.q", f"must be the 2 diagonal weights of Q, got {q!r}")
    for i, v in enumerate(q):
        check_positive(f"convexity.q[{i}]", v)
    return s


def run_convexity(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Evaluate the curves, write ``figures/mpc_convexity.png`` and the summary: per curve,
    the minimum eigenvalue at the smallest, middle and largest Σ_f and the fraction of the
    Σ_f range where the objective is convex."""
    s = _settings(cfg)
    t0 = time.perf_counter()
    curves = hessian_min_eig(s)
    conditions = {}
    for key, eig in curves.items():
        if key == "sigma_f" or key.endswith("/rel"):
            continue
        conditions[key] = {
            "min_eig_low_sigma_f": float(eig[0]),
            "min_eig_mid_sigma_f": float(eig[len(eig) // 2]),
            "min_eig_high_sigma_f": float(eig[-1]),
            "convex_fraction": float(np.mean(eig >= 0.0)),
            # the smallest swept Σ_f from which the objective stays convex (None: never)
            "convex_above_sigma_f": _convex_above(curves["sigma_f"], eig),
        }
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
