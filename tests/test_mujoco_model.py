"""The MuJoCo Panda is the PyBullet backend's Panda (issue #42, part 1): the same kinematic
tree, the same inertias (PyBullet's), the same joint limits, no damping, torque motors on the
seven joints, and the tool point where the PyBullet backend puts it.

The oracle is the PyBullet backend's own robot model (:class:`PandaDynamics`: Pinocchio on the
same URDF with PyBullet's inertials, itself checked against PyBullet's ``calculateMassMatrix``,
``calculateInverseDynamics`` and ``calculateJacobian`` in ``tests/test_panda_dynamics.py``):
M(q), the bias torques h(q, q̇) and the tool point's Jacobian must agree at random states."""

from __future__ import annotations

import shutil
import tempfile

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from ccm.sim.mujoco.model import ARM_JOINTS, TOOL_POINT, panda_model  # noqa: E402
from ccm.sim.panda import N_ARM, ToolSpec, pybullet_inertials, robot_urdf  # noqa: E402
from ccm.sim.pybullet.dynamics import PandaDynamics  # noqa: E402

TOOLS = [ToolSpec(), ToolSpec(size=(0.06, 0.03, 0.08), mass=0.4)]


def _pinocchio(tool: ToolSpec) -> PandaDynamics:
    tmp = tempfile.mkdtemp()
    try:
        urdf = robot_urdf(tool, tmp, visuals=False)
        return PandaDynamics(urdf, "ccm_tool", (0.0, 0.0, tool.size[2]), pybullet_inertials(tool))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


@pytest.mark.parametrize("tool", TOOLS, ids=["default tool", "larger tool"])
def test_mass_matrix_bias_and_jacobian_match_the_pybullet_backends_model(tool: ToolSpec) -> None:
    model, ref = panda_model(tool), _pinocchio(tool)
    data = mujoco.MjData(model)
    site = model.site(TOOL_POINT).id
    lo, hi = ref.joint_limits
    rng = np.random.default_rng(7)
    mass = np.zeros((N_ARM, N_ARM))
    jacp, jacr = np.zeros((3, N_ARM)), np.zeros((3, N_ARM))
    for _ in range(5):
        q = rng.uniform(lo + 0.1, hi - 0.1)
        dq = rng.normal(0.0, 1.0, N_ARM)
        data.qpos[:], data.qvel[:] = q, dq
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, mass)
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        terms = ref.compute(q, dq)
        np.testing.assert_allclose(mass, terms.mass, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(data.qfrc_bias, terms.h, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(np.vstack([jacp, jacr]), terms.jacobian, rtol=1e-9, atol=1e-12)


def test_joints_limits_motors_and_no_damping() -> None:
    """The URDF's limits (as Pinocchio reads them), zero damping, armature and friction loss,
    one gear-1 motor per arm joint without a torque limit, 1 ms steps, gravity −9.81 z."""
    tool = ToolSpec()
    model, ref = panda_model(tool), _pinocchio(tool)
    lo, hi = ref.joint_limits
    assert [model.joint(j).name for j in range(model.njnt)] == list(ARM_JOINTS)
    np.testing.assert_allclose(model.jnt_range, np.column_stack([lo, hi]), atol=1e-12)
    assert model.jnt_limited.all()
    assert not model.dof_damping.any() and not model.dof_armature.any()
    assert not model.dof_frictionloss.any()
    assert model.nu == N_ARM and (model.actuator_gear[:, 0] == 1.0).all()
    assert list(model.actuator_trnid[:, 0]) == list(range(N_ARM))
    assert not model.actuator_ctrllimited.any() and not model.actuator_forcelimited.any()
    assert model.opt.timestep == 0.001 and list(model.opt.gravity) == [0.0, 0.0, -9.81]


def test_a_motor_torque_is_the_joint_torque() -> None:
    """ctrl = τ: with gravity cancelled by the bias torques and a unit torque on joint 4
    from rest, q̈ = M⁻¹ e₄ (what the torque loop assumes of the actuators)."""
    model = panda_model(ToolSpec())
    data = mujoco.MjData(model)
    data.qpos[:] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
    mujoco.mj_forward(model, data)
    tau = data.qfrc_bias.copy()
    tau[3] += 1.0
    data.ctrl[:] = tau
    mujoco.mj_forward(model, data)
    mass = np.zeros((N_ARM, N_ARM))
    mujoco.mj_fullM(model, data, mass)
    np.testing.assert_allclose(data.qacc, np.linalg.solve(mass, np.eye(N_ARM)[3]), rtol=1e-9)
