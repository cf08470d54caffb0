"""Small statistics shared by the report and the suite: the mean of a few seeds' numbers and
its 95 % Student-t interval."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

# two-sided 95 % Student-t quantiles for 1..30 degrees of freedom (larger: normal 1.96)
_T95 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179,
        2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064,
        2.060, 2.056, 2.052, 2.048, 2.045, 2.042)  # fmt: skip


def t95(n: int) -> float:
    """Two-sided 95 % Student-t quantile for the mean of ``n`` samples (NaN if n < 2)."""
    if n < 2:
        return math.nan
    return _T95[n - 2] if n - 1 <= len(_T95) else 1.96


def mean_ci(x: Sequence[float]) -> tuple[float, float]:
    """Mean and 95 % t-interval half-width; one value: no interval (NaN)."""
    arr = np.asarray(x, dtype=float)
    if arr.size < 2:
        return float(arr.mean()), math.nan
    return float(arr.mean()), float(t95(arr.size) * arr.std(ddof=1) / math.sqrt(arr.size))
