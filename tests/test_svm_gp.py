"""Tests for the Khader et al. 2020 modal GP baseline (seed A §4.4)."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.gp.svm_gp import ModalGPDynamics

NOISE = 1e-3
SPEED = 0.01


def _true_step(s: np.ndarray) -> np.ndarray:
    """Two-mode system: x moves right; y rises left of 0.5, falls right of it."""
    x, y = s
    return np.array([x + SPEED, y + (0.01 if x < 0.5 else -0.02)])


def _trajectory(y0: float, steps: int, rng: np.random.Generator | None) -> np.ndarray:
    s = [np.array([0.0, y0])]
    for _ in range(steps):
        nxt = _true_step(s[-1])
        if rng is not None:
            nxt = nxt + NOISE * rng.standard_normal(2)
        s.append(nxt)
    return np.array(s)


def _dataset(n_trials: int = 6, steps: int = 100) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(1)
    xs, ys, ms = [], [], []
    for _ in range(n_trials):
        traj = _trajectory(rng.uniform(0.0, 0.2), steps, rng)
        xs.append(traj[:-1])
        ys.append(traj[1:])
        ms.append((traj[:-1, 0] >= 0.5).astype(int))
    return np.vstack(xs), np.vstack(ys), np.concatenate(ms)


@pytest.fixture(scope="module")
def fitted() -> tuple[ModalGPDynamics, tuple[np.ndarray, ...]]:
    data = _dataset()
    model = ModalGPDynamics(max_points_per_mode=200, n_particles=40, seed=3).fit(*data)
    return model, data


def test_mode_classifier_and_one_step(fitted) -> None:
    model, (X, Y, modes) = fitted
    assert model.n_modes_ == 2
    assert model.fit_time_s_ > 0
    rng = np.random.default_rng(7)
    test = _trajectory(0.1, 100, rng)
    Xt, Yt = test[:-1], test[1:]
    mt = (Xt[:, 0] >= 0.5).astype(int)
    assert np.mean(model.predict_mode(Xt) == mt) > 0.95
    mean, std = model.predict_step(Xt)
    assert mean.shape == std.shape == (100, 2)
    assert np.all(std > 0)
    # away from the boundary (where a one-step mode error is allowed) the error is ~noise
    far = np.abs(Xt[:, 0] - 0.5) > 0.03
    rmse = np.sqrt(np.mean((mean[far] - Yt[far]) ** 2))
    assert rmse < 5e-3


def test_rollout_tracks_truth_and_switches_mode(fitted) -> None:
    model, _ = fitted
    steps = 100
    truth = _trajectory(0.1, steps, None)[1:]
    mean, std, frac = model.rollout(np.array([0.0, 0.1]), steps)
    assert mean.shape == std.shape == (steps, 2)
    assert frac.shape == (steps, 2)
    np.testing.assert_allclose(frac.sum(axis=1), 1.0)
    assert np.all(np.abs(mean - truth) <= 4 * std + 2e-3)
    assert std[-1, 1] > std[5, 1]
    assert np.all(frac[:40, 0] == 1.0)
    assert np.all(frac[60:, 1] == 1.0)


def test_determinism(fitted) -> None:
    model, data = fitted
    a = model.rollout(np.array([0.0, 0.05]), 30)
    b = ModalGPDynamics(max_points_per_mode=200, n_particles=40, seed=3).fit(*data)
    b_out = b.rollout(np.array([0.0, 0.05]), 30)
    for u, v in zip(a, b_out, strict=True):
        np.testing.assert_array_equal(u, v)


def _force_data() -> tuple[np.ndarray, ...]:
    """Variant (ii) shape: input [F (1), v (1)], output F_{t+1}; stiff contact for F > 1."""
    rng = np.random.default_rng(2)
    f = np.zeros(201)
    v = 0.5 + 0.1 * np.sin(np.arange(201) / 10)
    for t in range(200):
        gain = 0.02 if f[t] < 1.0 else 0.05
        f[t + 1] = f[t] + gain * v[t] + NOISE * rng.standard_normal()
    X = np.column_stack([f[:-1], v[:-1]])
    return X, f[1:, None], (f[:-1] >= 1.0).astype(int), v


def test_exogenous_rollout() -> None:
    X, Y, modes, v = _force_data()
    model = ModalGPDynamics(max_points_per_mode=100, n_particles=20, key="ctl.h3").fit(X, Y, modes)
    mean, std, frac = model.rollout(X[0], 50, exog=v[:50, None])
    assert mean.shape == std.shape == (50, 1)
    assert frac.shape == (50, 2)
    assert np.all(np.isfinite(mean))
    np.testing.assert_allclose(mean[:, 0], Y[:50, 0], atol=0.05)
    whole = model.rollout(X[0], 50, exog=v[:51, None])  # a whole trial: last row unused
    np.testing.assert_array_equal(whole[0], mean)
    with pytest.raises(ConfigError, match=r"ctl\.h3\.exog"):
        model.rollout(X[0], 50, exog=v[:49, None])
    with pytest.raises(ConfigError, match=r"ctl\.h3\.exog"):
        model.rollout(X[0], 50, exog=v[:52, None])
    with pytest.raises(ConfigError, match=r"ctl\.h3\.exog"):
        model.rollout(X[0], 50)


def test_bad_inputs() -> None:
    X, Y, modes, _ = _force_data()
    m = ModalGPDynamics(key="ctl.h3")
    with pytest.raises(ConfigError, match=r"ctl\.h3\.fit"):
        m.predict_step(X)
    with pytest.raises(ConfigError, match=r"ctl\.h3\.fit"):
        m.rollout(X[0], 3, exog=X[:3, 1:])
    Xn = X.copy()
    Xn[3, 0] = np.nan
    with pytest.raises(ConfigError, match=r"ctl\.h3\.X"):
        m.fit(Xn, Y, modes)
    with pytest.raises(ConfigError, match=r"ctl\.h3"):
        m.fit(X[:-1], Y, modes)
    with pytest.raises(ConfigError, match=r"ctl\.h3\.Y"):
        m.fit(X[:, :1], np.hstack([Y, Y]), modes)
    bad_modes = modes.copy()
    bad_modes[0] = 9
    with pytest.raises(ConfigError, match=r"ctl\.h3\.modes"):
        m.fit(X, Y, bad_modes)
    with pytest.raises(ConfigError, match=r"ctl\.h3\.max_points_per_mode"):
        ModalGPDynamics(max_points_per_mode=-1, key="ctl.h3")
    with pytest.raises(ConfigError, match=r"ctl\.h3\.max_iter"):
        ModalGPDynamics(max_iter=0, key="ctl.h3")
    with pytest.raises(ConfigError, match=r"ctl\.h3\.svc_c"):
        ModalGPDynamics(svc_c=0.0, key="ctl.h3")
    with pytest.raises(ConfigError, match=r"ctl\.h3\.length_scale_bounds"):
        ModalGPDynamics(length_scale_bounds=(1.0, 0.1), key="ctl.h3")


def test_single_mode_and_independent_outputs() -> None:
    X, Y, modes = _dataset(n_trials=2, steps=40)
    model = ModalGPDynamics(independent_outputs=True, predict_delta=False, n_particles=5)
    model.fit(X, Y, np.zeros(len(X), dtype=int))
    assert model.n_modes_ == 1
    assert len(model.gps_[0]) == 2
    mean, std = model.predict_step(X[:5])
    assert mean.shape == std.shape == (5, 2)
    _, _, frac = model.rollout(X[0], 4)
    np.testing.assert_array_equal(frac, np.ones((4, 1)))


@pytest.mark.parametrize("kernel_name", ["ard", "isotropic", "matern"])
@pytest.mark.parametrize("n_out", [1, 3])
def test_fast_gpr_matches_sklearn_lml_and_gradient(n_out: int, kernel_name: str) -> None:
    """FastGPR's log marginal likelihood and gradient (Eqs 5.8-5.9, R&W 2006) equal
    scikit-learn's own at arbitrary hyperparameters (short and long length scales), for one
    and several outputs: the closed-form path (constant x RBF + white, ARD or isotropic) and
    the generic one (any other kernel)."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern, WhiteKernel

    from ccm.learn.gp._gpr import FastGPR, _constant_rbf_white

    rng = np.random.default_rng(3)
    x = rng.normal(size=(60, 4))
    y = np.column_stack([np.sin(x @ rng.normal(size=4)) for _ in range(n_out)])
    y = y[:, 0] if n_out == 1 else y
    inner = {"ard": RBF(np.ones(4)), "isotropic": RBF(1.0), "matern": Matern(np.ones(4))}
    kernel = ConstantKernel(1.0) * inner[kernel_name] + WhiteKernel(0.1)
    assert (_constant_rbf_white(kernel) is None) == (kernel_name == "matern")
    ref = GaussianProcessRegressor(kernel=kernel, optimizer=None, normalize_y=True).fit(x, y)
    fast = FastGPR(kernel=kernel, optimizer=None, normalize_y=True).fit(x, y)
    theta0 = ref.kernel_.theta
    for shift in (-3.0, 0.0, 2.0, None):
        step = rng.normal(scale=0.5, size=theta0.shape) if shift is None else shift
        theta = theta0 + step
        v_ref, g_ref = ref.log_marginal_likelihood(theta, eval_gradient=True)
        v_fast, g_fast = fast.log_marginal_likelihood(theta, eval_gradient=True)
        assert v_fast == pytest.approx(v_ref, rel=1e-9)
        np.testing.assert_allclose(g_fast, g_ref, rtol=1e-7, atol=1e-7 * np.abs(g_ref).max())
        assert fast.log_marginal_likelihood(theta) == pytest.approx(v_ref, rel=1e-10)
    assert fast.log_marginal_likelihood() == pytest.approx(ref.log_marginal_likelihood(), rel=1e-12)


def test_absolute_and_increment_gps_share_one_classifier(fitted) -> None:
    """The absolute GP (seed A §4.4.2's p(F_{t+1} | F_t, ẋ_t)) can reuse an increment GP's
    mode classifier; away from the data it reverts to its mean, the increment GP to
    persistence (the next state = the current one)."""
    model, data = fitted
    absolute = ModalGPDynamics(max_points_per_mode=200, seed=3, predict_delta=False)
    absolute.fit(*data, classifier=model)
    assert absolute.svc_ is model.svc_
    far = np.array([[0.3, 50.0]])  # y far outside the training range [0, ~1.2]
    assert model.predict_step(far)[0][0, 1] == pytest.approx(50.0, abs=1.0)
    assert abs(absolute.predict_step(far)[0][0, 1]) < 5.0
    X, Y, modes = data
    with pytest.raises(ConfigError, match="classifier"):
        ModalGPDynamics(seed=3).fit(X[:300], Y[:300], modes[:300], classifier=model)
