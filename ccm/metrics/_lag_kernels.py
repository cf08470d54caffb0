"""Numba kernel behind :func:`ccm.metrics.trial.lag_metrics` (seed A §4.2.2's lag).

The readable definition is the docstring of :func:`lag_metrics`: for every candidate delay
k, the mean over samples of ‖x(t_i + k) − x_d(t_i)‖², and the first k with the smallest.
In numpy that is ``np.mean(np.sum(d * d, axis=1))`` per delay: ~500 delays of ~6000 samples
each, ~0.09 s per H1 trial (issue #20), because every delay allocates three temporaries.

The kernel computes the same numbers bit for bit: each row's squares are added in axis order
(numpy's reduction over 2 or 3 columns), and the mean is numpy's pairwise summation
(:func:`pairwise_sum`: blocks of 8 accumulators up to 128 samples, halves above, as in numpy's
``loops_utils.h``) started from the identity 0.0, divided by the count.
``tests/test_metric_pins.py`` checks equality with the numpy loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_BLOCK = 128  #: numpy's PW_BLOCKSIZE


@njit(cache=True)
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's sum of a block of at most 128 elements ``a[lo:lo + n]``: one accumulator below
    8 elements, else 8 accumulators combined in a fixed tree, then the remainder."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
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


@njit(cache=True)
def _half(n: int) -> int:
    """numpy's split of n > 128 elements: the first half, a multiple of 8."""
    n2 = n // 2
    return n2 - n2 % 8


@njit(cache=True)
def pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:
    """The sum of ``a[lo:lo + n]`` in numpy's pairwise order: blocks of at most 128 elements
    (:func:`_block_sum`), and above that sum(first half) + sum(second half) recursively. The
    recursion runs on an explicit stack (numba's cache does not keep self-calling kernels)."""
    if n <= _BLOCK:
        return _block_sum(a, lo, n)
    depth = 64  # halving n > 128 ends within 64 levels for any int64 n
    los = np.empty(depth, np.int64)
    ns = np.empty(depth, np.int64)
    left = np.empty(depth)  # a node's first-half sum, once known
    stage = np.zeros(depth, np.int64)  # 0: first half next, 1: second half next, 2: done
    los[0], ns[0], top, ret = lo, n, 0, 0.0
    while top >= 0:
        n2 = _half(ns[top])
        if stage[top] == 0:  # the first half: a block now, or a child node first
            stage[top] = 1
            if n2 > _BLOCK:
                top += 1
                los[top], ns[top], stage[top] = los[top - 1], n2, 0
                continue
            ret = _block_sum(a, los[top], n2)
        if stage[top] == 1:  # ret holds the first half's sum
            left[top] = ret
            stage[top] = 2
            rlo, rn = los[top] + n2, ns[top] - n2
            if rn > _BLOCK:
                top += 1
                los[top], ns[top], stage[top] = rlo, rn, 0
                continue
            ret = _block_sum(a, rlo, rn)
        ret = left[top] + ret  # stage 2: ret holds the second half's sum
        top -= 1
    return ret


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
