"""Compiled per-physics-step math of the PyBullet backend (issue #20).

Per physics step of :class:`ccm.sim.pybullet.backend.PyBullet3D`:

* :func:`task_space`: M⁻¹ Jᵀ, the mobility J M⁻¹ Jᵀ and Λ at the new joint state, shared by
  the observation's inertia (:func:`translational_inertia`) and the next torques;
* :func:`torque_law`: the Panda's joint torques from Pinocchio's terms (the module docstring
  of :mod:`ccm.sim.pybullet.dynamics`),
  ``τ = Jᵀ [f; m + m_hold] + h − Jᵀ Λ J̇ q̇ + N τ₀`` with ``Λ = (J M⁻¹ Jᵀ)⁻¹`` and
  ``N τ₀ = τ₀ − Jᵀ Λ J M⁻¹ τ₀``. The readable form, on PyBullet's own queries, is
  ``TorqueLoop._torques_pybullet``; ``tests/test_panda_dynamics.py`` checks that the two
  agree.
* :func:`tool_sense`: the tool point's state from the tool link's state, and the external
  wrench from the tool joint's F/T reading by the Newton–Euler balance of the tool
  (the "F/T sensor" item of the module docstring of :mod:`ccm.sim.pybullet.robot`).

Small fixed sizes (7 joints, 6-D task space): plain loops, no BLAS call.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def orientation_error(q_des: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation vector [rad] (world frame) taking orientation ``q`` to ``q_des`` (x, y, z, w):
    the vector part of ``q_des ⊗ q⁻¹`` scaled to its angle, the shorter way round."""
    x1, y1, z1, w1 = q_des[0], q_des[1], q_des[2], q_des[3]
    x2, y2, z2, w2 = -q[0], -q[1], -q[2], q[3]
    ex = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
    ey = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
    ez = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
    ew = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
    if ew < 0.0:
        ex, ey, ez, ew = -ex, -ey, -ez, -ew
    s = math.sqrt(ex * ex + ey * ey + ez * ez)
    out = np.empty(3)
    if s < 1e-12:
        out[0], out[1], out[2] = 2.0 * ex, 2.0 * ey, 2.0 * ez
        return out
    k = 2.0 * math.atan2(s, ew) / s
    out[0], out[1], out[2] = ex * k, ey * k, ez * k
    return out


