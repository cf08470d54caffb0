"""A target-pattern segment from a recorded demonstration (seed A §3: P from a kinesthetic
demonstration; seed B: learning from a few demonstrations).

The recording (read and checked by :mod:`ccm.tasks.recording_file`) becomes a C²-continuous
target in three steps:

1. **Resample** each column by linear interpolation onto a uniform grid from 0 to the
   recording's duration T, with spacing h = T / round(T / h₀), h₀ the file's median sample
   interval (so the grid keeps the file's resolution and only evens out jitter).
2. **Smooth** each axis with a cubic smoothing spline
   (:func:`scipy.interpolate.make_smoothing_spline`), which minimises
   Σᵢ (yᵢ − f(tᵢ))² + λ ∫ f''(t)² dt. *Knot rule:* one knot at every grid point (the
   smoothing spline's own knots), natural end conditions (f'' = 0 at both ends).
   *Smoothing rule:* λ = 1 / (h (2π f_c)⁴). On a uniform grid the smoothing spline acts
   as the low-pass filter H(f) = 1 / (1 + λ h (2π f)⁴), so this λ puts its half-amplitude
   point at the cut-off f_c (``cutoff_hz``, default 5 Hz): above the ≤ 2 Hz of voluntary
   arm motion (H(2 Hz) = 0.975) and below the 8-12 Hz physiological tremor and the sensor
   noise, which it removes (H(8 Hz) = 0.13). The rule depends on f_c alone, not on the
   sampling rate, so the same demonstration recorded at 100 Hz or 1 kHz gives nearly the
   same P.
3. **Differentiate** analytically: velocity and acceleration are the spline's first and
   second derivatives. A cubic spline is C²: position, velocity and acceleration are
   continuous everywhere, the knots included. The natural end conditions fix the
   acceleration (0) at both ends, not the velocity: that is the smoothed demonstration's,
   small when it starts and ends at rest as a demonstration does; after the end P holds the
   last pose at zero velocity, like every pattern.

Where the file has force columns (the force the tool exerted on the environment), they are
smoothed by the same rule and become the hybrid force target (seed A Eq. 1, u_fc), per
sample: direction f/|f| and magnitude |f| of the smoothed force f, each component kept
only where the recorded one (linearly interpolated) reaches ``force_threshold_N``, and no
force target (pure motion) where |f| stays below it. The gate keeps each component to where
the demonstration pushed along it: the smoothing is not causal and spreads a contact's
force step over about ±1/f_c, and a target that tilts toward a wall before the wall is
reached pushes the tool into it by force (measured on h4_contact_learning_demo).

The spline's start is shifted onto the previous segment's end (the pattern's ``start`` for
the first segment) when it lies within ``max_offset_m`` of it, so that a recording made
from the task's start joins it exactly; a recording further away is refused. P's orientation
is constant in ccm (the task's ``orientation``): orientation columns are accepted only when
they stay within ``orientation_tol_rad`` of their first row.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import PPoly, make_smoothing_spline

from ccm.core.errors import ConfigError
from ccm.core.vector import readonly
from ccm.tasks.recording_file import MAX_SPEED_MPS, Recording, read_recording, resolve_path
from ccm.tasks.segments import Segment

#: Default cut-off of the smoothing spline [Hz] (see the module docstring).
CUTOFF_HZ = 5.0
#: Default force below which a sample has no force target [N]: 20 x the simulated F/T
#: sensor's noise std (0.05 N).
FORCE_THRESHOLD_N = 1.0
#: Default largest distance between the recording's start and the previous end [m].
MAX_OFFSET_M = 0.01
#: Default largest orientation change a recording may hold [rad].
ORIENTATION_TOL_RAD = 0.05


def smoothing_lambda(h: float, cutoff_hz: float) -> float:
    """λ of the smoothing rule: the spline's half-amplitude point at ``cutoff_hz``."""
    return 1.0 / (h * (2.0 * math.pi * cutoff_hz) ** 4)


def smooth_columns(t: np.ndarray, values: np.ndarray, cutoff_hz: float) -> PPoly:
    """Resample ``values`` (N, n) at times ``t`` onto a uniform grid and smooth each column
    with the cubic smoothing spline of the module's rule; returns one piecewise cubic with
    (n,)-vector values (the same knots on every axis)."""
    duration = float(t[-1])
    h0 = float(np.median(np.diff(t)))
    steps = max(int(round(duration / h0)), 4)
    grid = np.linspace(0.0, duration, steps + 1)
    lam = smoothing_lambda(duration / steps, cutoff_hz)
    pieces = [PPoly.from_spline(make_smoothing_spline(grid, np.interp(grid, t, col), lam=lam))
              for col in values.T]  # fmt: skip
    return PPoly(np.stack([p.c for p in pieces], axis=-1), pieces[0].x)


