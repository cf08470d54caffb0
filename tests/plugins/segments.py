"""Plugin motion segments for ``tests/test_plugins.py``: one that works, two that break."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ccm.tasks.segments import Segment


class Wave(Segment):
    """One period of a sine along ``axis``: x(t) = start + a sin(2π t / T) axis, back where it
    began (basis: the start and the axis; coefficients per row of position, velocity,
    acceleration)."""

    def __init__(self, start: np.ndarray, duration: float, force_dir: np.ndarray | None,
                 force_mag: float, name: str | None, amplitude: float = 0.01,
                 axis: Sequence[float] = (1.0, 0.0)) -> None:  # fmt: skip
        super().__init__(duration, len(start), force_dir, force_mag, name, "wave")
        self.amplitude = float(amplitude)
        unit = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        self._basis = np.vstack([np.asarray(start, dtype=float), unit])
        self._finish()

    def _coeffs(self, t_local: float) -> list[list[float]]:
        w = 2.0 * math.pi / self.duration
        a = self.amplitude
        return [[1.0, a * math.sin(w * t_local)], [0.0, a * w * math.cos(w * t_local)],
                [0.0, -a * w * w * math.sin(w * t_local)]]  # fmt: skip

    def _coeffs_many(self, t_local: np.ndarray) -> np.ndarray:
        return np.array([self._coeffs(float(t)) for t in t_local])


class Elsewhere(Wave):
    """Starts 1 m away from where it is put: a broken promise."""

    def __init__(self, start: np.ndarray, *args: object, **kwargs: object) -> None:
        super().__init__(np.asarray(start) + 1.0, *args, **kwargs)  # type: ignore[arg-type]


class Picky(Wave):
    """Refuses every parameter set with a plain exception."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        raise ValueError("amplitude must be in furlongs")
