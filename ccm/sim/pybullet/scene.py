"""Configuration of the PyBullet 3D backend (:mod:`ccm.sim.pybullet.backend`): the ``sim``
config group (backend settings, the block tool), parsed and validated into a frozen dataclass
whose errors name the offending key. The scene it builds (``task.scene``) is
:mod:`ccm.sim.scene3d`, shared with the other 3-D engine. Nothing here imports PyBullet.
"""

from __future__ import annotations

from dataclasses import dataclass

from ccm.core.errors import check_int_positive
from ccm.core.fields import checked, one_of
from ccm.sim.arm_config import PATCH_MODES, ArmConfig

__all__ = ["DYNAMICS", "PATCH_MODES", "PyBullet3DConfig"]

#: where the torque loop's model terms come from (``PyBullet3DConfig.dynamics``)
DYNAMICS = ("pinocchio", "pybullet")


# --------------------------------------------------------------------------- config


@dataclass(frozen=True)
class PyBullet3DConfig(ArmConfig):
    """Backend settings (``configs/sim/pybullet3d.yaml`` explains each default): those of
    every 3-D backend (:class:`ccm.sim.arm.ArmConfig`; ``contact_stiffness`` and
    ``contact_damping`` are Bullet's compliant contact model, per contact point) and:

    Attributes:
        solver_iterations: Bullet constraint solver iterations.
        dynamics: where the torque loop's J, J̇ q̇, h, M⁻¹ Jᵀ and Λ come from: ``pinocchio``
            (one call per physics step, :mod:`ccm.sim.pybullet.dynamics`) or ``pybullet``
            (its ``calculateJacobian`` twice, ``calculateInverseDynamics``,
            ``calculateMassMatrix`` and two inverses). The same model either way.
    """

    NAME = "pybullet3d"

    solver_iterations: int = checked(check_int_positive, 50)
    dynamics: str = checked(one_of(DYNAMICS), "pinocchio")
