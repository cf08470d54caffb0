"""Seed B §5.2 / Fig. 4 convexity study (issue #7): the Hessian of the one-step covariance
cost over (M, D), symbolic through casadi; its claims over a grid of operating points with
tolerances (issue #37)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ccm.analyses.mpc_convexity import (
    INTEGRATORS,
    OBJECTIVES,
    _settings,
    across_curves,
    curve_metrics,
    grid_curves,
    hessian_functions,
    hessian_min_eig,
    indefinite_fraction,
    rank_corr,
    run_convexity,
)
from ccm.analyses.mpc_convexity_grid import (
    RELATIONS,
    Tolerance,
    curve_stats,
    grid_fractions,
    operating_points,
    point_relations,
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


def _fd_hessian(cost: Callable[[np.ndarray], float], p0: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Central-difference Hessian of ``cost`` at ``p0`` with steps ``h``."""
    hess = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            ei, ej = np.eye(2)[i] * h[i], np.eye(2)[j] * h[j]
            hess[i, j] = (cost(p0 + ei + ej) - cost(p0 + ei - ej) - cost(p0 - ei + ej)
                          + cost(p0 - ei - ej)) / (4 * h[i] * h[j])  # fmt: skip
    return hess


def _one_step_sigma(p: np.ndarray, a22: float, prior: tuple[float, float], sf: float) -> np.ndarray:
    """Σ⁺ = A Σ Aᵀ + B Σ_f Bᵀ (Eq. 8, one step) with velocity entry ``a22`` of A, in numpy."""
    ts, mass = SETTINGS["ts"], p[0]
    a = np.array([[1.0, ts], [0.0, a22]])
    b = np.array([[0.0], [ts / mass]])
    return a @ np.diag(prior) @ a.T + sf * b @ b.T


def test_min_eigenvalue_matches_a_finite_difference_hessian() -> None:
    """``hessian_min_eig`` (casadi, symbolic) against a numpy central-difference Hessian of
    Tr(QΣ⁺) with the implicit integrator (Eq. 5, 8), at Σ_f = 1 N²; and the grid path
    (``grid_curves``, prior Σ a casadi input) against one of ln det(QΣ⁺) with explicit Euler
    at another operating point, where the prior position variance enters (ln det only)."""
    ts = SETTINGS["ts"]

    def trace_cost(p: np.ndarray) -> float:
        implicit = p[0] / (p[0] + ts * p[1])  # Eq. 5
        return float(np.trace(_one_step_sigma(p, implicit, (1e-6, 1e-4), 1.0)))

    hess = _fd_hessian(trace_cost, np.array([5.0, 200.0]), np.array([5e-3, 2e-1]))
    c = hessian_min_eig({**SETTINGS, "sigma_f_range": [1.0, 10.0], "n_points": 2})
    assert c["implicit/trace"][0] == pytest.approx(np.linalg.eigvalsh(hess)[0], rel=1e-3)

    prior, sf = (1e-4, 1e-2), 10.0  # 1 cm and 10 cm/s std, Σ_f = 10 N²

    def logdet_cost(p: np.ndarray) -> float:
        euler = 1.0 - ts * p[1] / p[0]  # explicit Euler, sign as in the module docstring
        return float(np.log(np.linalg.det(_one_step_sigma(p, euler, prior, sf))))

    p0 = np.array([17.32, 1732.0])
    hess = _fd_hessian(logdet_cost, p0, p0 * 1e-3)
    settings = {**SETTINGS, "sigma_f_range": [sf, 100.0], "n_points": 2}
    point = np.array([[*p0, *prior]])
    eig, _ = grid_curves(settings, hessian_functions(settings), point)["euler/logdet"]
    assert eig[0, 0] == pytest.approx(np.linalg.eigvalsh(hess)[0], rel=1e-3)


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
        ("convexity.grid.mass=[]", "convexity.grid.mass"),
        ("convexity.grid.vel_std=[0.01,-1.0]", "convexity.grid.vel_std[1]"),
        ("+convexity.grid.stiffness=[1.0]", "convexity.grid.stiffness"),
        ("convexity.tolerance.convex_steps=0", "convexity.tolerance.convex_steps"),
        ("convexity.tolerance.mean_rel=-0.1", "convexity.tolerance.mean_rel"),
        ("convexity.tolerance.rank_corr_min=2", "convexity.tolerance.rank_corr_min"),
        ("+convexity.tolerance.margin=1", "convexity.tolerance.margin"),
    ],
)
def test_bad_grid_settings_name_the_key(composer, override: str, key: str) -> None:
    cfg = composer(["experiment=mpc_convexity", override])
    with pytest.raises(ConfigError, match=re.escape(key)):
        _settings(cfg)


