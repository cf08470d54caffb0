"""Checks and derived values of the :class:`ccm.learn.mixtures.igmm.IGMM` settings.

The novelty threshold of Engel & Heinen (2010), parametrised by a chi-square quantile (see
:mod:`ccm.learn.mixtures.igmm`), and the per-feature standard deviation of a new component.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ccm.core.errors import ConfigError

__all__ = ["check_sigma", "chi2_quantile"]


def chi2_quantile(q: float, dof: int) -> float:
    """Quantile ``q`` of the chi-square distribution with ``dof`` degrees of freedom."""
    from scipy.special import gammaincinv  # lazy: keep `import ccm.learn.mixtures.igmm` light

    return float(2.0 * gammaincinv(0.5 * dof, q))


def check_sigma(name: str, value: Any, d: int) -> np.ndarray:
    """``sigma_init`` as one positive standard deviation per feature.

    Args:
        name: Configuration key for the error message (``f"{key}.sigma_init"``).
        value: A positive number (used for every feature) or ``d`` of them.
        d: Number of features.

    Returns:
        Shape (d,), float64.

    Raises:
        ConfigError: ``value`` is not a positive finite number or ``d`` of them.
    """
    if isinstance(value, bool):
        raise ConfigError(name, f"must be a positive number or {d} of them, got {value!r}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(
            name, f"must be a positive number or {d} of them, got {value!r}"
        ) from None
    if arr.ndim == 0:
        arr = np.full(d, float(arr))
    if arr.shape != (d,):
        raise ConfigError(name, f"must be a positive number or {d} of them, got {value!r}")
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise ConfigError(name, f"must be finite and > 0, got {value!r}")
    return arr
