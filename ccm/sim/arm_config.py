"""The ``sim`` settings every 3-D backend reads (:class:`ArmConfig`): the Panda's torque loop
gains, its tool, the tool's contact and the table's patches, the F/T sensor. A backend's config
adds its own fields. Nothing here imports a physics engine or a compiled kernel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ccm.core.errors import (
    ConfigError,
    check_bool,
    check_int_positive,
    check_nonneg,
    check_positive,
)
from ccm.core.fields import checked, field_values, nested, one_of, vector
from ccm.sim.base import OTHER_SIM_KEYS
from ccm.sim.panda import PANDA_READY, ToolSpec
from ccm.sim.sensor import SensorConfig

PATCH_MODES = ("friction_map", "footprint", "boxes")


@dataclass(frozen=True)
class ArmConfig:
    """The settings every 3-D backend reads (``configs/sim/pybullet3d.yaml`` and
    ``mujoco3d.yaml`` explain each default); a backend's config adds its own.

    Attributes:
        dt: physics step [s] (1 kHz, issue #4).
        control_decimation: physics steps per control step.
        gui: open the engine's viewer instead of running headless.
        max_speed: runaway guard used by the runner [m/s].
        tool: the block tool.
        rest_posture: joint configuration seeding the start IK [rad], shape (7,).
        nullspace_stiffness: K_n [N m/rad] of the posture term.
        nullspace_damping: D_n [N m s/rad] of the posture term.
        orientation_stiffness: K_o [N m/rad] of the built-in orientation hold.
        orientation_damping: D_o [N m s/rad] of the built-in orientation hold.
        task_coriolis_compensation: add ``−Jᵀ Λ J̇ q̇`` so a zero wrench gives zero tool
            acceleration even while the arm moves (e.g. in the null space).
        contact_stiffness: tool contact stiffness per contact point [N/m].
        contact_damping: tool contact damping per contact point [N s/m].
        patch_mode: ``friction_map`` (one continuous table top whose friction is set each
            physics step from the patch under the tool point), ``footprint`` (the same top,
            its friction the pressure-weighted mean over the tool's face:
            :mod:`ccm.sim.footprint`) or ``boxes`` (thin patch boxes flush with the top; the
            tool's edge catches on their side faces).
        footprint_grid: n of the n × n grid ``footprint`` integrates the face on.
        sensor: F/T sensor noise and bias (force (3,), torque (3,)).
    """

    #: the backend's ``sim.name``
    NAME = ""

    dt: float = checked(check_positive, 0.001)
    control_decimation: int = checked(check_int_positive, 1)
    gui: bool = checked(check_bool, False)
    max_speed: float = checked(check_positive, 5.0)
    tool: ToolSpec = checked(
        nested(lambda cfg, key: ToolSpec.from_mapping(cfg, key)), factory=ToolSpec
    )
    rest_posture: tuple[float, ...] = checked(vector(7), PANDA_READY)
    nullspace_stiffness: float = checked(check_nonneg, 10.0)
    nullspace_damping: float = checked(check_nonneg, 2.0)
    orientation_stiffness: float = checked(check_nonneg, 30.0)
    orientation_damping: float = checked(check_nonneg, 2.0)
    task_coriolis_compensation: bool = checked(check_bool, True)
    contact_stiffness: float = checked(check_positive, 1.0e5)
    contact_damping: float = checked(check_positive, 1.0e3)
    patch_mode: str = checked(one_of(PATCH_MODES), "friction_map")
    footprint_grid: int = checked(check_int_positive, 32)
    sensor: SensorConfig = checked(
        nested(lambda cfg, key: SensorConfig.from_mapping(cfg, 3, 3, key)),
        factory=lambda: SensorConfig.ideal(3, 3),
    )

    @classmethod
    def from_mapping(cls, cfg: Any, prefix: str = "sim") -> Any:
        """Parse the ``sim`` config group; errors name keys as ``sim.<field>``."""
        values, d = field_values(cls, cfg, prefix, extra=OTHER_SIM_KEYS)
        if "name" in d and d["name"] != cls.NAME:
            raise ConfigError(f"{prefix}.name", f"must be {cls.NAME!r}, got {d['name']!r}")
        return cls(**values)
