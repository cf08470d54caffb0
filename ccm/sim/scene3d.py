"""The 3-D scene every 3-D engine builds (``task.scene``): a table with friction patches,
static boxes (walls, obstacles) and an optional simulated hand on the tool; and the geometry
of the ``boxes`` patch mode. Frozen dataclasses; every error names the offending key.
Nothing here imports a physics engine.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ccm.core.errors import (
    ConfigError,
    check_keys,
    check_nonneg,
    check_positive,
    check_restitution,
    to_plain,
)
from ccm.core.fields import checked, field_values, vector
from ccm.sim.hand import HandSpec

# --------------------------------------------------------------------------- scene


@dataclass(frozen=True)
class TablePatch:
    """A rectangle of the table top with its own friction (seed A Fig. 1a, in 3D).

    Attributes:
        center: [x, y] [m]; size: [w, d] full extents [m]; friction: Coulomb coefficient.
    """

    center: tuple[float, float] = checked(vector(2))
    size: tuple[float, float] = checked(vector(2, positive=True))
    friction: float = checked(check_nonneg)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x0, x1, y0, y1)``."""
        (cx, cy), (w, h) = self.center, self.size
        return cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2


@dataclass(frozen=True)
class TableSpec:
    """A static table: top at ``height`` [m], rectangle ``center ± size/2`` in x, y.

    Attributes:
        height: z of the top surface [m] > 0.
        size: [w, d] [m]; center: [x, y] [m] (default in front of the robot).
        friction: Coulomb coefficient outside the patches; restitution: in [0, 1].
        patches: non-overlapping friction patches inside the table.
    """

    height: float = checked(check_positive, required="is required (z of the table top in m)")
    size: tuple[float, float] = checked(vector(2, positive=True), (0.8, 1.0))
    center: tuple[float, float] = checked(vector(2), (0.6, 0.0))
    friction: float = checked(check_nonneg, 0.5)
    restitution: float = checked(check_restitution, 0.0)
    patches: tuple[TablePatch, ...] = ()

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> TableSpec:
        values, d = field_values(cls, cfg, key)
        table = cls(**values)
        center, size = table.center, table.size
        raw = d.get("patches")
        if raw is None:
            raw = []
        if isinstance(raw, Mapping | str) or not isinstance(raw, Sequence):
            raise ConfigError(f"{key}.patches", f"must be a list, got {type(raw).__name__}")
        tx0, tx1 = center[0] - size[0] / 2, center[0] + size[0] / 2
        ty0, ty1 = center[1] - size[1] / 2, center[1] + size[1] / 2
        patches: list[TablePatch] = []
        for i, pcfg in enumerate(raw):
            pk = f"{key}.patches[{i}]"
            p = TablePatch(**field_values(TablePatch, pcfg, pk)[0])
            x0, x1, y0, y1 = p.bounds()
            eps = 1e-9
            if x0 < tx0 - eps or x1 > tx1 + eps or y0 < ty0 - eps or y1 > ty1 + eps:
                raise ConfigError(f"{pk}.center", "patch must lie inside the table top")
            for j, q in enumerate(patches):
                qx0, qx1, qy0, qy1 = q.bounds()
                if x0 < qx1 - eps and qx0 < x1 - eps and y0 < qy1 - eps and qy0 < y1 - eps:
                    raise ConfigError(f"{pk}.center", f"patch overlaps patches[{j}]")
            patches.append(p)
        return dataclasses.replace(table, patches=tuple(patches))


@dataclass(frozen=True)
class Box3DSpec:
    """A static axis-aligned block (a wall or an obstacle).

    Attributes:
        center: [x, y, z] [m]; size: full extents [m];
        friction: Coulomb coefficient (default 0.5); restitution: in [0, 1] (default 0).
    """

    center: tuple[float, float, float] = checked(vector(3))
    size: tuple[float, float, float] = checked(vector(3, positive=True))
    friction: float = checked(check_nonneg, 0.5)
    restitution: float = checked(check_restitution, 0.0)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> Box3DSpec:
        return cls(**field_values(cls, cfg, key)[0])


