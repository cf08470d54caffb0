"""Planar physics backend on pymunk (Chipmunk2D), in SI units.

Seed A (Sidhik et al.) ran its 2D experiments in a Box2D world with noiseless measurements
(§4.1, Fig. 1c); this backend plays that role. The end-effector is a box driven by a
task-space force, the controller command ``u_t`` of seed A Eq. 1. The robot's own gravity
compensation (the ``H_t`` term of Eq. 1) is done here, so a controller commands only the
task-space force.
The Chipmunk space (static scene and EE body) is built by :mod:`ccm.sim.pymunk.space`.

Modelling choices:

* pymunk's defaults assume pixel units, so ``collision_slop`` and ``iterations`` come from
  the config (1e-4 m, 30 by default) and every length is in metres.
* pymunk combines the friction and the restitution of two shapes by multiplying them. The
  end-effector's shape has friction 1.0 and elasticity 1.0, so the *surface's* values are the
  effective contact values.
* Springs and viscous drag are applied by this module as external forces each physics step
  (exact linear laws, explicit in the state at the start of the step). The explicit drag is
  stable while ``c * dt / m < 2``.
* The F/T sensor measures the external wrench on the end-effector: contact forces, springs
  and drag, never the command or gravity. Contact forces are the arbiters' impulses of the
  step divided by ``dt``. The impulse that ``Body.each_arbiter`` reports on the EE body is the
  impulse applied *to the EE* (a box resting on a floor under gravity reads +m g along +y).
  With ``control_decimation > 1`` the reported wrench is the mean over the control period's
  physics steps, like a sensor sampled at the physics rate and averaged to the control rate.
* Seed B's physical-HRI elements (:mod:`ccm.sim.pymunk.hri`, force laws in
  :mod:`ccm.sim.pymunk.hri_forces`) are external forces on the EE centre, applied each physics step
  like the springs, so the one F/T sensor measures their sum (seed B §3.1): *compliant walls*
  (a unilateral spring-damper ``max(0, k d - c v.n) n`` at penetration ``d > 0``; it counts as
  a contact in ``contact_force``, ``n_contacts`` and ``extra["contact"]``, with
  ``surface_friction`` 0 when nothing else is touched), a *human hand* (a PD pull toward a
  goal plus low-pass noise, norm-saturated) and a *vibration* (sinusoids with random phases
  plus white noise, optionally inside a region). Their random draws come from a generator of
  their own, ``default_rng([seed, 7])``, made at reset only for scenes that have them, so the
  sensor's stream and every other scene are unchanged. Their truth is in ``extra``:
  ``wall_offset_m``, ``human_goal``, ``human_goal_x_m``, ``human_goal_y_m``, ``human_fx_N``,
  ``human_fy_N``, ``disturbance_fx_N``, ``disturbance_fy_N`` (keys present only for the
  elements the scene has).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pymunk

from ccm.core.errors import (
    ConfigError,
    SimulationDiverged,
    check_vector,
)
from ccm.core.types import Command, Observation, StepInfo
from ccm.core.vector import readonly
from ccm.sim.base import Simulator
from ccm.sim.pymunk._contacts import ContactReader
from ccm.sim.pymunk._raw import RawBody
from ccm.sim.pymunk.config import Pymunk2DConfig
from ccm.sim.pymunk.hri_forces import HRIForces
from ccm.sim.pymunk.scene import SceneSpec
from ccm.sim.pymunk.space import build_space
from ccm.sim.sensor import FTSensor
from ccm.sim.start_pose import check_start_2d

# the arrays of _output: slices of its one buffer
_POS, _ANGLE, _VEL, _OMEGA = slice(0, 2), slice(2, 3), slice(3, 5), slice(5, 6)
_TRUE_F, _TRUE_T, _CONTACT_F = slice(6, 8), slice(8, 9), slice(9, 11)
_MEAS_F, _MEAS_T = slice(11, 13), slice(13, 14)

#: second entry of the seed sequence of the HRI elements' generator (walls, human, vibration)
HRI_STREAM = 7


class Pymunk2D(Simulator):
    """A 2D world with one box end-effector driven by a task-space force.

    Args:
        scene: the parsed scene.
        start: start pose ``[x, y]`` or ``[x, y, angle]`` [m, rad]; the EE starts at rest.
        config: backend settings (defaults if ``None``).

    Attributes:
        max_speed: runaway guard [m/s] for :func:`ccm.sim.base.check_state_finite`.
    """

    dim = 2

    def __init__(
        self,
        scene: SceneSpec,
        start: Sequence[float],
        config: Pymunk2DConfig | None = None,
    ) -> None:
        self.config = config if config is not None else Pymunk2DConfig()
        super().__init__(self.config.dt, self.config.control_decimation)
        self.scene = scene
        st = check_vector("task.start", start, (2, 3))
        self.start = (float(st[0]), float(st[1]), float(st[2]) if st.shape[0] == 3 else 0.0)
        check_start_2d(scene, self.start)
        self.max_speed = self.config.max_speed
        self.sensor = FTSensor(self.config.sensor, force_dim=2, torque_dim=1)
        self._ideal_sensor = self.sensor.ideal
        self._space: pymunk.Space | None = None
        self._body: pymunk.Body | None = None
        self._rng: np.random.Generator | None = None
        self._steps = 0
        self._path = 0.0
        self._contacts = ContactReader(self.dt, scene.ee.rotate)
        self._visc = (-1, 0.0)  # _viscosity's last (physics step, coefficient)
        self._springs = [
            (s.anchor[0], s.anchor[1], s.stiffness, s.rest_length) for s in scene.springs
        ]
        # physics-step window [attach, detach) of each spring, for scenes that schedule them
        self._spring_steps = [
            (
                round(s.attach_s / self.dt),
                math.inf if s.detach_s is None else round(s.detach_s / self.dt),
            )
            for s in scene.springs
        ]
        self._scheduled_springs = any(s.scheduled for s in scene.springs)
        # _attached()'s cache: flags, attached springs, and the step window they hold for
        self._att: tuple[list[bool], list[tuple[float, ...]], float, float, float]
        self._att = ([], [], 1, 0, 0.0)
        self._comp_fy = scene.ee.mass * scene.gravity if self.config.gravity_compensation else 0.0
        self._has_viscous = bool(scene.viscous)
        self._rotates = scene.ee.rotate
        self._has_static = bool(scene.surfaces or scene.boxes)
        self._angle0 = float(self.start[2])
        self._hri = HRIForces(scene, self.dt) if scene.has_hri else None
        vib = scene.vibration
        if vib is not None and vib.frequency_hz >= 0.5 / self.dt:
            raise ConfigError(
                "task.scene.vibration.frequency_hz",
                f"must be below the physics Nyquist rate {0.5 / self.dt:g} Hz, "
                f"got {vib.frequency_hz!r}",
            )

    @classmethod
    def from_config(
        cls, sim_cfg: Mapping[str, Any], scene_cfg: Mapping[str, Any], start: Sequence[float]
    ) -> Pymunk2D:
        """Build from the ``sim`` group, ``task.scene`` and ``task.start`` configs.

        Raises:
            ConfigError: naming the first invalid key (``sim.*``, ``task.scene.*``,
                ``task.start``).
        """
        config = Pymunk2DConfig.from_mapping(sim_cfg, "sim")
        scene = SceneSpec.from_mapping(scene_cfg, "task.scene")
        return cls(scene, start, config)

    # ------------------------------------------------------------------ public API

    @property
    def physics_steps(self) -> int:
        """Physics steps since the last reset."""
        return self._steps

    @property
    def path_length(self) -> float:
        """Path length travelled by the EE centre since the last reset [m]."""
        return self._path

    def reset(self, seed: int | None = None) -> tuple[Observation, StepInfo]:
        """Rebuild the space, put the EE at ``start`` at rest, seed the sensor noise."""
        self._space, self._body = build_space(self.scene, self.config, self.start)
        self._raw = RawBody(self._space, self._body)
        self._state: tuple[float, ...] | None = None
        self._visc = (-1, 0.0)
        self._rng = np.random.default_rng(seed)
        self.sensor.reset(self._rng)
        self._steps = 0
        self._path = 0.0
        self._new_step_objects()
        x, y = self.start[0], self.start[1]
        fsx, fsy = self._spring_force(x, y)
        if self._hri is None:
            return self._output((fsx, fsy, 0.0, 0.0, 0.0), 0, -1.0)
        # own stream, so the sensor's noise is the same as without the HRI elements
        self._hri.reset(np.random.default_rng(None if seed is None else [seed, HRI_STREAM]))
        wx, wy, nw = self._hri.at_rest(x, y)  # human and vibration: not applied yet
        return self._output((fsx + wx, fsy + wy, 0.0, wx, wy), nw, 0.0 if nw else -1.0)

    def step(self, command: Command) -> tuple[Observation, StepInfo]:
        """Hold ``command`` for ``control_decimation`` physics steps (zero-order hold).

        Raises:
            SimulationDiverged: on a non-finite command or state.
        """
        body = self._body
        if body is None:
            raise RuntimeError("Pymunk2D.step() called before reset()")
        cfx, cfy, ctq = self._command(command)
        cfy += self._comp_fy
        dt = self.dt
        sfx = sfy = stq = skx = sky = 0.0  # sums of external fx, fy, torque, contact fx, fy
        n_contacts, mu = 0, -1.0
        # the state read at the end of the previous step (nothing else moves the body)
        raw = self._raw
        x, y, vx, vy = self._state if self._state is not None else raw.state()
        hri = self._hri
        viscous, rotates, static = self._has_viscous, self._rotates, self._has_static
        if hri is not None:
            hri.start_period()
        for _ in range(self.control_decimation):
            fsx, fsy = self._spring_force(x, y)
            c = self._viscosity(x, y) if viscous else 0.0
            fex, fey = fsx - c * vx, fsy - c * vy
            if rotates:
                body.torque = ctq
            if hri is not None:  # human + vibration join (fex, fey); compliant walls: (wx, wy)
                hx, hy, wx, wy, nw = hri.step(x, y, vx, vy, self._steps * dt)
                fex += hx
                fey += hy
                nx, ny, vx, vy = raw.advance(cfx + fex + wx, cfy + fey + wy, dt)
            else:
                nx, ny, vx, vy = raw.advance(cfx + fex, cfy + fey, dt)
            if static:
                kfx, kfy, ktq, n_contacts, mu = self._contacts.read(body)
            else:  # nothing to touch: skip the arbiter walk (hot path of contact-free scenes)
                kfx = kfy = ktq = 0.0
            if hri is not None:  # a compliant wall is a (frictionless) contact
                kfx += wx
                kfy += wy
                n_static = n_contacts if static else 0
                if nw and not n_static:
                    mu = 0.0
                n_contacts = n_static + nw
            sfx += fex + kfx
            sfy += fey + kfy
            stq += ktq
            skx += kfx
            sky += kfy
            self._steps += 1
            self._path += math.hypot(nx - x, ny - y)
            x, y = nx, ny
            if not math.isfinite(x + y + vx + vy):
                self._check_state(body)
        k = 1.0 / self.control_decimation
        self._state = (x, y, vx, vy)
        wrench = (sfx * k, sfy * k, stq * k, skx * k, sky * k)
        return self._output(wrench, n_contacts, mu, self._state)

    def _command(self, command: Command) -> tuple[float, float, float]:
        """The command's (fx, fy, torque) as floats, checked for shape and finiteness."""
        f_cmd, t_cmd = command.force, command.torque
        if len(f_cmd) != 2 or len(t_cmd) != 1:
            raise ValueError(
                f"command must have force (2,) and torque (1,), got {np.shape(f_cmd)}, "
                f"{np.shape(t_cmd)}"
            )
        cfx, cfy, ctq = float(f_cmd[0]), float(f_cmd[1]), float(t_cmd[0])
        if not math.isfinite(cfx + cfy + ctq):
            raise SimulationDiverged(
                f"non-finite command force={np.asarray(f_cmd).tolist()} "
                f"torque={np.asarray(t_cmd).tolist()} at t={self._steps * self.dt:.3f} s"
            )
        return cfx, cfy, ctq

    def close(self) -> None:
        """Drop the pymunk space."""
        self._space = None
        self._body = None

    # ------------------------------------------------------------------ internals

    def _attached(self) -> tuple[list[bool], list[tuple[float, ...]], float, float, float]:
        """Whether each spring is attached at the current physics step, the attached springs,
        the step window this holds for and the attached count (a function of the step alone,
        recomputed only when the step leaves the window since the last attach/detach)."""
        n = self._steps
        if not self._att[2] <= n < self._att[3]:
            on = [a <= n < d for a, d in self._spring_steps]
            edges = [e for window in self._spring_steps for e in window]
            self._att = (
                on,
                [s for s, o in zip(self._springs, on, strict=True) if o],
                max((e for e in edges if e <= n), default=-math.inf),
                min((e for e in edges if e > n), default=math.inf),
                float(sum(on)),
            )
        return self._att

    def _spring_force(self, x: float, y: float) -> tuple[float, float]:
        """Sum of ``-k (|d| - L0) d/|d|`` over the attached springs; zero where ``|d| = 0``."""
        fx = fy = 0.0
        springs = self._attached()[1] if self._scheduled_springs else self._springs
        for axp, ayp, k, l0 in springs:
            dx, dy = x - axp, y - ayp
            if l0 == 0.0:
                fx -= k * dx
                fy -= k * dy
                continue
            r = math.hypot(dx, dy)
            if r > 0.0:
                s = -k * (r - l0) / r
                fx += s * dx
                fy += s * dy
        return fx, fy

    def _viscosity(self, x: float, y: float) -> float:
        """Sum of the coefficients [N s/m] of the viscous fields containing (x, y) now (the EE
        is at (x, y) for the whole physics step, so one step's value is kept for reuse)."""
        if self._visc[0] == self._steps:
            return self._visc[1]
        c = 0.0
        for field_ in self.scene.viscous:
            if field_.region is None or field_.region.contains(x, y):
                c += field_.schedule.coefficient(self._steps, self._path)
        self._visc = (self._steps, c)
        return c

    def _check_state(self, body: pymunk.Body) -> None:
        x, y = body.position
        vx, vy = body.velocity
        if not all(map(math.isfinite, (x, y, vx, vy, body.angle, body.angular_velocity))):
            raise SimulationDiverged(
                f"non-finite end-effector state at t={self._steps * self.dt:.3f} s "
                f"(position=({x}, {y}), velocity=({vx}, {vy}))"
            )

    def _output(
        self,
        wrench: tuple[float, float, float, float, float],
        n_contacts: int,
        mu: float,
        state: tuple[float, ...] | None = None,
    ) -> tuple[Observation, StepInfo]:
        """Observation and truth for the current state; ``state`` = (x, y, vx, vy) if known,
        ``wrench`` = the true external (fx, fy, torque) and its contact part (fx, fy).

        The same two objects every step of a trial (made at ``reset``), their arrays
        read-only views of one buffer written here in place: valid until the next step
        (issue #40, :mod:`ccm.core.types`)."""
        body = self._body
        assert body is not None
        if state is None:
            (x, y), (vx, vy) = body.position, body.velocity
        else:
            x, y, vx, vy = state
        angle, omega = (body.angle, body.angular_velocity) if self._rotates else (self._angle0, 0.0)
        fx, fy, tq, kx, ky = wrench
        obs, info = self._obs, self._info
        b = self._buf
        if self._ideal_sensor:  # measured = true, as FTSensor.measure gives it
            b[:] = (x, y, angle, vx, vy, omega, fx, fy, tq, kx, ky, fx, fy, tq)
        else:
            b[: _MEAS_F.start] = (x, y, angle, vx, vy, omega, fx, fy, tq, kx, ky)
            b[_MEAS_F], b[_MEAS_T] = self.sensor.measure(info.true_force, info.true_torque)
        obs.t = self._steps * self.dt
        info.n_contacts = n_contacts
        extra = info.extra
        extra["viscosity_Nspm"] = self._viscosity(x, y) if self._has_viscous else 0.0
        extra["surface_friction"] = mu if n_contacts > 0 else -1.0
        extra["contact"] = 1.0 if n_contacts > 0 else 0.0
        if self._scheduled_springs:  # truth of the environment changes (metrics only)
            extra["springs_attached"] = self._attached()[4]
        if self._hri is not None:
            extra.update(self._hri.extra())
        return obs, info

    def _new_step_objects(self) -> None:
        """The trial's one Observation and StepInfo (:meth:`_output` updates them): read-only
        views of one buffer that only the simulator writes."""
        b = self._buf = np.zeros(_MEAS_T.stop)
        pos, angle, vel, omega, f, t, true_f, true_t, contact_f = (
            readonly(b[k]) for k in (_POS, _ANGLE, _VEL, _OMEGA, _MEAS_F, _MEAS_T, _TRUE_F,
                                      _TRUE_T, _CONTACT_F)
        )  # fmt: skip
        self._obs = Observation(0.0, pos, angle, vel, omega, f, t)
        self._info = StepInfo(true_f, true_t, contact_f, 0, {})
