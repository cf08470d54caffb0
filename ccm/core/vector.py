"""``np.mean`` and ``np.linalg.norm`` of a 1-D float64 vector, for per-step code, and
:func:`readonly`.

The same arithmetic as numpy's functions (``np.add.reduce`` then a division by the count;
``sqrt(x · x)``), so the same bits, without their Python wrappers: ~1 µs instead of ~4 µs
a call, several of which run every control step (issue #20). ``tests/test_step_helpers.py``
checks equality with numpy.
"""

from __future__ import annotations

import math

import numpy as np


def mean(x: np.ndarray) -> float:
    """``float(np.mean(x))`` of a 1-D float64 array."""
    return float(np.add.reduce(x)) / x.shape[0]


def norm(x: np.ndarray) -> float:
    """``float(np.linalg.norm(x))`` of a 1-D float64 array (Euclidean)."""
    return math.sqrt(float(x.dot(x)))


def readonly(arr: np.ndarray) -> np.ndarray:
    """``arr`` itself, made read-only (a view stays read-only whatever its base's flags: the
    step objects' arrays, which only their owner writes through the base)."""
    arr.setflags(write=False)
    return arr
