"""Approach speed toward one collision contact (seed A Eq. 9, §3.4.1).

:class:`ApproachVelocityModel` starts at a safe low speed, then revises the speed after each
impact by Eq. 9 or by a fitted linear impact-force/velocity model, below the maximum allowed
impact force. Used per collision contact by :class:`ccm.learn.contact.contacts.ContactMap`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_bool,
    check_finite,
    check_positive,
    constructor_kwargs,
)

__all__ = ["ApproachVelocityModel"]


class ApproachVelocityModel:
    """Approach speed toward one collision contact (Eq. 9, §3.4.1, seed A).

    Trial 1 uses ``v_safe``. :meth:`update` records each impact (v_used, F_m), and
    :meth:`next_velocity` gives the speed for the next approach by these rules:

    1. Eq. 9: v = v_used + β (F_d - F_m). With a plant F = k v this converges to F_d / k for
       0 < β k < 2, monotonically for β <= 1 / k (the paper's "β at most the slope", read as
       dv/dF). ``beta=None`` estimates β = 1 / k̂ from the impacts so far, k̂ the
       through-origin least-squares slope of F over v (measured data only; one impact gives
       v_used · F_d / F_m).
    2. With ``use_model`` and a least-squares line F = a v + b over all impacts (fitted once
       their speeds span >= ``min_velocity_spread``) with a > 0, the target is instead the
       line's speed for F_d, (F_d - b) / a: the paper's linear model "used to compute the
       approach velocity for any (given) desired force".
    3. The change from v_used is limited to ±``max_step``, then clipped to [v_min, v_max].
    4. Force limit: v is lowered to the largest speed whose predicted force is <= F_max. The
       prediction is the line if usable, else F = a0 v through the origin (least squares;
       seed A found F proportional to v). The limit wins over v_min; only if the line gives
       F >= F_max at every v > 0 (b >= F_max) is v_min returned, with
       :attr:`force_limit_feasible` False.

    Args:
        v_safe: Speed of the first approach, m/s (seed A §4.5.1: 0.05).
        beta: β of Eq. 9, (m/s)/N (chosen 0.002: monotone for k up to 500 N s/m), or None to
            estimate it from the measured impacts (rule 1).
        f_desired: Desired impact force F_d, N (seed A §4.5.1: 8).
        f_max: Maximum allowed impact force, N, >= f_desired (chosen 10).
        v_min: Lower speed bound, m/s (chosen 0.01).
        v_max: Upper speed bound, m/s (chosen 0.25).
        max_step: Largest speed change per trial, m/s (chosen 0.05).
        min_velocity_spread: Speed span needed to fit the line, m/s (chosen 0.005).
        use_model: Apply rule 2; False is plain Eq. 9.
        key: Configuration key used as the prefix of error messages.
    """

    def __init__(
        self,
        v_safe: float = 0.05,
        beta: float | None = 0.002,
        f_desired: float = 8.0,
        f_max: float = 10.0,
        v_min: float = 0.01,
        v_max: float = 0.25,
        max_step: float = 0.05,
        min_velocity_spread: float = 0.005,
        use_model: bool = True,
        key: str = "controller.contacts.approach",
    ) -> None:
        self.key = key
        self.beta = None if beta is None else check_positive(f"{key}.beta", beta)
        self.f_max = check_positive(f"{key}.f_max", f_max)
        self.f_desired = check_positive(f"{key}.f_desired", f_desired)
        if self.f_desired > self.f_max:
            raise ConfigError(f"{key}.f_desired", f"must be <= f_max {f_max}, got {f_desired}")
        self.v_min = check_positive(f"{key}.v_min", v_min)
        self.v_max = check_positive(f"{key}.v_max", v_max)
        if self.v_max < self.v_min:
            raise ConfigError(f"{key}.v_max", f"must be >= v_min {v_min}, got {v_max}")
        self.v_safe = check_positive(f"{key}.v_safe", v_safe)
        if not self.v_min <= self.v_safe <= self.v_max:
            raise ConfigError(f"{key}.v_safe", f"must be in [{v_min}, {v_max}], got {v_safe}")
        self.max_step = check_positive(f"{key}.max_step", max_step)
        self.min_velocity_spread = check_positive(f"{key}.min_velocity_spread", min_velocity_spread)
        self.use_model = check_bool(f"{key}.use_model", use_model)
        self.velocities: list[float] = []
        self.forces: list[float] = []

    def get_params(self) -> dict[str, Any]:
        """Constructor arguments except ``key`` (JSON-safe)."""
        names = ("v_safe", "beta", "f_desired", "f_max", "v_min", "v_max", "max_step")
        return {n: getattr(self, n) for n in (*names, "min_velocity_spread", "use_model")}

    def update(self, v_used: float, f_measured: float) -> float:
        """Record an impact at ``v_used`` (m/s, > 0) with force ``f_measured`` (N, along the
        direction of motion); return :meth:`next_velocity`."""
        self.velocities.append(check_positive(f"{self.key}.v_used", v_used))
        self.forces.append(check_finite(f"{self.key}.f_measured", f_measured))
        return self.next_velocity()

    @property
    def coef_(self) -> tuple[float, float] | None:
        """(a, b) of the least-squares line F = a v + b; None while the speeds span too little."""
        v, f = np.asarray(self.velocities), np.asarray(self.forces)
        if v.size < 2 or np.ptp(v) < self.min_velocity_spread:
            return None
        dv = v - v.mean()
        a = float(dv @ (f - f.mean()) / (dv @ dv))
        return a, float(f.mean() - a * v.mean())

    def _force_model(self) -> tuple[float, float] | None:
        line = self.coef_
        if line is not None and line[0] > 0.0:
            return line
        v, f = np.asarray(self.velocities), np.asarray(self.forces)
        return (float(v @ f / (v @ v)), 0.0) if v.size else None

    def _beta(self) -> float:
        """β of Eq. 9: the configured value, or 1 / the through-origin slope (rule 1)."""
        if self.beta is not None:
            return self.beta
        v, f = np.asarray(self.velocities), np.asarray(self.forces)
        slope = float(v @ f / (v @ v))
        return 1.0 / slope if slope > 0.0 else 0.0

    def predict_force(self, v: float) -> float | None:
        """Impact force at speed ``v`` by rule 4's model, N; None before the first impact."""
        model = self._force_model()
        return None if model is None else model[0] * float(v) + model[1]

    def velocity_limit(self) -> float:
        """Largest speed whose predicted force is <= F_max, m/s (inf if force does not grow)."""
        model = self._force_model()
        return math.inf if model is None or model[0] <= 0.0 else (self.f_max - model[1]) / model[0]

    @property
    def force_limit_feasible(self) -> bool:
        """False when the model predicts F >= F_max at every speed > 0."""
        return self.velocity_limit() > 0.0

    def next_velocity(self) -> float:
        """Speed for the next approach, m/s (rules 1-4 of the class docstring)."""
        if not self.velocities:
            return self.v_safe
        v_used, f_m = self.velocities[-1], self.forces[-1]
        target = v_used + self._beta() * (self.f_desired - f_m)  # Eq. 9
        line = self.coef_
        if self.use_model and line is not None and line[0] > 0.0:
            target = (self.f_desired - line[1]) / line[0]
        step = min(max(target - v_used, -self.max_step), self.max_step)
        v = min(max(v_used + step, self.v_min), self.v_max)
        cap = self.velocity_limit()
        return self.v_min if cap <= 0.0 else min(v, cap)

    def state_dict(self) -> dict[str, Any]:
        """JSON-safe state: settings and the (v, F) pairs."""
        pairs = {"velocities": self.velocities[:], "forces": self.forces[:]}
        return {"params": self.get_params()} | pairs

    @classmethod
    def from_state_dict(cls, data: Mapping[str, Any], key: str) -> ApproachVelocityModel:
        """Rebuild from :meth:`state_dict` output (replaying the impacts); ConfigError if
        malformed."""
        try:
            out = cls(**constructor_kwargs(cls, data["params"], key), key=key)
            for v, f in zip(data["velocities"], data["forces"], strict=True):
                out.update(v, f)
        except ConfigError:
            raise
        except (KeyError, TypeError, ValueError) as e:
            raise ConfigError(key, f"malformed approach model: {e!r}") from None
        return out
