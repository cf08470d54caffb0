"""The static world of the MuJoCo backend (issue #42): the scene's table with its friction
patches, and its boxes, added to the model specification as fixed box geoms.

It mirrors :mod:`ccm.sim.pybullet.world`: ``patch_mode`` ``boxes`` cuts the table's top layer
around thin patch boxes (:func:`ccm.sim.scene3d.boxed_table_parts`); the other modes keep
one table box and record the patches for the friction under the tool. Two engine facts make
the contacts the PyBullet backend's:

* **Contact stiffness and damping per contact point.** Every static geom gets MuJoCo's direct
  ``solref = (−k, −c)`` with ``solimp = (0, 0, …)``: measured, a box resting on its face (4
  contact points) is then 4k stiff and its first touch at speed v pushes 4c·v, the
  per-point spring-damper of the PyBullet backend (``sim.contact_stiffness`` /
  ``contact_damping``). MuJoCo's default ``solimp`` would make it ~9× stiffer. This needs
  the *elliptic* friction cone, which :func:`add_world` sets: with the default pyramidal one
  the direct ``solref`` acts on the pyramid's edges, so the normal response depends on μ
  (measured: a box dropped 4 mm is thrown off at 6-100 m/s for μ = 0.2-0.5, and rests 4k
  stiff only at μ = 1); with the elliptic cone it rests 4k stiff at every μ.
* **The surface's friction.** MuJoCo takes the larger friction of two geoms, or the one of
  the geom with the higher ``priority``: static geoms get priority 1, so a contact has the
  surface's coefficient, as PyBullet's multiplication by the tool's 1 gives. MuJoCo's
  friction is soft: below μ N a pushed body creeps (mm/s) rather than sticks, and sliding
  it passes a little less than μ N (``tests/test_mujoco_world.py`` has the numbers); the
  PyBullet backend's Coulomb friction sticks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco

from ccm.sim.scene3d import Scene3D, boxed_table_parts

#: MuJoCo's impedance settings that give the direct solref its per-point meaning (above)
SOLIMP = (0.0, 0.0, 0.001, 0.5, 2.0)
#: rolling and torsional friction left at MuJoCo's small defaults' scale (the sliding one is set)
_SPIN, _ROLL = 0.005, 0.0001


@dataclass
class World:
    """What the backend keeps of the static world (geom names, as ids change per model).

    Attributes:
        geom_friction: the sliding friction of each static geom, by name.
        table_geom: the table's geom when one box carries it ("" otherwise).
        patch_map: (x0, x1, y0, y1, μ) of each patch for the friction under the tool.
        box_geoms: the names of the scene's boxes.
    """

    geom_friction: dict[str, float] = field(default_factory=dict)
    table_geom: str = ""
    patch_map: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    box_geoms: list[str] = field(default_factory=list)


def contact_params(stiffness: float, damping: float) -> dict[str, list[float]]:
    """``solref``/``solimp`` of a geom whose contacts are a spring ``stiffness`` [N/m] and a
    damper ``damping`` [N s/m] per contact point (module docstring)."""
    return {"solref": [-float(stiffness), -float(damping)], "solimp": list(SOLIMP)}


def add_world(spec: mujoco.MjSpec, scene: Scene3D, patch_mode: str, stiffness: float,
              damping: float) -> World:  # fmt: skip
    """Add the table (per ``patch_mode``) and the boxes of ``scene`` to ``spec``, and set
    the elliptic friction cone their contact model needs (module docstring)."""
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    world = World()
    contact = contact_params(stiffness, damping)
    table = scene.table
    if table is not None:
        (cx, cy), (w, d) = table.center, table.size
        if patch_mode != "boxes" or not table.patches:
            h = table.height
            world.table_geom = _box(spec, world, "table", (cx, cy, h / 2.0),
                                    (w / 2, d / 2, h / 2), table.friction, contact)  # fmt: skip
            world.patch_map = [(*pt.bounds(), pt.friction) for pt in table.patches]
        else:  # base slab, top layer cut around the patches, patch boxes
            for i, (center, half, mu, is_patch) in enumerate(boxed_table_parts(table)):
                _box(spec, world, f"table_{'patch' if is_patch else 'part'}_{i}", center,
                     half, mu, contact)  # fmt: skip
    for i, b in enumerate(scene.boxes):
        half = [s / 2.0 for s in b.size]
        world.box_geoms.append(_box(spec, world, f"box_{i}", b.center, half, b.friction, contact))
    return world


def _box(
    spec: mujoco.MjSpec, world: World, name: str, center: Sequence[float],
    half: Sequence[float], friction: float, contact: dict[str, list[float]],
) -> str:  # fmt: skip
    """A fixed box geom in the world body, its friction recorded; returns its name."""
    spec.worldbody.add_geom(
        name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(center), size=list(half),
        friction=[float(friction), _SPIN, _ROLL], priority=1, **contact,
    )  # fmt: skip
    world.geom_friction[name] = float(friction)
    return name
