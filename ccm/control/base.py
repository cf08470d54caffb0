"""Controller interface: state in, command out, gains as parameters (polymetis style)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np

from ccm.core.errors import ConfigError, constructor_kwargs
from ccm.core.plugins import accepts_key
from ccm.core.protocols import Pattern
from ccm.core.types import Command, Observation, TargetSample


class Controller(ABC):
    """Maps ``(Observation, TargetSample) -> Command``.

    A controller never sees a simulator handle or ground truth: only the ``Observation``
    (pose, twist, measured wrench, time; on the arm its model's inertia Λ(q)) and the target
    pattern sample. Controllers that
    learn across trials override :meth:`end_trial`, and :meth:`state_dict` /
    :meth:`load_state_dict` so that what they learned can be saved at the end of a run
    and start a later run (``ccm run ... init_from=<run dir>``; JSON, no pickle).
    """

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any], key: str = "controller") -> Self:
        """Build from a plain ``controller`` config mapping: every key must be a constructor
        argument (``type``, ``_target_`` and ``description`` are bookkeeping and ignored).
        ``key``, the config prefix that errors name, is passed only to a constructor that
        takes it: a plugin's needs no ccm-specific parameter."""
        kwargs = constructor_kwargs(cls, cfg, key)
        if accepts_key(cls):
            kwargs["key"] = key
        return cls(**kwargs)

    @property
    def type_name(self) -> str | None:
        """The registry name (``controller.type``) where one class serves several; None: the
        class's own registry entry."""
        return None

    def reset(self, dim: int, control_dt: float) -> None:
        """Prepare for a new trial in a ``dim``-dimensional task space at period ``control_dt``."""
        self.dim = dim
        self.control_dt = control_dt

    @abstractmethod
    def step(self, obs: Observation, target: TargetSample) -> Command:
        """Compute the task-space wrench command for this control step.

        ``obs`` and ``target`` are valid during this call only: the simulator and the pattern
        may update the same objects in place next step, so a controller copies what it
        keeps (:mod:`ccm.core.types`; :func:`ccm.checks.steps.check_keeps_no_views`). The
        returned command is read before the next call."""

    @abstractmethod
    def signals(self) -> dict[str, float]:
        """Internal signals of the last step for logging (stiffness, damping, mode, …).

        Keys carry units (``stiffness_Npm``); the set of keys is fixed for a controller.
        """

    def prepare(
        self, pattern: Pattern, contacts: Sequence[Mapping[str, Any]], rng: np.random.Generator
    ) -> Pattern:
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

    def report(self) -> dict[str, Any]:
        """What the controller believes at the end of a trial, for metrics (called after the
        trial, before :meth:`end_trial`). Plain data; ``{}`` by default."""
        return {}

    def state_dict(self) -> dict[str, Any] | None:
        """What the controller has learned across trials, as JSON-safe data.

        Nested dicts (string keys), lists, strings, bools, ints and finite floats only (numpy
        arrays as lists), so that ``json.loads(json.dumps(state))`` restores it exactly. Only
        cross-trial state belongs here (models, beliefs, counters), never per-trial state
        that :meth:`reset` rebuilds. The settings of the current config are not part of it.

        Returns:
            ``None`` for a controller that does not learn (the default). A learning
            controller returns a dict even before its first trial.
        """
        return None

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output (call between trials, e.g. before the first).

        Settings come from this controller's own config; only what was learned comes from
        ``state``. The controller is unchanged if the state is rejected.

        Raises:
            ConfigError: ``init_from``: this controller does not learn, or ``state`` is
                malformed or does not fit its config.
        """
        raise ConfigError("init_from", f"{type(self).__name__} has no learned state to load")


#: what malformed learned-state data raises while it is parsed (wrapped by :func:`state_error`)
STATE_ERRORS = (ValueError, TypeError, KeyError, IndexError, AttributeError)


def state_error(exc: BaseException) -> ConfigError:
    """A malformed learned state (KeyError, TypeError, ValueError, ...) as a one-line
    ``init_from`` error; a :class:`ConfigError` keeps its own key in the message."""
    if isinstance(exc, ConfigError) and exc.key == "init_from":
        return exc
    if isinstance(exc, KeyError):
        text = f"missing entry {exc.args[0]!r}"
    else:
        text = str(exc) or type(exc).__name__
    return ConfigError("init_from", "invalid learned state: " + " ".join(text.split()))


def check_state_keys(state: Any, keys: Sequence[str]) -> None:
    """``state`` must be a mapping with exactly ``keys`` (ConfigError ``init_from``)."""
    if not isinstance(state, Mapping):
        raise ConfigError(
            "init_from", f"invalid learned state: expected a mapping, got {type(state).__name__}"
        )
    missing = [k for k in keys if k not in state]
    unknown = sorted(str(k) for k in state if k not in keys)
    if missing or unknown:
        raise ConfigError(
            "init_from",
            f"invalid learned state: expected keys {', '.join(keys)}; "
            f"missing {missing or 'none'}, unknown {unknown or 'none'}",
        )
