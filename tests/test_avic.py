"""AVIC (seed A Eq. 4a-4c): bounds of lambda and K_p, feed-forward direction, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ccm.control.adaptive.avic import AVIC
from ccm.core.errors import ConfigError
from ccm.core.types import Observation, TargetSample

FIXED = {"kind": "fixed_gmm", "fixed_gmm": {"fit_steps": 50, "n_components": 2}}


def obs(vel=(0.1, 0.0), force=(-1.0, 0.0), pos=(0.0, 0.0)) -> Observation:
    return Observation(
        0.0,
        np.array(pos, float),
        np.zeros(1),
        np.array(vel, float),
        np.zeros(1),
        np.array(force, float),
        np.zeros(1),
    )


def target() -> TargetSample:
    z = np.zeros(2)
    return TargetSample(0.0, z.copy(), z.copy(), z.copy(), np.zeros(1))


def make(**kw) -> AVIC:
    kw.setdefault("forward_model", FIXED)
    c = AVIC(**kw)
    c.reset(2, 0.001)
    return c


def test_logistic_of_eq_4c() -> None:
    c = make(r=3.0, eps0=1.5)
    assert c.gate(1.5) == pytest.approx(0.5)
    eps = np.linspace(-5, 50, 500)
    lam = np.array([c.gate(e) for e in eps])
    assert np.all((lam >= 0) & (lam <= 1))
    assert np.all(np.diff(lam) <= 0), "larger prediction error, smaller lambda"
    assert c.gate(1e6) == 0.0 and c.gate(-1e6) == 1.0  # no overflow


def test_stiffness_stays_within_bounds_on_a_random_stream() -> None:
    rng = np.random.default_rng(0)
    c = make(k_free=200.0, k_max=2000.0, r=5.0, eps0=0.5)
    seen = []
    for _ in range(400):
        o = obs(vel=rng.normal(0, 0.2, 2), force=rng.normal(0, 5.0, 2))
        c.step(o, target())
        s = c.signals()
        seen.append(s["stiffness_Npm"])
        assert 0.0 <= s["lambda"] <= 1.0
        assert 200.0 - 1e-9 <= s["stiffness_Npm"] <= 2000.0 + 1e-9
    assert c.model.ready, "the frozen GMM fit after its 50-point window"
    assert np.isfinite(c.signals()["pred_force_N"])
    assert len(set(np.round(seen, 6))) > 1, "stiffness adapted"


def test_non_adaptive_baseline_is_fixed_at_k_max() -> None:
    c = make(adaptive=False, k_free=100.0, k_max=900.0)
    for _ in range(100):
        u = c.step(obs(pos=(0.01, 0.0), vel=(0.0, 0.0)), target())
        assert c.signals()["stiffness_Npm"] == 900.0
    # no feed-forward: the command is the impedance law alone
    kd = 2.0 * math.sqrt(900.0)
    assert u.force[0] == pytest.approx(-900.0 * 0.01 - kd * 0.0)


def test_predicted_wrench_directions() -> None:
    c = make(ff_direction="against_motion", min_speed=0.01)
    w = c.predicted_wrench(4.0, obs(vel=(0.0, 0.5)))
    np.testing.assert_allclose(w, [0.0, -4.0])
    assert np.all(c.predicted_wrench(4.0, obs(vel=(0.0, 0.001))) == 0.0)
    m = make(ff_direction="measured")
    np.testing.assert_allclose(m.predicted_wrench(2.0, obs(force=(3.0, 4.0))), [1.2, 1.6])


def test_along_motion_drops_the_reaction_of_a_wall_it_presses_into() -> None:
    """``along_motion``: only the measured force's part along the measured motion is
    cancelled, so a wall's normal reaction (across the motion) gets no feed-forward, and a
    tool stalled against a surface gets none at all (no F = K d / (1 - lambda) runaway)."""
    c = make(ff_direction="along_motion", min_speed=0.01)
    # sliding along +y against a wall at +x: reaction -3 N along x, friction -1.5 N along y
    w = c.predicted_wrench(2.0 * float(np.hypot(3.0, 1.5)), obs(vel=(0.0, 0.1), force=(-3.0, -1.5)))
    np.testing.assert_allclose(w, [0.0, -3.0])
    # stalled against the wall (the target inside it): no motion, no feed-forward
    np.testing.assert_array_equal(
        c.predicted_wrench(5.0, obs(vel=(0.001, 0.0), force=(-3.0, 0.0))), 0.0
    )


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"k_free": -1.0}, "controller.k_free"),
        ({"k_free": 500.0, "k_max": 100.0}, "controller.k_max"),
        ({"r": 0.0}, "controller.r"),
        ({"eps0": float("nan")}, "controller.eps0"),
        ({"ff_direction": "sideways"}, "controller.ff_direction"),
        ({"forward_model": {"kind": "magic"}}, "controller.forward_model.kind"),
        ({"forward_model": {"kind": "igmm", "colour": 1}}, "controller.forward_model.colour"),
    ],
)
def test_bad_parameters_name_the_key(kwargs: dict, key: str) -> None:
    kwargs.setdefault("forward_model", FIXED)
    with pytest.raises(ConfigError) as err:
        AVIC(**kwargs)
    assert err.value.key == key


def test_feed_forward_opposes_the_measured_external_force() -> None:
    """-lambda W_pred of Eq. 4a cancels the external force: with the tool on target and a
    steady external force of -3 N along x, AVIC's command exceeds the feed-forward-free one
    by +lambda * 3 N along x (a flipped sign would push with the disturbance)."""
    kw = {"k_free": 300.0, "k_max": 3000.0, "r": 2.0, "eps0": 5.0}
    ff, plain = make(**kw), make(feedforward=False, **kw)
    o = obs(vel=(0.0, 0.0), force=(-3.0, 0.0))
    for _ in range(120):  # past the fixed GMM's 50-point window
        u_ff, u_plain = ff.step(o, target()), plain.step(o, target())
    lam = ff.signals()["lambda"]
    assert lam > 0.9, "a steady force is predicted well"
    np.testing.assert_allclose(u_ff.force - u_plain.force, [lam * 3.0, 0.0], atol=0.05)


def test_horizon_predictions_are_made_h_steps_ahead() -> None:
    """With horizon 5 ms at 1 kHz the logged prediction of ||F_t|| was made from S_{t-5},
    and persistence is ||F_{t-5}||: on a force ramp of 0.1 N per step, persistence misses
    by 0.5 N."""
    c = make(forward_model={"kind": "igmm", "horizon_s": 0.005}, r=2.0, eps0=5.0)
    for k in range(200):
        c.step(obs(vel=(0.1, 0.0), force=(-(1.0 + 0.1 * k), 0.0)), target())
        s = c.signals()
        if k < 5:
            assert math.isnan(s["pred_force_N"]) and math.isnan(s["persist_force_N"])
    assert s["persist_force_N"] == pytest.approx(1.0 + 0.1 * 194)
    assert abs(s["persist_force_N"] - (1.0 + 0.1 * 199)) == pytest.approx(0.5)


def test_calibration_sets_eps0_and_r_from_the_first_trial() -> None:
    """calibrate: trial 1 runs at K_max without feed-forward while the errors are kept; then
    eps0 = their quantile and r = shape / eps0."""
    rng = np.random.default_rng(3)
    cal = {"trials": 1, "quantile": 0.8, "shape": 10.0}
    c = make(calibrate=cal, r=None, eps0=None, forward_model={"kind": "igmm"})
    errs = []
    for _ in range(300):
        c.step(obs(force=(-2.0 + rng.normal(0, 0.3), 0.0)), target())
        s = c.signals()
        assert s["stiffness_Npm"] == 3000.0 and s["calibrating"] == 1.0
        if np.isfinite(s["pred_error_N"]):
            errs.append(s["pred_error_N"])
    assert math.isnan(c.gate.eps0)
    c.end_trial()
    assert c.gate.eps0 == pytest.approx(np.quantile(errs, 0.8))
    assert c.gate.r == pytest.approx(10.0 / c.gate.eps0)
    c.reset(2, 0.001)
    c.step(obs(force=(-2.0, 0.0)), target())
    assert c.signals()["calibrating"] == 0.0
    state = c.state_dict()
    d = make(calibrate=cal, r=None, eps0=None, forward_model={"kind": "igmm"})
    d.load_state_dict(state)
    assert (d.gate.eps0, d.gate.r) == (c.gate.eps0, c.gate.r)


def test_calibration_and_fixed_eps0_exclude_each_other() -> None:
    with pytest.raises(ConfigError, match="controller.eps0"):
        AVIC(calibrate={"trials": 1}, r=None, eps0=2.0, forward_model=FIXED)
    with pytest.raises(ConfigError, match="controller.calibrate.quantile"):
        AVIC(calibrate={"quantile": 1.5}, r=None, eps0=None, forward_model=FIXED)
    with pytest.raises(ConfigError, match="controller.calibrate.colour"):
        AVIC(calibrate={"colour": 1}, r=None, eps0=None, forward_model=FIXED)


def test_a_frozen_model_calibrates_on_its_training_window() -> None:
    """AVIC guided by the fixed GMM (seed A §4.1): the model predicts only after trial 1,
    so eps0 comes from its errors on the trial-1 window."""
    cal = {"trials": 1, "quantile": 0.9, "shape": 20.0}
    fm = {"kind": "fixed_gmm", "fixed_gmm": {"fit_steps": None, "n_components": 1}}
    c = make(calibrate=cal, r=None, eps0=None, forward_model=fm)
    rng = np.random.default_rng(5)
    for _ in range(200):
        c.step(obs(force=(-2.0 + rng.normal(0, 0.3), 0.0)), target())
    assert math.isnan(c.gate.eps0) and not c.model.ready
    c.end_trial()
    assert c.model.ready and c.gate.eps0 > 0.0 and c.gate.r == pytest.approx(20.0 / c.gate.eps0)


def test_eq4c_lambda_and_eq4b_stiffness_off_the_midpoint() -> None:
    """Eq. 4c, λ = 1 − 1/(1 + e^(−r(ε − ε₀))), one 1/r either side of ε₀: 1 − 1/(1 + e^(−1))
    = 0.2689 above it (a poor model: little feed-forward) and 0.7311 below; the midpoint's 0.5
    would also hold with the sign inverted. Eq. 4b, K_p = K_free + (1 − λ)(K_max − K_free),
    then gives the stiffness those λ mean: high for the poor model, low for the good one."""
    from ccm.control.adaptive.logistic import LogisticGate

    gate = LogisticGate(r=4.0, eps0=0.5)
    assert gate(0.5) == 0.5
    assert gate(0.75) == pytest.approx(1.0 - 1.0 / (1.0 + math.exp(-1.0)), rel=1e-14)
    assert gate(0.75) == pytest.approx(0.268941, abs=1e-6)
    assert gate(0.25) == pytest.approx(0.731059, abs=1e-6)
    c = AVIC(k_free=300.0, k_max=3000.0, r=4.0, eps0=0.5, forward_model=FIXED)
    assert c.stiffness_for(gate(0.75)) == pytest.approx(300.0 + 0.731059 * 2700.0, abs=1e-2)
    assert c.stiffness_for(gate(0.25)) == pytest.approx(300.0 + 0.268941 * 2700.0, abs=1e-2)
    assert (c.stiffness_for(0.0), c.stiffness_for(1.0)) == (3000.0, 300.0)


def test_signals_keep_one_key_set_and_damping_follows_lambda_q() -> None:
    """The log's columns are fixed from reset on (``Controller.signals``), and under
    ``inertia: model`` K_d is designed for the arm's Λ(q) of each step: at K_p = k_max
    (nothing learned yet), Λ = diag(4, 1) gives K_d = 2 √(Λ K_p) per axis."""
    import dataclasses

    c = make(k_free=100.0, k_max=400.0, loop={"damping_rule": "critical", "inertia": "model",
                                               "mass_kg": 1.0})  # fmt: skip
    keys = set(c.signals())
    o = dataclasses.replace(obs(), inertia=np.diag([4.0, 1.0]))
    c.step(o, target())
    s = c.signals()
    assert set(s) == keys and "lambda" in keys
    k = s["stiffness_Npm"]
    assert s["damping_Nspm"] == pytest.approx((2 * math.sqrt(4.0 * k) + 2 * math.sqrt(k)) / 2)
