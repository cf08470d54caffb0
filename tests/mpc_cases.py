"""Shared cases of the Eq. 13-20 on/off tests (``test_mpc_terms_on_off.py`` and
``test_mpc_constraints_on_off.py``): seeded GP fixtures, the solve helper and the closed-form
plan that the tests compare the MPC's solution with (issue #37).

* ``_linear_plan``: with M, D fixed and a GP mean that is linear in the pose over the few
  millimetres the plan travels (asserted in each test), Eq. 7 makes the predicted states
  affine in f^r and Eq. 14 quadratic, so its optimum is one linear solve, computed here
  independently of ccm's problem code.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import pytest

from ccm.control.mpc.admittance import system_matrices
from ccm.control.mpc.problem import GPMPCProblem, MPCSolution
from ccm.control.mpc.settings import Weights
from ccm.learn.gp.gp_force_models import GPForceModels

TS, H = 0.01, 5
# Generous f^r bound and rate limit unless a test says otherwise, so that the closed-form
# optima below (which ignore bounds) apply; each such test asserts its f^r stays inside.
F_LIM = 100.0
K_WALL = 45000.0  # N/m, seed B's medium environment (as in test_gp_mpc.py)


# ------------------------------------------------- the GPs (fitted once per process)
def _line(lo: float, hi: float, n: int) -> np.ndarray:
    return np.linspace(lo, hi, n)[:, None]


@functools.cache
def flat_pos() -> GPForceModels:
    """1-D, μ^f ≈ +8 N everywhere near 0 (a steady human push along +x)."""
    x = _line(-0.1, 0.1, 15)
    f = 8.0 + np.random.default_rng(0).normal(0.0, 0.05, x.shape)
    return GPForceModels(1, mean="zero", n_restarts=1).fit(x, f)


@functools.cache
def flat_neg() -> GPForceModels:
    """1-D, μ^f ≈ -6 N (the other mode of the belief test: a pull along -x)."""
    x = _line(-0.1, 0.1, 15)
    f = -6.0 + np.random.default_rng(1).normal(0.0, 0.05, x.shape)
    return GPForceModels(1, mean="zero", n_restarts=1).fit(x, f)


@functools.cache
def ramp() -> GPForceModels:
    """1-D, μ^f ≈ 2 − 300 x N: a spring-like force that vanishes at x ≈ 6.7 mm."""
    x = _line(-0.1, 0.1, 15)
    f = 2.0 - 300.0 * x + np.random.default_rng(2).normal(0.0, 0.05, x.shape)
    return GPForceModels(1, mean="zero", n_restarts=1).fit(x, f)


@functools.cache
def wall() -> GPForceModels:
    """1-D push into a 45 kN/m wall at x = 0 (hinge mean, Eq. 1-2 as printed: tied σ_n²)."""
    x = np.r_[np.linspace(-0.08, 0.0, 20), np.linspace(0.0, 8e-4, 10)][:, None]
    f = np.random.default_rng(3).normal(0.0, 1.0, x.shape) - K_WALL * np.maximum(0.0, x)
    return GPForceModels(1, mean="hinge", hinge_form="smooth", variance="tied", n_restarts=1).fit(
        x, f
    )


@functools.cache
def patch() -> GPForceModels:
    """1-D, demonstrations only on x ∈ [-0.1, 0] (tied σ_n², Eq. 1-2): Σ^f rises from the
    data's scatter to σ_n² beyond x = 0 (seed B §4.3.1: it 'reverts to a baseline variance')."""
    x = _line(-0.1, 0.0, 12)
    f = 3.0 * np.sin(2 * np.pi * x / 0.1) + np.random.default_rng(4).normal(0.0, 0.3, x.shape)
    return GPForceModels(1, mean="zero", variance="tied", n_restarts=1).fit(x, f)


HAND = np.array([0.3, 0.0])  # TCP in front of joint_torque's default shoulder (0, -0.4, 0.3)


@functools.cache
def free2() -> GPForceModels:
    """2-D, ≈ zero force around HAND (free motion)."""
    rng = np.random.default_rng(5)
    x = HAND + rng.uniform(-0.05, 0.05, (20, 2))
    return GPForceModels(2, mean="zero", n_restarts=0).fit(x, rng.normal(0.0, 0.1, (20, 2)))


