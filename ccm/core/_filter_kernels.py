"""Compiled loop of :func:`ccm.core.filters.lowpass_sequence` (issue #20): the recursion runs over
every sample of a trial (up to ~10⁵) and cost ~16 ms per call as a Python loop."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def lowpass_rows(x: np.ndarray, alpha: float) -> np.ndarray:
    """``y_k = y_{k-1} + α (x_k − y_{k-1})`` down the rows of ``x`` (n, m), ``y_0 = x_0``."""
    y = np.empty_like(x)
    if x.shape[0] == 0:
        return y
    y[0] = x[0]
    for k in range(1, x.shape[0]):
        for j in range(x.shape[1]):
            y[k, j] = y[k - 1, j] + alpha * (x[k, j] - y[k - 1, j])
    return y
