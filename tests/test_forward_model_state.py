"""Learned state of the forward models (``state_dict`` / ``load_state_dict``; issue #39 item 1).

A saved model loaded into one built from the same config predicts what the saved one did;
its settings stay the config's; a snapshot of another kind, feature scale or horizon, or a
malformed one, is refused with the line that names the difference.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from ccm.learn.mixtures.forward_model import (
    DEFAULT_SCALE,
    FrozenGMMForwardModel,
    IncrementalForwardModel,
)
from tests.test_forward_model import drag_stream

_S, _D = drag_stream(400, 80.0, seed=3)
#: two regimes 40 N apart (free motion, then a press), so that the IGMM needs several components
S = np.vstack([_S[:200], _S[200:] + [0.0, 0.0, 40.0, 0.0]])
D = np.vstack([_D[:200], _D[200:] + [40.0, 0.0]])


def _json(state: dict[str, Any]) -> dict[str, Any]:
    return json.loads(json.dumps(state, allow_nan=False))


def _trained_incremental(**kw: Any) -> IncrementalForwardModel:
    m = IncrementalForwardModel(**kw)
    for s, d in zip(S, D, strict=True):
        m.update(s, d)
    return m


def test_incremental_state_round_trips_and_keeps_the_configs_settings() -> None:
    saved = _trained_incremental(igmm={"max_components": 8, "sigma_init": 0.3})
    state = _json(saved.state_dict())
    assert (state["kind"], state["horizon_s"]) == ("igmm", saved.horizon_s)
    assert state["feature_scale"] == list(DEFAULT_SCALE)
    fresh = IncrementalForwardModel(igmm={"max_components": 8, "sigma_init": 0.5})
    fresh.load_state_dict(state)
    assert fresh.model.n_components_ == saved.model.n_components_ > 1
    for s in S[::37]:
        np.testing.assert_array_equal(fresh.predict(s), saved.predict(s))
    # the components are the saved model's, the settings this config's
    assert fresh.model.get_params()["sigma_init"] == [0.5] * 6
    fresh.update(S[0], D[0])  # and it goes on learning
    assert fresh.model.n_seen_ == saved.model.n_seen_ + 1


def _refusal(model: Any, state: Any) -> str:
    with pytest.raises(ValueError) as info:
        model.load_state_dict(state)
    return str(info.value)


@pytest.mark.parametrize("cls", [IncrementalForwardModel, FrozenGMMForwardModel])
def test_a_foreign_snapshot_is_refused_naming_the_difference(cls: type) -> None:
    model = cls()
    kind = "igmm" if cls is IncrementalForwardModel else "fixed_gmm"
    state = _json(model.state_dict())
    assert _refusal(model, [state]) == "forward model state must be a mapping, got list"
    other = "fixed_gmm" if kind == "igmm" else "igmm"
    assert _refusal(model, {**state, "kind": other}) == (
        f"the saved forward model is kind {other!r}, this config's is {kind!r}"
    )
    scale = [0.1, 1.0, 10.0, 1.0, 10.0, 2.0]  # the same shape, one value differs
    assert _refusal(model, {**state, "feature_scale": scale}) == (
        f"the saved forward model has feature_scale {scale!r}, this config's is "
        f"{list(DEFAULT_SCALE)!r}"
    )
    assert "feature_scale [0.1, 1.0]" in _refusal(model, {**state, "feature_scale": [0.1, 1.0]})
    assert _refusal(model, {**state, "horizon_s": 0.05}) == (
        "the saved forward model has horizon_s 0.05, this config's is 0.001"
    )


def test_an_incremental_snapshot_without_its_mixture_is_refused() -> None:
    model = IncrementalForwardModel()
    state = _json(model.state_dict())
    for bad in (None, [1]):
        assert _refusal(model, {**state, "igmm": bad}) == (
            "forward model state: igmm must be a mapping"
        )
    too_many = _json(_trained_incremental(igmm={"max_components": 8}).state_dict())
    assert "means must have shape (K<=1, 6)" in _refusal(
        IncrementalForwardModel(igmm={"max_components": 1, "overflow": "prune"}), too_many
    )


def test_a_frozen_model_saved_before_its_fit_resumes_collecting() -> None:
    """Saved at 150 of 300 points: the loaded model fits at the same step on the same points
    as one that never stopped."""
    whole, part = FrozenGMMForwardModel(fit_steps=300), FrozenGMMForwardModel(fit_steps=300)
    for s, d in zip(S[:150], D[:150], strict=True):
        whole.update(s, d)
        part.update(s, d)
    state = _json(part.state_dict())
    assert state["fitted"] is None and len(state["points"]) == 150
    resumed = FrozenGMMForwardModel(fit_steps=300)
    resumed.load_state_dict(state)
    for s, d in zip(S[150:299], D[150:299], strict=True):
        whole.update(s, d)
        resumed.update(s, d)
    assert not resumed.ready
    whole.update(S[299], D[299])
    resumed.update(S[299], D[299])
    assert resumed.ready
    np.testing.assert_allclose(resumed.predict(S[5]), whole.predict(S[5]), rtol=1e-12)


def test_a_frozen_model_loads_fitted_or_fits_a_full_window_at_once() -> None:
    fitted = FrozenGMMForwardModel(fit_steps=200, n_components=2)
    for s, d in zip(S[:200], D[:200], strict=True):
        fitted.update(s, d)
    state = _json(fitted.state_dict())
    assert state["points"] == [] and set(state["fitted"]) == {"weights", "means", "covariances"}
    loaded = FrozenGMMForwardModel(fit_steps=200, n_components=2)
    loaded.load_state_dict(state)
    assert loaded.ready
    np.testing.assert_array_equal(loaded.predict(S[300]), fitted.predict(S[300]))
    # 250 saved points and a 200-point window: fit now on the first 200, as the run would have
    collected = FrozenGMMForwardModel(fit_steps=300, n_components=2)
    for s, d in zip(S[:250], D[:250], strict=True):
        collected.update(s, d)
    window = FrozenGMMForwardModel(fit_steps=200, n_components=2)
    window.load_state_dict(_json(collected.state_dict()))
    assert window.ready
    np.testing.assert_allclose(window.predict(S[300]), fitted.predict(S[300]), rtol=1e-12)
    # without fit_steps every saved point is kept, and none is fit before the trial ends
    open_ended = FrozenGMMForwardModel(fit_steps=None)
    open_ended.load_state_dict(_json(collected.state_dict()))
    assert not open_ended.ready and len(open_ended.state_dict()["points"]) == 250


def test_a_malformed_frozen_snapshot_is_refused() -> None:
    model = FrozenGMMForwardModel(fit_steps=10)
    state = _json(model.state_dict())
    assert _refusal(model, {**state, "fitted": [1]}) == (
        "forward model state: fitted must be a mapping or null"
    )
    points = [[1.0, 0.0, 0.0, 0.0, float("nan"), 0.0]]
    assert _refusal(model, {**state, "points": points}) == (
        "forward model state: points must be finite"
    )
