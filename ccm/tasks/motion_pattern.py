"""The target motion pattern P of seed A (§3, opening): consecutive smooth pose (and force)
target segments (:mod:`ccm.tasks.segments`) joined into one mapping from time to the target.

:class:`MotionPattern` samples P at one time into the one reusable :class:`TargetSample` of a
trial (issue #40, :func:`reusable_sample`) or at many times at once; :mod:`ccm.tasks.trajectory`
builds it from its YAML description.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence

import numpy as np

from ccm.core.errors import ConfigError, check_vector
from ccm.core.types import TargetSample
from ccm.core.vector import readonly
from ccm.tasks.segments import Segment, unit_vector

__all__ = ["MotionPattern", "reusable_sample"]


def reusable_sample(dim: int, orientation: np.ndarray) -> tuple[np.ndarray, TargetSample]:
    """(buffer, sample): the one ``TargetSample`` a pattern updates in place (issue #40),
    its position, velocity and acceleration read-only views of the buffer's three rows, which
    only the pattern writes."""
    buf = np.zeros((3, dim))
    pos, vel, acc = (readonly(buf[i]) for i in range(3))
    return buf, TargetSample(0.0, pos, vel, acc, orientation)


class MotionPattern:
    """A target motion pattern P: consecutive segments plus a constant orientation target.

    Seed A §3: P maps time to end-effector pose and (where force is controlled) force targets.
    Segments must join: each starts where the previous one ended.

    Args:
        segments: non-empty sequence of segments of the same dimension.
        orientation: 2D: angle [rad], shape (1,); 3D: quaternion (x, y, z, w), normalised here.
        key: configuration key used in error messages.
    """

    def __init__(
        self,
        segments: Sequence[Segment],
        orientation: Sequence[float] | np.ndarray,
        *,
        key: str = "pattern",
    ) -> None:
        if len(segments) == 0:
            raise ConfigError(key, "must contain at least one segment")
        self.segments: tuple[Segment, ...] = tuple(segments)
        self.dim = self.segments[0].dim
        for i, (prev, seg) in enumerate(zip(self.segments[:-1], self.segments[1:], strict=True)):
            if seg.dim != self.dim:
                raise ConfigError(
                    f"{key}[{i + 1}]", f"dimension {seg.dim} differs from the pattern's {self.dim}"
                )
            gap = float(np.linalg.norm(seg.start - prev.end))
            if gap > 1e-9:
                raise ConfigError(
                    f"{key}[{i + 1}]",
                    f"starts at {seg.start.tolist()}, {gap:.3g} m from the previous end "
                    f"{prev.end.tolist()}",
                )
        okey = (key.rsplit(".", 1)[0] + "." if "." in key else "") + "orientation"
        if self.dim == 2:
            self.orientation = readonly(check_vector(okey, orientation, 1))
        else:
            self.orientation = readonly(unit_vector(okey, orientation, 4))
        starts = [0.0]
        for seg in self.segments:
            starts.append(starts[-1] + seg.duration)
        self.duration: float = starts[-1]
        #: start time of each segment [s] (ascending; len == number of segments)
        self.start_times: tuple[float, ...] = tuple(starts[:-1])
        self._starts = list(self.start_times)
        self._starts_arr = np.asarray(self._starts)
        self.start: np.ndarray = self.segments[0].start
        self.end: np.ndarray = self.segments[-1].end
        last = self.segments[-1]
        zeros = np.zeros(self.dim)
        self._final = (
            readonly(self.end.copy()),
            readonly(zeros.copy()),
            readonly(zeros.copy()),
        )
        self._final_force = (
            last.force_at(last.duration) if last.varying_force else (last.force_dir, last.force_mag)
        )
        self._buf, self._sample = reusable_sample(self.dim, self.orientation)

    def __len__(self) -> int:
        return len(self.segments)

    def segment_index(self, t: float) -> int:
        """Index of the segment active at time ``t`` (a boundary belongs to the later segment)."""
        i = bisect.bisect_right(self._starts, t) - 1
        return 0 if i < 0 else i

    def sample(self, t: float) -> TargetSample:
        """Evaluate P at time ``t`` [s] (clipped to [0, duration]; ``TargetSample.t`` is ``t``).

        At and after the end the final pose is returned with zero velocity and acceleration,
        the last segment's force target and ``done=True``. The same object every call,
        updated in place: valid until the next call (issue #40, :mod:`ccm.core.types`).
        """
        buf = self._buf
        if t >= self.duration:
            n = len(self.segments) - 1
            fd, fm = self._final_force
            buf[...] = self._final
            return self._set(t, fd, fm, n, True)
        if t >= 0.0:
            t_eval = t
            i = bisect.bisect_right(self._starts, t) - 1
        elif t < 0.0:
            t_eval = 0.0
            i = 0
        else:
            raise ValueError(f"MotionPattern.sample: t must be a number, got {t!r}")
        seg = self.segments[i]
        buf[...] = seg._eval(t_eval - self._starts[i])
        if seg.varying_force:  # a recording: the force target changes within the segment
            fd, fm = seg.force_at(t_eval - self._starts[i])
            return self._set(t, fd, fm, i, False)
        return self._set(t, seg.force_dir, seg.force_mag, i, False)

    def _set(
        self, t: float, force_dir: np.ndarray | None, force_mag: float, segment: int, done: bool
    ) -> TargetSample:
        """The sample's scalar fields and force direction, for :meth:`sample`."""
        out = self._sample
        out.t, out.force_dir, out.force_mag, out.segment, out.done = (
            t,
            force_dir,
            force_mag,
            segment,
            done,
        )
        return out

    def sample_many(self, ts: Sequence[float] | np.ndarray) -> dict[str, np.ndarray]:
        """Vectorised :meth:`sample` for plotting and analysis.

        Args:
            ts: times [s], shape (N,).

        Returns:
            dict with ``t`` (N,), ``position``/``velocity``/``acceleration`` (N, n),
            ``segment`` (N,) int, ``done`` (N,) bool, ``force_active`` (N,) bool,
            ``force_dir`` (N, n) (zeros where no force is controlled) and ``force_mag`` (N,).
        """
        t = np.asarray(ts, dtype=float).reshape(-1)
        tc = np.clip(t, 0.0, self.duration)
        if np.any(np.isnan(t)):
            raise ValueError("MotionPattern.sample_many: times must not be NaN")
        idx = np.searchsorted(self._starts_arr, tc, side="right") - 1
        idx = np.clip(idx, 0, len(self.segments) - 1)
        pva = np.zeros((t.shape[0], 3, self.dim))
        force_dir = np.zeros((t.shape[0], self.dim))
        force_mag = np.zeros(t.shape[0])
        force_active = np.zeros(t.shape[0], dtype=bool)
        for i, seg in enumerate(self.segments):
            m = idx == i
            if not np.any(m):
                continue
            pva[m] = seg.sample_many(tc[m] - self._starts[i])
            if seg.varying_force:
                force_dir[m], force_mag[m] = seg.force_many(tc[m] - self._starts[i])
                force_active[m] = force_mag[m] > 0.0
            elif seg.force_dir is not None:
                force_dir[m] = seg.force_dir
                force_mag[m] = seg.force_mag
                force_active[m] = True
        done = t >= self.duration
        pva[done, 0] = self.end
        pva[done, 1:] = 0.0
        return {
            "t": t,
            "position": pva[:, 0],
            "velocity": pva[:, 1],
            "acceleration": pva[:, 2],
            "segment": idx,
            "done": done,
            "force_active": force_active,
            "force_dir": force_dir,
            "force_mag": force_mag,
        }

    def __repr__(self) -> str:
        return f"MotionPattern({len(self.segments)} segments, duration={self.duration} s)"
