"""Force laws of seed B's physical-HRI scene elements (specs in :mod:`ccm.sim.pymunk.hri`).

Each element is a small object with ``reset(rng)`` (draw this episode's random quantities)
and ``force(...)`` (the force on the end-effector centre for one physics step, explicit in
the state at the start of the step). :class:`HRIForces` bundles a scene's elements for the
simulator, keeps the order of the random draws fixed and averages the forces over a control
period for the truth record. Everything is plain Python floats: it runs once per physics step.

Order of the random draws (all from one generator, see :meth:`HRIForces.reset`): at reset,
the wall offsets (walls in order), the human goal (only if ``goal_index == -1``), the
human noise's initial state (only if ``noise_std > 0``), the vibration phases; then per
physics step, the human noise (if ``noise_std > 0``), then the vibration noise (if
``noise_std > 0``). The draws never depend on the trajectory, so a change of the controller
leaves the disturbance realisation unchanged.
"""

from __future__ import annotations

import math

import numpy as np

from ccm.sim.pymunk.hri import CompliantWallSpec, HumanSpec, VibrationSpec
from ccm.sim.pymunk.scene import SceneSpec


class CompliantWalls:
    """Unilateral spring-damper walls acting on the EE centre (:class:`CompliantWallSpec`)."""

    def __init__(self, specs: tuple[CompliantWallSpec, ...]) -> None:
        self.specs = specs
        # per wall: surface point x, y (shifted by the offset at reset), normal x, y, k, c
        self._walls: list[tuple[float, float, float, float, float, float]] = []
        self.offsets: list[float] = [0.0] * len(specs)

    def reset(self, rng: np.random.Generator) -> None:
        """Draw each wall's offset along its normal, uniform in ``[-j, j]`` (0 if ``j = 0``)."""
        self.offsets = [
            float(rng.uniform(-w.position_jitter_m, w.position_jitter_m))
            if w.position_jitter_m > 0.0
            else 0.0
            for w in self.specs
        ]
        self._walls = [
            (w.point[0] + o * w.normal[0], w.point[1] + o * w.normal[1], *w.normal,
             w.stiffness, w.damping)
            for w, o in zip(self.specs, self.offsets, strict=True)
        ]  # fmt: skip

    def force(self, x: float, y: float, vx: float, vy: float) -> tuple[float, float, int]:
        """Sum of the wall forces on the EE at (x, y) moving at (vx, vy), and walls touched.

        Per wall: ``d = (q - p) . n``; for ``d > 0``, ``F = max(0, k d - c v . n)`` along ``n``.
        """
        fx = fy = 0.0
        n = 0
        for qx, qy, nx, ny, k, c in self._walls:
            d = (qx - x) * nx + (qy - y) * ny
            if d > 0.0:
                n += 1
                f = k * d - c * (vx * nx + vy * ny)
                if f > 0.0:
                    fx += f * nx
                    fy += f * ny
        return fx, fy, n


class HumanHand:
    """A bounded, noisy PD pull toward a goal (:class:`HumanSpec`).

    The noise is a discretised first-order low-pass per axis: ``n_k = a n_{k-1} + b s w_k``
    with ``a = exp(-2 pi f_c dt)``, ``b = sqrt(1 - a^2)`` and ``w_k`` standard normal, so its
    stationary std is ``s``; the initial state is drawn from that stationary distribution.
    """

    def __init__(self, spec: HumanSpec, dt: float) -> None:
        self.spec = spec
        self.dt = dt
        self._a = math.exp(-2.0 * math.pi * spec.noise_cutoff_hz * dt)
        self._b = spec.noise_std * math.sqrt(max(0.0, 1.0 - self._a * self._a))
        self.goal_index = max(spec.goal_index, 0)
        self._gx, self._gy = spec.goals[self.goal_index]
        self._nx = self._ny = 0.0
        self._next = 1
        self._rng: np.random.Generator | None = None

    @property
    def goal(self) -> tuple[float, float]:
        """The active goal's position [m] (truth: metrics only)."""
        return float(self._gx), float(self._gy)

    def reset(self, rng: np.random.Generator) -> None:
        """Draw the goal (if random) and the noise's initial state."""
        self._rng = rng
        spec = self.spec
        if spec.goal_index < 0:
            self.goal_index = int(rng.integers(len(spec.goals)))
        else:  # a goal sequence ends each episode on its last goal
            self.goal_index = spec.goal_index
        self._gx, self._gy = spec.goals[self.goal_index]
        self._next = 1  # the next goal of a goal sequence (HumanSpec.goal_times)
        self._nx = self._ny = 0.0
        if spec.noise_std > 0.0:
            self._nx, self._ny = (float(v) for v in rng.normal(0.0, spec.noise_std, 2))

    def force(self, x: float, y: float, vx: float, vy: float, t: float) -> tuple[float, float]:
        """The hand force at time t [s]; advances the noise by one physics step."""
        spec = self.spec
        if self._b > 0.0:
            assert self._rng is not None, "HumanHand.force() before reset()"
            wx, wy = self._rng.standard_normal(2)
            self._nx = self._a * self._nx + self._b * float(wx)
            self._ny = self._a * self._ny + self._b * float(wy)
        if spec.goal_times is not None:
            times = spec.goal_times
            while self._next < len(times) and t >= times[self._next]:
                self.goal_index = self._next
                self._gx, self._gy = spec.goals[self._next]
                self._next += 1
        if t < spec.active_after_s:
            return 0.0, 0.0
        fx = spec.stiffness * (self._gx - x) - spec.damping * vx + self._nx
        fy = spec.stiffness * (self._gy - y) - spec.damping * vy + self._ny
        norm = math.hypot(fx, fy)
        s = spec.max_force / norm if norm > spec.max_force else 1.0
        rise = t - spec.active_after_s
        if rise < spec.ramp_s:  # raised-cosine onset (HumanSpec)
            s *= 0.5 * (1.0 - math.cos(math.pi * rise / spec.ramp_s))
        return fx * s, fy * s


