"""Discretised robot admittance and its stochastic propagation (seed B §3.2, Eq. 4-9).

Per degree of freedom i (M, D diagonal; K and x0 dropped, as in seed B §3.2), with the state
ξ = [x, ẋ] stacked as ``[x_1..x_n, ẋ_1..ẋ_n]``:

    f − f^r = M ẍ + D ẋ                                                   (4)
    ξ⁺ = [[I, T_s I], [0, M (M + T_s D)⁻¹]] ξ + [[0], [T_s M⁻¹]] (f − f^r)    (5)
       = A ξ + B (f − f^r)                                               (6)
    μ⁺ = A μ + B (μ_f(μ) − f^r)                                           (7)
    Σ⁺ = A Σ Aᵀ + B Σ_f(μ) Bᵀ                                             (8)

Eq. 5 is seed B's semi-implicit integrator. Its velocity factor M/(M + T_s D) lies in (0, 1]
for every M > 0, D ≥ 0, so the discrete velocity never oscillates (explicit Euler's
1 − T_s D/M does once T_s D/M > 1). As printed, B = T_s M⁻¹ is not backward Euler's
T_s (M + T_s D)⁻¹: under a constant force the discrete velocity settles at
(f − f^r)/D · (1 + T_s D/M) instead of (f − f^r)/D (+10 % at T_s D/M = 0.1; measured in
the tests). ccm implements Eq. 5 as printed, since seed B's MPC uses it. Eq. 9 (the
vectorised covariance step) is the same update in vec form; :func:`covariance_step` uses
the matrix form (8) and the tests check that it equals (9).

The functions take numpy arrays or casadi symbols alike (``ca.MX``/``ca.SX``), so the MPC
(issue #7) can build its problem from the same code.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_positive


def _lib(*xs: Any) -> Any:
    """casadi if any argument is symbolic, else numpy."""
    import casadi as ca

    return ca if any(isinstance(x, ca.MX | ca.SX | ca.DM) for x in xs) else np


def system_matrices(mass: Any, damping: Any, ts: float) -> tuple[Any, Any]:
    """A_φ, B_φ of Eq. 5-6 for diagonal M = diag(mass), D = diag(damping) (n DOF each).

    Args:
        mass: M_i [kg], shape (n,), > 0 (numpy or casadi column).
        damping: D_i [N s/m], shape (n,), >= 0.
        ts: T_s [s], > 0.

    Returns:
        A (2n, 2n) and B (2n, n).
    """
    ts = check_positive("admittance.ts", ts)
    lib = _lib(mass, damping)
    if lib is np:
        mass, damping = (
            np.atleast_1d(np.asarray(mass, float)),
            np.atleast_1d(np.asarray(damping, float)),
        )
        if mass.shape != damping.shape or mass.ndim != 1:
            raise ConfigError("admittance.damping", f"needs the shape of mass {mass.shape}")
        if np.any(~np.isfinite(mass)) or np.any(mass <= 0):
            raise ConfigError("admittance.mass", f"must be finite and > 0, got {mass.tolist()}")
        if np.any(~np.isfinite(damping)) or np.any(damping < 0):
            raise ConfigError(
                "admittance.damping", f"must be finite and >= 0, got {damping.tolist()}"
            )
        n = mass.size
        a = np.block([[np.eye(n), ts * np.eye(n)],
                      [np.zeros((n, n)), np.diag(mass / (mass + ts * damping))]])  # fmt: skip
        b = np.vstack([np.zeros((n, n)), np.diag(ts / mass)])
        return a, b
    import casadi as ca

    n = mass.shape[0]
    a = ca.vertcat(
        ca.horzcat(ca.DM.eye(n), ts * ca.DM.eye(n)),
        ca.horzcat(ca.DM.zeros(n, n), ca.diag(mass / (mass + ts * damping))),
    )
    b = ca.vertcat(ca.DM.zeros(n, n), ca.diag(ts / mass))
    return a, b


def mean_step(a: Any, b: Any, mu: Any, force_mean: Any, f_ref: Any) -> Any:
    """μ⁺ of Eq. 7: A μ + B (μ_f(μ) − f^r); ``force_mean`` is μ_f evaluated at μ's pose."""
    return a @ mu + b @ (force_mean - f_ref)


def covariance_step(a: Any, b: Any, sigma: Any, force_var: Any) -> Any:
    """Σ⁺ of Eq. 8: A Σ Aᵀ + B Σ_f Bᵀ, Σ_f = diag(``force_var``) (seed B: independent GPs)."""
    lib = _lib(a, b, sigma, force_var)
    sig_f = lib.diag(force_var)
    return a @ sigma @ a.T + b @ sig_f @ b.T


def rollout(
    mass: Any, damping: Any, ts: float, mu0: Any, sigma0: Any, f_ref: Any,
    force_model: Callable[[Any], tuple[Any, Any]], steps: int,
) -> tuple[list[Any], list[Any]]:  # fmt: skip
    """Means and covariances over ``steps`` steps (Eq. 7-8), with the force model's mean and
    variance evaluated at the predicted mean pose each step (seed B Fig. 3).

    Args:
        force_model: pose (n,) -> (μ_f (n,), Σ_f diagonal (n,)), numpy or casadi.
        f_ref: the force reference f^r, (n,) (held over the horizon) or a list per step.
    """
    a, b = system_matrices(mass, damping, ts)
    n = b.shape[1]
    mus, sigmas = [mu0], [sigma0]
    for k in range(steps):
        fr = f_ref[k] if isinstance(f_ref, list) else f_ref
        f_mu, f_var = force_model(mus[-1][:n])
        mus.append(mean_step(a, b, mus[-1], f_mu, fr))
        sigmas.append(covariance_step(a, b, sigmas[-1], f_var))
    return mus, sigmas
