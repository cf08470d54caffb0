"""Contracts of the contact learners (seed A §3.2–3.5; issue #39 item 1).

The anticipation region C with its minimum radius (a ball of radius r however certain the
belief), Eq. 7's features at the edge of contact, the transition trigger's refractory count,
and the learned state of the mode classifier and the contact map: each refusal is the one
line that names the field (checked whole), a round trip keeps every setting.
"""

from __future__ import annotations

import json
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.contact.belief import ContactBelief
from ccm.learn.contact.contacts import ContactMap
from ccm.learn.contact.mode_features import TransitionTrigger, mode_features
from ccm.learn.contact.modes import ModeClassifier
from tests.refusals import refusal

_line = partial(refusal, ConfigError)


def test_region_c_is_the_mahalanobis_ball_floored_at_the_minimum_radius() -> None:
    """P = 1e-10 I (σ = 10 µm) and s = 3: alone, C is a 30 µm ball; with r = 5 cm the
    distance is taken with P + (r/s)² I, so C is (just over) the 5 cm ball."""
    b = ContactBelief([0.0, 0.0], 1e-10 * np.eye(2), np.zeros((2, 2)), 1e-6 * np.eye(2))
    pts = np.array([[0.0, 2.5e-5], [0.001, 0.0], [0.0499, 0.0], [0.0, 0.051]])
    np.testing.assert_array_equal(b.region_contains(pts, 3.0), [True, False, False, False])
    np.testing.assert_array_equal(
        b.region_contains(pts, 3.0, min_radius=0.05), [True, True, True, False]
    )
    assert b.region_contains([0.0499, 0.0], 3.0, min_radius=0.05) is True
    assert b.first_entry(pts[1:], 3.0, min_radius=0.05) == 0
    assert b.first_entry(pts[1:], 3.0) is None
    assert _line(b.region_contains, pts, 3.0, min_radius=-1.0).startswith(
        "controller.contacts.belief.min_radius: "
    )


def test_region_c_includes_its_boundary() -> None:
    b = ContactBelief([0.0, 0.0], np.eye(2), np.zeros((2, 2)), np.eye(2))
    assert b.region_contains([2.0, 0.0], 2.0) is True  # Mahalanobis distance exactly s


@pytest.mark.parametrize(
    ("force", "torque", "normal", "kind", "expected"),
    [
        ([0.3, 0.4], None, 1e-3, "force_ratio", [500.0]),  # |R| = min_normal_force: defined
        ([0.3, 0.4], None, -2.0, "force_ratio", [0.25]),  # either sign of R
        ([0.3, 0.4], "ignored", 2.0, "force_ratio", [0.25]),  # Eq. 7 needs no torque
        ([0.3, 0.4], [0.0, 0.6, 0.8], 2.0, "torque_force_ratio", [0.5, 0.25]),
    ],
)
def test_eq7_features(force: Any, torque: Any, normal: float, kind: str, expected: Any) -> None:
    got = mode_features(np.array(force), torque, normal, kind, min_normal_force=1e-3)
    np.testing.assert_allclose(got, expected)


def test_features_out_of_contact_are_nan_of_the_kinds_width() -> None:
    f = np.array([0.3, 0.4])
    assert np.isnan(mode_features(f, None, 0.5e-3, "force_ratio", min_normal_force=1e-3)).all()
    two = mode_features(f, None, 0.5e-3, "torque_force_ratio", min_normal_force=1e-3)
    assert two.shape == (2,) and np.isnan(two).all()
    assert np.isnan(mode_features(f, None, 0.0, "force_ratio", min_normal_force=0.0)).all()
    key = "controller.modes.features"
    assert _line(mode_features, "ab", None, 1.0, "force_ratio") == (
        f"{key}.force: must be a vector of 1 to 3 numbers, got 'ab'"
    )
    assert _line(mode_features, np.zeros(4), None, 1.0, "force_ratio") == (
        f"{key}.force: must be a vector of 1 to 3 numbers, got shape (4,)"
    )
    nan = _line(mode_features, [np.nan], None, 1.0, "force_ratio")
    assert nan == f"{key}.force: must be finite"
    assert _line(mode_features, f, None, np.inf, "force_ratio").startswith(f"{key}.normal_force")
    assert _line(mode_features, f, None, 1.0, "force_ratio", min_normal_force=-1.0).startswith(
        f"{key}.min_normal_force"
    )


