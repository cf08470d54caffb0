"""Contracts of the GP learners (``ModalGPDynamics``, ``GPForceModels``; issue #39 item 1).

Each refusal is the one line that names the argument (checked whole); the per-mode GPs
standardise their inputs and fit their noise, so a smooth law far from the origin is
predicted to its noise level with a predictive std of that level; the settings reach what
they set (the classifier's subsample and C, the optimiser's iteration cap); convergence
warnings are counted over every mode; a rollout's first step uses the first exogenous row.
"""

from __future__ import annotations

import time
from functools import partial
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.gp.gp_force_models import GPForceModels
from ccm.learn.gp.svm_gp import ModalGPDynamics
from tests.refusals import refusal
from tests.test_gp_force import _contact_data
from tests.test_svm_gp import _dataset, _force_data

_line = partial(refusal, ConfigError)


@pytest.mark.parametrize(
    ("kwargs", "line"),
    [
        ({"max_points_classifier": 0}, "h.max_points_classifier: must be an integer >= 1, got 0"),
        ({"noise_level_bounds": (1.0, 0.1)}, "h.noise_level_bounds"),
        ({"n_restarts": -1}, "h.n_restarts"),
        ({"n_particles": 0}, "h.n_particles"),
        ({"seed": -1}, "h.seed"),
    ],
)
def test_settings_name_their_key(kwargs: dict[str, Any], line: str) -> None:
    assert _line(ModalGPDynamics, key="h", **kwargs).startswith(line)


def test_fit_refusals_are_whole_lines() -> None:
    X, Y, modes, _ = _force_data()
    m = ModalGPDynamics(key="h")
    assert _line(m.fit, [["a"]], Y, modes) == "h.X: must be a numeric array"
    assert _line(m.fit, X[:0], Y, modes) == "h.X: must be a non-empty 2-D array, got shape (0, 2)"
    assert _line(m.fit, X[:, :0], Y, modes) == (
        "h.X: must be a non-empty 2-D array, got shape (200, 0)"
    )
    assert _line(m.fit, X[:, 0], Y, modes) == "h.X: must be a non-empty 2-D array, got shape (200,)"
    bad = Y.copy()
    bad[4] = np.inf
    assert _line(m.fit, X, bad, modes) == "h.Y: must be finite (found NaN or inf)"
    assert _line(m.fit, X, Y[:-1], modes) == (
        "h.fit: X, Y, modes need the same length N; got (200, 2), (199, 1), (200,)"
    )
    assert _line(m.fit, X, Y, modes[:-1]) == (
        "h.fit: X, Y, modes need the same length N; got (200, 2), (200, 1), (199,)"
    )
    assert _line(m.fit, X, Y, modes[:, None]) == (
        "h.fit: X, Y, modes need the same length N; got (200, 2), (200, 1), (200, 1)"
    )
    assert _line(m.fit, X, Y, modes + 0.5) == "h.modes: must be integer labels"
    assert _line(m.fit, X, Y, modes.astype(str)) == "h.modes: must be integer labels"
    assert _line(m.fit, X[:, :1], np.hstack([Y, Y]), modes) == (
        "h.Y: has 2 columns, more than X's 1"
    )
    few = modes.copy()
    few[:2] = 7  # mode 7 has 2 points: allowed; mode 9 with 1 is not
    few[2] = 9
    assert _line(m.fit, X, Y, few) == "h.modes: every mode needs >= 2 points; too few for [9]"


def test_float_labels_that_are_whole_numbers_are_modes() -> None:
    X, Y, modes, _ = _force_data()
    modes = modes.copy()
    modes[:2] = 2  # a mode of exactly two points is fitted
    m = ModalGPDynamics(max_points_per_mode=50, n_particles=4).fit(X, Y, modes.astype(float))
    np.testing.assert_array_equal(m.classes_, [0, 1, 2])
    assert m.classes_.dtype.kind == "i"


def test_prediction_refusals_are_whole_lines() -> None:
    X, Y, modes, v = _force_data()
    m = ModalGPDynamics(max_points_per_mode=50, n_particles=4, key="h").fit(X, Y, modes)
    assert _line(m.predict_step, X[:, :1]) == "h.X: needs 2 columns, got 1"
    assert _line(m.rollout, X[0], 0, exog=v[:1, None]).startswith("h.steps: ")
    assert _line(m.rollout, X[0, :1], 3, exog=v[:3, None]) == (
        "h.x0: must be a finite vector of length 2"
    )
    assert _line(m.rollout, [np.nan, 0.5], 3, exog=v[:3, None]) == (
        "h.x0: must be a finite vector of length 2"
    )
    assert _line(m.rollout, X[0], 3, exog=v[:5, None]) == (
        "h.exog: must have shape (3 or 4, 1), got (5, 1)"
    )
    assert _line(m.rollout, X[0], 3, exog=np.full((3, 1), np.nan)) == (
        "h.exog: must be finite (found NaN or inf)"
    )
    assert _line(m.rollout, X[0], 3) == "h.exog: needed: inputs have 1 exogenous columns"
    joint = ModalGPDynamics(max_points_per_mode=30, n_particles=2, key="h")
    Xj, Yj, mj = _dataset(n_trials=1, steps=40)
    joint.fit(Xj, Yj, mj)
    assert _line(joint.rollout, Xj[0], 2, exog=np.zeros((2, 1))) == (
        "h.exog: must be None: the inputs have no exogenous columns"
    )


