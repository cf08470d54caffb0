"""3D physics backend on PyBullet: a torque-controlled Franka Panda with a block tool.

Seed A (Sidhik et al.) ran its 3D experiments on a Panda in PyBullet (§4.4). This backend
plays that role. The controller commands a task-space wrench ``u_t`` (seed A Eq. 1) at the
*tool point*; the robot's own torque loop turns it into joint torques.

Modelling choices (each one is also stated where it is implemented; the robot and tool, the
tool point, the F/T sensor, the contact ground truth and the compliant tool contact are
described in :mod:`ccm.sim.pybullet.robot`):

* **Torque control.** The default velocity motors are switched off (``VELOCITY_CONTROL``
  with force 0) and ``TORQUE_CONTROL`` is re-applied every physics step (it lasts one step),
  with the torques of the robot's own loop (:mod:`ccm.sim.pybullet.torque_loop`: gravity and
  Coriolis compensation, a dynamically consistent posture null space, an optional
  orientation hold, and its model terms from Pinocchio or PyBullet). Link and joint damping
  are set to 0 so the compensation is exact.
* **Table patches** (``patch_mode``: ``friction_map``, ``boxes`` or ``footprint``): the
  friction under the tool (:class:`ccm.sim.footprint.TableFriction`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import SimulationDiverged
from ccm.core.types import Command, Observation, StepInfo
from ccm.sim._kernels import tool_sense
from ccm.sim.arm import arm_output, hold_command
from ccm.sim.base import Simulator, all_finite
from ccm.sim.footprint import TableFriction
from ccm.sim.hand import Hand
from ccm.sim.panda import DOWN, GRAVITY, N_ARM, PANDA_READY, ToolSpec, box_inertia
from ccm.sim.pybullet.robot import (
    contact_truth,
    load_robot,
    orientation_error,
    set_joint_positions,
    start_ik,
    tool_point_in_link,
)
from ccm.sim.pybullet.scene import PATCH_MODES, PyBullet3DConfig
from ccm.sim.pybullet.torque_loop import TorqueLoop
from ccm.sim.pybullet.world import build_world
from ccm.sim.scene3d import Box3DSpec, Scene3D, TablePatch, TableSpec
from ccm.sim.sensor import FTSensor
from ccm.sim.start_pose import start_pose_3d

__all__ = [
    "DOWN", "GRAVITY", "N_ARM", "PANDA_READY", "PATCH_MODES", "Box3DSpec", "PyBullet3D",
    "PyBullet3DConfig", "Scene3D", "TablePatch", "TableSpec", "ToolSpec", "orientation_error",
]  # fmt: skip


# --------------------------------------------------------------------------- simulator


class PyBullet3D(Simulator):
    """A torque-controlled Panda with a block tool in a PyBullet world.

    Args:
        scene: the parsed 3D scene.
        start: tool-point start pose ``[x, y, z]`` (tool pointing down) or
            ``[x, y, z, qx, qy, qz, qw]`` [m]; the arm starts at rest in the configuration
            found by inverse kinematics from ``config.rest_posture``.
        config: backend settings (defaults if ``None``).

    Attributes:
        max_speed: runaway guard [m/s] for :func:`ccm.sim.base.check_state_finite`.
    """

    dim = 3

    def __init__(
        self, scene: Scene3D, start: Sequence[float], config: PyBullet3DConfig | None = None
    ) -> None:
        self.config = config if config is not None else PyBullet3DConfig()
        super().__init__(self.config.dt, self.config.control_decimation)
        self.scene = scene
        self.start_position, self.start_orientation = start_pose_3d(scene, start)
        self.max_speed = self.config.max_speed
        self.sensor = FTSensor(self.config.sensor, force_dim=3, torque_dim=3)
        tool = self.config.tool
        #: tool point in the tool's centre-of-mass frame (bottom face centre)
        self._tip_local = (0.0, 0.0, tool.size[2] / 2.0)
        #: the same point in the tool's URDF link frame (for calculateJacobian), set on reset
        self._tip_link = (0.0, 0.0, tool.size[2])
        #: the robot's joint-torque loop (its Pinocchio model built on the first reset)
        self.torque_loop = TorqueLoop(self.config, self.start_orientation)
        self._tip_local_arr = np.array(self._tip_local)
        self._tool_inertia = np.diag(box_inertia(tool.mass, tool.size))  # tool frame [kg m²]
        #: the tool's centre-of-mass twist at the previous physics step (NaN: none yet)
        self._twist_prev = np.full(6, np.nan)
        self._wrench = np.zeros(6)  # the command held this control step: [f; m]
        self._client: int | None = None
        self._p: Any = None
        self._robot = -1
        self._tool_link = -1
        self._arm = list(range(N_ARM))
        self._sensed_joints = [*self._arm, -1]  # the arm, then the tool joint (set on reset)
        self._q: np.ndarray | None = None  # the arm's joint state, read by _refresh_tip
        self._dq: np.ndarray | None = None
        self._body_friction: dict[int, float] = {}
        self._box_bodies: set[int] = set()
        self._table_body = -1
        base_mu = scene.table.friction if scene.table is not None else 0.0
        face = (tool.size[0], tool.size[1])  # the tool point's face [m] (footprint)
        #: the table's friction under the tool, set before every physics step
        self.table = TableFriction(
            self.config.patch_mode, face, self.config.footprint_grid, base_mu
        )
        self._steps = 0
        self._rng: np.random.Generator | None = None
        #: the simulated hand on the tool (scene.human), and its mean force over a period
        self._hand = Hand(scene.human, self.dt) if scene.human is not None else None
        self._hand_mean = np.zeros(3)

    @classmethod
    def from_config(
        cls, sim_cfg: Mapping[str, Any], scene_cfg: Mapping[str, Any], start: Sequence[float]
    ) -> PyBullet3D:
        """Build from the ``sim`` group, ``task.scene`` and ``task.start`` configs.

        Raises:
            ConfigError: naming the first invalid key (``sim.*``, ``task.scene.*``,
                ``task.start``).
        """
        config = PyBullet3DConfig.from_mapping(sim_cfg, "sim")
        scene = Scene3D.from_mapping(scene_cfg, "task.scene")
        return cls(scene, start, config)

    # ------------------------------------------------------------------ public API

    @property
    def physics_steps(self) -> int:
        """Physics steps since the last reset."""
        return self._steps

    @property
    def joint_positions(self) -> np.ndarray:
        """Current arm joint angles [rad], shape (7,)."""
        return self._joint_state()[0].copy()

    def reset(self, seed: int | None = None) -> tuple[Observation, StepInfo]:
        """(Re)connect, build the world, put the tool at the start pose at rest."""
        import pybullet as p

        self._p = p
        if self._client is None:
            self._client = p.connect(p.GUI if self.config.gui else p.DIRECT)
            if self._client < 0:
                raise RuntimeError("could not connect to a PyBullet physics server")
        cid = self._client
        p.resetSimulation(physicsClientId=cid)
        p.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
        p.setTimeStep(self.dt, physicsClientId=cid)
        p.setPhysicsEngineParameter(
            numSolverIterations=self.config.solver_iterations, physicsClientId=cid
        )
        self._body_friction = {}
        self._build_scene()
        self._robot, self._tool_link = load_robot(p, cid, self.config)
        self._sensed_joints = [*self._arm, self._tool_link]
        self._q = self._dq = None
        self._tip_link = tool_point_in_link(p, cid, self._robot, self._tool_link, self._tip_local)
        self.torque_loop.attach(p, cid, self._robot, self._tool_link, self._tip_link)
        self._place_at_start()
        self._twist_prev = np.full(6, np.nan)
        self._refresh_tip()
        self._rng = np.random.default_rng(seed)
        self.sensor.reset(self._rng)
        self._hand_mean = np.zeros(3)
        if self._hand is not None:  # its own stream: the sensor's draws stay as they were
            self._hand.reset(np.random.default_rng(None if seed is None else [seed, 1]))
        # one uncounted settling step with a zero wrench, so the joint F/T sensor holds a
        # reading (PyBullet fills it during a step); gravity compensation keeps the arm put
        self._update_patch_friction()
        tau = self._torques(np.zeros(6))
        p.setJointMotorControlArray(
            self._robot, self._arm, p.TORQUE_CONTROL, forces=tau.tolist(), physicsClientId=cid
        )
        p.stepSimulation(physicsClientId=cid)
        self._refresh_tip()
        self._steps = 0
        f, m = self._ft
        kf, km, n, mu, split = self._contacts()
        return self._output(f, m, kf, km, n, mu, split)

    def step(self, command: Command) -> tuple[Observation, StepInfo]:
        """Hold ``command`` for ``control_decimation`` physics steps (zero-order hold).

        Raises:
            SimulationDiverged: on a non-finite command or state.
        """
        if self._client is None:
            raise RuntimeError("PyBullet3D.step() called before reset()")
        # the torque law reads the buffer during this call only
        wrench = hold_command(command, self._wrench, self._steps * self.dt)
        p, cid, hold = self._p, self._client, self.control_decimation
        total: list[np.ndarray] = []  # sums of f, m, kf, km, split over the period
        hand_sum = np.zeros(3)
        for k in range(hold):
            self._update_patch_friction()
            tau = self._torques(wrench)
            p.setJointMotorControlArray(
                self._robot, self._arm, p.TORQUE_CONTROL, forces=tau.tolist(), physicsClientId=cid
            )
            if self._hand is not None:
                hand_sum = hand_sum + self._push_hand()
            p.stepSimulation(physicsClientId=cid)
            self._refresh_tip()
            self._steps += 1
            kf, km, n, mu, split = self._contacts()
            if hold > 1:
                parts = [*self._ft, kf, km, split]
                total = parts if k == 0 else [a + b for a, b in zip(total, parts, strict=True)]
        if self._hand is not None:
            self._hand_mean = hand_sum / hold
        if hold == 1:  # one physics step per control step (every shipped config): no means
            return self._output(*self._ft, kf, km, n, mu, split)
        f, m, kf, km, split = [a / hold for a in total]
        return self._output(f, m, kf, km, n, mu, split)

    def _push_hand(self) -> np.ndarray:
        """Apply the hand's force at the tool point for the next physics step; return it."""
        pos, _, lin, _ = self._tip
        assert self._hand is not None
        f = self._hand.force(pos, lin, self._steps * self.dt)
        self._p.applyExternalForce(
            self._robot, self._tool_link, f.tolist(), pos.tolist(), self._p.WORLD_FRAME,
            physicsClientId=self._client,
        )  # fmt: skip
        return f

    def close(self) -> None:
        """Disconnect this instance's physics client."""
        if self._client is not None and self._p is not None:
            try:
                self._p.disconnect(physicsClientId=self._client)
            except Exception:  # noqa: BLE001 - already disconnected (e.g. GUI closed)
                pass
        self._client = None

    def __del__(self) -> None:  # best effort: DIRECT clients are cheap but not free
        try:
            self.close()
        except Exception:  # noqa: BLE001
            pass

    # ------------------------------------------------------------------ world building

    def _build_scene(self) -> None:
        """Table and patches (per ``patch_mode``), boxes (:mod:`ccm.sim.pybullet.world`)."""
        cfg = self.config
        world = build_world(self._p, self._client, self.scene, cfg.patch_mode, cfg.gui)
        self._body_friction = world.body_friction
        self._box_bodies = world.box_bodies
        self._table_body = world.table_body
        self.table.attach(world.patch_map, world.table_mu)

    def _update_patch_friction(self) -> None:
        """The table's friction for the next physics step (:class:`TableFriction`)."""
        mu = self.table.update(self._tip[0], self._rot[:, :2])
        if mu is not None:
            self._p.changeDynamics(
                self._table_body, -1, lateralFriction=mu, physicsClientId=self._client
            )
            self._body_friction[self._table_body] = mu  # for the contact truth

    def _place_at_start(self) -> None:
        """Put the arm at rest in the start pose (IK seeded from the rest posture)."""
        p, cid = self._p, self._client
        q = start_ik(
            p, cid, self._robot, self._tool_link, self._tip_local, self.config.rest_posture,
            self.start_position, self.start_orientation,
        )  # fmt: skip
        set_joint_positions(p, cid, self._robot, q)
        self.torque_loop.set_rest(q)

    # ------------------------------------------------------------------ state and control

    def joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The arm's joint encoders (q [rad], q̇ [rad/s], 7 each): the robot's own measurement,
        for offline learners that work in joint space (seed A §4.4.1); never an Observation."""
        q, dq = self._joint_state()
        return q.copy(), dq.copy()

    def _recorded_joints(self) -> np.ndarray:
        """The joint angles after the last physics step, for the record (the state
        :meth:`_refresh_tip` read, which the next step's torque law uses too)."""
        return self._joint_state()[0]

    def _joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(q, q̇)`` as :meth:`_refresh_tip` last read them: every change of the joint state
        (a physics step, the placement at reset) is followed by a refresh."""
        if self._q is None:
            raise RuntimeError("PyBullet3D: no joint state before reset()")
        return self._q, self._dq

    def _refresh_tip(self) -> None:
        """Read the robot once per physics step: the arm's joint encoders (``self._q``,
        ``self._dq``: the next step's torques, :meth:`joint_state`) and the tool:
        ``self._tip`` = the tool point's position, orientation (x, y, z, w), linear and angular
        velocity, shared by every use within the step (patch friction, orientation hold,
        truth, observation), and ``self._ft`` = the external force and moment at the tool
        point from the tool joint's F/T reading (Newton–Euler balance of the tool,
        :func:`ccm.sim._kernels.tool_sense`)."""
        p, cid, robot, link = self._p, self._client, self._robot, self._tool_link
        ls = p.getLinkState(robot, link, 1, 1, physicsClientId=cid)
        # one query for the arm's encoders and the tool joint's F/T reading (its last entry)
        states = p.getJointStates(robot, self._sensed_joints, physicsClientId=cid)
        q, dq, reactions, _ = zip(*states, strict=True)  # columns: q, q̇, reaction, torque
        reading = reactions[N_ARM]
        self._q, self._dq = np.array(q[:N_ARM]), np.array(dq[:N_ARM])
        state = np.array(ls[0] + ls[1] + ls[6] + ls[7])
        tip, self._rot, wrench = tool_sense(
            state, np.array(reading), self._tip_local_arr, self._twist_prev,
            self.config.tool.mass, self._tool_inertia, GRAVITY, self.dt,
        )  # fmt: skip
        self._tip = (tip[:3], ls[1], tip[3:6], tip[6:])
        self._orn = state[3:7]
        self._twist_prev = state[7:]
        self._ft = (wrench[:3], wrench[3:])

    def _torques(self, wrench: np.ndarray) -> np.ndarray:
        """The robot's joint torques for ``wrench`` (:class:`TorqueLoop`) at the joint state
        read after the last physics step (:meth:`_refresh_tip`)."""
        q, dq = self._joint_state()
        if not all_finite(q, dq):
            raise SimulationDiverged(
                f"non-finite joint state at t={self._steps * self.dt:.3f} s: q={q.tolist()}"
            )
        return self.torque_loop.torques(wrench, q, dq, self._orn, self._tip[3])

    # ------------------------------------------------------------------ sensing

    def _contacts(self) -> tuple[np.ndarray, np.ndarray, int, float, np.ndarray]:
        """Ground-truth contact force/torque (about the tool point), count, friction and
        ``(table normal, box normal, box friction, normal force x, y, z)`` [N]
        (:func:`ccm.sim.pybullet.robot.contact_truth`)."""
        p, cid = self._p, self._client
        pts = p.getContactPoints(bodyA=self._robot, linkIndexA=self._tool_link, physicsClientId=cid)
        if self.table.patches:  # the table contacts, for the next step's footprint friction
            self.table.observe([(c[6], c[9]) for c in pts if c[2] == self._table_body])
        if not pts:
            return np.zeros(3), np.zeros(3), 0, -1.0, np.zeros(6)
        tip = self._tip[0]
        return contact_truth(pts, tip, self._box_bodies, self._body_friction)

    def _output(
        self,
        f_sensed: np.ndarray,
        t_sensed: np.ndarray,
        f_contact: np.ndarray,
        t_contact: np.ndarray,
        n: int,
        mu: float,
        split: np.ndarray,
    ) -> tuple[Observation, StepInfo]:
        """Observation (F/T path + sensor noise) and truth (:func:`ccm.sim.arm.arm_output`)."""
        return arm_output(
            self._steps * self.dt, self._tip, self._orn, (f_sensed, t_sensed), self.sensor,
            self.torque_loop.translational_inertia(*self._joint_state()),
            (f_contact, t_contact, n, mu, split), self.table.mu, self._recorded_joints(),
            self._hand_mean if self._hand is not None else None,
        )  # fmt: skip