def test_the_trigger_fires_once_then_stays_silent_for_its_refractory_count() -> None:
    """window 3, refractory 5, threshold 1 N: after three 0 N values a 2 N step fires; the
    next max(3, 5) − 1 = 4 updates are silent (filling the reference with post-step values),
    so a 9 N spike at the 4th is ignored and one at the 5th fires; a jump of exactly 1 N does
    not fire (> threshold)."""
    runs = {7: [False] * 8, 8: [False] * 8 + [True]}
    for spike_at, after in runs.items():
        trig = TransitionTrigger(1.0, 3, refractory_steps=5)
        xs = [0.0, 0.0, 0.0, 2.0] + [2.0] * (spike_at - 4) + [9.0]
        fired = [trig.update(x) for x in xs]
        assert fired[3] and fired[:3] == [False] * 3
        assert fired[4:] == after[4:], spike_at
    edge = TransitionTrigger(1.0, 2)
    assert [edge.update(x) for x in [0.0, 0.0, 1.0, 2.5]] == [False, False, False, True]


def _classifier() -> ModeClassifier:
    mc = ModeClassifier(0.1, 0.6, 5, branching_factor=20, key="mc")
    mc.classify(np.full((6, 1), 0.3))
    mc.classify(np.full((6, 1), 0.9))
    return mc


def test_a_mode_classifier_round_trips_its_settings_and_modes() -> None:
    mc = _classifier()
    state = json.loads(json.dumps(mc.state_dict()))
    back = ModeClassifier.from_state_dict(state)
    assert back.key == "mc" and back.branching_factor == 20 and back.n_modes == 2
    assert back.mode_counts_ == mc.mode_counts_
    probe = np.array([[0.31], [0.88], [0.6], [0.3], [0.9]])
    np.testing.assert_array_equal(back.assign(probe), [0, 1, -1, 0, 1])
    assert ModeClassifier.from_state_dict(state, key="other").key == "other"
    del state["settings"]["branching_factor"], state["settings"]["key"]
    old = ModeClassifier.from_state_dict(state)  # files before these settings were saved
    assert old.branching_factor == 50 and old.key == "controller.modes.classifier"
    assert _line(mc.mode_centres, True) == "mc.mode: must be an integer, got True"
    assert _line(mc.mode_centres, 2) == "mc.mode: must be in [0, 2), got 2"


def _mode_refusal(change: Any, key: str | None = "mc") -> str:
    state = json.loads(json.dumps(_classifier().state_dict()))
    change(state)
    return _line(ModeClassifier.from_state_dict, state, key=key)


def test_a_malformed_mode_state_is_refused_naming_the_field() -> None:
    k = "mc.from_state_dict"
    assert _mode_refusal(lambda s: s.pop("settings"), None) == (
        "controller.modes.classifier.from_state_dict: malformed state: KeyError('settings')"
    )
    assert _mode_refusal(lambda s: s.pop("modes")) == f"{k}: malformed state: KeyError('modes')"
    assert _mode_refusal(lambda s: s["modes"][1].pop("count")) == (
        f"{k}.modes[1]: malformed mode record: KeyError('count')"
    )
    wrong_id = _mode_refusal(lambda s: s["modes"][1].update(id=3))
    assert wrong_id == f"{k}.modes[1].id: must be 1, got 3"
    assert _mode_refusal(lambda s: s["modes"][0].update(count=0)).startswith(
        f"{k}.modes[0]: malformed mode record: ConfigError('{k}.modes[0].count: "
    )
    for centres in ([], [[0.3, 0.1]], [0.3]):
        assert _mode_refusal(lambda s, c=centres: s["modes"][0].update(centres=c)) == (
            f"{k}.modes[0].centres: must be (k, 1) with k >= 1"
        )
    assert _mode_refusal(lambda s: s["modes"][0].update(centres=[[float("nan")]])) == (
        f"{k}.modes[0].centres: must be finite"
    )


def _contact_map() -> ContactMap:
    cm = ContactMap(2, approach={"beta": 0.002, "f_desired": 4.0}, key="c")
    cm.observe([0.1, 0.2], "collision", v_used=0.05, f_measured=10.0)
    cm.observe([0.5, 0.0], "impactless")
    return cm


def test_a_contact_map_round_trips_and_counts_its_trials(tmp_path: Path) -> None:
    cm = _contact_map()
    cm.end_trial()
    cm.end_trial()
    assert cm.trial == 2
    back = ContactMap.load(cm.save(tmp_path / "map.json"))
    assert back.trial == 2 and back.approach_params == cm.approach_params
    assert back.approach_params["beta"] == 0.002
    assert back.state_dict() == cm.state_dict()
    assert not (tmp_path / "map.json.tmp").exists()


def _map_refusal(change: Any) -> str:
    state = json.loads(json.dumps(_contact_map().state_dict()))
    change(state)
    return _line(ContactMap.from_state_dict, state, key="init")


