"""The PyBullet Panda's own joint-torque loop: the task-space wrench command as joint torques.

The law is :class:`ccm.sim.arm.TorqueLaw` (the module docstring of :mod:`ccm.sim.arm`)::

    τ = Jᵀ [f; m + m_hold] + h(q, q̇) − Jᵀ Λ J̇ q̇ + N τ₀

with h = ``calculateInverseDynamics(q, q̇, 0)`` (gravity + Coriolis: H of seed A Eq. 1).

Model terms (``dynamics``). Default ``pinocchio``: J, J̇ q̇ (exact), h, M⁻¹ Jᵀ and Λ from one
Pinocchio call per physics step (:mod:`ccm.sim.pybullet.dynamics`: the same URDF and
PyBullet's own link inertias, checked against PyBullet's queries to 1e-8), and the law in a
compiled kernel (:func:`ccm.sim._kernels.torque_law`). ``pybullet``:
``calculateJacobian`` (twice: J̇ q̇ is a directional finite difference of the Jacobian),
``calculateInverseDynamics``, ``calculateMassMatrix`` and two ``np.linalg.inv``, in numpy.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ccm.sim.arm import TorqueLaw, model_terms
from ccm.sim.pybullet.dynamics import PandaDynamics, robot_dynamics
from ccm.sim.pybullet.robot import (
    inverse_dynamics,
    nullspace_projection,
    orientation_error,
    task_inertia,
    tool_jacobian,
)
from ccm.sim.pybullet.scene import PyBullet3DConfig


class TorqueLoop:
    """τ of the module docstring for one robot in one PyBullet client.

    Args:
        config: the backend settings (gains, ``dynamics``, ``task_coriolis_compensation``).
        start_orientation: the orientation hold's target (x, y, z, w).
    """

    def __init__(self, config: PyBullet3DConfig, start_orientation: np.ndarray) -> None:
        self.config = config
        self.start_orientation = start_orientation
        #: the law itself, shared with the other 3-D backend
        self.law = TorqueLaw(config, start_orientation)
        #: Pinocchio's model of the arm (``dynamics: pinocchio``), built once: same robot
        self.dynamics: PandaDynamics | None = None
        self._body: tuple[Any, int, int, int, tuple[float, ...]] | None = None
        # the model terms of the last joint state (the array object ``q``): the observation's
        # Λ and the next physics step's torques are computed at the same state
        self._terms_q: np.ndarray | None = None
        self._terms: tuple[np.ndarray, ...] = ()

    def attach(self, p: Any, cid: int, robot: int, tool_link: int, tip_link: Any) -> None:
        """Use the robot just loaded into client ``cid`` (Pinocchio's model on first use)."""
        self._body = (p, cid, robot, tool_link, tip_link)
        if self.config.dynamics == "pinocchio" and self.dynamics is None:
            self.dynamics = robot_dynamics(p, cid, robot, self.config.tool, tip_link)

    def set_rest(self, q: np.ndarray) -> None:
        """The posture target q_rest (the start configuration) and the law's gains."""
        self.law.set_rest(q)

    @property
    def q_rest(self) -> np.ndarray:
        """The posture target [rad] (a view: a test may displace it)."""
        return self.law.q_rest

    def torques(
        self, wrench: np.ndarray, q: np.ndarray, dq: np.ndarray, orn: Any, omega: np.ndarray
    ) -> np.ndarray:
        """τ for the task-space ``wrench`` [f; m] at joint state (q, q̇), tool orientation
        ``orn`` (x, y, z, w) and angular velocity ``omega``."""
        if self.dynamics is None:
            return self._torques_pybullet(wrench, q, dq, orn, omega)
        return self.law.torques(self._pinocchio_terms(q, dq), wrench, q, dq, orn, omega)

    def _pinocchio_terms(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(J, J̇ q̇, h, M⁻¹ Jᵀ, J M⁻¹ Jᵀ, Λ)`` at ``(q, q̇)``, computed once per joint state
        (the array object ``q`` that the backend reads after each physics step): the
        observation's inertia and the next physics step's torques share them."""
        if q is not self._terms_q:
            assert self.dynamics is not None
            minv, jac, jdq, h = self.dynamics.torque_terms(q, dq)
            self._terms = model_terms(minv, jac, jdq, h)
            self._terms_q = q
        return self._terms

    def translational_inertia(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The tool point's translational task-space inertia at joint angles ``q`` [kg], (3, 3)
        (:meth:`ccm.sim.arm.TorqueLaw.translational_inertia`)."""
        if self.dynamics is not None:
            return self.law.translational_inertia(self._pinocchio_terms(q, dq))
        jac, _, _, minv_jt, _ = self.model_terms(q, dq, True)
        mobility = jac @ minv_jt
        if self.law.locked:
            return np.linalg.inv(mobility)[:3, :3]
        return np.linalg.inv(mobility[:3, :3])

    def _torques_pybullet(
        self, wrench: np.ndarray, q: np.ndarray, dq: np.ndarray, orn: Any, omega: np.ndarray
    ) -> np.ndarray:
        """The torque law in numpy on PyBullet's queries (``dynamics: pybullet``)."""
        cfg = self.config
        use_null = cfg.nullspace_stiffness > 0.0 or cfg.nullspace_damping > 0.0
        jac, h, jdq, minv_jt, lam = self.model_terms(
            q, dq, use_null or cfg.task_coriolis_compensation
        )
        w = wrench
        if cfg.orientation_stiffness > 0.0 or cfg.orientation_damping > 0.0:
            hold = cfg.orientation_stiffness * orientation_error(self.start_orientation, orn)
            hold -= cfg.orientation_damping * omega
            w = wrench.copy()
            w[3:] += hold
        tau = jac.T @ w + h
        if cfg.task_coriolis_compensation:
            tau -= jac.T @ (lam @ jdq)
        if use_null:
            tau0 = cfg.nullspace_stiffness * (self.q_rest - q) - cfg.nullspace_damping * dq
            tau += nullspace_projection(jac, lam, minv_jt, tau0)  # N τ₀
        return tau

    def model_terms(self, q: np.ndarray, dq: np.ndarray, task: bool) -> tuple[Any, ...]:
        """``(J, h, J̇ q̇, M⁻¹ Jᵀ, Λ)`` of the torque law (``dynamics``): Pinocchio's in one
        call, or PyBullet's queries (the last three only if ``task``, else ``None``)."""
        if self.dynamics is not None:
            t = self.dynamics.compute(q, dq)
            return t.jacobian, t.h, t.jdot_qdot, t.minv_jt, t.lam
        assert self._body is not None, "TorqueLoop.attach() first"
        p, cid, robot, tool_link, tip_link = self._body
        jac = tool_jacobian(p, cid, robot, tool_link, tip_link, q, dq)
        h = inverse_dynamics(p, cid, robot, q, dq)
        if not task:
            return jac, h, None, None, None
        minv_jt, lam = task_inertia(p, cid, robot, q, jac)  # M⁻¹ Jᵀ, Λ = (J M⁻¹ Jᵀ)⁻¹
        jdq = None
        if self.config.task_coriolis_compensation:
            # J̇ q̇ as the directional derivative of J along q̇ (forward difference)
            eps = 1e-6
            jac_ahead = tool_jacobian(p, cid, robot, tool_link, tip_link, q + eps * dq, dq)
            jdq = (jac_ahead - jac) @ dq / eps
        return jac, h, jdq, minv_jt, lam
