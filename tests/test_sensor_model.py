"""Oracle tests of the F/T sensor model (``ccm.sim.sensor``; issue #39 item 1).

The model: measured = true + bias + std · z, z ~ N(0, 1) per axis and call from the sensor's
own seeded generator (force axes first, then torque); with faults, a spike of ±spike_N on
every force axis with probability spike_prob, and a dropout that repeats the last reading
for dropout_steps calls. Each test replays the generator by hand and checks the exact
numbers, so a flipped sign, a wrong scale or a draw in the wrong order fails.
"""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.sim.sensor import AHEAD, FORCE_LIMIT_N, FTSensor, SensorConfig

F_TRUE = np.array([1.0, -2.0, 3.0])
T_TRUE = np.array([0.5])
F_STD, T_STD = np.array([0.1, 0.2, 0.3]), np.array([0.05])
F_BIAS, T_BIAS = np.array([0.4, -0.6, 0.0]), np.array([-0.25])


def _sensor(**kw: object) -> FTSensor:
    cfg = SensorConfig.from_values(force_dim=3, torque_dim=1, **kw)  # type: ignore[arg-type]
    return FTSensor(cfg, force_dim=3, torque_dim=1)


def test_noise_is_the_std_times_the_generators_normals_plus_the_bias() -> None:
    """Without faults: call k uses row k of N(0, 1) draws of shape (AHEAD, 4), force axes
    first; call AHEAD + 1 starts a new block from the same generator."""
    s = _sensor(force_noise_std=F_STD, torque_noise_std=T_STD, force_bias=F_BIAS,
                torque_bias=T_BIAS)  # fmt: skip
    s.reset(np.random.default_rng(3))
    oracle = np.random.default_rng(3)
    block = oracle.normal(0.0, 1.0, (AHEAD, 4))
    for k in range(3):
        f, t = s.measure(F_TRUE, T_TRUE)
        np.testing.assert_allclose(f, F_TRUE + F_BIAS + F_STD * block[k, :3], rtol=0, atol=1e-15)
        np.testing.assert_allclose(t, T_TRUE + T_BIAS + T_STD * block[k, 3:], rtol=0, atol=1e-15)
    for _ in range(AHEAD - 3):
        s.measure(F_TRUE, T_TRUE)
    f, _ = s.measure(F_TRUE, T_TRUE)
    next_block = oracle.normal(0.0, 1.0, (AHEAD, 4))
    np.testing.assert_allclose(f, F_TRUE + F_BIAS + F_STD * next_block[0, :3], atol=1e-15)


def test_only_noisy_parts_draw_and_bias_alone_needs_no_generator() -> None:
    """A torque-only noise takes one sample per call; a bias-only sensor draws nothing and
    works before reset; an ideal sensor returns fresh float copies of the true wrench."""
    s = _sensor(torque_noise_std=T_STD)
    s.reset(np.random.default_rng(5))
    z = np.random.default_rng(5).normal(0.0, 1.0, (AHEAD, 1))
    f, t = s.measure(F_TRUE, T_TRUE)
    np.testing.assert_array_equal(f, F_TRUE)
    np.testing.assert_allclose(t, T_TRUE + T_STD * z[0], atol=1e-15)
    biased = _sensor(force_bias=F_BIAS, torque_bias=T_BIAS)
    f, t = biased.measure(F_TRUE, T_TRUE)  # no reset: no random numbers are needed
    np.testing.assert_array_equal(f, F_TRUE + F_BIAS)
    np.testing.assert_array_equal(t, T_TRUE + T_BIAS)
    ideal = FTSensor(None, force_dim=3, torque_dim=1)
    assert ideal.ideal and not biased.ideal
    f, t = ideal.measure(F_TRUE, T_TRUE)
    assert f is not F_TRUE and f.dtype == float and np.array_equal(f, F_TRUE)
    f, t = ideal.measure([1, 2, 3], 4)  # lists and scalars are reshaped
    assert f.shape == (3,) and t.shape == (1,) and t[0] == 4.0 and f.dtype == float
    with pytest.raises(RuntimeError, match=r"^FTSensor\.reset\(rng\) must be called before"):
        _sensor(force_noise_std=0.1).measure(F_TRUE, T_TRUE)


def test_a_spike_adds_spike_n_with_the_drawn_signs() -> None:
    """With faults each call draws, in order: force normals, torque normals, two uniforms
    (spike, dropout) and the spike's signs; spike_prob = 1 adds ±spike_N on every force axis."""
    s = _sensor(force_noise_std=F_STD, torque_noise_std=T_STD, force_bias=F_BIAS,
                torque_bias=T_BIAS, spike_prob=1.0, spike_N=5.0)  # fmt: skip
    s.reset(np.random.default_rng(11))
    oracle = np.random.default_rng(11)
    for _ in range(3):
        f, t = s.measure(F_TRUE, T_TRUE)
        zf, zt = oracle.normal(0.0, 1.0, 3), oracle.normal(0.0, 1.0, 1)
        oracle.random(2)
        signs = oracle.choice((-1.0, 1.0), 3)
        np.testing.assert_allclose(f, F_TRUE + F_BIAS + F_STD * zf + 5.0 * signs, atol=1e-14)
        np.testing.assert_allclose(t, T_TRUE + T_BIAS + T_STD * zt, atol=1e-15)
        assert set(np.round(np.abs(f - F_TRUE - F_BIAS - F_STD * zf), 12)) == {5.0}


