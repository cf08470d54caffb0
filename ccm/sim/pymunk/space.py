"""The Chipmunk space of :class:`ccm.sim.pymunk.backend.Pymunk2D`, built from the scene.

The static scene (surfaces split into friction pieces that Chipmunk treats as one line, boxes)
and the end-effector box, in SI units (``collision_slop`` and ``iterations`` from the config:
pymunk's defaults assume pixels). The EE's shape has friction 1.0 and elasticity 1.0, so
pymunk's multiplicative combination makes the surface's values the effective contact values.
"""

from __future__ import annotations

import pymunk

from ccm.sim.pymunk.config import Pymunk2DConfig
from ccm.sim.pymunk.scene import SceneSpec

__all__ = ["build_space"]


def build_space(
    scene: SceneSpec, cfg: Pymunk2DConfig, start: tuple[float, float, float]
) -> tuple[pymunk.Space, pymunk.Body]:
    """A fresh space with the static scene and the EE at ``start`` at rest.

    Args:
        scene: The parsed scene (surfaces, boxes, the end-effector, gravity).
        cfg: The backend settings (``iterations``, ``collision_slop``).
        start: The EE's start pose (x, y, angle) [m, rad].

    Returns:
        The space and the EE's body in it.
    """
    space = pymunk.Space()
    space.iterations = cfg.iterations
    space.collision_slop = cfg.collision_slop
    space.gravity = (0.0, -scene.gravity)
    static = space.static_body
    for surf in scene.surfaces:
        ax, ay = surf.a
        ux, uy = (surf.b[0] - ax) / surf.length, (surf.b[1] - ay) / surf.length
        pieces = []
        for s0, s1, mu in surf.pieces():
            seg = pymunk.Segment(
                static, (ax + ux * s0, ay + uy * s0), (ax + ux * s1, ay + uy * s1), surf.radius
            )
            seg.friction = mu
            seg.elasticity = surf.restitution
            pieces.append(seg)
        # Tell Chipmunk the pieces form one line so the EE does not catch on the joints.
        # A piece's own endpoint as neighbour means "no neighbour" (zero tangent).
        for i, seg in enumerate(pieces):
            last = i + 1 == len(pieces)
            seg.set_neighbors(pieces[i - 1].a if i else seg.a, seg.b if last else pieces[i + 1].b)
        space.add(*pieces)
    for box in scene.boxes:
        (cx, cy), (w, h) = box.center, box.size
        verts = [(cx - w / 2, cy - h / 2), (cx + w / 2, cy - h / 2),
                 (cx + w / 2, cy + h / 2), (cx - w / 2, cy + h / 2)]  # fmt: skip
        poly = pymunk.Poly(static, verts)
        poly.friction = box.friction
        poly.elasticity = box.restitution
        space.add(poly)
    ee = scene.ee
    moment = pymunk.moment_for_box(ee.mass, ee.size) if ee.rotate else float("inf")
    body = pymunk.Body(ee.mass, moment)
    body.position = (start[0], start[1])
    body.angle = start[2]
    shape = pymunk.Poly.create_box(body, ee.size)
    # Multiplicative combination: the surface's friction/restitution become effective.
    shape.friction = 1.0
    shape.elasticity = 1.0
    space.add(body, shape)
    return space, body