class _Cubic:
    """Fast scalar evaluation of a vector piecewise cubic and its two derivatives."""

    def __init__(self, pp: PPoly, offset: np.ndarray | None = None) -> None:
        x = np.asarray(pp.x, dtype=float)
        keep = np.concatenate([np.diff(x) > 0.0, [False]])  # drop the repeated end knots
        self.breaks = x[np.flatnonzero(keep)]
        self._breaks = self.breaks.tolist()
        self.coef = np.array(pp.c[:, keep[:-1]], dtype=float)  # (4, m, n), highest power first
        if offset is not None:
            self.coef[3] += offset

    def eval(self, t: float) -> np.ndarray:
        """(3, n): value, first and second derivative at ``t`` (inside the breaks)."""
        i = min(max(bisect.bisect_right(self._breaks, t) - 1, 0), len(self._breaks) - 1)
        d = t - self._breaks[i]
        powers = np.array([[d * d * d, d * d, d, 1.0], [3.0 * d * d, 2.0 * d, 1.0, 0.0],
                           [6.0 * d, 2.0, 0.0, 0.0]])  # fmt: skip
        return powers @ self.coef[:, i, :]

    def eval_many(self, t: np.ndarray) -> np.ndarray:
        """(N, 3, n) for times ``t`` (N,)."""
        i = np.clip(np.searchsorted(self.breaks, t, side="right") - 1, 0, len(self.breaks) - 1)
        d = (t - self.breaks[i])[:, None]
        c0, c1, c2, c3 = (self.coef[k, i, :] for k in range(4))
        pos = ((c0 * d + c1) * d + c2) * d + c3
        vel = (3.0 * c0 * d + 2.0 * c1) * d + c2
        acc = 6.0 * c0 * d + 2.0 * c1
        return np.stack([pos, vel, acc], axis=1)


@dataclass(frozen=True)
class Smoothed:
    """A checked recording with its smoothed motion and (optional) force, as piecewise cubics."""

    recording: Recording
    motion: PPoly
    force: PPoly | None


#: Smoothed recordings by (file, its mtime and size, dim, max_speed, cutoff): the windows of
#: one file (several pattern entries) and repeated task loads read and smooth it once.
_CACHE: dict[tuple[Any, ...], Smoothed] = {}


def load_smoothed(
    path: str, dim: int, key: str, *, max_speed: float = MAX_SPEED_MPS, cutoff_hz: float = CUTOFF_HZ
) -> Smoothed:
    """Read, check and smooth a demonstration file (cached; errors name ``key``)."""
    p = resolve_path(path)
    stat = p.stat() if p.is_file() else None
    ident = (str(p.resolve()), stat.st_mtime_ns, stat.st_size) if stat else None
    cache_key = (ident, dim, max_speed, cutoff_hz)
    if ident is not None and cache_key in _CACHE:
        return _CACHE[cache_key]
    rec = read_recording(path, dim, f"{key}.file", max_speed=max_speed)
    nyquist = 0.5 / float(np.median(np.diff(rec.t)))
    if not 0.0 < cutoff_hz < nyquist:
        raise ConfigError(
            f"{key}.cutoff_hz",
            f"must lie in (0, {nyquist:.4g}) Hz (the Nyquist rate of {rec.path}), got {cutoff_hz}",
        )
    force = None if rec.force is None else smooth_columns(rec.t, rec.force, cutoff_hz)
    out = Smoothed(rec, smooth_columns(rec.t, rec.position, cutoff_hz), force)
    if len(_CACHE) >= 16:
        _CACHE.clear()
    _CACHE[cache_key] = out
    return out