def test_a_dropout_repeats_the_reading_for_dropout_steps_calls() -> None:
    """dropout_prob = 1, dropout_steps = 2: call 1 is measured and held, calls 2 and 3 repeat
    it (while the generator still advances), call 4 is a new reading, held again."""
    s = _sensor(force_noise_std=F_STD, dropout_prob=1.0, dropout_steps=2)
    s.reset(np.random.default_rng(2))
    oracle = np.random.default_rng(2)
    readings = [s.measure(F_TRUE, T_TRUE)[0] for _ in range(4)]
    expected = []
    for _ in range(4):
        z = oracle.normal(0.0, 1.0, 3)
        oracle.random(2)
        oracle.choice((-1.0, 1.0), 3)
        expected.append(F_TRUE + F_STD * z)
    np.testing.assert_allclose(readings[0], expected[0], atol=1e-15)
    np.testing.assert_array_equal(readings[1], readings[0])
    np.testing.assert_array_equal(readings[2], readings[0])
    np.testing.assert_allclose(readings[3], expected[3], atol=1e-15)
    s.reset(np.random.default_rng(2))  # a reset ends the hold
    np.testing.assert_allclose(s.measure(F_TRUE, T_TRUE)[0], expected[0], atol=1e-15)


def test_faults_need_both_a_probability_and_a_size() -> None:
    """A spike of 0 N or a dropout of 0 steps is no fault: the sensor takes the block path and
    draws no uniforms (its readings equal the fault-free sensor's)."""
    plain = _sensor(force_noise_std=F_STD)
    for kw in ({"spike_prob": 1.0}, {"spike_N": 5.0}, {"dropout_prob": 1.0},
               {"dropout_steps": 3}):  # fmt: skip
        s = _sensor(force_noise_std=F_STD, **kw)
        s.reset(np.random.default_rng(4))
        plain.reset(np.random.default_rng(4))
        for _ in range(3):
            np.testing.assert_array_equal(s.measure(F_TRUE, T_TRUE)[0],
                                          plain.measure(F_TRUE, T_TRUE)[0])  # fmt: skip


@pytest.mark.parametrize(
    ("kw", "line"),
    [
        ({"force_noise_std": -0.1}, "sim.sensor.force_noise_std: must be >= 0"),
        ({"torque_noise_std": [-0.1]}, "sim.sensor.torque_noise_std: must be >= 0 on every axis"),
        ({"force_bias": float("nan")}, "sim.sensor.force_bias: "),
        ({"force_bias": 2 * FORCE_LIMIT_N}, "sim.sensor.force_bias: must lie within ±100000 on "
                                            "every axis (a sensor's scale)"),
        ({"torque_bias": [2e4]}, "sim.sensor.torque_bias: must lie within ±10000"),
        ({"dropout_prob": 1.5}, "sim.sensor.dropout_prob: "),
        ({"spike_prob": -0.1}, "sim.sensor.spike_prob: "),
        ({"dropout_steps": -1}, "sim.sensor.dropout_steps: "),
        ({"delay_steps": -2}, "sim.sensor.delay_steps: "),
        ({"delay_steps": 1.5}, "sim.sensor.delay_steps: "),
        ({"color": 1}, "sim.sensor.color: unknown key; allowed: force_noise_std, "),
    ],
)  # fmt: skip
def test_a_bad_sensor_setting_names_its_key(kw: dict, line: str) -> None:
    """Every bad value is one line naming ``sim.sensor.<key>`` (from_mapping's defaults: a 2D
    force and a 1D torque)."""
    with pytest.raises(ConfigError) as err:
        SensorConfig.from_mapping(kw)
    assert str(err.value).startswith(line)


def test_biases_may_be_negative_and_bounds_are_inclusive() -> None:
    """A bias is an offset of either sign; a std or bias of exactly the limit is allowed; the
    defaults are an ideal 2D sensor with no faults."""
    edge = {"force_bias": -FORCE_LIMIT_N, "torque_bias": -0.5, "force_noise_std": FORCE_LIMIT_N}
    c = SensorConfig.from_mapping({**edge, "dropout_prob": 1.0})
    assert c.force_bias == (-FORCE_LIMIT_N, -FORCE_LIMIT_N) and c.torque_bias == (-0.5,)
    assert c.force_noise_std == (FORCE_LIMIT_N, FORCE_LIMIT_N) and c.dropout_prob == 1.0
    d = SensorConfig.from_mapping({})
    assert (d.force_dim, d.torque_dim) == (2, 1) and d == SensorConfig.ideal()
    assert (d.spike_prob, d.spike_N, d.dropout_prob, d.dropout_steps) == (0.0, 0.0, 0.0, 0)
    assert SensorConfig.ideal(3, 3).force_dim == 3 and SensorConfig.ideal(3, 3).torque_dim == 3
    assert FTSensor(None, 3, 3).config == SensorConfig.ideal(3, 3)
    with pytest.raises(ValueError, match=r"sensor config has dims \(2, 1\), expected \(3, 1\)"):
        FTSensor(SensorConfig.ideal(), force_dim=3, torque_dim=1)


