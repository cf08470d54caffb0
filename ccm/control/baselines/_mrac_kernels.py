"""Numba kernel behind :meth:`ccm.control.baselines.mrac.MRAC.step` off force segments.

The readable definition, with the equations, is :class:`ccm.control.baselines.mrac.MRAC`
(``_adapt``, ``_stats``, ``_advance``); the kernel repeats that arithmetic per axis in the
same order (no fast-math, so no reassociation or fused multiply-adds), so the control law's
every value (reference model, integrals, f, K_p, K_v) agrees bit for bit, and so do the axis
means of K_p and K_v (numpy sums fewer than 8 values in order). The three norms of the
signals are plain sums of squares: numpy's ``linalg.norm`` goes through BLAS ``ddot``, which
may fuse a multiply-add, so they can differ in the last bit; they are recorded signals only
(``tests/test_mrac_kernels.py`` bounds them). One call replaces ~40 numpy operations on
2- or 3-vectors (~1 µs each): the MRAC step was the largest per-step cost of H1's loop.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def mrac_kernel(
    pos: np.ndarray,
    vel: np.ndarray,
    r: np.ndarray,
    x_m: np.ndarray,
    v_m: np.ndarray,
    omega2: np.ndarray,
    two_zeta_omega: np.ndarray,
    gains: np.ndarray,
    ints: np.ndarray,
    g: np.ndarray,
) -> tuple:
    """One MRAC step with no force direction (class docstring of ``MRAC``).

    Args:
        pos, vel: measured position and velocity; ``r``: target position.
        x_m, v_m: reference-model state (read only).
        omega2, two_zeta_omega: ω² and 2ζω per axis.
        gains: (w_p, w_v, dt, f0, α₁, α₂, β₁, β₂, γ₁, γ₂, K_p0, K_v0).
        ints: (3, n) integrals ∫q, ∫q e, ∫q ė, advanced in place.
        g: (6, n) the reference model's ZOH rows g00, g01, g02, g10, g11, g12.

    Returns:
        ``(a_m, f, K_p, K_v, x_m next, ẋ_m next, (mean K_p, mean K_v, |f|, |x_m − x|,
        |r − x_m|))``, new arrays.
    """
    w_p, w_v, dt, f0, a1, a2, b1, b2, c1, c2, kp0, kv0 = gains
    n = pos.shape[0]
    a_m, f, kp, kv = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    x_next, v_next = np.empty(n), np.empty(n)
    kp_sum = kv_sum = f_sq = err_sq = lag_sq = 0.0
    for i in range(n):
        a_m[i] = omega2[i] * (r[i] - x_m[i]) - two_zeta_omega[i] * v_m[i]
        e = x_m[i] - pos[i]
        ed = v_m[i] - vel[i]
        q = w_p * e + w_v * ed
        ints[0, i] += q * dt
        ints[1, i] += q * e * dt
        ints[2, i] += q * ed * dt
        f[i] = f0 + a1 * ints[0, i] + a2 * q
        kp[i] = kp0 + b1 * ints[1, i] + b2 * q * e
        kv[i] = kv0 + c1 * ints[2, i] + c2 * q * ed
        kp_sum += kp[i]
        kv_sum += kv[i]
        f_sq += f[i] * f[i]
        err_sq += (x_m[i] - pos[i]) * (x_m[i] - pos[i])
        lag_sq += (r[i] - x_m[i]) * (r[i] - x_m[i])
        x_next[i] = g[0, i] * x_m[i] + g[1, i] * v_m[i] + g[2, i] * r[i]
        v_next[i] = g[3, i] * x_m[i] + g[4, i] * v_m[i] + g[5, i] * r[i]
    stats = (kp_sum / n, kv_sum / n, math.sqrt(f_sq), math.sqrt(err_sq), math.sqrt(lag_sq))
    return a_m, f, kp, kv, x_next, v_next, stats
