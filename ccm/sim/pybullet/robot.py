"""The Panda with its block tool for the PyBullet 3D backend (:mod:`ccm.sim.pybullet.backend`).

Loading the Panda of :mod:`ccm.sim.panda` (its URDF: fingers removed, the block tool fixed
to ``panda_hand``) into PyBullet, and the kinematics/dynamics helpers of the backend's torque
loop and sensing: tool-point state and Jacobian, start-pose inverse kinematics, inverse
dynamics, task-space inertia and the dynamically consistent null-space projection,
orientation error, F/T gravity compensation and the contact ground truth. Functions take the
PyBullet module ``p`` and the physics client id ``cid`` explicitly.

Modelling choices (the torque loop and the table patches are described in
:mod:`ccm.sim.pybullet.backend`):

* **Robot and tool.** ``franka_panda/panda.urdf`` from ``pybullet_data`` with a fixed base.
  The fingers (two prismatic joints that would need their own controller) are removed and a
  rigid box, the *tool*, is attached to ``panda_hand`` by a fixed URDF joint
  (``ccm_tool_joint``) where the fingers were mounted. The tool is a link of the robot's
  multibody, not a second body held by a constraint, so the Jacobian, the inverse dynamics
  and the F/T sensor all see the same rigid tool and the contacts are clean box contacts.
  The modified URDF is written to a temporary directory (meshes by absolute path) and
  deleted after loading.
* **Tool point.** The centre of the tool's bottom face (the face that touches the table
  when the tool points down). Positions, velocities, the Jacobian, the commanded wrench and
  the measured wrench all refer to this point; vectors are in the world frame.
* **F/T sensor.** ``enableJointForceTorqueSensor`` on ``ccm_tool_joint`` (hand → tool), so
  only the tool lies beyond the sensor, like a wrist sensor carrying the tool. PyBullet
  reports the wrench the parent (hand) exerts on the child (tool), in the child's Bullet
  link frame, i.e. its *centre-of-mass* frame: the moment is about the tool's centre of mass
  ``c``, not about the URDF joint origin (measured: a tilted tool at rest reads zero moment;
  ``tests/test_pybullet_physics.py`` checks it against the contact truth). The reading is
  rotated to the world frame, the tool's weight is removed and the result is expressed as
  the external wrench *on* the tool at the tool point ``p``::

      F_ext = m_tool a_c − R F_joint − m_tool g
      M_ext = (I α + ω × I ω) − R M_joint + (c − p) × F_ext

  (Newton–Euler for the tool: what the hand and the world exert on it equals its rate of
  momentum.) The tool's acceleration a_c and angular acceleration α are backward differences
  of its centre-of-mass twist over one physics step, as a robot would differentiate its
  kinematics; I is the tool's inertia in the world frame. Then
  :class:`ccm.sim.sensor.FTSensor` adds bias and noise. With ``control_decimation > 1`` the
  reading is the mean over the control period's physics steps.
* **Ground truth.** ``getContactPoints`` on the tool link: normal force (entry 9) along the
  normal on B (entry 7, pointing from the other body to the tool) minus the two lateral
  friction forces (entries 10/12 along 11/13: PyBullet reports them as acting on body B,
  measured against the F/T reading and the commanded force), summed over points; the
  torque is about the tool point. ``surface_friction`` is the friction of the body carrying
  the largest normal force. Bullet multiplies the two bodies' friction (and restitution)
  coefficients, so the tool has friction 1 and restitution 1 and the surface's values are the
  effective ones, as in the 2D backend.
* **Compliant tool contact.** The tool's contacts use Bullet's spring-damper contact model
  (``contact_stiffness`` 1e5 N/m, ``contact_damping`` 1e3 N s/m, both chosen). They act
  per contact point: a flat face resting on 4 points measured 4e5 N/m (0.035 mm sink at
  10 N, 0.060 mm at 20 N). With Bullet's default rigid contacts (and with 1e6 N/m) the flat
  tool face sliding under a 10 N press at friction 0.8 chattered (normal-force std ≈ 40 N
  on a 10 N mean, edge contacts, hopping); with these values it slides smoothly and
  friction/normal = 0.800.
"""

from __future__ import annotations

import math
import shutil
import tempfile
from collections.abc import Container, Mapping, Sequence
from typing import Any

import numpy as np

