"""Tests for ccm.learn.contact.modes (seed A §3.2, Eq. 7, Algorithm 1)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.contact.mode_features import TransitionTrigger, mode_features
from ccm.learn.contact.modes import ModeClassifier, ModeDecision

KEY = "controller.modes.classifier"


def sliding_batch(
    rng: np.random.Generator, mu: float, normal: float, angle: float, n: int = 30
) -> np.ndarray:
    """Force-ratio features of n samples sliding on a surface with friction mu."""
    direction = np.array([np.cos(angle), np.sin(angle), 0.0])
    rows = []
    for _ in range(n):
        r = normal + rng.normal(0.0, 0.1)
        f_t = mu * r * direction + rng.normal(0.0, 0.05, size=3) * np.array([1.0, 1.0, 0.0])
        rows.append(mode_features(f_t, None, r, "force_ratio"))
    return np.array(rows)


# --- TransitionTrigger -------------------------------------------------------------------


def test_trigger_fires_once_per_step_change() -> None:
    rng = np.random.default_rng(0)
    levels = np.repeat([2.0, 6.0, 2.0, 9.0], 100)
    signal = levels + rng.uniform(-0.3, 0.3, size=levels.size)
    trig = TransitionTrigger(threshold_N=1.0, window=10, refractory_steps=20)
    fired = [t for t, x in enumerate(signal) if trig.update(x)]
    assert fired == [100, 200, 300]


def test_trigger_silent_on_noise_below_threshold() -> None:
    rng = np.random.default_rng(1)
    trig = TransitionTrigger(threshold_N=1.0, window=5)
    assert not any(trig.update(x) for x in 3.0 + rng.uniform(-0.45, 0.45, size=2000))


def test_trigger_refractory_blocks_second_fire_and_reset() -> None:
    trig = TransitionTrigger(threshold_N=0.5, window=3, refractory_steps=10)
    out = [trig.update(x) for x in [0, 0, 0, 5, 0, 5, 0, 5, 5, 5, 5, 5, 5, 5, 5, 5]]
    assert out.count(True) == 1 and out[3]
    trig.reset()
    assert [trig.update(x) for x in [1, 1, 1, 9]] == [False, False, False, True]


def test_trigger_validation_names_keys() -> None:
    with pytest.raises(ConfigError, match=r"^controller\.modes\.trigger\.threshold_N"):
        TransitionTrigger(threshold_N=-1.0, window=5)
    with pytest.raises(ConfigError, match=r"^t\.window"):
        TransitionTrigger(threshold_N=1.0, window=0, key="t")
    with pytest.raises(ConfigError, match=r"^t\.refractory_steps"):
        TransitionTrigger(threshold_N=1.0, window=3, refractory_steps=-1, key="t")
    with pytest.raises(ConfigError, match=r"^t\.wrench_feature"):
        TransitionTrigger(threshold_N=1.0, window=3, key="t").update(float("nan"))


# --- mode_features -----------------------------------------------------------------------


def test_force_ratio_invariant_to_normal_force_and_direction() -> None:
    rng = np.random.default_rng(2)
    low = sliding_batch(rng, 0.4, 5.0, 0.0, n=200).mean()
    high = sliding_batch(rng, 0.4, 15.0, 2.0, n=200).mean()
    assert low == pytest.approx(0.4, abs=0.01)
    assert high == pytest.approx(low, abs=0.01)


def test_torque_force_ratio_and_zero_normal_force() -> None:
    feat = mode_features(
        np.array([3.0, 4.0]), np.array([0.0, 0.0, 1.0]), -10.0, "torque_force_ratio"
    )
    np.testing.assert_allclose(feat, [0.1, 0.5])
    assert np.isnan(mode_features([1.0, 0.0], None, 0.0, "force_ratio")).all()
    assert mode_features([1.0], [2.0], 1e-9, "torque_force_ratio").shape == (2,)
    with pytest.raises(ConfigError, match=r"^f\.kind"):
        mode_features([1.0], None, 1.0, "bogus", key="f")
    with pytest.raises(ConfigError, match=r"^f\.torque"):
        mode_features([1.0], None, 1.0, "torque_force_ratio", key="f")
    with pytest.raises(ConfigError, match=r"^controller\.modes\.features\.force"):
        mode_features(np.ones(4), None, 1.0, "force_ratio")


# --- ModeClassifier ----------------------------------------------------------------------


def make_classifier() -> ModeClassifier:
    return ModeClassifier(threshold=0.05, confidence_threshold=0.8, min_batch=10)


def test_three_surfaces_then_revisit_known_mode() -> None:
    rng = np.random.default_rng(3)
    clf = make_classifier()
    decisions = [clf.classify(sliding_batch(rng, mu, 5.0, 0.0)) for mu in (0.2, 0.6, 0.35)]
    assert [(d.mode, d.is_new) for d in decisions] == [(0, True), (1, True), (2, True)]
    assert all(d.confidence < 0.8 for d in decisions)
    assert clf.n_modes == 3
    # Revisit mu = 0.2 with three times the normal force, sliding in another direction.
    d = clf.classify(sliding_batch(rng, 0.2, 15.0, 2.3))
    assert isinstance(d, ModeDecision)
    assert d.mode == 0 and not d.is_new
    assert d.confidence >= clf.confidence_threshold
    assert d.second_confidence < d.confidence
    assert sum(d.counts.values()) == 30
    assert clf.n_modes == 3
    assert clf.mode_counts_[0] >= 30 + int(round(d.confidence * 30))


def test_two_feature_modes() -> None:
    rng = np.random.default_rng(4)
    clf = make_classifier()
    edge = np.array([0.3, 0.2]) + rng.normal(0, 0.005, size=(20, 2))
    face = np.array([0.05, 0.2]) + rng.normal(0, 0.005, size=(20, 2))
    assert clf.classify(edge).mode == 0
    assert clf.classify(face).is_new
    again = clf.classify(edge + rng.normal(0, 0.005, size=edge.shape))
    assert (again.mode, again.is_new, again.second_confidence) == (0, False, 0.0)


def test_classifier_validation_names_keys() -> None:
    for kwargs, arg in [
        ({"threshold": 0.0}, "threshold"),
        ({"confidence_threshold": 0.0}, "confidence_threshold"),
        ({"confidence_threshold": 1.5}, "confidence_threshold"),
        ({"min_batch": 0}, "min_batch"),
        ({"branching_factor": 1}, "branching_factor"),
    ]:
        args = {"threshold": 0.05, "confidence_threshold": 0.8, "min_batch": 10} | kwargs
        with pytest.raises(ConfigError, match=rf"^{KEY}\.{arg}"):
            ModeClassifier(**args)
    clf = make_classifier()
    for bad in (np.ones((5, 1)), np.ones(20), np.full((20, 1), np.nan)):
        with pytest.raises(ConfigError, match=rf"^{KEY}\.batch"):
            clf.classify(bad)
    clf.classify(np.ones((10, 1)))
    with pytest.raises(ConfigError, match=rf"^{KEY}\.batch"):
        clf.classify(np.ones((10, 2)))
    with pytest.raises(ConfigError, match=rf"^{KEY}\.mode"):
        clf.mode_centres(3)


def test_round_trip_gives_same_decisions() -> None:
    rng = np.random.default_rng(5)
    clf = make_classifier()
    for mu in (0.2, 0.6, 0.35, 0.2, 0.6):
        clf.classify(sliding_batch(rng, mu, 8.0, 1.0))
    state = json.loads(json.dumps(clf.state_dict()))
    restored = ModeClassifier.from_state_dict(state)
    assert restored.n_modes == clf.n_modes and restored.mode_counts_ == clf.mode_counts_
    for mu in (0.35, 0.9, 0.2, 0.6, 0.9):
        batch = sliding_batch(rng, mu, 12.0, -0.5)
        assert restored.classify(batch) == clf.classify(batch)
    assert restored.state_dict()["modes"][3]["count"] == clf.state_dict()["modes"][3]["count"]
    bad = json.loads(json.dumps(state))
    bad["modes"][1]["id"] = 7
    with pytest.raises(ConfigError, match=rf"^{KEY}\.from_state_dict\.modes\[1\]\.id"):
        ModeClassifier.from_state_dict(bad)


def test_mixed_batch_is_new_mode_built_from_unclaimed_points() -> None:
    rng = np.random.default_rng(6)
    clf = make_classifier()
    clf.classify(sliding_batch(rng, 0.2, 5.0, 0.0))
    mixed = np.vstack(
        [sliding_batch(rng, 0.2, 5.0, 0.0, n=21), sliding_batch(rng, 0.8, 5.0, 0.0, n=9)]
    )
    d = clf.classify(mixed)
    assert (d.mode, d.is_new, d.counts) == (1, True, {0: 21, -1: 9})
    assert d.confidence == pytest.approx(0.7) and d.second_confidence == 0.0
    assert clf.mode_counts_ == {0: 30, 1: 9}
    assert np.all(np.abs(clf.mode_centres(1) - 0.8) < 0.05)
    assert clf.classify(sliding_batch(rng, 0.2, 9.0, 1.0)).mode == 0
    mostly = np.vstack(
        [sliding_batch(rng, 0.2, 5.0, 0.0, n=25), sliding_batch(rng, 0.8, 5.0, 0.0, n=5)]
    )
    before = clf.mode_counts_
    d = clf.classify(mostly)
    assert (d.mode, d.is_new, d.counts) == (0, False, {0: 25, 1: 5})
    assert d.second_confidence == pytest.approx(5 / 30)
    assert d.second_confidence < d.confidence
    assert clf.mode_counts_ == {0: before[0] + 25, 1: 9}
    with pytest.raises(ConfigError, match=r"^k\.from_state_dict"):
        ModeClassifier.from_state_dict({"modes": []}, key="k")
    state = clf.state_dict()
    state["settings"]["min_batch"] = 0
    with pytest.raises(ConfigError, match=rf"^{KEY}\.min_batch"):
        ModeClassifier.from_state_dict(state)
