"""Seed B Eq. 13-17, one cost term at a time (issue #37): every cost term of the GP-MPC is
switched off and on in a small problem, and the solution must move the way seed B says, by a
margin computed for the case (cases and the closed-form plan: ``tests/mpc_cases.py``).

Each test solves fresh problems (cold start, 1-D or 2-D poses, horizon 5, T_s = 0.01 s) from
the same state with the term off and on. The impedance terms (Q_Σ, Eq. 16-17, Q_u on ΔM, ΔD)
depend on (M, D) only, and their optimum is a bounded minimisation in numpy. Eq. 5-8
themselves are tested in test_admittance.py and test_gp_mpc.py (Monte Carlo); the human
joint-torque cost (Eq. 15) and the constraints (Eq. 18-20) in test_mpc_constraints_on_off.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize
import scipy.special
import scipy.stats

from ccm.control.mpc.admittance import system_matrices
from ccm.control.mpc.settings import Weights
from tests.mpc_cases import (
    FROZEN,
    TS,
    H,
    _assert_linear,
    _check_plan,
    _field,
    _linear_plan,
    _solve,
)
from tests.mpc_cases import (
    flat_neg as flat_neg_gp,
)
from tests.mpc_cases import (
    flat_pos as flat_pos_gp,
)
from tests.mpc_cases import (
    patch as patch_gp,
)
from tests.mpc_cases import (
    ramp as ramp_gp,
)
from tests.mpc_cases import (
    wall as wall_gp,
)


def test_velocity_weight_slows_the_plan() -> None:
    """Q_μ (Eq. 14, 'a small penalty on velocity'): f^r pulled to −10 N (+x push) by its
    target; with Q_μ on the push is smaller and the predicted velocity lower."""
    flat_pos = flat_pos_gp()
    xi0 = [0.0, 0.0]
    mu0, grad = _field(flat_pos, 0.0)
    w_off = Weights(vel=0.0, f_ref_target=1.0)
    w_on = Weights(vel=1e4, f_ref_target=1.0)
    off = _solve([flat_pos], w_off, xi0, f_ref_target=-10.0, **FROZEN)
    on = _solve([flat_pos], w_on, xi0, f_ref_target=-10.0, **FROZEN)
    _assert_linear(flat_pos, 0.0, np.r_[off.predicted[0, :, 0], on.predicted[0, :, 0]])
    _check_plan(off, _linear_plan(xi0, mu0, grad, target_w=1.0, target=-10.0), 2e-3)
    plan = _linear_plan(xi0, mu0, grad, vel=1e4, target_w=1.0, target=-10.0)
    _check_plan(on, plan, 2e-3)
    # margin from the closed form: |f^r_t| drops 10 -> 8.35 N, ẋ_H 0.0697 -> 0.0636 m/s
    assert abs(on.f_ref[0]) < abs(off.f_ref[0]) - 1.5
    assert on.predicted[0, -1, 1] < off.predicted[0, -1, 1] - 5e-3
    # a flipped sign (−Q_μ) would reward speed: f^r would pass −10 N and ẋ_H rise; fails.


def test_force_weight_moves_the_plan_to_a_smaller_gp_force() -> None:
    """Q_f on μ^f (Eq. 14): in a spring-like field μ^f ≈ 2 − 300 x the plan pushes toward
    μ^f = 0 (x ≈ 6.7 mm), ending where |μ^f| is smaller than the plan without the term."""
    ramp = ramp_gp()
    xi0 = [0.0, 0.0]
    mu0, grad = _field(ramp, 0.0)
    off = _solve([ramp], Weights(vel=0.0, f_ref=1e-3), xi0, **FROZEN)
    on = _solve([ramp], Weights(vel=0.0, f_ref=1e-3, force=1.0), xi0, **FROZEN)
    _assert_linear(ramp, 0.0, np.r_[off.predicted[0, :, 0], on.predicted[0, :, 0]])
    _check_plan(off, _linear_plan(xi0, mu0, grad, f_ref=1e-3), 2e-3)
    _check_plan(on, _linear_plan(xi0, mu0, grad, f_ref=1e-3, force=1.0), 2e-3)
    mu_off, mu_on = (abs(_field(ramp, s.predicted[0, -1, 0])[0]) for s in (off, on))
    assert mu_on < mu_off - 0.5  # closed form (matched above): |μ^f(x_H)| 1.94 -> 0.95 N
    assert on.f_ref[0] < -1.0  # f^r < 0 pushes +x (Eq. 5: ẍ ∝ f − f^r), toward μ^f = 0
    # a flipped sign (−Q_f) would push away from μ^f = 0: |μ^f(x_H)| would grow; fails.


def test_human_match_pulls_f_ref_to_minus_the_gp_force() -> None:
    """force_cost human_match (seed B §4.2.1): (μ^f + f^r)ᵀ Q_H (μ^f + f^r) with an f^r target
    of 0 at equal weight. Off: f^r stays at its target 0. On: at the measured pose
    f^r_t = −Q_H μ^f(x_t) / (Q_H + w_target) = −μ^f/2 ≈ −4 N (the later steps hardly couple:
    μ^f's slope is 0.3 N/m)."""
    flat_pos = flat_pos_gp()
    xi0 = [0.0, 0.0]
    mu0, grad = _field(flat_pos, 0.0)
    kw = {"force_cost": "human_match", "f_ref_target": 0.0, **FROZEN}
    off = _solve([flat_pos], Weights(vel=0.0, f_ref_target=1.0), xi0, **kw)
    on = _solve([flat_pos], Weights(vel=0.0, f_ref_target=1.0, force=1.0), xi0, **kw)
    _assert_linear(flat_pos, 0.0, np.r_[off.predicted[0, :, 0], on.predicted[0, :, 0]])
    assert off.f_ref[0] == pytest.approx(0.0, abs=1e-4)
    assert on.f_ref[0] == pytest.approx(-mu0 / 2.0, abs=1e-2)  # the one-step formula
    _check_plan(on, _linear_plan(xi0, mu0, grad, target_w=1.0, force=1.0, human_match=True), 2e-3)
    assert on.f_ref[0] < -3.5  # toward −μ^f ≈ −8 N by half of it
    # with (μ^f − f^r)² (flipped sign) f^r would go to +μ^f/2 = +4 N; fails.


def test_f_ref_weight_shrinks_f_ref() -> None:
    """Q_u on f^r (Eq. 14) against the f^r target −10 N: f^r_k = w_t T / (w_t + Q_u), i.e.
    −10 N off and −5 N with Q_u = w_t on (every step: nothing else depends on f^r here)."""
    flat_pos = flat_pos_gp()
    xi0 = [0.0, 0.0]
    kw = {"f_ref_target": -10.0, **FROZEN}
    off = _solve([flat_pos], Weights(vel=0.0, f_ref_target=1.0), xi0, **kw)
    on = _solve([flat_pos], Weights(vel=0.0, f_ref_target=1.0, f_ref=1.0), xi0, **kw)
    assert off.f_ref[0] == pytest.approx(-10.0, abs=1e-4)
    assert on.f_ref[0] == pytest.approx(-5.0, abs=1e-4)
    # a flipped sign (−Q_u) would give −10/(1 − 1): unbounded, f^r at −100 N; fails.


def test_f_ref_target_pulls_f_ref_to_the_target() -> None:
    """The f^r target cost ‖f^r − T‖² (seed B §6.2's ‖15 − f^r_2‖): with only Q_μ (1e4) and
    Q_u (1e-2) off-target, f^r ≈ 7.1 N nearly holds the robot still against μ^f ≈ 8 N; with the
    target T = −10 N on at weight 1 it moves toward T by the closed-form amount."""
    flat_pos = flat_pos_gp()
    xi0 = [0.0, 0.0]
    mu0, grad = _field(flat_pos, 0.0)
    base = {"vel": 1e4, "f_ref": 1e-2}
    kw = {"f_ref_target": -10.0, **FROZEN}
    off = _solve([flat_pos], Weights(**base), xi0, **kw)
    on = _solve([flat_pos], Weights(**base, f_ref_target=1.0), xi0, **kw)
    _assert_linear(flat_pos, 0.0, np.r_[off.predicted[0, :, 0], on.predicted[0, :, 0]])
    _check_plan(off, _linear_plan(xi0, mu0, grad, vel=1e4, f_ref=1e-2), 2e-3)
    plan = _linear_plan(xi0, mu0, grad, vel=1e4, f_ref=1e-2, target_w=1.0, target=-10.0)
    _check_plan(on, plan, 2e-3)
    assert on.f_ref[0] < off.f_ref[0] - 5.0  # closed form (matched above): 7.1 -> −8.3 N
    # a flipped sign (−‖f^r − T‖²) would push f^r away from −10 N (up); fails.


def test_force_variance_weight_moves_the_plan_to_lower_variance() -> None:
    """Q_Σ,f on Σ^f (Eq. 14): starting 2 cm beyond the demonstrations, where Σ^f rises toward
    σ_n², the plan pushes back toward the data (−x) and ends where Σ^f is smaller."""
    patch = patch_gp()
    x0, w_sf = 0.02, 100.0
    xi0 = [x0, 0.0]
    mu0, grad = _field(patch, x0)

    def var(x: float) -> float:
        return float(patch.predict([[x]])[1][0, 0])

    slope = (var(x0 + 1e-6) - var(x0 - 1e-6)) / 2e-6  # ≈ 24 N²/m
    off = _solve([patch], Weights(vel=0.0, f_ref=1e-2), xi0, **FROZEN)
    on = _solve([patch], Weights(vel=0.0, f_ref=1e-2, force_var=w_sf), xi0, **FROZEN)
    # μ^f bends by ~1e-3 N over the plan: immaterial against the 15 % check on f^r below
    _assert_linear(patch, x0, np.r_[off.predicted[0, :, 0], on.predicted[0, :, 0]], tol=5e-3)
    f, states = _linear_plan(xi0, mu0, grad, f_ref=1e-2, var_slope=w_sf * slope)
    # Σ^f's slope steepens toward the data (checked here), so the linearised optimum (f^r
    # 14.9 N, x_H 1.1 mm closer to the data, Σ^f 0.03 N² lower) is a lower bound on the pull
    x_on = on.predicted[0, -1, 0]
    assert (var(x_on + 1e-6) - var(x_on - 1e-6)) / 2e-6 > slope
    assert f[0] <= on.f_ref[0] <= 1.15 * f[0]  # measured +8 % (curvature over 1.2 mm)
    assert x_on <= states[-1, 0] + 1e-6
    assert states[-1, 0] < off.predicted[0, -1, 0] - 1e-3  # the linear margin: 1.1 mm
    assert var(x_on) < var(off.predicted[0, -1, 0]) - 0.02
    # a flipped sign (−Q_Σ,f) would push away from the data (f^r < 0, larger Σ^f); fails.


def _variance_cost(dm_dd: np.ndarray, sig_f: float, pos_w: float, vel_w: float) -> float:
    """Eq. 8 from Σ_t = 0 with a pose-independent Σ^f, and Tr(Q_Σ Σ) summed over the horizon,
    plus Q_u on ΔM, ΔD (1 and 1e-4) for M_prev = 10 kg, D_prev = 1000 N s/m."""
    a, b = system_matrices([10.0 + dm_dd[0]], [1000.0 + dm_dd[1]], TS)
    sigma, cost = np.zeros((2, 2)), 0.0
    for _ in range(H):
        sigma = a @ sigma @ a.T + sig_f * b @ b.T
        cost += pos_w * sigma[0, 0] + vel_w * sigma[1, 1]
    return cost + dm_dd[0] ** 2 + 1e-4 * dm_dd[1] ** 2


def test_state_variance_weight_raises_impedance_not_f_ref() -> None:
    """Q_Σ (Eq. 14, trace form) far from the data, where Σ^f = σ_n² does not depend on pose.
    Seed B §5.1 (Eq. 21): f^r does not enter Σ, the impedance does. So (a) with M, D frozen,
    turning Q_Σ on leaves f^r and the plan unchanged; (b) with M, D free it raises both, to
    the numpy optimum of the same cost (ΔM ≈ +3.4 kg, ΔD ≈ +68 N s/m)."""
    patch = patch_gp()
    xi0 = [0.5, 0.0]  # 50 cm from the demonstrations: Σ^f = σ_n², μ^f = 0
    sig_f = float(patch.predict([[0.5]])[1][0, 0])
    assert sig_f == pytest.approx(patch.models[0].noise_var_, rel=1e-9)
    q_sigma = {"pos_var": 1e9, "vel_var": 1e7}
    imp = {"mass": [10.0], "damping": [1000.0]}
    # (a) f^r non-trivial: a target −10 N traded against Q_μ
    base = {"vel": 1e4, "f_ref_target": 1.0}
    kw = {"f_ref_target": -10.0, **FROZEN, **imp}
    off = _solve([patch], Weights(**base), xi0, **kw)
    on = _solve([patch], Weights(**base, **q_sigma), xi0, **kw)
    assert -10.0 < off.f_ref[0] < -1.0
    assert on.f_ref[0] == pytest.approx(off.f_ref[0], abs=1e-6)
    np.testing.assert_allclose(on.predicted, off.predicted, rtol=0.0, atol=1e-9)
    # (b) impedance free: M and D rise
    base = {"vel": 0.0, "delta_mass": 1.0, "delta_damping": 1e-4}
    off = _solve([patch], Weights(**base), xi0, **imp)
    on = _solve([patch], Weights(**base, **q_sigma), xi0, **imp)
    best = scipy.optimize.minimize(
        _variance_cost, [0.0, 0.0], args=(sig_f, 1e9, 1e7), method="L-BFGS-B",
        bounds=[(-5.0, 5.0), (-500.0, 500.0)],
    ).x  # fmt: skip
    assert off.mass[0] == pytest.approx(10.0, abs=1e-4)
    assert off.damping[0] == pytest.approx(1000.0, abs=1e-2)
    assert on.mass[0] - 10.0 == pytest.approx(best[0], rel=1e-2)
    assert on.damping[0] - 1000.0 == pytest.approx(best[1], rel=1e-2)
    assert on.mass[0] > off.mass[0] + 2.0 and on.damping[0] > off.damping[0] + 30.0
    assert on.f_ref[0] == pytest.approx(0.0, abs=1e-6)  # f^r has no lever on Σ: it stays
    # a flipped sign (−Q_Σ) would lower M and D to inflate Σ; fails (b).


def _h2(mass: float, damping: float, alpha: float = 1.0, omega: float = 2 * math.pi * 15) -> float:
    """‖X^d‖²₂ = α² / (2 D (M ω_p² + D ω_p)) of Eq. 16-17 with K = 0 (seed B §3.2 drops K)."""
    return alpha**2 / (2.0 * damping * (mass * omega**2 + damping * omega))


DIST = {"disturbance": {"alpha": 1.0, "omega_p": 2 * math.pi * 15}}


def test_disturbance_cost_raises_mass_and_damping() -> None:
    """Eq. 16-17: ‖X^d‖²₂ falls in both M and D, so with the cost on both rise, to the numpy
    optimum of w H ‖X^d‖²₂ + Q_u (ΔM² 0.1, ΔD² 1e-5): ΔM ≈ +1.4 kg, ΔD ≈ +416 N s/m."""
    flat_pos = flat_pos_gp()
    xi0, imp = [0.0, 0.0], {"mass": [10.0], "damping": [1000.0]}
    base = {"vel": 0.0, "delta_mass": 0.1, "delta_damping": 1e-5}
    off = _solve([flat_pos], Weights(**base), xi0, **imp, **DIST)
    on = _solve([flat_pos], Weights(**base, disturbance=1e9), xi0, **imp, **DIST)

    def cost(z: np.ndarray) -> float:  # the stage cost is constant: × H (problem.py)
        return 1e9 * H * _h2(10.0 + z[0], 1000.0 + z[1]) + 0.1 * z[0] ** 2 + 1e-5 * z[1] ** 2

    best = scipy.optimize.minimize(
        cost, [0.0, 0.0], method="L-BFGS-B", bounds=[(-5.0, 5.0), (-500.0, 500.0)]
    ).x
    assert off.mass[0] == pytest.approx(10.0, abs=1e-4)
    assert off.damping[0] == pytest.approx(1000.0, abs=1e-2)
    assert on.mass[0] - 10.0 == pytest.approx(best[0], rel=1e-2)
    assert on.damping[0] - 1000.0 == pytest.approx(best[1], rel=1e-2)
    assert on.mass[0] > off.mass[0] + 1.0 and on.damping[0] > off.damping[0] + 300.0
    # a flipped sign (−‖X^d‖²) would lower M and D; fails.


def test_impedance_change_weights_shrink_the_changes() -> None:
    """Q_u on ΔM, ΔD (Eq. 14) against the disturbance cost: without them ‖X^d‖²₂ is lowered
    as far as the rate limits allow (ΔM = 5 kg, ΔD = 500 N s/m); with them the changes are
    the interior optimum of the previous test (≈ 1.4 kg, 416 N s/m)."""
    flat_pos = flat_pos_gp()
    xi0, imp = [0.0, 0.0], {"mass": [10.0], "damping": [1000.0]}
    off = _solve([flat_pos], Weights(vel=0.0, disturbance=1e9), xi0, **imp, **DIST)
    w_on = Weights(vel=0.0, disturbance=1e9, delta_mass=0.1, delta_damping=1e-5)
    on = _solve([flat_pos], w_on, xi0, **imp, **DIST)
    assert off.mass[0] == pytest.approx(15.0, abs=1e-4)  # the rate limits delta_*_max
    assert off.damping[0] == pytest.approx(1500.0, abs=1e-2)
    assert on.mass[0] - 10.0 < 5.0 - 3.0  # ΔM: 5 -> 1.4 kg
    assert on.damping[0] - 1000.0 < 500.0 - 50.0  # ΔD: 500 -> 416 N s/m
    assert on.mass[0] > 10.0 and on.damping[0] > 1000.0  # smaller, not reversed
    # a flipped sign (−Q_u) would reward change: still at the rate limits; fails.


def test_belief_weights_the_modes_in_human_match() -> None:
    """Eq. 13: Σ_n b[n] c_n with human_match (seed B §4.2.1) and two modes, μ^f ≈ +8 N and
    ≈ −6 N. f^r_t minimises Σ_n b[n] (μ^f_n + f^r)² + (f^r)², so f^r_t = −Σ_n b[n] μ^f_n / 2:
    ≈ −4 N with belief [1, 0], ≈ +3 N with [0, 1], ≈ −0.5 N with [½, ½]; 0 with Q_H off."""
    flat_pos = flat_pos_gp()
    flat_neg = flat_neg_gp()
    xi0 = [0.0, 0.0]
    gps = [flat_pos, flat_neg]
    mus = [_field(g, 0.0)[0] for g in gps]
    kw = {"force_cost": "human_match", "f_ref_target": 0.0, **FROZEN}
    w_on = Weights(vel=0.0, f_ref_target=1.0, force=1.0)
    off = _solve(gps, Weights(vel=0.0, f_ref_target=1.0), xi0, belief=[1.0, 0.0], **kw)
    assert off.f_ref[0] == pytest.approx(0.0, abs=1e-4)
    sols = {}
    for b in ((1.0, 0.0), (0.0, 1.0), (0.5, 0.5)):
        sols[b] = _solve(gps, w_on, xi0, belief=b, **kw)
        # μ^f's slope is < 0.5 N/m here: the later steps shift f^r_t by < 1e-2 N
        assert sols[b].f_ref[0] == pytest.approx(-(b[0] * mus[0] + b[1] * mus[1]) / 2, abs=1e-2)
    for m, b in enumerate(((1.0, 0.0), (0.0, 1.0))):  # each believed mode's own plan, exactly
        mu0, grad = _field(gps[m], 0.0)
        plan = _linear_plan(xi0, mu0, grad, target_w=1.0, force=1.0, human_match=True)
        f, states = plan
        assert sols[b].f_ref[0] == pytest.approx(f[0], abs=2e-3)
        np.testing.assert_allclose(sols[b].predicted[m], states, rtol=0.0, atol=2e-3 * TS)
    # toward −μ^f of the believed mode: 7 N apart (half of μ^f_0 − μ^f_1 ≈ 14 N)
    assert sols[(0.0, 1.0)].f_ref[0] - sols[(1.0, 0.0)].f_ref[0] > 6.5
    # flipped belief weighting (or sign of Q_H) would swap or mirror the two f^r; fails.


def test_continuity_slack_bounds_the_deviation_from_eq7() -> None:
    """Eq. 13's ϱ: |μ_{τ+1} − f(μ_τ, u_τ)| ≤ ϱ element-wise. With f^r and M, D frozen and a
    velocity cost, ϱ = 0 keeps the plan on Eq. 7; ϱ = 1 mm/s lets the optimiser shave the
    predicted velocity by up to ϱ per step, and by no more."""
    wall = wall_gp()
    xi0, rho = [-0.02, 0.05], 1e-3  # 2 cm before the wall: μ^f ≈ c1, flat
    kw = {"f_ref_max": 1e-9, "f_ref_rate_max": 1e-9, **FROZEN}
    plans = {r: _solve([wall], Weights(vel=1.0), xi0, continuity_slack=r, **kw) for r in (0, rho)}
    a, b = system_matrices([5.0], [500.0], TS)
    devs = {}
    for r, sol in plans.items():
        p = sol.predicted[0]
        f_mu = wall.predict(p[:-1, :1])[0]  # (H, 1) μ^f at μ_0..μ_{H-1}
        devs[r] = p[1:] - (p[:-1] @ a.T + f_mu @ b.T)  # f^r ≈ 0 (bound 1e-9 N)
    assert np.max(np.abs(devs[0])) < 1e-9
    assert np.max(np.abs(devs[rho])) <= rho + 1e-8  # never beyond ϱ
    # the first step's slack lowers every later velocity: it sits at −ϱ (IPOPT's barrier gap
    # is 1.4e-6 of 1e-3 here, measured)
    assert devs[rho][0, 1] <= -0.99 * rho
    factor = 5.0 / (5.0 + TS * 500.0)  # M / (M + T_s D): how far a velocity change carries
    drop = plans[0].predicted[0, -1, 1] - plans[rho].predicted[0, -1, 1]
    assert 0.0 < drop <= rho * sum(factor**j for j in range(H)) + 1e-9
    # a slack ignored (ϱ treated as 0) fails the −0.99 ϱ check; an unbounded one the ≤ ϱ check.


# --------------------------------------------------------------------------- Eq. 15
