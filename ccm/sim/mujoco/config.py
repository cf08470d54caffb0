"""Configuration of the MuJoCo 3D backend (:mod:`ccm.sim.mujoco.backend`): the ``sim`` config
group, parsed into a frozen dataclass whose errors name the offending key. Nothing here
imports MuJoCo.
"""

from __future__ import annotations

from dataclasses import dataclass

from ccm.core.errors import check_positive
from ccm.core.fields import checked
from ccm.sim.arm_config import ArmConfig

__all__ = ["MuJoCo3DConfig"]


@dataclass(frozen=True)
class MuJoCo3DConfig(ArmConfig):
    """Backend settings (``configs/sim/mujoco3d.yaml`` explains each default): those of every
    3-D backend (:class:`ccm.sim.arm_config.ArmConfig`) and:

    Attributes:
        contact_damping: tool contact damping per contact point [N s/m]; MuJoCo's damping is
            explicit, so its default is lower than PyBullet's (:mod:`ccm.sim.mujoco.world`).
        contact_mass_kg: the contact mass m_c [kg] that maps ``contact_stiffness`` and
            ``contact_damping`` (per point, force units) to MuJoCo's acceleration-level
            ``solref`` (:func:`ccm.sim.mujoco.world.contact_params`).
        impratio: MuJoCo's ratio of the friction rows' impedance to the normal's; the
            friction rows' damping is ``contact_damping / impratio``, which keeps the
            sliding contact on the table (:func:`ccm.sim.mujoco.world.add_pairs`).
    """

    NAME = "mujoco3d"

    contact_damping: float = checked(check_positive, 100.0)
    contact_mass_kg: float = checked(check_positive, 2.38)
    impratio: float = checked(check_positive, 100.0)
