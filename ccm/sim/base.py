"""Simulator interface, shared by every physics backend (gymnasium-style reset/step)."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import check_int_positive, check_positive
from ccm.core.types import Command, Observation, StepInfo

#: keys of the ``sim`` group that are not a backend's settings: its name or import path
#: (:func:`ccm.sim.sim_class`), its description, and the nominal mass the controllers read
OTHER_SIM_KEYS = ("name", "_target_", "description", "nominal_mass_kg")


class Simulator(ABC):
    """A world with one end-effector driven by a task-space wrench.

    ``step`` advances one *control* period, i.e. ``control_decimation`` physics steps of
    ``dt`` seconds, holding the command constant (zero-order hold). The returned
    ``Observation`` is what the robot senses; the ``StepInfo`` is ground truth for metrics.

    Args:
        dt: physics time step [s] (default 1 kHz, issue #2; seed A states no step rate).
        control_decimation: physics steps per control step (>= 1).
    """

    #: task-space dimension (2 or 3)
    dim: int = 2

    def __init__(self, dt: float, control_decimation: int) -> None:
        self.dt = check_positive("sim.dt", dt)
        self.control_decimation = check_int_positive("sim.control_decimation", control_decimation)

    @property
    def control_dt(self) -> float:
        """Control period [s]."""
        return self.dt * self.control_decimation

    @classmethod
    @abstractmethod
    def from_config(
        cls, sim_cfg: Mapping[str, Any], scene_cfg: Mapping[str, Any], start: Sequence[float]
    ) -> Simulator:
        """Build from the ``sim`` group, ``task.scene`` and ``task.start`` configs; a
        ConfigError names the first invalid key."""

    @abstractmethod
    def reset(self, seed: int | None = None) -> tuple[Observation, StepInfo]:
        """Rebuild the scene, place the end-effector at its start pose, seed the sensor noise."""

    @abstractmethod
    def step(self, command: Command) -> tuple[Observation, StepInfo]:
        """Apply ``command`` for one control period and return the new observation and truth.

        ``command`` is read during this call only. The returned objects may be the ones of
        the previous step, updated in place: they are valid until the next ``step`` or
        ``reset`` (:mod:`ccm.core.types`)."""

    def close(self) -> None:  # noqa: B027 - optional hook, most backends hold nothing
        """Release backend resources."""

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc: object) -> None:
        """``with make_sim(...) as sim:`` closes the simulator on the way out."""
        self.close()


def all_finite(*arrays: np.ndarray) -> bool:
    """Whether every entry of the (small) arrays is finite: one float sum, ~10x cheaper than
    ``np.all(np.isfinite(...))`` on 3-7 entries. A sum of finite values beyond ~1e308 also
    reads as non-finite, which only a runaway state reaches."""
    return math.isfinite(sum(sum(a.tolist()) for a in arrays))


def check_state_finite(obs: Observation, max_speed: float) -> str | None:
    """Return a reason string if the state has diverged (NaN/inf or speed above ``max_speed``).

    Called every control step, so the common path is a few float operations on lists: one
    float sum for finiteness (as :func:`all_finite`) and the velocity list reused for the
    speed.
    """
    vel = obs.lin_vel.tolist()
    if not math.isfinite(sum(obs.position.tolist()) + sum(vel) + sum(obs.force.tolist())):
        for name in ("position", "lin_vel", "force"):
            if not np.all(np.isfinite(getattr(obs, name))):
                return f"non-finite {name} at t={obs.t:.3f} s"
    speed = math.hypot(*vel)
    if speed > max_speed:
        return (
            f"end-effector speed {speed:.3g} m/s exceeds sim.max_speed={max_speed} m/s "
            f"at t={obs.t:.3f} s"
        )
    return None
