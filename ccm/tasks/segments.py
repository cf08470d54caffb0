"""The segments of a target pattern P (seed A §3): line, arc and hold, each timed with the
minimum-jerk polynomial

    s(τ) = 10 τ³ − 15 τ⁴ + 6 τ⁵,   τ = t / T,

so position, velocity and acceleration are continuous everywhere and velocity and acceleration
are zero at both ends of each segment (a jerk-free start and stop). Velocity and acceleration
are analytic (chain rule through s(τ); arcs add the centripetal term).

Every segment is evaluated as a small matrix product ``C(t) @ B``: ``B`` (k × n) holds constant
basis vectors fixed when the segment is built and ``C(t)`` (3 × k) holds scalar coefficients for
position, velocity and acceleration. This keeps sampling, which runs every control step, down
to a few microseconds. :mod:`ccm.tasks.trajectory` joins segments into a pattern.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_finite, check_nonneg, check_positive, check_vector
from ccm.core.vector import readonly
from ccm.tasks._trajectory_kernels import arc_eval, line_eval

#: Relative tolerance for "start − center is perpendicular to the arc normal" (3D arcs).
_PLANE_TOL = 1e-6


def min_jerk(tau: Any, duration: float) -> tuple[Any, Any, Any]:
    """Minimum-jerk time scaling and its time derivatives.

    Works on floats and numpy arrays alike (no clipping here; callers pass τ in [0, 1]).

    Args:
        tau: normalised time t / T.
        duration: segment duration T [s].

    Returns:
        ``(s, ds/dt, d²s/dt²)`` with s(τ) = 10τ³ − 15τ⁴ + 6τ⁵.
    """
    tau2 = tau * tau
    one_minus = 1.0 - tau
    s = tau2 * tau * (10.0 + tau * (6.0 * tau - 15.0))
    sd = 30.0 * tau2 * one_minus * one_minus / duration
    sdd = 60.0 * tau * one_minus * (1.0 - 2.0 * tau) / (duration * duration)
    return s, sd, sdd


def arrive_at_speed(tau: Any, duration: float, w: float) -> tuple[Any, Any, Any]:
    """Quintic time scaling that starts at rest and *arrives* at normalised speed ``w``.

    s(0) = ṡ(0) = s̈(0) = 0, s(1) = 1, ds/dτ(1) = w, s̈(1) = 0:
    s(τ) = (10 − 4w) τ³ + (7w − 15) τ⁴ + (6 − 3w) τ⁵; w = 0 is :func:`min_jerk`. For
    0 ≤ w ≤ 2 it never moves backwards.

    Returns:
        ``(s, ds/dt, d²s/dt²)`` as :func:`min_jerk`.
    """
    a3, a4, a5 = 10.0 - 4.0 * w, 7.0 * w - 15.0, 6.0 - 3.0 * w
    tau2 = tau * tau
    s = tau2 * tau * (a3 + tau * (a4 + tau * a5))
    sd = tau2 * (3.0 * a3 + tau * (4.0 * a4 + tau * 5.0 * a5)) / duration
    sdd = tau * (6.0 * a3 + tau * (12.0 * a4 + tau * 20.0 * a5)) / (duration * duration)
    return s, sd, sdd


def unit_vector(key: str, value: Any, dim: int) -> np.ndarray:
    vec = check_vector(key, value, dim)
    norm = float(np.linalg.norm(vec))
    if norm == 0.0:
        raise ConfigError(key, f"must be a non-zero vector, got {value!r}")
    return vec / norm


class Segment(ABC):
    """One smooth piece of a target pattern (seed A §3: a segment of P).

    Subclasses fix a basis ``B`` (k × n) at construction and give the 3 × k coefficient matrix
    ``C(t)`` (rows: position, velocity, acceleration); ``C(t) @ B`` is the sampled motion.

    Args:
        duration: segment duration T [s], > 0.
        force_dir: direction along which force is regulated instead of position (hybrid
            force-motion control, seed A Eq. 1), normalised here; ``None`` for pure motion.
        force_mag: desired force the end-effector exerts on the environment along
            ``force_dir`` [N], >= 0; must be 0 when ``force_dir`` is ``None``.
        name: optional label (for logs and plots).
        key: configuration key used in error messages.
    """

    #: True when the force target changes within the segment: then :meth:`force_at` and
    #: :meth:`force_many` give it, not ``force_dir``/``force_mag`` (a recording).
    varying_force = False

    def __init__(
        self,
        duration: float,
        dim: int,
        force_dir: Sequence[float] | np.ndarray | None,
        force_mag: float,
        name: str | None,
        key: str,
    ) -> None:
        self.key = key
        self.dim = dim
        self.duration = check_positive(f"{key}.duration", duration)
        self.force_mag = check_nonneg(f"{key}.force.magnitude", force_mag)
        if force_dir is None:
            if self.force_mag != 0.0:
                raise ConfigError(
                    f"{key}.force.direction", "required when the force magnitude is non-zero"
                )
            self.force_dir: np.ndarray | None = None
        else:
            self.force_dir = readonly(unit_vector(f"{key}.force.direction", force_dir, dim))
        self.name = name
        self._basis: np.ndarray = np.zeros((1, dim))

    @abstractmethod
    def _coeffs(self, t_local: float) -> list[list[float]]:
        """3 × k coefficients at ``t_local`` in [0, duration] (scalar math, no numpy)."""

    @abstractmethod
    def _coeffs_many(self, t_local: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`_coeffs`: shape (N, 3, k) for ``t_local`` of shape (N,)."""

    def _finish(self) -> None:
        self._basis = readonly(self._basis)
        self.start: np.ndarray = readonly(self._eval(0.0)[0].copy())
        self.end: np.ndarray = readonly(self._eval(self.duration)[0].copy())

    def _eval(self, t_local: float) -> np.ndarray:
        return np.array(self._coeffs(t_local)) @ self._basis

    def sample(self, t_local: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at local time ``t_local`` (clipped to [0, T]).

        Returns:
            ``(pos, vel, acc)``, each of shape (n,), world frame, SI units.
        """
        t_local = min(max(float(t_local), 0.0), self.duration)
        out = self._eval(t_local)
        return out[0], out[1], out[2]

    def sample_many(self, t_local: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`sample`; returns shape (N, 3, n) (pos, vel, acc per time)."""
        tl = np.clip(np.asarray(t_local, dtype=float), 0.0, self.duration)
        return self._coeffs_many(tl) @ self._basis

    def force_at(self, t_local: float) -> tuple[np.ndarray | None, float]:
        """The force target (direction, magnitude [N]) at ``t_local``; constant here."""
        return self.force_dir, self.force_mag

    def force_many(self, t_local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`force_at`: directions (N, n) (zeros: none), magnitudes (N,)."""
        n = np.asarray(t_local).shape[0]
        if self.force_dir is None:
            return np.zeros((n, self.dim)), np.zeros(n)
        return np.tile(self.force_dir, (n, 1)), np.full(n, self.force_mag)

    def __repr__(self) -> str:
        force = "" if self.force_dir is None else f", force={self.force_mag} N"
        return (
            f"{type(self).__name__}(start={self.start.tolist()}, end={self.end.tolist()}, "
            f"duration={self.duration}{force})"
        )


class LineSegment(Segment):
    """Straight line from ``start`` to ``end`` with minimum-jerk timing, or, with
    ``end_speed`` > 0, a quintic that arrives at ``end`` still moving at that speed
    (:func:`arrive_at_speed`): a move *into* a surface whose position is not known exactly,
    meeting it at the planned speed (seed A §4.5.1, the approach without contact handling).

    Args:
        start, end: endpoints, world frame [m], same length n (2 or 3).
        duration: T [s].
        force_dir, force_mag, name, key: see :class:`Segment`.
        end_speed: speed at ``end`` [m/s], 0 ≤ end_speed ≤ 2 |end − start| / T.
    """

    def __init__(
        self,
        start: Sequence[float] | np.ndarray,
        end: Sequence[float] | np.ndarray,
        duration: float,
        force_dir: Sequence[float] | np.ndarray | None = None,
        force_mag: float = 0.0,
        name: str | None = None,
        *,
        end_speed: float = 0.0,
        key: str = "segment",
    ) -> None:
        p0 = check_vector(f"{key}.start", start, (2, 3))
        p1 = check_vector(f"{key}.to", end, p0.shape[0])
        super().__init__(duration, p0.shape[0], force_dir, force_mag, name, key)
        length = float(np.linalg.norm(p1 - p0))
        end_speed = check_nonneg(f"{key}.end_speed", end_speed)
        if end_speed > 0.0 and end_speed > 2.0 * length / self.duration:
            raise ConfigError(
                f"{key}.end_speed",
                f"must be <= 2 x length / duration = {2.0 * length / self.duration:.4g} m/s "
                f"(the line would move backwards), got {end_speed}",
            )
        self.end_speed = end_speed
        self._w = end_speed * self.duration / length if end_speed > 0.0 else 0.0
        # pos = (1 - s) p0 + s p1 is exact at both ends (s = 0 and s = 1 are exact floats).
        self._basis = np.stack([p0, p1])
        self._finish()

    def _scaling(self, tau: Any) -> tuple[Any, Any, Any]:
        if self._w == 0.0:
            return min_jerk(tau, self.duration)
        return arrive_at_speed(tau, self.duration, self._w)

    def _coeffs(self, t_local: float) -> list[list[float]]:
        s, sd, sdd = self._scaling(t_local / self.duration)
        return [[1.0 - s, s], [-sd, sd], [-sdd, sdd]]

    def _eval(self, t_local: float) -> np.ndarray:
        # compiled C(t) @ B for min-jerk timing, bit-for-bit the readable version
        # (Segment._eval with _coeffs); a line that arrives at speed takes the readable path
        if self._w == 0.0:
            return line_eval(t_local, self.duration, self._basis)
        return super()._eval(t_local)

    def _coeffs_many(self, t_local: np.ndarray) -> np.ndarray:
        s, sd, sdd = self._scaling(t_local / self.duration)
        rows = [np.stack([1.0 - s, s], -1), np.stack([-sd, sd], -1), np.stack([-sdd, sdd], -1)]
        return np.stack(rows, 1)


class ArcSegment(Segment):
    """Circular arc: ``start`` rotated about ``center`` by ``sweep_rad`` with min-jerk timing.

    The angle follows θ(t) = sweep · s(t/T). Positive sweep is counter-clockwise about +z in 2D,
    or about ``normal`` in 3D (right-hand rule). The radius is |start − center|; in 3D,
    ``start − center`` must be perpendicular to ``normal``. Acceleration includes the
    tangential (θ̈) and centripetal (θ̇²) terms.

    Args:
        start: first point of the arc [m], shape (n,).
        center: circle centre [m], shape (n,).
        sweep_rad: signed swept angle [rad], non-zero (several turns allowed).
        duration: T [s].
        normal: 3D only: rotation axis (normalised here; default +z). Must be ``None`` in 2D.
        force_dir, force_mag, name, key: see :class:`Segment`.
    """

    def __init__(
        self,
        start: Sequence[float] | np.ndarray,
        center: Sequence[float] | np.ndarray,
        sweep_rad: float,
        duration: float,
        normal: Sequence[float] | np.ndarray | None = None,
        force_dir: Sequence[float] | np.ndarray | None = None,
        force_mag: float = 0.0,
        name: str | None = None,
        *,
        key: str = "segment",
        sweep_key: str = "sweep_rad",
    ) -> None:
        p0 = check_vector(f"{key}.start", start, (2, 3))
        dim = p0.shape[0]
        c = check_vector(f"{key}.center", center, dim)
        self.sweep = check_finite(f"{key}.{sweep_key}", sweep_rad)
        if self.sweep == 0.0:
            raise ConfigError(f"{key}.{sweep_key}", "must be non-zero")
        super().__init__(duration, dim, force_dir, force_mag, name, key)
        r0 = p0 - c
        self.radius = float(np.linalg.norm(r0))
        if self.radius <= 1e-12:
            raise ConfigError(
                f"{key}.center",
                f"zero-radius arc: the centre {c.tolist()} equals the start point",
            )
        if dim == 2:
            if normal is not None:
                raise ConfigError(f"{key}.normal", "only allowed for 3D patterns")
            k = np.array([0.0, 0.0, 1.0])
            b = np.array([-r0[1], r0[0]])  # z × r0
        else:
            k = unit_vector(f"{key}.normal", [0.0, 0.0, 1.0] if normal is None else normal, 3)
            off_plane = abs(float(k @ r0))
            if off_plane > _PLANE_TOL * self.radius:
                raise ConfigError(
                    f"{key}.center",
                    f"start - center must be perpendicular to the normal {k.tolist()} "
                    f"(off-plane component {off_plane:.3g} m)",
                )
            b = np.cross(k, r0)
        self.center = readonly(c.copy())
        self.normal = readonly(k)
        # Rodrigues' rotation of r0 about k: the component of r0 along k (at most a rounding
        # residue after the check above) stays fixed, the perpendicular part rotates.
        # Basis rows: fixed offset, perpendicular radius vector at θ = 0, its 90° rotation.
        par = np.zeros(2) if dim == 2 else float(k @ r0) * k
        self._basis = np.stack([c + par, r0 - par, b])
        self._finish()
        self.start = readonly(p0.copy())

    def _coeffs(self, t_local: float) -> list[list[float]]:
        s, sd, sdd = min_jerk(t_local / self.duration, self.duration)
        th, thd, thdd = self.sweep * s, self.sweep * sd, self.sweep * sdd
        c, si = math.cos(th), math.sin(th)
        thd2 = thd * thd
        return [
            [1.0, c, si],
            [0.0, -thd * si, thd * c],
            [0.0, -thdd * si - thd2 * c, thdd * c - thd2 * si],
        ]

    def _eval(self, t_local: float) -> np.ndarray:
        # compiled C(t) @ B, bit-for-bit the readable version (Segment._eval with _coeffs)
        return arc_eval(t_local, self.duration, self.sweep, self._basis)

    def _coeffs_many(self, t_local: np.ndarray) -> np.ndarray:
        s, sd, sdd = min_jerk(t_local / self.duration, self.duration)
        th, thd, thdd = self.sweep * s, self.sweep * sd, self.sweep * sdd
        c, si = np.cos(th), np.sin(th)
        thd2 = thd * thd
        one, zero = np.ones_like(s), np.zeros_like(s)
        rows = [
            np.stack([one, c, si], -1),
            np.stack([zero, -thd * si, thd * c], -1),
            np.stack([zero, -thdd * si - thd2 * c, thdd * c - thd2 * si], -1),
        ]
        return np.stack(rows, 1)


class HoldSegment(Segment):
    """Stay at ``position`` for ``duration`` (zero velocity and acceleration).

    Args:
        position: held point [m], shape (n,).
        duration: T [s].
        force_dir, force_mag, name, key: see :class:`Segment`.
    """

    def __init__(
        self,
        position: Sequence[float] | np.ndarray,
        duration: float,
        force_dir: Sequence[float] | np.ndarray | None = None,
        force_mag: float = 0.0,
        name: str | None = None,
        *,
        key: str = "segment",
    ) -> None:
        p = check_vector(f"{key}.position", position, (2, 3))
        super().__init__(duration, p.shape[0], force_dir, force_mag, name, key)
        self._basis = p[None, :].copy()
        self._finish()

    def _coeffs(self, t_local: float) -> list[list[float]]:
        return [[1.0], [0.0], [0.0]]

    def _coeffs_many(self, t_local: np.ndarray) -> np.ndarray:
        out = np.zeros((t_local.shape[0], 3, 1))
        out[:, 0, 0] = 1.0
        return out