@dataclass(frozen=True)
class Scene3D:
    """A 3D scene: an optional table (with friction patches), static boxes and an optional
    simulated human hand on the tool (:class:`ccm.sim.hand.HandSpec`, ``ccm demo``)."""

    table: TableSpec | None = None
    boxes: tuple[Box3DSpec, ...] = ()
    human: HandSpec | None = None

    @classmethod
    def from_mapping(cls, cfg: Any, prefix: str = "task.scene") -> Scene3D:
        """Parse ``{table, boxes}``; keys in errors start with ``prefix``."""
        d = to_plain(cfg, prefix)
        check_keys(prefix, d, ("table", "boxes", "human"))
        table = None
        if d.get("table") is not None:
            table = TableSpec.from_mapping(d["table"], f"{prefix}.table")
        raw = d.get("boxes")
        if raw is None:
            raw = []
        if isinstance(raw, Mapping | str) or not isinstance(raw, Sequence):
            raise ConfigError(f"{prefix}.boxes", f"must be a list, got {type(raw).__name__}")
        boxes = tuple(Box3DSpec.from_mapping(b, f"{prefix}.boxes[{i}]") for i, b in enumerate(raw))
        human = d.get("human")
        if human is not None:
            human = HandSpec.from_mapping(human, f"{prefix}.human", 3)
        return cls(table=table, boxes=boxes, human=human)


# --------------------------------------------------------------------------- geometry


def grid_cells(
    bounds: tuple[float, float, float, float], holes: Sequence[tuple[float, float, float, float]]
) -> list[tuple[float, float, float, float]]:
    """Cells ``(x0, x1, y0, y1)`` of the grid spanned by the holes' edges that no hole covers."""
    bx0, bx1, by0, by1 = bounds
    xs = sorted({bx0, bx1, *(v for h in holes for v in h[:2])})
    ys = sorted({by0, by1, *(v for h in holes for v in h[2:])})
    cells = []
    for x0, x1 in zip(xs, xs[1:], strict=False):
        for y0, y1 in zip(ys, ys[1:], strict=False):
            if x1 - x0 < 1e-9 or y1 - y0 < 1e-9:
                continue
            mx, my = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
            if not any(h[0] < mx < h[1] and h[2] < my < h[3] for h in holes):
                cells.append((x0, x1, y0, y1))
    return cells


def boxed_table_parts(
    table: TableSpec,
) -> list[tuple[tuple[float, float, float], tuple[float, float, float], float, bool]]:
    """``patch_mode: boxes``: the static boxes that make up the table, in creation order.

    A base slab, the top layer (1 cm, or half the height if less) cut around the patches
    into the cells of :func:`grid_cells`, then one box per patch flush with the top.

    Returns:
        ``(center, half_extents, friction, is_patch)`` per box [m].
    """
    layer = min(0.01, table.height / 2.0)  # thickness of the top layer [m]
    (cx, cy), (w, d) = table.center, table.size
    base_h = table.height - layer
    parts = [((cx, cy, base_h / 2.0), (w / 2, d / 2, base_h / 2), table.friction, False)]
    bounds = (cx - w / 2, cx + w / 2, cy - d / 2, cy + d / 2)
    zc = table.height - layer / 2.0

    def cell(x0: float, x1: float, y0: float, y1: float) -> tuple[Any, Any]:
        return ((x0 + x1) / 2, (y0 + y1) / 2, zc), ((x1 - x0) / 2, (y1 - y0) / 2, layer / 2)

    holes = [pt.bounds() for pt in table.patches]
    for c in grid_cells(bounds, holes):
        parts.append((*cell(*c), table.friction, False))
    for pt in table.patches:
        parts.append((*cell(*pt.bounds()), pt.friction, True))
    return parts
