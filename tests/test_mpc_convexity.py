"""Seed B §5.2 / Fig. 4 convexity study (issue #7): the Hessian of the one-step covariance
cost over (M, D), symbolic through casadi."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.analyses.mpc_convexity import (
    INTEGRATORS,
    OBJECTIVES,
    _settings,
    across_curves,
    curve_metrics,
    hessian_min_eig,
    indefinite_fraction,
    rank_corr,
)
from ccm.core.errors import ConfigError

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


# ---------------------------------------------------------------- summary metrics (issue #18)
GRID = {**SETTINGS, "typical_sigma_f": 1.0, "mass_range": (5.0, 60.0),
        "damping_range": (500.0, 6000.0), "n_phi": 5}  # fmt: skip


def test_rank_corr_reads_the_trend_either_way() -> None:
    x = np.logspace(-2, 2, 9)
    assert rank_corr(x, np.linspace(-1.0, 1.0, 9)) == pytest.approx(1.0)
    assert rank_corr(x, np.linspace(1.0, -1.0, 9)) == pytest.approx(-1.0)
    assert rank_corr(x, np.zeros(9)) == 0.0, "a constant curve has no trend"
    assert abs(rank_corr(x, np.array([0, 1, 0, 1, 0, 1, 0, 1, 0.0]))) < 0.3


def test_curve_metrics_halves_and_average() -> None:
    """Convex only in the upper half: the upper fraction is 1 and the lower 0; the mirrored
    curve (convex only at small Σ_f) gives the other answer; the middle point is in neither."""
    sf = np.logspace(-2, 2, 9)
    rising = np.array([-4, -3, -2, -1, 0.5, 1, 2, 3, 4.0])
    m = curve_metrics(sf, rising, rising / 4.0)
    assert (m["convex_fraction_lower_half"], m["convex_fraction_upper_half"]) == (0.0, 1.0)
    assert m["convex_fraction"] == pytest.approx(5 / 9)
    assert m["convex_above_sigma_f"] == pytest.approx(sf[4])
    assert m["mean_rel_min_eig"] == pytest.approx(np.mean(rising / 4.0))
    assert m["min_eig_rank_corr"] == pytest.approx(1.0)
    falling = rising[::-1].copy()
    f = curve_metrics(sf, falling, falling / 4.0)
    assert (f["convex_fraction_lower_half"], f["convex_fraction_upper_half"]) == (1.0, 0.0)
    assert f["convex_above_sigma_f"] is None and f["min_eig_rank_corr"] == pytest.approx(-1.0)


def test_across_curves_needs_every_curve() -> None:
    grow = {"convex_fraction_lower_half": 0.0, "convex_fraction_upper_half": 0.9,
            "min_eig_rank_corr": 0.9}  # fmt: skip
    flat = {"convex_fraction_lower_half": 1.0, "convex_fraction_upper_half": 1.0,
            "min_eig_rank_corr": 0.2}  # fmt: skip
    assert across_curves({"a": grow, "b": grow}) == {
        "frac_curves_convexity_grows": 1.0, "min_rank_corr": 0.9,
    }  # fmt: skip
    out = across_curves({"a": grow, "b": flat})
    assert out["frac_curves_convexity_grows"] == 0.5, "convex everywhere: no improvement"
    assert out["min_rank_corr"] == 0.2


def test_indefinite_fraction_gives_both_answers() -> None:
    """At a huge Σ_f every curve is convex on the whole (M, D) grid (fraction 0); at a tiny
    one most of the grid is indefinite; at one point the sign matches the eigenvalues."""
    assert set(indefinite_fraction({**GRID, "typical_sigma_f": 1e6}).values()) == {0.0}
    tiny = indefinite_fraction({**GRID, "typical_sigma_f": 1e-4})
    assert min(tiny.values()) >= 0.5
    one = {**GRID, "n_phi": 1, "mass_range": (5.0, 6.0), "damping_range": (200.0, 300.0)}
    eig = hessian_min_eig({**SETTINGS, "sigma_f_range": [1.0, 2.0], "n_points": 2})
    for key, frac in indefinite_fraction(one).items():
        assert frac == (1.0 if eig[key][0] < 0.0 else 0.0), key


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("convexity.mass_range=[60.0,5.0]", "convexity.mass_range"),
        ("convexity.damping_range=5", "convexity.damping_range"),
        ("convexity.typical_sigma_f=-1", "convexity.typical_sigma_f"),
        ("convexity.n_phi=0", "convexity.n_phi"),
    ],
)
def test_bad_grid_settings_name_the_key(composer, override: str, key: str) -> None:
    cfg = composer(["experiment=mpc_convexity", override])
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        _settings(cfg)
