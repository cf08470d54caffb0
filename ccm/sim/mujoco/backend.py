"""3D physics backend on MuJoCo: the PyBullet backend's torque-controlled Panda with its block
tool, scene and sensor, on a second engine (issue #42).

The controller commands a task-space wrench ``u_t`` (seed A Eq. 1) at the tool point; the
robot's own torque loop (:class:`ccm.sim.arm.TorqueLaw`, the same law as PyBullet's) turns it
into joint torques from MuJoCo's own model terms (:mod:`ccm.sim.mujoco.robot`). What is the
same as :class:`ccm.sim.pybullet.backend.PyBullet3D`, and what is not:

* **Same**: the robot (:mod:`ccm.sim.mujoco.model`: URDF, PyBullet's inertias, limits, no
  damping), the tool and the tool point, the scene (:mod:`ccm.sim.scene3d`) and its patch
  modes (:class:`ccm.sim.footprint.TableFriction`), the start IK, the torque law and its
  gains, the F/T conversion (:func:`ccm.sim._kernels.tool_sense`) and the sensor model
  (noise, bias, faults, latency), the hand, the one uncounted settling step at reset, and
  the Observation and truth keys.
* **Contact**: MuJoCo's soft constraints (:mod:`ccm.sim.mujoco.world`): the per-point spring
  and damper of ``sim.contact_stiffness`` / ``contact_damping``, mapped on the contact mass
  ``sim.contact_mass_kg``; soft friction (a creep below μ N where Bullet sticks), whose rows
  have their own damping through contact pairs (``sim.impratio``) so that sliding does not
  lift the tool.
* **Order within a physics step.** ``mj_step1`` (kinematics, collisions, the model terms at
  the new state), then the torques, then ``mj_step2`` (constraint forces, sensors,
  integration). The F/T reading and the contact truth of a step are those of its start, as
  PyBullet's are of its step; the table's friction under the tool is set from the tool point
  of the previous step (1 ms late: 0.1 mm at 0.1 m/s), because MuJoCo fixes a contact's
  friction when it detects it.
* **Viewer**: ``sim.gui: true`` opens ``mujoco.viewer``'s passive viewer (a display is needed),
  synchronised every control step.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from ccm.core.errors import ConfigError, SimulationDiverged
from ccm.core.types import Command, Observation, StepInfo
from ccm.sim._kernels import tool_sense
from ccm.sim.arm import TorqueLaw, arm_output, dls_ik, hold_command
from ccm.sim.base import Simulator, all_finite
from ccm.sim.footprint import TableFriction
from ccm.sim.hand import Hand
from ccm.sim.mujoco.config import MuJoCo3DConfig
from ccm.sim.mujoco.model import panda_spec
from ccm.sim.mujoco.robot import MjPanda
from ccm.sim.mujoco.world import add_pairs, add_world
from ccm.sim.panda import GRAVITY, box_inertia
from ccm.sim.scene3d import Scene3D
from ccm.sim.sensor import FTSensor
from ccm.sim.start_pose import start_pose_3d

__all__ = ["MuJoCo3D", "MuJoCo3DConfig"]


class MuJoCo3D(Simulator):
    """A torque-controlled Panda with a block tool in a MuJoCo world: the arguments, attributes
    and promises of :class:`ccm.sim.pybullet.backend.PyBullet3D` (``scene``, the ``start`` pose
    of ``task.start``, ``config``; ``max_speed``), on the other engine."""

    dim = 3

    def __init__(
        self, scene: Scene3D, start: Sequence[float], config: MuJoCo3DConfig | None = None
    ) -> None:
        self.config = config if config is not None else MuJoCo3DConfig()
        super().__init__(self.config.dt, self.config.control_decimation)
        self.scene = scene
        self.start_position, self.start_orientation = start_pose_3d(scene, start)
        cfg = self.config
        if (
            cfg.gui
            and sys.platform.startswith("linux")
            and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
        ):  # MuJoCo's viewer would end the process (GLFW cannot start), not raise
            raise ConfigError("sim.gui", "true needs a display (DISPLAY is not set); use false")
        self.max_speed = cfg.max_speed
        self.sensor = FTSensor(cfg.sensor, force_dim=3, torque_dim=3)
        self.law = TorqueLaw(cfg, self.start_orientation)
        tool = cfg.tool
        self._tip_local = np.array([0.0, 0.0, tool.size[2] / 2.0])  # from the centre of mass
        self._tool_inertia = np.diag(box_inertia(tool.mass, tool.size))
        base_mu = scene.table.friction if scene.table is not None else 0.0
        self.table = TableFriction(cfg.patch_mode, (tool.size[0], tool.size[1]),
                                   cfg.footprint_grid, base_mu)  # fmt: skip
        self._hand = Hand(scene.human, self.dt) if scene.human is not None else None
        self._hand_mean = np.zeros(3)
        self._robot: MjPanda | None = None
        self._table_pairs = np.zeros(0, dtype=np.intp)
        self._wrench = np.zeros(6)
        self._steps = 0
        self._viewer: Any = None
        self._q_start: np.ndarray | None = None

    @classmethod
    def from_config(
        cls, sim_cfg: Mapping[str, Any], scene_cfg: Mapping[str, Any], start: Sequence[float]
    ) -> MuJoCo3D:
        """Build from the ``sim`` group, ``task.scene`` and ``task.start`` configs.

        Raises:
            ConfigError: naming the first invalid key (``sim.*``, ``task.scene.*``,
                ``task.start``).
        """
        config = MuJoCo3DConfig.from_mapping(sim_cfg, "sim")
        return cls(Scene3D.from_mapping(scene_cfg, "task.scene"), start, config)

    # ------------------------------------------------------------------ public API

    @property
    def physics_steps(self) -> int:
        """Physics steps since the last reset."""
        return self._steps

    @property
    def joint_positions(self) -> np.ndarray:
        """Current arm joint angles [rad], shape (7,)."""
        return self._arm().data.qpos.copy()

    def joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The arm's joint encoders (q [rad], q̇ [rad/s], 7 each): the robot's own measurement,
        for offline learners that work in joint space (seed A §4.4.1); never an Observation."""
        d = self._arm().data
        return d.qpos.copy(), d.qvel.copy()

    def reset(self, seed: int | None = None) -> tuple[Observation, StepInfo]:
        """Build the model on first use, put the tool at the start pose at rest, seed the
        sensor noise (and the hand's own stream), and take one uncounted settling step with a
        zero wrench so the F/T sensor holds a reading (as the PyBullet backend does)."""
        if self._robot is None:
            self._robot = self._build()
        robot = self._robot
        m, d = robot.model, robot.data
        mujoco.mj_resetData(m, d)
        if self.table.patches:
            m.pair_friction[self._table_pairs, :2] = self.table.base
        one_box = len(self._table_pairs) > 0
        self.table.attach(self._patch_map, self.table.base if one_box else None)
        if self._q_start is None:
            self._q_start = dls_ik(robot.pose, robot.jacobian, robot.limits,
                                   self.config.rest_posture, self.start_position,
                                   self.start_orientation)  # fmt: skip
        d.qpos[:] = self._q_start
        self.law.set_rest(self._q_start.copy())
        rng = np.random.default_rng(seed)
        self.sensor.reset(rng)
        self._hand_mean = np.zeros(3)
        if self._hand is not None:  # its own stream: the sensor's draws stay as they were
            self._hand.reset(np.random.default_rng(None if seed is None else [seed, 1]))
        mujoco.mj_step1(m, d)
        self._refresh(first=True)
        self._wrench[:] = 0.0
        truth = self._physics_step()
        self._steps = 0
        return self._output(truth)

    def step(self, command: Command) -> tuple[Observation, StepInfo]:
        """Hold ``command`` for ``control_decimation`` physics steps (zero-order hold).

        Raises:
            SimulationDiverged: on a non-finite command or state.
        """
        if self._robot is None:
            raise RuntimeError("MuJoCo3D.step() called before reset()")
        hold_command(command, self._wrench, self._steps * self.dt)  # read by _physics_step
        hold = self.control_decimation
        total: list[Any] = []
        hand_sum = np.zeros(3)
        for k in range(hold):
            truth = self._physics_step()
            hand_sum += self._hand_force
            self._steps += 1
            if hold > 1:
                parts = [*self._ft, *truth[:2], truth[4]]
                total = parts if k == 0 else [a + b for a, b in zip(total, parts, strict=True)]
        self._hand_mean = hand_sum / hold
        if self._viewer is not None:
            self._viewer.sync()
        if hold > 1:
            f, m_, kf, km, split = [a / hold for a in total]
            self._ft = (f, m_)
            truth = (kf, km, truth[2], truth[3], split)
        return self._output(truth)

    def close(self) -> None:
        """Close the viewer, if open."""
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    # ------------------------------------------------------------------ internals

    def _arm(self) -> MjPanda:
        if self._robot is None:
            raise RuntimeError("MuJoCo3D: no joint state before reset()")
        return self._robot

    def _build(self) -> MjPanda:
        """Compile the Panda and the scene's static world (once per simulator)."""
        cfg = self.config
        spec = panda_spec(cfg.tool, cfg.dt)
        robot_geoms = [geom.name for geom in spec.geoms]
        contact = (cfg.contact_stiffness, cfg.contact_damping, cfg.contact_mass_kg)
        world = add_world(spec, self.scene, cfg.patch_mode, *contact)
        add_pairs(spec, world, robot_geoms, *contact, cfg.impratio)
        robot = MjPanda(spec.compile(), world.box_geoms)
        self._table_pairs = np.array([robot.model.pair(n).id for n in world.table_pairs],
                                     dtype=np.intp)  # fmt: skip
        self._patch_map = world.patch_map
        if cfg.gui:
            self._viewer = _open_viewer(robot)
        return robot

    def _physics_step(self) -> tuple[np.ndarray, np.ndarray, int, float, np.ndarray]:
        """One physics step from the state ``mj_step1`` last computed: the table's friction
        for the next contacts, the torques, the hand, ``mj_step2``; its F/T reading and
        contact truth; then ``mj_step1`` and the new state (module docstring)."""
        robot = self._arm()
        m, d = robot.model, robot.data
        mu = self.table.update(self._tip[0], self._rot[:, :2])
        if mu is not None:  # the table's pairs: the contacts mj_step1 detects next
            m.pair_friction[self._table_pairs, :2] = mu
        q, dq = d.qpos.copy(), d.qvel.copy()
        if not all_finite(q, dq):
            raise SimulationDiverged(
                f"non-finite joint state at t={self._steps * self.dt:.3f} s: q={q.tolist()}"
            )
        d.ctrl[:] = self.law.torques(self._terms, self._wrench, q, dq, self._orn, self._tip[3])
        self._push_hand()
        mujoco.mj_step2(m, d)
        robot.keep_reading()
        truth, table = robot.contact_truth(self._tip[0])
        self.table.observe(table)
        mujoco.mj_step1(m, d)
        self._refresh()
        return truth

    def _push_hand(self) -> None:
        """The hand's force at the tool point for this physics step, as a wrench on the tool
        body (about its centre of mass, where ``xfrc_applied`` acts) so the F/T sensor sees
        it, as it does PyBullet's external force."""
        self._hand_force = np.zeros(3)
        if self._hand is None:
            return
        d, body = self._robot.data, self._robot.tool_body  # type: ignore[union-attr]
        pos, _, lin, _ = self._tip
        f = self._hand.force(pos, lin, self._steps * self.dt)
        d.xfrc_applied[body, :3] = f
        d.xfrc_applied[body, 3:] = np.cross(pos - d.xipos[body], f)
        self._hand_force = f

    def _refresh(self, first: bool = False) -> None:
        """Read the state ``mj_step1`` just computed: the model terms, the tool point's state
        and the external wrench at it (:func:`ccm.sim._kernels.tool_sense`)."""
        robot = self._arm()
        self._terms = robot.terms()
        link, reading = robot.tool_link()
        prev = np.full(6, np.nan) if first else self._twist_prev
        tip, self._rot, wrench = tool_sense(
            link, reading, self._tip_local, prev, self.config.tool.mass, self._tool_inertia,
            GRAVITY, self.dt,
        )  # fmt: skip
        self._tip = (tip[:3], link[3:7], tip[3:6], tip[6:])
        self._orn = link[3:7].copy()
        self._twist_prev = link[7:].copy()
        self._ft = (wrench[:3], wrench[3:])

    def _output(
        self, truth: tuple[np.ndarray, np.ndarray, int, float, np.ndarray]
    ) -> tuple[Observation, StepInfo]:
        """Observation (F/T path + sensor model) and truth (:func:`ccm.sim.arm.arm_output`)."""
        d = self._arm().data
        return arm_output(
            self._steps * self.dt, self._tip, self._orn, self._ft, self.sensor,
            self.law.translational_inertia(self._terms), truth, self.table.mu, d.qpos.copy(),
            self._hand_mean if self._hand is not None else None,
        )  # fmt: skip


def _open_viewer(robot: MjPanda) -> Any:
    """MuJoCo's passive viewer on the model (``sim.gui``); a clear error without a display."""
    try:
        import mujoco.viewer

        return mujoco.viewer.launch_passive(robot.model, robot.data)
    except Exception as exc:  # noqa: BLE001 - no display, no GL: say so in one line
        raise ConfigError("sim.gui", f"cannot open the MuJoCo viewer here ({exc})") from exc