def test_a_shared_classifier_must_come_from_the_same_data() -> None:
    X, Y, modes, _ = _force_data()
    a = ModalGPDynamics(max_points_per_mode=50, key="h").fit(X, Y, modes)
    spread = X.mean(axis=0) + 2.0 * (X - X.mean(axis=0))  # same mean, twice the spread
    b = ModalGPDynamics(max_points_per_mode=50, key="h")
    assert _line(b.fit, spread, Y, modes, classifier=a) == (
        "h.classifier: must be a model fitted on the same X and modes"
    )


def _offset_smooth(n: int, noise: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """y = sin(3 x1) + 0.5 x2 on [10, 11] x [−6, −4]: far from the origin, unit-less scales."""
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(10.0, 11.0, n), rng.uniform(-6.0, -4.0, n)])
    return X, (np.sin(3 * X[:, 0]) + 0.5 * X[:, 1] + noise * rng.normal(size=n))[:, None]


def test_a_mode_gp_predicts_a_smooth_law_to_its_noise_and_knows_its_noise() -> None:
    X, Y = _offset_smooth(150, 1e-3, seed=4)
    Xt, Yt = _offset_smooth(50, 0.0, seed=5)
    for delta in (False, True):
        m = ModalGPDynamics(predict_delta=delta, n_particles=2)
        t0 = time.perf_counter()
        m.fit(X, Y, np.zeros(len(X), dtype=int))
        assert 0.0 < m.fit_time_s_ <= time.perf_counter() - t0
        mean, std = m.predict_step(Xt)
        assert np.sqrt(np.mean((mean - Yt) ** 2)) < 3e-3, delta
        # the predictive std holds the learned 1e-3 noise (plus a little model uncertainty)
        assert 0.5e-3 < float(np.median(std)) < 3e-3, delta


def test_the_iteration_cap_reaches_the_optimiser() -> None:
    X, Y = _offset_smooth(80, 1e-3, seed=6)
    zeros = np.zeros(len(X), dtype=int)
    capped = ModalGPDynamics(max_iter=1, n_particles=2).fit(X, Y, zeros)
    free = ModalGPDynamics(max_iter=200, n_particles=2).fit(X, Y, zeros)
    lml_capped = capped.gps_[0][0].log_marginal_likelihood_value_
    assert free.gps_[0][0].log_marginal_likelihood_value_ > lml_capped + 10.0


def test_convergence_warnings_are_counted_over_every_mode() -> None:
    """Pure-noise targets drive the length scales to their upper bound (scikit-learn's
    ConvergenceWarning); the count of a two-mode fit is the sum of its modes' counts."""
    rng = np.random.default_rng(8)
    X = rng.uniform(0.0, 1.0, (60, 2))
    Y = rng.normal(size=(60, 1))
    modes = (X[:, 0] > 0.5).astype(int)
    both = ModalGPDynamics(length_scale_bounds=(1e-2, 2.0)).fit(X, Y, modes)
    single = [
        ModalGPDynamics(length_scale_bounds=(1e-2, 2.0))
        .fit(X[modes == c], Y[modes == c], np.zeros(int(np.sum(modes == c)), dtype=int))
        .n_fit_warnings_
        for c in (0, 1)
    ]
    assert min(single) >= 1 and both.n_fit_warnings_ == sum(single)


def test_the_classifier_uses_its_subsample_and_c() -> None:
    """max_points_classifier = 2 of 200 points: each mode still gives its 10 (the floor)."""
    X, Y, modes, _ = _force_data()
    m = ModalGPDynamics(max_points_classifier=2, max_points_per_mode=20, svc_c=3.0).fit(X, Y, modes)
    assert m.svc_.shape_fit_[0] == 20 and m.svc_.C == 3.0
    m = ModalGPDynamics(max_points_classifier=100, max_points_per_mode=20).fit(X, Y, modes)
    counts = np.bincount(modes)
    assert m.svc_.shape_fit_[0] == sum(int(np.ceil(0.5 * c)) for c in counts)


def test_the_first_rollout_step_uses_the_first_exogenous_row() -> None:
    """F_{t+1} ≈ F_t + gain · v_t: two rollouts that differ only in exog row 0 (±1 m/s)
    differ in their first step by 2 · gain, and row 0 replaces x0's velocity."""
    X, Y, modes, v = _force_data()
    m = ModalGPDynamics(max_points_per_mode=100, n_particles=50).fit(X, Y, modes)
    x0 = np.array([0.2, 0.0])
    exog = np.column_stack([np.full(4, 0.5)])
    up, down = exog.copy(), exog.copy()
    up[0], down[0] = 0.6, 0.4
    first_up = m.rollout(x0, 4, exog=up)[0][0, 0]
    first_down = m.rollout(x0, 4, exog=down)[0][0, 0]
    assert first_up - first_down == pytest.approx(2 * 0.1 * 0.02, abs=1e-3)


