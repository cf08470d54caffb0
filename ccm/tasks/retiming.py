"""Re-timing a target pattern with the C∞ velocity profile of seed A Eq. 11 (§3.5.2, Fig. 3).

Entering the region C of an anticipated collision, the robot slows down along the target
pattern P: :class:`TimeWarp` maps wall time t to pattern time φ(t) = ∫₀ᵗ ρ with a rate
ρ = dφ/dt that changes between constant levels by Eq. 11 blends (:mod:`ccm.tasks.smooth_step`);
:class:`RetimedPattern` evaluates P(φ(t)), so the speed along the path is the plan's speed
times ρ.
"""

from __future__ import annotations

import bisect
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_finite, check_nonneg, check_positive
from ccm.core.types import TargetSample
from ccm.tasks.motion_pattern import MotionPattern, reusable_sample
from ccm.tasks.smooth_step import (
    integral_scalar,
    sigma_scalar,
    smooth_step_derivs,
    smooth_step_integral,
)


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
        s, s1, s2, _ = sigma_scalar(tau)
        phi = phi0 + T * (r0 * tau + dr * integral_scalar(tau))
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
            f = r0 * tau + dr * integral_scalar(tau) - target
            if f == 0.0:
                break
            lo, hi = (lo, tau) if f > 0.0 else (tau, hi)
            new = tau - f / (r0 + dr * sigma_scalar(tau)[0])
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
        self._buf, self._sample = reusable_sample(self.dim, self.orientation)
        self._scratch = np.zeros(self.dim)

    def sample(self, t: float) -> TargetSample:
        """The re-timed target at wall time ``t`` [s] (``TargetSample.t`` is ``t``); the same
        object every call, updated in place: valid until the next call (issue #40)."""
        buf, out = self._buf, self._sample
        if t >= self.duration:
            s = self.pattern.sample(self.pattern.duration)
            buf[0], buf[1], buf[2] = s.position, s.velocity, s.acceleration
            done = True
        else:
            phi, rho, drho, _ = self.warp.state(t)
            s = self.pattern.sample(phi)
            buf[0] = s.position
            if rho == 1.0 and drho == 0.0:  # outside any change: the plan itself
                buf[1], buf[2] = s.velocity, s.acceleration
            else:  # the same operations as s.velocity * rho, s.acceleration * ρ² + s.velocity ρ'
                np.multiply(s.velocity, rho, out=buf[1])
                np.multiply(s.acceleration, rho * rho, out=buf[2])
                np.multiply(s.velocity, drho, out=self._scratch)
                buf[2] += self._scratch
            done = False
        out.t, out.orientation, out.force_dir, out.force_mag, out.segment, out.done = (
            t,
            s.orientation,
            s.force_dir,
            s.force_mag,
            s.segment,
            done,
        )
        return out

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
