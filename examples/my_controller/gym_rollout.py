"""The example controller as a policy in a Gymnasium environment (its wrench action): the
same controller that `ccm run` runs, scored by the environment's reward."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from my_controller.ctrl import ForceLimitedImpedance

import ccm.envs  # noqa: F401 - registers ccm/<Name>-v0
from ccm.core.types import Observation, TargetSample


def as_step(obs: dict) -> tuple[Observation, TargetSample]:
    """The environment's observation as the controller's Observation and TargetSample."""
    get = {k: np.asarray(v, dtype=float) for k, v in obs.items()}
    o = Observation(0.0, get["position"], get["orientation"], get["lin_vel"], get["ang_vel"],
                    get["force"], get["torque"])  # fmt: skip
    target = TargetSample(0.0, get["target_position"], get["target_velocity"],
                          np.zeros_like(get["position"]), get["orientation"])  # fmt: skip
    return o, target


def main(env_id: str = "ccm/MultiSpring-v0", seed: int = 0) -> float:
    env = gym.make(env_id, action="wrench")
    ctrl = ForceLimitedImpedance()
    ctrl.reset(env.unwrapped.task.dim, env.unwrapped.sim.control_dt)
    obs, _ = env.reset(seed=seed)
    total, steps = 0.0, 0
    while True:
        action = ctrl.step(*as_step(obs)).force.astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        total, steps = total + reward, steps + 1
        if terminated or truncated:
            break
    env.close()
    print(f"{env_id}: {steps} steps, return {total:.1f}, "
          f"final tracking error {1000 * info['tracking_error_m']:.1f} mm")  # fmt: skip
    return total


if __name__ == "__main__":
    main()
