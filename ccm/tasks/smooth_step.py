"""The C∞ smooth step of seed A Eq. 11 and the controller blend of Eq. 10 (§3.5).

    σ(τ) = e^{−1/τ} / (e^{−1/τ} + e^{−1/(1−τ)}),   τ = t / T,

with σ = 0 for τ ≤ 0 and σ = 1 for τ ≥ 1. Every derivative of σ tends to 0 at both ends, so
a velocity profile v(τ) = v1 + (v2 − v1) σ(τ) is C∞ (:func:`smooth_step`,
:func:`smooth_step_derivs`). :mod:`ccm.tasks.retiming` re-times a pattern with it.

Integration: re-timing needs S(τ) = ∫₀^τ σ, which has no closed form. It is tabulated once on
[0, 1/2] (1024 intervals, 10-point Gauss–Legendre per interval, cumulative sum) and
interpolated by cubic Hermite with the exact slopes σ; [1/2, 1] follows from the symmetry
σ(τ) + σ(1 − τ) = 1, i.e. S(τ) = S(1 − τ) − 1/2 + τ, which also makes S(1) = 1/2 exact. Hermite
error ≤ h⁴/384 · max|σ'''| = (1/2048)⁴/384 · 110.6 ≈ 1.6e-14 in τ units (node values: Gauss
error ~1e-30, summation rounding ~1e-16); against adaptive quadrature (QUADPACK) the largest
difference seen is 1e-14, the reference's own accuracy (tests/test_retiming.py).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_choice, check_finite, check_nonneg, check_positive

#: Beyond |1/τ − 1/(1−τ)| > 700, e^{−700} · 700⁶ < 1e-286: σ is taken as exactly 0 or 1 there
#: and its derivatives as exactly 0 (this also keeps 1/τ⁴ far from overflow).
_G_CUT = 700.0
_N_TABLE = 1024  # intervals of the S table on [0, 1/2]
_H_TABLE = 0.5 / _N_TABLE
BLEND_SHAPES = ("linear", "smooth")


def _sigma_core(tau: Any, u: Any, e: Any, sgn: Any) -> tuple[Any, Any, Any, Any]:
    """σ and its first three τ-derivatives from τ, u = 1 − τ, e = e^{−|g|}, sgn = sign(g).

    With g = 1/τ − 1/u, σ = 1 / (1 + e^{g}) is the logistic of −g, so σ' = q h1 with
    q = σ(1 − σ) = e / (1 + e)², m = 1 − 2σ = tanh(g/2), h1 = −g' = 1/τ² + 1/u²,
    h2 = h1' = 2/u³ − 2/τ³, h3 = h2' = 6/τ⁴ + 6/u⁴; differentiating (q' = q h1 m, m' = −2 q h1,
    m² = 1 − 4q) gives σ'' = q (h1² m + h2) and σ''' = q (h1³ (1 − 6q) + 3 h1 h2 m + h3).
    Plain arithmetic, so it serves floats and numpy arrays alike.
    """
    it, iu, den = 1.0 / tau, 1.0 / u, 1.0 + e
    lo = e / den  # min(σ, 1 − σ)
    q = lo / den
    m = sgn * (1.0 - e) / den
    it2, iu2 = it * it, iu * iu
    h1 = it2 + iu2
    h2 = 2.0 * (iu2 * iu - it2 * it)
    h3 = 6.0 * (iu2 * iu2 + it2 * it2)
    s = 0.5 - sgn * (0.5 - lo)  # lo when g > 0 (τ < 1/2), 1 − lo when g < 0
    d2 = q * (h1 * h1 * m + h2)
    d3 = q * (h1 * h1 * h1 * (1.0 - 6.0 * q) + 3.0 * h1 * h2 * m + h3)
    return s, q * h1, d2, d3


def sigma_scalar(tau: float) -> tuple[float, float, float, float]:
    """Scalar :func:`smooth_step_derivs` (the per-control-step path, math module only)."""
    u = 1.0 - tau
    if tau <= 0.0 or u <= 0.0:
        return (0.0 if tau <= 0.5 else 1.0), 0.0, 0.0, 0.0
    g = (1.0 - 2.0 * tau) / (tau * u)
    if abs(g) > _G_CUT:
        return (0.0 if g > 0.0 else 1.0), 0.0, 0.0, 0.0
    return _sigma_core(tau, u, math.exp(-abs(g)), 1.0 if g >= 0.0 else -1.0)


def _as_tau(tau: Any, name: str) -> np.ndarray:
    x = np.asarray(tau, dtype=float)
    if np.any(np.isnan(x)):
        raise ValueError(f"{name}: tau must not be NaN")
    return x


def _out(x: np.ndarray) -> Any:
    return float(x) if x.ndim == 0 else x


def smooth_step_derivs(tau: Any) -> tuple[Any, Any, Any, Any]:
    """σ(τ) of Eq. 11 (seed A) and its first, second and third derivatives w.r.t. τ.

    Evaluated in the overflow-free form σ = 1 / (1 + e^{g}), g = 1/τ − 1/(1 − τ), with
    analytic derivatives (see ``_sigma_core``). σ(1/2) = 1/2 exactly.

    Args:
        tau: normalised time τ = t / T, float or array (any real; NaN is rejected).

    Returns:
        ``(σ, σ', σ'', σ''')``, floats for a scalar ``tau``, else arrays of its shape.
    """
    x = _as_tau(tau, "smooth_step_derivs")
    u = 1.0 - x
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        g = (1.0 - 2.0 * x) / (x * u)
        inside = (x > 0.0) & (u > 0.0) & (np.abs(g) <= _G_CUT)
        xi, ui, gi = x[inside], u[inside], g[inside]
    out = [np.where(x > 0.5, 1.0, 0.0), np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)]
    core = _sigma_core(xi, ui, np.exp(-np.abs(gi)), np.where(gi >= 0.0, 1.0, -1.0))
    for arr, val in zip(out, core, strict=True):
        arr[inside] = val
    return _out(out[0]), _out(out[1]), _out(out[2]), _out(out[3])


def smooth_step(tau: Any) -> Any:
    """The normalised Eq. 11 blend σ(τ) (seed A): 0 for τ ≤ 0, 1 for τ ≥ 1, C∞ in between.

    Eq. 11 is then v(τ) = v1 + (v2 − v1) σ(τ). Vectorised; see :func:`smooth_step_derivs`.
    """
    return smooth_step_derivs(tau)[0]


def _hermite(s: Any, v0: Any, v1: Any, d0: Any, d1: Any) -> Any:
    """Cubic Hermite on [0, 1] with values v0, v1 and slopes (already × h) d0, d1."""
    s2 = s * s
    s3 = s2 * s
    return (
        (2 * s3 - 3 * s2 + 1) * v0
        + (s3 - 2 * s2 + s) * d0
        + (3 * s2 - 2 * s3) * v1
        + (s3 - s2) * d1
    )


def _build_table() -> tuple[np.ndarray, np.ndarray]:
    nodes, weights = np.polynomial.legendre.leggauss(10)
    left = np.arange(_N_TABLE) * _H_TABLE
    pts = left[:, None] + 0.5 * _H_TABLE * (nodes[None, :] + 1.0)
    pieces = 0.5 * _H_TABLE * (smooth_step_derivs(pts)[0] @ weights)
    values = np.concatenate([[0.0], np.cumsum(pieces)])
    slopes = smooth_step_derivs(np.arange(_N_TABLE + 1) * _H_TABLE)[0] * _H_TABLE
    return values, slopes


_S_VAL, _S_SLOPE = _build_table()
_S_VAL_L, _S_SLOPE_L = _S_VAL.tolist(), _S_SLOPE.tolist()


def _integral_half(x: float) -> float:
    """S(x) for x in [0, 1/2] from the table (scalar)."""
    pos = x / _H_TABLE
    k = min(int(pos), _N_TABLE - 1)
    return _hermite(pos - k, _S_VAL_L[k], _S_VAL_L[k + 1], _S_SLOPE_L[k], _S_SLOPE_L[k + 1])


def integral_scalar(tau: float) -> float:
    """Scalar :func:`smooth_step_integral`."""
    if tau <= 0.0:
        return 0.0
    if tau >= 1.0:
        return tau - 0.5
    if tau <= 0.5:
        return _integral_half(tau)
    return _integral_half(1.0 - tau) - 0.5 + tau


def smooth_step_integral(tau: Any) -> Any:
    """S(τ) = ∫₀^τ σ (Eq. 11, seed A): 0 for τ ≤ 0, τ − 1/2 for τ ≥ 1 (S(1) = 1/2 exactly).

    Table + cubic Hermite interpolation (module docstring); error ≤ 1.6e-14. Vectorised.
    """
    x = _as_tau(tau, "smooth_step_integral")
    mirror = x > 0.5
    y = np.clip(np.where(mirror, 1.0 - x, x), 0.0, 0.5)
    pos = y / _H_TABLE
    k = np.minimum(pos.astype(int), _N_TABLE - 1)
    s = _hermite(pos - k, _S_VAL[k], _S_VAL[k + 1], _S_SLOPE[k], _S_SLOPE[k + 1])
    s = np.where(mirror, s - 0.5 + x, s)
    return _out(np.where(x >= 1.0, x - 0.5, s))


def profile_samples(
    v1: float, v2: float, n: int, *, duration: float = 1.0, margin: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The Eq. 11 velocity profile with matched position, acceleration and jerk (Fig. 3).

    Args:
        v1, v2: velocity before and after the change (Fig. 3: 1.2 → 0.5).
        n: number of samples (>= 2).
        duration: T = t2 − t1 [s] (Fig. 3: unit time).
        margin: τ range is [−margin, 1 + margin], to show the constant parts on either side.

    Returns:
        ``(τ, position, velocity, acceleration, jerk)``, each of shape (n,); position is
        ∫ v dt from τ = 0 (negative before it), acceleration = dv/dt, jerk = d²v/dt².
    """
    v1, v2 = check_finite("v1", v1), check_finite("v2", v2)
    T = check_positive("duration", duration)
    margin = check_nonneg("margin", margin)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 2:
        raise ConfigError("n", f"must be an integer >= 2, got {n!r}")
    tau = np.linspace(-margin, 1.0 + margin, int(n))
    s, s1, s2, _ = smooth_step_derivs(tau)
    dv = v2 - v1
    pos = T * (v1 * tau + dv * smooth_step_integral(tau))
    return tau, pos, v1 + dv * s, dv * s1 / T, dv * s2 / (T * T)


