"""MRAC's compiled step (ccm/control/baselines/_mrac_kernels.py) against its numpy lines:
the same command and state bit for bit, step after step, in the closed loop of H1's
multi_spring and on random 3-D observations; the three norm signals within a few ulp (numpy's
``linalg.norm`` goes through BLAS ``ddot``)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pytest
from omegaconf import DictConfig

from ccm.control.baselines.mrac import MRAC
from ccm.core.types import Command, Observation, TargetSample

Composer = Callable[[Sequence[str]], DictConfig]
NORMS = ("adaptive_force_N", "ref_error_m", "ref_lag_m")


def _pair(make: Callable[[], MRAC], dim: int, dt: float) -> tuple[MRAC, MRAC]:
    compiled, numpy_ = make(), make()
    numpy_.compiled = False
    for c in (compiled, numpy_):
        c.reset(dim, dt)
    return compiled, numpy_


def _same_step(a: MRAC, b: MRAC, obs: Observation, target: TargetSample) -> np.ndarray:
    """Step both; assert equal commands, states and signals; return the command's force."""
    ca, cb = a.step(obs, target), b.step(obs, target)
    assert ca.force.tobytes() == cb.force.tobytes()
    assert ca.torque.tobytes() == cb.torque.tobytes()
    for name in ("x_m", "v_m", "f", "kp", "kv", "_ints"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    sa, sb = a.signals(), b.signals()
    assert {k: v for k, v in sa.items() if k not in NORMS} == {
        k: v for k, v in sb.items() if k not in NORMS
    }
    for k in NORMS:
        assert sa[k] == pytest.approx(sb[k], rel=1e-15, abs=1e-300)
    return ca.force


@pytest.mark.parametrize("controller", ["mrac", "mrac_w1"])
def test_compiled_mrac_equals_numpy_in_the_h1_loop(composer: Composer, controller: str) -> None:
    """H1's task and both MRAC configs (seed A Fig. 5: ω = 1.5 and 1.0), a whole trial."""
    from ccm.control.registry import make_controller
    from ccm.core.errors import to_plain
    from ccm.experiment.components import build_components

    cfg = composer(["task=multi_spring", f"controller={controller}"])
    comp = build_components(cfg)
    sim, pattern = comp.sim, comp.task.pattern
    compiled, numpy_ = _pair(
        lambda: make_controller(to_plain(cfg.controller)), comp.task.dim, sim.control_dt
    )
    obs, _ = sim.reset(seed=3)
    try:
        for _ in range(int(pattern.duration / sim.control_dt)):
            force = _same_step(compiled, numpy_, obs, pattern.sample(obs.t))
            obs, _ = sim.step(Command(force=force, torque=np.zeros(1)))
    finally:
        sim.close()
    assert compiled.signals()["ref_lag_m"] > 0.0  # the reference model moved


def test_compiled_mrac_equals_numpy_on_random_3d_observations() -> None:
    """Three axes (the axis means sum three values) with per-axis ω and ζ; a force segment
    in the middle takes the numpy lines in both and hands the state back."""
    rng = np.random.default_rng(7)
    compiled, numpy_ = _pair(lambda: MRAC(omega=[1.5, 1.0, 2.0], zeta=[1.0, 0.7, 1.2]), 3, 1e-3)
    for k in range(400):
        obs = Observation(
            t=k * 1e-3, position=rng.normal(0, 0.05, 3), orientation=np.array([0, 0, 0, 1.0]),
            lin_vel=rng.normal(0, 0.1, 3), ang_vel=np.zeros(3), force=rng.normal(0, 5, 3),
            torque=np.zeros(3),
        )  # fmt: skip
        fdir = np.array([0.0, 0.0, -1.0]) if 150 <= k < 250 else None
        target = TargetSample(
            t=k * 1e-3, position=rng.normal(0, 0.05, 3), velocity=rng.normal(0, 0.1, 3),
            acceleration=np.zeros(3), orientation=np.array([0, 0, 0, 1.0]), force_dir=fdir,
            force_mag=5.0 if fdir is not None else 0.0,
        )  # fmt: skip
        _same_step(compiled, numpy_, obs, target)
    assert compiled.signals()["adaptive_force_N"] > 0.0
