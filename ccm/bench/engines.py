"""The engines' own cost: a minimal control loop on the same scene as a ccm row (issue #20).

A ``make bench`` loop row times ccm's whole closed loop (target sampling, control law,
recording, physics, sensor, divergence check). Beside it, :func:`raw_loop` times the least
a controlled simulation on the same engine and scene must do per control step, so the ratio
ccm / raw says how close ccm is to the engine's cost on this machine at this moment
(these machines are noisy: the two are timed in turn, in one process).

* **pymunk** (:class:`ccm.sim.pymunk2d.PyMunk2D`): per physics step, set the body's force (a
  PD hold of the start position, so the body stays in the scene), ``space.step``, read its
  position and velocity.
* **PyBullet** (:class:`ccm.sim.pybullet3d.PyBullet3D`): per physics step, the calls a
  task-space torque loop on the Panda needs: ``getJointStates``, ``calculateJacobian``,
  ``calculateMassMatrix``, ``calculateInverseDynamics`` (gravity compensation is the torque
  applied), ``setJointMotorControlArray(TORQUE_CONTROL)``, ``stepSimulation``.

Both run on the simulator ccm built for the row, after a reset, through its engine handles.
"""

from __future__ import annotations

import time
from typing import Any

# The raw loops reach into the simulators' engine handles on purpose: they are the engine.
# ruff: noqa: SLF001

#: pymunk raw loop: PD hold of the start position [N/m], [N s/m] (chosen: holds a 1 kg body)
HOLD_KP, HOLD_KD = 300.0, 30.0


def raw_loop(sim: Any, control_steps: int, seed: int = 0) -> float:
    """Wall time [s] of ``control_steps`` control steps of the minimal loop for ``sim``'s
    engine (module docstring), after ``sim.reset(seed)`` (not timed)."""
    sim.reset(seed=seed)
    if hasattr(sim, "_space"):
        return _pymunk(sim, control_steps)
    if hasattr(sim, "_robot"):
        return _pybullet(sim, control_steps)
    raise TypeError(f"no raw loop for {type(sim).__name__}")


def _pymunk(sim: Any, control_steps: int) -> float:
    body, space, dt = sim._body, sim._space, sim.dt
    x0, y0 = body.position
    n = control_steps * sim.control_decimation
    t0 = time.perf_counter()
    x, y = x0, y0
    vx, vy = body.velocity
    for _ in range(n):
        body.force = (HOLD_KP * (x0 - x) - HOLD_KD * vx, HOLD_KP * (y0 - y) - HOLD_KD * vy)
        space.step(dt)
        x, y = body.position
        vx, vy = body.velocity
    return time.perf_counter() - t0


def _pybullet(sim: Any, control_steps: int) -> float:
    p, cid, robot, arm = sim._p, sim._client, sim._robot, sim._arm
    link, tip = sim._tool_link, list(sim._tip_link)
    zeros = [0.0] * len(arm)
    n = control_steps * sim.control_decimation
    t0 = time.perf_counter()
    for _ in range(n):
        states = p.getJointStates(robot, arm, physicsClientId=cid)
        q = [s[0] for s in states]
        dq = [s[1] for s in states]
        p.calculateJacobian(robot, link, tip, q, dq, zeros, physicsClientId=cid)
        p.calculateMassMatrix(robot, q, physicsClientId=cid)
        tau = p.calculateInverseDynamics(robot, q, dq, zeros, physicsClientId=cid)
        p.setJointMotorControlArray(robot, arm, p.TORQUE_CONTROL, forces=tau, physicsClientId=cid)
        p.stepSimulation(physicsClientId=cid)
    return time.perf_counter() - t0
