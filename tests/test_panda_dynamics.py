"""Pinocchio's model of the Panda (:mod:`ccm.sim.pybullet.dynamics`) against PyBullet's queries.

At 20 seeded random joint configurations within the URDF's limits and velocities up to
±2 rad/s (about the Panda's 2.2-2.6 rad/s joint speed limits), every term of the torque
law agrees with what the PyBullet path computes: M with ``calculateMassMatrix``, J with
``calculateJacobian`` at the tool point, h with ``calculateInverseDynamics(q, q̇, 0)``, J̇ q̇
with a central difference of PyBullet's Jacobian along q̇, M⁻¹ Jᵀ and Λ with
:func:`ccm.sim.pybullet.robot.task_inertia`.

Tolerances: absolute 1e-8 for M [kg m²], J [m/rad, 1], h [N m] and M⁻¹ Jᵀ: their entries
reach ~3, 1, 50 and 250 here, so 1e-8 absolute is a relative 1e-8 or tighter, and the two
engines, with the same model in double precision, differ by rounding (measured: 3e-15,
7e-16, 1.4e-14, 1.1e-13). Λ is compared relative to its largest entry: Λ grows without
bound near a singular configuration (up to ~1600 kg here), and both sides' rounding grows
with it (~cond(J M⁻¹ Jᵀ) × machine epsilon × |Λ|, cond up to ~7e5 here; measured 1.8e-13).
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from ccm.sim.panda import GRAVITY, link_inertials, robot_urdf
from ccm.sim.pybullet.dynamics import PandaDynamics, robot_dynamics
from ccm.sim.pybullet.robot import (
    inverse_dynamics,
    load_robot,
    task_inertia,
    tool_jacobian,
    tool_point_in_link,
)
from ccm.sim.pybullet.scene import PyBullet3DConfig

pytest.importorskip("pybullet")
pytest.importorskip("pinocchio")


N_SAMPLES = 20
TOL = 1e-8


@dataclass
class Robot:
    p: Any
    cid: int
    body: int
    tool_link: int
    tip_link: tuple[float, float, float]
    dyn: PandaDynamics

    def jacobian(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        return tool_jacobian(self.p, self.cid, self.body, self.tool_link, self.tip_link, q, dq)


@pytest.fixture(scope="module")
def robot() -> Iterator[Robot]:
    """The Panda with the default block tool, loaded as ``PyBullet3D.reset`` loads it."""
    import pybullet as p

    cfg = PyBullet3DConfig()
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
        body, tool_link = load_robot(p, cid, cfg)
        tip_local = (0.0, 0.0, cfg.tool.size[2] / 2.0)  # as PyBullet3D: bottom-face centre
        tip_link = tool_point_in_link(p, cid, body, tool_link, tip_local)
        yield Robot(
            p, cid, body, tool_link, tip_link, robot_dynamics(p, cid, body, cfg.tool, tip_link)
        )
    finally:
        p.disconnect(physicsClientId=cid)


def samples(dyn: PandaDynamics) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(20)
    lower, upper = dyn.joint_limits
    return [(rng.uniform(lower, upper), rng.uniform(-2.0, 2.0, 7)) for _ in range(N_SAMPLES)]


def test_joint_limits_are_pybullets(robot: Robot) -> None:
    """The samples stay within the limits PyBullet loaded from the same URDF."""
    lower, upper = robot.dyn.joint_limits
    for j in range(7):
        lo, hi = robot.p.getJointInfo(robot.body, j, physicsClientId=robot.cid)[8:10]
        assert (lower[j], upper[j]) == (lo, hi)


def test_mass_matrix_jacobian_and_bias_match_pybullet(robot: Robot) -> None:
    p, cid, body = robot.p, robot.cid, robot.body
    worst = {"M": 0.0, "J": 0.0, "h": 0.0}
    for q, dq in samples(robot.dyn):
        t = robot.dyn.compute(q, dq)
        mass = np.array(p.calculateMassMatrix(body, q.tolist(), physicsClientId=cid))
        worst["M"] = max(worst["M"], float(np.abs(t.mass - mass).max()))
        worst["J"] = max(worst["J"], float(np.abs(t.jacobian - robot.jacobian(q, dq)).max()))
        h = inverse_dynamics(p, cid, body, q, dq)
        worst["h"] = max(worst["h"], float(np.abs(t.h - h).max()))
        assert np.array_equal(t.mass, t.mass.T)
    print(f"\n[pinocchio] max |Pinocchio - PyBullet|: {worst}")
    assert max(worst.values()) < TOL


def test_jdot_qdot_matches_a_central_difference(robot: Robot) -> None:
    """J̇ q̇ against (J(q + ε q̇) − J(q − ε q̇)) q̇ / 2ε with PyBullet's J, ε = 1e-6 s.

    Error of the difference: truncation ε² |q̇|³ |∂³J|/6, ~7e-7 measured at ε = 1e-4, so
    ~7e-11 at 1e-6; rounding: J's entries (≤ 1) carry ~1e-16, times |q̇|₁ ≤ 14 over
    2ε = 2e-6, ≤ 1e-9 (measured 7e-10). So 1e-8 (absolute; J̇ q̇ reaches ~9 m/s² here).
    """
    eps = 1e-6
    worst = 0.0
    for q, dq in samples(robot.dyn):
        fd = (robot.jacobian(q + eps * dq, dq) - robot.jacobian(q - eps * dq, dq)) @ dq
        worst = max(worst, float(np.abs(robot.dyn.compute(q, dq).jdot_qdot - fd / (2 * eps)).max()))
    print(f"\n[pinocchio] max |J̇q̇ - central difference|: {worst:.2g}")
    assert worst < TOL


def test_task_inertia_matches_the_pybullet_helper(robot: Robot) -> None:
    worst_minv_jt = worst_lam = 0.0
    for q, dq in samples(robot.dyn):
        t = robot.dyn.compute(q, dq)
        minv_jt, lam = task_inertia(robot.p, robot.cid, robot.body, q, robot.jacobian(q, dq))
        worst_minv_jt = max(worst_minv_jt, float(np.abs(t.minv_jt - minv_jt).max()))
        worst_lam = max(worst_lam, float(np.abs(t.lam - lam).max() / np.abs(lam).max()))
    print(f"\n[pinocchio] max |M⁻¹Jᵀ| error {worst_minv_jt:.2g}, Λ relative {worst_lam:.2g}")
    assert worst_minv_jt < TOL
    assert worst_lam < TOL


def test_the_urdfs_own_inertias_are_not_what_pybullet_simulates(robot: Robot) -> None:
    """Why PyBullet's link inertials replace the URDF's: without them M is off by > 0.1."""
    with tempfile.TemporaryDirectory() as tmp:
        urdf = robot_urdf(PyBullet3DConfig().tool, tmp)
        plain = PandaDynamics(urdf, "ccm_tool", robot.tip_link, None, GRAVITY)
    q, dq = samples(robot.dyn)[0]
    mass = np.array(robot.p.calculateMassMatrix(robot.body, q.tolist(), physicsClientId=robot.cid))
    assert np.abs(plain.compute(q, dq).mass - mass).max() > 0.1
    assert np.abs(robot.dyn.compute(q, dq).mass - mass).max() < TOL


def test_terms_are_not_overwritten_by_the_next_call(robot: Robot) -> None:
    (q0, dq0), (q1, dq1) = samples(robot.dyn)[:2]
    first = robot.dyn.compute(q0, dq0)
    kept = {k: np.copy(getattr(first, k)) for k in first.__slots__}
    robot.dyn.compute(q1, dq1)
    for k, v in kept.items():
        assert np.array_equal(getattr(first, k), v), k


def test_a_missing_link_or_inertial_is_refused(robot: Robot) -> None:

    inertials = link_inertials(robot.p, robot.cid, robot.body)
    with tempfile.TemporaryDirectory() as tmp:
        urdf = robot_urdf(PyBullet3DConfig().tool, tmp)
        with pytest.raises(ValueError, match="no link 'ccm_toll'"):
            PandaDynamics(urdf, "ccm_toll", robot.tip_link, inertials)
        del inertials["panda_hand"]
        with pytest.raises(ValueError, match="panda_hand"):
            PandaDynamics(urdf, "ccm_tool", robot.tip_link, inertials)


def test_the_torque_bench_times_both_paths() -> None:
    """ccm.bench.dynamics runs (a few calls; the timings themselves are make bench's)."""
    from ccm.bench.dynamics import bench_torques

    row = bench_torques(calls=5, repeats=2)
    assert set(row["us_per_call_median"]) == {"pinocchio", "pybullet"}
    assert all(len(v) == 2 and min(v) > 0.0 for v in row["us_per_call_all"].values())


def test_compiled_torque_law_matches_the_numpy_law(robot: Robot) -> None:
    """:func:`ccm.sim._kernels.torque_law` on :meth:`PandaDynamics.torque_terms`
    (with :func:`~ccm.sim._kernels.task_space`) against the torque law written in
    numpy on :meth:`PandaDynamics.compute`'s terms (the form ``TorqueLoop._torques_pybullet``
    uses): ``τ = Jᵀ [f; m + m_hold] + h − Jᵀ Λ J̇ q̇ + N τ₀``, with a random
    wrench, orientation hold and posture term at every sample.

    Tolerance: relative 1e-9 of max |τ|. The two compute Λ by different Cholesky codes (plain
    loops vs LAPACK), so they differ by rounding times cond(J M⁻¹ Jᵀ) (up to ~7e5 here).
    """
    from ccm.sim._kernels import orientation_error, task_space, torque_law

    rng = np.random.default_rng(7)
    worst = 0.0
    for q, dq in samples(robot.dyn):
        minv, jac, jdq, h = robot.dyn.torque_terms(q, dq)
        t = robot.dyn.compute(q, dq)
        assert np.allclose(minv, np.linalg.inv(t.mass), rtol=1e-9, atol=1e-9)
        wrench, q_rest = rng.normal(0.0, 10.0, 6), q + rng.normal(0.0, 0.1, 7)
        q_des, orn = rng.normal(size=4), rng.normal(size=4)
        q_des, orn = q_des / np.linalg.norm(q_des), orn / np.linalg.norm(orn)
        omega, (ko, do, kn, dn) = rng.normal(size=3), rng.uniform(1.0, 50.0, 4)
        hold = np.concatenate([[ko, do], q_des, orn, omega])
        posture = np.concatenate([[kn, dn], q_rest, q, dq])
        minv_jt, _, lam = task_space(minv, jac)
        tau = torque_law(jac, jdq, h, minv_jt, lam, wrench, hold, posture, True)
        w = wrench.copy()
        w[3:] += ko * orientation_error(q_des, orn) - do * omega
        tau0 = kn * (q_rest - q) - dn * dq
        ref = t.jacobian.T @ w + t.h - t.jacobian.T @ (t.lam @ t.jdot_qdot)
        ref += tau0 - t.jacobian.T @ (t.lam @ (t.minv_jt.T @ tau0))
        worst = max(worst, float(np.abs(tau - ref).max() / np.abs(ref).max()))
    print(f"\n[pinocchio] compiled vs numpy torque law, max relative error {worst:.2g}")
    assert worst < 1e-9


def test_the_robot_without_visual_meshes_has_the_same_dynamics(robot: Robot) -> None:
    """``robot_urdf(visuals=False)`` (what a DIRECT-mode simulator loads: the visual meshes
    made ``loadURDF`` ~1 s slower per trial) has no ``<visual>``, and PyBullet gives its links
    the same masses, inertias and frames as the full robot's."""
    import pybullet as p

    cfg = PyBullet3DConfig()
    with tempfile.TemporaryDirectory() as tmp:
        path = robot_urdf(cfg.tool, tmp, visuals=False)
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
        cid = p.connect(p.DIRECT)
        try:
            body = p.loadURDF(path, [0, 0, 0], useFixedBase=True, physicsClientId=cid)
            n = p.getNumJoints(body, physicsClientId=cid)
            assert n == p.getNumJoints(robot.body, physicsClientId=robot.cid)
            for j in range(n):
                lean = p.getDynamicsInfo(body, j, physicsClientId=cid)
                full = p.getDynamicsInfo(robot.body, j, physicsClientId=robot.cid)
                for k in (0, 2, 3, 4):  # mass, principal inertia, inertial position, frame
                    assert lean[k] == full[k], (j, k)
                assert p.getCollisionShapeData(body, j, physicsClientId=cid) == (
                    p.getCollisionShapeData(robot.body, j, physicsClientId=robot.cid)
                ), j
        finally:
            p.disconnect(physicsClientId=cid)
    assert "<visual" not in text and "<collision" in text
