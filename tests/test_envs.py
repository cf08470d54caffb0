"""Gymnasium environments (issue #41, part 4): every registered ``ccm/<Name>-v0`` passes
Gymnasium's own ``check_env``; a random policy and a scripted impedance policy run through
``gymnasium.make``; the three action layouts command what their documentation says."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")  # the `gym` extra; `make setup` installs it
from gymnasium.utils.env_checker import check_env  # noqa: E402

import ccm.envs  # noqa: E402,F401 - registers the environments
from ccm.core.errors import ConfigError  # noqa: E402
from ccm.envs import ENVS  # noqa: E402


# check_env recommends [-1, 1] action boxes and finite observation bounds: the actions are in
# physical units (m, N/m, N) as VICES' are, and a pose or a force has no natural bound
@pytest.mark.filterwarnings("ignore:.*(symmetric and normalized|infinity).*:UserWarning")
@pytest.mark.parametrize("name", list(ENVS))
def test_every_environment_passes_check_env(name: str) -> None:
    env = gym.make(f"ccm/{name}-v0")
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


def _episode(env, policy, seed: int, steps: int) -> tuple[float, list[float]]:  # noqa: ANN001
    obs, _ = env.reset(seed=seed)
    total, errors = 0.0, []
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        assert env.observation_space.contains(obs)
        total += reward
        errors.append(info["tracking_error_m"])
        if terminated or truncated:
            break
    return total, errors


def test_a_scripted_impedance_policy_tracks_better_than_a_random_one() -> None:
    """Through ``gymnasium.make``: holding Δx = 0 at 800 N/m, ζ = 1 follows the springs'
    circle within centimetres; uniformly random actions do far worse (the reward sees it)."""
    env = gym.make("ccm/MultiSpring-v0", action="variable_impedance")
    try:
        space = env.action_space
        scripted = np.concatenate([np.zeros(2), np.full(2, 800.0), np.ones(2)]).astype(np.float32)
        good, good_err = _episode(env, lambda _obs: scripted, seed=0, steps=1500)
        space.seed(0)
        bad, _ = _episode(env, lambda _obs: space.sample(), seed=0, steps=1500)
        assert max(good_err) < 0.02  # m
        assert good > bad
    finally:
        env.close()


def test_reset_with_a_seed_repeats_the_episode() -> None:
    env = gym.make("ccm/MultiSpring-v0", action="fixed_impedance")
    try:
        runs = [_episode(env, lambda _obs: np.zeros(2, np.float32), seed=4, steps=200)[1]
                for _ in range(2)]  # fmt: skip
        assert runs[0] == runs[1]
    finally:
        env.close()


def test_the_wrench_action_is_the_commanded_force() -> None:
    """In free space, a constant 2 N along x accelerates the 1 kg block at about 2 m/s²
    (the springs pull too: compared with the zero-force run)."""
    from ccm.envs.env import ChangingContactEnv

    env = ChangingContactEnv(task="multi_spring", action="wrench")
    try:
        vel = []
        for fx in (0.0, 2.0):
            env.reset(seed=1)
            for _ in range(50):
                obs, *_ = env.step(np.array([fx, 0.0], np.float32))
            vel.append(float(obs["lin_vel"][0]))
        assert (vel[1] - vel[0]) / 0.05 == pytest.approx(2.0, rel=0.1)
    finally:
        env.close()


def test_the_variable_impedance_action_is_the_documented_law() -> None:
    """``K (x_d + Δx − x) + 2 ζ √(K m) (ẋ_d − ẋ)`` per axis, m = 1 kg (the springs' block)."""
    from ccm.core.types import Observation, TargetSample
    from ccm.envs.env import ChangingContactEnv

    env = ChangingContactEnv(task="multi_spring")
    try:
        obs = Observation(0.0, np.array([0.1, 0.0]), np.zeros(1), np.array([0.02, -0.01]),
                          np.zeros(1), np.zeros(2), np.zeros(1))  # fmt: skip
        tgt = TargetSample(0.0, np.array([0.1, 0.02]), np.array([0.0, 0.1]), np.zeros(2),
                           np.zeros(1))  # fmt: skip
        act = np.array([0.01, 0.0, 400.0, 100.0, 1.0, 0.5])  # Δx, K, ζ
        got = env._command(act, obs, tgt).force
        want = [400.0 * 0.01 + 2 * 1.0 * 20.0 * -0.02, 100.0 * 0.02 + 2 * 0.5 * 10.0 * 0.11]
        np.testing.assert_allclose(got, want, rtol=1e-12)
    finally:
        env.close()


def test_bad_settings_are_one_line_naming_the_key() -> None:
    from ccm.envs.env import ChangingContactEnv

    with pytest.raises(ConfigError, match=r"^action: unknown value 'torque'; allowed: "):
        ChangingContactEnv(action="torque")
    with pytest.raises(ConfigError, match=r"^stiffness_range: must be \(low, high\)"):
        ChangingContactEnv(stiffness_range=(500.0, 10.0))
    with pytest.raises(
        ConfigError, match=r"^task: unknown task 'nope' of suite changing_contact_v1; "
    ):
        ChangingContactEnv(task="nope")


def test_an_environment_is_its_suite_task() -> None:
    """ContactLatency is the suite's contact_latency: its sensor reads 4 steps late, and its
    plan is the suite's approach and 10 N push (not mpc_contact's hold)."""
    env = gym.make("ccm/ContactLatency-v0")
    try:
        sim, task = env.unwrapped.sim, env.unwrapped.task
        assert sim.sensor.config.delay_steps == 4
        assert task.pattern.duration == pytest.approx(5.0)
        env.reset(seed=0)
        assert env.unwrapped._target.position[0] == pytest.approx(0.0)
        end = task.pattern.sample(4.9)
        assert end.position[0] == pytest.approx(0.0505) and end.force_mag == pytest.approx(10.0)
    finally:
        env.close()
