"""Numba kernels behind :meth:`ccm.tasks.motion_pattern.MotionPattern.sample` (the per-step path).

The readable definitions stay in :mod:`ccm.tasks.segments` (``min_jerk`` and each
segment's ``_coeffs``); the kernels here repeat the same arithmetic, operation for operation,
so that a sample is what ``np.array(seg._coeffs(t)) @ seg._basis`` gives, in one compiled
call instead of a Python list, an array conversion and a matrix product (~2-3 µs of a 1 ms
control step).

numpy's matrix product (OpenBLAS) accumulates ``C @ B`` with fused multiply-adds,
``fma(c2, b2, fma(c1, b1, c0 b0))``; :func:`_fma` issues the same LLVM ``fma`` (one rounding,
also where the CPU has no FMA unit), so the kernels agree with it bit for bit on such a BLAS
and within one ulp on any other (``tests/test_trajectory.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def _fma(typingctx, a, b, c):  # type: ignore[no-untyped-def]  # noqa: ARG001 - numba's API
    """``a * b + c`` with one rounding (LLVM's ``llvm.fma.f64``), for numba code."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]  # noqa: ARG001
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True)
def _dot3(c0: float, c1: float, c2: float, b0: float, b1: float, b2: float) -> float:
    """c0 b0 + c1 b1 + c2 b2 accumulated as numpy's matrix product does (module docstring)."""
    return _fma(c2, b2, _fma(c1, b1, c0 * b0))


@njit(cache=True)
def _min_jerk(tau: float, duration: float) -> tuple[float, float, float]:
    """s, ds/dt, d²s/dt² of :func:`~ccm.tasks.segments.min_jerk`, operation for operation."""
    tau2 = tau * tau
    one_minus = 1.0 - tau
    s = tau2 * tau * (10.0 + tau * (6.0 * tau - 15.0))
    sd = 30.0 * tau2 * one_minus * one_minus / duration
    sdd = 60.0 * tau * one_minus * (1.0 - 2.0 * tau) / (duration * duration)
    return s, sd, sdd


@njit(cache=True)
def line_eval(t_local: float, duration: float, basis: np.ndarray) -> np.ndarray:
    """``C(t) @ B`` of a min-jerk :class:`~ccm.tasks.segments.LineSegment`: rows position,
    velocity, acceleration, shape (3, n); ``C(t)`` = [[1 − s, s], [−ṡ, ṡ], [−s̈, s̈]] and
    ``B`` = [start, end], each entry accumulated as numpy's product does (two terms:
    ``fma(c1, b1, c0 b0)``)."""
    s, sd, sdd = _min_jerk(t_local / duration, duration)
    n = basis.shape[1]
    out = np.empty((3, n))
    for j in range(n):
        b0, b1 = basis[0, j], basis[1, j]
        out[0, j] = _fma(s, b1, (1.0 - s) * b0)
        out[1, j] = _fma(sd, b1, -sd * b0)
        out[2, j] = _fma(sdd, b1, -sdd * b0)
    return out


@njit(cache=True)
def arc_eval(t_local: float, duration: float, sweep: float, basis: np.ndarray) -> np.ndarray:
    """``C(t) @ B`` of :class:`~ccm.tasks.segments.ArcSegment`: rows position, velocity,
    acceleration, shape (3, n).

    θ = sweep · s(τ) with the min-jerk s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (:func:`min_jerk`), and
    ``B`` = [fixed offset, radius vector at θ = 0, its 90° rotation], so
    p = B₀ + cos θ B₁ + sin θ B₂, ṗ = θ̇ (−sin θ B₁ + cos θ B₂),
    p̈ = (−θ̈ sin θ − θ̇² cos θ) B₁ + (θ̈ cos θ − θ̇² sin θ) B₂.
    """
    s, sd, sdd = _min_jerk(t_local / duration, duration)
    th, thd, thdd = sweep * s, sweep * sd, sweep * sdd
    c, si = math.cos(th), math.sin(th)
    thd2 = thd * thd
    # the coefficient matrix C(t), 3 × 3, as in ArcSegment._coeffs
    c10, c11, c12 = 0.0, -thd * si, thd * c
    c20, c21, c22 = 0.0, -thdd * si - thd2 * c, thdd * c - thd2 * si
    n = basis.shape[1]
    out = np.empty((3, n))
    for j in range(n):
        b0, b1, b2 = basis[0, j], basis[1, j], basis[2, j]
        out[0, j] = _dot3(1.0, c, si, b0, b1, b2)
        out[1, j] = _dot3(c10, c11, c12, b0, b1, b2)
        out[2, j] = _dot3(c20, c21, c22, b0, b1, b2)
    return out
