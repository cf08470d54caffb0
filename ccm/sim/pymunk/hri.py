"""Scene elements for physical human-robot interaction (seed B, Haninger et al.).

Three external forces on the end-effector, parsed like the rest of the scene vocabulary
(:mod:`ccm.sim.pymunk.scene`): every invalid value raises :class:`ccm.core.errors.ConfigError`
naming the full dotted key, e.g. ``task.scene.human.max_force``. The force laws live in
:mod:`ccm.sim.pymunk.hri_forces`. All three act on the end-effector's centre (the tool-centre
point) and are measured by the single F/T sensor, which sees ``f = f_h + f_c + f_d``
(seed B §3.1):

* :class:`CompliantWallSpec` (``compliant_walls``): a unilateral spring-damper contact, the
  environment with a compliant element of seed B §5.3/§6.1 (15, 45, 126 N/mm; contact
  position varied by ±1 cm). ``f_c``.
* :class:`HumanSpec` (``human``): a simulated hand pulling the tool toward one of several
  goals with a bounded, noisy PD force (seed B §3.1 human force ``f_h``, §4.1 discrete
  human goals). ``f_h``.
* :class:`VibrationSpec` (``vibration``): a sinusoidal polishing-spindle disturbance
  (seed B §3.1, §6.3: predominantly high-frequency). ``f_d``.

The parsing helpers and the region shape come from :mod:`ccm.sim.pymunk.parse`, which
:mod:`ccm.sim.pymunk.scene` shares.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from ccm.core.errors import ConfigError, check_nonneg, check_positive
from ccm.core.fields import checked, field_values, nested, unchecked
from ccm.sim.pymunk.parse import RegionSpec, Vec2, as_list, nonneg_vec2, vec2


def unit_vec2(key: str, value: Any) -> Vec2:
    """A non-zero 2-vector, normalised."""
    nx, ny = vec2(key, value)
    norm = math.hypot(nx, ny)
    if norm < 1e-9:
        raise ConfigError(key, f"must be a non-zero vector, got {value!r}")
    return (nx / norm, ny / norm)


def _goals(key: str, value: Any) -> tuple[Vec2, ...]:
    """At least one goal [x, y] [m]."""
    goals = tuple(vec2(f"{key}[{i}]", g) for i, g in enumerate(as_list(key, value)))
    if not goals:
        raise ConfigError(key, "must hold at least one goal [x, y]")
    return goals


@dataclass(frozen=True)
class CompliantWallSpec:
    """A unilateral compliant contact acting on the end-effector centre (seed B §6.1).

    The wall surface is the line through ``point`` (shifted by ``offset`` along ``normal``)
    perpendicular to ``normal``; the wall occupies the half-plane behind it. With ``p`` the EE
    centre and ``v`` its velocity, the penetration is ``d = (point + offset n - p) . n``. For
    ``d > 0`` the force on the EE is ``F n`` with ``F = max(0, k d - c v . n)``: a spring-damper
    that never pulls. Each reset draws ``offset`` uniformly from ``[-j, j]`` (seed B §6.1,
    "higher variance (±1 cm)"); ``offset = 0`` when ``j = 0``.

    Attributes:
        point: a point on the wall surface [m].
        normal: unit normal from the wall into free space. Any non-zero vector is accepted and
            normalised; a (near-)zero vector is rejected.
        stiffness: k [N/m] > 0 (seed B §5.3: 15e3, 45e3, 126e3).
        damping: c [N s/m] >= 0 (default 0).
        position_jitter_m: j [m] >= 0 (default 0).
    """

    point: Vec2 = checked(vec2)
    normal: Vec2 = checked(unit_vec2)
    stiffness: float = checked(check_positive)
    damping: float = checked(check_nonneg, 0.0)
    position_jitter_m: float = checked(check_nonneg, 0.0)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> CompliantWallSpec:
        return cls(**field_values(cls, cfg, key)[0])


@dataclass(frozen=True)
class HumanSpec:
    """A simulated human hand holding the tool: a bounded, noisy PD pull toward a goal.

    The hand force is ``F = sat(k (g - p) - c v + n(t))`` with ``g`` the active goal, ``p``
    and ``v`` the EE centre's position and velocity, ``n(t)`` a low-frequency noise (per axis,
    white Gaussian through a first-order low-pass at ``noise_cutoff_hz``, stationary std
    ``noise_std``) and ``sat`` scaling the vector down to norm ``max_force``. ``F = 0`` for
    ``t < active_after_s``; over the next ``ramp_s`` it is scaled by the raised cosine
    ``(1 - cos(pi (t - active_after_s) / ramp_s)) / 2`` (a human's force builds up over a
    few hundred ms, it does not step).

    Attributes:
        goals: candidate goals ``[[x, y], ...]`` [m], at least one (seed B §4.1: discrete
            human goals).
        goal_index: index of the active goal, or -1 to draw it uniformly at each reset.
        stiffness: k [N/m] > 0; damping: c [N s/m] >= 0 (default 0).
        max_force: bound on the norm of the hand force [N] > 0.
        noise_std: stationary std of the noise per axis [N] >= 0 (default 0).
        noise_cutoff_hz: cut-off of the noise low-pass [Hz] > 0 (default 5.0).
        active_after_s: the hand force is zero before this time [s] >= 0 (default 0).
        ramp_s: rise time of the force after ``active_after_s`` [s] >= 0 (default 0: a step).
        goal_times: optional times [s], one per goal, strictly increasing from 0: the hand
            then pulls toward ``goals[i]`` from ``goal_times[i]`` on, a goal *sequence* (a
            human guiding the tool along a path, ``ccm demo``); ``goal_index`` must be 0.
    """

    goals: tuple[Vec2, ...] = checked(_goals)
    stiffness: float = checked(check_positive)
    max_force: float = checked(check_positive)
    goal_index: int = checked(unchecked, 0)  # checked against the goals in from_mapping
    damping: float = checked(check_nonneg, 0.0)
    noise_std: float = checked(check_nonneg, 0.0)
    noise_cutoff_hz: float = checked(check_positive, 5.0)
    active_after_s: float = checked(check_nonneg, 0.0)
    ramp_s: float = checked(check_nonneg, 0.0)
    goal_times: tuple[float, ...] | None = checked(unchecked, None)  # checked in from_mapping

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> HumanSpec:
        spec = cls(**field_values(cls, cfg, key)[0])
        idx, n = spec.goal_index, len(spec.goals)
        if isinstance(idx, bool) or not isinstance(idx, int) or not -1 <= idx < n:
            raise ConfigError(
                f"{key}.goal_index",
                f"must be an integer in [0, {n - 1}] or -1 (random), got {idx!r}",
            )
        times = _goal_times(f"{key}.goal_times", spec.goal_times, n, idx)
        return dataclasses.replace(spec, goal_times=times)


def _goal_times(key: str, value: Any, n_goals: int, goal_index: int) -> tuple[float, ...] | None:
    """``HumanSpec.goal_times``: one time per goal, from 0, strictly increasing."""
    if value is None:
        return None
    times = tuple(float(check_nonneg(f"{key}[{i}]", v)) for i, v in enumerate(as_list(key, value)))
    if len(times) != n_goals or times[0] != 0.0 or goal_index != 0:
        raise ConfigError(
            key, f"needs one time per goal ({n_goals}), the first 0, and goal_index 0"
        )
    if any(b <= a for a, b in zip(times[:-1], times[1:], strict=True)):
        raise ConfigError(key, "must increase strictly")
    return times


@dataclass(frozen=True)
class VibrationSpec:
    """A polishing-spindle disturbance ``f_d(t)`` (seed B §3.1, §6.3).

    Per axis ``i``: ``f_i(t) = a_i sin(2 pi f t + phi_i) + noise_std * w_i`` with phases
    ``phi_i`` drawn uniformly in ``[0, 2 pi)`` at each reset and ``w_i`` white standard normal
    per physics step. With a ``region`` the force is zero while the EE centre is outside it.

    Attributes:
        amplitude: ``[a_x, a_y]`` [N], each >= 0.
        frequency_hz: f [Hz] > 0 (must lie below the physics Nyquist rate, checked by the
            simulator).
        region: where the disturbance acts (everywhere if ``None``).
        noise_std: white noise std per axis [N] >= 0 (default 0).
    """

    amplitude: Vec2 = checked(nonneg_vec2)
    frequency_hz: float = checked(check_positive)
    region: RegionSpec | None = checked(nested(RegionSpec.from_mapping), None)
    noise_std: float = checked(check_nonneg, 0.0)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> VibrationSpec:
        return cls(**field_values(cls, cfg, key)[0])
