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

Both run on the simulator ccm built for the row, after a reset, through its engine handles.
"""

from __future__ import annotations

import time
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
    t = obs.t + sim.control_dt * np.arange(control_steps)
    targets = [tuple(pattern.sample(tk).position) for tk in t]
    if hasattr(sim, "_space"):
        return _pymunk(sim, targets)
    if hasattr(sim, "_robot"):
        return _pybullet(sim, targets)
    raise TypeError(f"no raw loop for {type(sim).__name__}")


def _pymunk(sim: Any, targets: list[tuple[float, ...]]) -> float:
    body, space, dt, hold = sim._body, sim._space, sim.dt, sim.control_decimation
    t0 = time.perf_counter()
    x, y = body.position
    vx, vy = body.velocity
    for tx, ty in targets:
        for _ in range(hold):
            body.force = (KP * (tx - x) - KD * vx, KP * (ty - y) - KD * vy)
            space.step(dt)
            x, y = body.position
            vx, vy = body.velocity
    return time.perf_counter() - t0


def _pybullet(sim: Any, targets: list[tuple[float, ...]]) -> float:
    p, cid, robot, arm = sim._p, sim._client, sim._robot, sim._arm
    link, tip, hold = sim._tool_link, list(sim._tip_link), sim.control_decimation
    zeros = [0.0] * len(arm)
    t0 = time.perf_counter()
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
    return time.perf_counter() - t0
