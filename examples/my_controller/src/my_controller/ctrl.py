"""A force-limited impedance controller: the kind of controller a lab brings to ccm.

F = sat(K (x_d − x) + D (ẋ_d − ẋ)), D = 2 ζ √(K m), with the force's magnitude saturated at
``max_force_N`` (a common safety limit on a real arm). It subclasses ccm's ``Controller``
and takes only its own parameters.
"""

from __future__ import annotations

import math

import numpy as np

from ccm.control.base import Controller
from ccm.core.types import Command, Observation, TargetSample


class ForceLimitedImpedance(Controller):
    """Impedance with a force limit.

    Args:
        stiffness: K [N/m]. damping_ratio: ζ. mass_kg: the end-effector mass m [kg] the
            damping is designed for. max_force_N: the largest force it commands [N].
    """

    def __init__(
        self,
        stiffness: float = 400.0,
        damping_ratio: float = 1.0,
        mass_kg: float = 1.0,
        max_force_N: float = 20.0,
    ) -> None:
        for name, value in (("stiffness", stiffness), ("damping_ratio", damping_ratio),
                            ("mass_kg", mass_kg), ("max_force_N", max_force_N)):  # fmt: skip
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        self.stiffness = float(stiffness)
        self.damping = 2.0 * damping_ratio * math.sqrt(stiffness * mass_kg)
        self.max_force_N = float(max_force_N)
        self._saturated = 0.0

    def step(self, obs: Observation, target: TargetSample) -> Command:
        force = self.stiffness * (target.position - obs.position)
        force += self.damping * (target.velocity - obs.lin_vel)
        size = float(np.linalg.norm(force))
        self._saturated = 1.0 if size > self.max_force_N else 0.0
        if self._saturated:
            force *= self.max_force_N / size
        return Command(force=force, torque=np.zeros_like(obs.ang_vel))

    def signals(self) -> dict[str, float]:
        return {"stiffness_Npm": self.stiffness, "damping_Nspm": self.damping,
                "saturated": self._saturated}  # fmt: skip
