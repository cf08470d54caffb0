"""Settings of the planar pymunk backend (the ``sim`` config group, ``configs/sim/pymunk2d.yaml``
explains each default)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ccm.core.errors import ConfigError, check_bool, check_int_positive, check_positive
from ccm.core.fields import checked, field_values, nested
from ccm.sim.base import OTHER_SIM_KEYS
from ccm.sim.sensor import SensorConfig


@dataclass(frozen=True)
class Pymunk2DConfig:
    """Backend settings (``configs/sim/pymunk2d.yaml`` explains each default).

    Attributes:
        dt: physics step [s] (1 kHz, issue #2).
        control_decimation: physics steps per control step.
        iterations: pymunk solver iterations.
        collision_slop: allowed overlap [m].
        gravity_compensation: add ``+m g`` along +y to the applied force (Eq. 1, H term).
        max_speed: runaway guard used by the runner [m/s].
        sensor: F/T sensor noise and bias.
    """

    dt: float = checked(check_positive, 0.001)
    control_decimation: int = checked(check_int_positive, 1)
    iterations: int = checked(check_int_positive, 30)
    collision_slop: float = checked(check_positive, 1.0e-4)
    gravity_compensation: bool = checked(check_bool, True)
    max_speed: float = checked(check_positive, 20.0)
    sensor: SensorConfig = checked(
        nested(lambda cfg, key: SensorConfig.from_mapping(cfg, 2, 1, key)),
        factory=SensorConfig.ideal,
    )

    @classmethod
    def from_mapping(cls, cfg: Any, prefix: str = "sim") -> Pymunk2DConfig:
        """Parse the ``sim`` config group; errors name keys as ``sim.<field>``."""
        values, d = field_values(cls, cfg, prefix, extra=OTHER_SIM_KEYS)
        if "name" in d and d["name"] != "pymunk2d":
            raise ConfigError(f"{prefix}.name", f"must be 'pymunk2d', got {d['name']!r}")
        return cls(**values)