# --------------------------------------------------------------------------- helpers
def _solve(
    gps: Sequence[GPForceModels],
    weights: Weights,
    xi0: Sequence[float],
    *,
    belief: Sequence[float] | None = None,
    mass: Sequence[float] = (5.0,),
    damping: Sequence[float] = (500.0,),
    **kw: object,
) -> MPCSolution:
    """A fresh problem (cold start) solved once; M_prev, D_prev per DOF, f^r_prev = 0."""
    n = len(xi0) // 2
    settings = {"horizon": H, "ts": TS, "f_ref_max": F_LIM, "f_ref_rate_max": F_LIM, **kw}
    prob = GPMPCProblem([g.casadi_functions() for g in gps], n, weights=weights, **settings)
    sol = prob.solve(xi0, belief or [1.0] + [0.0] * (len(gps) - 1), mass, damping, [0.0] * n)
    assert sol.success, sol.status
    return sol


FROZEN = {"delta_mass_max": 0.0, "delta_damping_max": 0.0}  # M, D held: f^r is the only lever


def _field(gp: GPForceModels, x0: float) -> tuple[float, float]:
    """μ^f and dμ^f/dx of a 1-D GP at x0 (numpy, not the casadi graph the MPC uses)."""
    return float(gp.predict([[x0]])[0][0, 0]), float(gp.models[0].mean_gradient([x0])[0])


def _assert_linear(gp: GPForceModels, x0: float, poses: np.ndarray, tol: float = 1e-3) -> None:
    """The GP mean departs from its tangent at x0 by < tol N over the plan's poses, so the
    linear-field optimum of ``_linear_plan`` applies to within about tol."""
    mu0, grad = _field(gp, x0)
    mu = gp.predict(poses[:, None])[0][:, 0]
    assert np.max(np.abs(mu - mu0 - grad * (poses - x0))) < tol


def _linear_plan(
    xi0: Sequence[float],
    mu0: float,
    grad: float,
    *,
    mass: float = 5.0,
    damping: float = 500.0,
    vel: float = 0.0,
    force: float = 0.0,
    human_match: bool = False,
    f_ref: float = 0.0,
    target_w: float = 0.0,
    target: float = 0.0,
    var_slope: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The optimum of Eq. 13-14 for one DOF and one mode with M, D fixed, μ^f(x) = mu0 +
    grad (x − x_t) and (optionally) a GP variance cost linear in x with slope ``var_slope``
    (Q_Σ,f times dΣ^f/dx). Eq. 7 gives ξ_k = c_k + G_k f^r; each term of Eq. 14 is a square of
    an affine function of f^r (or linear in it), so the minimiser solves one linear system.

    Returns:
        f^r (H,) and the predicted means (H + 1, 2).
    """
    a, b = system_matrices([mass], [damping], TS)
    b = b[:, 0]
    x0 = xi0[0]
    a_f = a + np.outer(b, [grad, 0.0])  # μ^f's slope acts like a spring in Eq. 7
    c, g = [np.asarray(xi0, float)], [np.zeros((2, H))]
    for k in range(H):
        g_next = a_f @ g[-1]
        g_next[:, k] -= b
        c.append(a_f @ c[-1] + b * (mu0 - grad * x0))
        g.append(g_next)
    eye = np.eye(H)
    squares = []  # (weight, constant, row): weight (constant + row · f)²
    for k in range(H):
        squares.append((vel, c[k + 1][1], g[k + 1][1]))  # Q_μ on ẋ_{k+1}
        if human_match:  # (μ^f(x_k) + f^r_k)² (seed B §4.2.1)
            squares.append((force, mu0 + grad * (c[k][0] - x0), grad * g[k][0] + eye[k]))
        else:  # μ^f(x_{k+1})²
            squares.append((force, mu0 + grad * (c[k + 1][0] - x0), grad * g[k + 1][0]))
        squares.append((f_ref, 0.0, eye[k]))
        squares.append((target_w, -target, eye[k]))
    hess = sum(2.0 * w * np.outer(r, r) for w, _, r in squares)
    lin = sum(2.0 * w * c0 * r for w, c0, r in squares)
    lin = lin + var_slope * sum(g[k + 1][0] for k in range(H))
    f = np.linalg.solve(hess, -lin)
    return f, np.array([ck + gk @ f for ck, gk in zip(c, g, strict=True)])


def _check_plan(sol: MPCSolution, plan: tuple[np.ndarray, np.ndarray], tol: float) -> None:
    """IPOPT's f^r_t and predicted means equal the closed-form optimum. Tolerance ``tol`` [N]
    on f^r: IPOPT's tol is 1e-6 and the GP's departure from linear is < 1e-3 N (asserted by
    the caller); an f^r error δ moves ẋ by at most H T_s δ / M = T_s δ (H = 5, M = 5 kg)."""
    f, states = plan
    assert np.all(np.abs(f) < F_LIM)  # the closed form ignores the f^r bound: it must not bind
    assert sol.f_ref[0] == pytest.approx(f[0], abs=tol)
    np.testing.assert_allclose(sol.predicted[0], states, rtol=0.0, atol=tol * TS)


# --------------------------------------------------------------------------- Eq. 14 terms
