"""A Gymnasium environment over a task of ccm's benchmark suite (issue #41, part 4): a policy
commands the end-effector of a changing-contact task through one of three action layouts,
and is rewarded for tracking the task's target motion without excess force.

**Observation** (a ``Dict`` of float32 boxes; n = 2 or 3 task axes, r = 1 or 3 rotational):
``position`` (n) [m], ``orientation`` (1: angle [rad]; 4: quaternion x, y, z, w),
``lin_vel`` (n) [m/s], ``ang_vel`` (r) [rad/s], ``force`` (n) [N] and ``torque`` (r) [N m]
from the modelled F/T sensor, ``target_position`` (n) [m] and ``target_velocity`` (n) [m/s]
of the task's pattern at this step, and ``phase`` (1): time / the pattern's duration, 0 to 1.
Only what a robot has: the pose, twist and wrench it measures, and its own plan.

**Actions** (``action=``), all in a float32 ``Box``:

* ``variable_impedance`` (VICES' layout, Martín-Martín et al. 2019): ``[Δx (n) [m],
  stiffness (n) [N/m], damping ratio (n)]`` within ``max_delta_m``, ``stiffness_range`` and
  ``damping_ratio_range``; the force is ``K (x_d + Δx − x) + D (ẋ_d − ẋ)`` per axis with
  ``D = 2 ζ √(K m)``, m the end-effector's nominal mass (2-D) or the diagonal of the arm's
  model inertia Λ(q) (3-D).
* ``fixed_impedance``: ``Δx (n)`` only, with ``fixed_stiffness`` and critical damping.
* ``wrench``: the task-space force (n) [N] within ±``max_force_N``, applied as it is.

Orientation is held by ccm's loop (2-D: its orientation impedance; 3-D: the arm's own hold).

**Reward** per control step, from the suite's two force-aware metrics:
``−‖x − x_d‖ / 0.01 m − max(0, ‖F‖ − force_limit_N) / 10 N`` (tracking error in cm, force
above the limit in 10 N units, on the measured force). An episode is the task's pattern:
truncated at its end; terminated (reward −100) if the simulation diverges.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ccm.control.loop import HybridLoop
from ccm.core.errors import ConfigError, SimulationDiverged, check_choice, check_positive, to_plain
from ccm.core.types import Command, Observation, TargetSample
from ccm.experiment.components import build_sim_task
from ccm.suite.definition import DEFAULT_SUITE, load_suite
from ccm.suite.runner import compose_task

ACTIONS = ("variable_impedance", "fixed_impedance", "wrench")
#: the reward's scales (module docstring): 1 cm of tracking error, 10 N of excess force
TRACK_SCALE_M, FORCE_SCALE_N, DIVERGED_REWARD = 0.01, 10.0, -100.0


def compose_setting(suite: str, task: str, overrides: Sequence[str]) -> Any:
    """The composed config of ``task`` of ``suite`` (its simulator, scene, sensor and plan,
    as ``ccm suite`` runs it), with ``overrides`` on top."""
    spec = load_suite(suite)
    if task not in spec.tasks:
        raise ConfigError("task", f"unknown task {task!r} of suite {spec.name}; allowed: "
                          f"{', '.join(spec.tasks)}")  # fmt: skip
    return compose_task(spec, spec.tasks[task], list(overrides), 0, ())


class ChangingContactEnv(gym.Env):
    """A ccm task as a Gymnasium environment (module docstring).

    Args:
        task: a task of ``suite`` (``ccm suite --list``): its simulator, scene, sensor and
            plan, as the benchmark runs them.
        suite: the benchmark suite (``configs/suite/<name>.yaml``).
        action: ``variable_impedance``, ``fixed_impedance`` or ``wrench``.
        overrides: more Hydra overrides (``sim.sensor.force_noise_std=0.1``).
        max_delta_m, stiffness_range, damping_ratio_range, fixed_stiffness, max_force_N,
            force_limit_N: the action bounds and the reward's force limit (module docstring).
    """

    metadata = {"render_modes": []}  # noqa: RUF012 - Gymnasium's class attribute

    def __init__(
        self,
        task: str = "multi_spring",
        suite: str = DEFAULT_SUITE,
        action: str = "variable_impedance",
        overrides: Sequence[str] = (),
        # the defaults are ccm's choices, none from the papers:
        max_delta_m: float = 0.05,  # m: half the springs' 0.1 m circle
        stiffness_range: tuple[float, float] = (10.0, 1000.0),  # N/m: spans ccm's presets
        damping_ratio_range: tuple[float, float] = (0.3, 2.0),  # under- to over-damped
        fixed_stiffness: float = 300.0,  # N/m: configs/controller/fixed_impedance.yaml
        max_force_N: float = 50.0,  # N: above every task's force target (≤ 15 N)
        force_limit_N: float = 30.0,  # N: twice the largest force target (15 N)
    ) -> None:
        self.action = check_choice("action", action, ACTIONS)
        cfg = compose_setting(suite, task, overrides)
        self.sim, self.task = build_sim_task(cfg)
        self.mass_kg = check_positive("sim.nominal_mass_kg", cfg.sim.get("nominal_mass_kg", 1.0))
        self.max_delta_m = check_positive("max_delta_m", max_delta_m)
        self.k_range = _interval("stiffness_range", stiffness_range)
        self.zeta_range = _interval("damping_ratio_range", damping_ratio_range)
        self.fixed_stiffness = check_positive("fixed_stiffness", fixed_stiffness)
        self.max_force_N = check_positive("max_force_N", max_force_N)
        self.force_limit_N = check_positive("force_limit_N", force_limit_N)
        self.loop = HybridLoop(**to_plain(cfg.controller.get("loop")) or {})
        n, r = self.task.dim, 1 if self.task.dim == 2 else 3
        self.observation_space = spaces.Dict(_observation_boxes(n, r, 1 if n == 2 else 4))
        self.action_space = self._action_box(n)
        self._obs: Observation | None = None
        self._target: TargetSample | None = None

    def _action_box(self, n: int) -> spaces.Box:
        d = self.max_delta_m
        if self.action == "wrench":
            lo, hi = [-self.max_force_N] * n, [self.max_force_N] * n
        elif self.action == "fixed_impedance":
            lo, hi = [-d] * n, [d] * n
        else:
            lo = [-d] * n + [self.k_range[0]] * n + [self.zeta_range[0]] * n
            hi = [d] * n + [self.k_range[1]] * n + [self.zeta_range[1]] * n
        return spaces.Box(np.array(lo, np.float32), np.array(hi, np.float32), dtype=np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        obs, _ = self.sim.reset(seed=int(self.np_random.integers(2**31 - 1)))
        self.loop.reset(self.task.dim, self.sim.control_dt)
        self._obs = obs
        self._target = self.task.pattern.sample(obs.t)
        return self._observe(), {}

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        if self._obs is None or self._target is None:
            raise RuntimeError("ChangingContactEnv.step() called before reset()")
        act = np.clip(np.asarray(action, dtype=float), self.action_space.low,
                      self.action_space.high)  # fmt: skip
        cmd = self._command(act, self._obs, self._target)
        try:
            obs, truth = self.sim.step(cmd)
        except SimulationDiverged as exc:
            return self._observe(), DIVERGED_REWARD, True, False, {"diverged": str(exc)}
        self._obs = obs
        self._target = self.task.pattern.sample(obs.t)
        err = float(np.linalg.norm(obs.position - self._target.position))
        excess = max(0.0, float(np.linalg.norm(obs.force)) - self.force_limit_N)
        reward = -err / TRACK_SCALE_M - excess / FORCE_SCALE_N
        truncated = obs.t >= self.task.pattern.duration - 0.5 * self.sim.control_dt
        # for analysis, not for a policy: n_contacts is the simulator's truth
        info = {"tracking_error_m": err, "n_contacts": truth.n_contacts}
        return self._observe(), reward, False, bool(truncated), info

    def _command(self, act: np.ndarray, obs: Observation, target: TargetSample) -> Command:
        n = self.task.dim
        torque = self.loop.rotation_torque(obs, target)
        if self.action == "wrench":
            return Command(force=act.copy(), torque=torque)
        delta = act[:n]
        if self.action == "fixed_impedance":
            k, zeta = np.full(n, self.fixed_stiffness), np.ones(n)
        else:
            k, zeta = act[n : 2 * n], act[2 * n :]
        mass = np.diag(obs.inertia) if obs.inertia is not None else np.full(n, self.mass_kg)
        damping = 2.0 * zeta * np.sqrt(k * mass)
        force = k * (target.position + delta - obs.position)
        force += damping * (target.velocity - obs.lin_vel)
        return Command(force=force, torque=torque)

    def _observe(self) -> dict[str, np.ndarray]:
        obs, target = self._obs, self._target
        assert obs is not None and target is not None
        phase = min(1.0, obs.t / self.task.pattern.duration)
        out = {name: getattr(obs, name) for name in _OBS_FIELDS}
        out |= {"target_position": target.position, "target_velocity": target.velocity,
                "phase": np.array([phase])}  # fmt: skip
        return {k: np.asarray(v, dtype=np.float32).copy() for k, v in out.items()}

    def close(self) -> None:
        self.sim.close()


_OBS_FIELDS = ("position", "orientation", "lin_vel", "ang_vel", "force", "torque")


def _observation_boxes(n: int, r: int, q: int) -> dict[str, spaces.Box]:
    sizes = {"position": n, "orientation": q, "lin_vel": n, "ang_vel": r, "force": n,
             "torque": r, "target_position": n, "target_velocity": n}  # fmt: skip
    boxes = {k: spaces.Box(-np.inf, np.inf, (m,), np.float32) for k, m in sizes.items()}
    boxes["phase"] = spaces.Box(0.0, 1.0, (1,), np.float32)
    return boxes


def _interval(key: str, value: Any) -> tuple[float, float]:
    lo, hi = (float(v) for v in value)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise ConfigError(key, f"must be (low, high) with 0 < low < high, got {value!r}")
    return lo, hi
