"""The MuJoCo backend's static world (issue #42): the scene's geoms where the PyBullet
backend puts its bodies, contacts that are the same per-point spring-damper on the contact
mass they are mapped for (and scale with the mass, MuJoCo's contacts being acceleration
level), and the surface's own friction coefficient.

Each physics check uses a free box (a 4 cm cube, 1 kg unless stated) dropped or pushed on the
table, with the physics' known answers: at rest on its face (4 contact points, gravity 9.81 N)
it sinks 9.81 / (4k); pushed sideways with a force F it slides at (F − μ m g) / m above μ m g.
Below it, MuJoCo's soft friction has no position term: the box creeps instead of sticking
(measured at c = 100 N s/m per point and 0.9 μ m g, after 0.3 s: 4.8 mm/s at μ = 0.2, 9.6 at
0.35, 15 at 0.5, against 0.53 m/s without friction; PyBullet's Coulomb friction sticks). The
agreement tests with PyBullet will have to allow for that creep, or the backend add stiction.
Sliding, the soft friction passes a little less than μ N: the box gains up to 12 % more speed
than Coulomb's (F − μ m g) / m gives (measured, μ = 0.35 and 0.5).

Sliding on the cone's surface, the box sinks ``r₀ (1 + μ_r²) − μ b_f v / k`` instead of r₀
(:mod:`ccm.sim.mujoco.world`): at μ = 0.2, b = 100 /s, k = 1e4 /s², v = 0.1 m/s, 55.0 µm
of the 245.2 at rest with MuJoCo's default friction rows (impratio 1, b_f = b), and 243.3 µm
through :func:`ccm.sim.mujoco.world.add_pairs` at impratio 100 (measured: 55.10, 243.38)."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from ccm.sim.mujoco.world import add_pairs, add_world, contact_params  # noqa: E402
from ccm.sim.scene3d import Scene3D  # noqa: E402

TABLE = {
    "height": 0.1,
    "friction": 0.2,
    "patches": [
        {"center": [0.53, 0.0], "size": [0.10, 0.4], "friction": 0.5},
        {"center": [0.63, 0.0], "size": [0.10, 0.4], "friction": 0.35},
    ],
}  # as changing_surface
WALL = {"center": [0.75, 0.0, 0.2], "size": [0.02, 0.4, 0.2], "friction": 0.9}


def _world(mode: str, k: float = 1.0e4, c: float = 100.0, x: float = 0.4, mass: float = 1.0,
           mapped: float = 1.0, impratio: float | None = None):  # fmt: skip
    """A model with the scene, its contacts mapped for contact mass ``mapped`` [kg], and a
    free box of ``mass`` resting (4 mm above) the table at x; with ``impratio``, the box
    meets the world through the backend's contact pairs (:func:`add_pairs`) instead of
    MuJoCo's automatic contacts."""
    scene = Scene3D.from_mapping({"table": TABLE, "boxes": [WALL]})
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.001
    spec.option.gravity = [0.0, 0.0, -9.81]
    world = add_world(spec, scene, mode, k, c, mapped)
    body = spec.worldbody.add_body(name="probe", pos=[x, 0.0, 0.1 + 0.02 + 0.004])
    body.add_freejoint()
    paired = {"contype": 0, "conaffinity": 0} if impratio is not None else {}
    body.add_geom(name="probe", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02] * 3, mass=mass,
                  friction=[1, 0, 0], **contact_params(k, c, mapped), **paired)  # fmt: skip
    if impratio is not None:
        add_pairs(spec, world, ["probe"], k, c, mapped, impratio)
    model = spec.compile()
    return model, mujoco.MjData(model), world


def test_geoms_are_the_scenes_boxes() -> None:
    """One table box with the patches recorded (friction_map), or the cut table of the
    boxes mode with the patch boxes flush with the top, and the wall, each with its
    friction."""
    model, _, world = _world("friction_map")
    table = model.geom("table")
    np.testing.assert_allclose(table.size, [0.4, 0.5, 0.05])  # half extents, table default
    np.testing.assert_allclose(table.pos, [0.6, 0.0, 0.05])
    patches = [(0.48, 0.58, -0.2, 0.2, 0.5), (0.58, 0.68, -0.2, 0.2, 0.35)]
    np.testing.assert_allclose(world.patch_map, patches, atol=1e-12)
    wall = model.geom(world.box_geoms[0])
    np.testing.assert_allclose(wall.pos, WALL["center"])
    np.testing.assert_allclose(wall.size, [0.01, 0.2, 0.1])
    assert wall.friction[0] == 0.9 and world.geom_friction["box_0"] == 0.9
    model, _, world = _world("boxes")
    patches = [n for n in world.geom_friction if "patch" in n]
    assert [world.geom_friction[n] for n in patches] == [0.5, 0.35]
    for n in patches:
        g = model.geom(n)
        assert g.pos[2] + g.size[2] == pytest.approx(0.1)  # flush with the top


