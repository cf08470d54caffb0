"""Plugin controllers for ``tests/test_plugins.py``: one that works, and one per broken
promise. None takes ccm's ``key`` argument: a plugin needs no ccm-specific parameter."""

from __future__ import annotations

import numpy as np

from ccm.control.base import Controller
from ccm.core.types import Command, Observation, TargetSample


class PlainPD(Controller):
    """A task-space PD toward the target: F = K (x_d − x) + D (ẋ_d − ẋ).

    Args:
        stiffness: K [N/m]; damping: D [N s/m].
    """

    def __init__(self, stiffness: float = 300.0, damping: float = 40.0) -> None:
        self.stiffness = float(stiffness)
        self.damping = float(damping)

    def step(self, obs: Observation, target: TargetSample) -> Command:
        force = self.stiffness * (target.position - obs.position)
        force += self.damping * (target.velocity - obs.lin_vel)
        return Command(force=force, torque=np.zeros_like(obs.ang_vel))

    def signals(self) -> dict[str, float]:
        return {"stiffness_Npm": self.stiffness}


class RaisesMidRun(PlainPD):
    """Works for ``fail_after_s`` seconds of a trial, then raises."""

    def __init__(self, fail_after_s: float = 0.05) -> None:
        super().__init__()
        self.fail_after_s = fail_after_s

    def step(self, obs: Observation, target: TargetSample) -> Command:
        if obs.t > self.fail_after_s:
            raise RuntimeError("the plugin's own bug")
        return super().step(obs, target)


class NoSignals(Controller):  # noqa: D101 - abstract on purpose: signals() is missing
    def step(self, obs: Observation, target: TargetSample) -> Command:
        return Command(force=np.zeros_like(obs.position), torque=np.zeros_like(obs.ang_vel))


class NotAController:
    """Has a step, but is not a ccm controller."""

    def step(self, obs: Observation, target: TargetSample) -> Command:
        return Command(force=np.zeros_like(obs.position), torque=np.zeros_like(obs.ang_vel))


def make_pd() -> PlainPD:
    """A factory function: not a class."""
    return PlainPD()
