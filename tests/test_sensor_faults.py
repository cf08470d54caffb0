"""F/T sensor faults (issue #8 reliability): noise x10, spikes and dropouts held at the last
reading leave no NaN, keep AVIC's stiffness inside [K_free, K_max], and the run completes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.core.timeseries import read_timeseries
from ccm.experiment.runner import run_experiment
from ccm.sim.sensor import FTSensor, SensorConfig

FAULTS = [
    "sim.sensor.force_noise_std=0.5",  # x10 the 0.05 N the H1/H2 experiments use
    "+sim.sensor.spike_prob=0.01",
    "+sim.sensor.spike_N=20.0",
    "+sim.sensor.dropout_prob=0.005",
    "+sim.sensor.dropout_steps=20",
]


def test_avic_survives_sensor_faults(composer, tmp_path: Path) -> None:
    """Trial 1 is AVIC's calibration (K_max); trial 2 adapts. Under spikes and dropouts both
    stay finite with K_p inside [K_free, K_max], and trial 2's stiffness still moves."""
    overrides = ["experiment=single", "controller=avic", "task=multi_spring",
                 "experiment.figures=false", "experiment.max_time_s=3.0",
                 "experiment.trials=2", *FAULTS]  # fmt: skip
    cfg = composer(overrides)
    summary = run_experiment(cfg, lambda extra: composer([*overrides, *extra]), tmp_path, False)
    assert summary["status"] == "ok"
    # no error exists for the first H steps of a trial (H = the model's horizon), nor for
    # the first 2 H of trial 1: the empty model learns its first pair at step H
    h = round(cfg.controller.forward_model.horizon_s / 0.001)
    for trial in ("trial_001.parquet", "trial_002.parquet"):
        log = read_timeseries(next((tmp_path / "timeseries").rglob(trial)))
        for name, col in log.items():
            late = name.startswith(("pred_", "persist_"))
            assert np.all(np.isfinite(col[2 * h + 1 :] if late else col)), (trial, name)
        k = log["stiffness_Npm"]
        assert k.min() >= 300.0 - 1e-9 and k.max() <= 3000.0 + 1e-9
    assert k.min() < 1000.0, "trial 2 adapts: the stiffness comes down from K_max"
    # the faults did happen: measured force jumps by ~20 N and repeats exactly while held
    f = log["force_x"]
    assert np.abs(np.diff(f)).max() > 15.0
    assert np.any((np.diff(f) == 0.0) & (np.diff(log["force_y"]) == 0.0))


def test_fault_model() -> None:
    cfg = SensorConfig.from_values(spike_prob=0.05, spike_N=10.0, dropout_prob=0.02,
                                   dropout_steps=5)  # fmt: skip
    s = FTSensor(cfg)
    s.reset(np.random.default_rng(0))
    out = np.array([s.measure(np.array([float(i), 0.0]), np.zeros(1))[0] for i in range(2000)])
    err = out[:, 0] - np.arange(2000)
    spikes = np.isclose(np.abs(out[:, 1]), 10.0)
    assert 50 < spikes.sum() < 150  # ~5 % of samples carry a spike, on every axis
    held = np.flatnonzero(np.diff(out[:, 0]) == 0.0)
    assert held.size > 50  # dropouts repeat the previous reading
    assert np.all(np.abs(err[~spikes & (np.r_[False, np.diff(out[:, 0]) != 0.0])]) < 1e-12)
    ideal = FTSensor(SensorConfig.from_values())
    ideal.reset(np.random.default_rng(0))  # faults off: no random numbers, exact values
    assert ideal.measure(np.array([1.0, 2.0]), np.zeros(1))[0].tolist() == [1.0, 2.0]


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [({"spike_prob": 1.5}, "sim.sensor.spike_prob"), ({"spike_N": -1.0}, "sim.sensor.spike_N"),
     ({"dropout_steps": -2}, "sim.sensor.dropout_steps")],
)  # fmt: skip
def test_bad_fault_settings(kwargs: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        SensorConfig.from_values(**kwargs)
    assert key in str(err.value)


@pytest.mark.parametrize(
    ("force_std", "torque_std"), [(0.05, 0.0), (0.0, 0.01), ([0.05, 0.1], 0.02)]
)
def test_noise_drawn_ahead_is_the_per_call_stream(force_std, torque_std) -> None:  # noqa: ANN001
    """Drawing the noise ahead (AHEAD calls at a time) gives, call by call and across block
    boundaries and resets, exactly the samples of one draw per call (force axes, then torque)."""
    from ccm.sim.sensor import AHEAD

    cfg = SensorConfig.from_values(force_noise_std=force_std, torque_noise_std=torque_std)
    s = FTSensor(cfg)
    f, t = np.array([1.0, -2.0]), np.array([0.5])
    for seed in (3, 4):  # a reset mid-block starts the new generator's stream
        s.reset(np.random.default_rng(seed))
        rng = np.random.default_rng(seed)
        for _ in range(AHEAD + 7 if seed == 3 else 5):
            fm, tm = s.measure(f, t)
            want_f = f + rng.normal(0.0, 1.0, 2) * s._f_std if s._noisy_force else f  # noqa: SLF001
            want_t = t + rng.normal(0.0, 1.0, 1) * s._t_std if s._noisy_torque else t  # noqa: SLF001
            assert np.array_equal(fm, want_f) and np.array_equal(tm, want_t)
