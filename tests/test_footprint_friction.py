"""The friction a tool face feels across a patch edge (``sim.patch_mode: footprint``,
:mod:`ccm.sim.footprint`): a ramp over the face's width, weighted by the pressure,
where ``friction_map`` switches in one step at the tool point (issue #17 item 5)."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.sim.footprint import face_grid, footprint_friction, table_friction

W = 0.04  # m, the default tool face
EDGE = 0.5  # m, the patch starts here along x
PATCHES = [(EDGE, 0.7, -0.25, 0.25, 0.4)]
BASE = 0.2
GRID = face_grid(W, W, 32)
AXES = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])  # face axes = table x, y


def corners(x: float, forces: tuple[float, float, float, float] = (2.5, 2.5, 2.5, 2.5)) -> list:
    """The four corner contacts of the face centred at (x, 0): trailing (-x) pair first."""
    h = W / 2
    pts = [(x - h, -h, 0.1), (x - h, h, 0.1), (x + h, -h, 0.1), (x + h, h, 0.1)]
    return list(zip(pts, forces, strict=True))


def mu(mode: str, x: float, contacts: list | None = None) -> float:
    c = corners(x) if contacts is None else contacts
    return table_friction(mode, np.array([x, 0.0, 0.1]), AXES, c, (W, W), GRID, PATCHES, BASE)


def test_a_face_straddling_the_edge_gets_the_mean_friction() -> None:
    """Uniform pressure, half the face on each surface: (0.2 + 0.4) / 2; friction_map gives
    one surface's value (the tool point sits on the patch edge)."""
    assert mu("footprint", EDGE) == pytest.approx(0.3, abs=1e-12)
    assert mu("friction_map", EDGE) == 0.4


def test_the_friction_ramps_monotonically_over_the_face_width() -> None:
    """Sweeping the face across the edge: the old value until the leading edge reaches it,
    the new value once the trailing edge has passed, strictly between and non-decreasing in
    between (the 4 cm face); friction_map jumps once at the tool point."""
    xs = np.linspace(EDGE - 0.03, EDGE + 0.03, 241)
    ramp = np.array([mu("footprint", float(x)) for x in xs])
    step = np.array([mu("friction_map", float(x)) for x in xs])
    assert np.all(np.diff(ramp) >= -1e-12)
    assert ramp[xs <= EDGE - W / 2] == pytest.approx(BASE, abs=1e-12)
    assert ramp[xs >= EDGE + W / 2] == pytest.approx(0.4, abs=1e-12)
    middle = np.abs(xs - EDGE) < W / 2 - 1.25e-3  # at least one grid cell inside
    assert np.all((ramp[middle] > BASE + 1e-3) & (ramp[middle] < 0.4 - 1e-3))
    assert np.count_nonzero((step > BASE) & (step < 0.4)) == 0
    assert np.unique(step).size == 2


def test_the_more_loaded_edge_weighs_more() -> None:
    """Leading (+x) corners carrying 60 % of the load, half the face on the patch: more than
    the uniform 0.3. With all the load on the trailing edge, the patch half lifts off
    (pressure clipped at 0) and the face feels little of the patch."""
    lead = corners(EDGE, (2.0, 2.0, 3.0, 3.0))
    trail = corners(EDGE, (5.0, 5.0, 0.0, 0.0))
    assert mu("footprint", EDGE, lead) > 0.3 + 0.01
    assert mu("footprint", EDGE, trail) < 0.2 + 0.2 * 0.1


def test_no_table_contact_falls_back_to_the_tool_point() -> None:
    assert mu("footprint", EDGE - 0.01, []) == BASE
    assert mu("footprint", EDGE + 0.01, []) == 0.4
    zero = corners(EDGE, (0.0, 0.0, 0.0, 0.0))
    assert footprint_friction(*zip(*zero, strict=True), np.zeros(3), AXES, (W, W), GRID,
                              PATCHES, BASE) is None  # fmt: skip


def test_a_rotated_face_uses_its_own_axes() -> None:
    """A face turned 90° about the vertical (tool x along table y): the same ramp."""
    turned = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 0.0]])
    tip = np.array([EDGE - 0.01, 0.0, 0.1])
    c = corners(EDGE - 0.01)
    a = table_friction("footprint", tip, turned, c, (W, W), GRID, PATCHES, BASE)
    assert a == pytest.approx(mu("footprint", EDGE - 0.01), abs=1e-12)
    assert BASE < a < 0.3
