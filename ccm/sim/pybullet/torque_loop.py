"""The Panda's own joint-torque loop: the task-space wrench command as joint torques.

Every physics step, with the command held (zero-order hold over ``control_decimation``
steps)::

    τ = Jᵀ [f; m + m_hold] + h(q, q̇) − Jᵀ Λ J̇ q̇ + N τ₀
    h = calculateInverseDynamics(q, q̇, 0)         (gravity + Coriolis: H of seed A Eq. 1)
    τ₀ = K_n (q_rest − q) − D_n q̇                 (posture toward the start configuration)
    N = I − Jᵀ Λ J M⁻¹,  Λ = (J M⁻¹ Jᵀ)⁻¹          (dynamically consistent null space)

The dynamically consistent projector is used so the posture term produces no task-space
acceleration, and ``− Jᵀ Λ J̇ q̇`` (``task_coriolis_compensation``; J̇ q̇ from the model or,
with ``dynamics: pybullet``, a directional finite difference of the Jacobian) removes the
velocity-product term, so that ``ẍ = Λ⁻¹ W``: with a zero wrench the tool stays put (issue #4
check 3) even while the posture term moves the elbow. The simple projector ``I − Jᵀ J⁺ᵀ``
would leak posture torques into the task space. ``m_hold = K_o e_R − D_o ω`` is an optional
orientation hold toward the start orientation (``orientation_stiffness`` /
``orientation_damping``): ccm's controllers close the translational loop only in 3D
(``FixedImpedance.rotation_torque`` returns zeros), so the robot keeps its tool orientation
itself. Set both gains to 0 to leave rotation to the commanded torque alone.

Model terms (``dynamics``). Default ``pinocchio``: J, J̇ q̇ (exact), h, M⁻¹ Jᵀ and Λ from one
Pinocchio call per physics step (:mod:`ccm.sim.pybullet.dynamics`: the same URDF and
PyBullet's own link inertias, checked against PyBullet's queries to 1e-8), and the law in a
compiled kernel (:func:`ccm.sim.pybullet._kernels.torque_law`). ``pybullet``:
``calculateJacobian`` (twice: J̇ q̇ is the forward difference above),
``calculateInverseDynamics``, ``calculateMassMatrix`` and two ``np.linalg.inv``, in numpy.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ccm.sim.panda import N_ARM
from ccm.sim.pybullet._kernels import task_space, torque_law, translational_inertia
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
        #: Pinocchio's model of the arm (``dynamics: pinocchio``), built once: same robot
        self.dynamics: PandaDynamics | None = None
        self._body: tuple[Any, int, int, int, tuple[float, ...]] | None = None
        self._hold = np.zeros(0)
        self._posture = np.zeros(0)
        self.q_rest = np.zeros(N_ARM)
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
        cfg, zeros = self.config, np.zeros(2 * N_ARM)
        # the torque law's gains and set points (:func:`torque_law`), the current state
        # filled in every physics step
        gains = [cfg.orientation_stiffness, cfg.orientation_damping]
        self._hold = np.concatenate([gains, self.start_orientation, zeros[:7]])
        self._posture = np.concatenate([[cfg.nullspace_stiffness, cfg.nullspace_damping], q, zeros])
        self.q_rest = self._posture[2 : 2 + N_ARM]  # a view: the posture target

    def torques(
        self, wrench: np.ndarray, q: np.ndarray, dq: np.ndarray, orn: Any, omega: np.ndarray
    ) -> np.ndarray:
        """τ for the task-space ``wrench`` [f; m] at joint state (q, q̇), tool orientation
        ``orn`` (x, y, z, w) and angular velocity ``omega``."""
        if self.dynamics is None:
            return self._torques_pybullet(wrench, q, dq, orn, omega)
        jac, jdq, h, minv_jt, _, lam = self._pinocchio_terms(q, dq)
        self._hold[6:10] = orn
        self._hold[10:] = omega
        self._posture[2 + N_ARM : 2 + 2 * N_ARM] = q
        self._posture[2 + 2 * N_ARM :] = dq
        return torque_law(
            jac, jdq, h, minv_jt, lam, wrench, self._hold, self._posture,
            self.config.task_coriolis_compensation,
        )  # fmt: skip

    def _pinocchio_terms(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(J, J̇ q̇, h, M⁻¹ Jᵀ, J M⁻¹ Jᵀ, Λ)`` at ``(q, q̇)``, computed once per joint state
        (the array object ``q`` that the backend reads after each physics step): the
        observation's inertia and the next physics step's torques share them."""
        if q is not self._terms_q:
            assert self.dynamics is not None
            minv, jac, jdq, h = self.dynamics.torque_terms(q, dq)
            self._terms = (jac, jdq, h, *task_space(minv, jac))
            self._terms_q = q
        return self._terms

    def translational_inertia(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The tool point's translational task-space inertia at joint angles ``q`` [kg], (3, 3):
        the f → ẍ map of this loop, for the controller's H (seed A Eq. 1's inertia; the
        robot model's, not the simulator's truth).

        With the orientation hold on, the hold supplies the moments that keep the tool's
        rotation, so at the translational loop's frequencies (~5 rad/s at K_free = 300 N/m)
        a force moves the tool as if its rotation were locked: the inertia is the
        translational block of the 6-D Λ = (J M⁻¹ Jᵀ)⁻¹ ([f; m] = Λ [ẍ; 0]). The hold takes
        ~0.1 s to catch up (measured with the tool point at [0.45, 0, 0.35] m: 5 N
        along x gives 4.2 m/s² over the first 20 ms, the unlocked (J_v M⁻¹ J_vᵀ)⁻¹ value, and
        1.4 m/s² averaged over 100 ms, on the way to the locked 0.57 m/s²). Without the hold
        the moment is zero and the inertia is (J_v M⁻¹ J_vᵀ)⁻¹.
        """
        cfg = self.config
        locked = cfg.orientation_stiffness > 0.0 or cfg.orientation_damping > 0.0
        if self.dynamics is not None:
            mob, lam = self._pinocchio_terms(q, dq)[4:]
            return translational_inertia(mob, lam, locked)
        jac, _, _, minv_jt, _ = self.model_terms(q, dq, True)
        mobility = jac @ minv_jt
        if locked:
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