@njit(cache=True)
def _task_inertia(a: np.ndarray) -> np.ndarray:
    """Λ = A⁻¹ of the 6 × 6 mobility ``A = J M⁻¹ Jᵀ`` by Cholesky; the pseudo-inverse if A is
    not positive definite in floating point (an exact singularity)."""
    n = a.shape[0]
    low = np.zeros((n, n))
    for j in range(n):
        d = a[j, j]
        for k in range(j):
            d -= low[j, k] * low[j, k]
        if not d > 0.0:
            return np.linalg.pinv(a)
        low[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            low[i, j] = s / low[j, j]
    lam = np.zeros((n, n))
    for c in range(n):  # solve L Lᵀ x = e_c
        y = np.zeros(n)
        for i in range(n):
            s = 1.0 if i == c else 0.0
            for k in range(i):
                s -= low[i, k] * y[k]
            y[i] = s / low[i, i]
        for i in range(n - 1, -1, -1):
            s = y[i]
            for k in range(i + 1, n):
                s -= low[k, i] * lam[k, c]
            lam[i, c] = s / low[i, i]
    return lam


@njit(cache=True)
def task_space(minv: np.ndarray, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(M⁻¹ Jᵀ, J M⁻¹ Jᵀ, Λ)`` at one joint state: the operational-space terms that the
    torque law and the observation's inertia share, with ``Λ = (J M⁻¹ Jᵀ)⁻¹``.

    Args:
        minv: M⁻¹ (7, 7); jac: J (6, 7).
    """
    nj = jac.shape[1]
    minv_jt = np.zeros((nj, 6))
    for i in range(nj):
        for r in range(6):
            s = 0.0
            for k in range(nj):
                s += minv[i, k] * jac[r, k]
            minv_jt[i, r] = s
    mob = np.zeros((6, 6))
    for r in range(6):
        for c in range(6):
            s = 0.0
            for k in range(nj):
                s += jac[r, k] * minv_jt[k, c]
            mob[r, c] = s
    return minv_jt, mob, _task_inertia(mob)


@njit(cache=True)
def translational_inertia(mob: np.ndarray, lam: np.ndarray, locked: bool) -> np.ndarray:
    """The tool point's translational inertia (3, 3) [kg]: Λ's translational block when the
    rotation is held (``locked``), else ``(J_v M⁻¹ J_vᵀ)⁻¹`` from the mobility's block
    (``TorqueLoop.translational_inertia`` says which applies when)."""
    if locked:
        return lam[:3, :3].copy()
    return _task_inertia(np.ascontiguousarray(mob[:3, :3]))


@njit(cache=True)
def torque_law(
    jac: np.ndarray,
    jdq: np.ndarray,
    h: np.ndarray,
    minv_jt: np.ndarray,
    lam: np.ndarray,
    wrench: np.ndarray,
    hold: np.ndarray,
    posture: np.ndarray,
    coriolis: bool,
) -> np.ndarray:
    """Joint torques ``τ = Jᵀ (W + [0; m_hold]) + h − Jᵀ Λ J̇ q̇ + N τ₀`` (module docstring).

    Args:
        jac: J (6, 7); jdq: J̇ q̇ (6,); h: gravity + Coriolis torques (7,).
        minv_jt, lam: M⁻¹ Jᵀ (7, 6) and Λ (6, 6) of :func:`task_space`.
        wrench: commanded task-space wrench ``[f; m]`` (6,).
        hold: the orientation hold ``(K_o, D_o, q_des (4), q (4), ω (3))`` (13,): the moment
            ``m_hold = K_o e_R(q_des, q) − D_o ω`` is added to ``m`` if either gain is non-zero.
        posture: ``(K_n, D_n, q_rest (7), q (7), q̇ (7))``: ``τ₀ = K_n (q_rest − q) − D_n q̇``
            and ``N τ₀`` is added if either gain is non-zero.
        coriolis: subtract ``Jᵀ Λ J̇ q̇``.
    """
    nj = jac.shape[1]
    w = wrench.copy()
    if hold[0] != 0.0 or hold[1] != 0.0:
        w[3:] += hold[0] * orientation_error(hold[2:6], hold[6:10]) - hold[1] * hold[10:13]
    tau = _mat_vec(jac.T, w) + h
    if coriolis:
        tau -= _mat_vec(jac.T, _mat_vec(lam, jdq))
    if posture[0] != 0.0 or posture[1] != 0.0:  # N τ₀ = τ₀ − Jᵀ Λ (M⁻¹ Jᵀ)ᵀ τ₀
        q, dq = posture[2 + nj : 2 + 2 * nj], posture[2 + 2 * nj :]
        tau0 = posture[0] * (posture[2 : 2 + nj] - q) - posture[1] * dq
        tau += tau0 - _mat_vec(jac.T, _mat_vec(lam, _mat_vec(minv_jt.T, tau0)))
    return tau


@njit(cache=True)
def _mat_vec(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``A v``."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        s = 0.0
        for k in range(a.shape[1]):
            s += a[i, k] * v[k]
        out[i] = s
    return out


@njit(cache=True)
def _rotate(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    out = np.zeros(3)
    for i in range(3):
        out[i] = rot[i, 0] * v[0] + rot[i, 1] * v[1] + rot[i, 2] * v[2]
    return out


@njit(cache=True)
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(cache=True)
def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` rotated by the unit quaternion ``q`` (x, y, z, w): ``v + w t + q_vec × t`` with
    ``t = 2 q_vec × v``."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    out = np.empty(3)
    out[0] = v[0] + w * tx + (y * tz - z * ty)
    out[1] = v[1] + w * ty + (z * tx - x * tz)
    out[2] = v[2] + w * tz + (x * ty - y * tx)
    return out


@njit(cache=True)
def quat_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of the unit quaternion ``q`` = (x, y, z, w)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    rot = np.empty((3, 3))
    rot[0, 0] = 1 - 2 * (y * y + z * z)
    rot[0, 1] = 2 * (x * y - z * w)
    rot[0, 2] = 2 * (x * z + y * w)
    rot[1, 0] = 2 * (x * y + z * w)
    rot[1, 1] = 1 - 2 * (x * x + z * z)
    rot[1, 2] = 2 * (y * z - x * w)
    rot[2, 0] = 2 * (x * z - y * w)
    rot[2, 1] = 2 * (y * z + x * w)
    rot[2, 2] = 1 - 2 * (x * x + y * y)
    return rot


@njit(cache=True)
def tool_sense(
    link: np.ndarray,
    reading: np.ndarray,
    tip_local: np.ndarray,
    prev: np.ndarray,
    mass: float,
    inertia_body: np.ndarray,
    gravity: float,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool point's state and the external wrench on the tool, at the tool point.

    Args:
        link: the tool link's centre-of-mass position (3), orientation (x, y, z, w) and
            linear and angular velocity (3 + 3): ``getLinkState`` entries 0, 1, 6, 7, (13,).
        reading: the tool joint's reaction wrench in the link frame, force then moment (6,):
            the force the hand exerts on the tool and its moment about the centre of mass.
        tip_local: the tool point in the link (centre-of-mass) frame (3,).
        prev: the previous step's centre-of-mass twist ``(v_c, ω)`` (6,), NaN if none (the
            arm was just placed at rest: no acceleration).
        mass, inertia_body: the tool's mass [kg] and body-frame inertia (3, 3) [kg m²].

    Returns:
        ``(tip, rot, wrench)``: ``tip`` = position, linear and angular velocity of the tool
        point (9,); ``rot`` the tool's orientation matrix; ``wrench`` the external force and
        its moment about the tool point (6,): ``f = m a_c − R f_joint − m g`` and
        ``m = I α + ω × I ω − R m_joint − r × f`` (Newton–Euler, a_c and α backward
        differences over ``dt``).
    """
    rot = quat_matrix(link[3:7])
    r = quat_rotate(link[3:7], tip_local)
    v, w = link[7:10], link[10:13]
    tip = np.empty(9)
    tip[:3] = link[:3] + r
    tip[3] = v[0] + w[1] * r[2] - w[2] * r[1]  # v + ω × r
    tip[4] = v[1] + w[2] * r[0] - w[0] * r[2]
    tip[5] = v[2] + w[0] * r[1] - w[1] * r[0]
    tip[6:] = w
    acc, alpha = np.zeros(3), np.zeros(3)
    if not np.isnan(prev[0]):
        acc = (v - prev[:3]) / dt
        alpha = (w - prev[3:]) / dt
    inertia = rot @ inertia_body @ rot.T
    wrench = np.empty(6)
    f = mass * acc - _rotate(rot, reading[:3])
    f[2] += mass * gravity  # minus the weight (0, 0, −m g)
    wrench[:3] = f
    wrench[3:] = inertia @ alpha + _cross(w, inertia @ w) - _rotate(rot, reading[3:]) - _cross(r, f)
    return tip, rot, wrench