def test_a_malformed_contact_map_is_refused_naming_the_field(tmp_path: Path) -> None:
    assert _line(ContactMap.from_state_dict, [1], key="init") == (
        "init: not a contact map (format 'list', expected 'ccm.contacts.ContactMap')"
    )
    assert _map_refusal(lambda s: s.update(format_version=9)) == (
        "init: unsupported format_version 9, not 1"
    )
    no_trial = _map_refusal(lambda s: s.pop("trial"))
    assert no_trial == "init: malformed contact map: KeyError('trial')"
    bad = "init: invalid contact map: c.contacts[1]"
    assert _map_refusal(lambda s: s["contacts"][1].update(mean=[0.5, 0.0, 0.1])).startswith(bad)
    lent = _map_refusal(lambda s: s["contacts"][1].update(approach=s["contacts"][0]["approach"]))
    assert lent == f"{bad}.approach: a collision, and only a collision, has one"
    assert _map_refusal(lambda s: s["contacts"][0].update(source="dream")).startswith(
        f"{bad[:-3]}[0].source: "
    )
    assert _map_refusal(lambda s: s["contacts"][0].update(lead=[1.0])).startswith(
        f"{bad[:-3]}[0].lead: "
    )
    assert _map_refusal(lambda s: s["contacts"][0]["approach"].update(params=[1])).startswith(
        "init: invalid contact map: c.approach: malformed approach model: "
    )
    path = tmp_path / "foreign.json"
    path.write_text(json.dumps({"format": "x"}), encoding="utf-8")
    assert _line(ContactMap.load, path, key="init") == (
        f"init: {str(path)!r}: not a contact map (format 'x', expected 'ccm.contacts.ContactMap')"
    )
    assert _line(ContactMap.load, tmp_path / "none.json", key="init").startswith(
        f"init: cannot read contact map {str(tmp_path / 'none.json')!r}: "
    )


def test_observe_refuses_half_an_impact_and_an_unknown_expectation() -> None:
    cm = _contact_map()
    assert _line(cm.observe, [0.1, 0.2], v_used=0.05) == (
        "c.f_measured: give both v_used and f_measured, or none"
    )
    assert _line(cm.observe, [0.5, 0.0], "impactless", v_used=0.05, f_measured=1.0) == (
        "c.v_used: only a collision has an approach velocity"
    )
    assert _line(cm.observe, [0.1, 0.2], expected=5) == "c.expected: no contact 5"


def _approach(**kw: Any) -> Any:
    from ccm.learn.contact.approach import ApproachVelocityModel

    return ApproachVelocityModel(**kw)


def test_a_shallow_line_sets_the_speed_and_the_force_limit() -> None:
    """Rule 2 and 4 with a line of slope 0.5 N/(m/s) (shallower than 1, so no slope threshold
    other than 0 passes unnoticed): F = 0.5 v + 7.95 through (0.05, 7.975) and (0.1, 8.0)."""
    m = _approach(f_desired=7.99)
    m.update(0.05, 7.975)
    v = m.update(0.10, 8.0)
    assert v == pytest.approx((7.99 - 7.95) / 0.5)  # the line's speed for F_d, 0.08 m/s
    assert m.predict_force(0.2) == pytest.approx(0.5 * 0.2 + 7.95)
    assert m.velocity_limit() == pytest.approx((10.0 - 7.95) / 0.5)
    plain = _approach(f_desired=7.99, use_model=False)
    plain.update(0.05, 7.975)
    assert plain.update(0.10, 8.0) == pytest.approx(0.10 + 0.002 * (7.99 - 8.0))  # Eq. 9


def test_a_line_at_the_force_limit_returns_v_min_and_a_flat_one_has_no_limit() -> None:
    m = _approach()
    assert m.predict_force(0.1) is None and m.velocity_limit() == np.inf
    m.update(0.05, 10.025)
    m.update(0.10, 10.05)  # F = 0.5 v + 10: F_max at v = 0
    assert m.velocity_limit() == pytest.approx(0.0, abs=1e-12)
    assert m.next_velocity() == m.v_min and not m.force_limit_feasible
    flat = _approach()
    flat.update(0.05, 0.0)  # no force at all: nothing to limit
    assert flat.velocity_limit() == np.inf and flat.force_limit_feasible


def test_an_estimated_beta_is_the_inverse_through_origin_slope() -> None:
    """beta=None (rule 1): β = 1 / k̂, k̂ = v·F / v·v; a zero slope gives β = 0 (no change)."""
    m = _approach(beta=None, use_model=False)
    # k̂ = 0.5: β = 2, target 0.05 + 2 · (8 − 0.025) is far: the step limit gives 0.05 + 0.05
    assert m.update(0.05, 0.025) == pytest.approx(0.10)
    still = _approach(beta=None, use_model=False)
    assert still.update(0.05, 0.0) == pytest.approx(0.05)
    with pytest.raises(ConfigError) as info:
        type(m).from_state_dict({"params": {"beta": -1.0}, "velocities": [], "forces": []}, "k")
    assert info.value.key == "k.beta"