from ccm.sim import _kernels as _k
from ccm.sim.arm import dls_ik
from ccm.sim.panda import N_ARM, robot_urdf
from ccm.sim.pybullet.scene import PyBullet3DConfig

# --------------------------------------------------------------------------- math helpers


def _quat_rotate(q: Sequence[float], v: Sequence[float]) -> tuple[float, float, float]:
    """Rotate ``v`` by the unit quaternion ``q`` (x, y, z, w)
    (:func:`ccm.sim._kernels.quat_rotate`)."""
    x, y, z = _k.quat_rotate(np.asarray(q, dtype=float), np.asarray(v, dtype=float)).tolist()
    return x, y, z


def orientation_error(q_des: Sequence[float], q: Sequence[float]) -> np.ndarray:
    """Rotation vector [rad] (world frame) that takes orientation ``q`` to ``q_des``
    (:func:`ccm.sim._kernels.orientation_error`)."""
    return _k.orientation_error(np.asarray(q_des, dtype=float), np.asarray(q, dtype=float))


# --------------------------------------------------------------------------- robot


def load_robot(p: Any, cid: int, config: PyBullet3DConfig) -> tuple[int, int]:
    """Load the Panda with the block tool, set up for torque control and F/T sensing.

    Link and joint damping are zeroed, the tool link gets friction 1, restitution 1 and the
    compliant contact model, the default velocity motors are switched off and the joint F/T
    sensor on ``ccm_tool_joint`` is enabled.

    Returns:
        ``(robot, tool_link)``: the body id and the tool's link index.
    """
    tmp = tempfile.mkdtemp(prefix="ccm_panda_")
    try:
        urdf = robot_urdf(config.tool, tmp, visuals=config.gui)  # meshes only to look at
        robot = p.loadURDF(urdf, [0, 0, 0], useFixedBase=True, physicsClientId=cid)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    names = {}
    for j in range(p.getNumJoints(robot, physicsClientId=cid)):
        info = p.getJointInfo(robot, j, physicsClientId=cid)
        names[info[1].decode()] = j
    arm = [names[f"panda_joint{i}"] for i in range(1, N_ARM + 1)]
    if arm != list(range(N_ARM)):  # pragma: no cover - URDF layout changed
        raise RuntimeError(f"unexpected Panda joint layout {names}")
    tool_link = names["ccm_tool_joint"]
    for link in range(-1, p.getNumJoints(robot, physicsClientId=cid)):
        # no artificial damping, so that calculateInverseDynamics is the exact model
        p.changeDynamics(
            robot, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
            physicsClientId=cid,
        )  # fmt: skip
    # the surface's friction/restitution become the effective ones (Bullet multiplies);
    # compliant contact (module docstring: rigid contacts chattered sliding at mu 0.8)
    p.changeDynamics(
        robot, tool_link, lateralFriction=1.0, restitution=1.0,
        contactStiffness=config.contact_stiffness,
        contactDamping=config.contact_damping, physicsClientId=cid,
    )  # fmt: skip
    # torque control: switch off the default velocity motors
    p.setJointMotorControlArray(
        robot, arm, p.VELOCITY_CONTROL, forces=[0.0] * N_ARM, physicsClientId=cid
    )
    p.enableJointForceTorqueSensor(robot, tool_link, True, physicsClientId=cid)
    return robot, tool_link


# --------------------------------------------------------------------------- kinematics


def tool_point_state(
    p: Any,
    cid: int,
    robot: int,
    tool_link: int,
    tip_local: Sequence[float],
    velocity: bool = True,
) -> tuple[np.ndarray, tuple[float, ...], np.ndarray, np.ndarray, np.ndarray]:
    """Tool point position, orientation (x, y, z, w), linear and angular velocity, and the
    linear velocity of the tool's centre of mass.

    ``tip_local`` is the tool point in the tool's centre-of-mass (Bullet link) frame.
    """
    ls = p.getLinkState(
        robot, tool_link, computeLinkVelocity=1 if velocity else 0,
        computeForwardKinematics=1, physicsClientId=cid,
    )  # fmt: skip
    com, orn = ls[0], ls[1]
    r = _quat_rotate(orn, tip_local)
    pos = np.array([com[0] + r[0], com[1] + r[1], com[2] + r[2]])
    if not velocity:
        return pos, orn, np.zeros(3), np.zeros(3), np.zeros(3)
    v, w = ls[6], ls[7]
    lin = np.array(
        [
            v[0] + w[1] * r[2] - w[2] * r[1],
            v[1] + w[2] * r[0] - w[0] * r[2],
            v[2] + w[0] * r[1] - w[1] * r[0],
        ]
    )
    return pos, orn, lin, np.array(w), np.array(v)


