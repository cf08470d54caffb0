"""The Panda with ccm's block tool as a MuJoCo model (issue #42, the ``mujoco3d`` backend).

The same robot as the PyBullet backend (:mod:`ccm.sim.panda`):

* **Kinematics** from the URDF :func:`ccm.sim.panda.robot_urdf` writes (fingers removed, the
  block tool fixed to ``panda_hand``), loaded by MuJoCo's URDF importer with the bodies
  behind fixed joints kept as bodies (``fusestatic="false"``) and no visual meshes.
* **Inertias** are PyBullet's (:func:`ccm.sim.panda.pybullet_inertials`): MuJoCo, like
  PyBullet, would otherwise use its own (the URDF's 0.1 kg m² placeholders, or inertias
  from the meshes), and the two engines would simulate two robots. Each body gets the
  URDF mass and centre of mass and PyBullet's principal moments and axes.
* **Joints** keep the URDF's position limits; no damping, friction loss or armature (the
  PyBullet backend zeroes its damping; the URDF has none).
* **Actuation**: a motor on each of the seven joints, gear 1 and no torque limit: the
  backend's torque loop sets ``ctrl`` to joint torques [N m].
* **Tool point**: a site ``ccm_tool_point`` at the centre of the tool's bottom face, the
  point every observation and Jacobian refers to.
* **Wrist F/T sensor**: MuJoCo's ``force`` and ``torque`` sensors on a site ``ccm_ft`` at the
  tool's centre of mass, in the tool's frame. They read the wrench the hand exerts on the
  tool (its subtree), the moment about the site: measured, the tool at rest in free space
  reads +m g upward in the world frame. That is the PyBullet backend's joint reading, and
  the backend turns it into the external wrench at the tool point the same way
  (:func:`ccm.sim._kernels.tool_sense`).
* **Collisions**: the robot's geoms, named ``<body>/<i>``, make no contacts of their own
  (``contype`` and ``conaffinity`` 0): a scene pairs each with every static geom
  (:func:`ccm.sim.mujoco.world.add_pairs`), so they collide with the world's and not with
  each other, as in PyBullet without self-collision.
* **Gravity** ``(0, 0, −g)`` and the time step ``dt`` as the ``sim`` config gives them.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import mujoco
import numpy as np

from ccm.sim.panda import GRAVITY, N_ARM, LinkInertial, ToolSpec, pybullet_inertials, robot_urdf

#: the tool point's site, the F/T sensor's site, and the arm's joint names
TOOL_POINT = "ccm_tool_point"
FT_SITE = "ccm_ft"
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, N_ARM + 1))
_COMPILER = '<mujoco><compiler fusestatic="false" discardvisual="true" strippath="false"/></mujoco>'


def panda_spec(tool: ToolSpec, dt: float = 0.001) -> mujoco.MjSpec:
    """The Panda with ``tool`` as a MuJoCo model specification (module docstring); a scene
    adds its bodies to it before :meth:`mujoco.MjSpec.compile`."""
    tmp = tempfile.mkdtemp(prefix="ccm_panda_mj_")
    try:
        text = Path(robot_urdf(tool, tmp, visuals=False)).read_text()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    end = text.index(">", text.index("<robot")) + 1  # MuJoCo's settings go inside <robot>
    spec = mujoco.MjSpec.from_string(text[:end] + _COMPILER + text[end:])
    spec.compiler.discardvisual = False  # else it drops the robot's pair-only geoms (below)
    spec.option.timestep = dt
    spec.option.gravity = [0.0, 0.0, -GRAVITY]
    _set_inertials(spec, pybullet_inertials(tool))
    for name in ARM_JOINTS:
        joint = spec.joint(name)
        joint.damping = [0.0, 0.0, 0.0]  # MuJoCo 4: linear, quadratic, cubic coefficients
        joint.armature, joint.frictionloss = 0.0, 0.0
        spec.add_actuator(name=f"{name}_motor", target=name,
                          trntype=mujoco.mjtTrn.mjTRN_JOINT, gear=[1, 0, 0, 0, 0, 0])  # fmt: skip
    tool_body = spec.body("ccm_tool")
    tool_body.add_site(name=TOOL_POINT, pos=[0.0, 0.0, tool.size[2]])
    tool_body.add_site(name=FT_SITE, pos=[0.0, 0.0, tool.size[2] / 2.0])  # centre of mass
    for kind, name in ((mujoco.mjtSensor.mjSENS_FORCE, "ccm_ft_force"),
                       (mujoco.mjtSensor.mjSENS_TORQUE, "ccm_ft_torque")):  # fmt: skip
        spec.add_sensor(name=name, type=kind, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=FT_SITE)
    for body in spec.bodies:  # every geom so far is the robot's: named for its pairs
        for i, geom in enumerate(body.geoms):
            geom.name = f"{body.name}/{i}"
            geom.contype, geom.conaffinity = 0, 0
    return spec


def panda_model(tool: ToolSpec, dt: float = 0.001) -> mujoco.MjModel:
    """The compiled model of :func:`panda_spec` (the robot alone, no scene)."""
    return panda_spec(tool, dt).compile()


def _set_inertials(spec: mujoco.MjSpec, inertials: dict[str, LinkInertial]) -> None:
    """Give every moving body PyBullet's inertial (mass, centre of mass, principal axes and
    moments); a body of the URDF without one is an error (a layout ccm does not know)."""
    for body in spec.bodies:
        if body.name in ("world", "panda_link0"):
            continue  # the fixed base does not move
        if body.name not in inertials:
            raise ValueError(f"no inertial for the Panda body {body.name!r}")
        link = inertials[body.name]
        body.explicitinertial = True
        if link.mass == 0.0:  # panda_link8, the flange: a frame, no mass in either engine
            body.mass, body.inertia, body.fullinertia = 0.0, [0.0] * 3, [np.nan] * 6
            continue
        x, y, z, w = link.orientation
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, np.array([w, x, y, z]) / np.linalg.norm([w, x, y, z]))
        rot = rot.reshape(3, 3)
        full = rot @ np.diag(link.principal) @ rot.T  # about the centre of mass, link axes
        body.mass = float(link.mass)
        body.ipos = list(link.com)
        # MuJoCo's order: Ixx, Iyy, Izz, Ixy, Ixz, Iyz (its principal axes are derived)
        body.fullinertia = [full[0, 0], full[1, 1], full[2, 2], full[0, 1], full[0, 2], full[1, 2]]
