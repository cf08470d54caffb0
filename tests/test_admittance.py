"""Seed B Eq. 4-9 (issue #7): the semi-implicit admittance step and its mean/covariance
propagation, in numpy and casadi."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from ccm.control.mpc.admittance import covariance_step, mean_step, rollout, system_matrices
from ccm.core.errors import ConfigError

TS = 0.01


def test_implicit_step_never_oscillates() -> None:
    """Eq. 5's velocity factor M/(M + T_s D) is in (0, 1] for any D >= 0; explicit Euler's
    1 - T_s D/M goes negative (oscillates) once T_s D/M > 1 (seed B §3.2.1)."""
    for d in (0.0, 10.0, 500.0, 1e5):
        a, _ = system_matrices([2.0], [d], TS)
        assert 0.0 < a[1, 1] <= 1.0
        assert (1 - TS * d / 2.0 < 0) == (d > 200.0)


def test_steady_velocity_of_eq5_as_printed() -> None:
    """Under a constant force difference Eq. 5 settles at (f - f^r)/D (1 + T_s D/M): the
    continuous steady state of Eq. 4 is (f - f^r)/D, so the printed B = T_s M^-1 (not
    backward Euler's T_s (M + T_s D)^-1) is biased by T_s D/M (module docstring)."""
    m, d, f = 3.0, 30.0, 6.0
    a, b = system_matrices([m], [d], TS)
    xi = np.zeros(2)
    for _ in range(3000):
        xi = a @ xi + b @ np.array([f])
    assert xi[1] == pytest.approx(f / d * (1 + TS * d / m), rel=1e-9)
    assert xi[1] != pytest.approx(f / d, rel=0.05)


def test_covariance_step_equals_the_kronecker_form_eq9() -> None:
    rng = np.random.default_rng(0)
    a, b = system_matrices([2.0, 5.0], [40.0, 100.0], TS)
    r = rng.normal(size=(4, 4))
    sigma = r @ r.T
    var_f = np.array([0.3, 1.7])
    lhs = covariance_step(a, b, sigma, var_f).reshape(-1, order="F")
    rhs = np.kron(a, a) @ sigma.reshape(-1, order="F") + np.kron(b, b) @ np.diag(var_f).reshape(
        -1, order="F"
    )
    np.testing.assert_allclose(lhs, rhs, rtol=1e-12)


def test_casadi_and_numpy_agree_and_give_gradients_over_impedance() -> None:
    m, d = ca.MX.sym("m", 2), ca.MX.sym("d", 2)
    mu0, sig0 = np.array([0.1, 0.0, 0.05, 0.0]), np.diag([1e-6, 1e-6, 1e-4, 1e-4])

    def force(x):  # a spring at 0.12 m along the first axis, variance growing with depth
        lib = ca if isinstance(x, ca.MX) else np
        pen = lib.fmax(x[0] - 0.12, 0) if lib is ca else max(float(x[0]) - 0.12, 0.0)
        f_mu = lib.vertcat(-4.5e4 * pen, 0) if lib is ca else np.array([-4.5e4 * pen, 0.0])
        f_var = lib.vertcat(1.0 + 100 * pen, 1.0) if lib is ca else np.array([1.0 + 100 * pen, 1.0])
        return f_mu, f_var

    mus, sigs = rollout(m, d, TS, ca.DM(mu0), ca.DM(sig0), ca.DM([5.0, 0.0]), force, 20)
    fn = ca.Function("f", [m, d], [mus[-1], ca.trace(sigs[-1])])
    cost_grad = ca.Function("g", [m, d], [ca.gradient(ca.trace(sigs[-1]), ca.vertcat(m, d))])
    mus_np, sigs_np = rollout([4.0, 4.0], [80.0, 80.0], TS, mu0, sig0, np.array([5.0, 0.0]),
                              force, 20)  # fmt: skip
    out_mu, out_tr = fn([4.0, 4.0], [80.0, 80.0])
    np.testing.assert_allclose(np.array(out_mu).ravel(), mus_np[-1], rtol=1e-10, atol=1e-14)
    assert float(out_tr) == pytest.approx(np.trace(sigs_np[-1]), rel=1e-10)
    g = np.array(cost_grad([4.0, 4.0], [80.0, 80.0])).ravel()
    assert np.all(np.isfinite(g)) and g.shape == (4,)


def test_bad_parameters_name_the_key() -> None:
    with pytest.raises(ConfigError, match="admittance.mass"):
        system_matrices([0.0], [1.0], TS)
    with pytest.raises(ConfigError, match="admittance.damping"):
        system_matrices([1.0], [-1.0], TS)
    with pytest.raises(ConfigError, match="admittance.ts"):
        system_matrices([1.0], [1.0], 0.0)
    with pytest.raises(ConfigError, match="admittance.damping"):
        system_matrices([1.0, 2.0], [1.0], TS)


def test_mean_step_is_eq7() -> None:
    a, b = system_matrices([2.0], [20.0], TS)
    mu = np.array([0.0, 0.1])
    np.testing.assert_allclose(mean_step(a, b, mu, np.array([3.0]), np.array([1.0])),
                               a @ mu + b @ np.array([2.0]))  # fmt: skip


def test_a_reference_per_step_is_applied_at_its_step() -> None:
    """``f_ref`` as a list gives f^r_k at step k of Eq. 7 (the held form repeats one)."""

    def free(_x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # no contact force
        return np.zeros(2), np.ones(2)

    refs = [np.array([2.0, 0.0]), np.array([0.0, -3.0]), np.array([1.0, 1.0])]
    args = ([4.0, 4.0], [80.0, 80.0], TS, np.zeros(4), np.zeros((4, 4)))
    mus, _ = rollout(*args, refs, free, 3)
    a, b = system_matrices([4.0, 4.0], [80.0, 80.0], TS)
    mu = np.zeros(4)
    for k, fr in enumerate(refs):
        mu = a @ mu + b @ (np.zeros(2) - fr)  # Eq. 7 with μ^f = 0
        np.testing.assert_allclose(mus[k + 1], mu, rtol=1e-12, atol=1e-15)
    held, _ = rollout(*args, refs[0], free, 3)
    assert not np.allclose(held[-1], mus[-1])