def blend_weight(t: Any, t_start: float, duration: float, shape: str = "linear") -> Any:
    """Weight α of the transition-phase controller in Eq. 10 (seed A §3.5.1).

    ``"linear"`` is the paper's α = (t − t_start)/T clipped to [0, 1]. Its derivative jumps
    from 0 to 1/T at t_start and back at t_start + T, so the blended command u has a kink
    there even when u1 and u2 are smooth. ``"smooth"`` uses α = σ((t − t_start)/T) of Eq. 11
    instead, which joins the constant parts with every derivative continuous (C∞). Both reach
    α = 1 exactly at t_start + T: start the blend T before the trajectory reaches p_c.

    Args:
        t: time [s], float or array.
        t_start: blend start [s].
        duration: T [s], > 0.
        shape: ``"linear"`` (Eq. 10, default) or ``"smooth"``.

    Raises:
        ConfigError: naming ``duration`` or ``shape``.
    """
    T = check_positive("duration", duration)
    check_choice("shape", shape, BLEND_SHAPES)
    t_end = t_start + T  # α = 1 from here on, even where (t − t_start)/T rounds below 1
    if isinstance(t, float | int):
        tau = 1.0 if t >= t_end else (t - t_start) / T
        return min(max(tau, 0.0), 1.0) if shape == "linear" else sigma_scalar(tau)[0]
    x = np.asarray(t, dtype=float)
    tau = np.where(x >= t_end, 1.0, (x - t_start) / T)
    return np.clip(tau, 0.0, 1.0) if shape == "linear" else smooth_step(tau)


def blend(u1: Any, u2: Any, alpha: Any) -> Any:
    """Eq. 10 (seed A): u = (1 − α) u1 + α u2 — exactly u1 at α = 0 and u2 at α = 1."""
    return (1.0 - alpha) * u1 + alpha * u2
