"""Contract checks over every registered controller config and simulator backend, in the
spirit of scikit-learn's ``check_estimator`` and Gymnasium's env checker (issue #21).

* A simulator: ``with`` closes it; ``reset(seed)`` is deterministic; ``step`` returns an
  Observation of the task's dimension and the same ``StepInfo.extra`` keys every step.
* A controller: a Command of the right shapes; the same ``signals()`` keys every step; the
  learned state survives a JSON round trip into a fresh controller of the same config.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ccm.control.registry import make_controller
from ccm.core.errors import to_plain
from ccm.core.types import Command, Observation
from ccm.experiment.components import build_components
from ccm.experiment.user_configs import group_options
from ccm.sim import BACKENDS

#: a task per backend for the checks (2D: springs; 3D: table contact)
TASK = {"pymunk2d": "multi_spring", "pybullet3d": "press_slide_3d"}
STEPS = 300


def run_steps(comp, seed: int, steps: int = STEPS) -> list[Observation]:  # noqa: ANN001
    obs, _ = comp.sim.reset(seed=seed)
    comp.controller.reset(comp.task.dim, comp.sim.control_dt)
    pattern = comp.controller.prepare(comp.task.pattern, comp.task.contacts,
                                      np.random.default_rng(seed))  # fmt: skip
    out = [obs]
    keys = None
    for _ in range(steps):
        cmd = comp.controller.step(obs, pattern.sample(obs.t))
        assert isinstance(cmd, Command)
        assert cmd.force.shape == (comp.task.dim,)
        assert cmd.torque.shape == obs.ang_vel.shape
        sig = comp.controller.signals()
        assert keys is None or set(sig) == keys, "signals() keys changed between steps"
        keys = set(sig)
        obs, _ = comp.sim.step(cmd)
        out.append(obs)
    return out


@pytest.mark.parametrize("backend", list(BACKENDS))
def test_simulator_contract(composer, backend: str) -> None:
    comp = build_components(composer([f"sim={backend}", f"task={TASK[backend]}",
                                       "controller=fixed_impedance"]))  # fmt: skip
    with comp.sim as sim:
        first, info0 = sim.reset(seed=4)
        again, _ = sim.reset(seed=4)
        for name in ("position", "orientation", "lin_vel", "force"):
            assert np.array_equal(getattr(first, name), getattr(again, name)), name
        assert first.position.shape == (comp.task.dim,) and sim.dim == comp.task.dim
        zero = Command(force=np.zeros(sim.dim), torque=np.zeros(first.ang_vel.shape))
        for _ in range(5):
            obs, info = sim.step(zero)
            assert obs.t > first.t and set(info.extra) == set(info0.extra)
    assert sim.dim in (2, 3)


def controllers() -> list[str]:
    return group_options("controller")


@pytest.mark.parametrize("name", controllers())
def test_controller_contract(composer, name: str) -> None:
    """Shapes and signal keys over 300 steps (2D), and the learned-state JSON round trip."""
    cfg = composer([f"controller={name}", "task=multi_spring"])
    comp = build_components(cfg)
    try:
        run_steps(comp, seed=1)
        comp.controller.end_trial()
        state = comp.controller.state_dict()
        if state is None:
            return
        text = json.dumps(state, allow_nan=False)
        fresh = make_controller(to_plain(cfg.controller))
        fresh.reset(comp.task.dim, comp.sim.control_dt)
        fresh.load_state_dict(json.loads(text))
        assert json.dumps(fresh.state_dict(), allow_nan=False) == text
    finally:
        comp.sim.close()


@pytest.mark.parametrize("name", ["avic", "fixed_impedance"])
def test_a_controller_is_deterministic_per_seed(composer, name: str) -> None:
    """The same seed gives the same closed loop, step for step."""
    runs = []
    for _ in range(2):
        comp = build_components(composer([f"controller={name}", "task=multi_spring"]))
        runs.append(np.array([o.position for o in run_steps(comp, seed=2, steps=200)]))
        comp.sim.close()
    assert np.array_equal(runs[0], runs[1])
