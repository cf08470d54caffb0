"""The H-step timing of a forward model in a 1 kHz control loop (seed A Eq. 5–6 with the
model's step = H control periods; :mod:`ccm.learn.mixtures.forward_model` explains the horizon)."""

from __future__ import annotations

import numpy as np

from ccm.core.errors import ConfigError, check_int_positive, check_positive


def horizon_steps(horizon_s: float, control_dt: float, key: str) -> int:
    """The prediction horizon in control steps: ``horizon_s`` must be a whole number (>= 1)
    of control periods, e.g. 0.01 s at 1 kHz -> 10."""
    h = check_positive(key, horizon_s)
    n = round(h / control_dt)
    if n < 1 or abs(n * control_dt - h) > 1e-9 * max(1.0, h):
        raise ConfigError(
            key, f"must be a whole number of control periods ({control_dt:g} s), got {horizon_s!r}"
        )
    return int(n)


class ForecastBuffer:
    """The last H states and the predictions made from them, for an H-step forward model.

    A forward model with horizon H control steps learns X = [S_{t−H}, D_t] and predicts
    D̂_{t+H} = f(S_t) (seed A Eq. 5–6 with the model's step = H control periods). At control
    step t the buffer gives back S_{t−H} and D̂_t (made H steps ago) for the error and the
    learning point, and D̂_{t+1} (made H − 1 steps ago, or now if H = 1) for the feed-forward
    of the command that acts until t + 1. It keeps references, not copies: the caller passes
    arrays it does not modify afterwards (AVIC makes fresh ones every step).

    Args:
        horizon: H >= 1 control steps.
    """

    def __init__(self, horizon: int) -> None:
        self.horizon = check_int_positive("forward_model.horizon", horizon)
        self._states: list[np.ndarray | None] = [None] * self.horizon
        self._preds: list[np.ndarray | None] = [None] * self.horizon
        self._i = 0  # slot of the step about to be pushed: (steps pushed) mod H

    def past(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(S_{t−H}, D̂_t) for the step about to be pushed; None where not available (the
        first H steps of a trial, or no prediction was made then)."""
        return self._states[self._i], self._preds[self._i]

    def push(self, state: np.ndarray, prediction: np.ndarray | None) -> None:
        """Store S_t and D̂_{t+H} = f(S_t) (None: the model could not predict yet)."""
        i = self._i
        self._states[i], self._preds[i] = state, prediction
        self._i = i + 1 if i + 1 < self.horizon else 0

    def next_prediction(self) -> np.ndarray | None:
        """D̂_{t+1} after :meth:`push` of step t: the prediction for the next control step."""
        return self._preds[self._i]

    def forget_predictions(self) -> None:
        """Drop every stored prediction (the model that made them was replaced)."""
        self._preds = [None] * self.horizon
