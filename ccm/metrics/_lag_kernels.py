"""Numba kernel behind :func:`ccm.metrics.trial.lag_metrics` (seed A §4.2.2's lag).

The readable definition is the docstring of :func:`lag_metrics`: for every candidate delay
k, the mean over samples of ‖x(t_i + k) − x_d(t_i)‖², and the first k with the smallest.
In numpy that is ``np.mean(np.sum(d * d, axis=1))`` per delay: ~500 delays of ~6000 samples
each, ~0.09 s per H1 trial (issue #20), because every delay allocates three temporaries.

The kernel computes the same numbers bit for bit: each row's squares are added in axis order
(numpy's reduction over 2 or 3 columns), and the mean is numpy's pairwise summation
(:func:`pairwise_sum`: blocks of 8 accumulators up to 128 samples, halves above, as in numpy's
``loops_utils.h``) started from the identity 0.0, divided by the count.
``tests/test_metrics.py`` checks equality with the numpy loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_BLOCK = 128  #: numpy's PW_BLOCKSIZE


@njit("float64(float64[::1], int64, int64)", cache=True)  # typed: it calls itself
def pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:
    """The sum of ``a[lo:lo + n]`` in numpy's pairwise order (module docstring)."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    if n <= _BLOCK:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        end = lo + n - n % 8
        i = lo + 8
        while i < end:
            r0 += a[i]
            r1 += a[i + 1]
            r2 += a[i + 2]
            r3 += a[i + 3]
            r4 += a[i + 4]
            r5 += a[i + 5]
            r6 += a[i + 6]
            r7 += a[i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < lo + n:
            res += a[i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return pairwise_sum(a, lo, n2) + pairwise_sum(a, lo + n2, n - n2)


@njit(cache=True)
def best_lag_steps(pos: np.ndarray, tgt: np.ndarray, max_shift: int, stride: int) -> int:
    """The delay k ∈ {0, stride, 2 stride, …} ≤ ``max_shift`` [samples] of smallest mean
    squared distance between ``pos[k:]`` and ``tgt[:n − k]`` (the first one on a tie)."""
    n, dim = pos.shape
    rows = np.empty(n)
    best, best_k = np.inf, 0
    for k in range(0, max_shift + 1, stride):
        m = n - k
        for i in range(m):
            s = 0.0
            for j in range(dim):
                d = pos[k + i, j] - tgt[i, j]
                s += d * d
            rows[i] = s
        err = (0.0 + pairwise_sum(rows, 0, m)) / m
        if err < best:
            best, best_k = err, k
    return best_k
