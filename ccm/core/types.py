"""Data passed between simulator, task and controller (Observation in, Command out).

Shapes use ``n`` = task-space dimension (2 for the planar world, 3 for PyBullet) and ``r`` =
rotational dimension (1 in 2D: angle about z; 3 in 3D).

**Valid until the next step** (issue #40). A simulator, a pattern or a controller may hand
out the same object every step with its arrays updated in place, as MuJoCo's ``MjData`` is:
what a receiver gets is read-only to it and holds its values until the giver's next step. A
receiver that keeps anything for later (a controller's history, a logger) copies it
(``obs.force.copy()``, ``float(obs.t)``); the recorder copies each step at ``record()``.
``ccm.checks.steps.check_keeps_no_views`` tests a controller for this. The records are
plain slotted dataclasses rather than frozen ones because a frozen dataclass costs ~0.5 µs
more per construction (``make bench``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(slots=True)
class Observation:
    """What a controller may see: the robot's own sensing, nothing else.

    Attributes:
        t: time since reset [s].
        position: end-effector position, world frame [m], shape (n,).
        orientation: 2D: angle [rad] shape (1,); 3D: quaternion (x, y, z, w) shape (4,).
        lin_vel: end-effector linear velocity, world frame [m/s], shape (n,).
        ang_vel: angular velocity [rad/s], shape (r,).
        force: measured external force on the end-effector, world frame [N], shape (n,).
            It comes from the modelled F/T sensor (with its noise and bias), never from the
            command.
        torque: measured external torque about the end-effector origin [N m], shape (r,).
        inertia: the robot model's translational task-space inertia Λ(q) [kg], shape (n, n),
            at the measured joint angles (what a real arm's model library gives, e.g.
            Franka's), or ``None`` where the end-effector's inertia does not depend on a
            configuration (the planar world's body, whose mass the controllers know).
    """

    t: float
    position: np.ndarray
    orientation: np.ndarray
    lin_vel: np.ndarray
    ang_vel: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    inertia: np.ndarray | None = None

    @property
    def dim(self) -> int:
        return int(self.position.shape[0])


@dataclass(slots=True)
class Command:
    """Task-space wrench command on the end-effector (Eq. 1, seed A: u_t), world frame.

    Attributes:
        force: [N], shape (n,).
        torque: [N m], shape (r,).
    """

    force: np.ndarray
    torque: np.ndarray


@dataclass(slots=True)
class TargetSample:
    """The target motion pattern P evaluated at one time (seed A §3: pose and force targets).

    Attributes:
        t: time [s].
        position, velocity, acceleration: desired end-effector motion, world frame, shape (n,).
        orientation: desired orientation, same convention as ``Observation.orientation``.
        force_dir: unit vector (n,) along which force is controlled instead of position
            (hybrid force-motion, Eq. 1 u_fc), or ``None`` for pure motion.
        force_mag: desired force the end-effector exerts *on the environment* along
            ``force_dir`` [N] (>= 0). Ignored when ``force_dir`` is ``None``.
        segment: index of the pattern segment this sample belongs to.
        done: True once the pattern has ended (the last pose is held).
    """

    t: float
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    orientation: np.ndarray
    force_dir: np.ndarray | None = None
    force_mag: float = 0.0
    segment: int = 0
    done: bool = False


@dataclass
class StepInfo:
    """Ground truth from the simulator, for metrics and plots only — never for controllers.

    Attributes:
        true_force: external force on the end-effector without sensor noise/bias [N], (n,).
        true_torque: external torque without noise/bias [N m], (r,).
        contact_force: part of ``true_force`` due to contacts [N], (n,).
        n_contacts: number of contact points touching the end-effector.
        extra: backend-specific truth (e.g. current viscosity [N s/m], surface id).
    """

    true_force: np.ndarray
    true_torque: np.ndarray
    contact_force: np.ndarray
    n_contacts: int = 0
    extra: dict[str, float] = field(default_factory=dict)
