"""The one causal first-order low-pass used across ccm (metrics and controllers)."""

from __future__ import annotations

import math

import numpy as np


def first_order_alpha(dt: float, cutoff_hz: float) -> float:
    """Gain α of ``y_k = y_{k-1} + α (x_k − y_{k-1})``: α = dt / (dt + 1/(2π f_c))."""
    return dt / (dt + 1.0 / (2.0 * math.pi * cutoff_hz))


def lowpass_sequence(x: np.ndarray, alpha: float) -> np.ndarray:
    """``y_k = y_{k-1} + α (x_k − y_{k-1})`` along axis 0, from y_0 = x_0 (causal)."""
    y = np.empty_like(x, dtype=float)
    if len(x) == 0:
        return y
    y[0] = x[0]
    for k in range(1, len(x)):
        y[k] = y[k - 1] + alpha * (x[k] - y[k - 1])
    return y
