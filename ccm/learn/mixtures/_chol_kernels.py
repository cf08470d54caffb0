"""Small dense linear algebra for the mixture kernels (:mod:`ccm.learn.mixtures._igmm_kernels`,
:mod:`ccm.learn.mixtures._gmr_kernels`): Cholesky factors, log-determinants and squared
Mahalanobis distances on preallocated buffers, and the numba options all of them compile with.

Small dense Cholesky factorisations and triangular solves are written out by hand: for
d <= 8 they are much faster than calling LAPACK through ``np.linalg``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


@njit(**_JIT)
def chol_into(a, out):
    """Lower Cholesky factor of ``a`` into ``out`` (zeros above); returns log det or NaN."""
    n = a.shape[0]
    prod = 1.0
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= out[j, k] * out[j, k]
        if not s > 0.0:
            return np.nan
        ljj = math.sqrt(s)
        out[j, j] = ljj
        prod *= ljj
        inv = 1.0 / ljj
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= out[i, k] * out[j, k]
            out[i, j] = s * inv
        for i in range(j):
            out[i, j] = 0.0
    # one logarithm instead of n; sum of logs if the product under- or overflows
    if 1e-280 < prod < 1e280:
        return 2.0 * math.log(prod)
    acc = 0.0
    for j in range(n):
        acc += math.log(out[j, j])
    return 2.0 * acc


@njit(**_JIT)
def factor_with_floor(c, out, floor):
    """Cholesky of covariance ``c`` with a safety net; returns (log det, jitter used).

    The IGMM update keeps every eigenvalue >= ``floor`` by construction; rounding can still
    break a factorisation when ``floor`` is tiny relative to the scale of ``c``. Then the
    diagonal of ``c`` is raised (in place) by ``floor``, 2 ``floor``, 4 ``floor``, ... until
    the factorisation succeeds.
    """
    logdet = chol_into(c, out)
    if not math.isnan(logdet):
        return logdet, False
    n = c.shape[0]
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(c[i, i]))
    add = max(floor, 1e-15 * scale)
    for _ in range(200):
        for i in range(n):
            c[i, i] += add
        logdet = chol_into(c, out)
        if not math.isnan(logdet):
            return logdet, True
        add *= 2.0
    return np.nan, True


@njit(**_JIT)
def maha_sq(x, mu, chol, e, z):
    """Squared Mahalanobis distance of ``x`` to ``mu`` under ``chol @ chol.T``.

    Leaves ``e = x - mu`` and ``z = chol^-1 e`` in the work vectors.
    """
    n = x.shape[0]
    for i in range(n):
        e[i] = x[i] - mu[i]
    acc = 0.0
    for i in range(n):
        s = e[i]
        for k in range(i):
            s -= chol[i, k] * z[k]
        s /= chol[i, i]
        z[i] = s
        acc += s * s
    return acc