# ------------------------------------------------ the claims over operating points (issue #37)
N_SF = 21  # Σ_f grid of the constructed curves: lower half 0..9, middle 10, upper half 11..20
SF = np.logspace(-2, 2, N_SF)
TOL = Tolerance(convex_steps=2, mean_rel=0.025, rank_corr_min=0.5)


def _stats(thresholds: dict[str, int], means: dict[str, float] | None = None) -> dict:
    """curve_stats of six constructed curves: λ_min rising through 0 at grid index
    ``thresholds[curve]`` (0: convex everywhere, N_SF: nowhere); λ_min / max|λ| the constant
    ``means[curve]`` (default 0)."""
    means = means or {}
    out = {}
    for integ in INTEGRATORS:
        for obj in OBJECTIVES:
            key = f"{integ}/{obj}"
            eig = np.arange(N_SF) - thresholds[key] + 0.5
            out[key] = curve_stats(eig, np.full(N_SF, means.get(key, 0.0)), SF)
    return out


# every relation holds by exactly its tolerance: trace 2 steps before ln det, implicit/trace
# 2 steps before euler/trace, implicit's mean 0.025 above euler's and exponential's
BASE = {"euler/trace": 10, "euler/logdet": 12, "implicit/trace": 8, "implicit/logdet": 10,
        "exponential/trace": 8, "exponential/logdet": 10}  # fmt: skip
MEANS = {"implicit/trace": 0.0, "euler/trace": -0.025, "exponential/trace": -0.03}


def test_relations_hold_at_their_tolerance() -> None:
    rel = point_relations(_stats(BASE, MEANS), TOL)
    assert set(rel) == set(RELATIONS)
    assert all(v is True for v in rel.values()), rel


def test_relations_by_less_than_the_tolerance_do_not_count() -> None:
    """One Σ_f grid step, or a mean 0.02 apart, is below the tolerance: False, not True; the
    relations that still hold by their margin stay True."""
    one_step = {**BASE, "euler/trace": 9, "implicit/logdet": 9}
    rel = point_relations(_stats(one_step, {**MEANS, "exponential/trace": -0.02}), TOL)
    assert rel["trace_implicit_convex"] is False, "euler/trace 1 step after implicit/trace"
    assert rel["trace_beats_logdet_implicit"] is False, "ln det 1 step after trace"
    assert rel["trace_beats_logdet_euler"] is True, "ln det 3 steps after trace"
    assert rel["implicit_beats_exponential_average"] is False, "means 0.02 apart"
    assert rel["implicit_beats_euler_average"] is True
    # a curve convex from grid index 1: 9 convex points in the lower half, 10 in the upper
    assert point_relations(_stats({**BASE, "euler/logdet": 1}), TOL)["convexity_grows"] is False
    loose = Tolerance(convex_steps=1, mean_rel=0.01, rank_corr_min=0.5)
    rel = point_relations(_stats(one_step, {**MEANS, "exponential/trace": -0.02}), loose)
    assert rel["trace_implicit_convex"] and rel["trace_beats_logdet_implicit"]
    assert rel["implicit_beats_exponential_average"]


