"""Tests for ccm.learn.contact.contacts (seed A §3.3 contact beliefs, Eq. 9 approach velocities)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.contact.approach import ApproachVelocityModel
from ccm.learn.contact.belief import ContactBelief
from ccm.learn.contact.contacts import ContactMap


def spd(rng: np.random.Generator, d: int, scale: float) -> np.ndarray:
    """A random symmetric positive definite matrix with eigenvalues spread over 1e-3..1 x scale."""
    q, _ = np.linalg.qr(rng.normal(size=(d, d)))
    return scale * (q * np.logspace(-3, 0, d)) @ q.T


# --- ContactBelief: Kalman update ---------------------------------------------------------


def test_update_matches_hand_computed_gain_per_axis() -> None:
    # Axis 0: P = 0.01, R = 0.0025 -> K = 0.01 / 0.0125 = 0.8; c = 0 + 0.8 * 0.1 = 0.08;
    # P+ = (1 - 0.8) * 0.01 = 0.002. Axis 1: P = R = 0.0025 -> K = 0.5; c = 0.5 * (-0.04).
    b = ContactBelief([0.0, 0.0], np.diag([0.01, 0.0025]), np.zeros((2, 2)), np.diag([0.0025] * 2))
    b.update([0.1, -0.04])
    np.testing.assert_allclose(b.mean, [0.08, -0.02], rtol=0, atol=1e-15)
    np.testing.assert_allclose(b.cov, np.diag([0.002, 0.00125]), rtol=0, atol=1e-15)
    assert b.n_updates == 1


def test_update_full_3d_covariance_hand_computed() -> None:
    # P = 3 R (full, correlated): K = 3R (4R)^-1 = 0.75 I, so the mean moves 3/4 of the way
    # and P+ = 0.25^2 * 3R + 0.75^2 * R = 0.75 R = P / 4.
    r = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]) * 1e-4
    b = ContactBelief([0.2, 0.1, 0.0], 3 * r, np.zeros((3, 3)), r)
    b.update([0.24, 0.06, 0.02])
    np.testing.assert_allclose(b.mean, [0.23, 0.07, 0.015], rtol=0, atol=1e-14)
    np.testing.assert_allclose(b.cov, 0.75 * r, rtol=1e-12, atol=0)


def test_update_agrees_with_textbook_form_and_shrinks_covariance() -> None:
    rng = np.random.default_rng(0)
    p, r = spd(rng, 3, 1e-2), spd(rng, 3, 1e-4)
    b = ContactBelief(np.zeros(3), p, np.zeros((3, 3)), r)
    b.update([0.01, -0.02, 0.03])
    k = p @ np.linalg.inv(p + r)
    np.testing.assert_allclose(b.cov, (np.eye(3) - k) @ p, rtol=1e-8, atol=1e-14)
    np.testing.assert_allclose(b.mean, k @ [0.01, -0.02, 0.03], rtol=1e-10, atol=1e-15)
    assert np.linalg.eigvalsh(p - b.cov).min() >= -1e-15  # P+ <= P (Loewner order)


def test_covariance_stays_symmetric_pd_over_100_random_updates() -> None:
    rng = np.random.default_rng(1)
    b = ContactBelief(np.zeros(3), spd(rng, 3, 1.0), 1e-10 * np.eye(3), spd(rng, 3, 1e-6))
    for _ in range(100):
        prior = b.cov.copy()
        b.update(rng.normal(0.0, 0.5, size=3))
        assert np.array_equal(b.cov, b.cov.T)  # exactly symmetric
        assert np.linalg.eigvalsh(b.cov).min() > 0.0
        assert np.linalg.eigvalsh(prior - b.cov).min() >= -1e-12 * np.abs(prior).max()
        b.predict()
    np.linalg.cholesky(b.cov)


def test_predict_adds_process_noise_and_keeps_mean() -> None:
    q = np.diag([1e-6, 4e-6])
    b = ContactBelief([0.3, 0.1], np.diag([1e-4, 1e-4]), q, np.eye(2) * 1e-5)
    b.predict()
    np.testing.assert_array_equal(b.mean, [0.3, 0.1])
    np.testing.assert_allclose(b.cov, np.diag([1e-4, 1e-4]) + q, rtol=1e-15)
    np.testing.assert_allclose(b.std, np.sqrt([1.01e-4, 1.04e-4]), rtol=1e-12)
    np.testing.assert_allclose(b.axes_std, np.sqrt([1.01e-4, 1.04e-4]), rtol=1e-12)


def test_five_noisy_measurements_converge_within_3_sigma() -> None:
    # From a 0.1 m error with P0 = 0.1^2 I, R = 0.005^2 I, Q = 0: after n = 5 updates the
    # posterior variance is 1 / (1/P0 + n/R) (std 2.24 mm) and the error is N(bias, that),
    # bias = 0.1 * (1/P0) / (1/P0 + n/R) = 5e-5 m.
    true_c = np.array([0.4, 0.1, 0.05])
    p0, r, n = 0.1**2, 0.005**2, 5
    var_post = 1.0 / (1.0 / p0 + n / r)
    bias = 0.1 * (1.0 / p0) / (1.0 / p0 + n / r)
    d2 = []
    for seed in range(300):
        rng = np.random.default_rng(seed)
        b = ContactBelief(true_c + [0.1, 0.0, 0.0], p0 * np.eye(3), np.zeros((3, 3)), r * np.eye(3))
        for _ in range(n):
            b.update(true_c + rng.normal(0.0, math.sqrt(r), size=3))
        err = b.mean - true_c
        np.testing.assert_allclose(b.std, math.sqrt(var_post), rtol=1e-9)
        if seed == 0:
            assert np.all(np.abs(err) <= 3.0 * math.sqrt(var_post) + bias)  # 3 sigma per axis
        d2.append(float(b.mahalanobis(b.mean + (true_c - b.mean))) ** 2)
    # Calibration: d^2 ~ chi2(3), mean 3; over 300 seeds its std is sqrt(6/300) = 0.14.
    assert np.mean(d2) == pytest.approx(3.0, abs=0.45)


# --- ContactBelief: region C ----------------------------------------------------------------


def test_region_is_the_mahalanobis_ellipsoid() -> None:
    sx, sy = 0.0605 / 3.0, 0.01
    b = ContactBelief([0.5, 0.0], np.diag([sx**2, sy**2]), np.zeros((2, 2)), np.eye(2) * 1e-6)
    assert b.mahalanobis([0.5 + 2 * sx, 0.0]) == pytest.approx(2.0, rel=1e-12)
    assert b.region_contains([0.5, 2.9 * sy], 3.0) and not b.region_contains([0.5, 3.1 * sy], 3.0)
    # (2 sigma, 2 sigma) is 2.83 sigma away (inside); (2.2, 2.2) is 3.11 (outside): an
    # ellipse, not a per-axis box.
    assert b.region_contains([0.5 + 2 * sx, 2 * sy], 3.0)
    assert not b.region_contains([0.5 + 2.2 * sx, 2.2 * sy], 3.0)
    pts = np.array([[0.5, 0.0], [0.5, 0.05]])
    np.testing.assert_array_equal(b.region_contains(pts, 3.0), [True, False])


def test_first_entry_on_straight_paths() -> None:
    sx, sy = 0.0605 / 3.0, 0.01
    b = ContactBelief([0.5, 0.0], np.diag([sx**2, sy**2]), np.zeros((2, 2)), np.eye(2) * 1e-6)
    x = np.linspace(0.0, 1.0, 1001)  # 1 mm samples
    on_axis = np.column_stack([x, np.zeros_like(x)])
    assert b.first_entry(on_axis, 3.0) == 440  # boundary at x = 0.5 - 0.0605 = 0.4395
    # At y = 0.015 (1.5 sigma_y) the ellipse half-width is sx * sqrt(9 - 2.25) = 0.05241.
    offset = np.column_stack([x, np.full_like(x, 0.015)])
    assert b.first_entry(offset, 3.0) == math.ceil((0.5 - sx * math.sqrt(6.75)) * 1000)
    assert b.first_entry(np.column_stack([x, np.full_like(x, 0.035)]), 3.0) is None
    assert b.first_entry(on_axis[::-1], 1.0) == 1000 - 520  # reversed path, 1 sigma: x <= 0.5202


# --- ContactMap: initial beliefs, association, trials --------------------------------------


def test_from_config_noise_is_seeded_and_has_the_configured_std() -> None:
    pos = [[0.4, 0.0, 0.1], {"position": [0.6, 0.2, 0.0], "name": "wall"}]
    a = ContactMap.from_config(pos, np.random.default_rng(7))
    b = ContactMap.from_config(pos, np.random.default_rng(7))
    c = ContactMap.from_config(pos, np.random.default_rng(8))
    for ca, cb, cc in zip(a.contacts, b.contacts, c.contacts, strict=True):
        np.testing.assert_array_equal(ca.belief.mean, cb.belief.mean)  # bit-identical
        assert np.abs(ca.belief.mean - cc.belief.mean).max() > 1e-3
    assert [ct.name for ct in a.contacts] == ["contact1", "wall"]
    np.testing.assert_allclose(a.contacts[0].belief.cov, np.eye(3) * 0.01, rtol=1e-15)
    many = ContactMap.from_config([[0.0, 0.0]] * 2000, np.random.default_rng(3))
    errs = np.array([ct.belief.mean for ct in many.contacts])
    # 4000 draws of N(0, 0.1^2): the sample std is within 5 % (its own std is 1.1 %).
    assert errs.std() == pytest.approx(0.1, rel=0.05)
    assert np.abs(errs.mean()) < 0.01  # mean of 4000 draws: std 0.0016


def test_from_config_zero_noise_uses_measurement_floor_and_init_std() -> None:
    m = ContactMap.from_config([[0.1, 0.2]], np.random.default_rng(0), init_noise_std=0.0)
    np.testing.assert_array_equal(m.contacts[0].belief.mean, [0.1, 0.2])
    np.testing.assert_allclose(m.contacts[0].belief.std, [0.005, 0.005], rtol=1e-12)
    m = ContactMap.from_config([[0.1, 0.2]], np.random.default_rng(0), init_std=[0.3, 0.2])
    np.testing.assert_allclose(m.contacts[0].belief.std, [0.3, 0.2], rtol=1e-12)  # Table 1 "±"


def fixed_map(**kwargs: object) -> ContactMap:
    """Contacts exactly at their configured positions with std 0.02 m: two collisions and an
    impact-less one."""
    wall = {"position": [0.5, 0.3, 0.0], "kind": "impactless"}
    kwargs = {"init_noise_std": 0.0, "init_std": 0.02, **kwargs}
    rng = np.random.default_rng(0)
    return ContactMap.from_config([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], wall], rng, **kwargs)


def test_expected_contact_wins_over_the_nearest_within_its_gate() -> None:
    """The anticipated contact (its region C was active) takes the event if within its gate,
    even when another belief is nearer; outside its gate, nearest-neighbour applies."""

    def wide() -> ContactMap:  # two collisions 0.5 m apart, std 0.2 m (innovation ~0.2 m)
        rng = np.random.default_rng(0)
        return ContactMap.from_config([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]], rng,
                                      init_noise_std=0.0, init_std=0.2)  # fmt: skip

    z = [0.3, 0.0, 0.0]  # ~1.0 sigma from contact 1, ~1.5 sigma from contact 0
    assert wide().associate(z) == 1
    ev = wide().observe(z, expected=0)
    assert (ev.index, ev.is_new) == (0, False)
    far = [0.9, 0.0, 0.0]  # ~4.4 sigma from contact 0 (outside the gate 3), ~2 from contact 1
    assert wide().observe(far, expected=0).index == 1
    with pytest.raises(ConfigError, match="controller.contacts.expected"):
        wide().observe(z, expected=9)


def test_association_gates_near_updates_far_creates() -> None:
    m = fixed_map()
    # Innovation std per axis: sqrt(0.02^2 + 0.005^2) = 0.0206; gate 3 -> 0.0618 on one axis.
    s = math.sqrt(0.02**2 + 0.005**2)
    assert m.associate([0.5 + 2.9 * s, 0.0, 0.0]) == 1
    assert m.associate([0.5 + 3.1 * s, 0.0, 0.0]) is None
    assert m.associate([0.5 + 3.1 * s, 0.0, 0.0], gate=4.0) == 1
    assert (
        m.associate([0.5, 0.3, 0.0]) == 2 and m.associate([0.5, 0.3, 0.0], kind="collision") is None
    )
    ev = m.observe([0.51, 0.0, 0.0])
    assert (ev.index, ev.is_new, ev.updated) == (1, False, True)
    assert ev.distance == pytest.approx(0.01 / s, rel=1e-12)
    assert 0.5 < m.contacts[1].belief.mean[0] < 0.51
    far = m.observe([1.0, 1.0, 0.0])  # a contact not in the config, seen in trial 1
    assert (far.index, far.is_new, far.distance) == (3, True, None)
    assert m.contacts[3].source == "observed" and m.contacts[3].approach is not None
    np.testing.assert_allclose(m.contacts[3].belief.std, [0.05] * 3, rtol=1e-12)
    # An impact-less event at a collision contact's position is a different contact.
    ev = m.observe([0.0, 0.0, 0.0], "impactless")
    assert ev.is_new and m.contacts[ev.index].approach is None


def test_one_measurement_per_contact_per_trial() -> None:
    m = fixed_map()
    assert m.observe([0.505, 0.0, 0.0]).updated
    cov = m.contacts[1].belief.cov.copy()
    bounce = m.observe([0.506, 0.0, 0.0])  # a bounce: same contact, not a new measurement
    assert (bounce.index, bounce.is_new, bounce.updated) == (1, False, False)
    np.testing.assert_array_equal(m.contacts[1].belief.cov, cov)
    m.end_trial()
    np.testing.assert_allclose(m.contacts[1].belief.cov, cov + np.eye(3) * 1e-6, rtol=1e-12)
    assert m.trial == 1 and m.observe([0.505, 0.0, 0.0]).updated
    # A bounce carries no new Eq. 9 measurement either; a rejected event changes nothing.
    approach = m.contacts[0].approach
    assert approach is not None
    m.observe([0.0, 0.0, 0.001], v_used=0.05, f_measured=4.0)
    m.observe([0.0, 0.0, 0.002], v_used=0.05, f_measured=9.0)
    assert approach.forces == [4.0]
    before = m.state_dict()
    with pytest.raises(ConfigError):
        m.observe([0.5, 0.0, 0.0], v_used=0.05, f_measured=float("nan"))
    assert m.state_dict() == before
    m2 = fixed_map(once_per_trial=False)
    m2.observe([0.505, 0.0, 0.0])
    assert m2.observe([0.506, 0.0, 0.0]).updated


def test_map_trials_converge_with_default_noise() -> None:
    true_c = np.array([0.3, -0.2, 0.1])
    rng = np.random.default_rng(11)
    m = ContactMap.from_config(
        [[0.4, -0.2, 0.1]], rng, init_noise_std=0.0, init_std=0.1
    )  # 0.1 m off
    for _ in range(5):
        ev = m.observe(true_c + rng.normal(0.0, 0.005, size=3))
        assert ev.index == 0 and not ev.is_new
        post = m.contacts[0].belief
        m.end_trial()
    # Before the last predict: posterior std ~ sqrt(1e-6 * 0.005 ...) ~ 2.5 mm per axis.
    assert np.all(np.abs(post.mean - true_c) <= 3.0 * np.sqrt(np.diag(post.cov - post.Q)) + 1e-4)
    assert np.all(post.std < 0.004)  # from 0.1 m (Table 1: 0.2-0.3 m -> 0.04 m in 5 trials)


# --- ApproachVelocityModel (Eq. 9) --------------------------------------------------------


def test_eq9_alone_converges_geometrically_for_beta_below_inverse_slope() -> None:
    k, fd = 80.0, 8.0  # v* = F_d / k = 0.1 m/s
    model = ApproachVelocityModel(beta=0.5 / k, f_desired=fd, use_model=False)
    v = model.next_velocity()
    assert v == 0.05  # v_safe in trial 1
    for n in range(1, 9):
        v = model.update(v, k * v)
        # e_{n} = (1 - beta k) e_{n-1} = 0.05 * 0.5^n
        assert v == pytest.approx(fd / k - 0.05 * 0.5**n, abs=1e-12)
    assert abs(v - fd / k) < 1e-3


def test_beta_estimated_from_the_impacts_needs_no_plant_knowledge() -> None:
    """beta=None: beta = 1 / the measured through-origin slope. On a plant F = k v one impact
    gives v_used F_d / F_m = F_d / k for any k (capped by max_step); a known beta would need k."""
    for k in (80.0, 200.0, 671.0):
        model = ApproachVelocityModel(beta=None, f_desired=8.0, f_max=10.0, use_model=False)
        v = model.update(0.05, k * 0.05)
        assert v == pytest.approx(8.0 / k, abs=1e-12)  # 0.1, 0.04 and 0.012 m/s
    noisy = ApproachVelocityModel(beta=None, f_desired=8.0, use_model=False)
    noisy.update(0.05, 20.0)  # slope 400 -> 0.02 m/s
    assert noisy.next_velocity() == pytest.approx(0.02, abs=1e-12)
    assert noisy.get_params()["beta"] is None


def test_linear_model_reaches_target_in_two_impacts() -> None:
    k = 80.0
    model = ApproachVelocityModel(beta=0.5 / k)
    v = model.update(0.05, k * 0.05)  # one velocity: Eq. 9 -> 0.075
    assert v == pytest.approx(0.075, abs=1e-12) and model.coef_ is None
    v = model.update(v, k * v)  # line F = 80 v through two points -> v = F_d / a
    assert model.coef_ == pytest.approx((80.0, 0.0), abs=1e-9)
    assert v == pytest.approx(0.1, abs=1e-12)


@pytest.mark.parametrize("seed", range(10))
def test_noisy_plant_with_offset_converges(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b = 160.0, 1.5  # v* = (8 - 1.5) / 160 = 0.0406 m/s
    model = ApproachVelocityModel(beta=1.0 / a, v_min=0.005)
    v = model.next_velocity()
    for _ in range(8):
        v = model.update(v, a * v + b + rng.normal(0.0, 0.3))
    assert abs(v - 6.5 / 160.0) < 0.005  # force error < 0.8 N at the learned speed


def test_force_limit_caps_the_next_velocity() -> None:
    # One impact: F = 2 N at 0.05 m/s -> proportional model F = 40 v, cap = 8.5 / 40.
    model = ApproachVelocityModel(beta=0.05, f_desired=8.0, f_max=8.5, max_step=1.0)
    v = model.update(0.05, 2.0)  # Eq. 9 alone would give 0.35, v_max 0.25
    assert v == pytest.approx(0.2125, rel=1e-12)
    assert model.predict_force(v) == pytest.approx(8.5, rel=1e-12)
    # A line with intercept >= F_max: no speed is safe; v_min and a flag.
    model = ApproachVelocityModel()
    model.update(0.05, 12.0)
    assert model.update(0.1, 13.0) == model.v_min and not model.force_limit_feasible


def test_model_prediction_never_exceeds_f_max() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        a, b = rng.uniform(20.0, 400.0), rng.uniform(-1.0, 3.0)
        beta, use_model = rng.uniform(1e-4, 0.05), bool(rng.integers(2))
        model = ApproachVelocityModel(beta=beta, f_max=10.0, use_model=use_model)
        v = model.next_velocity()
        for _ in range(6):
            v = model.update(v, a * v + b + rng.normal(0.0, 0.5))
            assert model.predict_force(v) <= 10.0 + 1e-9
            assert 0.0 < v <= model.v_max
            assert v >= model.v_min or model.predict_force(model.v_min) > 10.0


def test_speed_change_per_trial_is_limited_by_max_step() -> None:
    k = 20.0  # v* = 0.4 m/s: reached in steps of at most max_step = 0.05
    model = ApproachVelocityModel(beta=1.0 / k, v_max=1.0, f_max=20.0)
    v, seen = model.next_velocity(), []
    for _ in range(4):
        v = model.update(v, k * v)
        seen.append(v)
    np.testing.assert_allclose(seen, [0.1, 0.15, 0.2, 0.25], rtol=0, atol=1e-12)


def test_negative_slope_falls_back_to_eq9() -> None:
    model = ApproachVelocityModel(beta=0.001)
    model.update(0.05, 6.0)
    v = model.update(0.06, 5.0)  # line slope -100: unusable, so Eq. 9 from the last pair
    assert model.coef_ is not None and model.coef_[0] < 0
    assert v == pytest.approx(0.06 + 0.001 * 3.0, abs=1e-12)


# --- persistence -----------------------------------------------------------------------------


def trained_map() -> ContactMap:
    m = fixed_map(approach={"f_desired": 6.0})
    m.observe([0.01, 0.0, 0.0], v_used=0.05, f_measured=3.0)
    m.observe([0.49, 0.01, 0.0], v_used=0.05, f_measured=5.0)
    m.observe([0.9, 0.9, 0.9], "impactless")
    m.end_trial()
    m.observe([0.0, 0.0, 0.0], v_used=0.08, f_measured=4.5)
    return m


def test_json_round_trip(tmp_path: Path) -> None:
    m = trained_map()
    d = json.loads(json.dumps(m.state_dict()))
    assert d == m.state_dict()
    m2 = ContactMap.from_state_dict(d)
    assert m2.state_dict() == m.state_dict()
    m2 = ContactMap.load(m.save(tmp_path / "contacts.json"))
    assert m2.state_dict() == m.state_dict() and not list(tmp_path.glob("*.tmp"))
    assert m2.contacts[0].approach is not None and m.contacts[0].approach is not None
    assert m2.contacts[0].approach.next_velocity() == m.contacts[0].approach.next_velocity()
    z = [0.02, 0.01, 0.0]
    assert m2.contacts[0].belief.mahalanobis(z) == m.contacts[0].belief.mahalanobis(z)
    assert m2.observe([0.0, 0.0, 0.0]).updated is False  # the per-trial flag survives


def test_corrupted_and_foreign_files_raise_config_error(tmp_path: Path) -> None:
    path = tmp_path / "contacts.json"
    path.write_text('{"format": "ccm.contacts.ContactMap", "form')
    with pytest.raises(ConfigError, match=r"^init_from: cannot read contact map .*contacts\.json"):
        ContactMap.load(path)
    with pytest.raises(ConfigError, match=r"^init_from: cannot read"):
        ContactMap.load(tmp_path / "missing.json")
    path.write_text(json.dumps({"format": "ccm.igmm", "format_version": 1}))
    with pytest.raises(ConfigError, match=r"^my\.key: .*not a contact map"):
        ContactMap.load(path, key="my.key")


NOT_PD = [[1, 0, 0], [0, -1, 0], [0, 0, 1]]
BAD_STATES: list[tuple[Callable[[dict[str, Any]], object], str]] = [
    (lambda d: d.update(format_version=2), "unsupported format_version 2"),
    (lambda d: d.pop("contacts"), "malformed contact map"),
    (
        lambda d: d["contacts"][0].update(cov=NOT_PD),
        r"contacts\[0\]\.cov: must be positive definite",
    ),
    (lambda d: d["contacts"][0].update(approach=None), r"contacts\[0\]\.approach"),
    (lambda d: d["contacts"][2].update(kind="spring"), r"contacts\[2\]\.kind: unknown value"),
    (lambda d: d["settings"].update(gate=-1), r"controller\.contacts\.gate: must be > 0"),
    (lambda d: d["settings"].update(colour=1), "malformed contact map"),
    (lambda d: d["contacts"][0]["approach"].update(forces=[1.0]), "malformed approach"),
    (
        lambda d: d["contacts"][0]["approach"]["params"].update(beta=0),
        r"approach\.beta: must be > 0",
    ),
]


@pytest.mark.parametrize(("mutate", "message"), BAD_STATES)
def test_invalid_states_raise_config_error(
    tmp_path: Path, mutate: Callable[[dict[str, Any]], object], message: str
) -> None:
    bad = json.loads(json.dumps(trained_map().state_dict()))
    mutate(bad)
    path = tmp_path / "contacts.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(ConfigError, match=message) as err:
        ContactMap.load(path)
    assert err.value.key == "init_from" and "\n" not in str(err.value)


# --- validation ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"beta": 0.0}, "a.beta"),
        ({"f_desired": 12.0, "f_max": 10.0}, "a.f_desired"),
        ({"f_desired": -1.0}, "a.f_desired"),
        ({"v_safe": 0.5}, "a.v_safe"),
        ({"v_min": 0.3, "v_max": 0.2}, "a.v_max"),
        ({"max_step": float("nan")}, "a.max_step"),
        ({"use_model": "yes"}, "a.use_model"),
    ],
)
def test_approach_arguments_are_validated(kwargs: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        ApproachVelocityModel(**kwargs, key="a")  # type: ignore[arg-type]
    assert err.value.key == key


EYE = np.eye(3) * 1e-4
RNG = np.random.default_rng
BAD_CALLS: list[tuple[str, Callable[[], object]]] = [
    ("b.mean", lambda: ContactBelief([0, 0, 0, 0], EYE, EYE, EYE, key="b")),
    ("b.cov", lambda: ContactBelief([0, 0, 0], np.diag([1e-4, 0, 1e-4]), EYE, EYE, key="b")),
    ("b.process_noise_cov", lambda: ContactBelief([0, 0, 0], EYE, -EYE, EYE, key="b")),
    (
        "b.measurement_noise_cov",
        lambda: ContactBelief([0, 0, 0], EYE, EYE, np.ones((3, 3)), key="b"),
    ),
    ("b.z", lambda: ContactBelief([0, 0, 0], EYE, EYE, EYE, key="b").update([0, 0])),
    (
        "b.sigma_scale",
        lambda: ContactBelief([0, 0, 0], EYE, EYE, EYE, key="b").first_entry([[0, 0, 0]], 0),
    ),
    (
        "b.path_points",
        lambda: ContactBelief([0, 0, 0], EYE, EYE, EYE, key="b").first_entry([[0, 0]], 3),
    ),
    ("controller.contacts.dim", lambda: ContactMap(4)),
    ("controller.contacts.gate", lambda: ContactMap(3, gate=0.0)),
    ("controller.contacts.measurement_noise_std", lambda: ContactMap(3, measurement_noise_std=0.0)),
    ("controller.contacts.process_noise_std", lambda: ContactMap(3, process_noise_std=[0, 0])),
    ("controller.contacts.approach.speed", lambda: ContactMap(3, approach={"speed": 1})),
    ("controller.contacts.approach.beta", lambda: ContactMap(3, approach={"beta": -1})),
    ("controller.contacts.rng", lambda: ContactMap.from_config([[0, 0, 0]], 0)),  # type: ignore[arg-type]
    (
        "controller.contacts.expected_contacts[1].position",
        lambda: ContactMap.from_config([[0, 0, 0], [0, 0]], RNG()),
    ),
    (
        "controller.contacts.expected_contacts[0].kind",
        lambda: ContactMap.from_config([{"position": [0, 0], "kind": "spring"}], RNG()),
    ),
    (
        "controller.contacts.expected_contacts[0].pos",
        lambda: ContactMap.from_config([{"pos": [0, 0]}], RNG()),
    ),
    ("controller.contacts.dim", lambda: ContactMap.from_config([], RNG())),
    ("controller.contacts.init_std", lambda: ContactMap.from_config([[0, 0]], RNG(), init_std=0.0)),
    ("controller.contacts.kind", lambda: fixed_map().observe([0, 0, 0], "bump")),
    ("controller.contacts.f_measured", lambda: fixed_map().observe([0, 0, 0], v_used=0.1)),
    (
        "controller.contacts.v_used",
        lambda: fixed_map().observe([0, 0, 0], "impactless", v_used=0.1, f_measured=1.0),
    ),
    (
        "controller.contacts.v_used",
        lambda: fixed_map().observe([0, 0, 0], v_used=-0.1, f_measured=1.0),
    ),
    ("a.v_used", lambda: ApproachVelocityModel(key="a").update(0.0, 1.0)),
]


@pytest.mark.parametrize(("key", "make"), BAD_CALLS)
def test_belief_and_map_arguments_are_validated(key: str, make: Callable[[], object]) -> None:
    with pytest.raises(ConfigError) as err:
        make()
    assert err.value.key == key
