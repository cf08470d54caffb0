"""A simulated human hand on the tool, in any dimension (seed B §3.1, the human force f_h).

The same law as the planar backend's :class:`ccm.sim.pymunk.hri_forces.HumanHand`, written
for n-vectors so that the 3D backend (PyBullet, ``task.scene.human``) can have a hand too:
``F = sat(k (g − p) − c v + n(t))``, with ``g`` the active goal, ``p`` and ``v`` the tool
point's position and velocity, ``n(t)`` a low-pass noise per axis (white Gaussian through a
first-order low-pass at ``noise_cutoff_hz``, stationary std ``noise_std``) and ``sat``
scaling the vector to norm ``max_force``. Over the first ``ramp_s`` the force rises with a
raised cosine. With ``goal_times`` the hand pulls toward ``goals[i]`` from ``goal_times[i]``
on: a goal sequence, a person guiding the tool along a path (``ccm demo``). The planar
backend keeps its own scalar copy of the law, whose float operations its pinned results
rely on.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_keys, check_nonneg, check_positive, to_plain

_KEYS = ("goals", "goal_times", "stiffness", "damping", "max_force", "noise_std",
         "noise_cutoff_hz", "ramp_s")  # fmt: skip


@dataclass(frozen=True)
class HandSpec:
    """A hand guiding the tool (module docstring); lengths in m, forces in N.

    Attributes:
        goals: (G, n) goal positions [m].
        goal_times: (G,) times [s] from which each goal is active, strictly increasing
            from 0.
        stiffness: k [N/m] > 0; damping: c [N s/m] >= 0; max_force: bound [N] > 0.
        noise_std: [N] >= 0; noise_cutoff_hz: [Hz] > 0; ramp_s: rise time [s] >= 0.
    """

    goals: np.ndarray
    goal_times: tuple[float, ...]
    stiffness: float
    max_force: float
    damping: float = 0.0
    noise_std: float = 0.0
    noise_cutoff_hz: float = 5.0
    ramp_s: float = 0.0

    @classmethod
    def from_mapping(cls, cfg: Any, key: str, dim: int) -> HandSpec:
        """Parse ``{goals, goal_times, stiffness, max_force, …}``; errors name ``key``."""
        d = to_plain(cfg, key)
        check_keys(key, d, _KEYS)
        for name in ("goals", "stiffness", "max_force"):
            if d.get(name) is None:
                raise ConfigError(f"{key}.{name}", "is required")
        try:
            goals = np.asarray(d["goals"], dtype=float).reshape(-1, dim)
        except (TypeError, ValueError):
            raise ConfigError(f"{key}.goals", f"must be a list of [{dim} numbers]") from None
        if goals.shape[0] == 0 or not np.all(np.isfinite(goals)):
            raise ConfigError(f"{key}.goals", "must hold at least one finite goal")
        times = tuple(float(t) for t in d.get("goal_times") or [0.0])
        if len(times) != goals.shape[0] or times[0] != 0.0:
            raise ConfigError(f"{key}.goal_times", "needs one time per goal, the first 0")
        if any(b <= a for a, b in zip(times[:-1], times[1:], strict=True)):
            raise ConfigError(f"{key}.goal_times", "must increase strictly")
        return cls(
            goals=goals, goal_times=times,
            stiffness=check_positive(f"{key}.stiffness", d["stiffness"]),
            max_force=check_positive(f"{key}.max_force", d["max_force"]),
            damping=check_nonneg(f"{key}.damping", d.get("damping", 0.0)),
            noise_std=check_nonneg(f"{key}.noise_std", d.get("noise_std", 0.0)),
            noise_cutoff_hz=check_positive(f"{key}.noise_cutoff_hz",
                                           d.get("noise_cutoff_hz", 5.0)),
            ramp_s=check_nonneg(f"{key}.ramp_s", d.get("ramp_s", 0.0)),
        )  # fmt: skip


class Hand:
    """The hand's force, stepped once per physics step (noise: as ``HumanHand``)."""

    def __init__(self, spec: HandSpec, dt: float) -> None:
        self.spec = spec
        self._a = math.exp(-2.0 * math.pi * spec.noise_cutoff_hz * dt)
        self._b = spec.noise_std * math.sqrt(max(0.0, 1.0 - self._a * self._a))
        self._noise = np.zeros(spec.goals.shape[1])
        self._rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator) -> None:
        """Draw the noise's initial state from its stationary distribution."""
        self._rng = rng
        n = self.spec.goals.shape[1]
        std = self.spec.noise_std
        self._noise = rng.normal(0.0, std, n) if std > 0.0 else np.zeros(n)

    def force(self, p: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The hand force [N] at time ``t`` on a tool at ``p`` moving at ``v``."""
        spec = self.spec
        if self._b > 0.0:
            assert self._rng is not None, "Hand.force() before reset()"
            self._noise = self._a * self._noise + self._b * self._rng.standard_normal(
                self._noise.shape[0]
            )
        goal = spec.goals[bisect.bisect_right(spec.goal_times, t) - 1]
        f = spec.stiffness * (goal - p) - spec.damping * v + self._noise
        norm = float(np.linalg.norm(f))
        scale = spec.max_force / norm if norm > spec.max_force else 1.0
        if t < spec.ramp_s:
            scale *= 0.5 * (1.0 - math.cos(math.pi * t / spec.ramp_s))
        return f * scale
