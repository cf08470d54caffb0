"""The adaptive baselines' laws checked against values computed by hand (seed A §4.2: MRAC,
AIC, BAC), their documented defaults, and their refusals as whole lines.

``tests/test_baselines.py`` holds the closed-loop checks; here each test drives one controller
to a case where its law gives a known number, so that a dropped term, a flipped projection
or a wrong index shows (the mutation run of ``make mutation`` found these gaps).
"""

from __future__ import annotations

import dataclasses
import math
from functools import partial
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from omegaconf import OmegaConf

from ccm.control.baselines.aic import AIC
from ccm.control.baselines.bac import BAC
from ccm.control.baselines.mrac import MRAC, _expm, reference_model_discrete
from ccm.control.impedance import FixedImpedance
from tests.test_baselines import DT, _refusal, obs, target

CONFIGS = Path(__file__).resolve().parents[1] / "configs" / "controller"


def _shipped(make: type) -> dict:
    """The controller's config file, without its Hydra entries (defaults list, type, text)."""
    cfg = OmegaConf.to_container(OmegaConf.load(CONFIGS / f"{make.__name__.lower()}.yaml"))
    return {k: v for k, v in cfg.items() if k not in ("defaults", "type", "description")}


@pytest.mark.parametrize("make", [MRAC, AIC, BAC], ids=["mrac", "aic", "bac"])
def test_constructor_defaults_are_the_shipped_configs_values(make: type) -> None:
    """Each class docstring says: "Defaults are the tuned values of configs/controller/X.yaml"
    (a controller built in Python is the one the experiments ran): the state the defaults
    build equals the state the config's values build, the loop block included."""
    cfg = _shipped(make)
    assert len(cfg) >= 7, cfg  # every scalar gain of the law
    default, shipped = make(), make(**cfg)
    np.testing.assert_equal(
        {k: v for k, v in vars(default).items() if k != "loop"},
        {k: v for k, v in vars(shipped).items() if k != "loop"},
    )
    np.testing.assert_equal(vars(default.loop), vars(shipped.loop))


@pytest.mark.parametrize(
    ("make", "name"),
    [(m, k) for m in (MRAC, AIC, BAC) for k in _shipped(m) if k != "loop"],
)
def test_every_gain_refusal_names_its_key(make: type, name: str) -> None:
    """A NaN for any gain of the law is one line that starts with its config key."""
    line = _refusal(make, **{name: float("nan")})
    assert line.startswith(f"controller.{name}: must be "), line
    assert "\n" not in line


# ----------------------------------------------------------------------------- MRAC


@pytest.mark.parametrize("norm", [0.1, 1.0, 40.0])
def test_mrac_matrix_exponential_matches_scipy(norm: float) -> None:
    """The Taylor series with scaling and squaring, below and far above its 0.25 threshold."""
    rng = np.random.default_rng(7)
    m = rng.normal(size=(3, 3))
    m *= norm / np.max(np.sum(np.abs(m), axis=1))
    np.testing.assert_allclose(_expm(m), scipy.linalg.expm(m), rtol=1e-11, atol=1e-13)


