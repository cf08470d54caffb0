"""What starts contact-mode detection, and what it classifies (seed A §3.2, Algorithm 1).

* :class:`TransitionTrigger` - the "mode transition detected" test of Algorithm 1, line 2: a
  sudden, significant change in the force-torque measurements.
* :func:`mode_features` - the task features of §3.2: ``||F||/R`` (Eq. 7) and
  ``[||tau||/R, ||F||/R]``, which :class:`ccm.learn.contact.modes.ModeClassifier` clusters.
"""

from __future__ import annotations

import statistics
from collections import deque
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_choice,
    check_finite,
    check_int_nonneg,
    check_int_positive,
    check_nonneg,
    check_positive,
)

FEATURE_KINDS: tuple[str, ...] = ("force_ratio", "torque_force_ratio")


class TransitionTrigger:
    """Detects a sudden change in a scalar wrench feature (seed A, Algorithm 1, line 2).

    Rule: the reference is the median of the last ``window`` values. Update ``x_t`` fires when
    the reference window is full and ``|x_t - median| > threshold_N``. On firing, the window is
    cleared, so the reference is rebuilt from post-transition samples only, and the trigger
    stays silent for ``max(window, refractory_steps)`` further updates (``window`` to refill
    the reference, ``refractory_steps`` e.g. to cover the high-stiffness batch collection).
    A clean step change therefore fires exactly once, at its first sample. The median makes
    the reference robust to isolated spikes; a single spike above threshold still fires
    (seed A, Algorithm 1: such an anomaly is then classified as the current mode).

    Args:
        threshold_N: Firing threshold on ``|x_t - median|``, in the units of the feature
            (newtons for a force magnitude). Must be > 0.
        window: Number of past values in the median reference, >= 1.
        refractory_steps: Minimum number of updates after a firing before the next one can
            fire, >= 0. ``None`` means ``window``.
        key: Configuration key used as the prefix of error messages.

    Raises:
        ConfigError: On an invalid argument, named ``f"{key}.<arg>"``.
    """

    def __init__(
        self,
        threshold_N: float,
        window: int,
        refractory_steps: int | None = None,
        key: str = "controller.modes.trigger",
    ) -> None:
        self.key = key
        self.threshold_N = check_positive(f"{key}.threshold_N", threshold_N)
        self.window = check_int_positive(f"{key}.window", window)
        self.refractory_steps = (
            self.window
            if refractory_steps is None
            else check_int_nonneg(f"{key}.refractory_steps", refractory_steps)
        )
        self.reset()

    def reset(self) -> None:
        """Forget all past values (as after construction)."""
        self._buf: deque[float] = deque(maxlen=self.window)
        self._silent = 0

    def update(self, wrench_feature: float) -> bool:
        """Feed one measurement; return ``True`` if it marks a contact transition.

        Args:
            wrench_feature: Scalar wrench feature, e.g. the force magnitude in N.

        Returns:
            Whether this update fires.

        Raises:
            ConfigError: If ``wrench_feature`` is not a finite number.
        """
        x = check_finite(f"{self.key}.wrench_feature", wrench_feature)
        if self._silent > 0:
            self._silent -= 1
            self._buf.append(x)
            return False
        if len(self._buf) < self.window:
            self._buf.append(x)
            return False
        if abs(x - statistics.median(self._buf)) > self.threshold_N:
            self._buf.clear()
            self._buf.append(x)
            self._silent = max(self.refractory_steps, self.window) - 1
            return True
        self._buf.append(x)
        return False


def _vector(key: str, value: Any) -> np.ndarray:
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise ConfigError(key, f"must be a vector of 1 to 3 numbers, got {value!r}") from None
    if arr.ndim != 1 or not 1 <= arr.shape[0] <= 3:
        raise ConfigError(key, f"must be a vector of 1 to 3 numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, "must be finite")
    return arr


def mode_features(
    force: np.ndarray,
    torque: np.ndarray | None,
    normal_force: float,
    kind: str,
    *,
    min_normal_force: float = 1e-6,
    key: str = "controller.modes.features",
) -> np.ndarray:
    """Mode feature vector of seed A §3.2.

    ``"force_ratio"``: ``[||F|| / R]`` (Eq. 7), an estimate of the friction coefficient, so
    the mode does not depend on how hard the robot presses. ``"torque_force_ratio"``:
    ``[||tau|| / R, ||F|| / R]`` for tasks where contact types (edge, face) differ.

    ``F`` in Eq. 7 is the friction force, so the caller passes the *tangential* component of
    the end-effector force (in the sliding plane), not the full wrench force; ``R`` is the
    normal force, used as ``|R|`` so either sign convention works. Only its norm is used,
    which makes the feature independent of the sliding direction.

    Args:
        force: Tangential force vector (1 to 3 components), N.
        torque: Torque vector (1 to 3 components; a scalar in 2-D), N m. Ignored, and may
            be ``None``, for ``"force_ratio"``.
        normal_force: Normal force R, N.
        kind: ``"force_ratio"`` or ``"torque_force_ratio"``.
        min_normal_force: If ``|R| < min_normal_force`` (out of contact) the ratio is
            undefined and a NaN vector is returned instead of raising, so a control loop
            never stops here; :meth:`ModeClassifier.classify` rejects NaN batches. The
            caller should compute features only in contact.
        key: Configuration key used as the prefix of error messages.

    Returns:
        Feature vector of length 1 (``"force_ratio"``) or 2 (``"torque_force_ratio"``).

    Raises:
        ConfigError: On an unknown ``kind`` or non-finite / misshaped inputs.
    """
    kind = check_choice(f"{key}.kind", kind, FEATURE_KINDS)
    f = _vector(f"{key}.force", force)
    r = abs(check_finite(f"{key}.normal_force", normal_force))
    eps = check_nonneg(f"{key}.min_normal_force", min_normal_force)
    if r < eps or r == 0.0:
        return np.full(1 if kind == "force_ratio" else 2, np.nan)
    if kind == "force_ratio":
        return feature_vector(float(np.linalg.norm(f)), 0.0, r, kind)
    tau = _vector(f"{key}.torque", torque)
    return feature_vector(float(np.linalg.norm(f)), float(np.linalg.norm(tau)), r, kind)


def feature_vector(
    force_norm: float, torque_norm: float, normal_force: float, kind: str
) -> np.ndarray:
    """The arithmetic of :func:`mode_features` without validation, for a control loop that has
    checked its inputs: ``[‖F‖/R]`` (Eq. 7) or ``[‖τ‖/R, ‖F‖/R]``, with ``R > 0``."""
    if kind == "force_ratio":
        return np.array([force_norm / normal_force])
    return np.array([torque_norm / normal_force, force_norm / normal_force])
