"""The modelled force/torque sensor: true external wrench in, measured wrench out.

The measurement model is ``measured = true + bias + noise`` with ``noise ~ N(0, diag(std²))``
drawn independently per axis and per sample from a ``numpy.random.Generator`` given at
:meth:`FTSensor.reset` (all randomness flows through a seeded generator). The sensor
never sees the command or gravity: the simulator passes it the external wrench only.

It is dimension-agnostic (force ``(n,)``, torque ``(r,)``) so the 2D pymunk and the 3D
PyBullet backends share it. Seed A §4.1 used noiseless measurements in its 2D simulation,
hence the zero defaults.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_finite,
    check_int_nonneg,
    check_keys,
    check_nonneg,
    check_range,
    check_vector,
    to_plain,
)

#: the largest noise std, bias or spike a sensor may be given [N, N m] (issue #39: a std of
#: 1e200 N gave non-finite forces in an ``ok`` run). Chosen from the physics: a robot's wrist
#: F/T sensor is rated for a few kN and a few hundred N m (ATI's largest Omega sensors: tens of
#: kN); a noise or offset beyond ten times that is not a sensor but a bad number.
FORCE_LIMIT_N = 1e5
TORQUE_LIMIT_NM = 1e4


def _per_axis(key: str, value: Any, dim: int, nonneg: bool, limit: float) -> tuple[float, ...]:
    """A scalar (broadcast to every axis) or a length-``dim`` list, as a tuple of floats, each
    within ±``limit`` (and >= 0 if ``nonneg``)."""
    if isinstance(value, int | float | np.number) and not isinstance(value, bool):
        v = check_nonneg(key, value) if nonneg else check_finite(key, value)
        arr = np.full(dim, float(v))
    else:
        arr = check_vector(key, value, dim)
    if nonneg and np.any(arr < 0.0):
        raise ConfigError(key, f"must be >= 0 on every axis, got {value!r}")
    if np.any(np.abs(arr) > limit):
        raise ConfigError(key, f"must lie within ±{limit:g} on every axis (a sensor's scale), "
                          f"got {value!r}")  # fmt: skip
    return tuple(float(a) for a in arr)


@dataclass(frozen=True)
class SensorConfig:
    """Noise and bias of the F/T sensor, one entry per axis (tuples, so configs compare equal).

    Attributes:
        force_noise_std: Gaussian noise std per force axis [N], shape (n,).
        torque_noise_std: Gaussian noise std per torque axis [N m], shape (r,).
        force_bias: constant offset per force axis [N], shape (n,).
        torque_bias: constant offset per torque axis [N m], shape (r,).
        spike_prob, spike_N: fault injection (issue #8): with this probability per sample a
            force spike of ±spike_N on every axis (random signs).
        dropout_prob, dropout_steps: with this probability per sample the sensor stops
            updating and repeats its last reading for dropout_steps samples.
        delay_steps: latency: each reading reaches the controller this many samples (control
            steps) late; until that many samples exist, the first reading is repeated. It
            models a sensor or an external-control interface that delivers late (seed B's
            force latency, ``mpc_contact_latency``, for any controller).
        Faults are off by default and consume no random numbers then.
    """

    force_noise_std: tuple[float, ...]
    torque_noise_std: tuple[float, ...]
    force_bias: tuple[float, ...]
    torque_bias: tuple[float, ...]
    spike_prob: float = 0.0
    spike_N: float = 0.0
    dropout_prob: float = 0.0
    dropout_steps: int = 0
    delay_steps: int = 0

    @property
    def force_dim(self) -> int:
        return len(self.force_bias)

    @property
    def torque_dim(self) -> int:
        return len(self.torque_bias)

    @classmethod
    def ideal(cls, force_dim: int = 2, torque_dim: int = 1) -> SensorConfig:
        """A noiseless, unbiased sensor."""
        return cls.from_values(force_dim=force_dim, torque_dim=torque_dim)

    @classmethod
    def from_values(
        cls,
        force_noise_std: float | Sequence[float] = 0.0,
        torque_noise_std: float | Sequence[float] = 0.0,
        force_bias: float | Sequence[float] = 0.0,
        torque_bias: float | Sequence[float] = 0.0,
        force_dim: int = 2,
        torque_dim: int = 1,
        prefix: str = "sim.sensor",
        spike_prob: float = 0.0,
        spike_N: float = 0.0,
        dropout_prob: float = 0.0,
        dropout_steps: int = 0,
        delay_steps: int = 0,
    ) -> SensorConfig:
        """Build from scalars (broadcast to every axis) or per-axis sequences, validating."""
        return cls(
            delay_steps=check_int_nonneg(f"{prefix}.delay_steps", delay_steps),
            spike_prob=check_range(f"{prefix}.spike_prob", spike_prob, 0.0, 1.0),
            spike_N=check_range(f"{prefix}.spike_N", spike_N, 0.0, FORCE_LIMIT_N),
            dropout_prob=check_range(f"{prefix}.dropout_prob", dropout_prob, 0.0, 1.0),
            dropout_steps=check_int_nonneg(f"{prefix}.dropout_steps", dropout_steps),
            force_noise_std=_per_axis(
                f"{prefix}.force_noise_std", force_noise_std, force_dim, True, FORCE_LIMIT_N
            ),
            torque_noise_std=_per_axis(
                f"{prefix}.torque_noise_std", torque_noise_std, torque_dim, True, TORQUE_LIMIT_NM
            ),
            force_bias=_per_axis(
                f"{prefix}.force_bias", force_bias, force_dim, False, FORCE_LIMIT_N
            ),
            torque_bias=_per_axis(
                f"{prefix}.torque_bias", torque_bias, torque_dim, False, TORQUE_LIMIT_NM
            ),
        )

    @classmethod
    def from_mapping(
        cls, cfg: Any, force_dim: int = 2, torque_dim: int = 1, prefix: str = "sim.sensor"
    ) -> SensorConfig:
        """Parse ``{force_noise_std, torque_noise_std, force_bias, torque_bias}`` (all optional).

        Raises:
            ConfigError: on unknown keys, negative std or wrong vector lengths.
        """

        allowed = ("force_noise_std", "torque_noise_std", "force_bias", "torque_bias",
                   "spike_prob", "spike_N", "dropout_prob", "dropout_steps",
                   "delay_steps")  # fmt: skip
        d = to_plain(cfg, prefix)
        check_keys(prefix, d, allowed)
        return cls.from_values(
            **{k: d[k] for k in allowed if k in d},
            force_dim=force_dim,
            torque_dim=torque_dim,
            prefix=prefix,
        )


#: noise samples drawn at a time (:meth:`FTSensor.reset`; chosen: one Generator call per
#: 512 control steps instead of one per step, ~2-5 µs of the step)
AHEAD = 512


class FTSensor:
    """A force/torque sensor with per-axis Gaussian noise and constant bias.

    Args:
        config: noise and bias; ``None`` means an ideal sensor of the given dimensions.
        force_dim: n, length of the force vector.
        torque_dim: r, length of the torque vector.

    Example:
        >>> s = FTSensor(SensorConfig.from_values(force_noise_std=0.1))
        >>> s.reset(np.random.default_rng(0))
        >>> f, t = s.measure(np.zeros(2), np.zeros(1))
    """

    def __init__(
        self, config: SensorConfig | None = None, force_dim: int = 2, torque_dim: int = 1
    ) -> None:
        self.config = config if config is not None else SensorConfig.ideal(force_dim, torque_dim)
        if (self.config.force_dim, self.config.torque_dim) != (force_dim, torque_dim):
            raise ValueError(
                f"sensor config has dims ({self.config.force_dim}, {self.config.torque_dim}), "
                f"expected ({force_dim}, {torque_dim})"
            )
        self.force_dim = force_dim
        self.torque_dim = torque_dim
        self._f_std = np.array(self.config.force_noise_std)
        self._t_std = np.array(self.config.torque_noise_std)
        self._f_bias = np.array(self.config.force_bias)
        self._t_bias = np.array(self.config.torque_bias)
        self._noisy_force = bool(np.any(self._f_std > 0.0))
        self._noisy_torque = bool(np.any(self._t_std > 0.0))
        c = self.config
        self._faults = (c.spike_prob > 0 and c.spike_N > 0) or (
            c.dropout_prob > 0 and c.dropout_steps > 0
        )
        self._ideal = (
            not (
                self._noisy_force
                or self._noisy_torque
                or np.any(self._f_bias)
                or np.any(self._t_bias)
            )
            and not self._faults
            and not self.config.delay_steps
        )
        self._rng: np.random.Generator | None = None
        self._held: tuple[np.ndarray, np.ndarray] | None = None
        self._hold_left = 0
        #: noise drawn ahead (no faults: nothing else draws between two calls), one row per
        #: call: the force axes' samples if noisy, then the torque axes' if noisy
        self._width = force_dim * self._noisy_force + torque_dim * self._noisy_torque
        self._ahead = np.empty((0, self._width))
        self._row = 0
        self._late: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=c.delay_steps + 1)

    @property
    def ideal(self) -> bool:
        """True for a sensor without noise, bias and faults: it measures the true wrench."""
        return self._ideal

    def reset(self, rng: np.random.Generator) -> None:
        """Use ``rng`` for all later noise draws (the simulator seeds it at its reset).

        Without faults the sensor draws its noise ``AHEAD`` calls at a time, the same
        numbers in the same order as one draw per call (numpy's ``Generator`` fills an array
        sample by sample), so ``rng`` must be the sensor's own: nothing else may draw from
        it (each simulator makes one at its reset for the sensor alone)."""
        self._rng = rng
        self._held, self._hold_left = None, 0
        self._ahead, self._row = self._ahead[:0], 0
        self._late.clear()

    def measure(self, force: np.ndarray, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the measured ``(force, torque)`` for the true external wrench.

        Each call takes one noise sample per axis, force axes first, and only for the parts
        whose std is non-zero, so a noiseless sensor consumes no random numbers (the samples
        are drawn ahead, :meth:`reset`).

        Args:
            force: true external force, shape (n,).
            torque: true external torque, shape (r,).

        Returns:
            New arrays ``(force_measured, torque_measured)``; with ``delay_steps`` = d, the
            reading of d calls earlier (the first reading while fewer calls were made).
        """
        if not self.config.delay_steps:
            return self._measure_now(force, torque)
        self._late.append(self._measure_now(force, torque))
        f, t = self._late[0]
        return f.copy(), t.copy()

    def _measure_now(self, force: np.ndarray, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """This sample's reading of the true wrench (:meth:`measure` without the delay)."""
        if self._ideal:
            if isinstance(force, np.ndarray) and force.shape == (self.force_dim,):
                if isinstance(torque, np.ndarray) and torque.shape == (self.torque_dim,):
                    return force.astype(float), torque.astype(float)  # fresh copies
            return (
                np.array(force, dtype=float).reshape(self.force_dim),
                np.array(torque, dtype=float).reshape(self.torque_dim),
            )
        f = np.asarray(force, dtype=float).reshape(self.force_dim) + self._f_bias
        t = np.asarray(torque, dtype=float).reshape(self.torque_dim) + self._t_bias
        if self._width and not self._faults:
            z = self._next_noise()
            if self._noisy_force:
                f = f + z[: self.force_dim] * self._f_std
            if self._noisy_torque:
                t = t + z[self._width - self.torque_dim :] * self._t_std
            return f, t
        if self._noisy_force or self._noisy_torque:
            if self._rng is None:
                raise RuntimeError("FTSensor.reset(rng) must be called before a noisy measure()")
            if self._noisy_force:
                f = f + self._rng.normal(0.0, 1.0, self.force_dim) * self._f_std
            if self._noisy_torque:
                t = t + self._rng.normal(0.0, 1.0, self.torque_dim) * self._t_std
        if self._faults:
            return self._fault(f, t)
        return f, t

    def _next_noise(self) -> np.ndarray:
        """This call's row of standard normal samples (:meth:`reset`: drawn ``AHEAD`` at a time)."""
        row = self._row
        if row == len(self._ahead):
            if self._rng is None:
                raise RuntimeError("FTSensor.reset(rng) must be called before a noisy measure()")
            self._ahead = self._rng.normal(0.0, 1.0, (AHEAD, self._width))
            row = 0
        self._row = row + 1
        return self._ahead[row]

    def _fault(self, f: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Spikes and dropouts (held last reading) on top of the noisy measurement."""
        if self._rng is None:
            raise RuntimeError("FTSensor.reset(rng) must be called before a faulty measure()")
        c = self.config
        u_spike, u_drop = self._rng.random(2)
        signs = self._rng.choice((-1.0, 1.0), self.force_dim)
        if self._hold_left > 0 and self._held is not None:
            self._hold_left -= 1
            return self._held[0].copy(), self._held[1].copy()
        if u_spike < c.spike_prob:
            f = f + c.spike_N * signs
        if u_drop < c.dropout_prob and c.dropout_steps > 0:
            self._hold_left = c.dropout_steps
        self._held = (f.copy(), t.copy())
        return f, t
