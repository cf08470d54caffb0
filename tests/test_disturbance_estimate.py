"""α of the disturbance model (Eq. 16-17, seed B) estimated from measured force (issue #18)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ccm.control.mpc.disturbance_estimate import alpha_from_power, high_freq_power
from ccm.control.mpc.gp_mpc import GPMPC
from ccm.core.errors import ConfigError
from ccm.core.types import Observation, TargetSample

DT = 1e-3
T = np.arange(0.0, 4.0, DT)


def _demo(amp: float, rng: np.random.Generator, freq: float = 40.0) -> np.ndarray:
    """Measured force of one demonstration: a slow human pull (0.3 N raised-cosine onset over
    0.3 s, as the simulated hand, and a 0.5 Hz sway of 4 N) plus a spindle line of amplitude
    ``amp`` on both axes, random phases."""
    ph = rng.uniform(0, 2 * math.pi, 2)
    onset = 0.15 * (1.0 - np.cos(math.pi * np.minimum(T / 0.3, 1.0)))
    human = np.column_stack([onset, 2.0 * (1.0 - np.cos(math.pi * T))])
    return human + amp * np.sin(2 * math.pi * freq * T[:, None] + ph)


def test_alpha_recovers_a_spindle_amplitude_under_a_large_slow_human_force() -> None:
    rng = np.random.default_rng(0)
    powers = [high_freq_power(_demo(0.01, rng), DT, 15.0) for _ in range(3)]
    assert alpha_from_power(powers) == pytest.approx(0.01, rel=0.02)
    # ten times the line, ten times α: it scales with the disturbance, not the human
    powers = [high_freq_power(_demo(0.1, rng), DT, 15.0) for _ in range(3)]
    assert alpha_from_power(powers) == pytest.approx(0.1, rel=0.02)


def test_a_line_below_the_split_is_not_a_disturbance() -> None:
    """The other answer: the same 1 N line at 8 Hz (below 15 Hz) is human motion. Only the
    leak of its slope at the record's ends (a kink of the FFT split's even extension) is left,
    a few % of the amplitude, where the line at 40 Hz gives α = 1 N."""
    rng = np.random.default_rng(1)
    powers = [high_freq_power(_demo(1.0, rng, freq=8.0), DT, 15.0) for _ in range(3)]
    assert alpha_from_power(powers) < 0.05
    powers = [high_freq_power(_demo(1.0, rng, freq=40.0), DT, 15.0) for _ in range(3)]
    assert alpha_from_power(powers) == pytest.approx(1.0, rel=0.02)


def test_white_noise_counts_with_its_power_above_the_split() -> None:
    """Sensor noise drives the admittance like the spindle: its power above 15 Hz counts."""
    rng = np.random.default_rng(2)
    powers = [high_freq_power(rng.normal(0.0, 0.05, (len(T), 2)), DT, 15.0) for _ in range(3)]
    kept = 1.0 - 15.0 / 500.0  # the fraction of a white spectrum above 15 Hz (Nyquist 500 Hz)
    assert alpha_from_power(powers) == pytest.approx(math.sqrt(2 * kept) * 0.05, rel=0.03)


def test_no_demonstration_or_no_content_is_an_error() -> None:
    with pytest.raises(ConfigError, match="mpc.disturbance.alpha"):
        alpha_from_power([])
    with pytest.raises(ConfigError, match="mpc.disturbance.alpha"):
        alpha_from_power([high_freq_power(np.ones((100, 2)), DT, 15.0)])
    with pytest.raises(ConfigError, match="disturbance_estimate.force"):
        high_freq_power(np.ones(100), DT, 15.0)


def _obs(t: float, x: np.ndarray, f: np.ndarray) -> Observation:
    z = np.zeros(2)
    return Observation(t, x, np.zeros(1), z, np.zeros(1), f, z[:1])


def _run_demo(ctrl: GPMPC, force: np.ndarray) -> None:
    ctrl.reset(2, DT)
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    x = np.zeros(2)
    for k, f in enumerate(force[:1000]):
        x = x + DT * np.array([0.01, 0.0])
        ctrl.step(_obs(k * DT, x.copy(), f), target)
    ctrl.end_trial()


def test_controller_estimates_alpha_from_its_demonstrations_and_keeps_it_on_reload() -> None:
    mpc = {"disturbance": {"alpha": "demonstrations", "omega_p": 2 * math.pi * 15},
           "weights": {"disturbance": 1.0}, "horizon": 3}  # fmt: skip
    kw = {"mpc": mpc, "demo_modes": [0], "gp": {"mean": "zero", "n_restarts": 0}}
    ctrl = GPMPC(**kw)
    rng = np.random.default_rng(3)
    _run_demo(ctrl, _demo(0.2, rng))
    assert ctrl.disturbance_alpha == pytest.approx(0.2, rel=0.05)
    assert ctrl.report()["disturbance_alpha"] == ctrl.disturbance_alpha
    again = GPMPC(**kw)
    again.load_state_dict(ctrl.state_dict())
    again.reset(2, DT)  # refits from the stored state
    assert again.disturbance_alpha == ctrl.disturbance_alpha


@pytest.mark.parametrize("alpha", ["truth", -1.0, 0.0])
def test_alpha_must_be_positive_or_demonstrations(alpha: object) -> None:
    with pytest.raises(ConfigError, match="controller.mpc.disturbance.alpha"):
        GPMPC(mpc={"disturbance": {"alpha": alpha}})


def test_alpha_from_silent_demonstrations_is_refused_with_the_power() -> None:
    """α̂ = 0 would switch Eq. 16's cost off without a word: refused, the power named."""
    with pytest.raises(ConfigError) as err:
        alpha_from_power([np.zeros(3)])
    assert str(err.value) == (
        "mpc.disturbance.alpha: the demonstrations' measured force has no content above the "
        "split (0.0 N²)"
    )


def test_estimate_refusals_name_their_keys() -> None:
    with pytest.raises(ConfigError) as err:
        alpha_from_power([])
    assert str(err.value) == (
        "mpc.disturbance.alpha: estimating α needs at least one demonstration"
    )
    with pytest.raises(ConfigError) as err:
        high_freq_power(np.zeros((10, 2)), 0.001, 0.0)
    assert str(err.value) == "disturbance_estimate.split_hz: must be > 0, got 0.0"
