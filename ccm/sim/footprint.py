"""Friction of a table with patches under a flat tool face (``sim.patch_mode: footprint``).

Seed A §4.5.2 explains why the switch from a low- to a high-friction surface was detected
more easily than the way back: while the block leaves the high-friction surface, "the
trailing part of the block is in contact with the surface with higher friction that still
offers resistance", so the friction the block feels changes gradually over the block's
width. A friction value looked up at one point of the tool (``friction_map``) switches in one
physics step instead. This module gives the friction coefficient the whole face feels.

Physics. Coulomb friction on a face sliding in pure translation is the sum over the contact
area of μ(x) p(x) dA, all along the one sliding direction, so the face feels

    μ_eff = ∫ μ(x) p(x) dA / ∫ p(x) dA                                   (1)

(p the contact pressure). PyBullet (like MuJoCo) reports a flat box-on-box contact as the corners of
the contact polygon (four points with normal forces N_i) and sets friction per body (geom),
not per point. The four corner forces are the solver's representation of the pressure's resultant
N = Σ N_i and its centre of pressure c = Σ N_i r_i / N, not the pressure itself. A rigid face
on an elastic foundation (Winkler) carries a pressure that is linear over the face; the linear
pressure on a w × d rectangle with resultant N and centre of pressure c = (c_ξ, c_η) in face
coordinates is

    p(ξ, η) ∝ 1 + 12 c_ξ ξ / w² + 12 c_η η / d²                         (2)

(first moment of a linear field over a rectangle: ∫ ξ p dA = N c_ξ). Where (2) is negative the
face lifts off (c outside the middle third): the pressure is clipped at 0 there. (1) is
integrated on an n × n grid of cell centres over the face, μ(x) being the table's friction or
the patch's under each cell. Before every physics step the table gets μ_eff from the previous
step's table contact points; with no table contact (free space, or the tool touching only a
wall) it gets μ at the tool point, as ``friction_map`` does.

So, as a face slides across a patch edge, μ_eff moves continuously from one surface's value
to the other's over the face's width (4 cm for the default tool), weighted toward the more
loaded edge.

Limits. (1) holds for translation; a face that also spins about its normal has friction
forces in different directions, which a single coefficient cannot represent. A real face
straddling the edge also feels a yaw torque (more friction on one part); with one coefficient
per body PyBullet applies μ_eff at every point, so that torque is missing. The one-step lag
(1 ms) and the grid (n = ``sim.footprint_grid``) quantise the ramp. The pressure is the linear
field (2) fitted to the solver's resultant, not a deformation model of the face.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ccm.sim._footprint_kernels import cell_weights_and_friction, friction_at

#: a patch as ``(x0, x1, y0, y1, friction)`` [m, m, m, m, -]
Patch = tuple[float, float, float, float, float]


def face_grid(width: float, depth: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres (ξ, η) [m] of an n × n grid over a ``width`` × ``depth`` face, centred."""
    xi = (np.arange(n) + 0.5) / n * width - width / 2.0
    eta = (np.arange(n) + 0.5) / n * depth - depth / 2.0
    gx, gy = np.meshgrid(xi, eta, indexing="ij")
    return gx.ravel(), gy.ravel()


def footprint_friction(
    points: Sequence[tuple[float, float, float]],
    forces: Sequence[float],
    center: np.ndarray,
    axes: np.ndarray,
    size: tuple[float, float],
    grid: tuple[np.ndarray, np.ndarray],
    patches: Sequence[Patch],
    base: float,
) -> float | None:
    """μ_eff of (1) for a face with table contact points ``points`` carrying normal forces
    ``forces`` [N].

    Args:
        points: contact positions on the table [m] (PyBullet's ``positionOnB``).
        forces: their normal forces [N].
        center: the face centre [m], shape (3,) (the tool point).
        axes: the face's in-plane unit axes as columns, shape (3, 2) (tool frame x and y).
        size: the face's ``(width, depth)`` along those axes [m].
        grid: :func:`face_grid` cells for that size.
        patches: the table's patches; ``base``: its friction elsewhere.

    Returns:
        μ_eff, or None if the points carry no normal force (no contact: the caller falls
        back to the friction at the tool point).
    """
    total = float(sum(forces))
    if total <= 0.0:
        return None
    r = np.asarray(points, dtype=float) - center
    cop = (np.asarray(forces, dtype=float) @ (r @ axes)) / total  # (c_ξ, c_η)
    rows = np.asarray(patches, dtype=float).reshape(-1, 5)
    xi, eta = grid
    w, mu = cell_weights_and_friction(
        center, axes, xi, eta, (float(size[0]), float(size[1])), (float(cop[0]), float(cop[1])),
        rows, float(base),
    )  # fmt: skip
    if w.sum() <= 0.0:  # centre of pressure off the face (cannot happen for points on it)
        pts = np.asarray(points, dtype=float)
        mu_pts = friction_at(pts[:, 0].copy(), pts[:, 1].copy(), rows, float(base))
        return float(np.asarray(forces, dtype=float) @ mu_pts / total)
    return float(w @ mu / w.sum())


