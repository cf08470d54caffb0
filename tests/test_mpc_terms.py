"""Seed B's MPC terms (issue #7): human arm and joint-torque cost (Eq. 10, 11, 15), the
disturbance H2 cost (Eq. 16-17), the mode belief (Eq. 12) and the chance quantile (Eq. 18)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.signal
import scipy.special
import scipy.stats

from ccm.control.mpc.terms import (
    FOREARM,
    UPPER_ARM,
    arm_fk,
    arm_ik,
    arm_jacobian,
    belief_update,
    chance_margin,
    chance_quantile,
    disturbance_h2,
    disturbance_state_space,
    h2_norm_sq,
    joint_torque_cost,
)
from ccm.core.errors import ConfigError

SH = np.array([0.1, -0.2, 1.4])  # a shoulder somewhere in the world
L = UPPER_ARM + FOREARM
OMEGA = 2 * math.pi * 15


# --- arm (Eq. 10, 11, 15) ---------------------------------------------------------------


def test_fk_joint_conventions() -> None:
    """x forward, y left, z up; right arm hanging at q = 0 (module docstring)."""
    np.testing.assert_allclose(arm_fk([0, 0, 0, 0], SH), SH + [0, 0, -L], atol=1e-12)
    np.testing.assert_allclose(arm_fk([np.pi / 2, 0, 0, 0], SH), SH + [L, 0, 0], atol=1e-12)
    np.testing.assert_allclose(arm_fk([0, np.pi / 2, 0, 0], SH), SH + [0, -L, 0], atol=1e-12)
    elbow_bent = SH + [FOREARM, 0, -UPPER_ARM]
    np.testing.assert_allclose(arm_fk([0, 0, 0, np.pi / 2], SH), elbow_bent, atol=1e-12)
    turned_in = arm_fk([0, 0, np.pi / 2, np.pi / 2], SH)  # internal rotation: towards +y
    np.testing.assert_allclose(turned_in, SH + [0, FOREARM, -UPPER_ARM], atol=1e-12)
    assert arm_fk([0, 0, 1.0, 0], SH) == pytest.approx(SH + [0, 0, -L])  # no lever if straight


def test_jacobian_matches_finite_differences_and_casadi() -> None:
    rng = np.random.default_rng(1)
    q_sym = ca.SX.sym("q", 4)
    jac_ad = ca.Function("j", [q_sym], [ca.jacobian(arm_fk(q_sym, SH), q_sym)])
    jac_sym = ca.Function("j", [q_sym], [arm_jacobian(q_sym, SH)])
    for _ in range(10):
        q = rng.uniform(-2, 2, size=4)
        fd = np.column_stack(
            [(arm_fk(q + 1e-6 * e, SH) - arm_fk(q - 1e-6 * e, SH)) / 2e-6 for e in np.eye(4)]
        )
        jac = arm_jacobian(q, SH)
        assert jac.shape == (3, 4)
        np.testing.assert_allclose(jac, fd, atol=1e-8)
        np.testing.assert_allclose(np.array(jac_sym(q)), jac, atol=1e-12)
        np.testing.assert_allclose(np.array(jac_ad(q)), jac, atol=1e-12)


def test_ik_inverts_fk_with_zero_internal_rotation() -> None:
    rng = np.random.default_rng(2)
    for _ in range(50):  # hand below the shoulder: IK returns the same branch
        q = np.array([rng.uniform(-0.5, 1.2), rng.uniform(-0.4, 1.2), 0.0, rng.uniform(0.1, 2.3)])
        x = arm_fk(q, SH)
        if x[2] > SH[2] - 0.05:
            continue
        q_ik = arm_ik(x, SH)
        np.testing.assert_allclose(q_ik, q, atol=1e-9)
    for _ in range(50):  # any reachable point, any branch: the hand lands on x
        x = SH + rng.normal(size=3) * 0.3
        if not abs(UPPER_ARM - FOREARM) < np.linalg.norm(x - SH) < L:
            continue
        q_ik = arm_ik(x, SH)
        assert q_ik[2] == 0.0
        np.testing.assert_allclose(arm_fk(q_ik, SH), x, atol=1e-9)


def test_ik_clips_the_reach_along_the_hand_direction() -> None:
    direction = np.array([0.6, -0.3, -0.74])
    direction /= np.linalg.norm(direction)
    for dist, expect in ((2.0, L), (0.01, abs(UPPER_ARM - FOREARM))):
        q = arm_ik(SH + dist * direction, SH)
        hand = arm_fk(q, SH)
        assert np.linalg.norm(hand - SH) == pytest.approx(expect, abs=1e-5)  # elbow eps 1e-3
        np.testing.assert_allclose((hand - SH) / np.linalg.norm(hand - SH), direction, atol=1e-9)


def test_ik_casadi_matches_numpy_and_has_finite_gradients() -> None:
    x_sym = ca.MX.sym("x", 3)
    q_sym = arm_ik(x_sym, SH)
    fun = ca.Function("ik", [x_sym], [q_sym, ca.jacobian(q_sym, x_sym)])
    for x in (SH + [0.4, -0.1, -0.3], SH + [0.2, 0.2, -0.5], SH + [1.5, 0.0, -0.2]):
        q, dq = fun(x)
        np.testing.assert_allclose(np.array(q).ravel(), arm_ik(x, SH), atol=1e-12)
        assert np.all(np.isfinite(np.array(dq)))


def test_joint_torque_cost_eq15() -> None:
    x, f = SH + [0.4, -0.15, -0.3], np.array([10.0, -4.0, 3.0])
    jac = arm_jacobian(arm_ik(x, SH), SH)
    q_tau = np.diag([1.0, 2.0, 0.5, 3.0])
    expected = f @ jac @ q_tau @ jac.T @ f
    assert joint_torque_cost(x, f, q_tau, SH) == pytest.approx(expected, rel=1e-12)
    assert joint_torque_cost(x, f, np.diag(q_tau), SH) == pytest.approx(expected, rel=1e-12)
    scalar = f @ jac @ jac.T @ f
    assert joint_torque_cost(x, f, 1.0, SH) == pytest.approx(scalar, rel=1e-12)
    assert joint_torque_cost(x, np.zeros(3), q_tau, SH) == 0.0
    with pytest.raises(ConfigError, match="q_tau"):
        joint_torque_cost(x, f, np.eye(3), SH)
    # casadi: the position and a damping force f_H = D xdot (seed B polishing) are symbols
    xs, d = ca.MX.sym("x", 3), ca.MX.sym("d", 3)
    xdot = np.array([0.1, -0.04, 0.03])
    cost = ca.Function("c", [xs, d], [joint_torque_cost(xs, d * xdot, ca.DM(q_tau), SH)])
    assert float(cost(x, f / xdot)) == pytest.approx(expected, rel=1e-10)


def test_holding_a_weight_farther_forward_costs_more() -> None:
    """Sagittal plane, vertical force: the flexion torque is exactly r_x f_z."""
    f = np.array([0.0, 0.0, -20.0])
    costs = []
    for reach in (0.2, 0.3, 0.4, 0.5, 0.57):  # all within l1 + l2 of the shoulder
        x = SH + [reach, 0.0, -0.3]
        tau = arm_jacobian(arm_ik(x, SH), SH).T @ f
        assert tau[0] == pytest.approx(reach * f[2], rel=1e-9)
        costs.append(joint_torque_cost(x, f, 1.0, SH))
    assert np.all(np.diff(costs) > 0)


# --- disturbance rejection (Eq. 16-17) --------------------------------------------------

CASES = [(1.0, 50.0, 0.0), (5.0, 300.0, 0.0), (20.0, 2000.0, 0.0), (5.0, 300.0, 2000.0)]


@pytest.mark.parametrize(("m", "d", "k"), CASES)
def test_h2_closed_form_equals_the_observability_gramian(m: float, d: float, k: float) -> None:
    a, b, c = disturbance_state_space(m, d, k, 1.3, OMEGA)
    x_o = scipy.linalg.solve_continuous_lyapunov(a.T, -c.T @ c)  # A^T X + X A = -C^T C
    ref = (b.T @ x_o @ b).item()
    assert disturbance_h2(m, d, k, 1.3, OMEGA) == pytest.approx(ref, rel=1e-9)
    assert disturbance_h2(m, d, k, 1.3, OMEGA, method="lyapunov") == pytest.approx(ref, rel=1e-9)
    assert h2_norm_sq(a, b, c) == pytest.approx(ref, rel=1e-9)


@pytest.mark.parametrize(("m", "d", "k"), CASES)
def test_h2_equals_the_energy_of_the_impulse_response(m: float, d: float, k: float) -> None:
    """Parseval: the un-cancelled X^d(s) = α s / ((s + ω_p)(M s² + D s + K))."""
    alpha = 1.3
    den = np.polymul([1.0, OMEGA], [m, d, k])
    slowest = np.abs(np.roots(den).real).min()  # K = 0: the cancelled pole at 0 is skipped
    slowest = slowest if slowest > 0 else min(OMEGA, d / m)
    t = np.linspace(0.0, 15.0 / slowest, 200_001)
    _, y = scipy.signal.impulse(([alpha, 0.0], den), T=t)
    energy = scipy.integrate.trapezoid(y**2, t)
    assert disturbance_h2(m, d, k, alpha, OMEGA) == pytest.approx(energy, rel=0.01)


def test_printed_eq17_gives_a_negative_norm() -> None:
    """Seed B prints A X + X A^T = C^T C; with a stable A that yields B^T X B < 0."""
    a, b, c = disturbance_state_space(5.0, 300.0, 0.0, 1.0, OMEGA)
    x_printed = scipy.linalg.solve_continuous_lyapunov(a, c.T @ c)
    assert (b.T @ x_printed @ b).item() < 0 < disturbance_h2(5.0, 300.0, 0.0, 1.0, OMEGA)


@pytest.mark.parametrize("method", ["closed_form", "lyapunov"])
@pytest.mark.parametrize("k", [0.0, 2000.0])
def test_h2_casadi_value_and_gradient(method: str, k: float) -> None:
    m, d = ca.MX.sym("m"), ca.MX.sym("d")
    cost = disturbance_h2(m, d, k, 1.0, OMEGA, method=method)
    fun = ca.Function("h2", [m, d], [cost, ca.gradient(cost, ca.vertcat(m, d))])
    for m0, d0 in ((1.0, 50.0), (5.0, 300.0), (20.0, 2000.0)):
        val, grad = fun(m0, d0)
        assert float(val) == pytest.approx(disturbance_h2(m0, d0, k, 1.0, OMEGA), rel=1e-9)
        hm, hd = 1e-6 * m0, 1e-6 * d0
        fd_m = (disturbance_h2(m0 + hm, d0, k) - disturbance_h2(m0 - hm, d0, k)) / (2 * hm)
        fd_d = (disturbance_h2(m0, d0 + hd, k) - disturbance_h2(m0, d0 - hd, k)) / (2 * hd)
        np.testing.assert_allclose(np.array(grad).ravel(), [fd_m, fd_d], rtol=1e-5)


def test_symbolic_stiffness_uses_three_states() -> None:
    k = ca.MX.sym("k")
    cost = disturbance_h2(5.0, 300.0, k, 1.0, OMEGA, method="lyapunov")
    fun = ca.Function("h2", [k], [cost])
    assert float(fun(800.0)) == pytest.approx(disturbance_h2(5.0, 300.0, 800.0), rel=1e-9)


def test_more_impedance_rejects_more_disturbance() -> None:
    m, d = ca.MX.sym("m"), ca.MX.sym("d")
    cost = disturbance_h2(m, d, 0.0, 1.0, OMEGA)
    grad = ca.Function("g", [m, d], [ca.gradient(cost, ca.vertcat(m, d))])
    for m0 in np.linspace(1.0, 20.0, 5):
        for d0 in np.geomspace(50.0, 2000.0, 5):
            dm, dd = np.array(grad(m0, d0)).ravel()
            assert dm < 0 and dd < 0


def test_h2_rejects_bad_parameters() -> None:
    for args in ((0.0, 300.0, 0.0), (5.0, 0.0, 0.0), (5.0, 300.0, -1.0)):
        with pytest.raises(ConfigError):
            disturbance_h2(*args)
    with pytest.raises(ConfigError, match="omega_p"):
        disturbance_h2(5.0, 300.0, omega_p=0.0)
    with pytest.raises(ConfigError, match="method"):
        disturbance_h2(5.0, 300.0, method="bartels")


# --- mode belief (Eq. 12) ---------------------------------------------------------------

MEANS = np.array([[10.0, 0.0], [-10.0, 0.0]])
VARS = np.array([[4.0, 4.0], [4.0, 4.0]])


def test_belief_goes_to_the_mode_that_explains_the_force() -> None:
    rng = np.random.default_rng(3)
    b = np.array([0.5, 0.5])
    for _ in range(3):
        b = belief_update(b, MEANS[1] + rng.normal(size=2) * 2.0, MEANS, VARS)
    assert b[1] > 0.999
    assert b.sum() == pytest.approx(1.0)


def test_belief_is_bayes_with_the_gaussian_likelihood() -> None:
    b, f = np.array([0.2, 0.3, 0.5]), np.array([1.0, -2.0])
    means = np.array([[0.0, 0.0], [1.5, -1.0], [3.0, 3.0]])
    variances = np.array([[1.0, 2.0], [0.5, 4.0], [9.0, 1.0]])
    lik = [
        scipy.stats.multivariate_normal.pdf(f, m, np.diag(v))
        for m, v in zip(means, variances, strict=True)
    ]
    expected = b * lik / np.sum(b * lik)
    np.testing.assert_allclose(belief_update(b, f, means, variances), expected, rtol=1e-12)


def test_equal_likelihoods_leave_the_belief_unchanged() -> None:
    b = np.array([0.1, 0.6, 0.3])
    means, variances = np.tile([1.0, 2.0], (3, 1)), np.tile([0.5, 3.0], (3, 1))
    np.testing.assert_allclose(belief_update(b, [7.0, -3.0], means, variances), b, rtol=1e-12)


def test_belief_is_underflow_safe() -> None:
    b = belief_update([0.5, 0.5], [1e6, 1e6], MEANS, np.full((2, 2), 1e-4))
    assert np.all(np.isfinite(b)) and b.sum() == pytest.approx(1.0)
    assert b[0] == 1.0  # mode 0's mean is (slightly) closer


def test_min_belief_floors_and_lets_a_mode_recover() -> None:
    floor = 0.02
    b_bayes = b_floor = np.array([0.5, 0.5])
    for _ in range(20):  # the human heads for mode 0 a long while
        b_bayes = belief_update(b_bayes, MEANS[0] * 8, MEANS, VARS)
        b_floor = belief_update(b_floor, MEANS[0] * 8, MEANS, VARS, min_belief=floor)
        assert np.all(b_floor >= floor - 1e-15) and b_floor.sum() == pytest.approx(1.0)
    assert b_bayes[1] == 0.0  # pure Bayes: underflowed, cannot come back
    for _ in range(3):  # then switches to mode 1
        b_bayes = belief_update(b_bayes, MEANS[1], MEANS, VARS)
        b_floor = belief_update(b_floor, MEANS[1], MEANS, VARS, min_belief=floor)
    assert b_floor[1] == pytest.approx(1 - floor) and b_bayes[1] == 0.0
    b = belief_update(np.full(4, 0.25), [0.0], [[0.0], [5.0], [9.0], [20.0]], np.ones((4, 1)), 0.1)
    assert np.all(b >= 0.1 - 1e-15) and b.sum() == pytest.approx(1.0) and b[0] == b.max()


@pytest.mark.parametrize(
    ("belief", "f", "means", "variances", "floor", "match"),
    [
        ([0.5, 0.5], [0.0], MEANS, VARS, 0.0, "needs belief"),
        ([0.5, 0.6], [0.0, 0.0], MEANS, VARS, 0.0, "probability"),
        ([1.5, -0.5], [0.0, 0.0], MEANS, VARS, 0.0, "probability"),
        ([0.5, 0.5], [0.0, 0.0], MEANS, VARS * 0, 0.0, "variances"),
        ([0.5, 0.5], [np.nan, 0.0], MEANS, VARS, 0.0, "finite"),
        ([0.5, 0.5], [0.0, 0.0], MEANS, VARS, 0.6, "min_belief"),
    ],
)
def test_belief_validates_inputs(belief, f, means, variances, floor, match) -> None:
    with pytest.raises(ConfigError, match=match):
        belief_update(belief, f, means, variances, min_belief=floor)


# --- chance constraint (Eq. 18) ---------------------------------------------------------


def test_chance_quantile_numbers() -> None:
    assert chance_quantile(0.5) == pytest.approx(0.0, abs=1e-12)
    assert chance_quantile(0.5, "paper_erfinv") == pytest.approx(0.4769362762, rel=1e-9)
    assert chance_quantile(0.05) == pytest.approx(1.6448536270, rel=1e-9)
    assert chance_quantile(0.05, "paper_erfinv") == pytest.approx(1.3859038243, rel=1e-9)
    for eps in (0.01, 0.1, 0.3, 0.7):
        q = chance_quantile(eps)
        assert q == pytest.approx(math.sqrt(2) * scipy.special.erfinv(1 - 2 * eps), rel=1e-9)
        assert scipy.stats.norm.cdf(q) == pytest.approx(1 - eps, rel=1e-12)
        paper = chance_quantile(eps, "paper_erfinv")
        assert paper == pytest.approx(scipy.special.erfinv(1 - eps), rel=1e-9)


@pytest.mark.parametrize("eps", [0.0, 1.0, -0.1, 2.0])
def test_chance_quantile_rejects_bad_epsilon(eps: float) -> None:
    with pytest.raises(ConfigError, match="epsilon"):
        chance_quantile(eps)


def test_chance_margin_numpy_and_casadi() -> None:
    mean, var = np.array([5.0, 11.0]), np.array([4.0, 1.0])
    margin = chance_margin(mean, var, 12.0, 0.05)
    np.testing.assert_allclose(margin, 12.0 - mean - 1.6448536270 * np.sqrt(var), rtol=1e-9)
    mu = ca.MX.sym("mu", 2)
    fun = ca.Function("m", [mu], [chance_margin(mu, ca.DM(var), 12.0, 0.05)])
    np.testing.assert_allclose(np.array(fun(mean)).ravel(), margin, rtol=1e-12)
    with pytest.raises(ConfigError, match="quantile"):
        chance_quantile(0.1, "erf")


def test_the_arm_settings_reach_the_joint_torque_term() -> None:
    """Eq. 11/15's arm: each given key is used (the TCP height z too), the defaults are the
    documented ones, and an unknown key is refused by name."""
    from ccm.control.mpc.settings import MPCSettings

    arm = {"shoulder": [0.1, -0.5, 0.2], "l1": 0.28, "l2": 0.33, "z": 0.15, "velocity": "predicted"}
    jt = MPCSettings.parse({"joint_torque": arm}).joint_torque
    assert jt is not None
    np.testing.assert_array_equal(jt.shoulder, [0.1, -0.5, 0.2])
    assert (jt.l1, jt.l2, jt.z, jt.velocity) == (0.28, 0.33, 0.15, "predicted")
    default = MPCSettings.parse({"joint_torque": {"l1": 0.3}}).joint_torque
    np.testing.assert_array_equal(default.shoulder, [0.0, -0.4, 0.3])
    assert (default.l2, default.z, default.velocity) == (0.35, 0.0, "measured")
    with pytest.raises(ConfigError) as info:
        MPCSettings.parse({"joint_torque": {"elbow": 1.0}})
    assert info.value.key.startswith("controller.mpc.joint_torque")
    with pytest.raises(ConfigError) as info:
        MPCSettings.parse({"force_cost": "max"})
    assert info.value.key == "controller.mpc.force_cost"


def test_h2_refusal_names_both_parameters() -> None:
    with pytest.raises(ConfigError) as err:
        disturbance_h2(0.0, 300.0)
    assert str(err.value) == "mpc.disturbance: needs M, D > 0, got M=0.0, D=300.0"


def test_joint_torque_weights_of_every_accepted_shape_agree() -> None:
    """Q_τ as a scalar, (1,), (1, 1), a diagonal (4,) or (4, 1), or the (4, 4) matrix: the
    same cost for the same weights (Eq. 15)."""
    x, f, sh = np.array([0.4, 0.1, 0.3]), np.array([2.0, -1.0, 0.5]), np.zeros(3)
    scalar = joint_torque_cost(x, f, 2.0, sh)
    for q in (np.array([2.0]), np.array([[2.0]]), np.full(4, 2.0), np.full((4, 1), 2.0),
              2.0 * np.eye(4)):  # fmt: skip
        assert joint_torque_cost(x, f, q, sh) == pytest.approx(scalar, rel=1e-12)
    with pytest.raises(ConfigError) as err:
        joint_torque_cost(x, f, np.ones((2, 1)), sh)
    assert str(err.value) == "arm.q_tau: must be a scalar, (4,) or (4, 4), got shape (2, 1)"


def test_chance_quantile_errors_carry_the_mpc_key() -> None:
    with pytest.raises(ConfigError) as err:
        chance_quantile(1.5)
    assert str(err.value) == "mpc.chance.epsilon: must be in (0, 1), got 1.5"


def test_a_hand_force_of_the_wrong_size_is_one_line() -> None:
    with pytest.raises(ConfigError) as err:
        joint_torque_cost(np.array([0.4, 0.1, 0.3]), np.array([1.0, 2.0]), 1.0, np.zeros(3))
    assert str(err.value) == "arm.f_hand: must have 3 entries, got shape (2,)"


def test_belief_floor_rescales_until_no_mode_is_below_it() -> None:
    """``min_belief`` 0.3 on b = [0.6, 0.35, 0.05] with equal likelihoods: flooring the third
    (rest 0.7 over 0.95) drops the second to 0.258, so it is floored too: [0.4, 0.3, 0.3]. A
    floor of exactly 1/N is allowed and makes the belief uniform."""
    b, f, mu, var = [0.6, 0.35, 0.05], [1.0], [[0.0]] * 3, [[1.0]] * 3
    np.testing.assert_allclose(belief_update(b, f, mu, var), b, rtol=1e-12)
    np.testing.assert_allclose(belief_update(b, f, mu, var, min_belief=0.3), [0.4, 0.3, 0.3],
                               rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(belief_update(b, f, mu, var, min_belief=1 / 3), [1 / 3] * 3)


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (([], [1.0], [], []), "mpc.belief: needs belief (N,), f (d,), means and variances "
                              "(N, d); got (0,), (1,), (1, 0), (1, 0)"),
        (([1.0], [np.nan], [[0.0]], [[1.0]]), "mpc.belief: f, means and variances must be finite"),
        (([1.0], [0.0], [[0.0]], [[0.0]]), "mpc.belief.variances: must be > 0, got min 0.0"),
        (([0.5, 0.6], [0.0], [[0.0]] * 2, [[1.0]] * 2),
         "mpc.belief: must be a probability vector, got [0.5, 0.6]"),
        (([0.5, 0.5], [0.0], [[0.0]] * 2, [[1.0]] * 2, 0.6),
         "mpc.belief.min_belief: must be in [0, 1/N], got 0.6"),
    ],
)  # fmt: skip
def test_belief_update_refusals_are_whole_lines(args: tuple, line: str) -> None:
    with pytest.raises(ConfigError) as err:
        belief_update(*args)
    assert str(err.value) == line