@pytest.mark.parametrize(("k", "mass"), [(1.0e4, 1.0), (1.125e4, 1.0), (1.0e5, 1.0), (1.0e4, 0.5),
                                         (4.0e4, 2.5)])  # fmt: skip
def test_a_face_at_rest_is_four_point_springs(k: float, mass: float) -> None:
    """Mapped for the box's own mass, the face rests 4k stiff."""
    model, data, _ = _world("friction_map", k=k, mass=mass, mapped=mass)
    for _ in range(3000):
        mujoco.mj_step(model, data)
    sink = 0.1 + 0.02 - data.qpos[2]
    assert mass * 9.81 / sink == pytest.approx(4 * k, rel=0.01)
    assert np.linalg.norm(data.qvel) < 1e-6


def test_the_stiffness_scales_with_the_mass_moved() -> None:
    """Mapped for 1 kg, a 2.5 kg box rests 2.5 × 4k stiff: MuJoCo's contact is
    acceleration level (module docstring of :mod:`ccm.sim.mujoco.world`)."""
    model, data, _ = _world("friction_map", k=1.0e4, mass=2.5, mapped=1.0)
    for _ in range(3000):
        mujoco.mj_step(model, data)
    sink = 0.1 + 0.02 - data.qpos[2]
    assert 2.5 * 9.81 / sink == pytest.approx(2.5 * 4 * 1.0e4, rel=0.01)


def test_the_first_touch_pushes_four_c_v() -> None:
    """Dropped at 0.1 m/s onto the table without gravity, the box's face (4 points) first
    pushes 4 C v: the per-point damper C (the spring has not yet compressed)."""
    model, data, _ = _world("friction_map", k=1.0e4, c=100.0, mass=0.5, mapped=0.5)
    model.opt.gravity[:] = 0.0
    data.qpos[2] = 0.1 + 0.02 + 1e-4
    data.qvel[2] = -0.1
    peak = 0.0
    for _ in range(20):
        mujoco.mj_step(model, data)
        peak = max(peak, float(np.sum(data.efc_force[: data.nefc : 3])) if data.nefc else 0.0)
    assert peak == pytest.approx(4 * 100.0 * 0.1, rel=0.1)


@pytest.mark.parametrize(("x", "mu"), [(0.4, 0.2), (0.53, 0.5), (0.63, 0.35)])
@pytest.mark.parametrize("mode", ["friction_map", "boxes"])
def test_the_surfaces_friction_holds_or_gives(mode: str, x: float, mu: float) -> None:
    """On S1 (the table, 0.2), S2 (0.5) and S3 (0.35) of the boxes mode; the one-box table of
    friction_map has 0.2 everywhere (the backend sets it under the tool each step)."""
    mu = mu if mode == "boxes" else 0.2
    for factor, moves in ((0.9, False), (1.2, True)):
        model, data, _ = _world(mode, x=x)
        for _ in range(500):  # settle
            mujoco.mj_step(model, data)
        push = factor * mu * 9.81
        for _ in range(150):  # 0.15 s: it stays on its 10 cm strip (< 2 cm moved)
            data.xfrc_applied[model.body("probe").id, 0] = push
            mujoco.mj_step(model, data)
        v = data.qvel[0]
        if moves:  # 0.15 s at (F − μ m g) / m, a little faster (module docstring)
            coulomb = (push - mu * 9.81) * 0.15
            assert coulomb <= v <= 1.15 * coulomb
        else:  # a creep (module docstring), far below the frictionless 0.26 m/s
            assert 0.0 <= v < 0.02


@pytest.mark.parametrize("impratio", [1.0, 100.0])
def test_sliding_lifts_the_face_by_the_cones_coupling(impratio: float) -> None:
    """Pushed along at 0.1 m/s with μ m g (so at a steady speed) through the pairs of
    :func:`add_pairs`, the box sinks r₀ (1 + μ_r²) − μ b_f v / k, with b_f = b / impratio and
    μ_r² = μ² / impratio (module docstring): 55 µm of 245 at impratio 1; 243 at 100."""
    k, b, v, mu = 1.0e4, 100.0, 0.1, 0.2
    model, data, _ = _world("friction_map", k=k, c=b, x=0.25, impratio=impratio)
    for _ in range(3000):
        mujoco.mj_step(model, data)
    rest = 0.12 - data.qpos[2]
    assert rest == pytest.approx(9.81 / (4 * k), rel=1e-3)
    data.qvel[0] = v
    for _ in range(300):
        data.xfrc_applied[model.body("probe").id, 0] = mu * 9.81
        mujoco.mj_step(model, data)
    assert data.qvel[0] == pytest.approx(v, rel=1e-3)
    expected = rest * (1 + mu**2 / impratio) - mu * (b / impratio) * v / k
    assert 0.12 - data.qpos[2] == pytest.approx(expected, abs=0.5e-6)