def table_friction(
    mode: str,
    tip: np.ndarray,
    axes: np.ndarray,
    contacts: Sequence[tuple[tuple[float, float, float], float]],
    size: tuple[float, float],
    grid: tuple[np.ndarray, np.ndarray],
    patches: Sequence[Patch],
    base: float,
) -> float:
    """The table's friction for the next physics step under ``patch_mode`` ``mode``:
    ``friction_map``, μ at the tool point ``tip``; ``footprint``, μ_eff of (1) from the last
    step's table ``contacts`` (position, normal force), or μ at the tool point without one."""
    if mode == "footprint" and contacts:
        pts, forces = zip(*contacts, strict=True)
        mu = footprint_friction(pts, forces, tip, axes, size, grid, patches, base)
        if mu is not None:
            return mu
    x, y = float(tip[0]), float(tip[1])  # plain floats: this runs every physics step
    for x0, x1, y0, y1, pmu in patches:
        if x0 <= x <= x1 and y0 <= y <= y1:
            return pmu
    return base


class TableFriction:
    """The table's friction, set before every physics step by ``sim.patch_mode``; the engine
    neutral part (each 3-D backend applies the value to its table and reports the contacts).

    ``friction_map`` (default): the table top is one box and, before every physics step, its
    friction is set to that of the patch under the tool point (the table's own value
    elsewhere); patches are drawn as visual-only boxes in the GUI. The whole tool face
    therefore gets one friction value while it straddles a patch edge, switching when the
    tool point crosses it. ``boxes``: each patch is a thin box flush with the top and the
    table's top layer is cut around the patches (cells of the grid spanned by the patch
    edges, :func:`ccm.sim.scene3d.boxed_table_parts`); geometrically faithful, but the tool
    face, sunk slightly into the surface it rests on, catches on the side face of the next
    box: normal-force spikes of 57-136 N at a 10 N press were measured at edge crossings in
    PyBullet (friction_map: one ~26 N, 7 ms transient from the friction step itself); nothing
    is set per step. ``footprint``: the continuous top of ``friction_map``, its friction
    μ_eff of (1) under the tool's face from the previous step's table contacts, so it ramps
    across a patch edge over the face's width (module docstring).

    Args:
        mode: ``sim.patch_mode``.
        face: the tool face's ``(width, depth)`` [m].
        grid_n: cells per side of the face grid (``sim.footprint_grid``).
        base: the table's own friction (0 without a table).
    """

    def __init__(self, mode: str, face: tuple[float, float], grid_n: int, base: float) -> None:
        self.mode, self.face, self.base = mode, face, base
        self.grid = face_grid(*face, grid_n)
        self.mu = -1.0  # the table's friction this step
        self.patches: list[Patch] = []
        self.contacts: list[tuple[Any, float]] = []  # last step's table (position, N)

    def attach(self, patches: Sequence[Patch], table_mu: float | None) -> None:
        """Use a freshly built world: its ``patches`` and the friction of its one table box
        (``None`` when no single box carries the table: none, or the ``boxes`` mode)."""
        self.patches = list(patches)
        self.contacts = []
        if table_mu is not None:
            self.mu = table_mu

    def update(self, tip: np.ndarray, axes: np.ndarray) -> float | None:
        """Before a physics step: the table's friction for the tool point ``tip`` and the
        face's in-plane ``axes``, if it changed (the backend sets it on its table); ``None``
        if it did not, or without patches."""
        if not self.patches:
            return None
        mu = table_friction(
            self.mode, tip, axes, self.contacts, self.face, self.grid, self.patches, self.base
        )
        if mu == self.mu:
            return None
        self.mu = mu
        return mu

    def observe(self, contacts: Sequence[tuple[Any, float]]) -> None:
        """After a physics step: the tool's table contacts ``(position, normal force)`` for
        the next step's ``footprint`` friction (kept only with patches)."""
        if self.patches:
            self.contacts = list(contacts)
