"""The Panda's rigid-body dynamics in one call per step, by Pinocchio (issue #20).

:class:`PandaDynamics` gives the terms of the PyBullet backend's torque law (the module
docstring of :mod:`ccm.sim.pybullet.backend`)::

    τ = Jᵀ [f; m + m_hold] + h(q, q̇) − Jᵀ Λ J̇ q̇ + N τ₀,   N = I − Jᵀ Λ J M⁻¹

(``τ = Jᵀ u + H`` is seed A Eq. 1), from one Pinocchio ``computeAllTerms`` pass instead of
the four PyBullet queries (``calculateJacobian`` twice, ``calculateInverseDynamics``,
``calculateMassMatrix``) and two ``np.linalg.inv`` of the PyBullet path. PyBullet stays the
physics engine; this is the robot controller's model of the arm.

Modelling choices:

* **Same URDF, PyBullet's inertias.** The kinematic tree is read from the URDF that
  :func:`ccm.sim.pybullet.robot.robot_urdf` writes (the Panda without fingers, ccm's block
  tool fixed to ``panda_hand``). PyBullet's ``loadURDF`` does *not* use the URDF's inertia
  tensors unless asked (``URDF_USE_INERTIA_FROM_FILE``): it keeps the URDF masses and
  centres of mass and computes each link's principal moments from its collision shape (the
  Panda URDF's are all 0.1 kg m² placeholders; PyBullet's, e.g. 0.0230/0.0178/0.0115 kg m²
  for link 1). With the URDF's tensors M differs from ``calculateMassMatrix`` by ~1 kg m².
  So the links' inertials are passed in (:class:`LinkInertial`, read from PyBullet's
  ``getDynamicsInfo`` by :func:`link_inertials`) and replace the
  URDF's: each joint's body inertia is rebuilt as the sum of its links' (Pinocchio merges
  the links behind fixed joints, here link 8, the hand and the tool, into joint 7's body).
* **Tool point.** An extra frame on the tool link at ``tip_link`` (the tool point in the
  tool's URDF link frame). J is its geometric Jacobian ``[J_v; J_ω]`` in the world frame
  (``LOCAL_WORLD_ALIGNED``: linear velocity of the tool point, angular velocity, both in
  world axes), the convention of :func:`ccm.sim.pybullet.robot.tool_jacobian`.
* **J̇ q̇** is the tool point's *classical* acceleration at q̈ = 0 (``d/dt`` of its world
  linear velocity ``J_v q̇``, and ``ω̇``), not the spatial acceleration, which lacks the
  ``ω × v`` term. ``computeAllTerms`` leaves the zero-q̈ joint accelerations in ``data.a``.
* **h** = ``nle``, the RNEA torques at q̈ = 0 (gravity + Coriolis/centrifugal), what
  ``calculateInverseDynamics(q, q̇, 0)`` returns. No joint damping, friction or armature in
  either model (the URDF has none; ``load_robot`` zeroes PyBullet's damping). Gravity is
  ``(0, 0, −g)`` as in PyBullet's ``setGravity``.
* **Λ and M⁻¹ Jᵀ by Cholesky.** Pinocchio's sparse ``M = U D Uᵀ`` factorisation gives M⁻¹
  (no ``inv``); Λ = (J M⁻¹ Jᵀ)⁻¹ from LAPACK's Cholesky ``dpotrf``/``dpotrs`` of the
  6 × 6 operational-space mobility J M⁻¹ Jᵀ. If that is not positive definite in floating
  point (an exact singularity), Λ is its pseudo-inverse, as in
  :func:`ccm.sim.pybullet.robot.task_inertia`.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from ccm.sim.panda import GRAVITY, N_ARM, LinkInertial, ToolSpec, link_inertials, robot_urdf

_TOOL_POINT = "ccm_tool_point"  # the name of the added frame
_ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, N_ARM + 1))


@dataclass(frozen=True, slots=True)
class Terms:
    """The model terms of the torque law at one ``(q, q̇)`` (arrays owned by the caller).

    Attributes:
        mass: joint-space inertia matrix M(q) [kg m²], (7, 7), symmetric.
        jacobian: tool-point Jacobian J = [J_v; J_ω] in the world frame, (6, 7).
        jdot_qdot: J̇ q̇, the tool point's classical acceleration at q̈ = 0
            [m/s², rad/s²], (6,).
        h: gravity + Coriolis torques h(q, q̇) (H of seed A Eq. 1) [N m], (7,).
        minv_jt: M⁻¹ Jᵀ, (7, 6).
        lam: task-space inertia Λ = (J M⁻¹ Jᵀ)⁻¹, (6, 6).
    """

    mass: np.ndarray
    jacobian: np.ndarray
    jdot_qdot: np.ndarray
    h: np.ndarray
    minv_jt: np.ndarray
    lam: np.ndarray


class PandaDynamics:
    """Pinocchio model of the Panda with ccm's block tool; :meth:`compute` once per step.

    Args:
        urdf_path: the URDF PyBullet loads (:func:`ccm.sim.pybullet.robot.robot_urdf`).
        tool_link: the link carrying the tool point.
        tip_link: the tool point in ``tool_link``'s URDF frame [m], (3,)
            (:func:`ccm.sim.pybullet.robot.tool_point_in_link`).
        inertials: the links' inertials by link name, replacing the URDF's (module
            docstring: PyBullet does not use the URDF's tensors); ``None`` keeps the URDF's.
            Every link that moves must be present.
        gravity: g [m/s²], along −z.

    Raises:
        ValueError: if the URDF's movable joints are not ``panda_joint1..7`` in order, it
            has no ``tool_link``, or a moving link has no entry in ``inertials``.
    """

    def __init__(
        self,
        urdf_path: str,
        tool_link: str,
        tip_link: Sequence[float],
        inertials: Mapping[str, LinkInertial] | None = None,
        gravity: float = GRAVITY,
    ) -> None:
        model = pin.buildModelFromUrdf(urdf_path)
        if tuple(model.names)[1:] != _ARM_JOINTS or model.nv != N_ARM:
            raise ValueError(f"expected joints {_ARM_JOINTS}, the URDF has {list(model.names)}")
        if inertials is not None:
            _replace_inertias(model, inertials)
        model.gravity = pin.Motion(np.array([0.0, 0.0, -gravity]), np.zeros(3))
        if not model.existFrame(tool_link, pin.FrameType.BODY):
            raise ValueError(f"the URDF has no link {tool_link!r}")
        link = model.frames[model.getFrameId(tool_link, pin.FrameType.BODY)]
        placement = link.placement * pin.SE3(np.eye(3), np.asarray(tip_link, float))
        self._frame = model.addFrame(
            pin.Frame(_TOOL_POINT, link.parentJoint, placement, pin.FrameType.OP_FRAME)
        )
        self.model = model
        self._data = model.createData()
        self._lower = np.tril_indices(N_ARM, -1)
        self._eye6 = np.eye(6)

    @property
    def joint_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """The URDF's joint position limits ``(lower, upper)`` [rad], (7,) each."""
        return self.model.lowerPositionLimit.copy(), self.model.upperPositionLimit.copy()

    def compute(self, q: np.ndarray, dq: np.ndarray) -> Terms:
        """All terms of the torque law at joint angles ``q`` [rad] and velocities ``dq``
        [rad/s], (7,) each, in one ``computeAllTerms`` pass (module docstring)."""
        model, data, frame = self.model, self._data, self._frame
        pin.computeAllTerms(model, data, q, dq)  # M (upper triangle), nle, joint J, data.a
        jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        acc = pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        mass = data.M.copy()
        mass[self._lower] = mass.T[self._lower]
        pin.cholesky.decompose(model, data)  # M = U D Uᵀ (sparse, the tree's structure)
        minv_jt = pin.cholesky.computeMinv(model, data) @ jac.T
        return Terms(
            mass=mass,
            jacobian=jac,
            jdot_qdot=np.array(acc.vector),
            h=data.nle.copy(),
            minv_jt=minv_jt,
            lam=self._task_inertia(jac @ minv_jt),
        )

    def torque_terms(
        self, q: np.ndarray, dq: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(M⁻¹, J, J̇ q̇, h)`` at ``(q, q̇)``: what the compiled torque law
        (:func:`ccm.sim._kernels.torque_law`) needs, with no copies or Python-side
        algebra (the per-step path; :meth:`compute` gives every term)."""
        model, data, frame = self.model, self._data, self._frame
        pin.computeAllTerms(model, data, q, dq)
        jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        acc = pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        pin.cholesky.decompose(model, data)
        return pin.cholesky.computeMinv(model, data), jac, acc.vector, data.nle

    def _task_inertia(self, mobility: np.ndarray) -> np.ndarray:
        """Λ = (J M⁻¹ Jᵀ)⁻¹ by Cholesky; the pseudo-inverse if that is not positive definite."""
        chol, info = lapack.dpotrf(mobility)
        if info != 0:
            return np.linalg.pinv(mobility)
        lam, info = lapack.dpotrs(chol, self._eye6)
        return lam if info == 0 else np.linalg.pinv(mobility)


def _pin_inertia(link: LinkInertial) -> pin.Inertia:
    """A link's spatial inertia about its frame's origin (Pinocchio's ``Inertia``)."""
    x, y, z, w = link.orientation
    rot = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
    inertia = rot @ np.diag(link.principal) @ rot.T  # about the centre of mass, link axes
    return pin.Inertia(float(link.mass), np.asarray(link.com, float), inertia)


def _replace_inertias(model: pin.Model, inertials: Mapping[str, LinkInertial]) -> None:
    """Rebuild every moving joint's body inertia from its links' ``inertials``."""
    for j in range(1, model.njoints):
        model.inertias[j] = pin.Inertia.Zero()
    for frame in model.frames:
        if frame.type != pin.FrameType.BODY or frame.parentJoint == 0:
            continue  # the fixed base does not move
        if frame.name not in inertials:
            raise ValueError(f"no inertial given for the moving link {frame.name!r}")
        body = frame.placement.act(_pin_inertia(inertials[frame.name]))
        model.inertias[frame.parentJoint] = model.inertias[frame.parentJoint] + body


def robot_dynamics(
    p: Any, cid: int, robot: int, tool: ToolSpec, tip_link: Sequence[float]
) -> PandaDynamics:
    """Pinocchio's model of the loaded ``robot`` (the URDF :func:`robot_urdf` writes for
    ``tool``, PyBullet's link inertials) with the tool point ``tip_link`` (link frame)."""
    tmp = tempfile.mkdtemp(prefix="ccm_panda_")
    try:
        urdf = robot_urdf(tool, tmp)
        return PandaDynamics(urdf, "ccm_tool", tip_link, link_inertials(p, cid, robot), GRAVITY)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