def test_gp_force_models_name_each_output() -> None:
    X, f = _contact_data()
    assert len(GPForceModels(6).models) == 6  # six force/torque axes are allowed
    assert _line(GPForceModels, 7, key="fm") == "fm.n_outputs: must be <= 6, got 7"
    assert _line(GPForceModels, 0, key="fm").startswith("fm.n_outputs: ")
    assert _line(GPForceModels, 2, key="fm", hinge_input=0) == (
        "fm.hinge_input: use hinge_inputs (one per output)"
    )
    assert _line(GPForceModels, 2, key="fm", hinge_inputs=[0]) == (
        "fm.hinge_inputs: must have 2 entries"
    )
    models = GPForceModels(2, key="fm", hinge_inputs=[0, 0], mean="hinge")
    assert [m.key for m in models.models] == ["fm.outputs[0]", "fm.outputs[1]"]
    assert [m.hinge_input for m in models.models] == [0, 0]
    assert _line(models.fit, X, np.ones((len(X), 3))) == (
        f"fm.F: must have 2 columns, got ({len(X)}, 3)"
    )
    assert _line(models.fit, X, np.ones(len(X))).startswith("fm.F: ")
    models.fit(X, np.column_stack([f, 2 * f]))
    assert _line(models.models[0].negative_log_likelihood, [0.1], 1.0, 0.1) == (
        "fm.outputs[0].mean: hinge mean needs hinge=(c1, c2, c3)"
    )


def _clean_hinge() -> tuple[np.ndarray, np.ndarray]:
    """f = 2 − 30 · max(0, x − 0.4) on 41 points of [0, 1]: c3 = 0.4 lies on the start's grid
    of 21 values, so the least-squares hinge start recovers (c1, c2, c3) = (2, −30, 0.4)."""
    x = np.linspace(0.0, 1.0, 41)
    return x[:, None], 2.0 - 30.0 * np.maximum(0.0, x - 0.4)


@pytest.mark.parametrize("variance", ["separate", "tied"])
def test_the_hinge_start_is_the_least_squares_hinge(variance: str) -> None:
    """The deterministic start (seed B's hinge mean, Eq. 3): the hinge by least squares over a
    grid of c3; σ_f² the residual variance (floored at 1e-12) and σ_n² a tenth of it, or the
    same one variance when tied (Eq. 1–2 as printed)."""
    from ccm.learn.gp.gp_force import GPForceModel

    X, f = _clean_hinge()
    wide = {"signal_var_bounds": (1e-14, 1e4), "noise_var_bounds": (1e-14, 1e2)}  # no clip
    m = GPForceModel(mean="hinge", n_restarts=0, variance=variance, **wide).fit(X, f)
    start = m.initial_params_
    np.testing.assert_allclose(start["hinge"], (2.0, -30.0, 0.4), atol=1e-9)
    np.testing.assert_allclose(start["length_scales"], [X[:, 0].std()], rtol=1e-12)
    assert start["signal_var"] == pytest.approx(1e-12)
    noise = 1e-12 if variance == "tied" else 1e-13
    assert start["noise_var"] == pytest.approx(noise)


def test_gp_force_sample_and_hinge_input_bounds() -> None:
    from ccm.learn.gp.gp_force import GPForceModel

    X, f = _clean_hinge()
    GPForceModel(n_restarts=0).fit(X[:2], f[:2])  # two samples are enough
    assert _line(GPForceModel(key="g").fit, X[:1], f[:1]) == "g.X: needs at least 2 samples, got 1"
    assert _line(GPForceModel(key="g").fit, X, f[:-1]) == (
        "g.f: must have length 41 (rows of X), got 40"
    )
    assert _line(GPForceModel(key="g", mean="hinge", hinge_input=1).fit, X, f) == (
        "g.hinge_input: must be < input dimension 1"
    )


def test_a_singular_kernel_has_minus_infinite_likelihood() -> None:
    """FastGPR returns log p = −inf (zero gradient) where K is not positive definite, so the
    optimiser moves away; +inf would attract it."""
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    from ccm.learn.gp._gpr import FastGPR

    x = np.repeat(np.linspace(0.0, 1.0, 10), 3)[:, None]  # every point three times
    kernel = ConstantKernel(1.0) * RBF(0.3) + WhiteKernel(1e-3)
    gp = FastGPR(kernel=kernel, optimizer=None, alpha=0.0).fit(x, np.sin(3 * x[:, 0]))
    theta = gp.kernel_.theta.copy()
    theta[-1] = np.log(1e-300)  # no noise: K has repeated rows
    theta[0] = np.log(1e3)
    value, grad = gp.log_marginal_likelihood(theta, eval_gradient=True)
    assert value == -np.inf and np.all(grad == 0.0)
    assert gp.log_marginal_likelihood(theta) == -np.inf
