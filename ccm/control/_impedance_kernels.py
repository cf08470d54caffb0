"""Numba kernel behind :func:`ccm.control.loop.impedance_term` (every Eq. 1 controller).

The readable definition, with the equation, is :func:`ccm.control.loop.impedance_term`;
the kernel repeats its arithmetic in the same order (no fast-math, so no reassociation or
fused multiply-adds), so the two agree bit for bit (``tests/test_impedance.py``). It
replaces five numpy temporaries (~0.5 µs each) by one compiled call. The 3-D arm's terms
(an inertia matrix Λ: K_d from Λ^½, matrix products, the force loop's projections) have
kernels too; they agree with numpy's to rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import overload


def _gain(k: float | np.ndarray, i: int) -> float:
    """Gain ``k`` of axis ``i``: ``k[i]`` for a per-axis array, ``k`` for a scalar."""
    return float(k[i]) if isinstance(k, np.ndarray) else float(k)


@overload(_gain)
def _gain_numba(k, i):  # type: ignore[no-untyped-def]  # noqa: ANN001, ANN202, ARG001
    if isinstance(k, types.Array):
        return lambda k, i: k[i]
    return lambda k, i: k


@njit(cache=True)
def impedance_kernel(
    target_pos: np.ndarray,
    pos: np.ndarray,
    target_vel: np.ndarray,
    vel: np.ndarray,
    target_acc: np.ndarray,
    kp: float | np.ndarray,
    kd: float | np.ndarray,
    mass_kg: float,
    inertia_feedforward: bool,
) -> np.ndarray:
    """K_p Δx + K_d Δẋ (+ m ẍ_d) per axis, a new array (motion part of Eq. 1, seed A)."""
    n = pos.shape[0]
    u = np.empty(n)
    for i in range(n):
        e = (target_pos[i] - pos[i]) * _gain(kp, i) + (target_vel[i] - vel[i]) * _gain(kd, i)
        u[i] = e + mass_kg * target_acc[i] if inertia_feedforward else e
    return u


@njit(cache=True)
def impedance_matrix_kernel(
    target_pos: np.ndarray,
    pos: np.ndarray,
    target_vel: np.ndarray,
    vel: np.ndarray,
    target_acc: np.ndarray,
    kp: float | np.ndarray,
    kd: np.ndarray,
    lam: np.ndarray,
    inertia_feedforward: bool,
) -> np.ndarray:
    """K_p Δx + K_d Δẋ (+ Λ ẍ_d) with a damping matrix K_d and an inertia matrix Λ (n, n):
    the 3-D arm's case of :func:`ccm.control.loop.impedance_term`, a new array."""
    n = pos.shape[0]
    u = np.empty(n)
    for i in range(n):
        e = (target_pos[i] - pos[i]) * _gain(kp, i)
        s = 0.0
        for j in range(n):
            s += kd[i, j] * (target_vel[j] - vel[j])
        e += s
        if inertia_feedforward:
            s = 0.0
            for j in range(n):
                s += lam[i, j] * target_acc[j]
            e += s
        u[i] = e
    return u


@njit(cache=True)
def force_direction_terms(
    u: np.ndarray, d: np.ndarray, force: np.ndarray, vel: np.ndarray
) -> tuple[np.ndarray, float, float]:
    """``(u − d (d·u), d·F, d·ẋ)``: the motion force projected by P_m = I − d dᵀ, and the
    measured force and velocity along the force direction ``d`` (the force loop of
    :meth:`ccm.control.loop.HybridLoop.motion_force`; dots summed in order)."""
    n = u.shape[0]
    du = fd = vd = 0.0
    for i in range(n):
        du += d[i] * u[i]
        fd += d[i] * force[i]
        vd += d[i] * vel[i]
    out = np.empty(n)
    for i in range(n):
        out[i] = u[i] - d[i] * du
    return out, fd, vd


@njit(cache=True)
def _symmetric_root(a: np.ndarray) -> np.ndarray:
    """A^½ of a symmetric positive semi-definite ``a`` (n, n) by cyclic Jacobi rotations
    (plain loops: for n ≤ 6 much cheaper than a LAPACK call); negative rounding-level
    eigenvalues count as 0."""
    n = a.shape[0]
    m = a.copy()
    v = np.eye(n)
    scale = 0.0
    for i in range(n):
        scale += abs(m[i, i])
    for _sweep in range(50):
        off = 0.0
        for i in range(n):
            for j in range(i + 1, n):
                off += m[i, j] * m[i, j]
        if off <= (1e-17 * scale) ** 2:
            break
        for p in range(n):
            for q in range(p + 1, n):
                if m[p, q] == 0.0:
                    continue
                theta = (m[q, q] - m[p, p]) / (2.0 * m[p, q])
                t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):  # M ← Jᵀ M J, V ← V J for the rotation J(p, q, θ)
                    mkp, mkq = m[k, p], m[k, q]
                    m[k, p], m[k, q] = c * mkp - s * mkq, s * mkp + c * mkq
                for k in range(n):
                    mpk, mqk = m[p, k], m[q, k]
                    m[p, k], m[q, k] = c * mpk - s * mqk, s * mpk + c * mqk
                for k in range(n):
                    vkp, vkq = v[k, p], v[k, q]
                    v[k, p], v[k, q] = c * vkp - s * vkq, s * vkp + c * vkq
    root = np.zeros((n, n))
    for k in range(n):
        r = np.sqrt(max(m[k, k], 0.0))
        for i in range(n):
            for j in range(n):
                root[i, j] += v[i, k] * r * v[j, k]
    return root


@njit(cache=True)
def critical_damping_matrix(lam: np.ndarray, kp: float | np.ndarray, zeta: float) -> np.ndarray:
    """K_d = ζ (Λ^½ K^½ + K^½ Λ^½) for an inertia Λ (n, n, symmetric positive definite) and
    stiffness K = diag(kp) (``kp`` per axis or one for all): the critical rule of
    :func:`ccm.control.loop.damping_from_rule` for a matrix inertia (the factorization
    design)."""
    root = _symmetric_root(lam)  # Λ^½
    n = lam.shape[0]
    d = np.empty_like(root)
    for i in range(n):
        ki = np.sqrt(_gain(kp, i))
        for j in range(n):
            d[i, j] = zeta * (root[i, j] * np.sqrt(_gain(kp, j)) + ki * root[i, j])
    return d