def test_new_contacts_are_numbered_and_the_expected_one_is_gated_with_p_plus_r() -> None:
    cm = ContactMap(
        2, key="c", process_noise_std=0.0, measurement_noise_std=0.01, new_contact_std=0.01
    )
    first = cm.observe([0.0, 0.0], "impactless")
    assert (first.index, first.is_new, first.updated, first.distance) == (0, True, True, None)
    cm.observe([1.0, 0.0], "impactless")
    assert [c.name for c in cm.contacts] == ["new1", "new2"]
    assert _line(cm.observe, [0.0, 0.0], "impactless", expected=2) == "c.expected: no contact 2"
    cm.end_trial()  # a contact is corrected once per trial: the next trial
    # the expected contact 0 is tried first, with its innovation covariance P + R
    # (σ² = 1e-4 + 1e-4): 0.02 m is 1.41 σ, inside the gate; distance reported that way
    ev = cm.observe([0.02, 0.0], "impactless", expected=0, expected_gate=3.0)
    assert ev.index == 0 and ev.distance == pytest.approx(0.02 / np.sqrt(2e-4))
    assert cm.contacts[0].belief.n_updates == 1
    cm.end_trial()
    cm.observe([0.0, 0.0], "impactless")
    assert cm.contacts[0].belief.n_updates == 2


def test_a_batch_is_checked_before_it_is_classified() -> None:
    mc = ModeClassifier(0.1, 0.6, 5, key="mc")
    np.testing.assert_array_equal(mc.assign(np.zeros((5, 1))), [-1] * 5)  # no mode yet
    assert _line(mc.classify, [["a"]] * 5) == "mc.batch: must be a 2-D array of numbers"
    assert _line(mc.classify, np.zeros(5)) == "mc.batch: must be a 2-D array (N, d), got shape (5,)"
    assert _line(mc.classify, np.zeros((4, 1))) == "mc.batch: needs >= 5 rows (min_batch), got 4"
    assert _line(mc.classify, np.full((5, 1), np.nan)) == (
        "mc.batch: must be finite (features out of contact are NaN)"
    )
    # Birch's threshold is the classifier's: 0.3 apart is two subclusters at 0.1
    mc.classify(np.array([[0.3]] * 3 + [[0.6]] * 3))
    assert mc.mode_centres(0).shape == (2, 1)


def test_belief_inputs_are_refused_with_their_key() -> None:
    k = "controller.contacts.belief"
    eye = np.eye(2)
    assert _line(ContactBelief, [0.0, 0.0], np.eye(3), eye, eye) == (
        f"{k}.cov: must be a finite symmetric 2x2 matrix"
    )
    assert _line(ContactBelief, [0.0, 0.0], eye, -eye, eye) == (
        f"{k}.process_noise_cov: must be positive semi-definite (smallest eigenvalue -1)"
    )
    assert _line(ContactBelief, [0.0, 0.0], eye, eye, 0 * eye) == (
        f"{k}.measurement_noise_cov: must be positive definite (smallest eigenvalue 0)"
    )
    b = ContactBelief([0.0, 0.0], eye, eye, eye)
    assert _line(b.mahalanobis, [np.nan, 0.0]) == (
        f"{k}.x: must be finite, of shape (2,) or (N, 2)"
    )
    assert _line(ContactMap, 2, measurement_noise_std=[0.1, -0.1], key="c") == (
        "c.measurement_noise_std: must be > 0, got [0.1, -0.1]"
    )
    assert _line(ContactMap, 2, process_noise_std=-1.0, key="c") == (
        "c.process_noise_std: must be >= 0, got -1.0"
    )
    cm = ContactMap(2, key="c")
    assert _line(cm.observe, [0.0, 0.0, 0.0]).startswith("c.z: ")
    assert _line(cm.observe, [0.0, 0.0], v_used=0.1, f_measured=np.nan).startswith("c.f_measured: ")


def test_a_known_mode_absorbs_its_own_and_unassigned_points_only() -> None:
    """Algorithm 1: a batch decided as known mode 1 extends mode 1 with its own points and the
    unassigned ones, never with points inside mode 0's radius; a batch split between modes
    below the confidence threshold makes a new mode of the whole batch."""
    mc = _classifier()  # mode 0 around 0.3 (6 points), mode 1 around 0.9 (6 points)
    before = dict(mc.mode_counts_)
    d = mc.classify(np.array([[0.9]] * 4 + [[0.3]] + [[0.6]]))  # 4/6 = 0.67 ≥ 0.6: mode 1
    assert (d.mode, d.is_new) == (1, False)
    assert mc.mode_counts_ == {0: before[0], 1: before[1] + 5}
    split = mc.classify(np.array([[0.3]] * 3 + [[0.9]] * 3))  # 0.5 < 0.6 for each
    assert split.is_new and mc.mode_counts_[split.mode] == 6
