"""The Panda with ccm's block tool, as every 3-D backend simulates it (issue #42: PyBullet
and MuJoCo share it).

``franka_panda/panda.urdf`` from ``pybullet_data``, its fingers removed and the block tool
fixed to ``panda_hand`` (:func:`robot_urdf`), with the links' inertials that PyBullet
simulates (:func:`pybullet_inertials`: the URDF's masses and centres of mass, principal
moments from the collision shapes; the URDF's own tensors are 0.1 kg m² placeholders, and
:mod:`ccm.sim.pybullet.dynamics` explains why this matters). The tool point is the centre of
the tool's bottom face. Nothing here imports a physics engine at module level.
"""

from __future__ import annotations

import functools
import math
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ccm.core.errors import check_positive
from ccm.core.fields import checked, field_values, vector

GRAVITY = 9.81  # m/s^2, along -z
N_ARM = 7  # Panda arm joints (the only movable joints once the fingers are removed)
#: tool pointing straight down: 180° about x, quaternion (x, y, z, w)
DOWN = (1.0, 0.0, 0.0, 0.0)
TOOL_MOUNT_Z = 0.0584  # m, where the fingers attach in panda_hand's frame (panda.urdf)
#: Franka's documented "ready" pose, used as IK seed and default rest posture [rad]
PANDA_READY = (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4)


@dataclass(frozen=True)
class ToolSpec:
    """The rigid block fixed to the flange.

    Attributes:
        size: full extents [m] along the tool frame's x, y, z (z along the flange axis).
        mass: [kg] > 0.
    """

    size: tuple[float, float, float] = checked(vector(3, positive=True), (0.04, 0.04, 0.04))
    mass: float = checked(check_positive, 0.15)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> ToolSpec:
        return cls(**field_values(cls, cfg, key)[0])


def robot_urdf(tool: ToolSpec, directory: str, visuals: bool = True) -> str:
    """Write panda.urdf without fingers and with the block tool; return its path.

    ``visuals=False`` leaves out every ``<visual>`` element: the ~9 MB of visual meshes are
    what made ``loadURDF`` slow (~0.1-1.5 s per trial, depending on load), and nothing but
    rendering reads them (inertias come from the ``<inertial>`` masses and the collision
    shapes, contacts from the collision shapes)."""
    import pybullet_data

    src_dir = os.path.join(pybullet_data.getDataPath(), "franka_panda")
    tree = ET.parse(os.path.join(src_dir, "panda.urdf"))
    root = tree.getroot()
    drop = {"panda_leftfinger", "panda_rightfinger", "panda_grasptarget"}
    for el in list(root):
        if el.tag == "link" and el.get("name") in drop:
            root.remove(el)
        elif el.tag == "joint":
            child = el.find("child")
            if child is not None and child.get("link") in drop:
                root.remove(el)
    if not visuals:
        for link in root.iter("link"):
            for vis in link.findall("visual"):
                link.remove(vis)
    for mesh in root.iter("mesh"):
        fn = mesh.get("filename", "")
        if fn.startswith("package://"):
            mesh.set("filename", os.path.join(src_dir, fn[len("package://") :]))
    sx, sy, sz = tool.size
    m = tool.mass
    ixx, iyy, izz = box_inertia(m, tool.size)
    box = f'<geometry><box size="{sx} {sy} {sz}"/></geometry>'
    origin = f'<origin rpy="0 0 0" xyz="0 0 {sz / 2}"/>'
    root.append(
        ET.fromstring(
            f'<link name="ccm_tool"><inertial>{origin}<mass value="{m}"/>'
            f'<inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/>'
            "</inertial>"
            + (
                f"<visual>{origin}{box}"
                '<material name="ccm_tool"><color rgba="0.9 0.4 0.1 1"/></material></visual>'
                if visuals
                else ""
            )
            + f"<collision>{origin}{box}</collision></link>"
        )
    )
    root.append(
        ET.fromstring(
            '<joint name="ccm_tool_joint" type="fixed"><parent link="panda_hand"/>'
            f'<child link="ccm_tool"/><origin rpy="0 0 0" xyz="0 0 {TOOL_MOUNT_Z}"/></joint>'
        )
    )
    path = os.path.join(directory, "panda_ccm_tool.urdf")
    tree.write(path)
    return path


def box_inertia(mass: float, size: Sequence[float]) -> tuple[float, float, float]:
    """Principal moments of inertia [kg m²] of a solid box about its centre."""
    sx, sy, sz = size
    return (mass * (sy**2 + sz**2) / 12, mass * (sx**2 + sz**2) / 12, mass * (sx**2 + sy**2) / 12)


@dataclass(frozen=True)
class LinkInertial:
    """A link's mass distribution in its URDF link frame, as PyBullet reports it.

    Attributes:
        mass: [kg].
        com: centre of mass in the link frame [m], (3,).
        orientation: the principal axes in the link frame, a quaternion (x, y, z, w).
        principal: principal moments of inertia about the centre of mass [kg m²], (3,).
    """

    mass: float
    com: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    principal: tuple[float, float, float]


def link_inertials(p: Any, cid: int, robot: int) -> dict[str, LinkInertial]:
    """The inertials PyBullet simulates each link of ``robot`` with (not the base), by link
    name: the URDF's mass and centre of mass, principal moments from the collision shape
    (:mod:`ccm.sim.pybullet.dynamics` explains why this matters)."""
    out = {}
    for j in range(p.getNumJoints(robot, physicsClientId=cid)):
        name = p.getJointInfo(robot, j, physicsClientId=cid)[12].decode()
        mass, _, principal, com, orn = p.getDynamicsInfo(robot, j, physicsClientId=cid)[:5]
        out[name] = LinkInertial(mass, tuple(com), tuple(orn), tuple(principal))
    return out


@functools.cache
def pybullet_inertials(tool: ToolSpec) -> dict[str, LinkInertial]:
    """The inertials PyBullet simulates the Panda with ``tool`` with, by link name, read
    from a headless PyBullet client (once per tool)."""
    import pybullet as p

    cid = p.connect(p.DIRECT)
    tmp = tempfile.mkdtemp(prefix="ccm_panda_")
    try:
        robot = p.loadURDF(robot_urdf(tool, tmp, visuals=False), [0, 0, 0],
                           useFixedBase=True, physicsClientId=cid)  # fmt: skip
        return link_inertials(p, cid, robot)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        p.disconnect(physicsClientId=cid)
