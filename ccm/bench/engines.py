"""The engines' own cost: a minimal control loop on the same scene as a ccm row (issue #20).

A ``make bench`` loop row times ccm's whole closed loop (target sampling, control law,
recording, physics, sensor, divergence check). Beside it, :func:`raw_loop` times the least
a controlled simulation on the same engine, scene and target motion must do per step, so the
ratio ccm / raw says how close ccm is to the engine's cost on this machine at that moment
(these machines are noisy: the two are timed in turn, in one process).

Both loops follow the task's pattern P with a plain task-space PD (gains below), so they
make the same contacts as ccm's controllers roughly do; the targets are sampled before the
timing starts (P's own cost is ccm's, not the engine's).

* **pymunk** (:class:`ccm.sim.pymunk.backend.PyMunk2D`): per physics step, the body's force from
  the PD, ``space.step``, read its position and velocity.
* **PyBullet** (:class:`ccm.sim.pybullet.backend.PyBullet3D`): per physics step, the calls a
  task-space torque loop on the Panda needs: ``getJointStates``, ``getLinkState`` (the tool
  pose and twist), ``calculateJacobian``, ``calculateMassMatrix``,
  ``calculateInverseDynamics``, then ``τ = Jᵀ F + h`` in plain Python,
  ``setJointMotorControlArray(TORQUE_CONTROL)`` and ``stepSimulation``.
* **MuJoCo** (:class:`ccm.sim.mujoco.backend.MuJoCo3D`): the same loop in MuJoCo's calls:
  ``mj_step1`` (kinematics, collisions, bias forces), the tool point's position, ``mj_jacSite``
  (its twist is J q̇), ``mj_solveM`` (M⁻¹, as PyBullet's row asks for M), ``τ = Jᵀ F +
  qfrc_bias`` in numpy, ``ctrl`` and ``mj_step2``.

Both run on the simulator ccm built for the row, after a reset, through its engine handles.
:func:`raw_loop` gives a row's wall time; :func:`raw_cpu_per_step` and :func:`raw_reset_cpu`
give the CPU cost per physics step and per PyBullet reset that the paper floor
(:mod:`ccm.bench.floor`) multiplies by a paper run's recorded work.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

# The raw loops reach into the simulators' engine handles on purpose: they are the engine.
# ruff: noqa: SLF001

#: the raw loops' task-space PD [N/m], [N s/m] (chosen: as stiff as the medium fixed
#: impedance, configs/controller/fixed_impedance_medium.yaml) and rotational damping [N m s]
KP, KD, KD_ROT = 1000.0, 60.0, 2.0


def raw_loop(sim: Any, pattern: Any, control_steps: int, seed: int = 0) -> float:
    """Wall time [s] of ``control_steps`` control steps of the minimal loop for ``sim``'s
    engine following ``pattern`` (module docstring), after ``sim.reset(seed)`` (not timed)."""
    obs, _ = sim.reset(seed=seed)
    return _engine_loop(sim)(sim, _targets(sim, pattern, obs.t, control_steps), time.perf_counter)


def raw_cpu_per_step(sim: Any, pattern: Any, budget_s: float = 1.5, seed: int = 0) -> float:
    """CPU seconds per *physics* step of the minimal loop for ``sim``'s engine (module
    docstring), in whole passes over ``pattern``'s duration until ``budget_s`` of CPU time is
    spent; each pass starts from ``sim.reset(seed)`` (not timed), the targets are sampled once.
    CPU time (``time.process_time``), so that it compares with a sweep's recorded CPU time."""
    obs, _ = sim.reset(seed=seed)
    steps = max(1, int(pattern.duration / sim.control_dt))
    targets = _targets(sim, pattern, obs.t, steps)
    loop = _engine_loop(sim)
    spent, passes = 0.0, 0
    while spent < budget_s:
        if passes:
            sim.reset(seed=seed)
        spent += loop(sim, targets, time.process_time)
        passes += 1
    return spent / (passes * steps * sim.control_decimation)