class Vibration:
    """Sinusoids with random phases plus white noise, per axis (:class:`VibrationSpec`)."""

    def __init__(self, spec: VibrationSpec) -> None:
        self.spec = spec
        self._w = 2.0 * math.pi * spec.frequency_hz
        self._phx = self._phy = 0.0
        self._rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator) -> None:
        """Draw the phase of each axis uniformly in ``[0, 2 pi)``."""
        self._rng = rng
        self._phx, self._phy = (float(p) for p in rng.uniform(0.0, 2.0 * math.pi, 2))

    def force(self, x: float, y: float, t: float) -> tuple[float, float]:
        """The disturbance at time t [s] on an EE at (x, y); zero outside the region.

        The noise is drawn every step, inside the region or not, so its realisation does not
        depend on the trajectory.
        """
        spec = self.spec
        ax, ay = spec.amplitude
        fx = ax * math.sin(self._w * t + self._phx)
        fy = ay * math.sin(self._w * t + self._phy)
        if spec.noise_std > 0.0:
            assert self._rng is not None, "Vibration.force() before reset()"
            wx, wy = self._rng.standard_normal(2)
            fx += spec.noise_std * float(wx)
            fy += spec.noise_std * float(wy)
        if spec.region is not None and not spec.region.contains(x, y):
            return 0.0, 0.0
        return fx, fy


class HRIForces:
    """A scene's walls, human and vibration, stepped together by the simulator.

    Args:
        scene: the scene (its ``compliant_walls``, ``human`` and ``vibration``).
        dt: physics step [s].
    """

    def __init__(self, scene: SceneSpec, dt: float) -> None:
        self.walls = CompliantWalls(scene.compliant_walls) if scene.compliant_walls else None
        self.human = HumanHand(scene.human, dt) if scene.human is not None else None
        self.vibration = Vibration(scene.vibration) if scene.vibration is not None else None
        self._sums = [0.0, 0.0, 0.0, 0.0]  # human fx, fy, disturbance fx, fy over the period
        self._count = 0

    def reset(self, rng: np.random.Generator) -> None:
        """Draw this episode's random quantities (fixed order, see the module docstring)."""
        for element in (self.walls, self.human, self.vibration):
            if element is not None:
                element.reset(rng)
        self.start_period()

    def start_period(self) -> None:
        """Zero the human/disturbance averages (call at the start of each control step)."""
        self._sums = [0.0, 0.0, 0.0, 0.0]
        self._count = 0

    def step(
        self, x: float, y: float, vx: float, vy: float, t: float
    ) -> tuple[float, float, float, float, int]:
        """Forces for one physics step starting at time t in state (x, y, vx, vy).

        Returns:
            ``(fx, fy, wx, wy, n)``: the non-contact force (human + vibration), the wall
            (contact) force and the number of walls touched.
        """
        fx = fy = wx = wy = 0.0
        n = 0
        sums = self._sums
        if self.walls is not None:
            wx, wy, n = self.walls.force(x, y, vx, vy)
        if self.human is not None:
            hx, hy = self.human.force(x, y, vx, vy, t)
            sums[0] += hx
            sums[1] += hy
            fx, fy = hx, hy
        if self.vibration is not None:
            dx, dy = self.vibration.force(x, y, t)
            sums[2] += dx
            sums[3] += dy
            fx += dx
            fy += dy
        self._count += 1
        return fx, fy, wx, wy, n

    def at_rest(self, x: float, y: float) -> tuple[float, float, int]:
        """The wall force and walls touched for an EE at rest at (x, y) (used at reset)."""
        return self.walls.force(x, y, 0.0, 0.0) if self.walls is not None else (0.0, 0.0, 0)

    def extra(self) -> dict[str, float]:
        """Truth for ``StepInfo.extra``: keys only for the elements the scene has.

        ``wall_offset_m`` (first wall's offset this episode), ``human_goal`` (goal index),
        ``human_goal_x_m``/``human_goal_y_m`` (that goal's position), ``human_fx_N``/
        ``human_fy_N`` and ``disturbance_fx_N``/``disturbance_fy_N`` (means over the physics
        steps of the last control step; 0 right after reset).
        """
        out: dict[str, float] = {}
        k = 1.0 / self._count if self._count else 0.0
        if self.walls is not None:
            out["wall_offset_m"] = self.walls.offsets[0]
        if self.human is not None:
            out["human_goal"] = float(self.human.goal_index)
            out["human_goal_x_m"], out["human_goal_y_m"] = self.human.goal
            out["human_fx_N"] = self._sums[0] * k
            out["human_fy_N"] = self._sums[1] * k
        if self.vibration is not None:
            out["disturbance_fx_N"] = self._sums[2] * k
            out["disturbance_fy_N"] = self._sums[3] * k
        return out
