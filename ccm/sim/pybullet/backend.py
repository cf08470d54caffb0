"""3D physics backend on PyBullet: a torque-controlled Franka Panda with a block tool.

Seed A (Sidhik et al.) ran its 3D experiments on a Panda in PyBullet (§4.4). This backend
plays that role. The controller commands a task-space wrench ``u_t`` (seed A Eq. 1) at the
*tool point*; the robot's own torque loop turns it into joint torques.

Modelling choices (each one is also stated where it is implemented; the robot and tool, the
tool point, the F/T sensor, the contact ground truth and the compliant tool contact are
described in :mod:`ccm.sim.pybullet.robot`):

* **Torque control.** The default velocity motors are switched off (``VELOCITY_CONTROL``
  with force 0) and ``TORQUE_CONTROL`` is re-applied every physics step (it lasts one step).
  Every physics step, with the command held (zero-order hold over ``control_decimation``
  steps)::

      τ = Jᵀ [f; m + m_hold] + h(q, q̇) − Jᵀ Λ J̇ q̇ + N τ₀
      h = calculateInverseDynamics(q, q̇, 0)         (gravity + Coriolis: H of seed A Eq. 1)
      τ₀ = K_n (q_rest − q) − D_n q̇                 (posture toward the start configuration)
      N = I − Jᵀ Λ J M⁻¹,  Λ = (J M⁻¹ Jᵀ)⁻¹          (dynamically consistent null space)

  The dynamically consistent projector is used so the posture term produces no
  task-space acceleration, and ``− Jᵀ Λ J̇ q̇`` (``task_coriolis_compensation``; J̇ q̇ from
  the model or, with ``dynamics: pybullet``, a directional finite difference of the
  Jacobian) removes the velocity-product term, so that ``ẍ = Λ⁻¹ W``: with a zero wrench
  the tool stays put (issue #4 check 3) even while the posture term moves the elbow. The
  simple projector ``I − Jᵀ J⁺ᵀ`` would leak posture torques into the task space.
  ``m_hold = K_o e_R − D_o ω`` is an optional orientation hold toward the start orientation
  (``orientation_stiffness``/``orientation_damping``): ccm's controllers close the
  translational loop only in 3D (``FixedImpedance.rotation_torque`` returns zeros), so the
  robot keeps its tool orientation itself. Set both gains to 0 to leave rotation to the
  commanded torque alone. Link and joint damping are set to 0 so ``h`` is exact.
* **Model terms** (``dynamics``). Default ``pinocchio``: J, J̇ q̇ (exact), h, M⁻¹ Jᵀ and Λ
  from one Pinocchio call per physics step (:mod:`ccm.sim.pybullet.dynamics`: the same URDF
  and PyBullet's own link inertias, checked against PyBullet's queries to 1e-8).
  ``pybullet``: ``calculateJacobian`` (twice: J̇ q̇ is the forward difference above),
  ``calculateInverseDynamics``, ``calculateMassMatrix`` and two ``np.linalg.inv``.
* **Table patches** (``patch_mode``). Default ``friction_map``: the table top is one box
  and, before every physics step, its friction is set to that of the patch under the tool
  point (the table's own value elsewhere); patches are drawn as visual-only boxes in the
  GUI. The whole tool face therefore gets one friction value while it straddles a patch
  edge, switching when the tool point crosses it. ``boxes``: each patch is a thin box flush
  with the top and the table's top layer is cut around the patches (cells of the grid
  spanned by the patch edges); geometrically faithful, but the tool face, sunk slightly
  into the surface it rests on, catches on the side face of the next box: normal-force
  spikes of 57-136 N at a 10 N press were measured at edge crossings (friction_map: one
  ~26 N, 7 ms transient from the friction step itself). ``footprint``: the continuous top of
  ``friction_map``, its friction the pressure-weighted mean over the tool's face from the
  previous step's table contacts, so it ramps across a patch edge over the face's width
  (:mod:`ccm.sim.pybullet.footprint`, physics and limits there).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, SimulationDiverged, check_vector
from ccm.core.types import Command, Observation, StepInfo
from ccm.sim.base import Simulator, all_finite
from ccm.sim.hand import Hand
from ccm.sim.pybullet._kernels import tool_sense, torque_law
from ccm.sim.pybullet.dynamics import PandaDynamics, robot_dynamics
from ccm.sim.pybullet.footprint import face_grid, table_friction
from ccm.sim.pybullet.robot import (
    DOWN,
    GRAVITY,
    N_ARM,
    box_inertia,
    contact_truth,
    inverse_dynamics,
    load_robot,
    nullspace_projection,
    orientation_error,
    set_joint_positions,
    start_ik,
    task_inertia,
    tool_jacobian,
    tool_point_in_link,
)
from ccm.sim.pybullet.scene import (
    PANDA_READY,
    PATCH_MODES,
    Box3DSpec,
    PyBullet3DConfig,
    Scene3D,
    TablePatch,
    TableSpec,
    ToolSpec,
)
from ccm.sim.pybullet.world import build_world
from ccm.sim.sensor import FTSensor
from ccm.sim.start_pose import check_start_3d

__all__ = [
    "DOWN", "GRAVITY", "N_ARM", "PANDA_READY", "PATCH_MODES", "Box3DSpec", "PyBullet3D",
    "PyBullet3DConfig", "Scene3D", "TablePatch", "TableSpec", "ToolSpec", "orientation_error",
]  # fmt: skip


#: ``StepInfo.extra`` keys of the arm's joint angles [rad], recorded as ``truth_q1_rad`` ...
_JOINT_KEYS = tuple(f"q{i}_rad" for i in range(1, N_ARM + 1))


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
        st = check_vector("task.start", start, (3, 7))
        self.start_position = st[:3].copy()
        check_start_3d(scene, self.start_position)
        if st.shape[0] == 7:
            nq = float(np.linalg.norm(st[3:]))
            if nq < 1e-9:
                raise ConfigError("task.start", "quaternion part must be non-zero")
            self.start_orientation = st[3:] / nq
        else:
            self.start_orientation = np.array(DOWN)
        self.max_speed = self.config.max_speed
        self.sensor = FTSensor(self.config.sensor, force_dim=3, torque_dim=3)
        tool = self.config.tool
        #: tool point in the tool's centre-of-mass frame (bottom face centre)
        self._tip_local = (0.0, 0.0, tool.size[2] / 2.0)
        #: the same point in the tool's URDF link frame (for calculateJacobian), set on reset
        self._tip_link = (0.0, 0.0, tool.size[2])
        #: Pinocchio's model of the arm (``sim.dynamics: pinocchio``), built on the first reset
        self._dynamics: PandaDynamics | None = None
        self._tip_local_arr = np.array(self._tip_local)
        self._tool_inertia = np.diag(box_inertia(tool.mass, tool.size))  # tool frame [kg m²]
        #: the tool's centre-of-mass twist at the previous physics step (NaN: none yet)
        self._twist_prev = np.full(6, np.nan)
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
        self._q_rest = np.zeros(N_ARM)
        self._table_body = -1
        self._table_mu = -1.0
        self._patch_map: list[tuple[float, float, float, float, float]] = []
        self._face = (tool.size[0], tool.size[1])  # the tool point's face [m] (footprint)
        self._grid = face_grid(*self._face, self.config.footprint_grid)
        self._table_contacts: list[tuple[Any, float]] = []  # last step's (position, N)
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
        self._table_contacts = []
        self._build_scene()
        self._robot, self._tool_link = load_robot(p, cid, self.config)
        self._sensed_joints = [*self._arm, self._tool_link]
        self._q = self._dq = None
        self._tip_link = tool_point_in_link(p, cid, self._robot, self._tool_link, self._tip_local)
        if self.config.dynamics == "pinocchio" and self._dynamics is None:  # once: same robot
            self._dynamics = robot_dynamics(p, cid, self._robot, self.config.tool, self._tip_link)
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
        f_cmd, t_cmd = command.force, command.torque
        if len(f_cmd) != 3 or len(t_cmd) != 3:
            raise ValueError(
                f"command must have force (3,) and torque (3,), got {np.shape(f_cmd)}, "
                f"{np.shape(t_cmd)}"
            )
        wrench = np.concatenate([np.asarray(f_cmd, float), np.asarray(t_cmd, float)])
        if not all_finite(wrench):
            raise SimulationDiverged(
                f"non-finite command force={np.asarray(f_cmd).tolist()} "
                f"torque={np.asarray(t_cmd).tolist()} at t={self._steps * self.dt:.3f} s"
            )
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
        self._table_body, self._patch_map = world.table_body, world.patch_map
        self._box_bodies = world.box_bodies
        if world.table_mu is not None:
            self._table_mu = world.table_mu

    def _update_patch_friction(self) -> None:
        """``friction_map``: give the table the friction of the patch under the tool point;
        ``footprint``: the pressure-weighted mean under the tool's face (module docstring)."""
        if not self._patch_map:
            return
        base = self.scene.table.friction if self.scene.table is not None else 0.0
        mu = table_friction(
            self.config.patch_mode, self._tip[0], self._rot[:, :2], self._table_contacts,
            self._face, self._grid, self._patch_map, base,
        )  # fmt: skip
        if mu != self._table_mu:
            self._p.changeDynamics(
                self._table_body, -1, lateralFriction=mu, physicsClientId=self._client
            )
            self._table_mu = mu
            self._body_friction[self._table_body] = mu

    def _place_at_start(self) -> None:
        """Put the arm at rest in the start pose (IK seeded from the rest posture)."""
        p, cid = self._p, self._client
        q = start_ik(
            p, cid, self._robot, self._tool_link, self._tip_local, self.config.rest_posture,
            self.start_position, self.start_orientation,
        )  # fmt: skip
        set_joint_positions(p, cid, self._robot, q)
        cfg, zeros = self.config, np.zeros(2 * N_ARM)
        # the torque law's gains and set points (:func:`torque_law`), the current state
        # filled in every physics step
        gains = [cfg.orientation_stiffness, cfg.orientation_damping]
        self._hold = np.concatenate([gains, self.start_orientation, zeros[:7]])
        self._posture = np.concatenate([[cfg.nullspace_stiffness, cfg.nullspace_damping], q, zeros])
        self._q_rest = self._posture[2 : 2 + N_ARM]  # a view: the posture target

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
        :func:`ccm.sim.pybullet._kernels.tool_sense`)."""
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

    def _jacobian(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        return tool_jacobian(
            self._p, self._client, self._robot, self._tool_link, self._tip_link, q, dq
        )

    def _torques(self, wrench: np.ndarray) -> np.ndarray:
        """τ = Jᵀ W + h(q, q̇) − Jᵀ Λ J̇ q̇ + N τ₀ (module docstring): compiled on Pinocchio's
        terms (``sim.dynamics: pinocchio``), else :meth:`_torques_pybullet`."""
        cfg = self.config
        q, dq = self._joint_state()  # read after the last physics step (_refresh_tip)
        if not all_finite(q, dq):
            raise SimulationDiverged(
                f"non-finite joint state at t={self._steps * self.dt:.3f} s: q={q.tolist()}"
            )
        if self._dynamics is None:
            return self._torques_pybullet(wrench, q, dq)
        minv, jac, jdq, h = self._dynamics.torque_terms(q, dq)
        self._hold[6:10] = self._orn
        self._hold[10:] = self._tip[3]
        self._posture[2 + N_ARM : 2 + 2 * N_ARM] = q
        self._posture[2 + 2 * N_ARM :] = dq
        return torque_law(
            minv, jac, jdq, h, wrench, self._hold, self._posture, cfg.task_coriolis_compensation
        )

    def _torques_pybullet(self, wrench: np.ndarray, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The torque law in numpy on PyBullet's queries (``sim.dynamics: pybullet``)."""
        cfg = self.config
        use_null = cfg.nullspace_stiffness > 0.0 or cfg.nullspace_damping > 0.0
        jac, h, jdq, minv_jt, lam = self._model_terms(
            q, dq, use_null or cfg.task_coriolis_compensation
        )
        w = wrench
        if cfg.orientation_stiffness > 0.0 or cfg.orientation_damping > 0.0:
            _, orn, _, omega = self._tip
            hold = cfg.orientation_stiffness * orientation_error(self.start_orientation, orn)
            hold -= cfg.orientation_damping * omega
            w = wrench.copy()
            w[3:] += hold
        tau = jac.T @ w + h
        if cfg.task_coriolis_compensation:
            tau -= jac.T @ (lam @ jdq)
        if use_null:
            tau0 = cfg.nullspace_stiffness * (self._q_rest - q) - cfg.nullspace_damping * dq
            tau += nullspace_projection(jac, lam, minv_jt, tau0)  # N τ₀
        return tau

    def _model_terms(self, q: np.ndarray, dq: np.ndarray, task: bool) -> tuple[Any, ...]:
        """``(J, h, J̇ q̇, M⁻¹ Jᵀ, Λ)`` of the torque law (``sim.dynamics``): Pinocchio's in
        one call, or PyBullet's queries (the last three only if ``task``, else ``None``)."""
        if self._dynamics is not None:
            t = self._dynamics.compute(q, dq)
            return t.jacobian, t.h, t.jdot_qdot, t.minv_jt, t.lam
        p, cid = self._p, self._client
        jac = self._jacobian(q, dq)
        h = inverse_dynamics(p, cid, self._robot, q, dq)
        if not task:
            return jac, h, None, None, None
        minv_jt, lam = task_inertia(p, cid, self._robot, q, jac)  # M⁻¹ Jᵀ, Λ = (J M⁻¹ Jᵀ)⁻¹
        jdq = None
        if self.config.task_coriolis_compensation:
            # J̇ q̇ as the directional derivative of J along q̇ (forward difference)
            eps = 1e-6
            jdq = (self._jacobian(q + eps * dq, dq) - jac) @ dq / eps
        return jac, h, jdq, minv_jt, lam

    # ------------------------------------------------------------------ sensing

    def _contacts(self) -> tuple[np.ndarray, np.ndarray, int, float, np.ndarray]:
        """Ground-truth contact force/torque (about the tool point), count, friction and
        ``(table normal, box normal, box friction, normal force x, y, z)`` [N]
        (:func:`ccm.sim.pybullet.robot.contact_truth`)."""
        p, cid = self._p, self._client
        pts = p.getContactPoints(bodyA=self._robot, linkIndexA=self._tool_link, physicsClientId=cid)
        if self._patch_map:  # read by the next step's patch friction (footprint mode) only
            self._table_contacts = [(c[6], c[9]) for c in pts if c[2] == self._table_body]
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
        """Observation (F/T path + sensor noise) and truth (contact forces; the same
        ``extra`` keys at every step, as the recorder fixes its columns at the first)."""
        pos, _, lin, ang = self._tip
        if not all_finite(pos, lin):
            raise SimulationDiverged(
                f"non-finite tool state at t={self._steps * self.dt:.3f} s "
                f"(position={pos.tolist()}, velocity={lin.tolist()})"
            )
        f_meas, t_meas = self.sensor.measure(f_sensed, t_sensed)
        table_n, box_n, box_f, nx, ny, nz = split.tolist()
        obs = Observation(
            t=self._steps * self.dt,
            position=pos,
            orientation=self._orn,  # a fresh array every physics step
            lin_vel=lin,
            ang_vel=ang,
            force=f_meas,
            torque=t_meas,
        )
        hand = {}
        if self._hand is not None:  # the hand's force is external too, not a contact
            hand = dict(zip(("human_fx_N", "human_fy_N", "human_fz_N"),
                            self._hand_mean.tolist(), strict=True))  # fmt: skip
        info = StepInfo(
            # contacts (and a scene's hand) are the only external forces in this world
            true_force=f_contact if self._hand is None else f_contact + self._hand_mean,
            true_torque=t_contact,
            contact_force=f_contact,
            n_contacts=n,
            extra={
                "surface_friction": mu if n > 0 else -1.0,
                "table_friction": self._table_mu,  # the table's friction this step (patches)
                "contact": 1.0 if n > 0 else 0.0,
                "table_normal_N": table_n,  # normal force from the table [N]
                "box_normal_N": box_n,  # ... from scene.boxes (walls) [N]
                "box_friction_N": box_f,  # |friction force| from the boxes [N]
                # the normal part of the contact force (friction left out) [N]
                "normal_force_x": nx,
                "normal_force_y": ny,
                "normal_force_z": nz,
                # the arm's joint angles [rad] (q1_rad ... q7_rad): what `ccm animate` replays
                **dict(zip(_JOINT_KEYS, self._recorded_joints().tolist(), strict=True)),
                **hand,
            },
        )
        return obs, info
