"""``ccm.core.vector`` (numpy's mean and norm, bit for bit, without the wrappers) and the
recorder's column assembly."""

from __future__ import annotations

import numpy as np
import pytest

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


def test_the_recorder_copies_each_step() -> None:
    """Issue #40's rule, copy what you log: a simulator or controller that updates its arrays
    in place after a step leaves the logged row as it was. Strided views, integer and float32
    vectors are logged as their float64 values; a vector of the wrong length is refused on
    one line naming its column."""
    from ccm.core.records import TrialRecorder
    from ccm.core.types import Command, Observation, StepInfo, TargetSample

    pos, force, cmd = np.array([1.0, 2.0]), np.array([0.5, -0.5]), np.array([3.0, 4.0])
    obs = Observation(0.0, pos, np.zeros(1), np.zeros(2), np.zeros(1), force, np.zeros(1))
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    info = StepInfo(force, np.zeros(1), force, 1, {})
    signals = {"k": 100.0}
    rec = TrialRecorder(2, ["k"], [])
    rec.record(obs, target, Command(cmd, np.zeros(1)), info, signals)
    pos += 1.0  # the next step, written in place into the same arrays
    force *= 2.0
    cmd[:] = [-1.0, -2.0]
    signals["k"] = 200.0
    rec.record(obs, target, Command(cmd, np.zeros(1)), info, signals)
    cols = rec.arrays()
    np.testing.assert_array_equal(cols["pos_x"], [1.0, 2.0])
    np.testing.assert_array_equal(cols["force_y"], [-0.5, -1.0])
    np.testing.assert_array_equal(cols["true_force_x"], [0.5, 1.0])
    np.testing.assert_array_equal(cols["cmd_force_y"], [4.0, -2.0])
    np.testing.assert_array_equal(cols["k"], [100.0, 200.0])
    odd = TrialRecorder(2, [], [])
    strided = np.arange(6.0)[::3]  # [0, 3]
    ints, f32 = np.array([1, 2]), np.array([0.5, 0.25], dtype=np.float32)
    odd_obs = Observation(0.0, strided, np.zeros(1), ints, np.zeros(1), f32, np.zeros(1))
    odd.record(odd_obs, target, Command(cmd, np.zeros(1)), info, {})
    cols = odd.arrays()
    assert [cols[k][0] for k in ("pos_y", "vel_y", "force_x")] == [3.0, 2.0, 0.5]
    short = Observation(0.0, np.zeros(3), np.zeros(1), np.zeros(2), np.zeros(1), force,
                        np.zeros(1))  # fmt: skip
    with pytest.raises(ValueError, match="^step 1: pos has 3 values, the log expects 2$"):
        odd.record(short, target, Command(cmd, np.zeros(1)), info, {})


def test_the_recorder_keeps_numbers_not_objects() -> None:
    """Signals and truth extras go into float64 buffers (issue #40: no per-step Python object
    for the garbage collector): a missing key and a None value are NaN, a bool and an int
    their float values, and a row with a None is not half-written."""
    import gc

    from ccm.core.records import TrialRecorder
    from ccm.core.types import Command, Observation, StepInfo, TargetSample

    z1, z2 = np.zeros(1), np.zeros(2)
    obs = Observation(0.0, z2, z1, z2, z1, z2, z1)
    target = TargetSample(0.0, z2, z2, z2, z1)
    rec = TrialRecorder(2, ["a", "b", "c"], ["x"])
    steps = [({"a": 1.0, "b": True, "c": 3}, {"x": 0.5}),
             ({"a": 2.0, "b": None, "c": 4}, {}),
             ({"a": np.float64(3.0), "b": 0.0}, {"x": 1.5})]  # fmt: skip
    for sig, extra in steps:
        rec.record(obs, target, Command(z2, z1), StepInfo(z2, z1, z2, 0, extra), sig)
    cols = rec.arrays()
    np.testing.assert_array_equal(cols["a"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(cols["b"], [1.0, np.nan, 0.0])
    np.testing.assert_array_equal(cols["c"], [3.0, 4.0, np.nan])
    np.testing.assert_array_equal(cols["truth_x"], [0.5, np.nan, 1.5])
    info = StepInfo(z2, z1, z2, 0, {"x": 0.5})
    gc.collect()
    before = len(gc.get_objects())
    for _ in range(2000):
        rec.record(obs, target, Command(z2, z1), info, steps[0][0])
    assert len(gc.get_objects()) - before < 20  # the recorder of tuples grew by 414
