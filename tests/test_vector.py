"""``ccm.core.vector``: numpy's mean and norm of a vector, bit for bit, without the wrappers."""

from __future__ import annotations

import numpy as np

from ccm.core import vector


def test_mean_and_norm_equal_numpy_bit_for_bit() -> None:
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 7, 9, 130):
        for _ in range(200):
            x = rng.normal(size=n) * 10.0 ** rng.integers(-6, 6)
            assert vector.mean(x) == float(np.mean(x))
            assert vector.norm(x) == float(np.linalg.norm(x))
    row = np.arange(12.0).reshape(4, 3)[2]  # a row view, as BAC passes its profiles' rows
    assert vector.mean(row) == float(np.mean(row)) and vector.norm(row) == np.linalg.norm(row)