def test_mrac_reference_model_step_is_the_zero_order_hold_of_its_ode() -> None:
    """G = the first two rows of expm([[0, 1, 0], [−ω², −2ζω, ω²], [0, 0, 0]] dt): 2 × 3."""
    omega, zeta, dt = 30.0, 0.3, 0.02
    aug = np.array([[0.0, 1.0, 0.0], [-(omega**2), -2 * zeta * omega, omega**2], [0.0, 0.0, 0.0]])
    g = reference_model_discrete(omega, zeta, dt)
    assert g.shape == (2, 3)
    np.testing.assert_allclose(g, scipy.linalg.expm(aug * dt)[:2], rtol=1e-10, atol=1e-13)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_mrac_first_step_starts_the_model_at_the_robot_and_feeds_its_acceleration(
    compiled: bool,
) -> None:
    """x_m(0) = x(0), ẋ_m(0) = ẋ(0); with adaptation off (α = β = γ = 0, f0 = K_p0 = K_v0 = 0)
    the command is the feed-forward m a_m = m (ω² (r − x_m) − 2ζω ẋ_m) alone, and x_m advances
    by the zero-order hold."""
    omega, zeta, m = 3.0, 0.4, 2.0
    c = MRAC(omega=omega, zeta=zeta, f0=0.0, kp0=0.0, kv0=0.0, alpha1=0.0, alpha2=0.0,
             beta1=0.0, beta2=0.0, gamma1=0.0, gamma2=0.0,
             loop={"inertia_feedforward": True, "mass_kg": m})  # fmt: skip
    c.compiled = compiled
    c.reset(2, DT)
    x0, v0, r = np.array([0.01, -0.02]), np.array([0.1, 0.05]), np.array([0.05, 0.0])
    cmd = c.step(obs(pos=x0, vel=v0), target(pos=r))
    a_m = omega**2 * (r - x0) - 2 * zeta * omega * v0
    np.testing.assert_allclose(cmd.force, m * a_m, rtol=1e-12)
    g = reference_model_discrete(omega, zeta, DT)
    np.testing.assert_allclose(c.x_m, g[0] @ np.array([x0, v0, r]), rtol=1e-12)
    np.testing.assert_allclose(c.v_m, g[1] @ np.array([x0, v0, r]), rtol=1e-12)


def test_mrac_adaptation_on_a_force_segment_by_hand() -> None:
    """The numpy path (force segments): e, ė projected across d, q = w_p e + w_v ė, rectangle
    integrals; f, K_p, K_v after two steps, every gain distinct; f leaves the command along d."""
    gains = {"alpha1": 2.0, "alpha2": 3.0, "beta1": 5.0, "beta2": 7.0, "gamma1": 11.0,
             "gamma2": 13.0}  # fmt: skip
    c = MRAC(w_p=1.5, w_v=0.25, f0=4.0, kp0=100.0, kv0=20.0, **gains)
    c.reset(2, DT)
    d = np.array([0.0, -1.0])
    seg = target(fdir=tuple(d), fmag=5.0)
    c.step(obs(), seg)  # the model starts at the robot (rest at 0)
    x_m, v_m = c.x_m.copy(), c.v_m.copy()
    x, v = np.array([-0.01, 0.02]), np.array([0.03, -0.04])
    cmd = c.step(obs(pos=x, vel=v), seg)
    across = np.eye(2) - np.outer(d, d)
    e, ed = [], []
    e.append(np.zeros(2))
    ed.append(np.zeros(2))
    e.append(across @ (x_m - x))
    ed.append(across @ (v_m - v))
    q = [1.5 * a + 0.25 * b for a, b in zip(e, ed, strict=True)]
    iq = sum(qi * DT for qi in q)
    iqe = sum(qi * ei * DT for qi, ei in zip(q, e, strict=True))
    iqv = sum(qi * vi * DT for qi, vi in zip(q, ed, strict=True))
    np.testing.assert_allclose(c.f, 4.0 + 2.0 * iq + 3.0 * q[1], rtol=1e-12)
    np.testing.assert_allclose(c.kp, 100.0 + 5.0 * iqe + 7.0 * q[1] * e[1], rtol=1e-12)
    np.testing.assert_allclose(c.kv, 20.0 + 11.0 * iqv + 13.0 * q[1] * ed[1], rtol=1e-12)
    ref = FixedImpedance()  # along d only Eq. 1's force loop acts (its integral: two steps)
    ref.reset(2, DT)
    ref.step(obs(), seg)
    assert cmd.force[1] == pytest.approx(ref.step(obs(pos=x, vel=v), seg).force[1], rel=1e-12)


def test_mrac_initial_signals_are_its_effective_gains() -> None:
    """Effective K = K_p0 + α₁ w_v + α₂ w_p, D = K_v0 + α₂ w_v (MRAC docstring); |f0| √dim."""
    c = MRAC(w_p=2.0, w_v=0.5, f0=-3.0, kp0=100.0, kv0=20.0, alpha1=100.0, alpha2=10.0)
    c.reset(2, DT)
    assert c.signals() == pytest.approx({
        "stiffness_Npm": 100.0 + 100.0 * 0.5 + 10.0 * 2.0, "damping_Nspm": 20.0 + 10.0 * 0.5,
        "adaptive_kp_Npm": 100.0, "adaptive_kv_Nspm": 20.0, "adaptive_force_N": 3 * math.sqrt(2),
        "ref_error_m": 0.0, "ref_lag_m": 0.0, "force_error_N": 0.0, "force_control": 0.0,
    })  # fmt: skip
    c.compiled = False
    c.step(obs(vel=(0.1, 0.0)), target())
    assert c.signals()["damping_Nspm"] == pytest.approx(np.mean(c.kv) + 10.0 * 0.5)


