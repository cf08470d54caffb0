"""A task's start pose must be clear of the scene's static boxes (issue #19).

A start inside a wall or obstacle was accepted: the physics then pushes the tool out with an
arbitrary impulse, or leaves it stuck, and the run still reports ``ok``. 2D: the end-effector
block (with its start angle) must not overlap a ``task.scene.boxes`` entry. 3D: the tool point
must not lie inside a ``task.scene.boxes`` entry or the table (a box from z = 0 to its top).
Touching a face is allowed (a start resting on a surface).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_vector
from ccm.sim.panda import DOWN

#: overlap [m] below which a start counts as touching, not inside (float round-off)
TOLERANCE = 1e-6


def _fmt(values: Sequence[float]) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def check_start_2d(scene: Any, start: Sequence[float], prefix: str = "task.scene") -> None:
    """Reject a 2D start whose end-effector block overlaps one of ``scene.boxes``
    (:class:`ccm.sim.pymunk.scene.SceneSpec`; ``start`` = ``(x, y, angle)``)."""
    x, y, angle = start
    half = (scene.ee.size[0] / 2, scene.ee.size[1] / 2)
    c, s = math.cos(angle), math.sin(angle)
    ee_axes = ((c, s), (-s, c))
    for i, box in enumerate(scene.boxes):
        bhalf = (box.size[0] / 2, box.size[1] / 2)
        dx, dy = x - box.center[0], y - box.center[1]
        # separating-axis test of two rectangles: the box's axes, then the block's
        for ax, ay in ((1.0, 0.0), (0.0, 1.0), *ee_axes):
            r_ee = sum(
                h * abs(ux * ax + uy * ay) for h, (ux, uy) in zip(half, ee_axes, strict=True)
            )
            r_box = bhalf[0] * abs(ax) + bhalf[1] * abs(ay)
            if abs(dx * ax + dy * ay) >= r_ee + r_box - TOLERANCE:
                break  # separated (or touching) along this axis
        else:
            raise ConfigError(
                "task.start", f"the end-effector at {_fmt((x, y))} overlaps {prefix}.boxes[{i}] "
                f"(a static box at {_fmt(box.center)}, size {_fmt(box.size)}); start outside it",
            )  # fmt: skip


def check_start_3d(scene: Any, point: Sequence[float], prefix: str = "task.scene") -> None:
    """Reject a 3D start whose tool point lies inside one of ``scene.boxes`` or the table
    (:class:`ccm.sim.scene3d.Scene3D`)."""
    solids = [(f"{prefix}.boxes[{i}]", b.center, b.size) for i, b in enumerate(scene.boxes)]
    table = scene.table
    if table is not None:
        center = (*table.center, table.height / 2)
        solids.append((f"{prefix}.table", center, (*table.size, table.height)))
    for key, center, size in solids:
        if all(abs(p - c) < s / 2 - TOLERANCE for p, c, s in zip(point, center, size, strict=True)):
            raise ConfigError(
                "task.start", f"the tool point {_fmt(point)} is inside {key} (a static box at "
                f"{_fmt(center)}, size {_fmt(size)}); start outside it",
            )  # fmt: skip


def start_pose_3d(scene: Any, start: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """The tool point's start position [m] and orientation (x, y, z, w) from ``task.start``:
    ``[x, y, z]`` (the tool pointing down) or ``[x, y, z, qx, qy, qz, qw]`` (normalised),
    checked against the scene (:func:`check_start_3d`)."""
    st = check_vector("task.start", start, (3, 7))
    position = st[:3].copy()
    check_start_3d(scene, position)
    if st.shape[0] == 3:
        return position, np.array(DOWN)
    nq = float(np.linalg.norm(st[3:]))
    if nq < 1e-9:
        raise ConfigError("task.start", "quaternion part must be non-zero")
    return position, st[3:] / nq
