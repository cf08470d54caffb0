"""Controller interface: state in, command out, gains as parameters (polymetis style)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np

from ccm.errors import constructor_kwargs
from ccm.types import Command, Observation, TargetSample


class Controller(ABC):
    """Maps ``(Observation, TargetSample) -> Command``.

    A controller never sees a simulator handle or ground truth: only the ``Observation``
    (pose, twist, measured wrench, time) and the target pattern sample. Controllers that
    learn across trials override :meth:`end_trial`.
    """

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any], key: str = "controller") -> Self:
        """Build from a plain ``controller`` config mapping: every key must be a constructor
        argument (``type``/``description`` are bookkeeping and ignored)."""
        return cls(**constructor_kwargs(cls, cfg, key), key=key)  # type: ignore[call-arg]

    def reset(self, dim: int, control_dt: float) -> None:
        """Prepare for a new trial in a ``dim``-dimensional task space at period ``control_dt``."""
        self.dim = dim
        self.control_dt = control_dt

    @abstractmethod
    def step(self, obs: Observation, target: TargetSample) -> Command:
        """Compute the task-space wrench command for this control step."""

    @abstractmethod
    def signals(self) -> dict[str, float]:
        """Internal signals of the last step for logging (stiffness, damping, mode, …).

        Keys carry units (``stiffness_Npm``); the set of keys is fixed for a controller.
        """

    def prepare(
        self, pattern: Any, contacts: Sequence[Mapping[str, Any]], rng: np.random.Generator
    ) -> Any:
        """Called at the start of each trial, after :meth:`reset`, with the planned target
        pattern P, the task's *expected* contacts (nominal positions, standing in for a
        vision system; never the scene) and a seeded generator for estimate noise.

        Returns the pattern the runner samples this trial (it must offer ``sample(t)`` and
        ``duration`` in wall time). The default follows P as planned; a controller that
        anticipates contacts returns a re-timed P (seed A §3.5.2).
        """
        return pattern

    def end_trial(self) -> None:  # noqa: B027 - optional hook
        """Called after each trial; learning controllers update cross-trial state here."""
