"""The one causal first-order low-pass used across ccm (metrics and controllers)."""

from __future__ import annotations

import math


def first_order_alpha(dt: float, cutoff_hz: float) -> float:
    """Gain α of ``y_k = y_{k-1} + α (x_k − y_{k-1})``: α = dt / (dt + 1/(2π f_c))."""
    return dt / (dt + 1.0 / (2.0 * math.pi * cutoff_hz))
