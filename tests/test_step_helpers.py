"""``ccm.core.vector`` (numpy's mean and norm, bit for bit, without the wrappers) and the
recorder's column assembly."""

from __future__ import annotations

import numpy as np

from ccm.core import vector


def test_mean_and_norm_equal_numpy_bit_for_bit() -> None:
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 7, 9, 130):
        for _ in range(200):
            x = rng.normal(size=n) * 10.0 ** rng.integers(-6, 6)
            assert vector.mean(x) == float(np.mean(x))
            assert vector.norm(x) == float(np.linalg.norm(x))
    row = np.arange(12.0).reshape(4, 3)[2]  # a row view, as BAC passes its profiles' rows
    assert vector.mean(row) == float(np.mean(row)) and vector.norm(row) == np.linalg.norm(row)


def test_recorder_columns_keep_the_steps_values() -> None:
    """The recorder assembles its per-step vectors and signal dicts into columns in step
    order, with NaN for a signal or truth extra a step did not log."""
    from ccm.core.records import TrialRecorder
    from ccm.core.types import Command, Observation, StepInfo, TargetSample

    rec = TrialRecorder(2, ["a", "b"], ["x", "y"])
    for k in range(3):
        v = np.array([k, 10.0 + k])
        obs = Observation(0.1 * k, v, np.zeros(1), 2 * v, np.zeros(1), 3 * v, np.ones(1))
        target = TargetSample(0.1 * k, -v, v, v, np.zeros(1), segment=k)
        info = StepInfo(4 * v, np.zeros(1), 5 * v, k, {"x": float(k), "y": 2.0 * k})
        signals = {"a": float(k)} if k == 1 else {"a": float(k), "b": -float(k)}
        rec.record(obs, target, Command(6 * v, np.zeros(1)), info, signals)
    cols = rec.arrays()
    np.testing.assert_array_equal(cols["pos_y"], [10.0, 11.0, 12.0])
    np.testing.assert_array_equal(cols["force_x"], [0.0, 3.0, 6.0])
    np.testing.assert_array_equal(cols["cmd_force_y"], [60.0, 66.0, 72.0])
    np.testing.assert_array_equal(cols["target_pos_x"], [0.0, -1.0, -2.0])
    np.testing.assert_array_equal(cols["a"], [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(cols["b"], [0.0, np.nan, -2.0])
    np.testing.assert_array_equal(cols["truth_x"], [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(cols["truth_y"], [0.0, 2.0, 4.0])
    gap = TrialRecorder(2, [], ["x", "y"])
    for extra in ({"x": 1.0, "y": 2.0}, {"x": 3.0}):
        gap.record(obs, target, Command(v, np.zeros(1)), StepInfo(v, v[:1], v, 0, extra), {})
    np.testing.assert_array_equal(gap.arrays()["truth_y"], [2.0, np.nan])
    np.testing.assert_array_equal(gap.arrays()["truth_x"], [1.0, 3.0])
    single = TrialRecorder(2, ["a"], [])
    single.record(obs, target, Command(v, np.zeros(1)), info, {"a": 7.0})
    np.testing.assert_array_equal(single.arrays()["a"], [7.0])


def test_flat_joins_vectors_as_concatenate_does() -> None:
    """The recorder's byte join gives np.concatenate's numbers, writable, and falls back
    for strided views and other dtypes."""
    from ccm.core.records import _flat

    rng = np.random.default_rng(3)
    plain = [rng.standard_normal(3) for _ in range(50)]
    joined = _flat(plain)
    np.testing.assert_array_equal(joined, np.concatenate(plain))
    assert joined.dtype == np.float64 and joined.flags.writeable
    strided = [np.arange(6.0)[::2], np.arange(6.0).reshape(2, 3)[:, 1], np.ones(2)]
    np.testing.assert_array_equal(_flat(strided), [0.0, 2.0, 4.0, 1.0, 4.0, 1.0, 1.0])
    mixed = [np.array([1, 2]), np.array([0.5, np.nan], dtype=np.float32)]
    np.testing.assert_array_equal(_flat(mixed), [1.0, 2.0, 0.5, np.nan])
    assert _flat(mixed).dtype == np.float64
