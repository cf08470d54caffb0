"""α of seed B's disturbance model (Eq. 16-17), estimated from the demonstrations' measured force.

Seed B §4.2.3 models the process force as F^d(s) = α s / (s + ω_p): a high-pass with gain α
above the cut-off ω_p, "distinguishing from lower-frequency human input". Seed B gives no
value for α. ccm estimates it from what the controller has, the F/T sensor's measured force
during the demonstrations (the robot renders a fixed admittance while the human guides it
and the disturbance acts), not from the simulator's truth:

    α̂ = √2 · sqrt( mean over demonstrations and axes of  mean_t f_hp,i(t)² ),

where f_hp,i is demonstration i's measured force on one axis above f_c = ω_p / 2π, split off
by the zero-phase FFT mask of :func:`ccm.core.filters.fft_split`. α̂ is the amplitude of a sinusoid
with the measured high-frequency RMS: for a spindle force a·sin(ωt) with ω > ω_p alone it is
a. Everything the sensor measures above f_c counts, the sensor's own noise and the human's
tremor included: to the admittance loop, which is driven by the measured force, these are
high-frequency disturbances as much as the spindle is. Known leak: a low-frequency force
whose slope is not zero at the ends of a record puts a kink into the split's even extension,
which counts above f_c (a few % of its amplitude for a 1 N line at 8 Hz over 4 s;
``tests/test_disturbance_estimate.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ccm.core.errors import ConfigError, check_positive
from ccm.core.filters import fft_split


def high_freq_power(force: np.ndarray, dt: float, split_hz: float) -> np.ndarray:
    """Mean square per axis of the measured force above ``split_hz`` (one demonstration).

    Args:
        force: measured force, shape (T, n) [N], sampled every ``dt`` [s].
        dt: sample period [s] > 0.
        split_hz: the high-pass split f_c [Hz] > 0 (ω_p / 2π of Eq. 16).

    Returns:
        (n,) mean of f_hp,i(t)² per axis [N²].
    """
    check_positive("disturbance_estimate.dt", dt)
    check_positive("disturbance_estimate.split_hz", split_hz)
    f = np.asarray(force, dtype=float)
    if f.ndim != 2 or f.shape[0] < 2:
        raise ConfigError("disturbance_estimate.force", f"needs shape (T >= 2, n), got {f.shape}")
    return np.array([np.mean(fft_split(f[:, i], dt, split_hz)[1] ** 2) for i in range(f.shape[1])])


def alpha_from_power(powers: Sequence[np.ndarray]) -> float:
    """α̂ = √2 · sqrt(mean of the per-demonstration, per-axis powers) (module docstring).

    Raises ConfigError without any demonstration, or when the measured force has no
    high-frequency content at all (α̂ = 0 would switch the Eq. 16 cost off silently).
    """
    if not powers:
        raise ConfigError("mpc.disturbance.alpha", "estimating α needs at least one demonstration")
    mean_sq = float(np.mean(np.concatenate([np.ravel(p) for p in powers])))
    if not math.isfinite(mean_sq) or mean_sq <= 0.0:
        raise ConfigError(
            "mpc.disturbance.alpha",
            f"the demonstrations' measured force has no content above the split ({mean_sq!r} N²)",
        )
    return math.sqrt(2.0 * mean_sq)
