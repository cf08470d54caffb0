"""Hybrid force-motion impedance control with fixed gains (Eq. 1, seed A, with u_ff = 0)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ccm.control.base import Controller
from ccm.control.loop import HybridLoop, mean_gain
from ccm.core.errors import ConfigError, check_positive
from ccm.core.types import Command, Observation, TargetSample


class FixedImpedance(Controller):
    """Task-space hybrid force-motion impedance law of Eq. 1 (seed A) with constant gains.

    u = P_m [K_p Δx + K_d Δẋ + Λ ẍ_d] + u_fc with constant K_p, K_d from the loop's damping
    rule (for the arm's Λ(q) when the loop uses it: then K_d follows Λ every step), and
    u_ff = 0 (AVIC adds it). The shared terms (force loop u_fc, m ẍ_d, orientation
    hold, damping rule) are the :class:`ccm.control.loop.HybridLoop` it holds.

    Args:
        stiffness: K_p [N/m], scalar or per axis; > 0.
        loop: the ``controller.loop`` block (:class:`HybridLoop` arguments).
    """

    def __init__(
        self,
        stiffness: float | list[float] = 300.0,
        loop: Mapping[str, Any] | None = None,
        key: str = "controller",
    ) -> None:
        k = np.atleast_1d(np.asarray(stiffness, dtype=object))
        self.stiffness = np.array(
            [check_positive(f"{key}.stiffness", v) for v in k.ravel()], dtype=float
        )
        self.loop = HybridLoop.from_config(loop, f"{key}.loop")
        self._key = key
        self.dim = 0
        self.control_dt = 0.0
        self._gains: dict[str, float] = {}

    def reset(self, dim: int, control_dt: float) -> None:
        super().reset(dim, control_dt)
        if self.stiffness.size not in (1, dim):
            raise ConfigError(
                f"{self._key}.stiffness", f"needs 1 or {dim} values, got {self.stiffness.size}"
            )
        self._kp = np.broadcast_to(self.stiffness, (dim,)).astype(float)
        self._kd = np.broadcast_to(self.loop.damping_for(self._kp), (dim,)).astype(float)
        self.loop.reset(dim, control_dt)
        self._gains = {
            "stiffness_Npm": float(np.mean(self._kp)),
            "damping_Nspm": float(np.mean(self._kd)),
        }

    def step(self, obs: Observation, target: TargetSample) -> Command:
        """Eq. 1 (seed A) with constant K_p, K_d and u_ff = 0."""
        kd = self._kd
        inertia = self.loop.inertia_of(obs)
        if isinstance(inertia, np.ndarray):  # K_d for this step's Λ(q)
            kd = self.loop.damping_for(self._kp, inertia)
            self._gains["damping_Nspm"] = mean_gain(kd)
        u, u_force = self.loop.motion_force(obs, target, self._kp, kd)
        if u_force is not self.loop.zero:
            u += u_force
        return Command(force=u, torque=self.loop.rotation_torque(obs, target))

    def signals(self) -> dict[str, float]:
        return {**self._gains, **self.loop.signals()}
