"""Smooth controller blending (Eq. 10) and the C∞ velocity profile with re-timing (Eq. 11).

Seed A §3.5. Entering the region C of an anticipated contact change, the robot blends from
the base controller's output u1 to the transition-phase controller's output u2 (Eq. 10,
:func:`blend_weight`, :func:`blend`) and, for collisions, slows down along the target pattern
P with the velocity profile of Eq. 11 (§3.5.2, Fig. 3):

    v(τ) = v1 + (v2 − v1) σ(τ),   σ(τ) = e^{−1/τ} / (e^{−1/τ} + e^{−1/(1−τ)}),   τ = t / T,

with σ = 0 for τ ≤ 0 and σ = 1 for τ ≥ 1. Every derivative of σ tends to 0 at both ends, so
the profile is C∞ (:func:`smooth_step`, :func:`smooth_step_derivs`).

Re-timing: :class:`TimeWarp` maps wall time t to pattern time φ(t) = ∫₀ᵗ ρ with a rate
ρ = dφ/dt that changes between constant levels by Eq. 11 blends; :class:`RetimedPattern`
evaluates P(φ(t)), so the speed along the path is the plan's speed times ρ.

Integration: φ needs S(τ) = ∫₀^τ σ, which has no closed form. It is tabulated once on
[0, 1/2] (1024 intervals, 10-point Gauss–Legendre per interval, cumulative sum) and
interpolated by cubic Hermite with the exact slopes σ; [1/2, 1] follows from the symmetry
σ(τ) + σ(1 − τ) = 1, i.e. S(τ) = S(1 − τ) − 1/2 + τ, which also makes S(1) = 1/2 exact. Hermite
error ≤ h⁴/384 · max|σ'''| = (1/2048)⁴/384 · 110.6 ≈ 1.6e-14 in τ units (node values: Gauss
error ~1e-30, summation rounding ~1e-16); against adaptive quadrature (QUADPACK) the largest
difference seen is 1e-14, the reference's own accuracy (tests/test_retiming.py).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_choice, check_finite, check_nonneg, check_positive
from ccm.core.types import TargetSample
from ccm.tasks.trajectory import MotionPattern

__all__ = [
    "RetimedPattern",
    "TimeWarp",
    "blend",
    "blend_weight",
    "profile_samples",
    "smooth_step",
    "smooth_step_derivs",
    "smooth_step_integral",
]

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


def _sigma4(tau: float) -> tuple[float, float, float, float]:
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


def _integral1(tau: float) -> float:
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
        return min(max(tau, 0.0), 1.0) if shape == "linear" else _sigma4(tau)[0]
    x = np.asarray(t, dtype=float)
    tau = np.where(x >= t_end, 1.0, (x - t_start) / T)
    return np.clip(tau, 0.0, 1.0) if shape == "linear" else smooth_step(tau)


def blend(u1: Any, u2: Any, alpha: Any) -> Any:
    """Eq. 10 (seed A): u = (1 − α) u1 + α u2 — exactly u1 at α = 0 and u2 at α = 1."""
    return (1.0 - alpha) * u1 + alpha * u2


def _parse_change(key: str, change: Any) -> tuple[float, float, float]:
    names = ("t_start", "t_end", "rate_after")
    if isinstance(change, Mapping):
        unknown = [str(k) for k in change if k not in names]
        if unknown or any(n not in change for n in names):
            raise ConfigError(key, f"must have exactly the keys {', '.join(names)}")
        vals = [change[n] for n in names]
    elif isinstance(change, Sequence) and not isinstance(change, str) and len(change) == 3:
        vals = list(change)
    else:
        raise ConfigError(key, f"must be (t_start, t_end, rate_after), got {change!r}")
    t0 = check_nonneg(f"{key}.t_start", vals[0])
    t1 = check_finite(f"{key}.t_end", vals[1])
    if t1 <= t0:
        raise ConfigError(f"{key}.t_end", f"must be > t_start = {t0}, got {vals[1]!r}")
    return t0, t1, check_positive(f"{key}.rate_after", vals[2])


class TimeWarp:
    """Wall time t → pattern time φ(t) = ∫₀ᵗ ρ, with Eq. 11 rate changes (seed A §3.5.2).

    ρ = dφ/dt is ``rate0`` until the first change; a change ``(t_start, t_end, rate_after)``
    moves ρ from its current level to ``rate_after`` by ρ = r0 + (r1 − r0) σ(τ),
    τ = (t − t_start)/(t_end − t_start), so ρ is C∞. A pattern P re-timed by the warp moves at
    |P'(φ)| ρ: ρ scales the plan's speed along the same path.

    φ is exact (up to rounding) where ρ is constant and uses S = ∫σ (:func:`smooth_step_integral`,
    error ≤ 1.6e-14 · (t_end − t_start) · |r1 − r0| [s]) inside blends. φ' = ρ, φ'' = ρ' =
    (r1 − r0) σ'/T, φ''' = ρ'' = (r1 − r0) σ''/T² are analytic.

    Args:
        changes: ``(t_start, t_end, rate_after)`` triples (or mappings with those keys), in
            wall time [s], with 0 <= t_start < t_end <= next t_start, rate_after > 0.
        rate0: initial rate (> 0), default 1 (follow the plan).
        key: configuration key used in error messages.

    Raises:
        ConfigError: naming e.g. ``time_warp.changes[1].t_start``.
    """

    def __init__(
        self,
        changes: Sequence[Any] = (),
        rate0: float = 1.0,
        *,
        key: str = "time_warp",
    ) -> None:
        self.key = key
        self.rate0 = check_positive(f"{key}.rate0", rate0)
        if isinstance(changes, str) or not isinstance(changes, Sequence):
            raise ConfigError(f"{key}.changes", f"must be a list, got {changes!r}")
        parsed = [_parse_change(f"{key}.changes[{i}]", c) for i, c in enumerate(changes)]
        for i in range(1, len(parsed)):
            if parsed[i][0] < parsed[i - 1][1]:
                raise ConfigError(
                    f"{key}.changes[{i}].t_start",
                    f"must be >= the previous change's t_end {parsed[i - 1][1]}, "
                    f"got {parsed[i][0]}",
                )
        self.changes: tuple[tuple[float, float, float], ...] = tuple(parsed)
        # Pieces (t0, T, φ0, r0, Δr): φ = φ0 + T (r0 τ + Δr S(τ)), τ = (t − t0)/T. A constant
        # piece has T = 1 and Δr = 0, which reduces to φ0 + r0 (t − t0).
        pieces = [(0.0, 1.0, 0.0, self.rate0, 0.0)]
        rate, phi, const_t0 = self.rate0, 0.0, 0.0
        for t0, t1, r1 in parsed:
            phi = phi + rate * (t0 - const_t0)  # the constant piece's formula at its end
            T = t1 - t0
            pieces.append((t0, T, phi, rate, r1 - rate))
            phi = phi + T * (rate + (r1 - rate) * 0.5)  # the blend's formula at τ = 1
            pieces.append((t1, 1.0, phi, r1, 0.0))
            rate, const_t0 = r1, t1
        self.final_rate = rate
        self._pieces = pieces
        self._starts = [p[0] for p in pieces]
        self._table = np.array(pieces)

    @classmethod
    def for_speed(
        cls,
        v_plan: float,
        v_new: float,
        phi_start: float,
        phi_reach: float,
        hold: float | None = None,
        return_duration: float | None = None,
        *,
        key: str = "time_warp",
    ) -> TimeWarp:
        """ρ: 1 → v_new / v_plan → 1, timed so the slow-down is complete at p_c (§3.5).

        Speed along the path is the plan's speed × ρ, so the robot moves at exactly ``v_new``
        where the plan's speed is ``v_plan`` (pass the plan's speed at p_c).

        Args:
            v_plan: the plan's speed at the switch point p_c [m/s], > 0.
            v_new: the target speed there (e.g. the learned approach velocity, Eq. 9), > 0.
            phi_start: pattern (= plan) time [s] at which the blend starts, >= 0; ρ = 1
                before, so this is also its wall time.
            phi_reach: pattern time [s] of p_c; the blend ends exactly when φ reaches it,
                i.e. at wall time phi_start + 2 (phi_reach − phi_start) / (1 + v_new/v_plan).
            hold: how long [s, wall time] to keep the new speed before blending back to 1;
                ``None`` keeps it (append the return later with :meth:`extended`).
            return_duration: duration [s] of the blend back; default: that of the first.
            key: configuration key used in error messages.
        """
        rate = check_positive(f"{key}.v_new", v_new) / check_positive(f"{key}.v_plan", v_plan)
        p0 = check_nonneg(f"{key}.phi_start", phi_start)
        p1 = check_finite(f"{key}.phi_reach", phi_reach)
        if p1 <= p0:
            raise ConfigError(f"{key}.phi_reach", f"must be > phi_start = {p0}, got {p1}")
        t1 = p0 + 2.0 * (p1 - p0) / (1.0 + rate)
        changes = [(p0, t1, rate)]
        if hold is not None:
            t2 = t1 + check_nonneg(f"{key}.hold", hold)
            ret = t1 - p0 if return_duration is None else return_duration
            changes.append((t2, t2 + check_positive(f"{key}.return_duration", ret), 1.0))
        return cls(changes, key=key)

    def extended(self, t_start: float, t_end: float, rate_after: float) -> TimeWarp:
        """A copy with one more change appended (it must start after the last one ends)."""
        return TimeWarp([*self.changes, (t_start, t_end, rate_after)], self.rate0, key=self.key)

    def state(self, t: float) -> tuple[float, float, float, float]:
        """``(φ, ρ, ρ', ρ'')`` at wall time ``t`` [s] (scalar; the per-control-step path)."""
        i = bisect.bisect_right(self._starts, t) - 1
        t0, T, phi0, r0, dr = self._pieces[i if i > 0 else 0]
        if dr == 0.0:
            return phi0 + r0 * (t - t0), r0, 0.0, 0.0
        tau = (t - t0) / T
        s, s1, s2, _ = _sigma4(tau)
        phi = phi0 + T * (r0 * tau + dr * _integral1(tau))
        return phi, r0 + dr * s, dr * s1 / T, dr * s2 / (T * T)

    def evaluate(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Vectorised: ``(φ, ρ, ρ', ρ'', ρ''')`` at wall times ``t`` (array of any shape)."""
        x = np.asarray(t, dtype=float)
        idx = np.maximum(np.searchsorted(self._table[:, 0], x, side="right") - 1, 0)
        t0, T, phi0, r0, dr = (self._table[idx, j] for j in range(5))
        tau = (x - t0) / T
        s, s1, s2, s3 = (np.asarray(a) for a in smooth_step_derivs(tau))
        phi = phi0 + T * (r0 * tau + dr * smooth_step_integral(tau))
        return phi, r0 + dr * s, dr * s1 / T, dr * s2 / T**2, dr * s3 / T**3

    def phi(self, t: Any) -> Any:
        """Pattern time φ(t) [s]; float for a float ``t``, else an array."""
        return self.state(t)[0] if isinstance(t, float | int) else self.evaluate(t)[0]

    def rate(self, t: Any) -> Any:
        """ρ(t) = φ'(t); float for a float ``t``, else an array."""
        return self.state(t)[1] if isinstance(t, float | int) else self.evaluate(t)[1]

    def inverse(self, phi: float) -> float:
        """Wall time t with φ(t) = ``phi`` (φ is strictly increasing; safeguarded Newton)."""
        phis = [p[2] for p in self._pieces]
        i = max(bisect.bisect_right(phis, phi) - 1, 0)
        t0, T, phi0, r0, dr = self._pieces[i]
        if dr == 0.0:
            return t0 + (phi - phi0) / r0
        target = (phi - phi0) / T  # solve r0 τ + dr S(τ) = target for τ in [0, 1]
        lo, hi, tau = 0.0, 1.0, min(target / (r0 + 0.5 * dr), 1.0)
        for _ in range(100):
            f = r0 * tau + dr * _integral1(tau) - target
            if f == 0.0:
                break
            lo, hi = (lo, tau) if f > 0.0 else (tau, hi)
            new = tau - f / (r0 + dr * _sigma4(tau)[0])
            new = new if lo < new < hi else 0.5 * (lo + hi)
            done = abs(new - tau) <= 4e-16
            tau = new
            if done:
                break
        return t0 + T * tau


class RetimedPattern:
    """A target pattern P followed on a warped clock: sample(t) = P(φ(t)) (seed A §3.5.2).

    Position P(φ), velocity P'(φ) ρ, acceleration P''(φ) ρ² + P'(φ) ρ' (chain rule); force
    target, segment and orientation are the pattern's at φ. ``duration`` is in wall time
    (φ(duration) = pattern.duration); from then on the pattern's final sample is held exactly.

    Args:
        pattern: the plan P (pattern time = the plan's own time).
        warp: the wall-time → pattern-time map.
    """

    def __init__(self, pattern: MotionPattern, warp: TimeWarp) -> None:
        self.pattern = pattern
        self.warp = warp
        self.duration: float = warp.inverse(pattern.duration)
        self.dim = pattern.dim
        self.start, self.end, self.orientation = pattern.start, pattern.end, pattern.orientation

    def sample(self, t: float) -> TargetSample:
        """The re-timed target at wall time ``t`` [s] (``TargetSample.t`` is ``t``)."""
        if t >= self.duration:
            s = self.pattern.sample(self.pattern.duration)
            return TargetSample(
                t, s.position, s.velocity, s.acceleration, s.orientation,
                s.force_dir, s.force_mag, s.segment, True,
            )  # fmt: skip
        phi, rho, drho, _ = self.warp.state(t)
        s = self.pattern.sample(phi)
        if rho == 1.0 and drho == 0.0:  # outside any change: the plan itself, no copies
            vel, acc = s.velocity, s.acceleration
        else:
            vel = s.velocity * rho
            acc = s.acceleration * (rho * rho) + s.velocity * drho
        return TargetSample(
            t, s.position, vel, acc, s.orientation, s.force_dir, s.force_mag, s.segment, False
        )

    def sample_many(self, ts: Sequence[float] | np.ndarray) -> dict[str, np.ndarray]:
        """Vectorised :meth:`sample`: :meth:`MotionPattern.sample_many`'s keys at wall times,
        plus ``phi`` (pattern time) and ``rate`` (ρ)."""
        t = np.asarray(ts, dtype=float).reshape(-1)
        phi, rho, drho, _, _ = self.warp.evaluate(t)
        done = t >= self.duration
        phi = np.where(done, self.pattern.duration, phi)
        out = self.pattern.sample_many(phi)
        vel, acc = out["velocity"], out["acceleration"]
        acc = acc * (rho * rho)[:, None] + vel * drho[:, None]
        out.update(t=t, velocity=vel * rho[:, None], acceleration=acc, phi=phi, rate=rho)
        out["done"] = done
        return out

    def __repr__(self) -> str:
        return f"RetimedPattern({self.pattern!r}, duration={self.duration:.6g} s)"
