"""Numba kernel behind :func:`ccm.control.loop.impedance_term` (every Eq. 1 controller).

The readable definition, with the equation, is :func:`ccm.control.loop.impedance_term`;
the kernel repeats its arithmetic in the same order (no fast-math, so no reassociation or
fused multiply-adds), so the two agree bit for bit (``tests/test_impedance.py``). It
replaces five numpy temporaries (~0.5 µs each) by one compiled call.
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
def critical_damping_matrix(lam: np.ndarray, kp: np.ndarray, zeta: float) -> np.ndarray:
    """K_d = ζ (Λ^½ K^½ + K^½ Λ^½) for an inertia Λ (n, n, symmetric positive definite) and
    per-axis stiffness K = diag(kp): the critical rule of :func:`ccm.control.loop.
    damping_from_rule` for a matrix inertia (the factorization design)."""
    m, v = np.linalg.eigh(lam)
    root = (v * np.sqrt(np.maximum(m, 0.0))) @ v.T  # Λ^½
    k_half = np.sqrt(kp)
    d = np.empty_like(root)
    n = kp.shape[0]
    for i in range(n):
        for j in range(n):
            d[i, j] = zeta * (root[i, j] * k_half[j] + k_half[i] * root[i, j])
    return d