def raw_reset_cpu(sim: Any, repeats: int = 3) -> float:
    """Median CPU seconds of what a PyBullet trial's reset asks of the engine:
    ``resetSimulation`` and ``loadURDF`` of the Panda with ccm's tool (the URDF ccm loads,
    written once beforehand); 0.0 for pymunk, whose reset builds a few shapes."""
    if not hasattr(sim, "_client"):
        return 0.0
    import tempfile

    from ccm.sim.panda import robot_urdf

    sim.reset(seed=0)
    p, cid = sim._p, sim._client
    with tempfile.TemporaryDirectory(prefix="ccm_bench_") as tmp:
        urdf = robot_urdf(sim.config.tool, tmp, visuals=sim.config.gui)
        cpu = []
        for _ in range(repeats):
            t0 = time.process_time()
            p.resetSimulation(physicsClientId=cid)
            p.loadURDF(urdf, [0, 0, 0], useFixedBase=True, physicsClientId=cid)
            cpu.append(time.process_time() - t0)
    sim.reset(seed=0)  # the simulator's own world again
    return statistics.median(cpu)


def _targets(sim: Any, pattern: Any, t0: float, control_steps: int) -> list[tuple[float, ...]]:
    """The pattern's positions at the control steps from ``t0`` (sampled before timing)."""
    t = t0 + sim.control_dt * np.arange(control_steps)
    return [tuple(pattern.sample(tk).position) for tk in t]


def _engine_loop(sim: Any) -> Callable[..., float]:
    if hasattr(sim, "_space"):
        return _pymunk
    if hasattr(sim, "_client"):
        return _pybullet
    if hasattr(sim, "law"):
        return _mujoco
    raise TypeError(f"no raw loop for {type(sim).__name__}")


def _pymunk(sim: Any, targets: list[tuple[float, ...]], clock: Callable[[], float]) -> float:
    body, space, dt, hold = sim._body, sim._space, sim.dt, sim.control_decimation
    t0 = clock()
    x, y = body.position
    vx, vy = body.velocity
    for tx, ty in targets:
        for _ in range(hold):
            body.force = (KP * (tx - x) - KD * vx, KP * (ty - y) - KD * vy)
            space.step(dt)
            x, y = body.position
            vx, vy = body.velocity
    return clock() - t0


def _pybullet(sim: Any, targets: list[tuple[float, ...]], clock: Callable[[], float]) -> float:
    p, cid, robot, arm = sim._p, sim._client, sim._robot, sim._arm
    link, tip, hold = sim._tool_link, list(sim._tip_link), sim.control_decimation
    zeros = [0.0] * len(arm)
    t0 = clock()
    for tx, ty, tz in targets:
        for _ in range(hold):
            states = p.getJointStates(robot, arm, physicsClientId=cid)
            q = [s[0] for s in states]
            dq = [s[1] for s in states]
            ls = p.getLinkState(robot, link, 1, 1, physicsClientId=cid)
            (x, y, z), (vx, vy, vz), w = ls[0], ls[6], ls[7]
            lin, ang = p.calculateJacobian(robot, link, tip, q, dq, zeros, physicsClientId=cid)
            p.calculateMassMatrix(robot, q, physicsClientId=cid)
            h = p.calculateInverseDynamics(robot, q, dq, zeros, physicsClientId=cid)
            f = (KP * (tx - x) - KD * vx, KP * (ty - y) - KD * vy, KP * (tz - z) - KD * vz)
            m = (-KD_ROT * w[0], -KD_ROT * w[1], -KD_ROT * w[2])
            tau = [
                h[i] + sum(lin[r][i] * f[r] + ang[r][i] * m[r] for r in range(3))
                for i in range(len(arm))
            ]
            p.setJointMotorControlArray(
                robot, arm, p.TORQUE_CONTROL, forces=tau, physicsClientId=cid
            )
            p.stepSimulation(physicsClientId=cid)
    return clock() - t0


def _mujoco(sim: Any, targets: list[tuple[float, ...]], clock: Callable[[], float]) -> float:
    import mujoco

    robot = sim._robot
    m, d, site, hold = robot.model, robot.data, robot.tip_site, sim.control_decimation
    jac, minv, eye = np.zeros((6, m.nv)), np.zeros((m.nv, m.nv)), np.eye(m.nv)
    gains = np.array([KP, KP, KP]), np.array([KD, KD, KD, KD_ROT, KD_ROT, KD_ROT])
    mujoco.mj_step1(m, d)
    t0 = clock()
    for target in targets:
        for _ in range(hold):
            mujoco.mj_jacSite(m, d, jac[:3], jac[3:], site)
            mujoco.mj_solveM(m, d, minv, eye)
            twist = jac @ d.qvel
            wrench = -gains[1] * twist
            wrench[:3] += gains[0] * (np.asarray(target) - d.site_xpos[site])
            d.ctrl[:] = jac.T @ wrench + d.qfrc_bias
            mujoco.mj_step2(m, d)
            mujoco.mj_step1(m, d)
    return clock() - t0
