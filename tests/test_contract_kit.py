"""The contract kit (issue #41, part 2): every built-in controller config passes
``ccm.checks.controller``'s checks on both backends, and a controller that breaks a promise
fails the check that names it, in one line."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.checks.controller import check_controller, parametrize_with_checks
from ccm.checks.simulator import check_simulator
from ccm.checks.steps import ContractError
from ccm.checks.worlds import world
from ccm.control.registry import make_controller
from ccm.core.errors import to_plain
from ccm.core.types import Command, Observation
from tests.plugins.controllers import PlainPD
from tests.test_contracts import chosen, controllers

BACKENDS = ("pymunk2d", "pybullet3d", "mujoco3d")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", controllers())
def test_every_controller_config_passes_the_kit(composer, name: str, backend: str) -> None:  # noqa: ANN001
    cfg = to_plain(composer([*chosen(name), f"sim={backend}"]).controller)
    check_controller(lambda: make_controller(cfg), backends=(backend,))


@parametrize_with_checks({"plain_pd": lambda: PlainPD(stiffness=400.0)}, backends=BACKENDS)
def test_the_pytest_helper_runs_a_users_controller(check) -> None:  # noqa: ANN001
    check()


# ------------------------------------------------------- broken controllers, one per promise


class _Broken(PlainPD):
    def __init__(self) -> None:
        super().__init__(stiffness=300.0)


class NanOnSpike(_Broken):
    """Divides by the measured force's change in contact: a sensor dropout (the reading held)
    makes it zero, and the command NaN. Once the block moves (after 10 steps), the clean
    world never repeats a reading exactly."""

    def reset(self, dim: int, control_dt: float) -> None:
        self.last, self.k = None, 0

    def step(self, obs: Observation, target) -> Command:  # noqa: ANN001
        cmd = super().step(obs, target)
        self.k += 1
        held = self.k > 10 and np.array_equal(obs.force, self.last)
        self.last = obs.force.copy()
        in_contact = float(np.abs(obs.force).max()) > 1.0
        return Command(cmd.force * (np.nan if held and in_contact else 1.0), cmd.torque)


class Unseeded(_Broken):
    def step(self, obs: Observation, target) -> Command:  # noqa: ANN001
        cmd = super().step(obs, target)
        return Command(cmd.force + np.random.default_rng().normal(0, 0.1, cmd.force.shape),
                       cmd.torque)  # fmt: skip


class WrongTorque(_Broken):
    def step(self, obs: Observation, target) -> Command:  # noqa: ANN001
        return Command(super().step(obs, target).force, np.zeros(2))


class ChangingSignals(_Broken):
    def signals(self) -> dict[str, float]:
        self.n = getattr(self, "n", 0) + 1
        return {"stiffness_Npm": 1.0} if self.n < 10 else {"k": 1.0}


class KeepsAView(_Broken):
    def reset(self, dim: int, control_dt: float) -> None:
        self.start = None

    def step(self, obs: Observation, target) -> Command:  # noqa: ANN001
        if self.start is None:
            self.start = obs.position  # a view, not a copy
        return Command(100.0 * (self.start - obs.position), np.zeros(obs.ang_vel.shape))


class ForgetfulState(_Broken):
    def state_dict(self) -> dict:
        return {"k": self.stiffness}

    def load_state_dict(self, state: dict) -> None:
        self.stiffness = float(state["k"]) + 1.0  # not what was saved


@pytest.mark.parametrize(
    ("cls", "expected"),
    [
        (NanOnSpike, r"^finite_on_sensor_faults \(pymunk2d\): step \d+: non-finite command"),
        (Unseeded, r"^deterministic \(pymunk2d\): step 0: two controllers on the same seed"),
        (WrongTorque, r"^step_shapes \(pymunk2d\): step 0: the command's force has shape \(2,\) "
         r"and torque \(2,\); the task needs \(2,\) and \(1,\)$"),
        (ChangingSignals, r"^signals \(pymunk2d\): step 9: signals\(\) keys changed \(k, "
         r"stiffness_Npm\)$"),
        (KeepsAView, r"^keeps_no_views \(pymunk2d\): step \d+: the command's force differs "
         r"when the step objects are reused .*keeps a view.*copy what you keep$"),
        (ForgetfulState, r"^learned_state_round_trip \(pymunk2d\): load_state_dict\(state_dict"),
    ],
)  # fmt: skip
def test_a_broken_promise_fails_the_check_that_names_it(cls: type, expected: str) -> None:
    with pytest.raises(ContractError, match=expected) as err:
        check_controller(cls)
    assert "\n" not in str(err.value)


def test_the_fault_world_spikes_and_the_clean_one_does_not() -> None:
    """NanOnSpike passes in the clean world and fails under faults: the faults fail it."""
    from ccm.checks.controller import controller_checks, run_check

    checks = dict(controller_checks(NanOnSpike, world("pymunk2d")))
    run_check("step_shapes", "pymunk2d", checks["step_shapes"])
    with pytest.raises(ContractError):
        run_check("finite_on_sensor_faults", "pymunk2d", checks["finite_on_sensor_faults"])


# ---------------------------------------------------------------- simulators


@pytest.mark.parametrize("noise", [0.0, 0.05])
@pytest.mark.parametrize("backend", BACKENDS)
def test_every_backend_passes_the_simulator_kit(backend: str, noise: float) -> None:
    """With a noiseless and a noisy F/T sensor (N per axis)."""
    check_simulator(world(backend, sim={"sensor": {"force_noise_std": noise}}).make_sim, backend)


class _Wrapped:
    """A simulator plugin that delegates to ccm's planar backend and breaks one promise."""

    def __init__(self) -> None:
        self.inner = world("pymunk2d").make_sim()
        self.dim, self.control_dt, self.k = 2, self.inner.control_dt, 0

    def reset(self, seed: int | None = None):  # noqa: ANN201
        self.k = 0
        return self.inner.reset(seed=seed)

    def step(self, command: Command):  # noqa: ANN201
        self.k += 1
        return self.inner.step(command)

    def close(self) -> None:
        self.inner.close()

    def __enter__(self) -> _Wrapped:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class EchoSensor(_Wrapped):
    def step(self, command: Command):  # noqa: ANN201
        obs, info = super().step(command)
        obs.force = np.array(command.force, float)
        return obs, info


