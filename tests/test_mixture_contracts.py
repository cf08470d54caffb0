"""The contracts of the mixture learners (IGMM, GMR, the forward models; issue #39 item 1).

What a user meets around seed A's Eq. 5–6: each refusal is the one line that names the
argument and what is allowed (checked whole), the documented defaults and caching hold, a
frozen GMM fit on a linear law predicts that law, and a batch GMR prediction is its rows'
predictions even when one row lies far from every component.
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.mixtures.forecast import ForecastBuffer, horizon_steps
from ccm.learn.mixtures.forward_model import (
    FrozenGMMForwardModel,
    IncrementalForwardModel,
    make_forward_model,
)
from ccm.learn.mixtures.gmr import GMRConditional, gmr_predict
from ccm.learn.mixtures.igmm import IGMM
from tests.refusals import refusal

W, MU = [0.5, 0.5], [[0.0, 0.0, 0.0], [2.0, 1.0, -1.0]]
COV = [np.eye(3).tolist(), (0.5 * np.eye(3)).tolist()]


_message = partial(refusal, ValueError)


@pytest.mark.parametrize(
    ("in_idx", "out_idx", "message"),
    [
        ([[0]], [2], "in_idx: must be a non-empty 1-D sequence of integers, got [[0]]"),
        ([], [2], "in_idx: must be a non-empty 1-D sequence of integers, got []"),
        ([0], "a", "out_idx: must contain integers, got 'a'"),
        ([0], [1.5], "out_idx: must contain integers, got [1.5]"),
        ([0, 5], [2], "in_idx: indices must lie in [0, 2], got [0, 5]"),
        ([0], [-1], "out_idx: indices must lie in [0, 2], got [-1]"),
        ([0, [1]], [2], "in_idx: must be a sequence of integers, got [0, [1]]"),
        ([0, 0], [2], "in_idx: repeated index in [0, 0]"),
        ([0, 1], [1, 2], "in_idx and out_idx overlap: [0, 1] / [1, 2]"),
    ],
)
def test_a_bad_split_names_the_argument(in_idx: Any, out_idx: Any, message: str) -> None:
    assert _message(GMRConditional, W, MU, COV, in_idx, out_idx) == message
    assert _message(gmr_predict, W, MU, COV, [0.0], in_idx, out_idx) == message


def test_a_scalar_index_is_a_one_element_split() -> None:
    cond = GMRConditional(W, MU, COV, 0, 2)
    np.testing.assert_array_equal(cond.in_idx, [0])
    np.testing.assert_allclose(cond.predict([0.3]), GMRConditional(W, MU, COV, [0], [2]).predict(
        [0.3]))  # fmt: skip


@pytest.mark.parametrize(
    ("w", "mu", "cov", "message"),
    [
        ([1.0, 0.0, 0.0], MU, COV, "weights: expected shape (2,), got (3,)"),
        (W, [0.0, 1.0, 2.0], COV, "means: expected shape (K, d) with K >= 1, got (3,)"),
        (
            [],
            np.zeros((0, 3)),
            np.zeros((0, 3, 3)),
            "means: expected shape (K, d) with K >= 1, got (0, 3)",
        ),  # fmt: skip
        (W, MU, COV[:1], "covariances: expected shape (2, 3, 3) (full covariances), got (1, 3, 3)"),
        ([0.5, np.nan], MU, COV, "weights: must be finite"),
        (W, [[0.0, np.inf, 0.0], MU[1]], COV, "means: must be finite"),
        ([0.5, -0.1], MU, COV, "weights: must be >= 0 with a positive sum"),
        ([0.0, 0.0], MU, COV, "weights: must be >= 0 with a positive sum"),
        (W, [["a", 0.0, 0.0], MU[1]], COV, "weights, means and covariances must be numeric arrays"),
    ],
)
def test_a_bad_mixture_names_the_parameter(w: Any, mu: Any, cov: Any, message: str) -> None:
    assert _message(GMRConditional, w, mu, cov, [0], [2]) == message


def test_a_zero_weight_component_is_allowed_and_ignored() -> None:
    only = GMRConditional([1.0], MU[:1], COV[:1], [0, 1], [2])
    both = GMRConditional([1.0, 0.0], MU, COV, [0, 1], [2])
    np.testing.assert_allclose(both.predict([0.4, -0.2]), only.predict([0.4, -0.2]))


def test_inputs_that_are_not_finite_name_the_row() -> None:
    cond = GMRConditional(W, MU, COV, [0, 1], [2])
    x = np.zeros((4, 2))
    x[2, 1] = np.nan
    assert _message(cond.predict, x) == "x_in: row 2 is not finite"
    assert _message(cond.predict, "ab") == "x_in: must be numeric, got str"
    assert _message(cond.predict, [0.0]) == "x_in: expected shape (2,) or (N, 2), got (1,)"
    assert _message(gmr_predict, W, MU, COV, [0.0, np.nan], [0, 1], [2]) == ("x_in: must be finite")
    assert _message(gmr_predict, W, MU, COV, [0.0], [0, 1], [2]) == (
        "x_in: expected shape (2,) or (N, 2), got (1,)"
    )


def test_an_input_block_that_is_not_positive_definite_names_the_component() -> None:
    bad = [COV[0], [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]]
    assert _message(GMRConditional, W, MU, bad, [0, 1], [2]) == (
        "covariances: component 1 has an input block Sigma_in,in that is not positive definite"
    )
    assert _message(gmr_predict, W, MU, bad, [0.0, 0.0], [0, 1], [2]) == (
        "covariances: an input block Sigma_in,in is not positive definite"
    )


def test_a_batch_is_its_rows_even_when_a_row_is_far_from_every_component() -> None:
    """h_k is normalised per row: a row 60 standard deviations from every component (log
    densities near −1800) still has weights that sum to one, beside a row near the means."""
    X = np.array([[0.5, 0.2], [60.0, -60.0], [1.5, 1.0]])
    batch, batch_cov = gmr_predict(W, MU, COV, X, [0, 1], [2])
    for i, x in enumerate(X):
        mean, cov = gmr_predict(W, MU, COV, x, [0, 1], [2])
        np.testing.assert_allclose(batch[i], mean, rtol=1e-12)
        np.testing.assert_allclose(batch_cov[i], cov, rtol=1e-12)
    assert np.all(np.isfinite(batch))
    cond = GMRConditional(W, MU, COV, [0, 1], [2])
    np.testing.assert_allclose(cond.predict(X), batch, rtol=1e-10)


def test_an_empty_igmm_says_to_learn_first() -> None:
    model = IGMM(3, sigma_init=1.0)
    assert _message(model.conditional([0], [2]).predict, [0.0]) == (
        "the mixture has no components yet: call partial_fit first"
    )
    assert _message(model.score_samples, [0.0, 0.0, 0.0]) == (
        "IGMM has no components yet: call partial_fit first"
    )


def test_igmm_refusals_name_the_argument() -> None:
    assert _message(IGMM, 2, sigma_init=[1.0, 2.0, 3.0]) == (
        "igmm.sigma_init: must be a positive number or 2 of them, got [1.0, 2.0, 3.0]"
    )
    assert _message(IGMM, 2, sigma_init=0.0) == "igmm.sigma_init: must be finite and > 0, got 0.0"
    assert _message(IGMM, 2, sigma_init="x") == (
        "igmm.sigma_init: must be a positive number or 2 of them, got 'x'"
    )
    assert _message(IGMM, 2, key=3) == "igmm.key: must be a string, got 3"
    model = IGMM(2, sigma_init=1.0).partial_fit([[0.0, 0.0], [0.1, 0.0]])
    X = np.zeros((5, 2))
    X[3, 0] = np.inf
    assert _message(model.partial_fit, X) == "X: row 3 is not finite; the model was not changed"
    assert _message(model.fit, X) == "X: must be finite; the model was not changed"
    assert _message(model.fit, np.zeros(3)) == "X: expected shape (2,) or (N, 2), got (3,)"
    assert _message(model.score_samples, X) == "X: must be finite"
    assert _message(model.score_samples, np.zeros(3)) == (
        "X: expected shape (2,) or (N, 2), got (3,)"
    )
    assert model.n_seen_ == 2


def test_igmm_documented_defaults() -> None:
    """The defaults the class docstring states (Engel & Heinen's v_min, sp_min)."""
    params = IGMM(2).get_params()
    assert params["novelty_chi2_quantile"] == 0.99 and params["sigma_init"] == [0.1, 0.1]
    assert (params["v_min"], params["sp_min"], params["max_components"]) == (5, 3.0, 20)
    assert (params["cov_floor"], params["overflow"]) == (1e-6, "merge")


def test_a_split_is_cached_once_and_the_cache_is_bounded() -> None:
    model = IGMM(6, sigma_init=1.0)
    cond = model.conditional([0, 1], [4])
    assert model.conditional([0, 1], [4]) is cond
    assert model.conditional(np.array([0, 1]), (4,)) is cond
    base = model.nbytes()
    model.conditional([2], [5])
    assert model.nbytes() > base  # a new split's cache counts
    splits = [([i], [j]) for i in range(6) for j in range(6) if i != j]
    for s in splits[:16]:
        model.conditional(*s)
    full = model.nbytes()
    for s in splits[16:20]:  # at most 16 splits are kept (the oldest go first)
        model.conditional(*s)
        assert model.nbytes() == full


def test_a_reset_model_never_answers_from_its_old_cache() -> None:
    model = IGMM(2, sigma_init=1.0)
    cond = model.conditional([0], [1])
    model.partial_fit([0.0, 5.0])
    assert cond.predict([0.0]) == pytest.approx([5.0])
    model.reset().partial_fit([0.0, -3.0])
    assert cond.predict([0.0]) == pytest.approx([-3.0])
    assert model.stats_["created"] == 1 and model.n_seen_ == 1


def test_horizon_tolerance_scales_with_long_horizons_only() -> None:
    """|n·dt − H| ≤ 1e-9 · max(1, H): 1.5 ns off is a whole number of periods at H = 2 s,
    not at H = 50 ms."""
    assert horizon_steps(2.0 + 1.5e-9, 0.001, "k") == 2000
    assert _message(horizon_steps, 0.05 + 1.5e-9, 0.001, "k").startswith("k: must be a whole")
    assert _message(horizon_steps, 0.0005, 0.001, "fm.horizon_s") == (
        "fm.horizon_s: must be a whole number of control periods (0.001 s), got 0.0005"
    )
    assert _message(ForecastBuffer, 0).startswith("forward_model.horizon: ")


def test_make_forward_model_passes_each_setting_to_its_model() -> None:
    default = make_forward_model({})
    assert isinstance(default, IncrementalForwardModel) and default.horizon_s == 0.001
    inc = make_forward_model({"igmm": {"max_components": 7}, "horizon_s": 0.01})
    assert inc.model.get_params()["max_components"] == 7 and inc.horizon_s == 0.01
    frozen = make_forward_model(
        {"kind": "fixed_gmm", "horizon_s": 0.01,
         "fixed_gmm": {"fit_steps": 50, "n_components": 2, "horizon_s": 0.05}}
    )  # fmt: skip
    assert isinstance(frozen, FrozenGMMForwardModel)
    assert (frozen.fit_steps, frozen.n_components, frozen.horizon_s) == (50, 2, 0.01)
    for cfg, key in [
        ({"bogus": 1}, "c.fm.bogus"),
        ({"kind": "fixed_gmm", "fixed_gmm": {"n_components": 0}}, "c.fm.n_components"),
        ({"igmm": {"sigma_init": -1.0}}, "c.fm.igmm.sigma_init"),
    ]:
        with pytest.raises(ConfigError) as info:
            make_forward_model(cfg, key="c.fm")
        assert info.value.key == key


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"fit_steps": 0}, "controller.forward_model.fit_steps"),
        ({"fit_steps": 1}, "controller.forward_model.fit_steps"),
        ({"n_components": 0}, "controller.forward_model.n_components"),
        ({"reg_covar": 0.0}, "controller.forward_model.reg_covar"),
        ({"horizon_s": 0.0}, "controller.forward_model.horizon_s"),
        ({"feature_scale": [1.0] * 5}, "controller.forward_model.feature_scale"),
    ],
)
def test_frozen_model_settings_name_their_key(kwargs: dict[str, Any], key: str) -> None:
    with pytest.raises(ConfigError) as info:
        FrozenGMMForwardModel(**kwargs)
    assert info.value.key == key
    if key.endswith("feature_scale"):
        assert str(info.value) == f"{key}: needs 6 values, got [1.0, 1.0, 1.0, 1.0, 1.0]"


