"""Tests for the GP force-over-pose models (seed B, §3.1.1, Eq. 1-3)."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.gp.gp_force import GPForceModel
from ccm.learn.gp.gp_force_models import GPForceModels

K_CONTACT = 45_000.0  # N/m, seed B's 45 N/mm
X_CONTACT = 0.3


def _contact_data(seed: int = 1, n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(0.2, 0.35, n))
    f = np.where(x < X_CONTACT, 0.0, -K_CONTACT * (x - X_CONTACT)) + rng.normal(0, 0.5, n)
    return x[:, None], f


def _smooth_data(seed: int = 2, n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(0.0, 1.0, n))
    return x[:, None], np.sin(6.0 * x) + rng.normal(0, 0.01, n)


@pytest.fixture(scope="module")
def hinge_model() -> GPForceModel:
    return GPForceModel(mean="hinge").fit(*_contact_data())


@pytest.fixture(scope="module")
def smooth_model() -> GPForceModel:
    return GPForceModel().fit(*_smooth_data())


def test_zero_mean_fits_smooth_function(smooth_model: GPForceModel) -> None:
    xs = np.linspace(0.05, 0.95, 50)[:, None]
    mu, var = smooth_model.predict(xs)
    assert np.sqrt(np.mean((mu - np.sin(6.0 * xs[:, 0])) ** 2)) < 0.02
    X, _ = _smooth_data()
    _, var_data = smooth_model.predict(X)
    _, var_far = smooth_model.predict(np.array([[3.0]]))
    assert var_data.max() < 1e-3
    assert var_far[0] > 100 * var_data.max()
    assert var_far[0] == pytest.approx(smooth_model.signal_var_, rel=1e-6)
    assert smooth_model.hinge_ is None


def test_hinge_mean_recovers_contact(hinge_model: GPForceModel) -> None:
    c1, c2, c3 = hinge_model.hinge_
    assert abs(c3 - X_CONTACT) < 5e-3
    assert abs(c2 + K_CONTACT) < 0.2 * K_CONTACT
    assert abs(c1) < 5.0


def test_hinge_extrapolates_zero_mean_reverts(hinge_model: GPForceModel) -> None:
    zero = GPForceModel(mean="zero").fit(*_contact_data())
    x_far = np.array([[0.5]])
    expected = -K_CONTACT * (0.5 - X_CONTACT)
    mu_hinge = hinge_model.predict(x_far, return_var=False)[0]
    mu_zero = zero.predict(x_far, return_var=False)[0]
    assert mu_hinge == pytest.approx(expected, rel=0.05)
    assert abs(mu_zero) < 0.05 * abs(expected)


def test_paper_hinge_form_runs() -> None:
    model = GPForceModel(mean="hinge", hinge_form="paper").fit(*_contact_data())
    X, f = _contact_data()
    mu = model.predict(X, return_var=False)
    assert np.sqrt(np.mean((mu - f) ** 2)) < 50.0
    xmin, xmax = X.min(), X.max()
    assert xmin <= model.hinge_[2] <= xmax


@pytest.mark.parametrize("which", ["smooth", "hinge"])
def test_mean_gradient_matches_finite_differences(
    which: str, smooth_model: GPForceModel, hinge_model: GPForceModel
) -> None:
    model = smooth_model if which == "smooth" else hinge_model
    points = [0.1, 0.37, 0.8] if which == "smooth" else [0.25, 0.33, 0.4]
    h = 1e-6
    for p in points:
        g = model.mean_gradient(np.array([p]))
        fd = (model.predict(np.array([[p + h], [p - h]]), return_var=False) @ [1, -1]) / (2 * h)
        assert g[0] == pytest.approx(fd, rel=1e-5, abs=1e-4)


def test_casadi_functions_match_numpy(hinge_model: GPForceModel) -> None:
    rng = np.random.default_rng(3)
    X = rng.uniform(-1, 1, (80, 3))
    f = np.sin(2 * X[:, 0]) * X[:, 1] + np.maximum(0, X[:, 2]) * -5 + rng.normal(0, 0.01, 80)
    model3 = GPForceModel(mean="hinge", hinge_input=2).fit(X, f)
    for model, pts in [
        (hinge_model, np.array([[0.21], [0.28], [0.33], [0.6]])),
        (model3, rng.uniform(-1.2, 1.2, (5, 3))),
    ]:
        fns = model.casadi_functions()
        mu, var = model.predict(pts)
        for i, x in enumerate(pts):
            scale = max(1.0, abs(mu[i]))
            assert float(fns["mean"](x)) == pytest.approx(mu[i], rel=1e-8, abs=1e-10 * scale)
            vtol = 1e-10 * model.signal_var_
            assert float(fns["var"](x)) == pytest.approx(var[i], rel=1e-8, abs=vtol)
            g = np.array(fns["grad"](x)).ravel()
            g_np = model.mean_gradient(x)
            np.testing.assert_allclose(g, g_np, rtol=1e-8, atol=1e-10 * max(1, abs(g_np).max()))


def test_multi_output_stacks(hinge_model: GPForceModel) -> None:
    rng = np.random.default_rng(4)
    X = rng.uniform(-1, 1, (60, 3))
    F = np.column_stack([np.sin(X[:, 0]), X[:, 1] ** 2]) + rng.normal(0, 0.01, (60, 2))
    models = GPForceModels(2, mean="hinge", n_restarts=1).fit(X, F)
    assert [m.hinge_input for m in models.models] == [0, 1]
    pts = rng.uniform(-1, 1, (4, 3))
    mu, var = models.predict(pts)
    assert mu.shape == var.shape == (4, 2)
    fns = models.casadi_functions()
    for i, x in enumerate(pts):
        np.testing.assert_allclose(np.array(fns["mean"](x)).ravel(), mu[i], rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(np.array(fns["var"](x)).ravel(), var[i], rtol=1e-8, atol=1e-10)
        jac = np.array(fns["grad"](x))
        assert jac.shape == (2, 3)
        ref = np.vstack([m.mean_gradient(x) for m in models.models])
        np.testing.assert_allclose(jac, ref, rtol=1e-8, atol=1e-10)


def test_fit_improves_nll(hinge_model: GPForceModel, smooth_model: GPForceModel) -> None:
    for model in (hinge_model, smooth_model):
        nll0 = model.negative_log_likelihood(**model.initial_params_)
        assert model.nll_ <= nll0
        fitted = model.negative_log_likelihood(
            model.length_scales_, model.signal_var_, model.noise_var_, model.hinge_
        )
        assert fitted == pytest.approx(model.nll_, rel=1e-9)
    nll0 = hinge_model.negative_log_likelihood(**hinge_model.initial_params_)
    assert hinge_model.nll_ < nll0 - 1.0  # strict improvement, not just the start kept


def test_deterministic() -> None:
    X, f = _contact_data()
    a = GPForceModel(mean="hinge", seed=7).fit(X, f)
    b = GPForceModel(mean="hinge", seed=7).fit(X, f)
    np.testing.assert_array_equal(a.length_scales_, b.length_scales_)
    assert (a.signal_var_, a.noise_var_, a.hinge_, a.nll_) == (
        b.signal_var_,
        b.noise_var_,
        b.hinge_,
        b.nll_,
    )


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"mean": "linear"}, "gp.mean"),
        ({"hinge_form": "soft"}, "gp.hinge_form"),
        ({"hinge_width": 0.0}, "gp.hinge_width"),
        ({"hinge_input": -1}, "gp.hinge_input"),
        ({"length_scale_bounds": (1.0, 0.1)}, "gp.length_scale_bounds"),
        ({"noise_var_bounds": (0.0, 1.0)}, "gp.noise_var_bounds"),
        ({"n_restarts": 1.5}, "gp.n_restarts"),
    ],
)
def test_bad_config(kwargs: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        GPForceModel(**kwargs)
    assert err.value.key == key


def test_bad_data() -> None:
    X, f = _contact_data()
    m = GPForceModel(key="force.fx")
    with pytest.raises(ConfigError, match="force.fx.fit"):
        m.predict(X)
    bad = X.copy()
    bad[3, 0] = np.nan
    cases = [
        ((bad, f), "force.fx.X"),
        ((X, f[:-1]), "force.fx.f"),
        ((X[:1], f[:1]), "force.fx.X"),
        ((X[:, 0], f), "force.fx.X"),
        ((X, np.full_like(f, np.inf)), "force.fx.f"),
    ]
    for args, key in cases:
        with pytest.raises(ConfigError) as err:
            m.fit(*args)
        assert err.value.key == key
    with pytest.raises(ConfigError) as err:
        GPForceModel(mean="hinge", hinge_input=2).fit(X, f)
    assert err.value.key == "gp.hinge_input"
    m.fit(X, f)
    with pytest.raises(ConfigError) as err:
        m.predict(np.ones((2, 3)))
    assert err.value.key == "force.fx.X"
    with pytest.raises(ConfigError) as err:
        m.mean_gradient(np.ones(2))
    assert err.value.key == "force.fx.X"
    with pytest.raises(ConfigError) as err:
        GPForceModels(7)
    assert err.value.key == "gp.n_outputs"
    with pytest.raises(ConfigError) as err:
        GPForceModels(2).fit(X, np.ones((X.shape[0], 3)))
    assert err.value.key == "gp.F"


def test_smooth_hinge_recovers_contact_and_matches_casadi() -> None:
    """hinge_form="smooth" (softplus, a ccm option for the MPC): the fit still finds the
    contact and the stiffness, and numpy, casadi and finite differences agree on the slope."""
    rng = np.random.default_rng(5)
    x = np.r_[np.linspace(-0.05, 0.0, 40), np.linspace(0.0, 1e-3, 20)]
    f = -45000.0 * np.maximum(0.0, x - 0.0) + 2.0 + rng.normal(0, 0.2, x.size)
    model = GPForceModel(mean="hinge", hinge_form="smooth", hinge_width=1e-4).fit(x[:, None], f)
    c1, c2, c3 = model.hinge_
    assert abs(c3) < 1e-3 and c2 == pytest.approx(-45000.0, rel=0.1)
    fns = model.casadi_functions()
    for p in (-0.002, 0.0, 2e-4, 8e-4):
        xp = np.array([p])
        assert float(fns["mean"](xp)) == pytest.approx(model.predict(xp[None, :], False)[0])
        g = model.mean_gradient(xp)[0]
        assert float(fns["grad"](xp)) == pytest.approx(g, rel=1e-8, abs=1e-6)
        h = 1e-7
        fd = (model.predict(np.array([[p + h], [p - h]]), return_var=False) @ [1, -1]) / (2 * h)
        assert g == pytest.approx(fd, rel=1e-4, abs=1e-2)


# ---------------------------------------------------------------- Eq. 1-2 as printed (tied)
def test_tied_variance_is_eq2_as_printed() -> None:
    """Seed B Eq. 1-2 with one σ_n² as kernel amplitude and noise: Σ^f = σ_n² − k*ᵀ(K+σ_n²I)⁻¹k*,
    written out here from the fitted hyperparameters, reverts to σ_n² far from the data
    (§4.3.1), and is far above the separate model's latent variance on scattered data."""
    X, f = _contact_data()
    bounds = {"length_scale_bounds": (0.005, 0.05)}  # so that 0.9 m lies far from the data
    tied = GPForceModel(mean="hinge", variance="tied", **bounds).fit(X, f)
    sep = GPForceModel(mean="hinge", **bounds).fit(X, f)
    assert tied.signal_var_ == tied.noise_var_
    s2, ls = tied.noise_var_, tied.length_scales_[0]
    xs = np.array([[0.25], [0.31], [0.9]])

    def k(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return s2 * np.exp(-0.5 * ((a[:, None, 0] - b[None, :, 0]) / ls) ** 2)

    kxx = k(X, X) + s2 * np.eye(len(X))
    expected = s2 - np.einsum("ij,ji->i", k(xs, X), np.linalg.solve(kxx, k(X, xs)))
    _, var = tied.predict(xs)
    np.testing.assert_allclose(var, expected, rtol=1e-8, atol=1e-12)
    assert var[2] == pytest.approx(s2, rel=1e-6)  # far from the data: the baseline σ_n²
    # near the data the tied Σ^f keeps a share of the scatter (σ_n² / (points within a length
    # scale + 1), here ~5 % of σ_n²);
    # the separate model's latent variance leaves it to σ_n² and is tiny
    assert var[0] > 0.02 * s2 and var[0] > 20 * sep.predict(xs)[1][0]


def test_tied_variance_sits_at_its_likelihood_optimum() -> None:
    """At the fitted optimum, ∂NLL/∂log σ² = 0 for K = σ²(R + I) gives σ² = rᵀ(R + I)⁻¹r / M
    (r the residual from the hinge mean): a chain rule that summed the two variance slots'
    gradients wrongly would leave σ² elsewhere."""
    X, f = _contact_data(seed=3)
    gp = GPForceModel(mean="hinge", variance="tied", noise_var_bounds=(1e-6, 1e4)).fit(X, f)
    r = f - gp._mean_fn(X, gp.hinge_)
    d = (X[:, None, 0] - X[None, :, 0]) / gp.length_scales_[0]
    R = np.exp(-0.5 * d**2) + np.eye(len(X))
    assert gp.noise_var_ == pytest.approx(r @ np.linalg.solve(R, r) / len(X), rel=1e-3)


def test_tied_variance_is_checked() -> None:
    with pytest.raises(ConfigError, match=r"gp\.variance"):
        GPForceModel(variance="shared")
