"""What both 3-D backends share about the torque-controlled Panda: the joint-torque law that
turns the commanded task-space wrench into joint torques (:class:`TorqueLaw`) and the start
pose's inverse kinematics (:func:`dls_ik`). Its ``sim`` settings are
:class:`ccm.sim.arm_config.ArmConfig`.

The law, every physics step, with the command held (zero-order hold over
``control_decimation`` steps)::

    τ = Jᵀ [f; m + m_hold] + h(q, q̇) − Jᵀ Λ J̇ q̇ + N τ₀
    h: gravity + Coriolis torques (H of seed A Eq. 1)
    τ₀ = K_n (q_rest − q) − D_n q̇                 (posture toward the start configuration)
    N = I − Jᵀ Λ J M⁻¹,  Λ = (J M⁻¹ Jᵀ)⁻¹          (dynamically consistent null space)

The dynamically consistent projector is used so the posture term produces no task-space
acceleration, and ``− Jᵀ Λ J̇ q̇`` (``task_coriolis_compensation``) removes the
velocity-product term, so that ``ẍ = Λ⁻¹ W``: with a zero wrench the tool stays put (issue #4
check 3) even while the posture term moves the elbow. The simple projector ``I − Jᵀ J⁺ᵀ``
would leak posture torques into the task space. ``m_hold = K_o e_R − D_o ω`` is an optional
orientation hold toward the start orientation (``orientation_stiffness`` /
``orientation_damping``): ccm's controllers close the translational loop only in 3D
(``FixedImpedance.rotation_torque`` returns zeros), so the robot keeps its tool orientation
itself. Set both gains to 0 to leave rotation to the commanded torque alone.

Each engine supplies the model terms J, J̇ q̇, h and M⁻¹ at the joint state it just read
(PyBullet's backend from Pinocchio or its own queries, MuJoCo's from its own calls); the law
itself is the compiled kernel :func:`ccm.sim._kernels.torque_law`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, SimulationDiverged
from ccm.core.types import Command, Observation, StepInfo
from ccm.sim._kernels import orientation_error, task_space, torque_law, translational_inertia
from ccm.sim.arm_config import ArmConfig
from ccm.sim.base import all_finite
from ccm.sim.panda import N_ARM
from ccm.sim.sensor import FTSensor


class TorqueLaw:
    """τ of the module docstring from the model terms an engine supplies.

    Args:
        config: the gains (``nullspace_*``, ``orientation_*``, ``task_coriolis_compensation``).
        start_orientation: the orientation hold's target (x, y, z, w).
    """

    def __init__(self, config: ArmConfig, start_orientation: np.ndarray) -> None:
        self.config = config
        self.start_orientation = start_orientation
        self._hold = np.zeros(0)
        self._posture = np.zeros(0)
        self.q_rest = np.zeros(N_ARM)

    @property
    def locked(self) -> bool:
        """Whether the orientation hold is on (it locks the tool's rotation)."""
        return self.config.orientation_stiffness > 0.0 or self.config.orientation_damping > 0.0

    def set_rest(self, q: np.ndarray) -> None:
        """The posture target q_rest (the start configuration) and the law's gains."""
        cfg, zeros = self.config, np.zeros(2 * N_ARM)
        # the kernel's gains and set points (:func:`torque_law`), the state filled in per step
        gains = [cfg.orientation_stiffness, cfg.orientation_damping]
        self._hold = np.concatenate([gains, self.start_orientation, zeros[:7]])
        self._posture = np.concatenate([[cfg.nullspace_stiffness, cfg.nullspace_damping], q, zeros])
        self.q_rest = self._posture[2 : 2 + N_ARM]  # a view: the posture target

    def torques(
        self, terms: tuple[np.ndarray, ...], wrench: np.ndarray, q: np.ndarray,
        dq: np.ndarray, orn: Any, omega: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """τ for the task-space ``wrench`` [f; m] at joint state (q, q̇), tool orientation
        ``orn`` (x, y, z, w) and angular velocity ``omega``; ``terms`` are
        ``(J, J̇ q̇, h, M⁻¹ Jᵀ, J M⁻¹ Jᵀ, Λ)`` at (q, q̇) (:func:`model_terms`)."""
        jac, jdq, h, minv_jt, _, lam = terms
        self._hold[6:10] = orn
        self._hold[10:] = omega
        self._posture[2 + N_ARM : 2 + 2 * N_ARM] = q
        self._posture[2 + 2 * N_ARM :] = dq
        return torque_law(
            jac, jdq, h, minv_jt, lam, wrench, self._hold, self._posture,
            self.config.task_coriolis_compensation,
        )  # fmt: skip

    def translational_inertia(self, terms: tuple[np.ndarray, ...]) -> np.ndarray:
        """The tool point's translational task-space inertia [kg], (3, 3), from ``terms``
        (:func:`model_terms`): the f → ẍ map of this law, for the controller's H (seed A
        Eq. 1's inertia; the robot model's, not the simulator's truth).

        With the orientation hold on, the hold supplies the moments that keep the tool's
        rotation, so at the translational loop's frequencies (~5 rad/s at K_free = 300 N/m)
        a force moves the tool as if its rotation were locked: the inertia is the
        translational block of the 6-D Λ = (J M⁻¹ Jᵀ)⁻¹ ([f; m] = Λ [ẍ; 0]). The hold takes
        ~0.1 s to catch up (measured in PyBullet with the tool point at [0.45, 0, 0.35] m:
        5 N along x gives 4.2 m/s² over the first 20 ms, the unlocked (J_v M⁻¹ J_vᵀ)⁻¹
        value, and 1.4 m/s² averaged over 100 ms, on the way to the locked 0.57 m/s²).
        Without the hold the moment is zero and the inertia is (J_v M⁻¹ J_vᵀ)⁻¹.
        """
        return translational_inertia(terms[4], terms[5], self.locked)


def model_terms(
    minv: np.ndarray, jac: np.ndarray, jdq: np.ndarray, h: np.ndarray
) -> tuple[np.ndarray, ...]:
    """``(J, J̇ q̇, h, M⁻¹ Jᵀ, J M⁻¹ Jᵀ, Λ)`` from an engine's M⁻¹, J, J̇ q̇ and h at one joint
    state: what :meth:`TorqueLaw.torques` and :meth:`TorqueLaw.translational_inertia` share."""
    return (jac, jdq, h, *task_space(minv, jac))


def dls_ik(
    pose: Callable[[np.ndarray], tuple[np.ndarray, Any]],
    jacobian: Callable[[np.ndarray], np.ndarray],
    limits: tuple[np.ndarray, np.ndarray],
    q_seed: Any,
    position: np.ndarray,
    orientation: np.ndarray,
) -> np.ndarray:
    """Damped least-squares IK of the tool point to a start pose, seeded from ``q_seed``.

    Args:
        pose: the tool point's position [m] and orientation (x, y, z, w) at joint angles q
            (the engine may move its arm there).
        jacobian: the tool point's Jacobian [J_v; J_ω] (6, 7) at the q ``pose`` last saw.
        limits: the joints' ``(lower, upper)`` position limits [rad].

    Returns:
        The joint angles [rad], shape (7,).

    Raises:
        ConfigError: on ``task.start`` if the pose is not reachable or needs a joint angle
            outside its limits.
    """
    q = np.array(q_seed, dtype=float)
    lam2 = 1e-4
    for _ in range(300):
        pos, orn = pose(q)
        e = np.concatenate([position - pos, orientation_error(orientation, np.asarray(orn, float))])
        if float(np.max(np.abs(e))) < 1e-7:
            break
        jac = jacobian(q)
        dq = jac.T @ np.linalg.solve(jac @ jac.T + lam2 * np.eye(6), e)
        q = q + dq
    else:
        raise ConfigError(
            "task.start",
            f"pose {np.round(position, 4).tolist()} is not reachable by the "
            f"Panda tool (IK residual {float(np.linalg.norm(e)):.3g})",
        )
    lower, upper = limits
    for j in range(N_ARM):
        lo, hi = float(lower[j]), float(upper[j])
        if not lo - 1e-6 <= q[j] <= hi + 1e-6:
            raise ConfigError(
                "task.start",
                f"pose {np.round(position, 4).tolist()} needs panda_joint{j + 1} "
                f"= {q[j]:.3f} rad, outside its limits [{lo:.3f}, {hi:.3f}] "
                "(try another start or sim.rest_posture)",
            )
    return q


#: ``StepInfo.extra`` keys of the arm's joint angles [rad], recorded as ``truth_q1_rad`` ...
JOINT_KEYS = tuple(f"q{i}_rad" for i in range(1, N_ARM + 1))


def arm_output(
    t: float,
    tip: tuple[np.ndarray, Any, np.ndarray, np.ndarray],
    orientation: np.ndarray,
    wrench: tuple[np.ndarray, np.ndarray],
    sensor: FTSensor,
    inertia: np.ndarray,
    truth: tuple[np.ndarray, np.ndarray, int, float, np.ndarray],
    table_mu: float,
    joints: np.ndarray,
    hand: np.ndarray | None,
) -> tuple[Observation, StepInfo]:
    """The Observation and the truth of a 3-D backend's step (the same ``extra`` keys at every
    step, as the recorder fixes its columns at the first).

    Args:
        t: time [s]; tip: the tool point's position, (engine) orientation, linear and angular
            velocity; orientation: the tool's orientation (x, y, z, w).
        wrench: the external force and moment at the tool point before the sensor model.
        sensor: the F/T sensor model (noise, bias, faults); inertia: the tool point's
            translational inertia for the controller [kg] (3, 3).
        truth: ``(contact force, moment about the tool point, count, friction of the surface
            carrying the largest normal force, split)``, split = (table normal, box normal,
            |box friction|, normal part x, y, z) [N].
        table_mu: the table's friction this step; joints: the arm's joint angles [rad].
        hand: the hand's mean force over the period [N] (3,), ``None`` without a hand.

    Raises:
        SimulationDiverged: on a non-finite tool position or velocity.
    """
    pos, _, lin, ang = tip
    if not all_finite(pos, lin):
        raise SimulationDiverged(
            f"non-finite tool state at t={t:.3f} s (position={pos.tolist()}, "
            f"velocity={lin.tolist()})"
        )
    f_meas, t_meas = sensor.measure(*wrench)
    obs = Observation(t=t, position=pos, orientation=orientation, lin_vel=lin, ang_vel=ang,
                      force=f_meas, torque=t_meas, inertia=inertia)  # fmt: skip
    f_contact, t_contact, n, mu, split = truth
    table_n, box_n, box_f, nx, ny, nz = split.tolist()
    extra_hand = {}
    if hand is not None:  # the hand's force is external too, not a contact
        extra_hand = dict(zip(("human_fx_N", "human_fy_N", "human_fz_N"), hand.tolist(),
                              strict=True))  # fmt: skip
    info = StepInfo(
        # contacts (and a scene's hand) are the only external forces in these worlds
        true_force=f_contact if hand is None else f_contact + hand,
        true_torque=t_contact,
        contact_force=f_contact,
        n_contacts=n,
        extra={
            "surface_friction": mu if n > 0 else -1.0,
            "table_friction": table_mu,  # the table's friction this step (patches)
            "contact": 1.0 if n > 0 else 0.0,
            "table_normal_N": table_n,  # normal force from the table [N]
            "box_normal_N": box_n,  # ... from scene.boxes (walls) [N]
            "box_friction_N": box_f,  # |friction force| from the boxes [N]
            # the normal part of the contact force (friction left out) [N]
            "normal_force_x": nx,
            "normal_force_y": ny,
            "normal_force_z": nz,
            # the arm's joint angles [rad] (q1_rad ... q7_rad): what `ccm animate` replays
            **dict(zip(JOINT_KEYS, joints.tolist(), strict=True)),
            **extra_hand,
        },
    )
    return obs, info


def hold_command(command: Command, wrench: np.ndarray, t: float) -> np.ndarray:
    """Copy ``command`` into the reused ``wrench`` buffer [f; m] (6,) for a 3-D backend's
    control step and return it.

    Raises:
        ValueError: if the force or torque is not a 3-vector.
        SimulationDiverged: on a non-finite entry (``t``: the time, for the message).
    """
    f_cmd, t_cmd = command.force, command.torque
    if len(f_cmd) != 3 or len(t_cmd) != 3:
        raise ValueError(
            f"command must have force (3,) and torque (3,), got {np.shape(f_cmd)}, "
            f"{np.shape(t_cmd)}"
        )
    wrench[:3], wrench[3:] = f_cmd, t_cmd
    if not all_finite(wrench):
        raise SimulationDiverged(
            f"non-finite command force={np.asarray(f_cmd).tolist()} "
            f"torque={np.asarray(t_cmd).tolist()} at t={t:.3f} s"
        )
    return wrench
