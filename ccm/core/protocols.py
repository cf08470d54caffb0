"""The contracts that parts of ccm agree on without sharing a base class (issue #21).

A controller is given a target pattern; AVIC holds a forward model; the runner calls the
extra metrics an experiment names. Each of these was only implied (``Any``); these
``typing.Protocol`` classes say what each side may rely on. They are structural: an object
satisfies one by having the attributes, no registration or inheritance needed.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ccm.core.types import TargetSample


@runtime_checkable
class Pattern(Protocol):
    """A target motion P (seed A §3.2): what the runner samples every control step.

    ``duration`` is the pattern's length in wall time [s]; a re-timing controller may change
    it during a trial (:meth:`ccm.control.base.Controller.prepare`).
    """

    duration: float

    def sample(self, t: float) -> TargetSample:
        """The target at time ``t`` [s] since the trial's start."""
        ...


@runtime_checkable
class ForwardModel(Protocol):
    """A learned forward model D_{t+H} = f(S_t) (seed A Eq. 5-6), as AVIC uses it.

    ``update`` revises it with one pair (X_t = [S_{t-1}, D_t]); ``predict`` gives the
    effect vector expected from a state (None until the model can predict). The state
    round-trips through JSON-ready dicts.
    """

    horizon_s: float

    @property
    def ready(self) -> bool:
        """Whether :meth:`predict` has a model to predict with."""
        ...

    def update(self, s_prev: np.ndarray, d_now: np.ndarray) -> None:
        """Learn from the state ``s_prev`` and the effect ``d_now`` it led to."""
        ...

    def predict(self, s: np.ndarray) -> np.ndarray | None:
        """The expected effect of state ``s`` one horizon ahead."""
        ...

    def end_trial(self) -> None:
        """A trial ended (a batch learner fits here; an incremental one does nothing)."""
        ...

    def state_dict(self) -> dict[str, Any]:
        """The learned state as JSON-ready data."""
        ...

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output."""
        ...


class Metric(Protocol):
    """An extra metric an experiment names in ``experiment.metrics``
    (:data:`ccm.metrics.trial.EXTRA_METRICS`): one trial's log in, named values out (None where
    the trial gives the metric nothing to measure)."""

    def __call__(
        self, log: Mapping[str, np.ndarray], dim: int, params: Mapping[str, Any]
    ) -> dict[str, float | None]: ...