def tool_point_in_link(
    p: Any, cid: int, robot: int, tool_link: int, tip_local: Sequence[float]
) -> tuple[float, float, float]:
    """The tool point in the tool's URDF link frame, from ``tip_local`` in its centre-of-mass
    frame: ``c + R_c tip_local`` with PyBullet's local inertial frame ``(c, R_c)``."""
    com, orn = p.getDynamicsInfo(robot, tool_link, physicsClientId=cid)[3:5]
    r = _quat_rotate(orn, tip_local)
    return (com[0] + r[0], com[1] + r[1], com[2] + r[2])


def tool_jacobian(
    p: Any,
    cid: int,
    robot: int,
    tool_link: int,
    tip_link: Sequence[float],
    q: np.ndarray,
    dq: np.ndarray,
) -> np.ndarray:
    """Geometric Jacobian ``[J_v; J_ω]`` (6, 7) of the tool point in the world frame.

    ``tip_link`` is the tool point in the tool's *URDF link* frame
    (:func:`tool_point_in_link`): ``calculateJacobian`` takes its point in that frame, not in
    the centre-of-mass frame its documentation names (measured: with the centre-of-mass-frame
    offset its J_v differs from a finite difference of the tool point by 0.02 m/rad, the
    distance to the centre of mass; with the link-frame point by 1e-10).
    """
    lin, ang = p.calculateJacobian(
        robot, tool_link, list(tip_link), q.tolist(), dq.tolist(), [0.0] * N_ARM,
        physicsClientId=cid,
    )  # fmt: skip
    return np.array((*lin, *ang))


def set_joint_positions(p: Any, cid: int, robot: int, q: Sequence[float]) -> None:
    """Reset the arm joints to ``q`` [rad] with zero velocity."""
    for j in range(N_ARM):
        p.resetJointState(robot, j, float(q[j]), 0.0, physicsClientId=cid)


def start_ik(
    p: Any,
    cid: int,
    robot: int,
    tool_link: int,
    tip_local: Sequence[float],
    q_seed: Sequence[float],
    position: np.ndarray,
    orientation: np.ndarray,
) -> np.ndarray:
    """The start pose's joint angles [rad], (7,), by :func:`ccm.sim.arm.dls_ik` seeded from
    ``q_seed``, on PyBullet's kinematics (moves the arm while iterating).

    Raises:
        ConfigError: on ``task.start`` if the pose is not reachable or needs a joint angle
            outside its limits.
    """
    tip_link = tool_point_in_link(p, cid, robot, tool_link, tip_local)

    def pose(q: np.ndarray) -> tuple[np.ndarray, Any]:
        set_joint_positions(p, cid, robot, q)
        pos, orn, _, _, _ = tool_point_state(p, cid, robot, tool_link, tip_local, velocity=False)
        return pos, orn

    def jacobian(q: np.ndarray) -> np.ndarray:
        return tool_jacobian(p, cid, robot, tool_link, tip_link, q, np.zeros(N_ARM))

    info = [p.getJointInfo(robot, j, physicsClientId=cid)[8:10] for j in range(N_ARM)]
    limits = (np.array([lo for lo, _ in info]), np.array([hi for _, hi in info]))
    return dls_ik(pose, jacobian, limits, q_seed, position, orientation)


# --------------------------------------------------------------------------- dynamics


