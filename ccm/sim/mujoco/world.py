"""The static world of the MuJoCo backend (issue #42): the scene's table with its friction
patches, and its boxes, added to the model specification as fixed box geoms.

It mirrors :mod:`ccm.sim.pybullet.world`: ``patch_mode`` ``boxes`` cuts the table's top layer
around thin patch boxes (:func:`ccm.sim.scene3d.boxed_table_parts`); the other modes keep
one table box and record the patches for the friction under the tool. Engine facts behind
the contact settings, each measured (``tests/test_mujoco_world.py``):

* **MuJoCo's contacts are acceleration-level.** A contact is a soft constraint whose
  reference acceleration is ``−b v − k r`` (penetration r, its rate v): the force it gives is
  k and b times the mass the contact moves. With MuJoCo's direct ``solref = (−k, −b)`` and
  ``solimp = (0, 0, …)`` (the impedance at its floor, so the reference is the whole
  response), a box of mass m resting on its face (4 contact points) is 4 k m stiff, and
  first touching at speed v it pushes 4 b m v: a per-point spring-damper k m, b m (measured
  at m = 0.15, 1 and 10 kg). So a contact stiffness K [N/m] and damping C [N s/m] per point,
  the PyBullet backend's settings (``sim.contact_stiffness`` / ``contact_damping``), are
  ``k = K / m_c`` and ``b = C / m_c`` for a contact mass m_c (:func:`contact_params`): exact
  for a body of that mass; for the tool on the arm, m_c is the mass the arm presents at a
  contact point, which changes with its configuration (``sim.contact_mass_kg`` says where the
  backend's value was measured). MuJoCo's default ``solimp`` (0.9, 0.95, …) would make the
  contact ~9× stiffer and nonlinear over its first millimetre.
* **The elliptic cone.** With the default pyramidal cone the direct ``solref`` acts on the
  pyramid's edges, so the normal response depends on μ (measured: a box dropped 4 mm is
  thrown off at 6-100 m/s for μ = 0.2-0.5, and rests 4k stiff only at μ = 1); with the
  elliptic cone, which :func:`add_world` sets, it rests 4 k m stiff at every μ.
* **Damping is explicit.** The reference acceleration uses the current velocity, so the
  damping must stay well inside one step: at 1 kHz, b = 1000 /s (the 1 kg box at C = 1000
  N s/m) throws the box off, and the Panda's tool held with 10 N on the table chatters at
  b ≈ 250 /s (C = 600 N s/m on the backend's contact mass: force std 2.1 N; 4.7 N at C =
  1000) and not at 126 /s (``configs/sim/mujoco3d.yaml`` has the numbers behind the
  backend's default).
* **The surface's friction.** A contact pair (:func:`add_pairs`) carries the static geom's
  coefficient, as PyBullet's multiplication by the tool's 1 gives; for MuJoCo's automatic
  contacts (a free body in the tests) static geoms get ``priority`` 1, so those too take the
  surface's coefficient and ``solref`` rather than the larger of the two. MuJoCo's friction
  is soft: below μ N a pushed body creeps (mm/s) rather than sticks, and sliding it passes a
  little less than μ N; the PyBullet backend's Coulomb friction sticks.
* **The cone couples friction into the normal force.** In MuJoCo's soft contact a sliding
  contact sits on the elliptic cone's surface, where the normal force is
  ``m (k r + b v_n + μ b_f |v_t|) / (1 + μ_r²)`` (MuJoCo's ``mj_constraintUpdate``, middle
  zone; ``b_f`` the friction rows' damping, ``μ_r = μ / √impratio``): the slip speed v_t lifts
  the contact. With ``b_f = b`` (MuJoCo's default) the Panda's tool pressed with 10 N rose
  from 25 µm to 10 µm penetration at 6 cm/s, and from 0.1 m/s it left the table and fell
  back (normal-force std 3.4 N at 0.1 m/s, 6.4 N at 0.15; PyBullet 0.11, 0.31; measured).
  :func:`add_pairs` therefore gives the friction rows ``b_f = b / impratio`` and the cone
  ``impratio``: a sticking contact keeps the viscosity ``C`` per point (its friction rows'
  impedance is ``impratio`` times the normal's), and the lift falls ``impratio`` times
  (``sim.impratio`` says what was measured). MuJoCo sets ``solreffriction`` only on explicit
  contact pairs, so every robot geom meets every static geom through a pair.
* **Collisions.** Only those pairs make contacts: the robot's geoms have ``contype`` and
  ``conaffinity`` 0 (:mod:`ccm.sim.mujoco.model`), so they do not collide with each other, as
  PyBullet does without self-collision; static geoms (``contype`` 0, ``conaffinity`` 1) do
  not collide with each other.
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
        table_pairs: the contact pairs of ``table_geom`` (:func:`add_pairs`), whose friction
            the backend sets under the tool.
    """

    geom_friction: dict[str, float] = field(default_factory=dict)
    table_geom: str = ""
    patch_map: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    box_geoms: list[str] = field(default_factory=list)
    table_pairs: list[str] = field(default_factory=list)


def contact_params(stiffness: float, damping: float, mass: float) -> dict[str, list[float]]:
    """``solref``/``solimp`` of a geom whose contacts are a spring ``stiffness`` [N/m] and a
    damper ``damping`` [N s/m] per contact point on a body of contact mass ``mass`` [kg]:
    ``solref = (−K/m_c, −C/m_c)`` (module docstring)."""
    return {"solref": [-stiffness / mass, -damping / mass], "solimp": list(SOLIMP)}


def friction_params(damping: float, mass: float, impratio: float) -> dict[str, list[float]]:
    """``solreffriction`` of a contact pair whose friction rows keep a sticking viscosity of
    ``damping`` [N s/m] per point on contact mass ``mass`` [kg] under the cone's ``impratio``:
    ``b_f = C / (m_c · impratio)`` (module docstring; MuJoCo ignores a friction row's
    stiffness)."""
    return {"solreffriction": [0.0, -damping / (mass * impratio)]}


def add_pairs(spec: mujoco.MjSpec, world: World, robot_geoms: Sequence[str], stiffness: float,
              damping: float, mass: float, impratio: float) -> None:  # fmt: skip
    """A contact pair of every robot geom with every static geom of ``world``: the static
    geom's friction, the contact of :func:`contact_params`, the friction rows of
    :func:`friction_params`; and the model's ``impratio`` (module docstring)."""
    spec.option.impratio = impratio
    contact = {**contact_params(stiffness, damping, mass),
               **friction_params(damping, mass, impratio)}  # fmt: skip
    for static, mu in world.geom_friction.items():
        for geom in robot_geoms:
            name = f"{geom}|{static}"
            spec.add_pair(name=name, geomname1=static, geomname2=geom, condim=3,
                          friction=[mu, mu, _SPIN, _ROLL, _ROLL], **contact)  # fmt: skip
            if static == world.table_geom:
                world.table_pairs.append(name)


def add_world(spec: mujoco.MjSpec, scene: Scene3D, patch_mode: str, stiffness: float,
              damping: float, mass: float) -> World:  # fmt: skip
    """Add the table (per ``patch_mode``) and the boxes of ``scene`` to ``spec``, their
    contacts per point a spring ``stiffness`` and damper ``damping`` on contact mass ``mass``,
    and set the elliptic friction cone their contact model needs (module docstring)."""
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    world = World()
    contact = contact_params(stiffness, damping, mass)
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
        friction=[float(friction), _SPIN, _ROLL], priority=1, contype=0, conaffinity=1,
        **contact,
    )  # fmt: skip
    world.geom_friction[name] = float(friction)
    return name
