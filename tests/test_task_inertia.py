"""Seed A Eq. 1's inertia in 3-D (issue #38 item 1): the arm's Λ(q) in the impedance law.

The observation carries the robot model's translational task-space inertia; the checks:
* it equals the inertia from PyBullet's own mass matrix and Jacobian (a second library);
* with the orientation hold off it is the arm's measured f → ẍ map (a finite difference);
* the critical rule for a matrix inertia damps every eigen-direction with ratio ζ;
* Eq. 1's motion term with Λ is K Δx + K_d Δẋ + Λ ẍ_d, value for value;
* free-space tracking at K_free no longer rings once Λ(q) replaces the nominal 4 kg.
"""

from __future__ import annotations

import numpy as np
import pytest

from ccm.control.impedance import FixedImpedance
from ccm.control.loop import HybridLoop, damping_from_rule, impedance_term
from ccm.core.types import Command, Observation, TargetSample
from ccm.sim.pybullet.backend import DOWN, PyBullet3D
from ccm.sim.pybullet.robot import task_inertia, tool_jacobian

pytest.importorskip("pybullet")

START = [0.45, 0.0, 0.35]
NO_HOLD = {"orientation_stiffness": 0.0, "orientation_damping": 0.0}


def _moved_sim(**cfg: float) -> tuple[PyBullet3D, Observation]:
    """A sim whose arm has moved off its start pose (a non-trivial q and q̇)."""
    sim = PyBullet3D.from_config(dict(cfg), {}, START)
    obs, _ = sim.reset(0)
    push = Command(force=np.array([4.0, -3.0, 2.0]), torque=np.zeros(3))
    for _ in range(150):
        obs, _ = sim.step(push)
    return sim, obs


@pytest.mark.parametrize("cfg", [{}, NO_HOLD], ids=["hold", "no_hold"])
def test_observed_inertia_is_pybullets_task_inertia(cfg: dict) -> None:
    """obs.inertia against Λ = (J M⁻¹ Jᵀ)⁻¹ from PyBullet's calculateMassMatrix and
    calculateJacobian: its translational block with the hold, (J_v M⁻¹ J_vᵀ)⁻¹ without."""
    sim, obs = _moved_sim(**cfg)
    try:
        q, dq = sim.joint_state()
        p, cid, robot, link, tip = sim.torque_loop._body  # the loaded robot
        jac = tool_jacobian(p, cid, robot, link, tip, q, dq)
        minv_jt, lam6 = task_inertia(p, cid, robot, q, jac)
        want = lam6[:3, :3] if cfg == {} else np.linalg.inv((jac @ minv_jt)[:3, :3])
        np.testing.assert_allclose(obs.inertia, want, rtol=1e-6, atol=1e-6)
        # the two differ a lot: the hold changes which inertia a force meets
        other = np.linalg.inv((jac @ minv_jt)[:3, :3]) if cfg == {} else lam6[:3, :3]
        assert np.abs(other - want).max() > 0.5  # kg
    finally:
        sim.close()


def test_without_the_hold_the_inertia_is_the_arms_response() -> None:
    """From rest, a constant 5 N per axis for 10 ms: the measured acceleration Δv / Δt equals
    obs.inertia⁻¹ f within 2 % (the model is the physics' f → ẍ map)."""
    sim = PyBullet3D.from_config(dict(NO_HOLD), {}, START)
    try:
        for f in np.eye(3) * 5.0:
            obs, _ = sim.reset(0)
            lam, v0 = obs.inertia, obs.lin_vel.copy()
            for _ in range(10):
                obs, _ = sim.step(Command(force=f, torque=np.zeros(3)))
            acc = (obs.lin_vel - v0) / (10 * sim.dt)
            want = np.linalg.solve(lam, f)
            assert np.linalg.norm(acc - want) < 0.02 * np.linalg.norm(want)
    finally:
        sim.close()