def test_mrac_reset_refusals_are_whole_lines() -> None:
    assert _refusal(MRAC(zeta=[1.0, 1.0, 1.0]).reset, 2, DT) == (
        "controller.zeta: needs 1 or 2 values, got 3"
    )
    assert _refusal(MRAC(omega=[1.0, 4000.0]).reset, 2, DT) == (
        "controller.omega: must be <= pi / control step = 3142 rad/s (the Nyquist rate at "
        "0.001 s), got 4000"
    )
    MRAC(omega=math.pi / DT).reset(2, DT)  # at the Nyquist rate: allowed


# ----------------------------------------------------------------------------- AIC


def test_aic_first_step_starts_the_beliefs_at_the_robot() -> None:
    """μ = y₀, μ' = ẏ₀, μ'' = 0 on the first step, then one Euler step of perception from
    there, with every precision distinct and μ' ≠ 0 so that each term of Eq. (Pezzato et al.
    2020) shows; the signals report |y − μ| and |μ_d − μ| before the update."""
    c = AIC(k_mu=2.0, k_a=1e-9, sigma_y=0.5, sigma_yp=2.0, sigma_mu=4.0, sigma_mup=8.0,
            attractor_rate=3.0)  # fmt: skip
    c.reset(2, DT)
    y0, yp0 = np.array([0.01, -0.02]), np.array([0.05, 0.02])
    c.step(obs(pos=y0, vel=yp0), target(pos=y0))
    lam, kmu = 3.0, 2.0
    e_mu, e_mup = yp0, lam * yp0  # μ' − λ(r − μ) with r = μ = y₀; μ'' + λ μ'
    np.testing.assert_allclose(c.mu, y0 + DT * (yp0 - kmu * lam * e_mu / 4.0), rtol=1e-12)
    g_mup = e_mu / 4.0 + lam * e_mup / 8.0
    np.testing.assert_allclose(c.mu_p, yp0 - DT * kmu * g_mup, rtol=1e-12)
    np.testing.assert_allclose(c.mu_pp, -DT * kmu * e_mup / 8.0, rtol=1e-12)
    mu = c.mu.copy()
    r = np.array([0.05, 0.05])
    c.step(obs(pos=y0, vel=yp0), target(pos=r))
    assert c.signals()["belief_lag_m"] == pytest.approx(np.linalg.norm(r - mu), rel=1e-12)


def test_aic_reset_signals() -> None:
    c = AIC(k_a=500.0, sigma_yp=2.0)
    c.reset(2, DT)
    s = c.signals()
    assert math.isnan(s.pop("damping_Nspm"))
    assert s == {"stiffness_Npm": 250.0, "belief_error_m": 0.0, "belief_lag_m": 0.0,
                 "action_N": 0.0, "force_error_N": 0.0, "force_control": 0.0}  # fmt: skip


# ----------------------------------------------------------------------------- all three


@pytest.mark.parametrize(
    "make", [partial(MRAC, f0=3.0), partial(AIC, k_a=5e4), partial(BAC, init_force=3.0)],
    ids=["mrac", "aic", "bac"],
)  # fmt: skip
def test_adaptive_force_never_acts_along_the_force_direction(make: partial) -> None:
    """The adapted feed-forward (MRAC's f, AIC's action u, BAC's F(k)) is built up in free
    space with a part along y; on a force segment along d = −y the command along d is then
    the force loop's alone, as for the fixed impedance, and stays so while u keeps adapting."""
    free, seg = target(), target(fdir=(0.0, -1.0), fmag=10.0)
    ref, c = FixedImpedance(), make()
    for ctrl in (ref, c):
        ctrl.reset(2, DT)
    for i in range(3):  # free space, moving: errors for every law to adapt on
        o = obs(pos=(0.01 * i, 0.02 * i), vel=(0.1 * i, 0.3 * i))
        ref.step(o, free)
        c.step(o, free)
    u_d = c.u[1] if isinstance(c, AIC) else None
    assert u_d is None or abs(u_d) > 1e-3  # the action has a part along d
    for i in range(3):
        o = obs(pos=(0.01, 0.05 + 0.01 * i), vel=(0.0, 0.3 + 0.2 * i))
        expected, got = ref.step(o, seg).force[1], c.step(o, seg).force[1]
        assert got == pytest.approx(expected, rel=1e-12)
    if u_d is not None:  # AIC's action adapts across d only: its part along d is kept
        assert c.u[1] == pytest.approx(u_d, rel=1e-12)


