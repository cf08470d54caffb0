"""Parsing helpers and the region shape shared by the 2D scene specs (:mod:`ccm.sim.pymunk.scene`,
:mod:`ccm.sim.pymunk.hri`): a 2-vector, a list (a config mapping as a plain dict is
:func:`ccm.core.errors.to_plain`)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from ccm.core.errors import (
    ConfigError,
    check_keys,
    check_nonneg,
    check_positive,
    check_vector,
    to_plain,
)

Vec2 = tuple[float, float]


def vec2(key: str, value: Any) -> Vec2:
    """``value`` as a finite 2-vector ``(x, y)``; ConfigError naming ``key`` otherwise."""
    arr = check_vector(key, value, 2)
    return (float(arr[0]), float(arr[1]))


def positive_vec2(key: str, value: Any) -> Vec2:
    """A 2-vector whose entries are > 0 (errors name ``key[i]``)."""
    out = vec2(key, value)
    for i, v in enumerate(out):
        check_positive(f"{key}[{i}]", v)
    return out


def nonneg_vec2(key: str, value: Any) -> Vec2:
    """A 2-vector whose entries are >= 0 (errors name ``key[i]``)."""
    out = vec2(key, value)
    for i, v in enumerate(out):
        check_nonneg(f"{key}[{i}]", v)
    return out


def as_list(key: str, value: Any) -> list[Any]:
    """``value`` as a list (None: empty); ConfigError naming ``key`` if it is not a list."""
    if value is None:
        return []
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, Iterable):
        raise ConfigError(key, f"must be a list, got {value!r}")
    return list(value)


@dataclass(frozen=True)
class RegionSpec:
    """Axis-aligned rectangle ``center ± half_extents`` [m]."""

    center: Vec2
    half_extents: Vec2

    def contains(self, x: float, y: float) -> bool:
        """True if the point (x, y) lies inside the rectangle (boundary included)."""
        return (
            abs(x - self.center[0]) <= self.half_extents[0]
            and abs(y - self.center[1]) <= self.half_extents[1]
        )

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> RegionSpec:
        """Parse ``{center, half_extents}`` (both required; half extents > 0)."""
        d = to_plain(cfg, key)
        check_keys(key, d, ("center", "half_extents"))
        for req in ("center", "half_extents"):
            if req not in d:
                raise ConfigError(f"{key}.{req}", "is required")
        half = vec2(f"{key}.half_extents", d["half_extents"])
        for i, h in enumerate(half):
            check_positive(f"{key}.half_extents[{i}]", h)
        return cls(center=vec2(f"{key}.center", d["center"]), half_extents=half)