def inverse_dynamics(p: Any, cid: int, robot: int, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """``h(q, q̇)``: gravity + Coriolis joint torques (inverse dynamics at zero acceleration)."""
    return np.asarray(
        p.calculateInverseDynamics(
            robot, q.tolist(), dq.tolist(), [0.0] * N_ARM, physicsClientId=cid
        )
    )


def task_inertia(
    p: Any, cid: int, robot: int, q: np.ndarray, jac: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(M⁻¹ Jᵀ, Λ)`` with the task-space inertia ``Λ = (J M⁻¹ Jᵀ)⁻¹``.

    J M⁻¹ Jᵀ is inverted directly; only if that fails (exactly singular) the pseudo-inverse is
    used. (NumPy's pinv truncates singular values below 1e-15 relative only, so near a
    singularity it gives the same huge Λ as the inverse: the tasks keep the arm away from
    singular configurations.)
    """
    mass = np.array(p.calculateMassMatrix(robot, q.tolist(), physicsClientId=cid))
    minv_jt = np.linalg.inv(mass) @ jac.T  # M⁻¹ Jᵀ (M is 7x7 and positive definite)
    a = jac @ minv_jt
    try:
        return minv_jt, np.linalg.inv(a)
    except np.linalg.LinAlgError:
        return minv_jt, np.linalg.pinv(a)


def nullspace_projection(
    jac: np.ndarray, lam: np.ndarray, minv_jt: np.ndarray, tau0: np.ndarray
) -> np.ndarray:
    """``N τ₀`` with the dynamically consistent projector ``N = I − Jᵀ Λ J M⁻¹``."""
    # N τ₀ = τ₀ − Jᵀ Λ J M⁻¹ τ₀ ; J M⁻¹ τ₀ = (M⁻¹ Jᵀ)ᵀ τ₀ since M is symmetric
    return tau0 - jac.T @ (lam @ (minv_jt.T @ tau0))


# --------------------------------------------------------------------------- sensing


def contact_truth(
    pts: Sequence[Sequence[Any]],
    tip: np.ndarray,
    box_bodies: Container[int],
    body_friction: Mapping[int, float],
) -> tuple[np.ndarray, np.ndarray, int, float, np.ndarray]:
    """Contact ground truth in one pass over the tool's contact points (module docstring).

    Args:
        pts: ``getContactPoints`` of the tool link (body A), non-empty: the other body's id
            is entry 2, the position on A entry 5, the normal on B entry 7 (pointing from the
            other body to the tool), the normal force entry 9, the two lateral friction
            forces entries 10/12 along the directions 11/13.
        tip: the tool point [m].
        box_bodies: body ids of ``scene.boxes`` (walls, obstacles); every other static body
            belongs to the table (patch boxes included).
        body_friction: friction of each static body by body id.

    Returns:
        ``(force, moment about tip, count, friction of the body with the largest normal
        force, split)``, ``split`` = (table normal, box normal, |box friction force|, the
        normal part of the contact force x, y, z) [N]. PyBullet's lateral friction entries
        act on body B along the listed directions, so the tool gets the opposite (checked
        against the F/T reading). The normal part (friction left out) is the H4 onset truth
        (:mod:`ccm.metrics.contacts`).
    """
    fx = fy = fz = mx = my = mz = 0.0
    table_n = box_n = bx = by = bz = nx = ny = nz = 0.0
    tx, ty, tz = float(tip[0]), float(tip[1]), float(tip[2])
    best, mu = -1.0, -1.0
    for c in pts:  # plain floats: a handful of points, numpy's per-call cost would dominate
        fn, l1, l2 = c[9], c[10], c[12]
        nrm, d1, d2 = c[7], c[11], c[13]
        lx, ly, lz = l1 * d1[0] + l2 * d2[0], l1 * d1[1] + l2 * d2[1], l1 * d1[2] + l2 * d2[2]
        cx = fn * nrm[0] - l1 * d1[0] - l2 * d2[0]
        cy = fn * nrm[1] - l1 * d1[1] - l2 * d2[1]
        cz = fn * nrm[2] - l1 * d1[2] - l2 * d2[2]
        rx, ry, rz = c[5][0] - tx, c[5][1] - ty, c[5][2] - tz
        fx, fy, fz = fx + cx, fy + cy, fz + cz
        mx, my, mz = mx + ry * cz - rz * cy, my + rz * cx - rx * cz, mz + rx * cy - ry * cx
        nx, ny, nz = nx + fn * nrm[0], ny + fn * nrm[1], nz + fn * nrm[2]
        if c[2] in box_bodies:
            box_n += fn
            bx, by, bz = bx - lx, by - ly, bz - lz
        else:
            table_n += fn
        if fn > best:
            best, mu = fn, body_friction.get(c[2], -1.0)
    split = np.array([table_n, box_n, math.sqrt(bx * bx + by * by + bz * bz), nx, ny, nz])
    return np.array([fx, fy, fz]), np.array([mx, my, mz]), len(pts), mu, split