def _linear_stream(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """S ~ N(0, diag(scale)²) and D = A S + c + 1 mN noise: one Gaussian, so one-component
    GMR is the least-squares line."""
    rng = np.random.default_rng(seed)
    S = rng.normal(0.0, 1.0, (n, 4)) * [0.05, 0.5, 5.0, 0.5]
    A = np.array([[30.0, 0.0, 0.8, 0.0], [0.0, 0.2, 0.0, 1.5]])
    D = S @ A.T + [12.0, 3.0] + rng.normal(0.0, 1e-3, (n, 2))
    return S, D, A


def test_a_one_component_frozen_gmm_predicts_the_linear_law() -> None:
    S, D, A = _linear_stream(2000, seed=5)
    m = FrozenGMMForwardModel(fit_steps=2000, n_components=1)
    assert np.all(m.predict(S[0]) == 0.0)
    for s, d in zip(S, D, strict=True):
        m.update(s, d)
    probe = np.array([0.02, -0.3, 4.0, 0.1])
    np.testing.assert_allclose(m.predict(probe), A @ probe + [12.0, 3.0], atol=0.01)
    # the errors on the window are ‖D − D̂‖: the 1 mN noise, √2 · 1e-3 in RMS
    assert m.fit_errors.shape == (2000,)
    assert np.sqrt(np.mean(m.fit_errors**2)) == pytest.approx(np.sqrt(2) * 1e-3, rel=0.1)


def test_frozen_fits_are_reproducible_and_end_trial_needs_points() -> None:
    S, D, _ = _linear_stream(300, seed=6)
    a, b = (FrozenGMMForwardModel(fit_steps=300, n_components=3) for _ in range(2))
    for s, d in zip(S, D, strict=True):
        a.update(s, d)
        b.update(s, d)
    np.testing.assert_array_equal(a.predict(S[7]), b.predict(S[7]))
    empty = FrozenGMMForwardModel(fit_steps=None)
    empty.end_trial()
    assert not empty.ready
    empty.update(S[0], D[0])
    empty.end_trial()  # one point is no mixture: the window stays open into the next trial
    assert not empty.ready
    empty.update(S[1], D[1])
    empty.end_trial()
    assert empty.ready
    loaded = FrozenGMMForwardModel(fit_steps=None)
    loaded.load_state_dict({**loaded.state_dict(), "points": []})
    for s, d in zip(S[:3], D[:3], strict=True):  # the window grows from an empty load
        loaded.update(s, d)
    assert len(loaded.state_dict()["points"]) == 3


def test_incremental_model_before_learning_and_on_bad_points() -> None:
    m = IncrementalForwardModel()
    np.testing.assert_array_equal(m.predict(np.ones(4)), [0.0, 0.0])
    bad = np.array([np.nan, 0.0, 0.0, 0.0])
    assert _message(m.update, bad, np.zeros(2)) == (
        "X: the point is not finite; the model was not changed"
    )
    assert _message(m.update_predict, bad, np.zeros(2), np.ones(4)) == (
        "X: the point is not finite; the model was not changed"
    )
    m.update(np.ones(4), np.ones(2))
    assert _message(m.predict, bad) == "x_in: row 0 is not finite"
    assert _message(m.update_predict, np.ones(4), np.ones(2), bad) == "x_in: row 0 is not finite"
    with pytest.raises(ConfigError) as info:
        IncrementalForwardModel(igmm={"sigma_init": -1.0})
    assert info.value.key == "controller.forward_model.igmm.sigma_init"


def test_igmm_setting_bounds_are_exact() -> None:
    """(0, 1) for the novelty quantile, two components for a merge, σ² ≥ the floor: each
    bound itself is allowed or refused as documented, with its own line."""
    assert _message(IGMM, 2, novelty_chi2_quantile=1.5) == (
        "igmm.novelty_chi2_quantile: must be in [0.0, 1.0], got 1.5"
    )
    assert _message(IGMM, 2, novelty_chi2_quantile=1.0) == (
        "igmm.novelty_chi2_quantile: must be in (0, 1) exclusive, got 1.0"
    )
    assert _message(IGMM, 2, max_components=1) == (
        "igmm.max_components: must be >= 2 with overflow='merge' (a merge needs two)"
    )
    IGMM(2, max_components=2)  # two are enough to merge
    IGMM(2, sigma_init=0.5, cov_floor=0.25)  # σ² equal to the floor is allowed
    assert _message(IGMM, 2, sigma_init=1e-4, cov_floor=1e-6) == (
        "igmm.sigma_init: sigma_init**2 must be >= cov_floor=1e-06, got min sigma_init 0.0001"
    )
    assert _message(FrozenGMMForwardModel, fit_steps=1) == (
        "controller.forward_model.fit_steps: must be >= 2 (a mixture needs two points)"
    )
    assert FrozenGMMForwardModel().fit_errors.shape == (0,)  # no errors before the fit