def test_critical_rule_damps_each_inertia_direction_critically() -> None:
    """K_d = ζ(Λ^½K^½ + K^½Λ^½) with K = k I: the closed loop Λë + K_d ė + K e = 0 has, for
    each eigen-mass m_i of Λ, a double eigenvalue at −√(k/m_i) for ζ = 1 (and the scalar
    rule 2ζ√(k m) for a scalar mass)."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 3))
    lam = a @ a.T + np.diag([1.0, 3.0, 8.0])  # kg, SPD with distinct eigen-masses
    k = 300.0
    kd = damping_from_rule(np.full(3, k), "critical", lam, 1.0, 0.0)
    np.testing.assert_allclose(kd, kd.T, atol=1e-12)
    state = np.block(
        [
            [np.zeros((3, 3)), np.eye(3)],
            [-np.linalg.solve(lam, k * np.eye(3)), -np.linalg.solve(lam, kd)],
        ]
    )
    poles = np.sort(np.linalg.eigvals(state).real)
    want = np.sort(np.repeat(-np.sqrt(k / np.linalg.eigvalsh(lam)), 2))
    np.testing.assert_allclose(poles, want, rtol=1e-3)  # a double root: ~1e-4 splits
    assert damping_from_rule(300.0, "critical", 4.0, 0.7, 0.0) == pytest.approx(
        2 * 0.7 * np.sqrt(1200.0)
    )


def test_eq1_motion_term_with_the_arms_inertia() -> None:
    """K Δx + K_d Δẋ + Λ ẍ_d with a full Λ and K_d, against the sum written out."""
    lam = np.array([[9.4, -0.2, -1.6], [-0.2, 3.7, 0.0], [-1.6, 0.0, 4.7]])
    kp = np.array([300.0, 500.0, 800.0])
    kd = damping_from_rule(kp, "critical", lam, 1.0, 0.0)
    obs = Observation(0.0, np.array([0.1, 0.2, 0.3]), np.array(DOWN), np.array([0.05, -0.02, 0.0]),
                      np.zeros(3), np.zeros(3), np.zeros(3), inertia=lam)  # fmt: skip
    tgt = TargetSample(0.0, np.array([0.11, 0.19, 0.3]), np.array([0.1, 0.0, 0.01]),
                       np.array([1.0, -0.5, 0.2]), np.array(DOWN))  # fmt: skip
    u = impedance_term(obs, tgt, kp, kd, lam, True)
    want = kp * np.array([0.01, -0.01, 0.0]) + kd @ np.array([0.05, 0.02, 0.01])
    want += lam @ np.array([1.0, -0.5, 0.2])
    np.testing.assert_allclose(u, want, rtol=1e-12)
    loop = HybridLoop(inertia="nominal", mass_kg=4.0)
    assert loop.inertia_of(obs) == 4.0
    assert HybridLoop(inertia="model").inertia_of(obs) is lam


def _free_move(inertia: str) -> tuple[float, float]:
    """Max tracking error [mm] of a 15 cm min-jerk move along x in 1 s at K_free = 300 N/m:
    during the move, and from 1 s after it ends (the ringing)."""
    sim = PyBullet3D.from_config({}, {}, START)
    ctrl = FixedImpedance(stiffness=300.0, loop={"mass_kg": 4.0, "inertia": inertia})
    try:
        obs, _ = sim.reset(0)
        ctrl.reset(3, sim.control_dt)
        p0, d = obs.position.copy(), np.array([0.15, 0.0, 0.0])
        errs = []
        for i in range(2500):
            s = min(i * sim.dt, 1.0)
            tgt = TargetSample(
                i * sim.dt,
                p0 + d * (10 * s**3 - 15 * s**4 + 6 * s**5),
                d * (30 * s**2 - 60 * s**3 + 30 * s**4),
                d * (60 * s - 180 * s**2 + 120 * s**3),
                np.array(DOWN),
            )
            obs, _ = sim.step(ctrl.step(obs, tgt))
            errs.append(1e3 * np.linalg.norm(tgt.position - obs.position))
        return max(errs[:1000]), max(errs[2000:])
    finally:
        sim.close()


def test_free_motion_with_the_arms_inertia_no_longer_rings() -> None:
    """Λ(q) in H and in the critical rule: the move's error and the ringing 1 s after it
    shrink at least 3× and 5× against the nominal 4 kg (measured 12.8 → 3.1 mm and
    1.25 → 0.08 mm), and the ringing is below 0.2 mm."""
    during_nom, late_nom = _free_move("nominal")
    during, late = _free_move("model")
    assert during < during_nom / 3.0
    assert late < late_nom / 5.0
    assert late < 0.2
