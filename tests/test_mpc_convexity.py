"""Seed B §5.2 / Fig. 4 convexity study (issue #7): the Hessian of the one-step covariance
cost over (M, D), symbolic through casadi."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.mpc_convexity import INTEGRATORS, OBJECTIVES, hessian_min_eig

SETTINGS = {"ts": 0.01, "mass": 5.0, "damping": 200.0, "sigma_x": 1e-6, "sigma_v": 1e-4,
            "q": [1.0, 1.0], "sigma_f_range": [1e-4, 1e4], "n_points": 9}  # fmt: skip


def test_convexity_improves_as_the_force_variance_grows() -> None:
    """Seed B: 'convexity improves as Σ_f increases' - every curve ends convex (>= 0) and
    its minimum eigenvalue at the largest Σ_f is above that at the smallest."""
    c = hessian_min_eig(SETTINGS)
    for integ in INTEGRATORS:
        for obj in OBJECTIVES:
            eig = c[f"{integ}/{obj}"]
            assert eig[-1] >= 0.0 and eig[-1] > eig[0], (integ, obj)


def test_min_eigenvalue_matches_a_finite_difference_hessian() -> None:
    """``hessian_min_eig`` (casadi, symbolic) against a numpy central-difference Hessian of
    Tr(QΣ⁺) with the implicit integrator (Eq. 5, 8), at Σ_f = 1 N²."""
    ts, sf = SETTINGS["ts"], 1.0

    def cost(p: np.ndarray) -> float:
        mass, damp = p
        a = np.array([[1.0, ts], [0.0, mass / (mass + ts * damp)]])
        b = np.array([[0.0], [ts / mass]])
        return float(np.trace(a @ np.diag([1e-6, 1e-4]) @ a.T + sf * b @ b.T))

    p0, h = np.array([5.0, 200.0]), np.array([5e-3, 2e-1])
    hess = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            ei, ej = np.eye(2)[i] * h[i], np.eye(2)[j] * h[j]
            hess[i, j] = (cost(p0 + ei + ej) - cost(p0 + ei - ej) - cost(p0 - ei + ej)
                          + cost(p0 - ei - ej)) / (4 * h[i] * h[j])  # fmt: skip
    c = hessian_min_eig({**SETTINGS, "sigma_f_range": [1.0, 10.0], "n_points": 2})
    assert c["implicit/trace"][0] == pytest.approx(np.linalg.eigvalsh(hess)[0], rel=1e-3)