def test_a_bias_on_one_part_alone_is_measured() -> None:
    """A force bias without a torque bias (and the reverse) still makes the sensor non-ideal."""
    f, t = _sensor(force_bias=F_BIAS).measure(F_TRUE, T_TRUE)
    np.testing.assert_array_equal(f, F_TRUE + F_BIAS)
    np.testing.assert_array_equal(t, T_TRUE)
    f, t = _sensor(torque_bias=T_BIAS).measure(F_TRUE, T_TRUE)
    np.testing.assert_array_equal(f, F_TRUE)
    np.testing.assert_array_equal(t, T_TRUE + T_BIAS)


def test_small_faults_are_faults() -> None:
    """A 0.5 N spike and a one-step dropout act; with faults and a 3-axis torque, each call
    draws 3 force and 3 torque normals; a faulty sensor needs its generator."""
    spike = {"spike_prob": 1.0, "spike_N": 0.5}
    t_std = [0.01, 0.02, 0.03]
    cfg = SensorConfig.from_values(F_STD, t_std, force_dim=3, torque_dim=3, **spike)
    s = FTSensor(cfg, force_dim=3, torque_dim=3)
    s.reset(np.random.default_rng(8))
    oracle = np.random.default_rng(8)
    f, t = s.measure(F_TRUE, np.zeros(3))
    zf, zt = oracle.normal(0.0, 1.0, 3), oracle.normal(0.0, 1.0, 3)
    oracle.random(2)
    signs = oracle.choice((-1.0, 1.0), 3)
    np.testing.assert_allclose(f, F_TRUE + F_STD * zf + 0.5 * signs, atol=1e-14)
    np.testing.assert_allclose(t, np.array([0.01, 0.02, 0.03]) * zt, atol=1e-15)
    one = _sensor(force_noise_std=F_STD, dropout_prob=1.0, dropout_steps=1)
    one.reset(np.random.default_rng(2))
    r = [one.measure(F_TRUE, T_TRUE)[0] for _ in range(3)]
    np.testing.assert_array_equal(r[1], r[0])  # held for one call
    assert not np.array_equal(r[2], r[0])  # then measured (and held) again
    with pytest.raises(RuntimeError, match=r"^FTSensor\.reset\(rng\) must be called before a fau"):
        _sensor(spike_prob=0.5, spike_N=1.0).measure(F_TRUE, T_TRUE)
    with pytest.raises(RuntimeError, match=r"^FTSensor\.reset\(rng\) must be called before a noi"):
        _sensor(force_noise_std=0.1, spike_prob=0.5, spike_N=1.0).measure(F_TRUE, T_TRUE)
    with pytest.raises(ConfigError, match=r"^sim\.sensor: "):
        SensorConfig.from_mapping("noisy")
    with pytest.raises(ConfigError, match=r"^arm\.ft\.force_bias: "):
        SensorConfig.from_mapping({"force_bias": "x"}, prefix="arm.ft")


def test_a_delay_of_d_returns_the_reading_of_d_calls_before() -> None:
    """delay_steps = d: call k returns call k − d's reading, and the first reading until d
    calls have been made; the noise is that of the call that took the reading, so the
    delayed stream is the undelayed one shifted by d; a reset forgets the old readings."""
    d = 3
    late, now = (
        _sensor(force_noise_std=F_STD.tolist(), delay_steps=d),
        _sensor(force_noise_std=F_STD.tolist()),
    )
    assert not late.ideal  # a delayed sensor never returns the true wrench as it is
    truths = [F_TRUE * (k + 1) for k in range(8)]
    for s in (late, now):
        s.reset(np.random.default_rng(7))
    got = [late.measure(f, T_TRUE)[0] for f in truths]
    want = [now.measure(f, T_TRUE)[0] for f in truths]
    for k in range(8):
        np.testing.assert_array_equal(got[k], want[max(0, k - d)])
    late.reset(np.random.default_rng(7))
    np.testing.assert_allclose(late.measure(-F_TRUE, T_TRUE)[0], want[0] - 2 * F_TRUE, atol=1e-12)


def test_an_ideal_sensor_with_a_delay_is_late_but_exact() -> None:
    """Without noise the delayed readings are the true wrenches of d calls before."""
    s = _sensor(delay_steps=2)
    s.reset(np.random.default_rng(0))
    out = [s.measure(np.full(3, float(k)), np.array([float(-k)])) for k in range(5)]
    assert [float(f[0]) for f, _ in out] == [0.0, 0.0, 0.0, 1.0, 2.0]
    assert [float(t[0]) for _, t in out] == [0.0, 0.0, 0.0, -1.0, -2.0]