class RecordingSegment(Segment):
    """A segment that follows a smoothed demonstration (see the module docstring).

    Args:
        start: where the previous segment ended (the pattern's start for the first) [m].
        smoothed: the smoothed demonstration (:func:`load_smoothed`).
        window: ``(from, to)`` [s] of the recording this segment plays (default: all of it).
            Consecutive windows of one file (``to`` of one = ``from`` of the next) join
            exactly, C² included, as they cut one spline: a demonstration split into named
            segments (e.g. for a task's ``contacts``).
        use_force: whether the file's force columns are the force target.
        force_threshold_N: smallest force magnitude that is a force target [N].
        max_offset_m: largest start offset that is shifted away [m]; beyond it, an error.
        orientation_tol_rad: largest orientation change the recording may hold [rad].
        name, key: see :class:`Segment`.
    """

    #: The force target changes within the segment (:meth:`force_at`).
    varying_force = True

    def __init__(
        self,
        start: Sequence[float] | np.ndarray,
        smoothed: Smoothed,
        *,
        window: tuple[float, float] | None = None,
        use_force: bool = True,
        force_threshold_N: float = FORCE_THRESHOLD_N,
        max_offset_m: float = MAX_OFFSET_M,
        orientation_tol_rad: float = ORIENTATION_TOL_RAD,
        name: str | None = None,
        key: str = "segment",
    ) -> None:
        p0 = np.asarray(start, dtype=float)
        rec = smoothed.recording
        total = float(rec.t[-1])
        t0, t1 = (0.0, total) if window is None else window
        if not 0.0 <= t0 < t1 <= total + 1e-9:
            raise ConfigError(
                f"{key}.from", f"window [{t0}, {t1}] s must lie in [0, {total:.6g}] s of {rec.path}"
            )
        super().__init__(t1 - t0, p0.shape[0], None, 0.0, name, key)
        _check_orientation(rec, key, orientation_tol_rad)
        self.path = rec.path
        self.t0 = t0
        self.force_threshold_N = float(force_threshold_N)
        first = smoothed.motion(t0)
        offset = p0 - first
        gap = float(np.linalg.norm(offset))
        if gap > max_offset_m:
            raise ConfigError(
                f"{key}.file",
                f"{rec.path}: starts at {np.round(first, 4).tolist()}, {gap:.4g} m from the "
                f"previous end {p0.tolist()} (more than max_offset_m = {max_offset_m} m)",
            )
        #: the shift applied to the recording so that it starts at ``start`` [m]
        self.offset = readonly(offset)
        self._motion = _Cubic(smoothed.motion, offset)
        self._force = _Cubic(smoothed.force) if use_force and smoothed.force else None
        if self._force is not None and rec.force is not None:
            # the recording's own force, per axis: a component only where it was recorded
            self._raw_t, self._raw_abs = rec.t, np.abs(rec.force)
            self._raw_list = rec.t.tolist()
        self.start = readonly(p0.copy())
        self.end = readonly(self._eval(self.duration)[0].copy())

    def _coeffs(self, t_local: float) -> list[list[float]]:  # pragma: no cover - unused
        raise NotImplementedError("RecordingSegment evaluates its spline directly (_eval)")

    def _coeffs_many(self, t_local: np.ndarray) -> np.ndarray:  # pragma: no cover - unused
        raise NotImplementedError("RecordingSegment evaluates its spline directly (sample_many)")

    def _eval(self, t_local: float) -> np.ndarray:
        return self._motion.eval(t_local + self.t0)

    def sample_many(self, t_local: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`sample`; shape (N, 3, n)."""
        tl = np.clip(np.asarray(t_local, dtype=float), 0.0, self.duration)
        return self._motion.eval_many(tl + self.t0)

    def force_at(self, t_local: float) -> tuple[np.ndarray | None, float]:
        """The force target at ``t_local``: (unit direction, magnitude [N]) or (None, 0.0)."""
        if self._force is None:
            return None, 0.0
        t = min(max(t_local, 0.0), self.duration) + self.t0
        k = min(max(bisect.bisect_right(self._raw_list, t) - 1, 0), len(self._raw_list) - 2)
        w = (t - self._raw_list[k]) / (self._raw_list[k + 1] - self._raw_list[k])
        raw = (1.0 - w) * self._raw_abs[k] + w * self._raw_abs[k + 1]
        f = np.where(raw >= self.force_threshold_N, self._force.eval(t)[0], 0.0)
        mag = float(np.linalg.norm(f))
        if mag < self.force_threshold_N:
            return None, 0.0
        return f / mag, mag

    def force_many(self, t_local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`force_at`: directions (N, n) (zeros: no target), magnitudes (N,)."""
        n = np.asarray(t_local).shape[0]
        if self._force is None:
            return np.zeros((n, self.dim)), np.zeros(n)
        t = np.clip(t_local, 0.0, self.duration) + self.t0
        raw = np.column_stack([np.interp(t, self._raw_t, col) for col in self._raw_abs.T])
        f = np.where(raw >= self.force_threshold_N, self._force.eval_many(t)[:, 0, :], 0.0)
        mag = np.linalg.norm(f, axis=1)
        on = mag >= self.force_threshold_N
        direction = np.where(on[:, None], f / np.where(on, mag, 1.0)[:, None], 0.0)
        return direction, np.where(on, mag, 0.0)

    def __repr__(self) -> str:
        return f"RecordingSegment({self.path}, duration={self.duration:.4g} s)"


def _check_orientation(rec: Recording, key: str, tol: float) -> None:
    """Refuse a recording whose orientation moves: P's orientation is constant in ccm."""
    q = rec.orientation
    if q is None:
        return
    if q.shape[1] == 1:
        change = np.abs((q[:, 0] - q[0, 0] + math.pi) % (2.0 * math.pi) - math.pi)
    else:
        qn = q / np.linalg.norm(q, axis=1, keepdims=True)
        change = 2.0 * np.arccos(np.clip(np.abs(qn @ qn[0]), 0.0, 1.0))
    bad = np.flatnonzero(change > tol)
    if bad.size:
        raise ConfigError(
            f"{key}.file",
            f"{rec.path}: row {int(bad[0]) + 1}: orientation turns {float(change[bad[0]]):.3g} rad "
            f"from the first row; a pattern's orientation is constant (limit "
            f"orientation_tol_rad = {tol})",
        )