def test_relations_go_against_and_saturated_points_are_not_informative() -> None:
    """Reversed orders fail; where both curves of a comparison are convex at every swept Σ_f,
    or both at none, the point says nothing (None); one always and one never convex does."""
    swapped = {**BASE, "implicit/trace": 14, "euler/logdet": 6}
    rel = point_relations(_stats(swapped), TOL)
    assert rel["trace_implicit_convex"] is False and rel["trace_beats_logdet_euler"] is False
    never = {k: N_SF for k in BASE}
    rel = point_relations(_stats(never), TOL)
    for name in ("trace_implicit_convex", "trace_beats_logdet_euler", "convexity_grows"):
        assert rel[name] is None, name
    always = {k: 0 for k in BASE}
    assert point_relations(_stats(always), TOL)["convexity_grows"] is None
    apart = {**never, "implicit/trace": 0}
    rel = point_relations(_stats(apart), TOL)
    assert rel["trace_implicit_convex"] is True and rel["trace_beats_logdet_implicit"] is True


def test_min_eig_grows_reads_the_rank_correlation() -> None:
    stats = _stats(BASE)
    assert point_relations(stats, TOL)["min_eig_grows"] is True
    falling = np.linspace(1.0, -1.0, N_SF)
    stats["exponential/logdet"] = curve_stats(falling, falling, SF)
    assert point_relations(stats, TOL)["min_eig_grows"] is False


def test_grid_fractions_leave_out_points_that_are_not_informative() -> None:
    rows = [{n: v for n in RELATIONS} for v in (True, False, None, True)]
    out = grid_fractions(rows)
    assert out["grid_frac_convexity_grows"] == pytest.approx(2 / 3)
    assert out["grid_informative_convexity_grows"] == pytest.approx(3 / 4)
    none = grid_fractions([{n: None for n in RELATIONS}])
    assert none["grid_frac_min_eig_grows"] is None and none["grid_informative_min_eig_grows"] == 0


def test_operating_points_add_the_single_point_once() -> None:
    grid = {"mass": [5.0, 60.0], "damping": [500.0], "pos_std": [1e-3], "vel_std": [1e-2, 1e-1]}
    pts = operating_points(grid, (5.0, 200.0, 1e-6, 1e-4))
    assert pts.shape == (5, 4)
    assert pts[-1].tolist() == [5.0, 200.0, 1e-6, 1e-4]
    assert pts[0].tolist() == pytest.approx([5.0, 500.0, 1e-6, 1e-4]), "stds squared"
    assert len(operating_points(grid, (60.0, 500.0, 1e-6, 1e-2))) == 4, "already in the grid"


def test_grid_run_matches_the_single_point_and_repeats(composer, tmp_path: Path) -> None:
    """The grid path gives the single-point path's convex thresholds at the single point, every
    relation has its two summary metrics, and a second run writes the same summary.json."""
    over = ["experiment=mpc_convexity", "experiment.figures=false", "convexity.n_points=41",
            "convexity.grid.mass=[5.0,60.0]", "convexity.grid.damping=[500.0]"]  # fmt: skip
    summary = run_convexity(composer(over), lambda extra: None, tmp_path / "a")
    rows = json.loads((tmp_path / "a" / "operating_points.json").read_text(encoding="utf-8"))
    cond = summary["conditions"]
    assert cond["all_curves"]["grid_n_points"] == len(rows) == 2 * 9 + 1
    single = rows[-1]
    assert (single["mass"], single["damping"]) == (5.0, 200.0)
    for key, above in single["convex_above_sigma_f"].items():
        assert above == cond[key]["convex_above_sigma_f"], key
    for name in RELATIONS:
        assert f"grid_frac_{name}" in cond["all_curves"], name
        assert f"grid_informative_{name}" in cond["all_curves"], name
    run_convexity(composer(over), lambda extra: None, tmp_path / "b")
    assert (tmp_path / "a" / "summary.json").read_bytes() == (
        tmp_path / "b" / "summary.json"
    ).read_bytes()
