"""The static world of the PyBullet backend: the table with its friction patches, and boxes.

``patch_mode`` (module docstring of :mod:`ccm.sim.pybullet.backend`) decides how patches are
built: ``friction_map`` and ``footprint`` keep one table box whose friction the backend
changes under the tool (patches drawn as visual-only boxes in the GUI); ``boxes`` cuts the
table's top layer around thin patch boxes. Bodies are created in a fixed order (table,
patches, boxes), so their ids are the same on every reset.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from ccm.sim.scene3d import Scene3D, boxed_table_parts

_GREY = (0.6, 0.5, 0.4, 1.0)
_BLUE = (0.2, 0.4, 0.8, 1.0)
_BOX = (0.5, 0.5, 0.5, 1.0)


@dataclass
class World:
    """What the backend keeps of the static world.

    Attributes:
        body_friction: friction coefficient of each static body (contact ground truth).
        table_body: the table's body id (-1: none, or ``boxes`` mode).
        table_mu: the table's friction when one box carries it (None otherwise).
        patch_map: (x0, x1, y0, y1, μ) of each patch for the friction under the tool.
        box_bodies: ids of the scene's boxes.
    """

    body_friction: dict[int, float] = field(default_factory=dict)
    table_body: int = -1
    table_mu: float | None = None
    patch_map: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    box_bodies: set[int] = field(default_factory=set)


def build_world(p: Any, cid: int, scene: Scene3D, patch_mode: str, gui: bool) -> World:
    """Create the table (per ``patch_mode``) and the boxes of ``scene`` in client ``cid``."""
    world = World()
    table = scene.table
    if table is not None:
        (cx, cy), (w, d) = table.center, table.size
        if patch_mode != "boxes" or not table.patches:
            h = table.height
            world.table_body = _static_box(
                p, cid, world, (cx, cy, h / 2.0), (w / 2, d / 2, h / 2), table.friction,
                table.restitution, _GREY, gui,
            )  # fmt: skip
            for pt in table.patches:
                world.patch_map.append((*pt.bounds(), pt.friction))
                if gui:  # visual only, 0.2 mm proud so it shows
                    x0, x1, y0, y1 = pt.bounds()
                    centre = ((x0 + x1) / 2, (y0 + y1) / 2, h)
                    _visual_box(p, cid, centre, ((x1 - x0) / 2, (y1 - y0) / 2, 2e-4), _BLUE)
            world.table_mu = table.friction
        else:  # base slab, top layer cut around the patches, patch boxes
            for center, half, mu, is_patch in boxed_table_parts(table):
                colour = _BLUE if is_patch else _GREY
                _static_box(p, cid, world, center, half, mu, table.restitution, colour, gui)
    for b in scene.boxes:
        half = [s / 2.0 for s in b.size]
        world.box_bodies.add(
            _static_box(p, cid, world, b.center, half, b.friction, b.restitution, _BOX, gui)
        )
    return world


def _static_box(
    p: Any,
    cid: int,
    world: World,
    center: Sequence[float],
    half: Sequence[float],
    friction: float,
    restitution: float,
    rgba: Sequence[float],
    gui: bool,
) -> int:
    """A fixed box (collision shape; a visual one in the GUI) with its friction recorded."""
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=cid)
    vis = -1
    if gui:
        vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba), physicsClientId=cid
        )
    body = p.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=col,
        baseVisualShapeIndex=vis,
        basePosition=list(center),
        physicsClientId=cid,
    )
    p.changeDynamics(
        body, -1, lateralFriction=friction, restitution=restitution, physicsClientId=cid
    )
    world.body_friction[body] = friction
    return body


def _visual_box(
    p: Any, cid: int, center: Sequence[float], half: Sequence[float], rgba: Sequence[float]
) -> None:
    vis = p.createVisualShape(
        p.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba), physicsClientId=cid
    )
    p.createMultiBody(
        baseMass=0.0, baseVisualShapeIndex=vis, basePosition=list(center), physicsClientId=cid
    )
