"""Filters used across ccm (metrics and controllers): the one causal first-order low-pass and
the one zero-phase FFT split into low and high frequencies."""

from __future__ import annotations

import math

import numpy as np

from ccm.core._filter_kernels import lowpass_rows


def first_order_alpha(dt: float, cutoff_hz: float) -> float:
    """Gain α of ``y_k = y_{k-1} + α (x_k − y_{k-1})``: α = dt / (dt + 1/(2π f_c))."""
    return dt / (dt + 1.0 / (2.0 * math.pi * cutoff_hz))


def lowpass_sequence(x: np.ndarray, alpha: float) -> np.ndarray:
    """``y_k = y_{k-1} + α (x_k − y_{k-1})`` along axis 0, from y_0 = x_0 (causal); compiled
    (:func:`ccm.core._filter_kernels.lowpass_rows`)."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return np.empty_like(x)
    rows = np.ascontiguousarray(x.reshape(len(x), -1))
    return lowpass_rows(rows, float(alpha)).reshape(x.shape)


def lowpass(x: np.ndarray, dt: float, cutoff_hz: float) -> np.ndarray:
    """Causal first-order low-pass along axis 0: y_k = y_{k-1} + α (x_k − y_{k-1}).

    α = dt / (dt + 1/(2π f_c)). One documented filter, used for every condition, stands in for
    the velocity filtering a robot applies to encoder-derived velocities.
    """
    return lowpass_sequence(x, first_order_alpha(dt, cutoff_hz))


def derivatives(vel: np.ndarray, dt: float, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Acceleration and jerk from a velocity series: low-pass velocity, then finite differences.

    Args:
        vel: (T, n) velocities [m/s] sampled every ``dt``.
        cutoff_hz: low-pass cut-off applied to velocity and again to acceleration.

    Returns:
        acc (T, n) [m/s²] and jerk (T, n) [m/s³]; the first sample of each is 0.
    """
    v = lowpass(vel, dt, cutoff_hz)
    acc = np.zeros_like(v)
    acc[1:] = np.diff(v, axis=0) / dt
    acc = lowpass(acc, dt, cutoff_hz)
    jerk = np.zeros_like(acc)
    jerk[1:] = np.diff(acc, axis=0) / dt
    return acc, jerk


def fft_split(x: np.ndarray, dt: float, f_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-phase split of ``x`` (1-D) into the parts below and above ``f_hz`` (FFT mask).

    The signal is mirrored before the FFT (even extension), so its two ends do not meet in a
    jump that the mask would turn into ringing (a press ending at 15 N next to a start at
    0 N)."""
    n = len(x)
    ext = np.concatenate([x, x[::-1]])
    spec = np.fft.rfft(ext)
    freqs = np.fft.rfftfreq(2 * n, dt)
    low = np.fft.irfft(np.where(freqs < f_hz, spec, 0.0), n=2 * n)[:n]
    return low, x - low