def test_mrac_needs_one_weight_of_its_error() -> None:
    MRAC(w_p=0.0, w_v=0.1)  # either weight alone adapts the gains
    MRAC(w_p=1.0, w_v=0.0)
    assert _refusal(MRAC, w_p=0.0, w_v=0.0) == (
        "controller.w_p: w_p and w_v are both 0: the gains could not adapt"
    )


# ----------------------------------------------------------------------------- BAC


def _with_inertia(o, lam: np.ndarray):  # type: ignore[no-untyped-def]
    return dataclasses.replace(o, inertia=lam)


def test_bac_two_trials_by_hand() -> None:
    """Yang et al.'s update over two trials and a short third: trial 2 starts from trial 1's
    F(k), K(k) (K clipped into [k_min, k_max]), a longer trial uses index N − 1 past N and
    learns nothing there, a shorter one updates only the indices it reached. Each command is
    F(k) + K(k) e_p + D(k) e_v with D(k) = 2 √(Λ K(k)) from the arm's Λ(q)."""
    law = {"kappa": 10.0, "q_force": 2.0, "q_stiffness": 1e4, "gamma_force": 0.01,
           "gamma_stiffness": 1e-6}  # fmt: skip
    c = BAC(init_stiffness=[300.0, 400.0], init_force=[1.0, -2.0], k_min=290.0, **law)
    lam = np.diag([4.0, 9.0])
    f = np.array([[1.0, -2.0]] * 3)
    k = np.array([[300.0, 400.0]] * 3)
    trials = [  # (e_p, e_v) per step: target at rest at 0, so x = −e_p, ẋ = −e_v
        [((0.01, 0.0), (0.0, -0.1)), ((0.01, -0.02), (-0.2, -0.1)), ((0.0, 0.01), (0.0, 0.0))],
        [((0.0, 0.01), (0.05, 0.0)), ((-0.01, 0.0), (0.0, 0.02)), ((0.02, 0.02), (0.1, 0.1)),
         ((0.01, 0.01), (0.0, 0.0))],
        [((0.03, 0.0), (0.0, 0.0))],
    ]  # fmt: skip
    for n_trial, steps in enumerate(trials, start=1):
        c.reset(2, DT)
        for i, (ep, ev) in enumerate(steps):
            ep, ev = np.array(ep), np.array(ev)
            o = _with_inertia(obs(pos=-ep, vel=-ev), lam)
            idx = min(i, 2)
            kd = 2.0 * np.sqrt(np.diag(lam) * k[idx])
            np.testing.assert_allclose(
                c.step(o, target()).force, f[idx] + k[idx] * ep + kd * ev, rtol=1e-12
            )
            assert c.signals()["damping_Nspm"] == pytest.approx(np.mean(kd), rel=1e-12)
        c.end_trial()
        ep = np.array([s[0] for s in steps[:3]])
        eps = np.array([s[1] for s in steps[:3]]) + 10.0 * ep
        m = len(ep)
        f[:m] = f[:m] + 2.0 * (eps - 0.01 * f[:m])
        k[:m] = np.clip(k[:m] + 1e4 * (eps * ep - 1e-6 * k[:m]), 290.0, 3000.0)
        np.testing.assert_allclose(c.force_profile, f, rtol=1e-12)
        np.testing.assert_allclose(c.stiffness_profile, k, rtol=1e-12)
        assert c.trials_learned == n_trial and c.horizon_steps == 3
        if n_trial == 1:
            assert k[1, 0] == 290.0  # the clip acted (287 N/m before it)


