"""The causal low-pass (:func:`ccm.core.filters.lowpass_sequence`) is its recursion, exactly."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.filters import first_order_alpha, lowpass_sequence


def recursion(x: np.ndarray, alpha: float) -> np.ndarray:
    y = np.array(x, dtype=float)
    for k in range(1, len(y)):
        y[k] = y[k - 1] + alpha * (y[k] - y[k - 1])
    return y


@pytest.mark.parametrize("shape", [(2000,), (2000, 3), (1,), (1, 2), (0,), (0, 3)])
def test_lowpass_is_the_first_order_recursion_bit_for_bit(shape: tuple[int, ...]) -> None:
    x = np.random.default_rng(3).normal(size=shape)
    alpha = first_order_alpha(1e-3, 30.0)
    y = lowpass_sequence(x, alpha)
    assert y.shape == x.shape and y.dtype == float
    assert np.array_equal(y, recursion(x, alpha))


def test_lowpass_of_a_step_approaches_it() -> None:
    y = lowpass_sequence(np.r_[0.0, np.ones(999)], 0.01)
    assert y[0] == 0.0 and y[1] == pytest.approx(0.01) and y[-1] == pytest.approx(1.0, abs=1e-4)