class UnseededNoise(_Wrapped):
    def step(self, command: Command):  # noqa: ANN201
        obs, info = super().step(command)
        obs.force = obs.force + np.random.default_rng().normal(0.0, 0.01, 2)
        return obs, info


class NewExtraKey(_Wrapped):
    def step(self, command: Command):  # noqa: ANN201
        obs, info = super().step(command)
        if self.k > 10:
            info.extra = {**info.extra, "late": 1.0}
        return obs, info


class SwallowsNaN(_Wrapped):
    def step(self, command: Command):  # noqa: ANN201
        return super().step(Command(np.nan_to_num(command.force), command.torque))


class QuaternionIn2D(_Wrapped):
    def step(self, command: Command):  # noqa: ANN201
        obs, info = super().step(command)
        obs.orientation = np.array([0.0, 0.0, 0.0, 1.0])
        return obs, info


@pytest.mark.parametrize(
    ("cls", "expected"),
    [
        (EchoSensor, r"^measures_external_wrench \(sim\): the mean measured force \[5\.0, 0\.0\] "
         r"N is not the true external force .* N \(it is the command\)$"),
        (UnseededNoise, r"^deterministic \(sim\): step 1: force differs between two runs"),
        (NewExtraKey, r"^extra_keys \(sim\): step 11: StepInfo.extra keys changed \(late\)$"),
        (SwallowsNaN, r"^refuses_non_finite \(sim\): a NaN command did not raise "
         r"SimulationDiverged$"),
        (QuaternionIn2D, r"^step_shapes \(sim\): step 1: observation orientation has shape "
         r"\(4,\), need \(1,\)$"),
    ],
)  # fmt: skip
def test_a_broken_simulator_fails_the_check_that_names_it(cls: type, expected: str) -> None:
    with pytest.raises(ContractError, match=expected):
        check_simulator(cls, "sim")
