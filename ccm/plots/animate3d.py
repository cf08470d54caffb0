"""3D animation of a 3-D trial (either engine: PyBullet or MuJoCo, the same Panda): the recorded
joint states replayed and rendered offscreen by PyBullet.

A DIRECT PyBullet client loads the Panda with its visual meshes and the block tool
(:func:`ccm.sim.panda.robot_urdf`, ``visuals=True``: the simulator itself leaves them out) and
draws the scene as visual-only boxes: the table, its friction patches (blue) and the static
boxes (walls). For each frame the arm's joints are set to the recorded angles (``truth_q1_rad``
... ``truth_q7_rad``, both 3-D backends record them) with ``resetJointState``, so nothing is
simulated: the image is PyBullet's tiny software renderer (``getCameraImage``,
``ER_TINY_RENDERER``) from the ``animate.camera`` view. The target of P (its path faint, its
current point a cross), the measured F/T force as an arrow from the tool point (scale in N per
m), the legend and the time / phase / mode overlay are drawn on the image with Pillow, projected
through the same camera matrices.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError
from ccm.plots.frames import AnimateSettings, frame_steps, nice_scale, overlay_text
from ccm.sim.arm_config import ArmConfig
from ccm.sim.panda import N_ARM, robot_urdf
from ccm.sim.scene3d import Scene3D

#: the recorded joint angle columns [rad] (``StepInfo.extra`` keys ``q1_rad`` ... ``q7_rad``)
JOINT_COLUMNS = tuple(f"truth_q{i}_rad" for i in range(1, N_ARM + 1))
_BOX_COLOURS = (
    (0.8, 0.25, 0.2, 1.0),
    (0.25, 0.4, 0.85, 1.0),
    (0.3, 0.65, 0.3, 1.0),
    (0.6, 0.6, 0.6, 1.0),
)
_TARGET, _FORCE, _TEXT, _TOOL = (20, 140, 40), (220, 30, 30), (20, 20, 20), (230, 100, 25)
#: m: a camera without a target looks this far above the centre of the tool's path, so that
#: the arm above the tool is in the picture too (chosen: the Panda's hand is ~0.2 m tall)
_LIFT = 0.2


def check_joints(log: Mapping[str, np.ndarray], where: str) -> None:
    """A 3D replay needs the recorded joint angles; runs made before they were recorded
    have none (one line naming the file)."""
    missing = [c for c in JOINT_COLUMNS if c not in log]
    if missing:
        raise ConfigError(
            where,
            "holds no joint angles (truth_q1_rad ... truth_q7_rad, recorded since ccm "
            "animate exists): run the experiment again to animate it",
        )


def _box(p: Any, cid: int, center: Any, half: Any, rgba: Any) -> None:
    vis = p.createVisualShape(
        p.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba), physicsClientId=cid
    )
    p.createMultiBody(
        baseMass=0.0, baseVisualShapeIndex=vis, basePosition=list(center), physicsClientId=cid
    )


def _build_world(p: Any, cid: int, scene: Scene3D, config: ArmConfig) -> int:
    """Table, patches and boxes as visual shapes, and the robot; returns its id. No floor:
    the tiny renderer's cost grows with the pixels each shape covers (a 3 m floor took the
    frame from 0.09 to 0.12 s at 640 x 480, measured)."""
    table = scene.table
    if table is not None:
        (cx, cy), (w, d), h = table.center, table.size, table.height
        _box(p, cid, (cx, cy, h / 2), (w / 2, d / 2, h / 2), (0.62, 0.52, 0.42, 1.0))
        for pt in table.patches:
            x0, x1, y0, y1 = pt.bounds()
            _box(
                p,
                cid,
                ((x0 + x1) / 2, (y0 + y1) / 2, h),
                ((x1 - x0) / 2, (y1 - y0) / 2, 5e-4),
                (0.2, 0.4, 0.8, 1.0),
            )
    for i, b in enumerate(scene.boxes):
        _box(p, cid, b.center, [s / 2 for s in b.size], _BOX_COLOURS[i % len(_BOX_COLOURS)])
    tmp = tempfile.mkdtemp(prefix="ccm_anim_")
    try:
        urdf = robot_urdf(config.tool, tmp, visuals=True)  # meshes: this is what they are for
        return p.loadURDF(urdf, [0, 0, 0], useFixedBase=True, physicsClientId=cid)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def camera_matrices(
    p: Any, settings: AnimateSettings, log: Mapping[str, np.ndarray]
) -> tuple[list[float], list[float]]:
    """PyBullet's view and projection matrices (column-major 4x4 lists) of ``animate.camera``;
    a camera without a target looks at the centre of the recorded tool path."""
    cam = settings.camera
    if cam.target is not None:
        target = list(cam.target)
    else:
        xyz = np.column_stack([log["pos_x"], log["pos_y"], log["pos_z"]])
        target = ((np.nanmin(xyz, axis=0) + np.nanmax(xyz, axis=0)) / 2 + [0, 0, _LIFT]).tolist()
    view = p.computeViewMatrixFromYawPitchRoll(target, cam.distance, cam.yaw, cam.pitch, 0.0, 2)
    proj = p.computeProjectionMatrixFOV(cam.fov, settings.width / settings.height, 0.02, 10.0)
    return list(view), list(proj)


def project(
    points: np.ndarray, view: list[float], proj: list[float], width: int, height: int
) -> np.ndarray:
    """World points (N, 3) [m] to pixel coordinates (N, 2) of the rendered image (NaN
    behind the camera)."""
    v = np.array(view, dtype=float).reshape(4, 4).T  # PyBullet's matrices are column-major
    pr = np.array(proj, dtype=float).reshape(4, 4).T
    hom = np.column_stack([points, np.ones(len(points))]) @ (pr @ v).T
    w = hom[:, 3:4]
    ndc = np.where(w > 1e-9, hom[:, :2] / np.where(w > 1e-9, w, 1.0), np.nan)
    return np.column_stack([(ndc[:, 0] + 1) / 2 * width, (1 - ndc[:, 1]) / 2 * height])


def _arrow(draw: Any, a: np.ndarray, b: np.ndarray) -> None:
    """A red arrow from pixel ``a`` to ``b`` (head 10 px)."""
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return
    draw.line([tuple(a), tuple(b)], fill=_FORCE, width=3)
    d = b - a
    n = float(np.hypot(*d))
    if n < 2.0:
        return
    u, perp = d / n, np.array([-d[1], d[0]]) / n
    head = [tuple(b), tuple(b - 10 * u + 5 * perp), tuple(b - 10 * u - 5 * perp)]
    draw.polygon(head, fill=_FORCE)


def frames_3d(
    log: Mapping[str, np.ndarray],
    scene: Scene3D,
    config: ArmConfig,
    settings: AnimateSettings,
    labels: Mapping[str, Any],
) -> Iterator[np.ndarray]:
    """RGB frames (height x width x 3, uint8) of one recorded 3D trial (module docstring);
    ``labels``: ``phase`` and ``segments`` for the overlay."""
    import pybullet as p

    check_joints(log, labels.get("source", "the time series"))
    w, h = settings.width, settings.height
    cid = p.connect(p.DIRECT)
    try:
        robot = _build_world(p, cid, scene, config)
        view, proj = camera_matrices(p, settings, log)
        target = np.column_stack([log[f"target_pos_{a}"] for a in "xyz"])
        path_px = project(target[:: max(1, len(target) // 400)], view, proj, w, h)
        typical = float(np.nanpercentile(np.linalg.norm(_cols(log, "force"), axis=1), 95))
        scale = settings.force_scale_N_per_m or nice_scale(typical, settings.camera.distance)
        for k in frame_steps(log["t"], settings.fps):
            for j, col in enumerate(JOINT_COLUMNS):
                p.resetJointState(robot, j, float(log[col][k]), physicsClientId=cid)
            img = p.getCameraImage(
                w,
                h,
                view,
                proj,
                renderer=p.ER_TINY_RENDERER,
                shadow=0,
                flags=p.ER_NO_SEGMENTATION_MASK,
                physicsClientId=cid,
            )  # no shadow, no segmentation mask: 0.11 -> 0.05 s a frame for the arm (measured)
            rgb = np.reshape(np.asarray(img[2], dtype=np.uint8), (h, w, 4))[:, :, :3]
            yield _overlay(rgb, log, k, (view, proj), path_px, scale, labels)
    finally:
        p.disconnect(physicsClientId=cid)


def _cols(log: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    return np.column_stack([log[f"{prefix}_{a}"] for a in "xyz"]).astype(float)


def _overlay(
    rgb: np.ndarray,
    log: Mapping[str, np.ndarray],
    k: int,
    cam: tuple[list[float], list[float]],
    path_px: np.ndarray,
    scale: float,
    labels: Mapping[str, Any],
) -> np.ndarray:
    """The target path and point, the force arrow, the legend and the overlay text."""
    from PIL import Image, ImageDraw, ImageFont

    h, w = rgb.shape[:2]
    image = Image.fromarray(rgb)
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=max(10, h // 40))
    pts = [tuple(q) for q in path_px if np.all(np.isfinite(q))]
    if len(pts) > 1:
        draw.line(pts, fill=(150, 200, 150), width=1)
    tool = np.array([[log[f"pos_{a}"][k] for a in "xyz"]], dtype=float)
    target = np.array([[log[f"target_pos_{a}"][k] for a in "xyz"]], dtype=float)
    force = np.array([[log[f"force_{a}"][k] for a in "xyz"]], dtype=float) / scale
    (tp,), (gp,), (fp,) = (project(x, *cam, w, h) for x in (tool, target, tool + force))
    if np.all(np.isfinite(gp)):
        x, y = gp
        draw.line([(x - 6, y - 6), (x + 6, y + 6)], fill=_TARGET, width=2)
        draw.line([(x - 6, y + 6), (x + 6, y - 6)], fill=_TARGET, width=2)
    _arrow(draw, tp, fp)
    draw.text((8, 6), overlay_text(log, k, labels), fill=_TEXT, font=font)
    legend = [
        ("orange block: tool", _TOOL),
        ("green x: target (P)", _TARGET),
        (f"red arrow: measured force ({scale:g} N per m)", _FORCE),
    ]
    for i, (line, colour) in enumerate(legend):
        draw.text((8, h - (len(legend) - i) * (font.size + 4) - 4), line, fill=colour, font=font)
    return np.asarray(image)
