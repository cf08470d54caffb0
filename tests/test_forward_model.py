"""Forward models of seed A Eq. 2-6: features, incremental learning, the frozen baseline."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.learn.mixtures.forecast import ForecastBuffer, horizon_steps
from ccm.learn.mixtures.forward_model import (
    FrozenGMMForwardModel,
    IncrementalForwardModel,
    magnitudes,
    make_forward_model,
)


def drag_stream(n: int, c_end: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """S_{t-1}, D_t pairs of a drag force whose coefficient ramps 0 -> c_end (porridge-like)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    speed = 0.2 * np.abs(np.sin(2 * np.pi * t / 2.0)) + 1e-3
    c = np.linspace(0.0, c_end, n)
    f = c * speed + rng.normal(0, 0.02, n)
    S = np.column_stack([speed, np.zeros(n), np.abs(f), np.zeros(n)])
    D = np.column_stack([np.abs(f), np.zeros(n)])
    return S[:-1], D[1:]


def test_magnitudes_eq_2() -> None:
    s = magnitudes(np.array([3.0, 4.0]), np.array([0.5]), np.array([0.0, -2.0]), np.array([1.0]))
    np.testing.assert_allclose(s, [5.0, 0.5, 2.0, 1.0])


def test_incremental_model_tracks_a_drifting_force() -> None:
    S, D = drag_stream(6000, 150.0)
    m = IncrementalForwardModel()
    err = []
    for s_prev, d, s_now, d_next in zip(S[:-1], D[:-1], S[1:], D[1:], strict=True):
        m.update(s_prev, d)
        err.append(m.predict(s_now)[0] - d_next[0])
    rmse_late = float(np.sqrt(np.mean(np.square(err[-2000:]))))
    assert rmse_late < 0.5, f"one-step RMSE {rmse_late:.3f} N on the late (unseen) part"


def test_frozen_model_fits_once_and_never_changes() -> None:
    S, D = drag_stream(3000, 80.0)
    m = FrozenGMMForwardModel(fit_steps=1000, n_components=3)
    assert not m.ready and np.all(m.predict(S[0]) == 0.0)
    for s, d in zip(S[:1000], D[:1000], strict=True):
        m.update(s, d)
    assert m.ready
    probe = S[2500]
    before = m.predict(probe).copy()
    for s, d in zip(S[1000:], D[1000:], strict=True):
        m.update(s, d)
    np.testing.assert_array_equal(m.predict(probe), before)


def test_incremental_beats_frozen_outside_the_training_range() -> None:
    """The unit-level version of H1: train on 0->80, test on 0->150 (seed A §4.1)."""
    S_tr, D_tr = drag_stream(6000, 80.0, seed=1)
    S_te, D_te = drag_stream(6000, 150.0, seed=2)
    inc, fro = IncrementalForwardModel(), FrozenGMMForwardModel(fit_steps=len(S_tr))
    for s, d in zip(S_tr, D_tr, strict=True):
        inc.update(s, d)
        fro.update(s, d)
    e_inc, e_fro = [], []
    for s_prev, d, s_now, d_next in zip(S_te[:-1], D_te[:-1], S_te[1:], D_te[1:], strict=True):
        inc.update(s_prev, d)
        fro.update(s_prev, d)
        e_inc.append(inc.predict(s_now)[0] - d_next[0])
        e_fro.append(fro.predict(s_now)[0] - d_next[0])
    unseen = slice(3300, None)  # coefficient above 80 N s/m
    r_inc = np.sqrt(np.mean(np.square(e_inc[unseen])))
    r_fro = np.sqrt(np.mean(np.square(e_fro[unseen])))
    assert r_inc < r_fro, (r_inc, r_fro)


def test_make_forward_model_validates() -> None:
    with pytest.raises(ConfigError, match="forward_model.kind"):
        make_forward_model({"kind": "neural"})
    with pytest.raises(ConfigError, match=r"feature_scale\[2\]"):
        make_forward_model({"kind": "igmm", "feature_scale": [1, 1, -1, 1, 1, 1]})
    with pytest.raises(ConfigError, match="fixed_gmm.fit_step"):
        make_forward_model({"kind": "fixed_gmm", "fixed_gmm": {"fit_step": 3}})
    with pytest.raises(ConfigError, match="forward_model.horizon_s"):
        make_forward_model({"kind": "igmm", "horizon_s": -0.01})


def test_horizon_steps_needs_whole_control_periods() -> None:
    assert horizon_steps(0.001, 0.001, "k") == 1
    assert horizon_steps(0.05, 0.001, "k") == 50
    for bad in (0.0005, 0.0105, float("nan")):
        with pytest.raises(ConfigError, match="^k"):
            horizon_steps(bad, 0.001, "k")


@pytest.mark.parametrize("h", [1, 3])
def test_forecast_buffer_pairs_states_and_predictions_h_steps_apart(h: int) -> None:
    """At step t: past() gives S_{t-H} and the prediction made from it; after push(S_t),
    next_prediction() is the one made from S_{t+1-H} (for H = 1: the one just pushed)."""
    buf = ForecastBuffer(h)
    for t in range(12):
        state, pred = buf.past()
        if t < h:
            assert state is None and pred is None
        else:
            assert state[0] == t - h and pred[0] == 100 + t - h
        buf.push(np.array([float(t)]), np.array([100.0 + t]))
        nxt = buf.next_prediction()
        assert (nxt is None) if t + 1 < h else (nxt[0] == 100 + t + 1 - h)
    buf.forget_predictions()
    assert buf.past()[1] is None and buf.next_prediction() is None
    assert buf.past()[0] is not None, "states stay: the next learning pair still exists"


def test_saved_model_must_have_the_same_horizon() -> None:
    a = make_forward_model({"kind": "igmm", "horizon_s": 0.01})
    a.update(np.ones(4), np.ones(2))
    b = make_forward_model({"kind": "igmm", "horizon_s": 0.05})
    with pytest.raises(ValueError, match="horizon_s"):
        b.load_state_dict(a.state_dict())


def test_frozen_gmm_without_fit_steps_fits_on_the_first_trial() -> None:
    """fit_steps=None: the window is the first trial (any length); then frozen, with its
    errors on the window kept for AVIC's calibration."""
    S, D = drag_stream(1500, 80.0, seed=4)
    m = FrozenGMMForwardModel(fit_steps=None, n_components=2)
    for s, d in zip(S, D, strict=True):
        m.update(s, d)
    assert not m.ready
    m.end_trial()
    assert m.ready and m.fit_errors.shape == (len(S),)
    before = m.predict(S[10]).copy()
    m.update(S[0], D[0] + 100.0)
    m.end_trial()
    np.testing.assert_array_equal(m.predict(S[10]), before)