def test_bac_learned_state_needs_both_profiles() -> None:
    c = BAC()
    c.reset(2, DT)
    state = {"force_profile": None, "stiffness_profile": [[300.0, 300.0]], "trials_learned": 1}
    assert _refusal(c.load_state_dict, state) == (
        "init_from: profiles must be (N, dim) alike, got (), (1, 2)"
    )
    c.load_state_dict({"force_profile": [[0.0, 0.0]], "stiffness_profile": [[1.0, 300.0]],
                       "trials_learned": 1})  # fmt: skip
    np.testing.assert_array_equal(c.stiffness_profile, [[c.k_min, 300.0]])


def test_bac_damping_follows_the_loop_block() -> None:
    """The ``loop`` block reaches D(k) (critical rule: 2 ζ √(m K))."""
    c = BAC(init_stiffness=400.0, loop={"mass_kg": 4.0, "damping_ratio": 0.5})
    c.reset(2, DT)
    assert c.signals()["damping_Nspm"] == pytest.approx(2 * 0.5 * math.sqrt(4.0 * 400.0))


@pytest.mark.parametrize("make", [MRAC, AIC, BAC], ids=["mrac", "aic", "bac"])
def test_loop_block_is_used_and_its_errors_carry_its_key(make: type) -> None:
    assert make(loop={"rot_stiffness": 7.0}).loop.rot_stiffness == 7.0
    assert _refusal(make, loop={"damping_ratio": -1.0}) == (
        "controller.loop.damping_ratio: must be > 0, got -1.0"
    )


def test_bac_learned_stiffness_is_capped_at_k_max() -> None:
    """ε e_p = 0.2 · 0.01 over one step with Q_K = 10⁶ would add 2000 N/m: K stops at k_max."""
    c = BAC(init_stiffness=300.0, k_max=400.0, kappa=10.0, q_stiffness=1e6, gamma_stiffness=0.0)
    c.reset(2, DT)
    c.step(obs(pos=(-0.01, 0.0), vel=(-0.1, 0.0)), target())
    c.end_trial()
    np.testing.assert_array_equal(c.stiffness_profile, [[400.0, 300.0]])


@pytest.mark.parametrize(
    ("kwargs", "line"),
    [
        ({"k_min": -1.0}, "controller.k_min: must be >= 0, got -1.0"),
        ({"k_max": 0.0}, "controller.k_max: must be > 0, got 0.0"),
        ({"k_min": 500.0, "k_max": 400.0, "init_stiffness": 450.0},
         "controller.k_max: must be >= k_min=500.0, got 400.0"),
        ({"init_stiffness": 3500.0},
         "controller.init_stiffness: must be in [k_min, k_max] = [50.0, 3000.0], got 3500.0"),
        ({"init_force": float("inf")}, "controller.init_force: must be a finite number, got inf"),
        ({"gamma_force": -1.0}, "controller.gamma_force: must be >= 0, got -1.0"),
        ({"gamma_stiffness": -1.0}, "controller.gamma_stiffness: must be >= 0, got -1.0"),
        ({"q_stiffness": -1.0}, "controller.q_stiffness: must be >= 0, got -1.0"),
        ({"q_force": 3.0, "gamma_force": 0.5},
         "controller.gamma_force: Q * gamma = 1.5 must be <= 1"),
        ({"q_stiffness": 1e6, "gamma_stiffness": 2e-6},
         "controller.gamma_stiffness: Q * gamma = 2 must be <= 1"),
    ],
)  # fmt: skip
def test_bac_refusals_are_whole_lines(kwargs: dict, line: str) -> None:
    assert _refusal(BAC, **kwargs) == line


def test_bac_bounds_are_inclusive() -> None:
    """k_min = k_max = K₀ and Q γ = 1 (F forgotten in one trial) are valid settings."""
    BAC(init_stiffness=300.0, k_min=300.0, k_max=300.0)
    BAC(init_stiffness=3000.0, q_force=2.0, gamma_force=0.5)
    assert _refusal(BAC(init_force=[1.0, 2.0, 3.0]).reset, 2, DT) == (
        "controller.init_force: needs 1 or 2 values, got 3"
    )
